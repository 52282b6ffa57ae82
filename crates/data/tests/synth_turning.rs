//! The winding, look-around and stopped-pan presets exist to put camera rotation into every
//! training window; these tests hold them to that.

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

fn cameras(preset: Preset, seed: u64) -> Vec<Mat4> {
    let cfg = SynthConfig {
        width: 32,
        height: 24,
        frames: FRAMES,
        preset,
        seed,
        supersample: 1,
    };
    let clip = render_clip(&cfg, 0, || {}).unwrap();
    clip.cameras.iter().map(|c| c.world_to_camera).collect()
}

fn yaw_steps_of(cams: &[Mat4]) -> Vec<f64> {
    cams.windows(2).map(|w| yaw_between(&w[0], &w[1])).collect()
}

fn yaw_steps(seed: u64) -> Vec<f64> {
    yaw_steps_of(&cameras(Preset::Winding, seed))
}

fn centre(m: &Mat4) -> [f64; 3] {
    let c = m.rigid_inverse().0;
    [c[0][3], c[1][3], c[2][3]]
}

/// Guards a look-around preset that is not the urban world with a panning camera: for the
/// same seed the camera centres are urban's (the vehicle drives the same path), the yaw
/// rate changes within a clip (a pan, not a bend), stays under 3.5° per frame and reaches
/// 0.5° somewhere in every clip.
#[test]
fn look_around_pans_the_urban_camera() {
    for seed in 0..6 {
        let (urban, look) = (
            cameras(Preset::Urban, seed),
            cameras(Preset::LookAround, seed),
        );
        for (k, (u, l)) in urban.iter().zip(&look).enumerate() {
            let (a, b) = (centre(u), centre(l));
            let d = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
            assert!(d < 1e-9, "seed {seed}, frame {k}: centres {d} m apart");
        }
        let extra: Vec<f64> = yaw_steps_of(&look)
            .iter()
            .zip(yaw_steps_of(&urban))
            .map(|(l, u)| l - u)
            .collect();
        let max = extra.iter().fold(0.0f64, |m, y| m.max(y.abs()));
        assert!(
            (0.5..3.5).contains(&max),
            "seed {seed}: largest pan step {max:.3}°"
        );
        let (lo, hi) = extra
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &y| (lo.min(y), hi.max(y)));
        assert!(
            hi - lo > 0.3,
            "seed {seed}: pan rate constant ({lo:.3}..{hi:.3})"
        );
    }
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

/// Guards a stopped-pan preset whose ego still drives: every camera centre of a clip is the
/// first one, and the camera turns (only rotation is left to see).
#[test]
fn stopped_pan_only_rotates() {
    for seed in 0..4 {
        let cams = cameras(Preset::StoppedPan, seed);
        let c0 = centre(&cams[0]);
        for (k, m) in cams.iter().enumerate() {
            let c = centre(m);
            let d = (0..3).map(|i| (c[i] - c0[i]).powi(2)).sum::<f64>().sqrt();
            assert!(d < 1e-9, "seed {seed}, frame {k}: the camera moved {d} m");
        }
        let max = yaw_steps_of(&cams)
            .iter()
            .fold(0.0f64, |m, y| m.max(y.abs()));
        assert!(
            (0.5..3.5).contains(&max),
            "seed {seed}: largest pan step {max:.3}°"
        );
    }
}
