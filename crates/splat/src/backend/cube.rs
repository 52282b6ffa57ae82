//! `SplatOps` for the CubeCL backends (wgpu; CUDA where built).

use super::SplatOps;
use burn_cubecl::CubeBackend;

impl SplatOps for CubeBackend {}
