//! One splat's gradient at one pixel of the compositing backward, and the two ways it reaches
//! the per-Gaussian lanes `v_proj [N, RECORD_LANES]`: every unit adds its own
//! ([`reverse_step()`], both backward kernels), or the units of a plane (warp, subgroup) sum
//! theirs first and one unit adds the sums ([`plane_step()`], gsplat's warp sum).
//!
//! Why the plane sum: a splat covering a whole 16x16 tile gets its ten lanes added by all
//! 256 units, to the same ten addresses; a GPU serialises atomics to one address, so the
//! backward waits on them. Summed per plane (32 units on NVIDIA), the adds fall 32-fold.
//! Lane order: mean2d (x, y), conic (q00, q01, q11), opacity, colour (r, g, b), depth.

use super::project_forward::RECORD_LANES;
use super::rasterize_forward::Eval;
use cubecl::prelude::*;

/// How a gradient lane is added to the shared buffer: a native float atomic where the device
/// has one, otherwise a compare-and-swap loop on the u32 bit pattern.
#[cube]
pub trait GradAdd: Send + Sync + 'static {
    type Proxy: Numeric;
    fn add(slot: &mut Atomic<Self::Proxy>, value: f32);
}

/// Native `Atomic<f32>::fetch_add`.
#[derive(CubeType)]
pub struct NativeAdd;

/// CAS fallback for devices without float atomics.
#[derive(CubeType)]
pub struct CasAdd;

#[cube]
impl GradAdd for NativeAdd {
    type Proxy = f32;

    fn add(slot: &mut Atomic<f32>, value: f32) {
        slot.fetch_add(value);
    }
}

#[cube]
impl GradAdd for CasAdd {
    type Proxy = u32;

    fn add(slot: &mut Atomic<u32>, value: f32) {
        // Adding zero changes nothing; skipping it saves a round trip.
        if value != 0.0f32 {
            let mut bits = slot.load();
            loop {
                let seen = bits;
                let new = (f32::from_bits(seen) + value).to_bits();
                bits = slot.compare_exchange_weak(seen, new);
                if bits == seen {
                    break;
                }
            }
        }
    }
}

/// A pixel's upstream gradient, one per output channel, and its final transmittance.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Upstream {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
    pub a: f32,
    pub t_final: f32,
}

/// The reverse pass's running state at a pixel: the transmittance in front of the next
/// splat, and the colour and depth composited behind it.
#[derive(CubeType)]
pub struct Behind {
    pub t: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
}

#[cube]
impl Behind {
    /// Nothing behind yet, transmittance `t_final`: the state past the last composited splat.
    pub fn new(t_final: f32) -> Behind {
        Behind {
            t: t_final,
            r: 0.0f32,
            g: 0.0f32,
            b: 0.0f32,
            d: 0.0f32,
        }
    }
}

/// The record lanes the gradient reads besides the evaluation: conic, opacity, colour, depth.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Shade {
    pub q00: f32,
    pub q01: f32,
    pub q11: f32,
    pub opacity: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
}

/// The [`Shade`] of the batched record at `s`.
#[cube]
pub fn shade_of_batch(batch: &[f32], s: usize) -> Shade {
    Shade {
        q00: batch[s + 2],
        q01: batch[s + 3],
        q11: batch[s + 4],
        opacity: batch[s + 5],
        r: batch[s + 6],
        g: batch[s + 7],
        b: batch[s + 8],
        d: batch[s + 9],
    }
}

/// The [`Shade`] of the record at `rec` in global memory.
#[cube]
pub fn shade_of_record(records: &Tensor<f32>, rec: usize) -> Shade {
    Shade {
        q00: records[rec + 2],
        q01: records[rec + 3],
        q11: records[rec + 4],
        opacity: records[rec + 5],
        r: records[rec + 6],
        g: records[rec + 7],
        b: records[rec + 8],
        d: records[rec + 9],
    }
}

/// One composited splat's gradient at one pixel, in record-lane order. `geometry` is false
/// where the alpha clamp was active: alpha then depends on neither opacity nor the 2D shape,
/// and those six lanes are zero.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct SplatGrad {
    pub mean_x: f32,
    pub mean_y: f32,
    pub q00: f32,
    pub q01: f32,
    pub q11: f32,
    pub opacity: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
    pub geometry: bool,
}

#[cube]
impl SplatGrad {
    /// The gradient of a pixel that did not composite the splat.
    pub fn zero() -> SplatGrad {
        SplatGrad {
            mean_x: 0.0f32,
            mean_y: 0.0f32,
            q00: 0.0f32,
            q01: 0.0f32,
            q11: 0.0f32,
            opacity: 0.0f32,
            r: 0.0f32,
            g: 0.0f32,
            b: 0.0f32,
            d: 0.0f32,
            geometry: false,
        }
    }
}

/// Writes into `grad` (zero on entry) the gradient of the splat composited with evaluation
/// `e` at a pixel whose reverse pass stands at `state`, which then steps in front of the
/// splat. Every kernel and both ways of adding come here, so the formulas cannot diverge.
#[cube]
pub fn splat_grad(
    e: Eval,
    sh: Shade,
    up: Upstream,
    state: &mut Behind,
    alpha_max: f32,
    grad: &mut SplatGrad,
) {
    let one_minus = 1.0f32 - e.alpha;
    let t_i = state.t / one_minus;
    let fac = e.alpha * t_i;
    grad.r = fac * up.r;
    grad.g = fac * up.g;
    grad.b = fac * up.b;
    grad.d = fac * up.d;
    let mut v_alpha = up.a * up.t_final / one_minus;
    v_alpha += up.r * (sh.r * t_i - state.r / one_minus);
    v_alpha += up.g * (sh.g * t_i - state.g / one_minus);
    v_alpha += up.b * (sh.b * t_i - state.b / one_minus);
    v_alpha += up.d * (sh.d * t_i - state.d / one_minus);
    // When the clamp is active alpha no longer depends on opacity or geometry.
    if sh.opacity * e.vis <= alpha_max {
        let v_sigma = (0.0f32 - sh.opacity) * e.vis * v_alpha;
        grad.mean_x = v_sigma * (sh.q00 * e.dx + sh.q01 * e.dy);
        grad.mean_y = v_sigma * (sh.q01 * e.dx + sh.q11 * e.dy);
        grad.q00 = 0.5f32 * e.dx * e.dx * v_sigma;
        grad.q01 = e.dx * e.dy * v_sigma;
        grad.q11 = 0.5f32 * e.dy * e.dy * v_sigma;
        grad.opacity = e.vis * v_alpha;
        grad.geometry = true;
    }
    state.r += sh.r * fac;
    state.g += sh.g * fac;
    state.b += sh.b * fac;
    state.d += sh.d * fac;
    state.t = t_i;
}

/// One splat of a pixel's reverse pass, added by the pixel's own unit: the colour and depth
/// lanes always, the geometry lanes unless the clamp was active.
#[cube]
pub fn reverse_step<A: GradAdd>(
    v_proj: &mut Tensor<Atomic<A::Proxy>>,
    id: usize,
    e: Eval,
    sh: Shade,
    up: Upstream,
    state: &mut Behind,
    alpha_max: f32,
) {
    let mut grad = SplatGrad::zero();
    splat_grad(e, sh, up, state, alpha_max, &mut grad);
    let lane = id * RECORD_LANES;
    A::add(&mut v_proj[lane + 6], grad.r);
    A::add(&mut v_proj[lane + 7], grad.g);
    A::add(&mut v_proj[lane + 8], grad.b);
    A::add(&mut v_proj[lane + 9], grad.d);
    if grad.geometry {
        A::add(&mut v_proj[lane], grad.mean_x);
        A::add(&mut v_proj[lane + 1], grad.mean_y);
        A::add(&mut v_proj[lane + 2], grad.q00);
        A::add(&mut v_proj[lane + 3], grad.q01);
        A::add(&mut v_proj[lane + 4], grad.q11);
        A::add(&mut v_proj[lane + 5], grad.opacity);
    }
}

/// Adds `sum` to a lane unless it is zero: a plane sum is zero wherever no unit of the plane
/// composited the splat or the clamp held for all of them, and an add of zero changes nothing.
#[cube]
fn add_nonzero<A: GradAdd>(slot: &mut Atomic<A::Proxy>, sum: f32) {
    if sum != 0.0f32 {
        A::add(slot, sum);
    }
}

/// One splat of the reverse pass for a whole plane: `composited` says whether this unit's
/// pixel composited it (else its part is zero and `state` stays). Must be reached by every
/// unit of the plane (uniform control flow); the planes where no unit composited the splat
/// skip the sums. The plane's first unit adds the ten sums.
///
/// `converge` (where the device has a plane barrier: CUDA) re-joins the plane before the
/// vote and before the sums. CubeCL's CUDA plane operations act on the lanes running at that
/// moment (`__activemask()`), and after a branch (this unit's gradient, the first unit's
/// adds of the splat before) CUDA does not promise the warp has re-joined: a vote or a sum
/// over part of it would be wrong. `__syncwarp()` costs a few cycles. WGSL has no such
/// barrier; its subgroup operations are defined for the whole subgroup.
#[cube]
#[allow(clippy::too_many_arguments)]
pub fn plane_step<A: GradAdd>(
    v_proj: &mut Tensor<Atomic<A::Proxy>>,
    id: usize,
    composited: bool,
    e: Eval,
    sh: Shade,
    up: Upstream,
    state: &mut Behind,
    alpha_max: f32,
    #[comptime] converge: bool,
) {
    if converge {
        sync_plane();
    }
    if plane_any(composited) {
        let mut grad = SplatGrad::zero();
        if composited {
            splat_grad(e, sh, up, state, alpha_max, &mut grad);
        }
        if converge {
            sync_plane();
        }
        // Every unit of the plane takes part in the sums; the first adds them.
        let mean_x = plane_sum(grad.mean_x);
        let mean_y = plane_sum(grad.mean_y);
        let q00 = plane_sum(grad.q00);
        let q01 = plane_sum(grad.q01);
        let q11 = plane_sum(grad.q11);
        let opacity = plane_sum(grad.opacity);
        let r = plane_sum(grad.r);
        let g = plane_sum(grad.g);
        let b = plane_sum(grad.b);
        let d = plane_sum(grad.d);
        if UNIT_POS_PLANE == 0 {
            let lane = id * RECORD_LANES;
            add_nonzero::<A>(&mut v_proj[lane], mean_x);
            add_nonzero::<A>(&mut v_proj[lane + 1], mean_y);
            add_nonzero::<A>(&mut v_proj[lane + 2], q00);
            add_nonzero::<A>(&mut v_proj[lane + 3], q01);
            add_nonzero::<A>(&mut v_proj[lane + 4], q11);
            add_nonzero::<A>(&mut v_proj[lane + 5], opacity);
            add_nonzero::<A>(&mut v_proj[lane + 6], r);
            add_nonzero::<A>(&mut v_proj[lane + 7], g);
            add_nonzero::<A>(&mut v_proj[lane + 8], b);
            add_nonzero::<A>(&mut v_proj[lane + 9], d);
        }
    }
}
