//! Device time per kernel of one pass, from CubeCL's launch observer: every launch the pass
//! issues is timed without waiting (`TimingRequest::Deferred`: on CUDA and wgpu with
//! timestamp queries, two events in the stream), and the measurements are read once the
//! device is done, so the kernels still run back to back as in the timed runs. Where a
//! backend has no device timer (lavapipe), CubeCL times each launch on the host around a
//! blocking submit, so the kernels run one at a time; the table says which.

use burn::tensor::Device;
use cubecl::config::{type_name_format, TypeNameFormatLevel};
use cubecl::logging::{
    LaunchObservation, LaunchObserver, ProfileDuration, TimingMethod, TimingRequest,
};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// One kernel's launches in a pass: how many, and their summed device time.
pub struct KernelTime {
    pub name: String,
    pub launches: usize,
    pub total_ms: f64,
}

/// The launches of the observed pass, measurements unread.
#[derive(Default)]
struct Pending(Mutex<Vec<(&'static str, ProfileDuration)>>);

impl LaunchObserver for Pending {
    fn launched(&self, _kernel: &'static str) {}

    fn timing(&self) -> TimingRequest {
        TimingRequest::Deferred
    }

    fn profiled(&self, kernel: &'static str, profile: ProfileDuration) {
        self.0.lock().unwrap().push((kernel, profile));
    }
}

/// Runs `pass` once under the observer and returns its kernels, slowest first, with the
/// timing method of the measurements (`None` when nothing was launched).
pub fn per_kernel(device: &Device, pass: impl FnOnce()) -> (Vec<KernelTime>, Option<String>) {
    let pending = Arc::new(Pending::default());
    let watching = LaunchObservation::new(pending.clone());
    pass();
    device
        .sync()
        .expect("the device failed during the observed pass");
    drop(watching);
    let launches = std::mem::take(&mut *pending.0.lock().unwrap());
    let mut method = None;
    let mut sums: BTreeMap<String, (usize, f64)> = BTreeMap::new();
    for (kernel, profile) in launches {
        method.get_or_insert_with(|| match profile.timing_method() {
            TimingMethod::Device => "device timestamps".to_owned(),
            TimingMethod::System => "host clock around each blocking launch".to_owned(),
        });
        // A measurement the device could not take is left out, not counted as zero.
        let Some(ticks) = cubecl::future::block_on(profile.resolve()) else {
            continue;
        };
        // CubeCL's balanced form writes generics as "Name | Arg"; a table cell wants "Name<Arg>".
        let balanced = type_name_format(kernel, TypeNameFormatLevel::Balanced);
        let name = match balanced.split_once(" | ") {
            Some((base, args)) => format!("{base}<{}>", args.replace(" | ", ", ")),
            None => balanced,
        };
        let entry = sums.entry(name).or_default();
        entry.0 += 1;
        entry.1 += ticks.duration().as_secs_f64() * 1e3;
    }
    let mut rows: Vec<KernelTime> = sums
        .into_iter()
        .map(|(name, (launches, total_ms))| KernelTime {
            name,
            launches,
            total_ms,
        })
        .collect();
    rows.sort_by(|a, b| b.total_ms.total_cmp(&a.total_ms));
    (rows, method)
}
