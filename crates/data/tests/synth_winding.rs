//! The winding preset exists to put ego rotation into every training window; these tests
//! hold it to that, and keep it inside the world (the bend must not end within a clip).

use envision4d_data::synth::{render_clip, Preset, SynthConfig};
use envision4d_data::Mat4;

/// Frames per clip: the longest clips the project trains on.
const FRAMES: usize = 24;
/// Yaw per frame the preset promises (degrees), with a little slack for the speed change.
const MIN_YAW_PER_FRAME_DEG: f64 = 0.3;
const MAX_YAW_PER_FRAME_DEG: f64 = 2.5;

/// Signed yaw (about the camera's y axis) of `b` relative to `a`, in degrees.
fn yaw_between(a: &Mat4, b: &Mat4) -> f64 {
    let r = b.mul(&a.rigid_inverse()).0;
    (r[0][2] - r[2][0]).atan2(r[0][0] + r[2][2]).to_degrees()
}

fn yaw_steps(seed: u64) -> Vec<f64> {
    let cfg = SynthConfig {
        width: 32,
        height: 24,
        frames: FRAMES,
        preset: Preset::Winding,
        seed,
        supersample: 1,
    };
    let clip = render_clip(&cfg, 0, || {}).unwrap();
    clip.cameras
        .windows(2)
        .map(|w| yaw_between(&w[0].world_to_camera, &w[1].world_to_camera))
        .collect()
}

/// Guards a "winding" preset that does not wind: every frame-to-frame step of every clip
/// turns by 0.3-2.5°, always the same way within a clip (the ego is in one bend from the
/// first frame to the last), and both directions occur across seeds.
#[test]
fn every_step_of_a_winding_clip_turns_one_way() {
    let mut signs = Vec::new();
    for seed in 0..8 {
        let steps = yaw_steps(seed);
        assert_eq!(steps.len(), FRAMES - 1);
        let sign = steps[0].signum();
        for (k, &y) in steps.iter().enumerate() {
            assert!(
                (MIN_YAW_PER_FRAME_DEG..=MAX_YAW_PER_FRAME_DEG).contains(&y.abs()),
                "seed {seed}, step {k}: yaw {y:.3}° outside the promised range"
            );
            assert_eq!(y.signum(), sign, "seed {seed}, step {k}: the bend reversed");
        }
        signs.push(sign);
    }
    assert!(
        signs.contains(&1.0) && signs.contains(&-1.0),
        "8 seeds all bend the same way: {signs:?}"
    );
}
