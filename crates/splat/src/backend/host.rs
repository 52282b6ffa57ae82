//! The default `SplatOps` bodies: copy tensors to the host, run [`crate::cpu`], copy back.
//!
//! f64 tensors run the f64 rasterizer (the oracle), everything else runs in f32.

use super::SplatGrads;
use crate::camera::Camera;
use crate::config::RasterConfig;
use crate::cpu::{self, project::Scene, raster::OUT_CHANNELS};
use crate::real::Real;
use crate::views::ViewSets;
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::{Backend, TensorMetadata};
use burn::tensor::{read_sync, DType, Element, TensorData};

fn to_host<B: Backend, F: Real + Element>(t: FloatTensor<B>) -> Vec<F> {
    let data = read_sync(B::float_into_data(t))
        .unwrap_or_else(|e| panic!("splat: reading a tensor back from the device failed: {e:?}"));
    data.convert::<F>()
        .try_into_vec::<F>()
        .unwrap_or_else(|e| panic!("splat: tensor conversion failed: {e:?}"))
}

fn from_host<B: Backend, F: Real + Element>(
    v: Vec<F>,
    shape: Vec<usize>,
    device: &B::Device,
    dtype: DType,
) -> FloatTensor<B> {
    B::float_from_data(TensorData::new(v, shape).convert_dtype(dtype), device)
}

/// Builds the cameras; inputs were validated by the public API, so an error here is a bug.
fn cameras<F: Real>(viewmats: &[F], ks: &[F], width: u32, height: u32) -> Vec<Camera<F>> {
    (0..viewmats.len() / 16)
        .map(|v| {
            Camera::from_matrices(
                v,
                &viewmats[16 * v..16 * v + 16],
                &ks[9 * v..9 * v + 9],
                width,
                height,
            )
            .unwrap_or_else(|e| {
                panic!("splat: invalid camera reached the kernel (validate first): {e}")
            })
        })
        .collect()
}

/// The seven inputs copied to the host, with what is needed to send results back.
struct HostInputs<F, D> {
    arrays: [Vec<F>; 7],
    shapes: [Vec<usize>; 7],
    device: D,
    dtype: DType,
}

impl<F: Real + Element, D: Clone> HostInputs<F, D> {
    fn new<B: Backend<Device = D>>(inputs: [FloatTensor<B>; 7]) -> Self {
        let device = inputs[0].device();
        let dtype = inputs[0].dtype();
        let shapes = inputs.each_ref().map(|t| t.shape().to_vec());
        HostInputs {
            arrays: inputs.map(to_host::<B, F>),
            shapes,
            device,
            dtype,
        }
    }

    fn scene(&self) -> Scene<'_, F> {
        let [m, q, s, o, c, _, _] = &self.arrays;
        Scene {
            means: m,
            quats: q,
            scales: s,
            opacities: o,
            colors: c,
        }
    }

    fn cameras(&self, width: u32, height: u32) -> Vec<Camera<F>> {
        cameras(&self.arrays[5], &self.arrays[6], width, height)
    }
}

pub fn forward<B: Backend>(
    inputs: [FloatTensor<B>; 7],
    width: u32,
    height: u32,
    sets: &ViewSets,
    cfg: &RasterConfig,
) -> (FloatTensor<B>, IntTensor<B>, IntTensor<B>) {
    if inputs[0].dtype() == DType::F64 {
        forward_in::<B, f64>(inputs, width, height, sets, cfg)
    } else {
        forward_in::<B, f32>(inputs, width, height, sets, cfg)
    }
}

fn forward_in<B: Backend, F: Real + Element>(
    inputs: [FloatTensor<B>; 7],
    width: u32,
    height: u32,
    sets: &ViewSets,
    cfg: &RasterConfig,
) -> (FloatTensor<B>, IntTensor<B>, IntTensor<B>) {
    let host = HostInputs::<F, B::Device>::new::<B>(inputs);
    let (device, dtype) = (host.device.clone(), host.dtype);
    let scene = host.scene();
    let cams = host.cameras(width, height);
    let out = cpu::render_forward_sets(&scene, &cams, sets, cfg);
    let v = cams.len();
    let n = sets.radii_rows(scene.len());
    let image = from_host::<B, F>(
        out.image,
        vec![v, height as usize, width as usize, OUT_CHANNELS],
        &device,
        dtype,
    );
    let radii = B::int_from_data(TensorData::new(out.radii, vec![v, n, 2]), &device);
    let counts: Vec<i64> = out
        .visible
        .iter()
        .zip(&out.intersections)
        .flat_map(|(a, b)| [*a as i64, *b as i64])
        .collect();
    let counts = B::int_from_data(TensorData::new(counts, vec![v, 2]), &device);
    (image, radii, counts)
}

pub fn backward<B: Backend>(
    inputs: [FloatTensor<B>; 7],
    grad_image: FloatTensor<B>,
    width: u32,
    height: u32,
    sets: &ViewSets,
    cfg: &RasterConfig,
) -> SplatGrads<B> {
    if inputs[0].dtype() == DType::F64 {
        backward_in::<B, f64>(inputs, grad_image, width, height, sets, cfg)
    } else {
        backward_in::<B, f32>(inputs, grad_image, width, height, sets, cfg)
    }
}

fn backward_in<B: Backend, F: Real + Element>(
    inputs: [FloatTensor<B>; 7],
    grad_image: FloatTensor<B>,
    width: u32,
    height: u32,
    sets: &ViewSets,
    cfg: &RasterConfig,
) -> SplatGrads<B> {
    let host = HostInputs::<F, B::Device>::new::<B>(inputs);
    let grad = to_host::<B, F>(grad_image);
    let scene = host.scene();
    let cams = host.cameras(width, height);
    let g = cpu::render_backward_sets(&scene, &cams, sets, cfg, &grad);
    let t = |v: Vec<F>, k: usize| {
        from_host::<B, F>(v, host.shapes[k].clone(), &host.device, host.dtype)
    };
    SplatGrads {
        means: t(g.means, 0),
        quats: t(g.quats, 1),
        scales: t(g.scales, 2),
        opacities: t(g.opacities, 3),
        colors: t(g.colors, 4),
        viewmats: t(g.viewmats, 5),
        ks: t(g.ks, 6),
    }
}
