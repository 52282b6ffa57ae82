//! Procedural textures: value noise, the ground (asphalt, markings, kerb, pavement,
//! grass) in road coordinates, and object materials in their local frames. All colours
//! are albedo in linear [0, 1]; texture detail gives the photometric tests something to
//! lock onto.

use super::road::{HALF_WIDTH, KERB_WIDTH, LANE_WIDTH, PAVEMENT_WIDTH};
use crate::geom::Vec3;

pub type Rgb = [f32; 3];

/// Surface kinds of objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    Paint(Rgb),
    Glass,
    /// Wall colour, window seed, floor height (m).
    Facade {
        wall: Rgb,
        seed: u32,
    },
    Roof,
    Bark,
    Foliage(Rgb),
    Metal,
    Cloth(Rgb),
    Skin,
    /// Horizontal bands (a truck's livery).
    Stripes(Rgb, Rgb),
}

const MARKING_HALF_WIDTH: f64 = 0.08;
const DASH_PERIOD: f64 = 9.0;
const DASH_LENGTH: f64 = 3.0;
const TILE: f64 = 0.6;
const FLOOR_HEIGHT: f64 = 3.0;
const WINDOW_PITCH: f64 = 2.4;

fn hash2(ix: i64, iy: i64, seed: u32) -> f32 {
    let mut h = (ix as u64).wrapping_mul(0x9E37_79B1_85EB_CA87)
        ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ u64::from(seed).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h & 0xFF_FFFF) as f32 / 0xFF_FFFF as f32
}

/// Smooth value noise in [0, 1] with unit lattice spacing.
pub fn noise2(x: f64, y: f64, seed: u32) -> f32 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let s = |t: f64| (t * t * (3.0 - 2.0 * t)) as f32;
    let (u, v) = (s(x - fx), s(y - fy));
    let a = hash2(ix, iy, seed) * (1.0 - u) + hash2(ix + 1, iy, seed) * u;
    let b = hash2(ix, iy + 1, seed) * (1.0 - u) + hash2(ix + 1, iy + 1, seed) * u;
    a * (1.0 - v) + b * v
}

/// Two octaves: coarse blotches plus fine grain.
fn grain(x: f64, y: f64, scale: f64, seed: u32) -> f32 {
    0.6 * noise2(x * scale, y * scale, seed)
        + 0.4 * noise2(x * scale * 4.0, y * scale * 4.0, seed + 1)
}

fn scale(c: Rgb, k: f32) -> Rgb {
    [c[0] * k, c[1] * k, c[2] * k]
}

/// Ground albedo at road coordinates (s, lateral) and world point (x, y).
pub fn ground(s: f64, lat: f64, x: f64, y: f64) -> Rgb {
    let a = lat.abs();
    if a < HALF_WIDTH {
        let asphalt = scale([0.22, 0.22, 0.24], 0.75 + 0.5 * grain(x, y, 1.3, 11));
        let centre = a < 2.0 * MARKING_HALF_WIDTH && (a > 0.04);
        let dashed =
            (a - LANE_WIDTH).abs() < MARKING_HALF_WIDTH && s.rem_euclid(DASH_PERIOD) < DASH_LENGTH;
        let edge = (a - (HALF_WIDTH - 0.3)).abs() < MARKING_HALF_WIDTH;
        if centre {
            return [0.85, 0.7, 0.15];
        }
        if dashed || edge {
            return scale([0.9, 0.9, 0.88], 0.9 + 0.1 * grain(x, y, 3.0, 5));
        }
        return asphalt;
    }
    if a < HALF_WIDTH + KERB_WIDTH {
        // Alternating kerb blocks, 1 m long.
        let light = s.rem_euclid(2.0) < 1.0;
        return if light {
            [0.75, 0.75, 0.72]
        } else {
            [0.55, 0.2, 0.18]
        };
    }
    if a < HALF_WIDTH + KERB_WIDTH + PAVEMENT_WIDTH {
        let (u, v) = ((s / TILE).rem_euclid(1.0), (a / TILE).rem_euclid(1.0));
        if u < 0.06 || v < 0.06 {
            return [0.35, 0.34, 0.32];
        }
        let tile = hash2((s / TILE).floor() as i64, (a / TILE).floor() as i64, 3);
        return scale([0.6, 0.58, 0.55], 0.85 + 0.25 * tile);
    }
    scale([0.25, 0.42, 0.15], 0.6 + 0.6 * grain(x, y, 0.7, 21))
}

/// Albedo of a material at a part-frame point with its part-frame normal.
pub fn albedo(m: &Material, p: Vec3, n: Vec3) -> Rgb {
    match *m {
        Material::Paint(c) => scale(c, 0.9 + 0.1 * noise2(p.x * 3.0, p.z * 3.0 + p.y, 7)),
        Material::Glass => [0.08, 0.1, 0.13],
        Material::Facade { wall, seed } => facade(wall, seed, p, n),
        Material::Roof => scale([0.3, 0.28, 0.27], 0.8 + 0.4 * grain(p.x, p.y, 1.0, 9)),
        Material::Bark => scale(
            [0.3, 0.2, 0.12],
            0.7 + 0.6 * noise2(p.z * 4.0, p.x * 8.0 + p.y * 8.0, 2),
        ),
        Material::Foliage(c) => scale(c, 0.5 + 0.9 * grain(p.x + p.z, p.y - p.z, 2.0, 4)),
        Material::Metal => scale([0.5, 0.5, 0.52], 0.9 + 0.2 * noise2(p.z * 2.0, 0.0, 8)),
        Material::Cloth(c) => scale(c, 0.85 + 0.3 * noise2(p.z * 6.0, p.x * 6.0, 6)),
        Material::Skin => [0.75, 0.55, 0.42],
        Material::Stripes(a, b) => {
            if (p.z * 1.5).rem_euclid(1.0) < 0.5 {
                a
            } else {
                b
            }
        }
    }
}

/// Walls with a grid of windows (floors and bays); the roof and floor faces are plain.
fn facade(wall: Rgb, seed: u32, p: Vec3, n: Vec3) -> Rgb {
    if n.z.abs() > 0.5 {
        return albedo(&Material::Roof, p, n);
    }
    // Horizontal coordinate along the face.
    let u = if n.x.abs() > 0.5 { p.y } else { p.x };
    let (floor, bay) = ((p.z / FLOOR_HEIGHT).floor(), (u / WINDOW_PITCH).floor());
    let (fv, fu) = (
        (p.z / FLOOR_HEIGHT).rem_euclid(1.0),
        (u / WINDOW_PITCH).rem_euclid(1.0),
    );
    let is_window =
        p.z > FLOOR_HEIGHT * 0.8 && (0.3..0.8).contains(&fv) && (0.2..0.8).contains(&fu);
    if is_window {
        let lit = hash2(floor as i64, bay as i64, seed);
        return [0.1 + 0.25 * lit, 0.12 + 0.22 * lit, 0.16 + 0.15 * lit];
    }
    scale(wall, 0.75 + 0.4 * grain(u, p.z, 1.5, seed))
}
