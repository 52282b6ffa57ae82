//! Ground-truth pose labels against the model's own pose decoder.

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::{Intrinsics, Mat4, Vec3};
use envision4d_model::pose::pose_encoding_to_extri_intri;
use envision4d_train::batch::pose_encodings;

/// World-to-camera matrix of a camera at `centre` turned by `yaw` about the world z axis
/// (up) and `pitch` about its own x axis, OpenCV axes (x right, y down, z forward).
fn camera(yaw: f64, pitch: f64, centre: Vec3) -> Mat4 {
    let (sy, cy) = yaw.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let forward = Vec3::new(cy * cp, sy * cp, -sp);
    let right = Vec3::new(sy, -cy, 0.0);
    let down = forward.cross(right);
    let r = [right.to_array(), down.to_array(), forward.to_array()];
    let t = Vec3::new(
        -(r[0][0] * centre.x + r[0][1] * centre.y + r[0][2] * centre.z),
        -(r[1][0] * centre.x + r[1][1] * centre.y + r[1][2] * centre.z),
        -(r[2][0] * centre.x + r[2][1] * centre.y + r[2][2] * centre.z),
    );
    Mat4::from_rt(r, t)
}

/// Guards the sign convention of the pose labels: a conjugated, scalar-first or
/// camera-to-world quaternion in `pose_encodings` would teach every turn backwards (the
/// model then learns no rotation at all, the camera loss and the rendering loss cancelling),
/// and the large-angle Shepperd branches (trace ≤ 0) would be wrong without a test.
#[test]
fn pose_labels_decode_to_the_relative_cameras() {
    let device = Device::default();
    let k = Intrinsics {
        fx: 80.0,
        fy: 78.0,
        cx: 42.0,
        cy: 28.0,
    };
    let first = camera(0.3, 0.03, Vec3::new(1.0, -2.0, 1.6));
    let others = [
        camera(0.3 + 0.05, 0.03, Vec3::new(1.6, -1.9, 1.6)), // a 2.9° turn
        camera(0.3 - 0.4, 0.1, Vec3::new(3.0, -1.0, 1.5)),
        camera(0.3 + 2.8, -0.2, Vec3::new(-4.0, 2.0, 1.7)), // nearly turned around
        camera(0.3 + std::f64::consts::PI, 0.0, Vec3::new(0.0, 0.0, 1.6)), // exactly 180°
    ];
    let cams: Vec<(Mat4, Intrinsics)> = std::iter::once(first)
        .chain(others)
        .map(|m| (m, k))
        .collect();
    let (h, w) = (56, 84);
    let enc = pose_encodings(&cams, h, w);
    let n = cams.len();
    let t = Tensor::<3>::from_data(TensorData::new(enc, [1, n, 9]), &device);
    let (extr, intr) = pose_encoding_to_extri_intri(t, h, w);
    let got: Vec<f64> = extr.into_data().iter::<f64>().collect();
    let first_inv = first.rigid_inverse();
    for (j, (m, _)) in cams.iter().enumerate() {
        let want = m.mul(&first_inv);
        for r in 0..4 {
            for c in 0..4 {
                let g = got[j * 16 + r * 4 + c];
                assert!(
                    (g - want.0[r][c]).abs() < 1e-4,
                    "camera {j} entry ({r},{c}): decoded {g}, relative pose {}",
                    want.0[r][c]
                );
            }
        }
    }
    let k_got: Vec<f64> = intr.into_data().iter::<f64>().collect();
    assert!((k_got[0] - k.fx).abs() < 1e-3 && (k_got[4] - k.fy).abs() < 1e-3);
}
