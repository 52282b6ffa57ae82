//! Which compositing kernels a render runs on a device: the GPU settings of
//! [`RasterConfig`] (their `Auto` values) resolved against what CubeCL reports of the
//! device. The launches and every report of them (the bench's rows, `kernel_plan`) read
//! this one decision, so they cannot disagree.

use crate::config::{GradAccumulation, GradCombine, RasterConfig, TileSchedule};
use burn_cubecl::tensor::CubeTensor;
use cubecl::features::{AtomicUsage, Plane};
use cubecl::ir::{ElemType, FloatKind, Type};

use super::plane_probe::device_runs_plane_ops;

/// The kernels of a render on one device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KernelPlan {
    /// The tiles are walked in shared-memory batches ([`TileSchedule::SharedBatches`]), not
    /// per pixel.
    pub shared_batches: bool,
    /// The backward sums a splat's gradient over each plane before adding it
    /// ([`GradCombine::PlaneSums`]), not once per pixel.
    pub plane_sums: bool,
    /// Plane sums were asked for (`GradCombine::PlaneSums`) but the device runs no subgroup
    /// operations, so the backward adds per pixel instead (the results agree; only speed
    /// differs) and the plan says so.
    pub plane_sums_refused: bool,
    /// With plane sums, a plane barrier before each vote and sum (where the device has
    /// plane barriers: CUDA).
    pub plane_sync: bool,
    /// The backward adds with native float atomics, not a compare-and-swap loop.
    pub native_atomics: bool,
}

impl KernelPlan {
    /// The plan of a render with `cfg` on the device of `like`.
    pub fn of(like: &CubeTensor, cfg: &RasterConfig) -> Self {
        let props = like.client.properties();
        let shared_batches = match cfg.tile_schedule {
            TileSchedule::SharedBatches => true,
            TileSchedule::PerPixel => false,
            // No physical device is reported exactly for a software adapter (wgpu's
            // `DeviceType::Cpu`, e.g. lavapipe).
            TileSchedule::Auto => props.identity.physical.is_some(),
        };
        let reported = props.features.plane.contains(Plane::Ops);
        let plane_sums = plane_sums(cfg.grad_combine, shared_batches, reported, || {
            device_runs_plane_ops(like)
        });
        let plane_sums_refused =
            !plane_sums && shared_batches && cfg.grad_combine == GradCombine::PlaneSums;
        let float_add = props
            .atomic_type_usage(Type::atomic(ElemType::Float(FloatKind::F32)))
            .contains(AtomicUsage::Add);
        KernelPlan {
            shared_batches,
            plane_sums,
            plane_sums_refused,
            plane_sync: plane_sums && props.features.plane.contains(Plane::Sync),
            native_atomics: float_add && cfg.grad_accumulation != GradAccumulation::CompareAndSwap,
        }
    }

    /// `shared batches, plane sums, native atomics`: the plan in words, for reports.
    pub fn describe(&self) -> String {
        let pick = |yes: bool, a: &str, b: &str| if yes { a } else { b }.to_owned();
        [
            pick(self.shared_batches, "shared batches", "per pixel"),
            match (self.plane_sums, self.plane_sums_refused) {
                (true, _) => "plane sums".to_owned(),
                (false, false) => "per-pixel adds".to_owned(),
                (false, true) => "per-pixel adds (plane sums asked; no subgroups)".to_owned(),
            },
            pick(self.native_atomics, "native atomics", "CAS atomics"),
        ]
        .join(", ")
    }
}

/// Whether the batched backward sums each splat's gradient over a plane before adding it
/// ([`GradCombine`]): `Auto` where CubeCL reports plane operations, `PlaneSums` where it
/// reports them or the device runs them all the same (`runs`, asked only then: a software
/// adapter with subgroups, such as lavapipe, reports none), never with the per-pixel
/// schedule, whose units walk their lists apart.
fn plane_sums(
    combine: GradCombine,
    batched: bool,
    reported: bool,
    runs: impl FnOnce() -> bool,
) -> bool {
    batched
        && match combine {
            GradCombine::PlaneSums => reported || runs(),
            GradCombine::PerPixel => false,
            GradCombine::Auto => reported,
        }
}

#[cfg(test)]
mod tests {
    use super::plane_sums;
    use crate::config::GradCombine::{Auto, PerPixel, PlaneSums};

    /// Guards the gradient-add choice: plane sums never under the per-pixel schedule (its
    /// units are not at the same splat, so a plane sum would mix splats), `Auto` exactly
    /// where the device reports plane operations, the explicit modes as asked; a forced
    /// `PlaneSums` on a device that reports none and cannot run them (wgpu on OpenGL, whose
    /// shader then failed at launch) falls back to per-pixel adds, and the device is asked
    /// only where its report leaves the answer open.
    #[test]
    fn plane_sums_only_with_shared_batches() {
        let never = || -> bool { panic!("the device was probed where the plan needs no probe") };
        for combine in [Auto, PerPixel, PlaneSums] {
            for reported in [false, true] {
                assert!(
                    !plane_sums(combine, false, reported, never),
                    "{combine:?}, per pixel"
                );
            }
        }
        assert!(plane_sums(Auto, true, true, never));
        assert!(!plane_sums(Auto, true, false, never));
        assert!(plane_sums(PlaneSums, true, true, never));
        assert!(plane_sums(PlaneSums, true, false, || true));
        assert!(!plane_sums(PlaneSums, true, false, || false));
        assert!(!plane_sums(PerPixel, true, true, never));
    }
}
