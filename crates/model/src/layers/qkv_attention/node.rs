//! The autodiff node: one parent for the projection, and four more for the qk-norms'
//! parameters when the attention has them.

use super::{
    backward, forward, tables, QkNormParams, QkNorms, QkvAttentionOps, QkvLayout, RopeParams, Saved,
};
use crate::layers::norm::NormNeeds;
use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, NodeGuard, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Backend;

type Tables<B> = Option<(FloatTensor<B>, FloatTensor<B>)>;

/// What the backward reads: the forward's tensors, the norms' parameters (their gammas
/// scale the input gradients), RoPE's tables and the attention's block size.
#[derive(Clone, Debug)]
struct State<B: Backend> {
    saved: Saved<B>,
    norms: Option<QkNorms<B>>,
    rope: Tables<B>,
    block: usize,
}

/// `N` parents: the projection, then `q_gamma, q_beta, k_gamma, k_beta` when `N` is 5.
#[derive(Debug)]
struct QkvBackward<const N: usize>;

impl<B: QkvAttentionOps, const N: usize> Backward<B, N> for QkvBackward<N> {
    type State = State<B>;

    fn backward(self, ops: Ops<Self::State, N>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let State {
            saved,
            norms,
            rope,
            block,
        } = ops.state;
        let tracked = ops.parents.each_ref().map(Option::is_some);
        // Each norm as its own node would: a frozen one needs the input gradient only.
        let needs = |gamma: usize| NormNeeds {
            input: tracked[0],
            params: tracked.get(gamma).is_some_and(|t| *t)
                || tracked.get(gamma + 1).is_some_and(|t| *t),
        };
        let needs = [needs(1), needs(3)];
        let g = backward::<B>(saved, norms.as_ref(), rope.as_ref(), grad, needs, block);
        let mut parents = ops.parents.into_iter();
        if let (Some(node), Some(dqkv)) = (parents.next().flatten(), g.qkv) {
            grads.register::<B>(node.id, dqkv);
        }
        for (parent, grad) in parents.zip(g.norms.into_iter().flatten()) {
            if let Some(node) = parent {
                grads.register::<B>(node.id, grad);
            }
        }
    }
}

/// Records the node over `nodes` (taken before their primitives were consumed) and returns
/// the output.
fn record<B: QkvAttentionOps, C: CheckpointStrategy, const N: usize>(
    nodes: [NodeGuard; N],
    saved: Saved<B>,
    norms: Option<QkNorms<B>>,
    rope: Tables<B>,
    block: usize,
) -> FloatTensor<Autodiff<B, C>> {
    let out = saved.out.clone();
    match QkvBackward::<N>
        .prepare::<C>(nodes)
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(prep) => prep.finish(
            State {
                saved,
                norms,
                rope,
                block,
            },
            out,
        ),
        OpsKind::UnTracked(prep) => prep.finish(out),
    }
}

impl<B: QkvAttentionOps, C: CheckpointStrategy> QkvAttentionOps for Autodiff<B, C> {
    fn qkv_attention(
        qkv: FloatTensor<Self>,
        norms: QkNormParams<Self>,
        rope: RopeParams<Self>,
        layout: QkvLayout,
    ) -> FloatTensor<Self> {
        // The tables are constants of the graph: no gradient flows to them.
        let rope = tables(rope).map(|(c, s)| (c.into_primitive(), s.into_primitive()));
        let block = layout.block;
        match norms.on() {
            None => {
                let nodes = [qkv.node()];
                let saved = forward::<B>(qkv.into_primitive(), None, rope.as_ref(), layout);
                record::<B, C, 1>(nodes, saved, None, rope, block)
            }
            Some(p) => {
                let nodes = [
                    qkv.node(),
                    p.q_gamma.node(),
                    p.q_beta.node(),
                    p.k_gamma.node(),
                    p.k_beta.node(),
                ];
                let inner = QkNorms {
                    q_gamma: p.q_gamma.into_primitive(),
                    q_beta: p.q_beta.into_primitive(),
                    k_gamma: p.k_gamma.into_primitive(),
                    k_beta: p.k_beta.into_primitive(),
                };
                let saved = forward::<B>(qkv.into_primitive(), Some(&inner), rope.as_ref(), layout);
                record::<B, C, 5>(nodes, saved, Some(inner), rope, block)
            }
        }
    }
}
