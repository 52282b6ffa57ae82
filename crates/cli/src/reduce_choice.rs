//! `--grad-reduce`: how `--devices` combine their gradients, decided once the devices have
//! started (docs/TRAINING.md, "Several GPUs: `--devices`").

use crate::backend_choice::is_cuda_spec;
use crate::InputError;
use envision4d_train::parallel::GradientReduce;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ReduceChoice {
    Auto,
    Gather,
    AllReduce,
}

/// The CUDA GPU a `--devices` entry names (`cuda` is GPU 0); `None` for other kinds.
fn cuda_index(spec: &str) -> Option<usize> {
    match spec.trim() {
        "cuda" => Some(0),
        s => s.strip_prefix("cuda:")?.parse().ok(),
    }
}

/// The first GPU `specs` lists twice (`cuda` and `cuda:0` are the same GPU).
fn repeated_gpu(specs: &[String]) -> Option<usize> {
    let mut seen = std::collections::BTreeSet::new();
    specs
        .iter()
        .filter_map(|s| cuda_index(s))
        .find(|&i| !seen.insert(i))
}

/// The gradient reduction for the `--devices` entries `specs` (already started), where
/// `transport(i)` says whether CUDA GPU `i` has NCCL to all-reduce with.
///
/// All-reduce needs every device to be a distinct CUDA GPU with NCCL: on a GPU listed twice
/// the second rank would wait on the first's thread forever (NCCL has no timeout), and
/// without NCCL Burn's all-reduce panics on the device thread. `auto` falls back to gather
/// then, saying why; asking for all-reduce is an input error naming what is missing.
pub fn reduce_for(
    choice: ReduceChoice,
    specs: &[String],
    transport: impl Fn(usize) -> bool,
) -> Result<(GradientReduce, Option<String>), InputError> {
    if choice == ReduceChoice::Gather {
        return Ok((GradientReduce::Gather, None));
    }
    let all_cuda = !specs.is_empty() && specs.iter().all(|s| is_cuda_spec(s));
    let refusal = why_not_all_reduce(specs, all_cuda, transport);
    match (choice, refusal) {
        (_, None) => Ok((GradientReduce::AllReduce, None)),
        (ReduceChoice::AllReduce, Some(why)) => Err(InputError(format!(
            "--grad-reduce all-reduce: {why}; use --grad-reduce gather (or auto)"
        ))),
        // `auto`: other backends gather as a matter of course; CUDA GPUs say why.
        (_, Some(why)) => Ok((
            GradientReduce::Gather,
            all_cuda
                .then(|| format!("--grad-reduce auto: gathering on the first GPU, since {why}")),
        )),
    }
}

/// Why `specs` cannot all-reduce, or `None` when they can: every entry a CUDA GPU, none
/// twice, each with NCCL.
fn why_not_all_reduce(
    specs: &[String],
    all_cuda: bool,
    transport: impl Fn(usize) -> bool,
) -> Option<String> {
    if !all_cuda {
        return Some(format!(
            "Burn's collectives run on CUDA devices only, but --devices is {:?}",
            specs.join(",")
        ));
    }
    if let Some(i) = repeated_gpu(specs) {
        return Some(format!(
            "--devices lists cuda:{i} twice, and NCCL needs one rank per GPU (a GPU twice \
             would wait on itself forever)"
        ));
    }
    let without = specs
        .iter()
        .filter_map(|s| cuda_index(s))
        .find(|&i| !transport(i));
    without.map(|i| {
        format!(
            "cuda:{i} has no NCCL: CubeCL looks for libnccl.so (or libnccl.so.12, .11, ...) \
             on the library path, and NCCL's runtime alone installs libnccl.so.2; link \
             libnccl.so to it or put a folder with that link on LD_LIBRARY_PATH"
        )
    })
}

/// Whether CUDA GPU `index` has NCCL (it has been started by then).
#[cfg(feature = "cuda")]
pub fn nccl(index: usize) -> bool {
    envision4d_splat::cuda_machine::has_device_transport(index)
}

/// Never asked: without the `cuda` feature a CUDA `--devices` entry is refused first.
#[cfg(not(feature = "cuda"))]
pub fn nccl(_index: usize) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specs(list: &str) -> Vec<String> {
        list.split(',').map(str::to_owned).collect()
    }

    /// Guards the all-reduce on distinct CUDA GPUs with NCCL: still chosen by `auto`.
    #[test]
    fn auto_all_reduces_distinct_gpus_with_nccl() {
        let got = reduce_for(ReduceChoice::Auto, &specs("cuda:0,cuda:1"), |_| true).unwrap();
        assert_eq!(got, (GradientReduce::AllReduce, None));
    }

    /// Guards the NCCL hang: one GPU listed twice (`cuda` is `cuda:0`) would make its only
    /// device thread wait on itself, so `auto` gathers and says why, and all-reduce is refused.
    #[test]
    fn one_gpu_twice_never_all_reduces() {
        let (mode, note) = reduce_for(ReduceChoice::Auto, &specs("cuda,cuda:0"), |_| true).unwrap();
        assert_eq!(mode, GradientReduce::Gather);
        assert!(note.unwrap().contains("cuda:0 twice"));
        let err =
            reduce_for(ReduceChoice::AllReduce, &specs("cuda:1, cuda:1"), |_| true).unwrap_err();
        assert!(
            err.0.contains("cuda:1 twice") && err.0.contains("gather"),
            "{}",
            err.0
        );
    }

    /// Guards a run that would stop at its first step on a machine whose NCCL CubeCL cannot
    /// find (`libnccl.so.2` only): `auto` gathers, all-reduce is an error naming the library.
    #[test]
    fn missing_nccl_gathers_or_refuses() {
        let no_second = |i: usize| i != 1;
        let (mode, note) =
            reduce_for(ReduceChoice::Auto, &specs("cuda:0,cuda:1"), no_second).unwrap();
        assert_eq!(mode, GradientReduce::Gather);
        assert!(note.unwrap().contains("cuda:1 has no NCCL"));
        let err =
            reduce_for(ReduceChoice::AllReduce, &specs("cuda:0,cuda:1"), no_second).unwrap_err();
        assert!(err.0.contains("libnccl.so"), "{}", err.0);
    }

    /// Guards the other backends: `auto` gathers quietly, all-reduce is refused (cubecl would
    /// panic mid-step), and gather is always taken as asked.
    #[test]
    fn non_cuda_devices_gather() {
        let never = |_: usize| panic!("NCCL asked about a non-CUDA device");
        let got = reduce_for(ReduceChoice::Auto, &specs("cpu,cpu"), never).unwrap();
        assert_eq!(got, (GradientReduce::Gather, None));
        let got = reduce_for(ReduceChoice::Gather, &specs("cuda:0,cuda:0"), never).unwrap();
        assert_eq!(got, (GradientReduce::Gather, None));
        let err = reduce_for(ReduceChoice::AllReduce, &specs("wgpu,cuda:0"), never).unwrap_err();
        assert!(err.0.contains("CUDA devices only"), "{}", err.0);
        assert!(reduce_for(ReduceChoice::Auto, &[], never).is_ok());
    }
}
