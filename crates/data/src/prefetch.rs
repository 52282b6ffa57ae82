//! Prefetch: a worker thread prepares the next items while the caller computes.
//!
//! [`Prefetch`] is the general form: any sequence of work items, each turned into a value
//! (decoded, converted, augmented) on the worker, delivered in order. [`Prefetcher`] is the
//! dataset form that skips clips that fail to decode.

use crate::clip::Clip;
use crate::dataset::ClipDataset;
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;

/// The values of `f` over `items`, computed `depth` ahead on a worker thread and delivered
/// in the order of `items` (errors included, as values: the consumer decides).
pub struct Prefetch<T> {
    rx: Option<Receiver<T>>,
    worker: Option<JoinHandle<()>>,
}

impl<T: Send + 'static> Prefetch<T> {
    pub fn new<I, F>(items: I, depth: usize, mut f: F) -> Prefetch<T>
    where
        I: IntoIterator + Send + 'static,
        I::IntoIter: Send,
        F: FnMut(I::Item) -> Option<T> + Send + 'static,
    {
        // depth 0 would make a rendezvous channel: still correct, but no overlap.
        let (tx, rx) = sync_channel(depth.max(1));
        let worker = std::thread::spawn(move || {
            for item in items {
                if let Some(v) = f(item)
                    && tx.send(v).is_err()
                {
                    return; // the consumer went away
                }
            }
        });
        Prefetch {
            rx: Some(rx),
            worker: Some(worker),
        }
    }
}

impl<T> Iterator for Prefetch<T> {
    type Item = T;
    fn next(&mut self) -> Option<T> {
        self.rx.as_ref()?.recv().ok()
    }
}

impl<T> Drop for Prefetch<T> {
    fn drop(&mut self) {
        // Close the channel first so a worker blocked on `send` wakes up and exits.
        self.rx.take();
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// Iterates the clips of `order`, decoded `depth` ahead on a worker thread. Bad clips are
/// skipped (the dataset warns and counts them).
pub struct Prefetcher(Prefetch<Arc<Clip>>);

impl Prefetcher {
    pub fn new(dataset: Arc<ClipDataset>, order: Vec<usize>, depth: usize) -> Prefetcher {
        Prefetcher(Prefetch::new(order, depth, move |i| dataset.get(i)))
    }
}

impl Iterator for Prefetcher {
    type Item = Arc<Clip>;
    fn next(&mut self) -> Option<Arc<Clip>> {
        self.0.next()
    }
}
