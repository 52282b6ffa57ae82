//! Difficulty presets: each picks the road, the ego speed profile, the agents and the light.

use super::motion::{EgoMotion, LookAround, Motion};
use super::road::{right_lane, Road, HALF_WIDTH, KERB_WIDTH};
use super::world::{
    car, pedestrian, road_pose, scenery, truck, Kind, Lighting, Object, World, CAR_COLOURS,
};
use crate::geom::Vec3;
use crate::rng::Rng;
use std::f64::consts::FRAC_PI_2;

pub use super::preset_kind::Preset;

/// 10 Hz, like the Waymo front camera.
pub const FRAME_INTERVAL_S: f64 = 0.1;
pub(super) const CAMERA_HEIGHT: f64 = 1.6;
pub(super) const CAMERA_PITCH: f64 = 0.03;
/// Radius range of the winding preset's bend; with its 5-9 m/s ego that is a yaw rate of
/// 0.4-2° per 10 Hz frame.
const WINDING_RADIUS_M: (f64, f64) = (25.0, 70.0);
/// Pan amplitude and period of the look-around preset: up to ~3° of yaw per frame, the
/// size of the sharp-turn bends, so that the signal is a few pixels at 56x84.
const LOOK_AMPLITUDE_DEG: (f64, f64) = (2.0, 6.0);
const LOOK_PERIOD_S: (f64, f64) = (1.2, 2.5);
/// Scenery this far behind and beyond the ego's path.
pub(super) const SCENERY_BEHIND: f64 = 40.0;
pub(super) const SCENERY_AHEAD: f64 = 160.0;

pub(super) fn lane(
    s0: f64,
    v0: f64,
    accel: f64,
    dir: f64,
    from: f64,
    to: f64,
    change_start: f64,
) -> Motion {
    Motion::Lane {
        s0,
        v0,
        accel,
        v_max: 30.0,
        direction: dir,
        lane_from: from,
        lane_to: to,
        change_start,
        change_time: 1.5,
    }
}

fn crossing(s: f64, from_right: bool, speed: f64, accel: f64, wobble: f64) -> Motion {
    let edge = HALF_WIDTH + KERB_WIDTH + 1.5;
    Motion::Crossing {
        s,
        lateral0: if from_right { -edge } else { edge },
        direction: if from_right { 1.0 } else { -1.0 },
        speed,
        accel,
        wobble,
        period: 1.3,
    }
}

pub(super) fn cloth(rng: &mut Rng) -> [f32; 3] {
    [
        rng.range(0.1, 0.8) as f32,
        rng.range(0.1, 0.6) as f32,
        rng.range(0.1, 0.8) as f32,
    ]
}

pub(super) fn colour(rng: &mut Rng) -> [f32; 3] {
    CAR_COLOURS[rng.below(CAR_COLOURS.len())]
}

/// The moving agents of a preset (track ids assigned by the caller).
fn agents(preset: Preset, road: &Road, rng: &mut Rng, ego_v: f64) -> Vec<Object> {
    let (l0, l1) = (right_lane(0), right_lane(1));
    let mut out = Vec::new();
    let urban = |rng: &mut Rng, out: &mut Vec<Object>, s_base: f64| {
        let lead = lane(
            s_base + rng.range(12.0, 22.0),
            ego_v,
            rng.range(-3.0, -1.5),
            1.0,
            l0,
            l0,
            0.0,
        );
        out.push(car(Kind::Car, colour(rng), lead, "braking"));
        let changer = lane(
            s_base + rng.range(4.0, 14.0),
            ego_v * 0.8,
            rng.range(1.0, 2.5),
            1.0,
            l1,
            l0,
            rng.range(0.0, 0.4),
        );
        out.push(car(
            Kind::Car,
            colour(rng),
            changer,
            "accelerating, lane change",
        ));
        let oncoming = lane(
            s_base + rng.range(45.0, 70.0),
            rng.range(8.0, 12.0),
            rng.range(-1.0, 1.0),
            -1.0,
            -l0,
            -l0,
            0.0,
        );
        out.push(car(
            Kind::Car,
            colour(rng),
            oncoming,
            "oncoming, speed change",
        ));
        let c = road_pose(road, s_base + rng.range(30.0, 40.0), 0.0);
        let r = -l1;
        let turner = Motion::Arc {
            centre: c.position,
            radius: r,
            angle0: c.yaw - FRAC_PI_2,
            omega0: rng.range(4.0, 6.0) / r,
            alpha: rng.range(-0.4, -0.1),
        };
        out.push(car(Kind::Car, colour(rng), turner, "turning arc (U-turn)"));
        let walker = crossing(
            s_base + rng.range(18.0, 30.0),
            rng.coin(0.5),
            rng.range(1.0, 1.6),
            0.2,
            0.35,
        );
        out.push(pedestrian(cloth(rng), walker, "crossing"));
        let stroll = lane(
            s_base + rng.range(5.0, 25.0),
            1.3,
            rng.range(-0.3, 0.3),
            rng.sign(),
            -(HALF_WIDTH + KERB_WIDTH + 1.8),
            -(HALF_WIDTH + KERB_WIDTH + 1.8),
            0.0,
        );
        out.push(pedestrian(cloth(rng), stroll, "walking, speed change"));
    };
    match preset {
        Preset::Static => {}
        // Built by `suite::build_world`, never here.
        Preset::MotionConstant
        | Preset::MotionAccelerating
        | Preset::MotionTurning
        | Preset::MotionCrossing
        | Preset::MotionStopAndGo => {}
        Preset::Urban
        | Preset::LowLight
        | Preset::Winding
        | Preset::LookAround
        | Preset::StoppedPan => urban(rng, &mut out, 0.0),
        Preset::SharpTurn => {
            let oncoming = lane(
                rng.range(25.0, 35.0),
                6.0,
                rng.range(-1.0, 0.5),
                -1.0,
                -l0,
                -l0,
                0.0,
            );
            out.push(car(
                Kind::Car,
                colour(rng),
                oncoming,
                "oncoming through the bend",
            ));
            let lead = lane(rng.range(10.0, 14.0), 6.0, -1.5, 1.0, l0, l0, 0.0);
            out.push(car(Kind::Car, colour(rng), lead, "braking in the bend"));
            let walker = crossing(rng.range(12.0, 20.0), rng.coin(0.5), 1.4, 0.0, 0.4);
            out.push(pedestrian(cloth(rng), walker, "crossing"));
        }
        Preset::FastApproach => {
            let fast = lane(
                rng.range(60.0, 80.0),
                rng.range(22.0, 28.0),
                rng.range(-4.0, -2.0),
                -1.0,
                -l0,
                -l0,
                0.0,
            );
            out.push(car(Kind::Car, colour(rng), fast, "fast oncoming, braking"));
            let second = lane(rng.range(80.0, 100.0), 15.0, 1.5, -1.0, -l1, -l0, 0.5);
            out.push(car(Kind::Car, colour(rng), second, "oncoming, lane change"));
        }
        Preset::FarSmallMovers => {
            for i in 0..4 {
                let s0 = rng.range(60.0, 130.0);
                let lat = [l0, l1, -l0, -l1][i];
                let dir = if lat < 0.0 { 1.0 } else { -1.0 };
                let m = lane(
                    s0,
                    rng.range(5.0, 12.0),
                    rng.range(-2.0, 2.0),
                    dir,
                    lat,
                    lat,
                    0.0,
                );
                out.push(car(Kind::Car, colour(rng), m, "far, speed change"));
            }
            for _ in 0..3 {
                let m = crossing(
                    rng.range(50.0, 90.0),
                    rng.coin(0.5),
                    rng.range(1.0, 1.8),
                    0.3,
                    0.4,
                );
                out.push(pedestrian(cloth(rng), m, "far, crossing"));
            }
        }
        Preset::CrossingTruck => {
            let m = crossing(
                rng.range(16.0, 22.0),
                rng.coin(0.5),
                rng.range(2.0, 4.0),
                rng.range(0.8, 1.5),
                0.05,
            );
            out.push(truck(m, "crossing, accelerating"));
            let walker = crossing(rng.range(25.0, 35.0), rng.coin(0.5), 1.3, 0.0, 0.3);
            out.push(pedestrian(cloth(rng), walker, "crossing"));
        }
    }
    out
}

pub(super) fn lighting(preset: Preset, rng: &mut Rng) -> Lighting {
    let az = rng.range(0.0, std::f64::consts::TAU);
    if preset == Preset::LowLight {
        let el: f64 = 0.07;
        return Lighting {
            sun_dir: Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()),
            sun: [0.45, 0.28, 0.15],
            ambient: [0.07, 0.08, 0.12],
            sky_horizon: [0.2, 0.13, 0.12],
            sky_zenith: [0.02, 0.03, 0.08],
        };
    }
    let el = rng.range(0.4, 1.0);
    Lighting {
        sun_dir: Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()),
        sun: [1.0, 0.95, 0.85],
        ambient: [0.35, 0.38, 0.45],
        sky_horizon: [0.75, 0.82, 0.9],
        sky_zenith: [0.25, 0.45, 0.8],
    }
}

/// Builds the world of one clip from its own RNG stream.
pub fn build_world(preset: Preset, rng: &mut Rng, frames: usize) -> World {
    if let Some(kind) = preset.suite_motion() {
        return super::suite::build_world(preset, kind, rng, frames);
    }
    let left = rng.sign();
    let (turn_at, turn_len, curvature, ego_v, ego_a) = match preset {
        Preset::SharpTurn => (
            rng.range(3.0, 8.0),
            24.0,
            left / 15.0,
            6.0,
            rng.range(-0.6, 0.3),
        ),
        Preset::FarSmallMovers => (30.0, 40.0, left / rng.range(200.0, 400.0), 5.0, 0.0),
        Preset::CrossingTruck => (40.0, 30.0, left / 300.0, 7.0, rng.range(-2.0, -1.0)),
        Preset::Winding => {
            let radius = rng.range(WINDING_RADIUS_M.0, WINDING_RADIUS_M.1);
            (
                rng.range(-12.0, -2.0),
                // A quarter circle at most: a longer arc would bring the scenery placed
                // along the exit straight back across the road already driven.
                radius * FRAC_PI_2,
                left / radius,
                rng.range(5.0, 9.0),
                rng.range(-0.5, 0.5),
            )
        }
        _ => (
            rng.range(0.0, 20.0),
            60.0,
            left / rng.range(80.0, 200.0),
            rng.range(7.0, 11.0),
            rng.range(-1.5, 1.5),
        ),
    };
    // Drawn like urban's (the same road for a seed), then parked.
    let (ego_v, ego_a) = match preset {
        Preset::StoppedPan => (0.0, 0.0),
        _ => (ego_v, ego_a),
    };
    let road = Road::with_bend(-SCENERY_BEHIND - 10.0, turn_at, turn_len, curvature);
    let ego_lane = lane(0.0, ego_v, ego_a, 1.0, right_lane(0), right_lane(0), 0.0);
    let duration = frames as f64 * FRAME_INTERVAL_S;
    let ego_reach = ego_v * duration + 0.5 * ego_a.max(0.0) * duration * duration;
    let mut objects = scenery(&road, rng, -SCENERY_BEHIND, ego_reach + SCENERY_AHEAD);
    for (i, mut agent) in agents(preset, &road, rng, ego_v).into_iter().enumerate() {
        agent.track_id = (i + 1) as u16;
        objects.push(agent);
    }
    let light = lighting(preset, rng);
    // Drawn last, and only here, so every other preset's worlds stay byte-identical.
    let look = match preset {
        Preset::LookAround | Preset::StoppedPan => LookAround {
            amplitude: rng
                .range(LOOK_AMPLITUDE_DEG.0, LOOK_AMPLITUDE_DEG.1)
                .to_radians(),
            omega: std::f64::consts::TAU / rng.range(LOOK_PERIOD_S.0, LOOK_PERIOD_S.1),
            phase: rng.range(0.0, std::f64::consts::TAU),
        },
        _ => LookAround::default(),
    };
    World {
        road,
        objects,
        ego: EgoMotion {
            lane: ego_lane,
            camera_height: CAMERA_HEIGHT,
            pitch: CAMERA_PITCH,
            look,
        },
        light,
        dt: FRAME_INTERVAL_S,
    }
}
