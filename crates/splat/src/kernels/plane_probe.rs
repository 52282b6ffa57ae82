//! Whether a device runs the subgroup (plane) operations of the batched backward, found by
//! running them once. CubeCL reports plane operations only on a card (wgpu's software
//! adapters are left out even where they have subgroups, as Mesa's lavapipe does), so
//! `GradCombine::PlaneSums` asked on a device that reports none needs a real answer: an
//! adapter without subgroups at all (wgpu on OpenGL) rejects the shader at its first launch,
//! and the render's read back would fail. One unit's cube of 32 votes and sums, as
//! `splat_grad::plane_step` does; a device that compiles and runs it has what the kernel
//! needs. Asked once per device and process, and only where the plan needs the answer.

use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeDevice;
use cubecl::prelude::*;
use std::collections::HashMap;
use std::sync::Mutex;

/// Units of the probe's one cube: a whole plane on every device CubeCL runs on.
const PROBE_UNITS: u32 = 32;

/// Unit 0 writes the plane's sum of ones where the plane's vote is true: the plane's width,
/// at least 1, on a device with subgroups. It reads the unit's place in its plane too, as
/// the backward does.
#[cube(launch)]
pub fn plane_probe(out: &mut Tensor<f32>) {
    let mut sum = 0.0f32;
    if plane_any(UNIT_POS == 0 && UNIT_POS_PLANE == 0) {
        sum = plane_sum(1.0f32);
    }
    if UNIT_POS == 0 {
        out[0] = sum;
    }
}

/// The answers so far, by device.
static ANSWERS: Mutex<Option<HashMap<CubeDevice, bool>>> = Mutex::new(None);

/// Whether the device of `like` compiles and runs plane votes and sums (once per device;
/// later calls read the answer). A launch the device rejects leaves only this buffer
/// unwritten, so the device stays usable.
pub fn device_runs_plane_ops(like: &CubeTensor) -> bool {
    let mut answers = ANSWERS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let answers = answers.get_or_insert_with(HashMap::new);
    if let Some(&known) = answers.get(&like.device) {
        return known;
    }
    let answer = probe(like);
    answers.insert(like.device.clone(), answer);
    answer
}

fn probe(like: &CubeTensor) -> bool {
    let out = super::buffers::zeros(like, 1);
    plane_probe::launch(
        &like.client,
        CubeCount::new_single(),
        CubeDim::new_1d(PROBE_UNITS),
        out.clone().into_tensor_arg(),
    );
    super::readback::try_read_f32s(out).is_some_and(|v| v.first().is_some_and(|&s| s >= 1.0))
}
