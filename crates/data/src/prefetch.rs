//! Prefetch: a worker thread decodes the next clips while the caller computes.

use crate::clip::Clip;
use crate::dataset::ClipDataset;
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Iterates the clips of `order`, decoded `depth` ahead on a worker thread. Bad clips are
/// skipped (the dataset warns and counts them).
pub struct Prefetcher {
    rx: Option<Receiver<Arc<Clip>>>,
    worker: Option<JoinHandle<()>>,
}

impl Prefetcher {
    pub fn new(dataset: Arc<ClipDataset>, order: Vec<usize>, depth: usize) -> Prefetcher {
        // depth 0 would make a rendezvous channel: still correct, but no overlap.
        let (tx, rx) = sync_channel(depth.max(1));
        let worker = std::thread::spawn(move || {
            for i in order {
                if let Some(clip) = dataset.get(i) {
                    if tx.send(clip).is_err() {
                        return; // the consumer went away
                    }
                }
            }
        });
        Prefetcher {
            rx: Some(rx),
            worker: Some(worker),
        }
    }
}

impl Iterator for Prefetcher {
    type Item = Arc<Clip>;
    fn next(&mut self) -> Option<Arc<Clip>> {
        self.rx.as_ref()?.recv().ok()
    }
}

impl Drop for Prefetcher {
    fn drop(&mut self) {
        // Close the channel first so a worker blocked on `send` wakes up and exits.
        self.rx.take();
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}
