//! The oracle's frame algebra on a constructed clip whose model frame is neither the true
//! world nor metric.

use super::*;
use crate::motion::{read3, MotionTruth, PredictedMotion};
use envision4d_data::{FrameMotionTruth, ObjectPose, Vec3};
use glam::{DMat3, DMat4, DVec3};

/// A camera at `(x, 0, 1.5)` looking along world +x (OpenCV axes, world z up).
fn camera_at(x: f64) -> Mat4 {
    let r = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]];
    let c = DVec3::new(x, 0.0, 1.5);
    let rm = DMat3::from_cols_array_2d(&r).transpose();
    let t = -(rm * c);
    Mat4::from_rt(r, Vec3::new(t.x, t.y, t.z))
}

/// Frame `j`: the camera drives 0.7 m per frame; a car turns (its yaw grows 0.2 rad per
/// frame) while moving diagonally; pixel 0 sees the ground, pixels 1 and 2 the car.
fn frame(j: usize) -> Option<FrameMotionTruth> {
    let jf = j as f64;
    let centre = Vec3::new(12.0 + 1.1 * jf, 2.0 - 0.4 * jf, 0.8);
    let yaw = 0.3 + 0.2 * jf;
    let on_car = |dx: f64, dy: f64| {
        let (s, c) = yaw.sin_cos();
        Vec3::new(centre.x + c * dx - s * dy, centre.y + s * dx + c * dy, 1.0)
    };
    Some(FrameMotionTruth {
        points: vec![
            Some(Vec3::new(9.0, -1.0, 0.0)),
            Some(on_car(1.0, 0.5)),
            Some(on_car(-1.5, 0.0)),
        ],
        instance: vec![0, 7, 7],
        objects: vec![ObjectPose { id: 7, centre, yaw }],
        world_to_camera: camera_at(0.7 * jf),
    })
}

fn dv(v: Vec3) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}

/// Guards the oracle renders' geometry: a Gaussian placed where the model's frame puts the
/// true surface (rotated, shifted and at 1/2.5 of metric scale), moved by the oracle's
/// displacement and seen through the oracle's true camera, lands exactly where the true
/// surface point, moved by the exact flow, is seen by the true camera (camera coordinates
/// shrink by the scale, so pixels agree). A wrong inverse rotation, a scale on the wrong
/// side or a translation left metric each break it by metres.
#[test]
fn oracle_motion_and_true_cameras_reproduce_the_true_future_view() {
    let (tc, n, s) = (2usize, 4usize, 2.5f64);
    let truth: Vec<_> = (0..n).map(frame).collect();
    // The model's frame-0 camera: any rigid map; model world = true frame-0 camera / s,
    // pulled back through it.
    let e0 = DMat4::from_rotation_translation(
        glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -0.9, 0.2),
        DVec3::new(0.3, -2.0, 1.1),
    );
    let w0 = truth[0].as_ref().unwrap().world_to_camera.to_glam();
    let to_model = |p: DVec3| e0.inverse().transform_point3(w0.transform_point3(p) / s);
    let mut means = Vec::new();
    for f in truth.iter().take(tc) {
        for p in &f.as_ref().unwrap().points {
            let m = to_model(dv(p.unwrap()));
            means.extend([m.x as f32, m.y as f32, m.z as f32]);
        }
    }
    let extrinsics = vec![Mat4::from_glam(e0); n];
    let zeros = vec![0.0f32; tc * (n - 1) * 3 * 3];
    let masks = vec![None; n];
    let pred = PredictedMotion {
        context: tc,
        frames: n,
        grid: (1, 3),
        means: &means,
        motions: &zeros,
        extrinsics: &extrinsics,
    };
    let t = MotionTruth {
        size: (1, 3),
        frames: &truth,
        masks: &masks,
    };
    let a = Aligned::new(&pred, &t).expect("complete truth");
    assert!((a.scale - s).abs() < 1e-6, "{}", a.scale);
    let oracle = oracle_motions(&a);
    let cams = true_cameras(&a);
    for i in 0..tc {
        let fi = truth[i].as_ref().unwrap();
        for j in (0..n).filter(|&j| j != i) {
            let flow = fi.flow_to(&truth[j].as_ref().unwrap().objects);
            let wj = truth[j].as_ref().unwrap().world_to_camera.to_glam();
            for k in 0..3 {
                let moved_true = dv(fi.points[k].unwrap()) + dv(flow[k].unwrap());
                let want = wj.transform_point3(moved_true) / s;
                let slot = (i * (n - 1) + envision4d_model::motion::target_slot(i, j)) * 3 + k;
                let m = read3(&means, i * 3 + k) + read3(&oracle, slot);
                let got = cams[j].to_glam().transform_point3(m);
                assert!(
                    (got - want).length() < 1e-5,
                    "{i}->{j} px {k}: {got} vs {want}"
                );
            }
        }
    }
}
