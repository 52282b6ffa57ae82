//! Camera AUC@30 on constructed pose sets with known errors.

use envision4d_losses::{
    auc_from_errors, camera_auc30, relative_pose_errors, Extrinsic, LossError,
    AUC_MAX_THRESHOLD_DEG,
};

/// World-to-camera `[Rz(deg) | t]`.
fn rz(deg: f64, t: [f64; 3]) -> Extrinsic {
    let (s, c) = deg.to_radians().sin_cos();
    [[c, -s, 0.0, t[0]], [s, c, 0.0, t[1]], [0.0, 0.0, 1.0, t[2]]]
}

/// `E · G` for a world transform `G = [Rx(deg) | g]` (changes only the world frame).
fn reframe(e: &Extrinsic, deg: f64, g: [f64; 3]) -> Extrinsic {
    let (s, c) = deg.to_radians().sin_cos();
    let gm = [
        [1.0, 0.0, 0.0, g[0]],
        [0.0, c, -s, g[1]],
        [0.0, s, c, g[2]],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut out = [[0.0; 4]; 3];
    for r in 0..3 {
        for col in 0..4 {
            // Row r of E in homogeneous form is (e[r][0], e[r][1], e[r][2], e[r][3]).
            out[r][col] = (0..4).map(|k| e[r][k] * gm[k][col]).sum();
        }
    }
    out
}

/// Cameras rotating about z, centres on the z axis (so translation directions agree):
/// gt yaw 20°·k, prediction yaw 20°·k + step·k → pair (i, j) rotation error step·(j − i).
fn poses(step: f64, n: usize) -> (Vec<Extrinsic>, Vec<Extrinsic>) {
    let t = |k: usize| [0.0, 0.0, -(k as f64 + 1.0)];
    let gt = (0..n).map(|k| rz(20.0 * k as f64, t(k))).collect();
    let pred = (0..n).map(|k| rz((20.0 + step) * k as f64, t(k))).collect();
    (pred, gt)
}

/// Guards the AUC histogram (numpy bins [k, k+1), last bin closed, > 30 not counted).
#[test]
fn auc_from_known_errors() {
    let t = AUC_MAX_THRESHOLD_DEG;
    assert!((auc_from_errors(&[15.0; 6], t).unwrap() - 0.5).abs() < 1e-12);
    assert_eq!(auc_from_errors(&[0.0; 3], t).unwrap(), 1.0);
    assert_eq!(auc_from_errors(&[31.0, 1e6], t).unwrap(), 0.0);
    assert!((auc_from_errors(&[30.0], t).unwrap() - 1.0 / 30.0).abs() < 1e-12);
    assert!((auc_from_errors(&[29.5], t).unwrap() - 1.0 / 30.0).abs() < 1e-12);
    // Half the pairs perfect, half out of range.
    assert!((auc_from_errors(&[0.2, 45.0], t).unwrap() - 0.5).abs() < 1e-12);
    assert!(auc_from_errors(&[], t).is_err());
    assert!(auc_from_errors(&[f64::NAN], t).is_err());
}

/// Guards the pose path: a 15° relative rotation error on every pair gives AUC 0.5 ± one bin.
#[test]
fn all_pairs_fifteen_degrees() {
    let (pred, gt) = poses(15.0, 2);
    let errs = relative_pose_errors(&pred, &gt).unwrap();
    assert_eq!(errs.len(), 1);
    assert!((errs[0].rotation_deg - 15.0).abs() < 1e-6, "{errs:?}");
    assert!(errs[0].translation_deg < 1e-3, "{errs:?}");
    let auc = camera_auc30(&pred, &gt).unwrap();
    assert!((auc - 0.5).abs() <= 1.0 / 30.0 + 1e-12, "{auc}");
}

/// Guards all-pairs enumeration, world-frame invariance and the
/// scale-free translation term on a 4-frame clip with errors 7.5°·(j − i).
#[test]
fn four_frame_clip_with_known_errors() {
    let (pred, gt) = poses(7.5, 4);
    let errs = relative_pose_errors(&pred, &gt).unwrap();
    let pairs: Vec<(usize, usize)> = errs.iter().map(|e| (e.i, e.j)).collect();
    assert_eq!(pairs, vec![(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]);
    for e in &errs {
        assert!(
            (e.rotation_deg - 7.5 * (e.j - e.i) as f64).abs() < 1e-6,
            "{e:?}"
        );
        assert!(e.translation_deg < 1e-3, "{e:?}");
    }
    // Errors 7.5 (×3), 15 (×2), 22.5: cumulative 0.5 on bins 7..14, 5/6 on 15..21, 1 on 22..29.
    let want = (8.0 * 0.5 + 7.0 * 5.0 / 6.0 + 8.0) / 30.0;
    let auc = camera_auc30(&pred, &gt).unwrap();
    assert!((auc - want).abs() < 1e-12, "{auc} vs {want}");

    // Another world frame for the prediction and a different scale change nothing.
    let moved: Vec<Extrinsic> = pred
        .iter()
        .map(|e| {
            let mut m = reframe(e, 33.0, [1.0, -2.0, 0.5]);
            for row in &mut m {
                row[3] *= 3.0;
            }
            m
        })
        .collect();
    let again = relative_pose_errors(&moved, &gt).unwrap();
    for (a, b) in errs.iter().zip(&again) {
        assert!((a.max_deg() - b.max_deg()).abs() < 1e-6, "{a:?} vs {b:?}");
    }
}

/// Guards the pair convention (VGGT's `E_i·E_j⁻¹`, not `E_i⁻¹·E_j`): the translation of a
/// pair is camera j's centre seen from camera i, so a prediction that gets camera 2's centre
/// right in camera 1's frame but its rotation wrong has no translation error, only rotation.
#[test]
fn pair_translation_is_seen_from_the_first_camera() {
    let gt = vec![
        rz(0.0, [0.0; 3]),
        rz(90.0, [0.0; 3]),
        rz(90.0, [-1.0, 0.0, 0.0]),
    ];
    let pred = vec![
        rz(0.0, [0.0; 3]),
        rz(90.0, [0.0; 3]),
        rz(0.0, [0.0, -1.0, 0.0]),
    ];
    let errs = relative_pose_errors(&pred, &gt).unwrap();
    let e12 = errs.iter().find(|e| (e.i, e.j) == (1, 2)).unwrap();
    // E_1·E_2⁻¹: gt t = (1, 0, 0); pred t = −Rz(90)·(0, −1, 0) = (−1, 0, 0): the same line.
    assert!(e12.translation_deg < 1e-4, "{e12:?}");
    assert!((e12.rotation_deg - 90.0).abs() < 1e-6, "{e12:?}");
}

/// Guards the identical-camera case: a pair of equal, not quite orthonormal cameras (f32
/// predictions) has no translation, so its direction error is 90°, not the 0° the rounding
/// residue of `E·E⁻¹` would give (which scored a copy-last baseline AUC 100).
#[test]
fn identical_cameras_have_no_translation_direction() {
    // Rotation scaled by (1 + 1e-7), as float32 round-off leaves it, and a translation.
    let k = 1.0 + 1e-7;
    let (s, c) = (0.3f64.sin() * k, 0.3f64.cos() * k);
    let p1 = [[c, -s, 0.0, 0.1], [s, c, 0.0, 0.2], [0.0, 0.0, k, -1.3]];
    let g = |z: f64| rz(0.0, [0.0, 0.0, -z]);
    let pred = vec![rz(0.0, [0.0; 3]), p1, p1];
    let gt = vec![g(0.0), g(0.1), g(1.3)];
    let errs = relative_pose_errors(&pred, &gt).unwrap();
    let e12 = errs.iter().find(|e| (e.i, e.j) == (1, 2)).unwrap();
    assert!((e12.translation_deg - 90.0).abs() < 1e-6, "{e12:?}");
}

/// Guards invalid pose input: NaN, one frame, mismatched counts.
#[test]
fn bad_pose_inputs_are_errors() {
    let (mut pred, gt) = poses(5.0, 3);
    assert!(matches!(
        camera_auc30(&pred[..1], &gt[..1]),
        Err(LossError::Invalid { .. })
    ));
    assert!(matches!(
        camera_auc30(&pred[..2], &gt),
        Err(LossError::ShapeMismatch { .. })
    ));
    pred[1][0][3] = f64::NAN;
    assert!(matches!(
        camera_auc30(&pred, &gt),
        Err(LossError::NonFinite { .. })
    ));
}
