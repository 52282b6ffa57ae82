//! The motion suite's presets must be what they claim: simple ego motion (standing, or
//! straight at constant speed), visible movers, and each preset's motion type in its tracks.

use envision4d_data::layout::synth::Track;
use envision4d_data::synth::footprint::footprint;
use envision4d_data::synth::{render_clip, ClipRender, Preset, SynthConfig};
use envision4d_data::Vec3;

const FRAMES: usize = 8;

fn clip(preset: Preset, index: u64) -> ClipRender {
    let cfg = SynthConfig {
        width: 84,
        height: 56,
        frames: FRAMES,
        preset,
        seed: 3,
        supersample: 1,
    };
    render_clip(&cfg, index, || {}).unwrap()
}

fn centre(tr: &Track, t: usize) -> Vec3 {
    let p = tr.states[t].position;
    Vec3::new(p[0], p[1], p[2])
}

/// Largest change of a track's per-frame displacement over the clip (metres per frame per
/// frame): 0 for constant velocity.
fn max_second_difference(tr: &Track) -> f64 {
    (1..FRAMES - 1)
        .map(|t| (centre(tr, t + 1) - centre(tr, t) * 2.0 + centre(tr, t - 1)).norm())
        .fold(0.0, f64::max)
}

/// Guards the suite's ego motion: in every clip the camera either stands or moves by the same
/// step every frame without turning, and both kinds occur.
#[test]
fn ego_stands_or_drives_straight_at_constant_speed() {
    let (mut standing, mut driving) = (0, 0);
    for preset in Preset::MOTION_SUITE {
        for index in 0..4 {
            let c = clip(preset, index);
            let centres: Vec<Vec3> = c
                .cameras
                .iter()
                .map(|cam| {
                    let inv = cam.world_to_camera.rigid_inverse();
                    Vec3::new(inv.0[0][3], inv.0[1][3], inv.0[2][3])
                })
                .collect();
            let step = centres[1] - centres[0];
            for t in 1..FRAMES {
                let d = centres[t] - centres[t - 1];
                assert!(
                    (d - step).norm() < 1e-9,
                    "{preset:?} {index}: ego step varies"
                );
                let r = c.cameras[t].world_to_camera.rotation();
                let r0 = c.cameras[0].world_to_camera.rotation();
                assert!((r - r0).abs_diff_eq(glam::DMat3::ZERO, 1e-12), "ego turns");
            }
            if step.norm() == 0.0 {
                standing += 1;
            } else {
                driving += 1;
            }
        }
    }
    assert!(
        standing > 0 && driving > 0,
        "{standing} standing, {driving} driving"
    );
}

/// Guards each preset's motion type: the control's movers have constant velocity (second
/// differences ~0), accelerating and stop-and-go movers change speed, turning movers change
/// heading every frame, crossing movers move across the road; and every preset shows movers.
#[test]
fn each_preset_has_its_motion_type() {
    for preset in Preset::MOTION_SUITE {
        let c = clip(preset, 1);
        let movers: Vec<&Track> = c.tracks.iter().collect();
        assert!(movers.len() >= 3, "{preset:?}: {} movers", movers.len());
        assert!(footprint(&c).sightings > 0, "{preset:?}: no mover in view");
        let curvy = movers
            .iter()
            .map(|t| max_second_difference(t))
            .fold(0.0, f64::max);
        let turns = movers
            .iter()
            .map(|t| (t.states[1].yaw - t.states[0].yaw).abs())
            .fold(0.0, f64::max);
        match preset {
            Preset::MotionConstant | Preset::MotionCrossing => {
                assert!(curvy < 1e-9, "{preset:?}: second difference {curvy}");
                assert!(turns < 1e-12, "{preset:?}: turns {turns}");
            }
            // 2 m/s² over 0.1 s frames is 0.02 m per frame per frame.
            Preset::MotionAccelerating | Preset::MotionStopAndGo => {
                assert!(curvy > 0.015, "{preset:?}: second difference {curvy}");
            }
            Preset::MotionTurning => {
                assert!(turns > 0.02, "{preset:?}: heading step {turns}");
                assert!(curvy > 0.01, "{preset:?}: second difference {curvy}");
            }
            _ => unreachable!(),
        }
        if preset == Preset::MotionCrossing {
            // Across the road: the movers' displacement is mostly along world y.
            for t in &movers {
                let d = centre(t, 1) - centre(t, 0);
                assert!(d.y.abs() > 5.0 * d.x.abs(), "{preset:?}: {d:?}");
            }
        }
    }
}
