//! The memory lines of `train`: the estimate of `--dry-run` (and whether it fits this
//! machine) and the measured peak beside the estimate after a run.

use crate::backend_choice::BackendChoice;
use envision4d_train::memory::{StepMemory, GIB};

/// This machine's memory (`MemTotal`), in bytes.
fn host_memory_bytes() -> Option<f64> {
    envision4d_model::bench::proc_kb("/proc/meminfo", "MemTotal:").map(|kb| kb * 1024.0)
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
        && let Some(total) = host_memory_bytes()
    {
        let verdict = if m.later_steps() <= total {
            "fits"
        } else {
            "does NOT fit"
        };
        out.push_str(&format!("\n  this machine has {} GiB: {verdict}", g(total)));
    }
    out.push_str(&format!(
        "\n  on a GPU: about {} GiB of device memory (the same tensors without the host \
         process; the device's allocator adds slack this estimate does not know)",
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
