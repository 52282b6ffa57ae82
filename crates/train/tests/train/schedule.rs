use envision4d_train::config::{AnnealOrigin, LrSchedule, Switch};
use envision4d_train::{frame_weights, Phase, Schedule};

fn paper() -> Schedule {
    Schedule {
        warmup_iterations: 2500,
        s_max: 50_000,
        alpha0: 1.0,
        origin: AnnealOrigin::AfterWarmup,
        weighting: Switch::On,
        lr: 1e-4,
        min_lr: 0.0,
        lr_schedule: LrSchedule::Cosine,
        iterations: 100_000,
    }
}

/// Guards the α annealing values, its origin and its clamp at 0.
#[test]
fn alpha_at_chosen_steps() {
    let s = paper();
    assert_eq!(s.alpha(0), 1.0);
    assert_eq!(s.alpha(2500), 1.0);
    assert!((s.alpha(2500 + 25_000) - 0.5).abs() < 1e-12);
    assert_eq!(s.alpha(2500 + 50_000), 0.0);
    assert_eq!(s.alpha(1_000_000), 0.0);
    let z = Schedule {
        origin: AnnealOrigin::StepZero,
        ..s
    };
    assert!((z.alpha(25_000) - 0.5).abs() < 1e-12);
}

/// Guards the frame weights: mean exactly 1, context frames equal, decreasing in t.
#[test]
fn frame_weights_normalised_and_monotone() {
    let w = frame_weights(1.0, 2, 4);
    let e = (-1.0f64).exp();
    let sum = 2.0 + e + e * e;
    let expect = [4.0 / sum, 4.0 / sum, 4.0 * e / sum, 4.0 * e * e / sum];
    for (a, b) in w.iter().zip(expect) {
        assert!((a - b).abs() < 1e-12, "{w:?}");
    }
    for alpha in [0.0, 0.3, 1.0, 5.0] {
        let w = frame_weights(alpha, 2, 6);
        assert!((w.iter().sum::<f64>() / 6.0 - 1.0).abs() < 1e-12);
        assert_eq!(w[0], w[1]);
        assert!(w.windows(2).all(|p| p[1] <= p[0]));
    }
    assert!(frame_weights(0.0, 2, 4)
        .iter()
        .all(|&v| (v - 1.0).abs() < 1e-15));
    let off = Schedule {
        weighting: Switch::Off,
        ..paper()
    };
    assert_eq!(off.frame_weights(2500, 2, 4), vec![1.0; 4]);
}

/// Guards the warm-up boundary and the cosine learning rate.
#[test]
fn phase_and_cosine_lr() {
    let s = paper();
    assert_eq!(s.phase(2499), Phase::Warmup);
    assert_eq!(s.phase(2500), Phase::Progressive);
    let off = Schedule {
        warmup_iterations: 0,
        ..s
    };
    assert_eq!(off.phase(0), Phase::Progressive);
    assert_eq!(s.learning_rate(0), 1e-4);
    assert!((s.learning_rate(50_000) - 5e-5).abs() < 1e-15);
    assert!(s.learning_rate(100_000).abs() < 1e-15);
    assert!(s.learning_rate(30_000) > s.learning_rate(60_000));
}
