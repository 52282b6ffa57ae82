//! The NaN guard's check as one CubeCL kernel per tensor: every unit tests one element's
//! exponent bits and, for an infinity or a NaN, sets the pass's shared flag.

use cubecl::prelude::*;
use envision4d_splat::kernels::math::finite;

/// Sets `flags[0]` to 1 when some element of `x[..len]` is NaN or infinite; leaves it as it
/// was otherwise. Every writer writes the same value, so concurrent writes agree. The test is
/// on the bit pattern, which no fast-math assumption of a shader compiler can fold away.
#[cube(launch)]
// Nested, not `&&`: the bound must be tested before `x[i]` is read, whatever the kernel
// language does with a combined condition.
#[allow(clippy::collapsible_if)]
pub fn flag_non_finite(x: &Tensor<f32>, flags: &mut Tensor<f32>, len: u32) {
    let i = ABSOLUTE_POS;
    if i < len as usize {
        if !finite(x[i]) {
            flags[0] = 1.0f32;
        }
    }
}
