//! `SplatOps` for the CubeCL backends (wgpu; CUDA where built): f32 tensors run the CubeCL
//! kernels of [`crate::kernels`]; other float types (f64 oracle runs, half precision) take the
//! host path, which is exact but slow.

use super::{host, SplatGrads, SplatOps};
use crate::config::RasterConfig;
use crate::kernels::launch::{self, Inputs};
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::CubeBackend;

impl SplatOps for CubeBackend {
    fn splat_forward(
        means: FloatTensor<Self>,
        quats: FloatTensor<Self>,
        scales: FloatTensor<Self>,
        opacities: FloatTensor<Self>,
        colors: FloatTensor<Self>,
        viewmats: FloatTensor<Self>,
        ks: FloatTensor<Self>,
        width: u32,
        height: u32,
        config: RasterConfig,
    ) -> (FloatTensor<Self>, IntTensor<Self>, IntTensor<Self>) {
        let inputs = [means, quats, scales, opacities, colors, viewmats, ks];
        if inputs.iter().any(|t| t.dtype() != DType::F32) {
            return host::forward::<Self>(inputs, width, height, &config);
        }
        launch::forward(&Inputs::new(inputs, width, height), &config)
    }

    fn splat_backward(
        means: FloatTensor<Self>,
        quats: FloatTensor<Self>,
        scales: FloatTensor<Self>,
        opacities: FloatTensor<Self>,
        colors: FloatTensor<Self>,
        viewmats: FloatTensor<Self>,
        ks: FloatTensor<Self>,
        grad_image: FloatTensor<Self>,
        width: u32,
        height: u32,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        let inputs = [means, quats, scales, opacities, colors, viewmats, ks];
        if inputs.iter().any(|t| t.dtype() != DType::F32) || grad_image.dtype() != DType::F32 {
            return host::backward::<Self>(inputs, grad_image, width, height, &config);
        }
        let shapes = inputs.each_ref().map(|t| t.shape());
        launch::backward(
            &Inputs::new(inputs, width, height),
            grad_image,
            shapes,
            &config,
        )
    }
}
