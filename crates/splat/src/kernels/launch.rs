//! Host side of the CubeCL rasterizer: camera records, kernel launches and the per-view
//! driver, for f32 tensors of any CubeCL runtime (the binning's launches in `binning`, the
//! backward pass in `launch_backward`).
//!
//! Every launch is skipped when its work is empty (N == 0, no visible Gaussian, no tile
//! intersection): CubeCL does not support zero-size dispatches, and the zero-filled outputs
//! are already the right answer.

use super::binning::{bins_of_view, order_view, DepthOrder};
use super::buffers::{check_binding, flat, upload_f32, zeros, zeros_u32};
use super::kept::ViewRender;
use super::math::CAM_LANES;
use super::plan::KernelPlan;
use super::project_forward::{project_forward, META_LANES, RECORD_LANES};
use super::rasterize_forward::{rasterize_forward, OUT_CHANNELS, TILE};
use super::rasterize_forward_per_pixel::rasterize_forward_per_pixel;
use super::readback::read_u32s;
use super::sort::{empty_u32_for, retype};
use super::view_meta::{view_counts, view_radii};
use crate::camera::Camera;
use crate::config::RasterConfig;
use crate::views::{HostCameras, ViewSets};
use burn::backend::ops::{FloatTensorOps, IntTensorOps};
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeCount, CubeDim};

/// The `CAM_LANES` record of one camera (limits computed on the host with the CPU's code).
fn camera_record(cam: &Camera<f32>) -> Vec<f32> {
    let r = &cam.rot.0;
    let lim = cam.frustum_limits();
    let mut v = Vec::with_capacity(CAM_LANES);
    v.extend(r.iter().flatten().copied());
    v.extend_from_slice(&cam.trans);
    v.extend_from_slice(&[
        cam.fx, cam.fy, cam.cx, cam.cy, lim.x_neg, lim.x_pos, lim.y_neg, lim.y_pos,
    ]);
    v
}

/// The seven flat f32 inputs, the cameras and sizes of one call.
pub struct Inputs {
    pub means: CubeTensor,
    pub quats: CubeTensor,
    pub scales: CubeTensor,
    pub opacities: CubeTensor,
    pub colors: CubeTensor,
    pub cams: Vec<Camera<f32>>,
    /// Input rows (all views' Gaussians).
    pub n: usize,
    /// `(first row, rows)` of every view's Gaussians.
    pub ranges: Vec<(usize, usize)>,
    /// Row width of the radii output ([`ViewSets::radii_rows`]).
    pub radii_rows: usize,
    pub width: u32,
    pub height: u32,
}

impl Inputs {
    /// Flattens the Gaussian tensors; the cameras come from `host` (validation read them),
    /// so the device is not read here.
    pub fn new(
        t: [FloatTensor<CubeBackend>; 7],
        host: &HostCameras,
        width: u32,
        height: u32,
        sets: &ViewSets,
    ) -> Self {
        let n = t[0].shape()[0];
        let [means, quats, scales, opacities, colors, _viewmats, _ks] = t.map(flat);
        let (vm, k) = (&host.viewmats, &host.ks);
        let cams = (0..vm.len() / 16)
            .map(|v| {
                Camera::from_matrices(
                    v,
                    &vm[16 * v..16 * v + 16],
                    &k[9 * v..9 * v + 9],
                    width,
                    height,
                )
                .unwrap_or_else(|e| {
                    panic!("splat: invalid camera reached the kernel (validate first): {e}")
                })
            })
            .collect::<Vec<_>>();
        Inputs {
            ranges: sets.ranges(cams.len(), n),
            radii_rows: sets.radii_rows(n),
            means,
            quats,
            scales,
            opacities,
            colors,
            cams,
            n,
            width,
            height,
        }
    }
}

/// One view after projection and the first half of the binning.
pub(super) struct ViewBins {
    /// The view's Gaussians: `rows` input rows from `first`.
    first: usize,
    rows: usize,
    cam_rec: CubeTensor,
    records: CubeTensor,
    meta: CubeTensor,
    depth: DepthOrder,
    /// Tile intersections of the view (read back with every other view's).
    intersections: usize,
}

impl ViewBins {
    /// The view with its tile lists, as the compositing reads it, its pixels' ends to be
    /// written to `ends`; `None` when no Gaussian touches a tile.
    pub(super) fn into_render(
        self,
        inp: &Inputs,
        v: usize,
        ends: &CubeTensor,
    ) -> Option<ViewRender> {
        let cam = &inp.cams[v];
        let bins = bins_of_view(
            &self.depth,
            &self.meta,
            self.rows,
            self.intersections,
            cam.tiles_x(),
            cam.tiles_y(),
        )?;
        Some(ViewRender {
            first: self.first,
            rows: self.rows,
            cam_rec: self.cam_rec,
            records: self.records,
            meta: self.meta,
            bins,
            ends: ends.clone(),
        })
    }
}

/// Projects and depth-orders every view, then reads all their intersection totals back at
/// once (the render call's one readback besides the cameras). `None` for a view without
/// Gaussians.
///
/// # Panics
/// When a view has 2^32 or more tile intersections (past what u32 offsets address; possible
/// only with millions of Gaussians each covering most tiles): the op has no error channel,
/// and a wrapped total would size its buffers too small.
pub(super) fn project_and_bin_all(inp: &Inputs, cfg: &RasterConfig) -> Vec<Option<ViewBins>> {
    let view_count = inp.cams.len();
    // One slot per view for its total, then one per view for its wrap flag.
    let totals = zeros_u32(&inp.means, 2 * view_count);
    let views: Vec<_> = (0..view_count)
        .map(|v| {
            let (first, rows) = inp.ranges[v];
            (rows > 0).then(|| {
                let (cam_rec, records, meta) = project(inp, v, cfg);
                let depth = order_view(&records, &meta, rows, &totals, v, view_count + v);
                (first, rows, cam_rec, records, meta, depth)
            })
        })
        .collect();
    if views.iter().all(Option::is_none) {
        return views.into_iter().map(|_| None).collect();
    }
    let all = read_u32s(totals);
    let (totals, wrapped) = all.split_at(view_count);
    if let Some(v) = wrapped.iter().position(|&f| f != 0) {
        let cam = &inp.cams[v];
        panic!(
            "splat (CubeCL): view {v} has 2^32 or more tile intersections ({} Gaussians over \
             {} tiles), more than u32 offsets address; render fewer or smaller Gaussians, or \
             fewer pixels per view",
            inp.ranges[v].1,
            cam.tiles_x() * cam.tiles_y()
        );
    }
    views
        .into_iter()
        .zip(totals.iter().copied())
        .map(|(view, m)| {
            view.map(|(first, rows, cam_rec, records, meta, depth)| ViewBins {
                first,
                rows,
                cam_rec,
                records,
                meta,
                depth,
                intersections: m as usize,
            })
        })
        .collect()
}

/// Runs `project_forward` for view `v`: `(camera record, records, meta)`. Requires the view
/// to have Gaussians.
fn project(inp: &Inputs, v: usize, cfg: &RasterConfig) -> (CubeTensor, CubeTensor, CubeTensor) {
    let cam = &inp.cams[v];
    let (first, n) = inp.ranges[v];
    let client = inp.means.client.clone();
    let cam_rec = upload_f32(&inp.means, camera_record(cam));
    check_binding(&inp.means, "projected Gaussian", n * RECORD_LANES);
    let records = empty_device_dtype(
        client.clone(),
        inp.means.device.clone(),
        Shape::new([n * RECORD_LANES]),
        DType::F32,
    );
    let meta = empty_device_dtype(
        client.clone(),
        inp.means.device.clone(),
        Shape::new([n * META_LANES]),
        DType::F32,
    );
    let cube_dim = CubeDim::new(&client, n);
    let cube_count = calculate_cube_count_elemwise(&client, n, cube_dim);
    project_forward::launch(
        &client,
        cube_count,
        cube_dim,
        inp.means.clone().into_tensor_arg(),
        inp.quats.clone().into_tensor_arg(),
        inp.scales.clone().into_tensor_arg(),
        inp.opacities.clone().into_tensor_arg(),
        inp.colors.clone().into_tensor_arg(),
        cam_rec.clone().into_tensor_arg(),
        records.clone().into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        first as u32,
        n as u32,
        inp.width,
        inp.height,
        cfg.near as f32,
        cfg.far as f32,
        cfg.eps2d as f32,
        cfg.alpha_min as f32,
    );
    (cam_rec, records, meta)
}

/// Writes view `v`'s radii and (visible, intersections) into the forward's meta buffers.
fn write_view_meta(inp: &Inputs, v: usize, vb: &ViewBins, radii: &CubeTensor, counts: &CubeTensor) {
    let client = &inp.means.client;
    let n = vb.rows;
    let dim = CubeDim::new(client, n);
    view_radii::launch(
        client,
        calculate_cube_count_elemwise(client, n, dim),
        dim,
        vb.meta.clone().into_tensor_arg(),
        radii.clone().into_tensor_arg(),
        n as u32,
        inp.radii_rows as u32,
        v as u32,
    );
    view_counts::launch(
        client,
        CubeCount::new_single(),
        CubeDim::new_1d(1),
        vb.depth.sorted_keys().clone().into_tensor_arg(),
        counts.clone().into_tensor_arg(),
        n as u32,
        v as u32,
        u32::try_from(vb.intersections).expect("splat: tile intersections exceed u32"),
    );
}

/// One cube per tile, one unit per pixel. The cube is one-dimensional (unit = row x
/// [`TILE`] + column): WGSL has subgroup ids only in one-dimensional workgroups, and the
/// backward's plane sums need them.
pub(super) fn tile_grid(inp: &Inputs) -> (CubeCount, CubeDim) {
    let (tx, ty) = (inp.width.div_ceil(TILE), inp.height.div_ceil(TILE));
    (CubeCount::Static(tx, ty, 1), CubeDim::new_1d(TILE * TILE))
}

pub(super) fn view_offset(inp: &Inputs, v: usize) -> u32 {
    let off = v * inp.width as usize * inp.height as usize * OUT_CHANNELS;
    u32::try_from(off).expect("splat: image batch too large for 32-bit offsets")
}

/// Composites view `v` into `image` (the call's batch; `batched`: the call's plan), and with
/// `keep_ends` each pixel's final transmittance and last composited item into `view.ends`.
fn composite(
    inp: &Inputs,
    cfg: &RasterConfig,
    batched: bool,
    v: usize,
    view: &ViewRender,
    image: &CubeTensor,
    keep_ends: bool,
) {
    let launch = if batched {
        rasterize_forward::launch
    } else {
        rasterize_forward_per_pixel::launch
    };
    let (count, dim) = tile_grid(inp);
    launch(
        &inp.means.client,
        count,
        dim,
        view.records.clone().into_tensor_arg(),
        view.bins.tile_start.clone().into_tensor_arg(),
        view.bins.items.clone().into_tensor_arg(),
        image.clone().into_tensor_arg(),
        view.ends.clone().into_tensor_arg(),
        inp.width,
        inp.height,
        inp.cams[v].tiles_x(),
        view_offset(inp, v),
        cfg.alpha_min as f32,
        cfg.alpha_clamp.max_alpha() as f32,
        cfg.transmittance_min as f32,
        keep_ends,
    );
}

/// Where the pixels of every view stop compositing, `[V x H x W, 2]` u32 (8 bytes per pixel
/// and view), or one unused word for a forward that keeps none.
fn ends_buffer(inp: &Inputs, keep: bool) -> CubeTensor {
    let pixels = inp.cams.len() * inp.width as usize * inp.height as usize;
    empty_u32_for(&inp.means, "pixel ends", if keep { pixels * 2 } else { 1 })
}

/// Every view projected, binned and composited again, for a backward whose forward kept
/// nothing ([`crate::config::BackwardBins::Recompute`]): the compositing (into a scratch
/// image) gives each pixel's ends, which the backward kernels read. `None` for a view
/// without tiles.
pub(super) fn recomputed_views(inp: &Inputs, cfg: &RasterConfig) -> Vec<Option<ViewRender>> {
    let (w, h) = (inp.width as usize, inp.height as usize);
    let scratch = empty_device_dtype(
        inp.means.client.clone(),
        inp.means.device.clone(),
        Shape::new([inp.cams.len() * h * w * OUT_CHANNELS]),
        DType::F32,
    );
    let ends = ends_buffer(inp, true);
    let batched = KernelPlan::of(&inp.means, cfg).shared_batches;
    let binned = project_and_bin_all(inp, cfg).into_iter().enumerate();
    binned
        .map(|(v, vb)| {
            let view = vb?.into_render(inp, v, &ends)?;
            composite(inp, cfg, batched, v, &view, &scratch, true);
            Some(view)
        })
        .collect()
}

/// `splat_forward` on the GPU: `(image [V,H,W,5], radii [V,R,2], counts [V,2])`, and with
/// `keep` every view as the compositing read it, for the backward (empty without).
pub fn forward(
    inp: &Inputs,
    cfg: &RasterConfig,
    keep: bool,
) -> (
    FloatTensor<CubeBackend>,
    IntTensor<CubeBackend>,
    IntTensor<CubeBackend>,
    Vec<Option<ViewRender>>,
) {
    let (v_count, r) = (inp.cams.len(), inp.radii_rows);
    let (w, h) = (inp.width as usize, inp.height as usize);
    let image = zeros(&inp.means, v_count * h * w * OUT_CHANNELS);
    // Zero-filled, so views and Gaussians with nothing to say need no launch.
    let radii = zeros_u32(&inp.means, v_count * r * 2);
    let counts = zeros_u32(&inp.means, v_count * 2);
    let mut kept: Vec<Option<ViewRender>> = Vec::new();
    if keep {
        kept.resize_with(v_count, || None);
    }
    // Where every pixel stopped, for the backward (which else composites again).
    let ends = ends_buffer(inp, keep);
    let batched = KernelPlan::of(&inp.means, cfg).shared_batches;
    for (v, vb) in project_and_bin_all(inp, cfg).into_iter().enumerate() {
        let Some(vb) = vb else {
            continue;
        };
        write_view_meta(inp, v, &vb, &radii, &counts);
        let Some(view) = vb.into_render(inp, v, &ends) else {
            continue;
        };
        composite(inp, cfg, batched, v, &view, &image, keep);
        if keep {
            kept[v] = Some(view);
        }
    }
    let image = CubeBackend::float_reshape(image, Shape::new([v_count, h, w, OUT_CHANNELS]));
    // The counters are small non-negative integers: their u32 bits read as i32.
    let as_int =
        |t: CubeTensor, shape: Shape| CubeBackend::int_reshape(retype(t, DType::I32), shape);
    let radii = as_int(radii, Shape::new([v_count, r, 2]));
    let counts = as_int(counts, Shape::new([v_count, 2]));
    (image, radii, counts, kept)
}
