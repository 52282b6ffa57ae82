//! The host side of the rasterizer's backward pass on CubeCL backends: per view, the
//! compositing backward (float atomics, or compare-and-swap where the device has none), the
//! projection backward, and the camera gradient, all on the device. Each view's projection,
//! tile lists and pixel ends are the forward's where it kept them (`kept`), else recomputed
//! with the forward's code (`launch.rs`).

use super::buffers::{flat, zeros};
use super::camera_grad::camera_grad_matrices;
use super::kept::ViewRender;
use super::launch::{recomputed_views, tile_grid, view_offset, Inputs};
use super::plan::KernelPlan;
use super::project_backward::{project_backward, CAM_GRAD_LANES};
use super::project_forward::RECORD_LANES;
use super::rasterize_backward::rasterize_backward;
use super::rasterize_backward_per_pixel::rasterize_backward_per_pixel;
use super::splat_grad::{CasAdd, NativeAdd};
use crate::backend::SplatGrads;
use crate::config::RasterConfig;
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::tensor::{DType, Shape};
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeCount, CubeDim};

/// `splat_backward` on the GPU; `shapes` are the seven input shapes for the outputs. `kept`
/// is every view as the forward composited it ([`super::launch::forward`] with `keep`);
/// `None` projects, bins and composites them again (one more host read).
pub fn backward(
    inp: &Inputs,
    grad_image: FloatTensor<CubeBackend>,
    shapes: [Shape; 7],
    cfg: &RasterConfig,
    kept: Option<Vec<Option<ViewRender>>>,
) -> SplatGrads<CubeBackend> {
    let n = inp.n;
    let grad_image = flat(grad_image);
    let [g_means, g_quats, g_scales, g_opac, g_colors] =
        [3, 4, 3, 1, 3].map(|lanes| zeros(&inp.means, n * lanes));
    let v_count = inp.cams.len();
    let (g_viewmats, g_ks) = (
        zeros(&inp.means, v_count * 16),
        zeros(&inp.means, v_count * 9),
    );
    // With plane sums, a plane barrier before each vote and sum where the device has one
    // (CUDA; see `plane_step`).
    let plan = KernelPlan::of(&inp.means, cfg);
    let (native, batched) = (plan.native_atomics, plan.shared_batches);
    let (plane, plane_sync) = (plan.plane_sums, plan.plane_sync);
    let views = kept.unwrap_or_else(|| recomputed_views(inp, cfg));
    for (v, view) in views.into_iter().enumerate() {
        if let Some(vb) = view {
            let (first, n, bins) = (vb.first, vb.rows, vb.bins);
            let v_proj = zeros(&inp.means, n * RECORD_LANES);
            let (count, dim) = tile_grid(inp);
            // The four kernels take the same arguments; the batched one also its plane flags.
            macro_rules! composite {
                ($kernel:ident::<$add:ty>($($flag:expr),*)) => {
                    $kernel::launch::<$add>(
                        &inp.means.client,
                        count,
                        dim,
                        vb.records.into_tensor_arg(),
                        bins.tile_start.into_tensor_arg(),
                        bins.items.into_tensor_arg(),
                        grad_image.clone().into_tensor_arg(),
                        vb.ends.into_tensor_arg(),
                        v_proj.clone().into_tensor_arg(),
                        inp.width,
                        inp.height,
                        inp.cams[v].tiles_x(),
                        view_offset(inp, v),
                        cfg.alpha_min as f32,
                        cfg.alpha_clamp.max_alpha() as f32,
                        $($flag),*
                    )
                };
            }
            match (native, batched) {
                (true, true) => composite!(rasterize_backward::<NativeAdd>(plane, plane_sync)),
                (false, true) => composite!(rasterize_backward::<CasAdd>(plane, plane_sync)),
                (true, false) => composite!(rasterize_backward_per_pixel::<NativeAdd>()),
                (false, false) => composite!(rasterize_backward_per_pixel::<CasAdd>()),
            }
            let cam_part = empty_device_dtype(
                inp.means.client.clone(),
                inp.means.device.clone(),
                Shape::new([n * CAM_GRAD_LANES]),
                DType::F32,
            );
            let client = &inp.means.client;
            let cube_dim = CubeDim::new(client, n);
            let cube_count = calculate_cube_count_elemwise(client, n, cube_dim);
            project_backward::launch(
                client,
                cube_count,
                cube_dim,
                inp.means.clone().into_tensor_arg(),
                inp.quats.clone().into_tensor_arg(),
                inp.scales.clone().into_tensor_arg(),
                vb.cam_rec.into_tensor_arg(),
                vb.meta.into_tensor_arg(),
                v_proj.into_tensor_arg(),
                g_means.clone().into_tensor_arg(),
                g_quats.clone().into_tensor_arg(),
                g_scales.clone().into_tensor_arg(),
                g_opac.clone().into_tensor_arg(),
                g_colors.clone().into_tensor_arg(),
                cam_part.clone().into_tensor_arg(),
                first as u32,
                n as u32,
                cfg.near as f32,
                cfg.far as f32,
                cfg.eps2d as f32,
            );
            // Sum the per-Gaussian camera partials and lay them out as the camera
            // tensors, all on the device.
            let sums = CubeBackend::float_sum_dim(
                CubeBackend::float_reshape(cam_part, Shape::new([n, CAM_GRAD_LANES])),
                0,
            );
            camera_grad_matrices::launch(
                client,
                CubeCount::new_single(),
                CubeDim::new_1d(1),
                into_contiguous(sums).into_tensor_arg(),
                g_viewmats.clone().into_tensor_arg(),
                g_ks.clone().into_tensor_arg(),
                v as u32,
            );
        }
    }
    let [s_m, s_q, s_s, s_o, s_c, s_v, s_k] = shapes;
    SplatGrads {
        means: CubeBackend::float_reshape(g_means, s_m),
        quats: CubeBackend::float_reshape(g_quats, s_q),
        scales: CubeBackend::float_reshape(g_scales, s_s),
        opacities: CubeBackend::float_reshape(g_opac, s_o),
        colors: CubeBackend::float_reshape(g_colors, s_c),
        viewmats: CubeBackend::float_reshape(g_viewmats, s_v),
        ks: CubeBackend::float_reshape(g_ks, s_k),
    }
}
