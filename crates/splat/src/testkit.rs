//! Deterministic scenes and cameras for tests and benchmarks (one seeded RNG for all of them).

/// SplitMix64: tiny, seedable, and the same on every platform.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A scene as flat f64 arrays (convert to f32 with [`HostScene::to_f32`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HostScene {
    pub means: Vec<f64>,
    pub quats: Vec<f64>,
    pub scales: Vec<f64>,
    pub opacities: Vec<f64>,
    pub colors: Vec<f64>,
}

/// Ranges for [`random_scene`].
#[derive(Debug, Clone, Copy)]
pub struct SceneSpec {
    /// Half extent of the x/y box the centres are drawn from (world units).
    pub xy: f64,
    /// Depth range of the centres (the default camera looks down +z from the origin).
    pub z: (f64, f64),
    pub scale: (f64, f64),
    pub opacity: (f64, f64),
}

impl Default for SceneSpec {
    fn default() -> Self {
        SceneSpec {
            xy: 1.0,
            z: (2.0, 4.0),
            scale: (0.05, 0.25),
            opacity: (0.5, 0.95),
        }
    }
}

impl HostScene {
    pub fn len(&self) -> usize {
        self.opacities.len()
    }

    pub fn is_empty(&self) -> bool {
        self.opacities.is_empty()
    }

    pub fn push(
        &mut self,
        mean: [f64; 3],
        quat: [f64; 4],
        scale: [f64; 3],
        opacity: f64,
        color: [f64; 3],
    ) {
        self.means.extend_from_slice(&mean);
        self.quats.extend_from_slice(&quat);
        self.scales.extend_from_slice(&scale);
        self.opacities.push(opacity);
        self.colors.extend_from_slice(&color);
    }

    pub fn to_f32(&self) -> [Vec<f32>; 5] {
        let c = |v: &Vec<f64>| v.iter().map(|x| *x as f32).collect::<Vec<f32>>();
        [
            c(&self.means),
            c(&self.quats),
            c(&self.scales),
            c(&self.opacities),
            c(&self.colors),
        ]
    }
}

/// `n` random Gaussians in front of the default camera.
pub fn random_scene(n: usize, seed: u64, spec: SceneSpec) -> HostScene {
    let mut rng = SplitMix64::new(seed);
    let mut s = HostScene::default();
    for _ in 0..n {
        let z = rng.range(spec.z.0, spec.z.1);
        let mean = [
            rng.range(-spec.xy, spec.xy) * z / 3.0,
            rng.range(-spec.xy, spec.xy) * z / 3.0,
            z,
        ];
        let quat = [
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ];
        let scale = [
            rng.range(spec.scale.0, spec.scale.1),
            rng.range(spec.scale.0, spec.scale.1),
            rng.range(spec.scale.0, spec.scale.1),
        ];
        let opacity = rng.range(spec.opacity.0, spec.opacity.1);
        let color = [rng.unit(), rng.unit(), rng.unit()];
        s.push(mean, quat, scale, opacity, color);
    }
    s
}

/// Row-major world-to-camera matrix of a camera at `eye` looking at `target` (OpenCV axes:
/// x right, y down, z forward), with world "up" = -y.
pub fn look_at(eye: [f64; 3], target: [f64; 3]) -> [f64; 16] {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let norm = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let f = norm(sub(target, eye));
    let down = [0.0, 1.0, 0.0];
    let r = norm(cross(down, f));
    let d = cross(f, r);
    let rows = [r, d, f];
    let t: Vec<f64> = rows
        .iter()
        .map(|row| -(row[0] * eye[0] + row[1] * eye[1] + row[2] * eye[2]))
        .collect();
    [
        rows[0][0], rows[0][1], rows[0][2], t[0], rows[1][0], rows[1][1], rows[1][2], t[1],
        rows[2][0], rows[2][1], rows[2][2], t[2], 0.0, 0.0, 0.0, 1.0,
    ]
}

/// Identity world-to-camera matrix (camera at the origin looking down +z).
pub fn identity_view() -> [f64; 16] {
    [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]
}

/// Row-major K with square pixels and the principal point at the image centre.
pub fn intrinsics(width: u32, height: u32, focal: f64) -> [f64; 9] {
    [
        focal,
        0.0,
        width as f64 / 2.0,
        0.0,
        focal,
        height as f64 / 2.0,
        0.0,
        0.0,
        1.0,
    ]
}

/// The GPU device of the parity tests: wgpu by default, or `None` when skipped on purpose
/// (`ENVISION4D_SKIP_WGPU=1`). Panics with what to install when no adapter can be made, so a
/// CI machine without a Vulkan driver fails loudly instead of passing silently.
///
/// `ENVISION4D_TEST_GPU=cuda` gives the first CUDA GPU instead, in a build with this crate's
/// `cuda` feature: the same tests then hold the CUDA kernels (32-lane planes, native float
/// atomics) to the CPU oracle on a GPU machine (`scripts/gpu_device_check.sh`).
pub fn wgpu_test_device() -> Option<burn::tensor::Device> {
    use burn::tensor::{Device, DeviceKind, Tensor};
    use std::panic::{catch_unwind, AssertUnwindSafe};
    match std::env::var("ENVISION4D_TEST_GPU").as_deref() {
        Err(_) | Ok("wgpu") => {}
        Ok("cuda") => return Some(cuda_test_device()),
        Ok(other) => panic!("ENVISION4D_TEST_GPU={other}: not a test GPU (wgpu or cuda)"),
    }
    // No `XDG_RUNTIME_DIR` makes the Vulkan loader warn on stderr, nothing worse; it is the
    // environment's to set (`.ci/run` does), not a test thread's: setting a variable while
    // other test threads run is a data race.
    let probe = catch_unwind(AssertUnwindSafe(|| {
        let device = Device::wgpu(DeviceKind::DefaultDevice);
        let t = Tensor::<1>::from_floats([1.0, 2.0], &device);
        let _ = t.into_data();
        device
    }));
    match probe {
        Ok(d) => Some(d),
        Err(_) if std::env::var("ENVISION4D_SKIP_WGPU").as_deref() == Ok("1") => {
            eprintln!("SKIP wgpu parity: no wgpu adapter and ENVISION4D_SKIP_WGPU=1");
            None
        }
        Err(_) => panic!("no wgpu adapter could be created (install a Vulkan driver, e.g. mesa-vulkan-drivers, or set ENVISION4D_SKIP_WGPU=1)"),
    }
}

/// The first CUDA GPU, touched once so a machine without one fails here, by name.
#[cfg(feature = "cuda")]
fn cuda_test_device() -> burn::tensor::Device {
    let device = burn::tensor::Device::cuda(0);
    let t = burn::tensor::Tensor::<1>::from_floats([1.0, 2.0], &device);
    let _ = t.into_data();
    device
}

#[cfg(not(feature = "cuda"))]
fn cuda_test_device() -> burn::tensor::Device {
    panic!("ENVISION4D_TEST_GPU=cuda needs a build with --features envision4d-splat/cuda")
}
