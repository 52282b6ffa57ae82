//! The road: a centreline of straight and constant-curvature pieces in the ground plane
//! (world z = 0), with road coordinates (s along the centreline, lateral offset to the
//! left). Lanes: driving on the right, ego lanes at negative offsets.

use std::f64::consts::PI;

pub const LANE_WIDTH: f64 = 3.5;
pub const LANES_PER_SIDE: usize = 2;
pub const HALF_WIDTH: f64 = LANE_WIDTH * LANES_PER_SIDE as f64;
pub const KERB_WIDTH: f64 = 0.3;
pub const PAVEMENT_WIDTH: f64 = 3.5;
/// Lateral offset where the pavement ends and buildings may begin.
pub const BUILDABLE_FROM: f64 = HALF_WIDTH + KERB_WIDTH + PAVEMENT_WIDTH;

/// Lateral offset of the centre of lane `i` (0 = nearest the centre line) on the right side.
pub fn right_lane(i: usize) -> f64 {
    -(LANE_WIDTH * (i as f64 + 0.5))
}

/// A point of the centreline with its heading (radians from world +x, counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadPose {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
}

/// One piece: starts at arc length `s0` and pose `start`, `length` long, `curvature` 1/m
/// (positive turns left, 0 = straight).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    s0: f64,
    start: RoadPose,
    length: f64,
    curvature: f64,
}

const STRAIGHT_EPS: f64 = 1e-9;

impl Piece {
    fn pose_at(&self, s_local: f64, lateral: f64) -> RoadPose {
        let h0 = self.start.heading;
        if self.curvature.abs() < STRAIGHT_EPS {
            let (sh, ch) = h0.sin_cos();
            return RoadPose {
                x: self.start.x + s_local * ch - lateral * sh,
                y: self.start.y + s_local * sh + lateral * ch,
                heading: h0,
            };
        }
        let k = self.curvature;
        let (cx, cy) = self.centre();
        let h = h0 + k * s_local;
        let rho = 1.0 / k - lateral;
        RoadPose {
            x: cx + rho * h.sin(),
            y: cy - rho * h.cos(),
            heading: h,
        }
    }
    fn centre(&self) -> (f64, f64) {
        let (sh, ch) = self.start.heading.sin_cos();
        let r = 1.0 / self.curvature;
        (self.start.x - r * sh, self.start.y + r * ch)
    }
    /// (s_local, lateral) of a ground point.
    fn coords(&self, x: f64, y: f64) -> (f64, f64) {
        let h0 = self.start.heading;
        if self.curvature.abs() < STRAIGHT_EPS {
            let (sh, ch) = h0.sin_cos();
            let (dx, dy) = (x - self.start.x, y - self.start.y);
            return (dx * ch + dy * sh, -dx * sh + dy * ch);
        }
        let k = self.curvature;
        let (cx, cy) = self.centre();
        let (vx, vy) = (x - cx, y - cy);
        let rho = (vx * vx + vy * vy).sqrt();
        let (h, lateral) = if k > 0.0 {
            (vx.atan2(-vy), 1.0 / k - rho)
        } else {
            ((-vx).atan2(vy), 1.0 / k + rho)
        };
        let dh = wrap_angle(h - h0);
        (dh / k, lateral)
    }
    fn end(&self) -> RoadPose {
        self.pose_at(self.length, 0.0)
    }
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}

#[derive(Debug, Clone, PartialEq)]
pub struct Road {
    pieces: Vec<Piece>,
}

impl Road {
    /// A straight run from s = `s_start` to `turn_at`, a bend of `turn_length` metres with
    /// `curvature`, then a long straight. The first and last pieces extend without end.
    pub fn with_bend(s_start: f64, turn_at: f64, turn_length: f64, curvature: f64) -> Road {
        let first = Piece {
            s0: s_start,
            start: RoadPose {
                x: s_start,
                y: 0.0,
                heading: 0.0,
            },
            length: turn_at - s_start,
            curvature: 0.0,
        };
        let bend = Piece {
            s0: turn_at,
            start: first.end(),
            length: turn_length,
            curvature,
        };
        let last = Piece {
            s0: turn_at + turn_length,
            start: bend.end(),
            length: f64::INFINITY,
            curvature: 0.0,
        };
        Road {
            pieces: vec![first, bend, last],
        }
    }

    fn piece_for(&self, s: f64) -> &Piece {
        self.pieces
            .iter()
            .rev()
            .find(|p| s >= p.s0)
            .unwrap_or(&self.pieces[0])
    }

    /// World pose at road coordinates (s, lateral).
    pub fn pose(&self, s: f64, lateral: f64) -> RoadPose {
        let p = self.piece_for(s);
        p.pose_at(s - p.s0, lateral)
    }

    /// Road coordinates (s, lateral) of a ground point: the piece whose span contains the
    /// projection with the smallest |lateral| (the two end pieces extend without end).
    pub fn coords(&self, x: f64, y: f64) -> (f64, f64) {
        let last = self.pieces.len() - 1;
        let mut best: Option<(f64, f64)> = None;
        for (i, p) in self.pieces.iter().enumerate() {
            let (sl, lat) = p.coords(x, y);
            let inside = (sl >= 0.0 || i == 0) && (sl <= p.length || i == last);
            // A bend's far side (beyond its centre) is not part of the road.
            let sane = p.curvature.abs() < STRAIGHT_EPS || lat.abs() < 1.0 / p.curvature.abs();
            if inside && sane && best.is_none_or(|(_, b)| lat.abs() < b.abs()) {
                best = Some((p.s0 + sl, lat));
            }
        }
        best.unwrap_or_else(|| {
            let (sl, lat) = self.pieces[0].coords(x, y);
            (self.pieces[0].s0 + sl, lat)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the road-coordinate inverse: coords(pose(s, l)) == (s, l) on straights and
    /// on left and right bends (texture and placement both depend on it).
    #[test]
    fn coords_invert_pose() {
        for k in [0.0, 1.0 / 15.0, -1.0 / 40.0] {
            let road = Road::with_bend(-50.0, 10.0, 20.0, k);
            for s in [-20.0, 0.0, 15.0, 25.0, 60.0] {
                for l in [-6.0, -1.0, 0.0, 3.0] {
                    let p = road.pose(s, l);
                    let (s2, l2) = road.coords(p.x, p.y);
                    assert!(
                        (s - s2).abs() < 1e-9 && (l - l2).abs() < 1e-9,
                        "k {k} s {s} l {l}: {s2} {l2}"
                    );
                }
            }
        }
    }
}
