//! Hand-computed motion metrics on a constructed two-pixel clip.

use super::*;
use envision4d_data::ObjectPose;

/// OpenCV camera at the world origin looking along world +x (world z up): camera x = −y,
/// camera y = −z, camera z = x.
fn looking_along_x() -> Mat4 {
    Mat4::from_rt(
        [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]],
        Vec3::ZERO,
    )
}

fn car_at(x: f64) -> Vec<ObjectPose> {
    vec![ObjectPose {
        id: 1,
        centre: Vec3::new(x, 1.0, 0.0),
        yaw: 0.0,
    }]
}

/// Frame truth: pixel 0 static ground 10 m ahead, pixel 1 on the car (at its centre).
fn frame(car_x: f64) -> Option<FrameMotionTruth> {
    Some(FrameMotionTruth {
        points: vec![
            Some(Vec3::new(10.0, 0.0, 0.0)),
            Some(Vec3::new(car_x, 1.0, 0.0)),
        ],
        instance: vec![0, 1],
        objects: car_at(car_x),
        world_to_camera: looking_along_x(),
    })
}

/// `[T_c = 2, N − 1 = 2, G = 2, 3]`: source 0 → targets 1, 2; source 1 → targets 0, 2.
#[rustfmt::skip]
const MOTIONS: [f32; 24] = [
    0.0, 0.0, 0.0,   0.0, 0.0, 0.5,  // 0→1: exact after the scale 2
    0.05, 0.0, 0.0,  0.0, 0.0, 1.0,  // 0→2: static off by 0.1 m, car 1 m short of 3 m
    0.0, 0.0, 0.0,   0.0, 0.0, -0.5, // 1→0: exact
    0.0, 0.0, 0.0,   0.0, 0.0, 0.0,  // 1→2: car predicted still (true 1 m)
];

/// Predicted means at half the true depth (the clip's scale is 2): camera axes = model world.
#[rustfmt::skip]
const MEANS: [f32; 12] = [
    0.0, 0.0, 5.0,  -0.5, 0.0, 2.5,
    0.0, 0.0, 5.0,  -0.5, 0.0, 3.0,
];

fn score(truth: &[Option<FrameMotionTruth>]) -> Option<MotionScore> {
    let extrinsics = [Mat4::IDENTITY; 3];
    let masks = vec![Some(vec![false, true]), Some(vec![false, true]), None];
    motion_score(
        &PredictedMotion {
            context: 2,
            frames: 3,
            grid: (1, 2),
            means: &MEANS,
            motions: &MOTIONS,
            extrinsics: &extrinsics,
        },
        &MotionTruth {
            size: (1, 2),
            frames: truth,
            masks: &masks,
        },
    )
}

fn close(a: Option<f64>, b: f64) -> bool {
    a.is_some_and(|a| (a - b).abs() < 1e-6)
}

/// Guards the flow metrics end to end on a hand-computed field: the median-depth scale (2),
/// the truth re-expressed in camera-0 axes (world +x is camera +z), the static/dynamic split,
/// the relative error, the future-pair means, and the mask IoU from the next-frame motion.
#[test]
fn hand_computed_flow_field() {
    // The car moves 1 m then 2 m along world +x (5 → 6 → 8): camera +z.
    let s = score(&[frame(5.0), frame(6.0), frame(8.0)]).expect("complete truth");
    assert!((s.flow_scale - 2.0).abs() < 1e-12, "{}", s.flow_scale);
    let pair = |i, j| {
        s.pairs
            .iter()
            .find(|p| p.source == i && p.target == j)
            .unwrap()
    };
    let p01 = pair(0, 1);
    assert!(
        close(p01.epe_dynamic, 0.0) && close(p01.epe_static, 0.0),
        "{p01:?}"
    );
    let p02 = pair(0, 2);
    assert_eq!((p02.dynamic_pixels, p02.static_pixels), (1, 1));
    assert!(close(p02.epe_dynamic, 1.0), "{p02:?}");
    assert!(close(p02.epe_static, 0.1), "{p02:?}");
    assert!(close(p02.true_displacement, 3.0), "{p02:?}");
    assert!(close(p02.rel_epe_dynamic, 1.0 / 3.0), "{p02:?}");
    let p12 = pair(1, 2);
    assert!(
        close(p12.epe_dynamic, 2.0) && close(p12.rel_epe_dynamic, 1.0),
        "{p12:?}"
    );
    assert!(close(pair(1, 0).epe_dynamic, 0.0));
    // Future pairs (0→2, 1→2) only.
    assert!(
        close(s.epe_dynamic, 1.5) && close(s.epe_static, 0.05),
        "{s:?}"
    );
    assert!(close(s.true_displacement, 2.5) && close(s.rel_epe_dynamic, 2.0 / 3.0));
    // Frame 0: the car moves 1 m to frame 1 in both: IoU 1. Frame 1: predicted still: 0.
    assert_eq!(s.per_frame_iou, vec![Some(1.0), Some(0.0)]);
    assert!(close(s.mask_iou, 0.5));
    let mean = mean_motion(&[&s, &s]).unwrap();
    assert!(close(mean.epe_dynamic, 1.5) && mean.pairs.len() == 4);
}

/// Guards "only where the data has the truth": a frame without truth gives no score rather
/// than a score over the wrong pixels.
#[test]
fn missing_truth_gives_no_score() {
    assert!(score(&[frame(5.0), None, frame(8.0)]).is_none());
}

/// Guards the IoU's edge cases: both masks empty is undefined (left out), disjoint is 0.
#[test]
fn iou_edges() {
    let f = [false, false];
    assert_eq!(iou(f.into_iter(), f.into_iter()), None);
    assert_eq!(
        iou([true, false].into_iter(), [false, true].into_iter()),
        Some(0.0)
    );
    assert_eq!(
        iou([true, true].into_iter(), [true, false].into_iter()),
        Some(0.5)
    );
}

/// Guards the grid map: a prediction made at a smaller input size reads the frame pixel its
/// centre falls in.
#[test]
fn smaller_prediction_grid_reads_covering_pixels() {
    assert_eq!(grid_map((1, 2), (2, 4)), vec![5, 7]);
    assert_eq!(grid_map((2, 2), (2, 2)), vec![0, 1, 2, 3]);
}

/// Guards the oracle-motion render's displacements: the exact flow brought back to the
/// prediction's own world axes (here not its camera axes) and unit (half a metre) scores zero
/// error and a perfect mask, and the car's steps come out along model-world +x.
#[test]
fn oracle_displacements_score_zero_error() {
    let truth = [frame(5.0), frame(6.0), frame(8.0)];
    // The model's world is the true world at half scale, its cameras look along +x too.
    let extrinsics = [looking_along_x(); 3];
    #[rustfmt::skip]
    let means: [f32; 12] = [
        5.0, 0.0, 0.0,  2.5, 0.5, 0.0,
        5.0, 0.0, 0.0,  3.0, 0.5, 0.0,
    ];
    let masks = vec![Some(vec![false, true]), Some(vec![false, true]), None];
    let t = MotionTruth {
        size: (1, 2),
        frames: &truth,
        masks: &masks,
    };
    let pred = |motions| PredictedMotion {
        context: 2,
        frames: 3,
        grid: (1, 2),
        means: &means,
        motions,
        extrinsics: &extrinsics,
    };
    let zeros = [0.0f32; 24];
    let still = pred(&zeros);
    let a = Aligned::new(&still, &t).expect("complete truth");
    assert!((a.scale - 2.0).abs() < 1e-12, "{}", a.scale);
    let oracle = crate::motion_scene::oracle_motions(&a);
    // Car along +x by 0.5 (0→1), 1.5 (0→2), −0.5 (1→0), 1.0 (1→2) model units; ground still.
    let car: Vec<f32> = oracle.chunks(3).skip(1).step_by(2).map(|c| c[0]).collect();
    assert_eq!(car, vec![0.5, 1.5, -0.5, 1.0]);
    assert!(oracle
        .chunks(3)
        .enumerate()
        .all(|(k, c)| c[1] == 0.0 && c[2] == 0.0 && (k % 2 == 1 || c[0] == 0.0)));
    let s = motion_score(&pred(&oracle), &t).expect("complete truth");
    assert!(
        close(s.epe_dynamic, 0.0) && close(s.epe_static, 0.0),
        "{s:?}"
    );
    assert!(
        close(s.rel_epe_dynamic, 0.0) && close(s.mask_iou, 1.0),
        "{s:?}"
    );
}
