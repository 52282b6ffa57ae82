//! `ClipDataset`: a scanned root, clip loading with a small LRU cache, and bad clips
//! skipped with a warning and counted (never silently).

use crate::clip::{Clip, ClipSpec};
use crate::error::{DataError, Result};
use crate::layout::{folder, load_clip, nuscenes, synth, waymo, ClipEntry, Scan};
use crate::resize::Fit;
use crate::split::{assign, Split, SplitRatios};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Which on-disk layout the root has.
#[derive(Debug, Clone, PartialEq)]
pub enum Layout {
    /// Folder(s) of frames; clips every `stride` frames.
    Folder { stride: usize },
    /// `<root>/<split>/<scene>/images/<t>_<cam>.png` (official loader / STORM).
    Waymo(waymo::WaymoConfig),
    /// The official nuScenes tree: `samples/`, `<version>/*.json`, official scene splits.
    NuScenes(nuscenes::NuScenesConfig),
    /// Our synthetic clips; windows every `stride` frames.
    Synth { stride: usize },
}

#[derive(Debug, Clone, PartialEq)]
pub struct DatasetConfig {
    pub layout: Layout,
    pub spec: ClipSpec,
    pub fit: Fit,
    /// Decoded clips kept in memory (0 = no cache).
    pub cache_clips: usize,
}

impl Default for DatasetConfig {
    fn default() -> Self {
        DatasetConfig {
            layout: Layout::Folder { stride: 1 },
            spec: ClipSpec::default(),
            fit: Fit::default(),
            cache_clips: 8,
        }
    }
}

/// Warnings about skipped sources/clips, kept so callers can report the count.
#[derive(Debug, Default)]
pub struct SkipLog {
    messages: Mutex<Vec<String>>,
}

impl SkipLog {
    pub fn warn(&self, msg: String) {
        eprintln!("warning: skipping {msg}");
        if let Ok(mut m) = self.messages.lock() {
            m.push(msg);
        }
    }
    pub fn count(&self) -> usize {
        self.messages.lock().map(|m| m.len()).unwrap_or(0)
    }
    pub fn messages(&self) -> Vec<String> {
        self.messages.lock().map(|m| m.clone()).unwrap_or_default()
    }
}

/// Least-recently-used cache of decoded clips by entry index.
#[derive(Debug, Default)]
struct ClipCache {
    capacity: usize,
    items: VecDeque<(usize, Arc<Clip>)>,
}

impl ClipCache {
    fn get(&mut self, index: usize) -> Option<Arc<Clip>> {
        let pos = self.items.iter().position(|(i, _)| *i == index)?;
        let item = self.items.remove(pos)?;
        let clip = item.1.clone();
        self.items.push_back(item);
        Some(clip)
    }
    fn put(&mut self, index: usize, clip: Arc<Clip>) {
        if self.capacity == 0 {
            return;
        }
        if self.items.len() >= self.capacity {
            self.items.pop_front();
        }
        self.items.push_back((index, clip));
    }
}

#[derive(Debug)]
pub struct ClipDataset {
    root: PathBuf,
    entries: Vec<ClipEntry>,
    config: DatasetConfig,
    cache: Mutex<ClipCache>,
    skips: SkipLog,
    /// Entries that failed to load once; not retried (decoding them again would fail again).
    failed: Mutex<Vec<bool>>,
}

impl ClipDataset {
    /// Scans `root`. Sources that cannot give a clip are skipped with a warning; a root that
    /// gives no clip at all is an error.
    pub fn open(root: &Path, config: DatasetConfig) -> Result<ClipDataset> {
        config.spec.validate()?;
        config.fit.validate()?;
        let Scan { entries, skipped } = match &config.layout {
            Layout::Folder { stride } => folder::scan(root, &config.spec, *stride)?,
            Layout::Waymo(cfg) => waymo::scan(root, &config.spec, cfg)?,
            Layout::NuScenes(cfg) => nuscenes::scan(root, &config.spec, cfg)?,
            Layout::Synth { stride } => synth::scan(root, &config.spec, *stride)?,
        };
        let skips = SkipLog::default();
        for m in skipped {
            skips.warn(m);
        }
        if entries.is_empty() {
            return Err(DataError::NoClips {
                root: root.to_path_buf(),
                skipped: skips.count(),
            });
        }
        let n = entries.len();
        Ok(ClipDataset {
            root: root.to_path_buf(),
            entries,
            cache: Mutex::new(ClipCache {
                capacity: config.cache_clips,
                items: VecDeque::new(),
            }),
            config,
            skips,
            failed: Mutex::new(vec![false; n]),
        })
    }
    pub fn root(&self) -> &Path {
        &self.root
    }
    pub fn len(&self) -> usize {
        self.entries.len()
    }
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    pub fn entries(&self) -> &[ClipEntry] {
        &self.entries
    }
    pub fn config(&self) -> &DatasetConfig {
        &self.config
    }
    /// Loads clip `index` (from the cache if present), returning the error if it is bad.
    pub fn load(&self, index: usize) -> Result<Arc<Clip>> {
        let entry = self.entries.get(index).ok_or_else(|| {
            DataError::config("clip index", index, format!("dataset has {}", self.len()))
        })?;
        if let Some(clip) = self.cache.lock().ok().and_then(|mut c| c.get(index)) {
            return Ok(clip);
        }
        let clip = Arc::new(load_clip(entry, &self.config.spec, &self.config.fit)?);
        if let Ok(mut c) = self.cache.lock() {
            c.put(index, clip.clone());
        }
        Ok(clip)
    }
    /// Loads clip `index`; a bad clip is skipped with a warning and counted (once).
    pub fn get(&self, index: usize) -> Option<Arc<Clip>> {
        if self
            .failed
            .lock()
            .ok()
            .is_some_and(|f| f.get(index) == Some(&true))
        {
            return None;
        }
        match self.load(index) {
            Ok(clip) => Some(clip),
            Err(e) => {
                if let Ok(mut f) = self.failed.lock()
                    && let Some(slot) = f.get_mut(index)
                {
                    *slot = true;
                }
                let id = self.entries.get(index).map_or("?", |e| e.id.as_str());
                self.skips.warn(format!("clip {id}: {e}"));
                None
            }
        }
    }
    /// Number of skipped sources and clips so far.
    pub fn skipped(&self) -> usize {
        self.skips.count()
    }
    pub fn skip_messages(&self) -> Vec<String> {
        self.skips.messages()
    }
    /// Indices of the entries in `split`, in dataset order.
    pub fn split_indices(&self, split: Split, seed: u64, ratios: &SplitRatios) -> Vec<usize> {
        (0..self.len())
            .filter(|&i| assign(&self.entries[i].group, seed, ratios) == split)
            .collect()
    }
}
