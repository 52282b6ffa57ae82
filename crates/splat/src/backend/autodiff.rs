//! The custom autodiff node: one Backward step with seven parents (the five Gaussian
//! parameter tensors and the two camera tensors).
//!
//! The state keeps the inner-backend input primitives and, with
//! [`BackwardBins::Keep`](crate::BackwardBins) on a backend that keeps them, every view's
//! projected records and tile lists, so the backward neither sorts nor reads the host again;
//! with `Recompute` it projects and bins again, holding less between the passes. A forward
//! nothing will differentiate keeps nothing.

use super::{Forward, SplatGrads, SplatKeep, SplatOps};
use crate::config::{BackwardBins, RasterConfig};
use crate::kernels::plan::KernelPlan;
use crate::views::{HostCameras, ViewSets};
use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::AutodiffBackend;

#[derive(Debug)]
struct RenderBackward;

#[derive(Debug, Clone)]
struct RenderState<B: SplatKeep> {
    inputs: [FloatTensor<B>; 7],
    width: u32,
    height: u32,
    sets: ViewSets,
    host_cameras: HostCameras,
    config: RasterConfig,
    /// What the inner forward kept for the backward (`None`: recompute).
    kept: Option<B::Kept>,
}

impl<B: SplatKeep> Backward<B, 7> for RenderBackward {
    type State = RenderState<B>;

    fn backward(
        self,
        ops: Ops<Self::State, 7>,
        grads: &mut Gradients,
        _checkpointer: &mut Checkpointer,
    ) {
        let grad_image = grads.consume::<B>(&ops.node);
        let RenderState {
            inputs,
            width,
            height,
            sets,
            host_cameras,
            config,
            kept,
        } = ops.state;
        let g = match kept {
            Some(kept) => B::splat_backward_kept(
                inputs,
                grad_image,
                kept,
                width,
                height,
                sets,
                host_cameras,
                config,
            ),
            None => backward_of::<B>(
                inputs,
                grad_image,
                width,
                height,
                sets,
                host_cameras,
                config,
            ),
        };
        for (parent, grad) in ops.parents.into_iter().zip([
            g.means,
            g.quats,
            g.scales,
            g.opacities,
            g.colors,
            g.viewmats,
            g.ks,
        ]) {
            if let Some(node) = parent {
                grads.register::<B>(node.id, grad);
            }
        }
    }
}

/// [`SplatOps::splat_forward`] with its seven inputs as one array.
fn forward_of<B: SplatOps>(
    inputs: [FloatTensor<B>; 7],
    width: u32,
    height: u32,
    sets: ViewSets,
    host_cameras: HostCameras,
    config: RasterConfig,
) -> Forward<B> {
    let [m, q, s, o, c, v, k] = inputs;
    B::splat_forward(
        m,
        q,
        s,
        o,
        c,
        v,
        k,
        width,
        height,
        sets,
        host_cameras,
        config,
    )
}

/// [`SplatOps::splat_backward`] with its seven inputs as one array.
fn backward_of<B: SplatOps>(
    inputs: [FloatTensor<B>; 7],
    grad_image: FloatTensor<B>,
    width: u32,
    height: u32,
    sets: ViewSets,
    host_cameras: HostCameras,
    config: RasterConfig,
) -> SplatGrads<B> {
    let [m, q, s, o, c, v, k] = inputs;
    B::splat_backward(
        m,
        q,
        s,
        o,
        c,
        v,
        k,
        grad_image,
        width,
        height,
        sets,
        host_cameras,
        config,
    )
}

impl<B: SplatKeep, C: CheckpointStrategy> SplatOps for Autodiff<B, C> {
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
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (FloatTensor<Self>, IntTensor<Self>, IntTensor<Self>) {
        let tensors = [means, quats, scales, opacities, colors, viewmats, ks];
        let nodes = tensors.each_ref().map(|t| t.node());
        let inner = tensors.map(|t| t.into_primitive());
        match RenderBackward
            .prepare::<C>(nodes)
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let (cameras, sets_kept) = (host_cameras.clone(), sets.clone());
                let ((image, radii, counts), kept) = match config.backward_bins {
                    BackwardBins::Keep => B::splat_forward_kept(
                        inner.clone(),
                        width,
                        height,
                        sets_kept,
                        cameras,
                        config,
                    ),
                    BackwardBins::Recompute => (
                        forward_of::<B>(inner.clone(), width, height, sets_kept, cameras, config),
                        None,
                    ),
                };
                let state = RenderState {
                    inputs: inner,
                    width,
                    height,
                    sets,
                    host_cameras,
                    config,
                    kept,
                };
                (prep.finish(state, image), radii, counts)
            }
            OpsKind::UnTracked(prep) => {
                let (image, radii, counts) =
                    forward_of::<B>(inner, width, height, sets, host_cameras, config);
                (prep.finish(image), radii, counts)
            }
        }
    }

    /// Gradients are computed, not differentiated again: the results are constants.
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
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        let g = B::splat_backward(
            means.into_primitive(),
            quats.into_primitive(),
            scales.into_primitive(),
            opacities.into_primitive(),
            colors.into_primitive(),
            viewmats.into_primitive(),
            ks.into_primitive(),
            grad_image.into_primitive(),
            width,
            height,
            sets,
            host_cameras,
            config,
        );
        let lift = <Self as AutodiffBackend>::from_inner;
        SplatGrads {
            means: lift(g.means),
            quats: lift(g.quats),
            scales: lift(g.scales),
            opacities: lift(g.opacities),
            colors: lift(g.colors),
            viewmats: lift(g.viewmats),
            ks: lift(g.ks),
        }
    }

    /// Integer ops carry no gradient: the inner backend's.
    fn splat_sort_pairs(
        keys: IntTensor<Self>,
        values: IntTensor<Self>,
        bits: u32,
    ) -> (IntTensor<Self>, IntTensor<Self>) {
        B::splat_sort_pairs(keys, values, bits)
    }

    fn splat_exclusive_scan(values: IntTensor<Self>) -> IntTensor<Self> {
        B::splat_exclusive_scan(values)
    }

    fn splat_scan_wrapped(offsets: IntTensor<Self>) -> bool {
        B::splat_scan_wrapped(offsets)
    }

    fn splat_kernel_plan(like: FloatTensor<Self>, config: RasterConfig) -> Option<KernelPlan> {
        B::splat_kernel_plan(like.into_primitive(), config)
    }
}
