//! The packed projection's split into heads and the merge back (`qkv_attention::heads`):
//! one kernel each way on a GPU backend, and the op's checks of its widths.

use burn::tensor::{Device, Tensor};
use envision4d_model::bench::{watch_launches, Launches, MATMUL_ROUTINE};
use envision4d_model::layers::qkv_attention::{qkv_attention, QkvLayout};
use support::{gpu, host, turn, uniform};

mod support;

const EPS: f64 = 1e-5;

/// Guards the wiring of the split and merge kernels into the one node (and that nothing
/// else copies the thirds): one attention forward and backward on wgpu launches each once,
/// no slice assignment and no copy of its own (a matmul routine's relayout of an operand,
/// which depends on autotune's timing, is not the attention's), and the projection's
/// gradient still holds every third (a merge that dropped one would leave it out).
#[test]
fn the_split_and_the_merge_are_one_launch_each_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let (b, n, heads, d) = (2, 13, 3, 8);
    let qkv = Tensor::<3>::from_data(
        burn::tensor::TensorData::new(uniform(b * n * 3 * heads * d, 4), [b, n, 3 * heads * d]),
        &device,
    )
    .require_grad();
    let layout = QkvLayout {
        heads,
        epsilon: EPS,
        block: 1 << 24,
    };
    let pass = || {
        let out = qkv_attention(qkv.clone(), None, None, layout);
        let g = out.powi_scalar(2).sum().backward();
        host(qkv.grad(&g).expect("the projection's gradient"))
    };
    let _ = pass(); // compile and tune first
    let (grad, launches) = watch_launches(Launches::new(true).with_sites("Copy"), pass);
    for (kernel, expected) in [
        ("SplitHeads", 1),
        ("MergeHeads", 1),
        ("SliceAssignKernel", 0),
    ] {
        assert_eq!(launches.of(kernel), expected, "{kernel} launches");
    }
    // A matmul candidate that autotune picked by timing may relay out an operand itself;
    // that copy is the product's, not the split's, so only the others count.
    let own = launches.at_sites(|site| !site.starts_with(MATMUL_ROUTINE));
    if own != 0 {
        launches.print_sites(10);
    }
    assert_eq!(
        own, 0,
        "copies in the attention outside the matmul routines"
    );
    // Each third of every token's gradient is nonzero somewhere.
    let width = 3 * heads * d;
    for third in 0..3 {
        let any = (0..b * n)
            .any(|t| (0..heads * d).any(|j| grad[t * width + third * heads * d + j] != 0.0));
        assert!(any, "third {third} of the gradient is all zero");
    }
}

/// Guards the op's width check: a qk-norm beta narrower than the heads is refused with the
/// widths named (the norm's kernels would read past it), before any backend runs.
#[test]
#[should_panic(expected = "qk-norm k_norm.beta of width 4 applied to heads of 8")]
fn a_norm_parameter_of_the_wrong_width_is_refused() {
    let cpu = Device::flex();
    let qkv = Tensor::<3>::from_data(
        burn::tensor::TensorData::new(uniform(5 * 48, 3), [1, 5, 48]),
        &cpu,
    );
    let ones = |n: usize| Tensor::<1>::ones([n], &cpu);
    let norms = Some([ones(8), ones(8), ones(8), ones(4)]);
    let layout = QkvLayout {
        heads: 2,
        epsilon: EPS,
        block: 1024,
    };
    let _ = qkv_attention(qkv, norms, None, layout);
}

/// Guards the check on the projection's width: one that is not `3 · heads · d` is refused
/// rather than split into mislabelled heads.
#[test]
#[should_panic(expected = "packed q/k/v projection of width 50 does not split into 3 x 2 heads")]
fn a_projection_that_does_not_split_into_heads_is_refused() {
    let cpu = Device::flex();
    let qkv = Tensor::<3>::zeros([1, 5, 50], &cpu);
    let layout = QkvLayout {
        heads: 2,
        epsilon: EPS,
        block: 1024,
    };
    let _ = qkv_attention(qkv, None, None, layout);
}
