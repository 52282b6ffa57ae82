//! The motion suite: worlds where object motion dominates and the ego motion is simple, one
//! motion type per preset, so the paper's motion claims (§3.3, §4.3: time-conditioned motion
//! beats linear velocities on non-linear movers and ties on constant velocity) can be tested
//! per motion type against exact truth.
//!
//! The road is straight; the ego either stands (waiting) or drives its lane at a constant
//! speed, half of the clips each, so the camera motion is zero or a constant translation.
//! Movers are placed 6-20 m ahead in the lanes beside the ego's and across the road, where
//! they cover the most pixels; the ego's own lane gets a mover only when the ego stands.

use super::motion::{EgoMotion, LookAround, Motion};
use super::preset::{
    cloth, colour, lane, lighting, Preset, CAMERA_HEIGHT, CAMERA_PITCH, FRAME_INTERVAL_S,
    SCENERY_AHEAD, SCENERY_BEHIND,
};
use super::road::{right_lane, Road};
use super::world::{car, pedestrian, road_pose, scenery, Kind, Object, World};
use crate::rng::Rng;
use std::f64::consts::TAU;

/// The motion type of a suite preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SuiteMotion {
    /// Every mover at a constant speed on a straight line: the control, where a linear
    /// velocity model is exact.
    Constant,
    /// Movers along the lanes that brake hard or accelerate (±2-5 m/s²).
    Accelerating,
    /// Movers on circular arcs at constant speed (radius 4-7 m): curved, not faster.
    Turning,
    /// Cars and pedestrians crossing the road ahead at constant speed: linear in the world,
    /// but across the view, the largest image motion per metre.
    Crossing,
    /// Queued traffic: speed between standstill and 4-8 m/s, period 1.5-3 s.
    StopAndGo,
}

/// Ego speed range (m/s) of the clips where the ego drives.
const EGO_SPEED: (f64, f64) = (4.0, 9.0);
/// Fraction of clips where the ego stands.
const EGO_STANDS: f64 = 0.5;
/// Where movers start, metres ahead of the ego (before the ego's own travel is added).
const NEAR: (f64, f64) = (6.0, 20.0);
/// Turning radius range of the arcs (m) and their speed (m/s).
const ARC_RADIUS: (f64, f64) = (4.0, 7.0);
const ARC_SPEED: (f64, f64) = (3.0, 7.0);
/// Crossing movers start up to this far beside the centreline (m), on the side they come
/// from: the kerb is at 7.3 m.
const CROSSING_START_M: f64 = 8.0;
/// Stop-and-go peak speed (m/s) and period (s).
const STOP_GO_PEAK: (f64, f64) = (4.0, 8.0);
const STOP_GO_PERIOD: (f64, f64) = (1.5, 3.0);

impl Preset {
    /// The suite motion type of a motion-suite preset, `None` for the others.
    pub fn suite_motion(self) -> Option<SuiteMotion> {
        match self {
            Preset::MotionConstant => Some(SuiteMotion::Constant),
            Preset::MotionAccelerating => Some(SuiteMotion::Accelerating),
            Preset::MotionTurning => Some(SuiteMotion::Turning),
            Preset::MotionCrossing => Some(SuiteMotion::Crossing),
            Preset::MotionStopAndGo => Some(SuiteMotion::StopAndGo),
            _ => None,
        }
    }
}

/// A mover's start, `NEAR` ahead of where the ego is halfway through the clip, so it stays in
/// view while the ego drives.
fn ahead(rng: &mut Rng, ego_mid: f64) -> f64 {
    ego_mid + rng.range(NEAR.0, NEAR.1)
}

fn stop_go(rng: &mut Rng, s0: f64, direction: f64, lateral: f64) -> Motion {
    Motion::StopGo {
        s0,
        v_peak: rng.range(STOP_GO_PEAK.0, STOP_GO_PEAK.1),
        omega: TAU / rng.range(STOP_GO_PERIOD.0, STOP_GO_PERIOD.1),
        phase: rng.range(0.0, TAU),
        direction,
        lateral,
    }
}

/// A car turning about a centre beside the road at constant speed, either way round.
fn arc(rng: &mut Rng, road: &Road, s: f64, lateral: f64) -> Motion {
    let c = road_pose(road, s, lateral);
    let radius = rng.range(ARC_RADIUS.0, ARC_RADIUS.1);
    let speed = rng.range(ARC_SPEED.0, ARC_SPEED.1);
    Motion::Arc {
        centre: c.position,
        radius,
        angle0: rng.range(0.0, TAU),
        omega0: rng.sign() * speed / radius,
        alpha: 0.0,
    }
}

/// Crossing at constant speed, starting anywhere from the kerb to a lane beyond the ego's
/// (movers that start at the kerb stay out of view at 8-15 m for most of a clip).
fn crossing_at(rng: &mut Rng, s: f64, speed: (f64, f64)) -> Motion {
    let direction = rng.sign();
    Motion::Crossing {
        s,
        lateral0: -direction * rng.range(0.0, CROSSING_START_M),
        direction,
        speed: rng.range(speed.0, speed.1),
        accel: 0.0,
        wobble: 0.0,
        period: 1.0,
    }
}

fn add_car(out: &mut Vec<Object>, rng: &mut Rng, m: Motion, label: &'static str) {
    out.push(car(Kind::Car, colour(rng), m, label));
}

/// The movers of one suite clip.
fn movers(kind: SuiteMotion, road: &Road, rng: &mut Rng, ego_v: f64, mid: f64) -> Vec<Object> {
    let (own, right, oncoming, far_oncoming) =
        (right_lane(0), right_lane(1), -right_lane(0), -right_lane(1));
    let standing = ego_v == 0.0;
    let mut out = Vec::new();
    match kind {
        SuiteMotion::Constant => {
            let mut lanes = vec![(right, 1.0, 0.0), (oncoming, -1.0, 10.0)];
            if standing {
                lanes.push((own, 1.0, 0.0));
            }
            for (lateral, dir, extra) in lanes {
                let s = ahead(rng, mid) + extra;
                let v = rng.range(3.0, 8.0);
                add_car(
                    &mut out,
                    rng,
                    lane(s, v, 0.0, dir, lateral, lateral, 0.0),
                    "constant",
                );
            }
            let s = ahead(rng, mid);
            let walker = crossing_at(rng, s, (1.0, 1.8));
            out.push(pedestrian(cloth(rng), walker, "constant, crossing"));
        }
        SuiteMotion::Accelerating => {
            // (lane, direction, start speed, acceleration, extra distance)
            let mut movers = vec![
                (right, 1.0, (6.0, 10.0), (-5.0, -3.0), 0.0),
                (oncoming, -1.0, (0.0, 3.0), (2.0, 4.0), 0.0),
                (far_oncoming, -1.0, (2.0, 5.0), (2.0, 4.0), 8.0),
            ];
            if standing {
                movers.push((own, 1.0, (5.0, 8.0), (-5.0, -2.0), 0.0));
            }
            for (lateral, dir, v0, a, extra) in movers {
                let s = ahead(rng, mid) + extra;
                let (v, acc) = (rng.range(v0.0, v0.1), rng.range(a.0, a.1));
                let label = if acc < 0.0 { "braking" } else { "accelerating" };
                add_car(
                    &mut out,
                    rng,
                    lane(s, v, acc, dir, lateral, lateral, 0.0),
                    label,
                );
            }
        }
        SuiteMotion::Turning => {
            for (lateral, extra) in [(-3.0, 4.0), (3.0, 4.0), (0.0, 12.0)] {
                let s = ahead(rng, mid) + extra;
                let m = arc(rng, road, s, lateral);
                add_car(&mut out, rng, m, "turning arc");
            }
        }
        SuiteMotion::Crossing => {
            for _ in 0..2 {
                let s = ahead(rng, mid) + 4.0;
                let m = crossing_at(rng, s, (3.0, 7.0));
                add_car(&mut out, rng, m, "crossing");
            }
            for _ in 0..2 {
                let s = ahead(rng, mid);
                let m = crossing_at(rng, s, (1.0, 1.8));
                out.push(pedestrian(cloth(rng), m, "crossing"));
            }
        }
        SuiteMotion::StopAndGo => {
            let mut lanes = vec![(right, 1.0), (oncoming, -1.0), (far_oncoming, -1.0)];
            if standing {
                lanes.push((own, 1.0));
            }
            for (lateral, dir) in lanes {
                let s = ahead(rng, mid);
                let m = stop_go(rng, s, dir, lateral);
                add_car(&mut out, rng, m, "stop-and-go");
            }
        }
    }
    out
}

/// Builds the world of one suite clip from its own RNG stream.
pub fn build_world(preset: Preset, kind: SuiteMotion, rng: &mut Rng, frames: usize) -> World {
    let ego_v = if rng.coin(EGO_STANDS) {
        0.0
    } else {
        rng.range(EGO_SPEED.0, EGO_SPEED.1)
    };
    // Straight: the bend starts far beyond anything the camera sees.
    let road = Road::with_bend(-SCENERY_BEHIND - 10.0, 1.0e4, 1.0, 0.0);
    let duration = frames as f64 * FRAME_INTERVAL_S;
    let ego_reach = ego_v * duration;
    let mut objects = scenery(&road, rng, -SCENERY_BEHIND, ego_reach + SCENERY_AHEAD);
    for (i, mut m) in movers(kind, &road, rng, ego_v, ego_reach / 2.0)
        .into_iter()
        .enumerate()
    {
        m.track_id = (i + 1) as u16;
        objects.push(m);
    }
    let light = lighting(preset, rng);
    World {
        road,
        objects,
        ego: EgoMotion {
            lane: lane(0.0, ego_v, 0.0, 1.0, right_lane(0), right_lane(0), 0.0),
            camera_height: CAMERA_HEIGHT,
            pitch: CAMERA_PITCH,
            look: LookAround::default(),
        },
        light,
        dt: FRAME_INTERVAL_S,
    }
}
