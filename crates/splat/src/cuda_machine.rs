//! What a CUDA machine offers, asked before any work starts so that a missing piece is an
//! error naming it rather than a panic, a hang or a failed read halfway through a run:
//! how many GPUs the driver reports, whether libdevice (NVIDIA's math bitcode, which the
//! kernels' `exp` and `ln` link against) is where CubeCL looks for it, and whether the
//! runtime moves data between GPUs itself (NCCL, which Burn's all-reduce needs).
//!
//! Built with the `cuda` feature only; the callers gate on it too.

use std::path::{Path, PathBuf};

/// Where CubeCL's LLVM route looks for the CUDA toolkit when `CUDA_PATH` is unset (its
/// `nvptx::libdevice` lookup, in its order).
const CUDA_ROOTS: [&str; 4] = ["/usr/local/cuda", "/opt/cuda", "/usr/lib/cuda", "/usr"];

/// libdevice's path under a toolkit root.
const LIBDEVICE: [&str; 3] = ["nvvm", "libdevice", "libdevice.10.bc"];

/// Why a CUDA device cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CudaMachineError {
    #[error("the NVIDIA driver (libcuda.so.1) is not on the library path or reports no GPU")]
    NoDriver,
    #[error("there is no cuda:{index}: the driver reports {available} GPU(s), cuda:0 to cuda:{last}", last = available - 1)]
    NoSuchDevice { index: usize, available: usize },
    #[error(
        "libdevice.10.bc was not found at {looked}: CubeCL links the kernels' math functions \
         from it; set CUDA_PATH to a folder holding nvvm/libdevice/libdevice.10.bc (a CUDA \
         toolkit, or the nvidia-cuda-nvcc wheel's cuda_nvcc folder)"
    )]
    NoLibdevice { looked: String },
}

/// Checks that the driver reports GPU `index`, without starting it (asking loads the driver
/// library only if it is present, so a machine without one gets an error, not a panic).
pub fn check_device(index: usize) -> Result<(), CudaMachineError> {
    match cubecl::Device::cuda(index) {
        Ok(_) => Ok(()),
        Err(cubecl::device::DeviceUnavailable::NoSuchDevice { available, .. }) if available > 0 => {
            Err(CudaMachineError::NoSuchDevice { index, available })
        }
        Err(_) => Err(CudaMachineError::NoDriver),
    }
}

/// The libdevice file CubeCL's LLVM route will link, found as CubeCL finds it: the root is
/// `CUDA_PATH` when set, else the first standard root with an `nvvm/libdevice` folder, and
/// the file must be in that root (a later root's copy is never read).
pub fn check_libdevice() -> Result<PathBuf, CudaMachineError> {
    let folder = |root: &Path| root.join(LIBDEVICE[0]).join(LIBDEVICE[1]);
    let root = match std::env::var_os("CUDA_PATH") {
        Some(root) => Some(PathBuf::from(root)),
        None => CUDA_ROOTS
            .iter()
            .map(PathBuf::from)
            .find(|r| folder(r).is_dir()),
    };
    let looked = match &root {
        Some(root) => folder(root).join(LIBDEVICE[2]),
        None => {
            return Err(CudaMachineError::NoLibdevice {
                looked: format!(
                    "CUDA_PATH (unset) and {}",
                    CUDA_ROOTS
                        .iter()
                        .map(|r| folder(Path::new(r)).display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })
        }
    };
    if looked.is_file() {
        Ok(looked)
    } else {
        Err(CudaMachineError::NoLibdevice {
            looked: looked.display().to_string(),
        })
    }
}

/// Whether CUDA device `index`'s runtime moves data between GPUs itself: true when it
/// found NCCL (by the names `libnccl.so`, `libnccl.so.12`, ...; not `libnccl.so.2`, NCCL's
/// own soname, so a runtime-only install needs a `libnccl.so` link). Without it Burn's
/// all-reduce panics on the device thread; `to_device` still copies through the host.
/// Starts the device (call after it passed [`check_device`]).
pub fn has_device_transport(index: usize) -> bool {
    cubecl::Device::cuda(index)
        .map(|d| d.client().has_device_transport())
        .unwrap_or(false)
}
