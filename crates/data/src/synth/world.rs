//! The scene: road, static scenery (buildings, trees, poles, parked cars), moving agents and
//! the light. Objects are built from parts in their own frame (x forward, y left, z up,
//! origin on the ground under the object's centre).

use super::motion::{EgoMotion, Motion, Pose};
use super::road::{Road, BUILDABLE_FROM, HALF_WIDTH, KERB_WIDTH};
use super::shapes::Shape;
use super::texture::{Material, Rgb};
use crate::geom::Vec3;
use crate::rng::Rng;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Building,
    Tree,
    Pole,
    ParkedCar,
    Car,
    Pedestrian,
    Truck,
}

impl Kind {
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Building => "building",
            Kind::Tree => "tree",
            Kind::Pole => "pole",
            Kind::ParkedCar => "parked_car",
            Kind::Car => "car",
            Kind::Pedestrian => "pedestrian",
            Kind::Truck => "truck",
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    pub offset: Vec3,
    pub shape: Shape,
    pub material: Material,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// 0 for static scenery; agents get 1, 2, ... (their value in the instance map).
    pub track_id: u16,
    pub kind: Kind,
    pub motion: Motion,
    /// Words for tracks.json, e.g. "braking".
    pub label: &'static str,
    pub parts: Vec<Part>,
    /// Box extents (length, width, height) containing every part, centred over the origin.
    pub size: [f64; 3],
    /// Bounding sphere (local centre, radius) for fast rejection.
    pub bound: (Vec3, f64),
}

impl Object {
    pub fn new(
        kind: Kind,
        motion: Motion,
        label: &'static str,
        parts: Vec<Part>,
        size: [f64; 3],
    ) -> Object {
        let centre = Vec3::new(0.0, 0.0, size[2] / 2.0);
        let radius = parts
            .iter()
            .map(|p| (p.offset - centre).norm() + p.shape.bound_radius())
            .fold(0.0, f64::max);
        Object {
            track_id: 0,
            kind,
            motion,
            label,
            parts,
            size,
            bound: (centre, radius),
        }
    }
}

/// Sun and sky. `sun_dir` points towards the sun.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    pub sun_dir: Vec3,
    pub sun: Rgb,
    pub ambient: Rgb,
    pub sky_horizon: Rgb,
    pub sky_zenith: Rgb,
}

#[derive(Debug, Clone, PartialEq)]
pub struct World {
    pub road: Road,
    pub objects: Vec<Object>,
    pub ego: EgoMotion,
    pub light: Lighting,
    /// Seconds between frames (10 Hz, like Waymo).
    pub dt: f64,
}

fn part(offset: [f64; 3], shape: Shape, material: Material) -> Part {
    Part {
        offset: Vec3::new(offset[0], offset[1], offset[2]),
        shape,
        material,
    }
}

fn cuboid(hx: f64, hy: f64, hz: f64) -> Shape {
    Shape::Box {
        half: Vec3::new(hx, hy, hz),
    }
}

pub const CAR_COLOURS: [Rgb; 6] = [
    [0.6, 0.08, 0.06],
    [0.1, 0.2, 0.55],
    [0.8, 0.8, 0.78],
    [0.08, 0.08, 0.09],
    [0.45, 0.47, 0.5],
    [0.75, 0.6, 0.1],
];

pub fn car(kind: Kind, colour: Rgb, motion: Motion, label: &'static str) -> Object {
    let parts = vec![
        part([0.0, 0.0, 0.2], cuboid(2.0, 0.8, 0.15), Material::Metal),
        part(
            [0.0, 0.0, 0.65],
            cuboid(2.2, 0.9, 0.3),
            Material::Paint(colour),
        ),
        part([-0.2, 0.0, 1.2], cuboid(1.2, 0.8, 0.25), Material::Glass),
        part(
            [-0.2, 0.0, 1.5],
            cuboid(1.1, 0.78, 0.05),
            Material::Paint(colour),
        ),
    ];
    Object::new(kind, motion, label, parts, [4.4, 1.8, 1.55])
}

pub fn pedestrian(cloth: Rgb, motion: Motion, label: &'static str) -> Object {
    let parts = vec![
        part(
            [0.0, 0.0, 0.72],
            Shape::Cylinder {
                radius: 0.22,
                half_height: 0.72,
            },
            Material::Cloth(cloth),
        ),
        part(
            [0.0, 0.0, 1.57],
            Shape::Sphere { radius: 0.12 },
            Material::Skin,
        ),
    ];
    Object::new(Kind::Pedestrian, motion, label, parts, [0.5, 0.5, 1.7])
}

pub fn truck(motion: Motion, label: &'static str) -> Object {
    let livery = Material::Stripes([0.85, 0.85, 0.8], [0.7, 0.15, 0.1]);
    let parts = vec![
        part([0.0, 0.0, 0.3], cuboid(4.8, 1.1, 0.2), Material::Metal),
        part([-1.1, 0.0, 2.0], cuboid(3.8, 1.25, 1.6), livery),
        part(
            [3.8, 0.0, 1.5],
            cuboid(1.1, 1.2, 1.3),
            Material::Paint([0.15, 0.3, 0.6]),
        ),
    ];
    Object::new(Kind::Truck, motion, label, parts, [9.8, 2.5, 3.6])
}

fn building(w: f64, d: f64, h: f64, wall: Rgb, seed: u32, pose: Pose) -> Object {
    let parts = vec![part(
        [0.0, 0.0, h / 2.0],
        cuboid(w / 2.0, d / 2.0, h / 2.0),
        Material::Facade { wall, seed },
    )];
    Object::new(
        Kind::Building,
        Motion::Fixed(pose),
        "static",
        parts,
        [w, d, h],
    )
}

fn tree(canopy: f64, leaf: Rgb, pose: Pose) -> Object {
    let trunk_h = 2.4;
    let parts = vec![
        part(
            [0.0, 0.0, trunk_h / 2.0],
            Shape::Cylinder {
                radius: 0.15,
                half_height: trunk_h / 2.0,
            },
            Material::Bark,
        ),
        part(
            [0.0, 0.0, trunk_h + canopy * 0.7],
            Shape::Sphere { radius: canopy },
            Material::Foliage(leaf),
        ),
    ];
    let size = [2.0 * canopy, 2.0 * canopy, trunk_h + 1.7 * canopy];
    Object::new(Kind::Tree, Motion::Fixed(pose), "static", parts, size)
}

fn pole(pose: Pose) -> Object {
    let parts = vec![
        part(
            [0.0, 0.0, 3.0],
            Shape::Cylinder {
                radius: 0.08,
                half_height: 3.0,
            },
            Material::Metal,
        ),
        part([0.0, 0.0, 6.05], cuboid(0.3, 0.3, 0.08), Material::Metal),
    ];
    Object::new(
        Kind::Pole,
        Motion::Fixed(pose),
        "static",
        parts,
        [0.6, 0.6, 6.2],
    )
}

/// Pose on the road at (s, lateral), facing along it.
pub fn road_pose(road: &Road, s: f64, lateral: f64) -> Pose {
    let rp = road.pose(s, lateral);
    Pose {
        position: Vec3::new(rp.x, rp.y, 0.0),
        yaw: rp.heading,
    }
}

/// True when no corner of a (length x width) footprint at `pose` comes within
/// `min_lateral` of the road centreline (keeps scenery off the road on bends).
fn clear_of_road(road: &Road, pose: &Pose, length: f64, width: f64, min_lateral: f64) -> bool {
    let (s, c) = pose.yaw.sin_cos();
    [
        (-1.0, -1.0),
        (-1.0, 1.0),
        (1.0, -1.0),
        (1.0, 1.0),
        (0.0, 0.0),
    ]
    .iter()
    .all(|(a, b)| {
        let (lx, ly) = (a * length / 2.0, b * width / 2.0);
        let x = pose.position.x + lx * c - ly * s;
        let y = pose.position.y + lx * s + ly * c;
        road.coords(x, y).1.abs() >= min_lateral
    })
}

const WALLS: [Rgb; 5] = [
    [0.7, 0.62, 0.5],
    [0.55, 0.35, 0.28],
    [0.8, 0.78, 0.72],
    [0.45, 0.48, 0.52],
    [0.65, 0.55, 0.4],
];

/// Buildings, trees, poles and parked cars along both sides of the road for s in range.
pub fn scenery(road: &Road, rng: &mut Rng, s_from: f64, s_to: f64) -> Vec<Object> {
    let mut out = Vec::new();
    for side in [-1.0, 1.0] {
        let mut s = s_from + rng.range(0.0, 6.0);
        while s < s_to {
            let (w, d, h) = (
                rng.range(8.0, 18.0),
                rng.range(8.0, 14.0),
                rng.range(6.0, 22.0),
            );
            let lateral = side * (BUILDABLE_FROM + rng.range(0.5, 3.0) + d / 2.0);
            let pose = road_pose(road, s + w / 2.0, lateral);
            if clear_of_road(road, &pose, w, d, BUILDABLE_FROM - 0.2) {
                let wall = WALLS[rng.below(WALLS.len())];
                out.push(building(w, d, h, wall, rng.next_u64() as u32, pose));
            }
            s += w + rng.range(1.0, 6.0);
        }
        let mut s = s_from + rng.range(0.0, 10.0);
        while s < s_to {
            let lateral = side * (HALF_WIDTH + KERB_WIDTH + rng.range(0.8, 2.2));
            let pose = road_pose(road, s, lateral);
            if clear_of_road(road, &pose, 0.6, 0.6, HALF_WIDTH + KERB_WIDTH + 0.4) {
                let obj = match rng.below(4) {
                    0 | 1 => tree(
                        rng.range(1.2, 2.2),
                        [0.2, rng.range(0.35, 0.5) as f32, 0.12],
                        pose,
                    ),
                    2 => pole(pose),
                    _ => {
                        let colour = CAR_COLOURS[rng.below(CAR_COLOURS.len())];
                        let park = road_pose(road, s, side * (HALF_WIDTH + KERB_WIDTH + 1.1));
                        car(Kind::ParkedCar, colour, Motion::Fixed(park), "parked")
                    }
                };
                out.push(obj);
            }
            s += rng.range(8.0, 16.0);
        }
    }
    out
}
