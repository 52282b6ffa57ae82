//! `RopeOps` for the CubeCL backends: f32 tokens and tables of the expected shapes run
//! [`super::kernels::rope_rotate`]; anything else (another float type, a head width not a
//! multiple of 4, tables of another shape, indices past u32, the switch off) takes Burn's
//! ops.

use super::kernels::rope_rotate;
use super::ops::{decomposed_backward, decomposed_forward, fused_rope_on, RopeOps};
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{check_binding, flat};

/// `[B, H, N, D]` and the tables' batch count, when the kernel can take them.
fn layout(x: &CubeTensor, cos: &CubeTensor, sin: &CubeTensor) -> Option<[usize; 5]> {
    let dims: [usize; 4] = x.shape().to_vec().try_into().ok()?;
    let [b, h, n, d] = dims;
    let table = cos.shape().to_vec();
    let tb = *table.first()?;
    let tables_fit = table == [tb, 1, n, d] && sin.shape().to_vec() == table;
    let f32s = [x, cos, sin].iter().all(|t| t.dtype() == DType::F32);
    let len = x.shape().num_elements();
    let ok = fused_rope_on()
        && f32s
        && tables_fit
        && (tb == b || tb == 1)
        && d % 4 == 0
        && len > 0
        && u32::try_from(len).is_ok();
    ok.then_some([b, h, n, d, tb])
}

/// One launch of the kernel on `x` (the tokens, or the gradient with `vjp`).
fn launch(
    x: CubeTensor,
    cos: CubeTensor,
    sin: CubeTensor,
    dims: [usize; 5],
    vjp: bool,
) -> CubeTensor {
    let [b, h, n, d, tb] = dims;
    let shape = x.shape();
    let len = b * h * n * d;
    let (x, cos, sin) = (flat(x), flat(cos), flat(sin));
    check_binding(&x, "RoPE output", len);
    let y = empty_device_dtype(
        x.client.clone(),
        x.device.clone(),
        Shape::new([len]),
        DType::F32,
    );
    let dim = CubeDim::new(&x.client, len);
    rope_rotate::launch(
        &x.client,
        calculate_cube_count_elemwise(&x.client, len, dim),
        dim,
        x.clone().into_tensor_arg(),
        cos.into_tensor_arg(),
        sin.into_tensor_arg(),
        y.clone().into_tensor_arg(),
        h as u32,
        n as u32,
        d as u32,
        tb as u32,
        len as u32,
        vjp,
    );
    <CubeBackend as burn::backend::ops::FloatTensorOps<CubeBackend>>::float_reshape(y, shape)
}

impl RopeOps for CubeBackend {
    fn rope_forward(
        x: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        match layout(&x, &cos, &sin) {
            Some(dims) => launch(x, cos, sin, dims, false),
            None => decomposed_forward::<Self>(x, cos, sin),
        }
    }

    fn rope_backward(
        grad: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        match layout(&grad, &cos, &sin) {
            Some(dims) => launch(grad, cos, sin, dims, true),
            None => decomposed_backward::<Self>(grad, cos, sin),
        }
    }
}
