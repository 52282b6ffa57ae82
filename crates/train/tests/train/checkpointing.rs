//! Activation checkpointing (Burn's balanced strategy, recomputed frozen blocks): less
//! memory, the same gradients.

use crate::common::tiny_config;
use burn::tensor::Device;
use envision4d_model::aggregator::BlockMemory;
use envision4d_model::layers::recompute::is_frozen;
use envision4d_train::Trainer;

/// One training step's gradients (in the model's parameter order) under `c` on `device`.
fn step_gradients(c: &envision4d_train::TrainConfig, device: &Device) -> Vec<Vec<f32>> {
    use burn::optim::GradientsParams;
    let batch = envision4d_train::batch::Batch::from_clips(
        &[crate::common::synth_clip(3)],
        2,
        true,
        device,
    )
    .unwrap();
    let t = Trainer::new(c.clone(), device).unwrap();
    let mut g = t.loss(&batch, 0).unwrap().total.backward();
    let g = GradientsParams::from_params(&mut g, &t.model, &t.split.trainable);
    // Two trainers' parameter ids differ: compare in the model's order.
    crate::common::ordered_grads(&t.model, &g)
}

/// Asserts two gradient sets are equal within 1e-5 of the largest entry.
fn assert_same_gradients(plain: &[Vec<f32>], other: &[Vec<f32>], what: &str) {
    assert_eq!(plain.len(), other.len());
    assert!(plain.len() > 20, "only {} gradients compared", plain.len());
    let pairs = || plain.iter().flatten().zip(other.iter().flatten());
    let diff = pairs().map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    let largest = plain
        .iter()
        .flatten()
        .map(|a| a.abs())
        .fold(0.0f32, f32::max);
    assert!(
        diff <= 1e-5 * largest,
        "{what}: gradients differ by {diff} (largest {largest})"
    );
}

/// Guards `run.activation_checkpointing`: Burn's balanced checkpointing recomputes
/// activations in the backward instead of keeping them, which must change memory, not the
/// gradients: one training step's gradients at tiny widths equal those without it.
#[test]
fn activation_checkpointing_keeps_the_gradients() {
    let mut c = tiny_config();
    c.progressive.warmup_iterations = 0;
    let plain = step_gradients(&c, &Device::flex().autodiff());
    assert!(plain.len() > 100, "only {} gradients compared", plain.len());
    let checkpointed = step_gradients(&c, &Device::flex().autodiff().gradient_checkpointing());
    assert_same_gradients(&plain, &checkpointed, "balanced checkpointing");
}

/// Guards `run.recompute_frozen_blocks` under the paper's freeze list, where the in-layer
/// temporal blocks send the gradient back through the frozen frame and global blocks: the
/// recomputing backward must give one step's gradients of the run without it (the trainable
/// heads, the temporal blocks and the future-pose module alike).
#[test]
fn recomputing_frozen_blocks_keeps_the_gradients() {
    let mut c = tiny_config();
    c.progressive.warmup_iterations = 0;
    c.freeze = envision4d_train::config::FreezeGroup::PAPER.to_vec();
    let device = Device::flex().autodiff();
    let plain = step_gradients(&c, &device);
    c.run.recompute_frozen_blocks = true;
    let t = Trainer::new(c.clone(), &device).unwrap();
    assert_eq!(
        t.model.aggregator.block_memory,
        BlockMemory::RecomputeFrozen
    );
    assert!(is_frozen(&t.model.aggregator.frame_blocks[1]));
    let recomputed = step_gradients(&c, &device);
    assert_same_gradients(&plain, &recomputed, "recomputed frozen blocks");
}
