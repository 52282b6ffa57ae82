//! How things move: the ego camera and agents, all as closed-form functions of time, so
//! any frame (and the next one, for scene flow) is exact. Agent motions are non-linear on
//! purpose (constant-velocity extrapolation must be measurably wrong), except the motion
//! suite's control preset, which drives `Lane` and `Crossing` at constant speed.

use super::road::Road;
use crate::geom::Vec3;
use std::f64::consts::FRAC_PI_2;

/// Ground position (z = 0 under the object) and heading about world +z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub position: Vec3,
    pub yaw: f64,
}

/// Distance travelled after `t` s from speed `v0` with acceleration `a`; stops at 0 speed
/// (braking never reverses) and never exceeds `v_max`.
fn travelled(v0: f64, a: f64, v_max: f64, t: f64) -> f64 {
    if a < 0.0 {
        let t_stop = v0 / -a;
        let tt = t.min(t_stop);
        return v0 * tt + 0.5 * a * tt * tt;
    }
    if a > 0.0 && v0 < v_max {
        let t_max = (v_max - v0) / a;
        if t > t_max {
            return v0 * t_max + 0.5 * a * t_max * t_max + v_max * (t - t_max);
        }
        return v0 * t + 0.5 * a * t * t;
    }
    v0 * t
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// Not moving (parked or placed).
    Fixed(Pose),
    /// Along the road: speed change (`accel`), optional lane change from `lane_from` to
    /// `lane_to` during [`change_start`, `change_start + change_time`]; `direction` -1 drives
    /// against increasing s (oncoming traffic).
    Lane {
        s0: f64,
        v0: f64,
        accel: f64,
        v_max: f64,
        direction: f64,
        lane_from: f64,
        lane_to: f64,
        change_start: f64,
        change_time: f64,
    },
    /// A turning arc about a fixed centre, angular speed changing linearly in time.
    Arc {
        centre: Vec3,
        radius: f64,
        angle0: f64,
        omega0: f64,
        alpha: f64,
    },
    /// Crossing the road at `s` from `lateral0` in `direction` (+1 left, -1 right) with a
    /// speed that surges and slows (`wobble` fraction of `speed`, period `period`).
    Crossing {
        s: f64,
        lateral0: f64,
        direction: f64,
        speed: f64,
        accel: f64,
        wobble: f64,
        period: f64,
    },
    /// Stop-and-go along the road at lateral offset `lateral`: speed
    /// `v_peak·(1 − cos(omega·t + phase))/2`, from standstill to `v_peak` and back every
    /// `2π/omega` seconds (traffic in a queue).
    StopGo {
        s0: f64,
        v_peak: f64,
        omega: f64,
        phase: f64,
        direction: f64,
        lateral: f64,
    },
}

/// Distance a stop-and-go agent has covered after `t` s (the integral of its speed).
fn stop_go_distance(v_peak: f64, omega: f64, phase: f64, t: f64) -> f64 {
    0.5 * v_peak * (t - ((omega * t + phase).sin() - phase.sin()) / omega)
}

impl Motion {
    pub fn pose(&self, road: &Road, t: f64) -> Pose {
        match *self {
            Motion::Fixed(p) => p,
            Motion::Lane {
                s0,
                v0,
                accel,
                v_max,
                direction,
                lane_from,
                lane_to,
                change_start,
                change_time,
            } => {
                let s = s0 + direction * travelled(v0, accel, v_max, t);
                let blend = |tt: f64| {
                    let u = smoothstep((tt - change_start) / change_time.max(1e-6));
                    lane_from + (lane_to - lane_from) * u
                };
                let lat = blend(t);
                let rp = road.pose(s, lat);
                // Heading follows the road, tilted by the lateral drift rate over the
                // forward speed (exact derivative of the blend, by central difference).
                let eps = 1e-3;
                let dlat = (blend(t + eps) - blend(t - eps)) / (2.0 * eps);
                let v = (travelled(v0, accel, v_max, t + eps)
                    - travelled(v0, accel, v_max, t - eps))
                    / (2.0 * eps);
                let tilt = if v > 0.1 { (dlat / v).atan() } else { 0.0 };
                let base = if direction < 0.0 {
                    rp.heading + std::f64::consts::PI
                } else {
                    rp.heading
                };
                Pose {
                    position: Vec3::new(rp.x, rp.y, 0.0),
                    yaw: base + direction * tilt,
                }
            }
            Motion::Arc {
                centre,
                radius,
                angle0,
                omega0,
                alpha,
            } => {
                let a = angle0 + omega0 * t + 0.5 * alpha * t * t;
                let omega = omega0 + alpha * t;
                let sign = if omega >= 0.0 { 1.0 } else { -1.0 };
                Pose {
                    position: centre + Vec3::new(radius * a.cos(), radius * a.sin(), 0.0),
                    yaw: a + sign * FRAC_PI_2,
                }
            }
            Motion::Crossing {
                s,
                lateral0,
                direction,
                speed,
                accel,
                wobble,
                period,
            } => {
                let w = 2.0 * std::f64::consts::PI / period;
                // d/dt of (speed t + wobble speed / w (1 - cos w t)) stays >= speed (1 - wobble) > 0.
                let dist = speed * t + 0.5 * accel * t * t + wobble * speed / w * (w * t).sin();
                let rp = road.pose(s, lateral0 + direction * dist);
                Pose {
                    position: Vec3::new(rp.x, rp.y, 0.0),
                    yaw: rp.heading + direction * FRAC_PI_2,
                }
            }
            Motion::StopGo {
                s0,
                v_peak,
                omega,
                phase,
                direction,
                lateral,
            } => {
                let s = s0 + direction * stop_go_distance(v_peak, omega, phase, t);
                let rp = road.pose(s, lateral);
                let back = if direction < 0.0 {
                    std::f64::consts::PI
                } else {
                    0.0
                };
                Pose {
                    position: Vec3::new(rp.x, rp.y, 0.0),
                    yaw: rp.heading + back,
                }
            }
        }
    }
}

/// The ego vehicle: drives its lane with a speed profile; the camera sits on it.
#[derive(Debug, Clone, PartialEq)]
pub struct EgoMotion {
    pub lane: Motion,
    pub camera_height: f64,
    /// Downward pitch of the camera, radians.
    pub pitch: f64,
    /// The camera turning on its mount, added to the vehicle's heading.
    pub look: LookAround,
}

/// A camera that pans left and right on its mount: yaw `amplitude·sin(omega·t + phase)`
/// (radians) on top of the vehicle's heading. Zero amplitude is a fixed mount.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LookAround {
    pub amplitude: f64,
    pub omega: f64,
    pub phase: f64,
}

impl LookAround {
    /// Extra camera yaw at `t_s` seconds, radians.
    pub fn yaw(&self, t_s: f64) -> f64 {
        if self.amplitude == 0.0 {
            return 0.0;
        }
        self.amplitude * (self.omega * t_s + self.phase).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the stop-and-go distance: it is the integral of the stated speed (checked by
    /// finite differences) and never decreases (a queue never reverses).
    #[test]
    fn stop_go_distance_integrates_its_speed() {
        let (v, w, ph) = (6.0, 2.5, 0.7);
        let mut last = stop_go_distance(v, w, ph, 0.0);
        assert_eq!(last, 0.0);
        for k in 1..200 {
            let t = k as f64 * 0.01;
            let d = stop_go_distance(v, w, ph, t);
            assert!(d >= last - 1e-12, "moved backwards at {t}");
            let h = 1e-5;
            let speed =
                (stop_go_distance(v, w, ph, t + h) - stop_go_distance(v, w, ph, t - h)) / (2.0 * h);
            let want = v * (1.0 - (w * t + ph).cos()) / 2.0;
            assert!(
                (speed - want).abs() < 1e-6,
                "speed {speed} vs {want} at {t}"
            );
            last = d;
        }
    }
}
