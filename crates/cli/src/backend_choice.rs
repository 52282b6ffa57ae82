//! `--backend`: which Burn device runs the work, chosen at run time.

use burn::tensor::{Device, DeviceKind};
use clap::ValueEnum;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum BackendChoice {
    /// burn-flex on the CPU (rayon-parallel); the default.
    #[default]
    Cpu,
    /// wgpu on the best available GPU (WGSL kernels; a software Vulkan driver also works).
    Wgpu,
}

impl BackendChoice {
    pub fn device(self) -> Device {
        match self {
            BackendChoice::Cpu => Device::flex(),
            BackendChoice::Wgpu => Device::wgpu(DeviceKind::DefaultDevice),
        }
    }
}
