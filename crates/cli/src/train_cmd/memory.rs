//! The memory lines of `train`: the estimate of `--dry-run` (and whether it fits this
//! machine) and the measured peak beside the estimate after a run.

use crate::backend_choice::BackendChoice;
use envision4d_train::memory::{StepMemory, GIB};

/// The memory limit files of cgroup v2 and v1: a container's share of the machine.
const CGROUP_LIMITS: [&str; 2] = [
    "/sys/fs/cgroup/memory.max",
    "/sys/fs/cgroup/memory/memory.limit_in_bytes",
];

/// The memory this process may use, in bytes, and where the figure comes from: the machine's
/// `MemTotal`, or a container's cgroup limit where that is lower (inside a container
/// `MemTotal` is the host's, and the limit is what the OOM killer enforces).
fn host_memory_bytes() -> Option<(f64, &'static str)> {
    let total = envision4d_model::bench::proc_kb("/proc/meminfo", "MemTotal:")? * 1024.0;
    let limits = CGROUP_LIMITS.map(|p| std::fs::read_to_string(p).ok());
    Some(lower_limit(total, &limits))
}

/// `total` or the lowest numeric limit among `cgroup` file contents (`max`, absent or
/// unparsable entries are no limit; v1 writes a huge number for none).
fn lower_limit(total: f64, cgroup: &[Option<String>]) -> (f64, &'static str) {
    let limit = cgroup
        .iter()
        .flatten()
        .filter_map(|t| t.trim().parse::<f64>().ok())
        .min_by(f64::total_cmp);
    match limit {
        Some(l) if l < total => (l, "cgroup limit"),
        _ => (total, "MemTotal"),
    }
}

/// The process's peak resident memory so far, in bytes.
pub fn peak_rss_bytes() -> Option<f64> {
    let gib = envision4d_model::bench::peak_rss_gib();
    gib.is_finite().then_some(gib * GIB)
}

/// The dry run's memory lines for `m` on `backend`.
pub fn describe_estimate(m: &StepMemory, backend: BackendChoice) -> String {
    let g = |b: f64| format!("{:.2}", b / GIB);
    let teacher = if m.teacher_first > 0.0 {
        format!(" + teacher {}", g(m.teacher_later))
    } else if m.teacher_later > 0.0 {
        format!(
            " + teacher copy {} (after the first update)",
            g(m.teacher_later)
        )
    } else {
        String::new()
    };
    let mut out = format!(
        "memory (estimate; docs/TRAINING.md \"Will it fit?\"): first step {} GiB, later steps \
         {} GiB\n  = parameters {} + LPIPS VGG {} + gradients {} + Adam {}{teacher} + \
         activations {} + process {}",
        g(m.first_step()),
        g(m.later_steps()),
        g(m.parameters),
        g(m.lpips_weights),
        g(m.gradients),
        g(m.optimizer),
        g(m.activations),
        g(m.runtime),
    );
    if backend == BackendChoice::Cpu
        && let Some((total, from)) = host_memory_bytes()
    {
        let verdict = if m.later_steps() <= total {
            "fits"
        } else {
            "does NOT fit"
        };
        out.push_str(&format!(
            "\n  this machine has {} GiB ({from}): {verdict}",
            g(total)
        ));
    }
    let bins = if m.raster_bins > 0.0 {
        format!(
            ", plus {} GiB of tile lists the rasterizer keeps for its backward, dropped by \
             `[run] recompute_raster_bins = true`",
            g(m.raster_bins)
        )
    } else {
        String::new()
    };
    out.push_str(&format!(
        "\n  on a GPU: about {} GiB of device memory (the same tensors without the host \
         process{bins}; the device's allocator adds slack this estimate does not know)",
        g(m.device_tensors())
    ));
    out
}

/// The line printed after a run: measured peak beside the estimate.
pub fn describe_peak(estimated_bytes: f64) -> Option<String> {
    let peak = peak_rss_bytes()?;
    Some(format!(
        "peak host memory {:.2} GiB (memory model: {:.2} GiB)",
        peak / GIB,
        estimated_bytes / GIB
    ))
}

#[cfg(test)]
mod tests {
    use super::lower_limit;

    /// Guards the dry run's verdict inside a container: a cgroup limit below `MemTotal` is
    /// the memory that counts; `max` (v2) and v1's huge "no limit" number are not limits.
    #[test]
    fn a_cgroup_limit_below_memtotal_wins() {
        let total = 24e9;
        let s = |t: &str| Some(t.to_owned());
        assert_eq!(lower_limit(total, &[s("max\n"), None]), (total, "MemTotal"));
        assert_eq!(
            lower_limit(total, &[None, s("9223372036854771712\n")]),
            (total, "MemTotal")
        );
        assert_eq!(
            lower_limit(total, &[s("8589934592\n"), s("garbage")]),
            (8589934592.0, "cgroup limit")
        );
    }
}
