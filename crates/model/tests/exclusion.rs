//! Which Gaussians a target frame is rendered from (`gaussians_at` under each `Exclusion`),
//! on hand-made Gaussians whose values say where they come from.

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::adapter::{gaussians_at, AdaptedGaussians, Exclusion};
use envision4d_model::motion::target_slot;

/// `T_c = 3` context frames of `G = 2` Gaussians, `N = 4` timestamps. Source i's means are
/// `10·i + g`; the displacement of source i to time j is `100·j` on x.
fn gaussians() -> AdaptedGaussians {
    let (s, g, n) = (3, 2, 4);
    let device = Device::flex();
    let t4 = |c: usize, f: &dyn Fn(usize, usize, usize) -> f32| {
        let data: Vec<f32> = (0..s * g * c)
            .map(|k| f(k / (g * c), (k / c) % g, k % c))
            .collect();
        Tensor::<4>::from_data(TensorData::new(data, [1, s, g, c]), &device)
    };
    let mut motion = vec![0.0f32; s * (n - 1) * g * 3];
    for i in 0..s {
        for j in (0..n).filter(|&j| j != i) {
            for gi in 0..g {
                motion[((i * (n - 1) + target_slot(i, j)) * g + gi) * 3] = 100.0 * j as f32;
            }
        }
    }
    AdaptedGaussians {
        means: t4(3, &|i, gi, _| (10 * i + gi) as f32),
        scales: t4(3, &|_, _, _| 0.1),
        rotations: t4(4, &|_, _, c| if c == 3 { 1.0 } else { 0.0 }),
        colors: t4(3, &|i, _, _| i as f32),
        opacities: Tensor::<3>::from_data(TensorData::new(vec![0.5f32; s * g], [1, s, g]), &device),
        motions: Tensor::<5>::from_data(TensorData::new(motion, [1, s, n - 1, g, 3]), &device),
    }
}

fn host(t: Tensor<2>) -> Vec<f32> {
    t.into_data().iter::<f32>().collect()
}

/// Guards the cross-frame table's renders: `OnlySource(1)` at target 0 is exactly frame 1's
/// Gaussians moved to time 0 (the appendix's `1→0`), `SelfExclusive` is every other frame's
/// moved, and `IncludeOwn` adds the target's own unmoved.
#[test]
fn each_exclusion_renders_from_the_right_sources() {
    let a = gaussians();
    let (means, _, _, _, colors) = gaussians_at(&a, 0, 0, Exclusion::OnlySource(1));
    // x of frame 1's means (10, 11) moved to time 0 (+0), y and z unmoved.
    assert_eq!(host(means), vec![10.0, 10.0, 10.0, 11.0, 11.0, 11.0]);
    assert_eq!(host(colors), vec![1.0; 6]);
    let (means, _, _, _, _) = gaussians_at(&a, 0, 1, Exclusion::OnlySource(0));
    // `0→1`: frame 0's means (0, 1) moved by +100 on x.
    assert_eq!(host(means), vec![100.0, 0.0, 0.0, 101.0, 1.0, 1.0]);
    let (_, _, _, _, colors) = gaussians_at(&a, 0, 1, Exclusion::SelfExclusive);
    let sources: Vec<f32> = host(colors).chunks(3).map(|c| c[0]).collect();
    assert_eq!(sources, vec![0.0, 0.0, 2.0, 2.0]);
    let (means, _, _, _, _) = gaussians_at(&a, 0, 1, Exclusion::IncludeOwn);
    let m = host(means);
    assert_eq!(m.len(), 3 * 2 * 3);
    // Frame 1's own Gaussians stay where they are.
    assert_eq!(&m[6..12], &[10.0, 10.0, 10.0, 11.0, 11.0, 11.0]);
}
