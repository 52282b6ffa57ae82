//! Analytic ray intersections in an object's local frame (z up): axis-aligned boxes,
//! vertical cylinders and spheres. Ray directions need not be unit length, so the hit
//! parameter `t` keeps whatever scale the caller chose (the tracer uses camera z-depth).

use crate::geom::Vec3;

/// A ray `origin + t * dir`.
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// A primitive centred at the origin of its part frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Half extents along x, y, z.
    Box {
        half: Vec3,
    },
    /// Axis along z, from -half_height to +half_height, with caps.
    Cylinder {
        radius: f64,
        half_height: f64,
    },
    Sphere {
        radius: f64,
    },
}

/// A hit: ray parameter and the outward normal (part frame).
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    pub t: f64,
    pub normal: Vec3,
}

impl Shape {
    /// Radius of a sphere around the origin that contains the shape.
    pub fn bound_radius(&self) -> f64 {
        match *self {
            Shape::Box { half } => half.norm(),
            Shape::Cylinder {
                radius,
                half_height,
            } => (radius * radius + half_height * half_height).sqrt(),
            Shape::Sphere { radius } => radius,
        }
    }

    /// Nearest hit with t in (t_min, t_max).
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        match *self {
            Shape::Box { half } => intersect_box(ray, half, t_min, t_max),
            Shape::Cylinder {
                radius,
                half_height,
            } => intersect_cylinder(ray, radius, half_height, t_min, t_max),
            Shape::Sphere { radius } => {
                let t = sphere_t(ray, Vec3::ZERO, radius, t_min, t_max)?;
                Some(Hit {
                    t,
                    normal: ray.at(t).normalized(),
                })
            }
        }
    }
}

/// Nearest t in (t_min, t_max) where the ray meets a sphere.
pub fn sphere_t(ray: &Ray, centre: Vec3, radius: f64, t_min: f64, t_max: f64) -> Option<f64> {
    let oc = ray.origin - centre;
    let a = ray.dir.dot(ray.dir);
    let b = oc.dot(ray.dir);
    let c = oc.dot(oc) - radius * radius;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    [(-b - sq) / a, (-b + sq) / a]
        .into_iter()
        .find(|&t| t > t_min && t < t_max)
}

/// Slab test; the normal is the face the entry (or, from inside, exit) crossed.
fn intersect_box(ray: &Ray, half: Vec3, t_min: f64, t_max: f64) -> Option<Hit> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut axis0, mut axis1) = (0, 0);
    for axis in 0..3 {
        let o = ray.origin.get(axis);
        let d = ray.dir.get(axis);
        let h = half.get(axis);
        if d.abs() < 1e-12 {
            if o.abs() > h {
                return None;
            }
            continue;
        }
        let (mut a, mut b) = ((-h - o) / d, (h - o) / d);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        if a > t0 {
            t0 = a;
            axis0 = axis;
        }
        if b < t1 {
            t1 = b;
            axis1 = axis;
        }
        if t0 > t1 {
            return None;
        }
    }
    let (t, axis) = if t0 > t_min { (t0, axis0) } else { (t1, axis1) };
    if t <= t_min || t >= t_max {
        return None;
    }
    let p = ray.at(t);
    let mut n = [0.0; 3];
    n[axis] = p.get(axis).signum();
    Some(Hit {
        t,
        normal: Vec3::new(n[0], n[1], n[2]),
    })
}

fn intersect_cylinder(ray: &Ray, r: f64, hh: f64, t_min: f64, t_max: f64) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut consider = |t: f64, normal: Vec3| {
        if t > t_min && t < t_max && best.is_none_or(|b| t < b.t) {
            best = Some(Hit { t, normal });
        }
    };
    // Side: x^2 + y^2 = r^2 with |z| <= hh.
    let (ox, oy, dx, dy) = (ray.origin.x, ray.origin.y, ray.dir.x, ray.dir.y);
    let a = dx * dx + dy * dy;
    if a > 1e-18 {
        let b = ox * dx + oy * dy;
        let c = ox * ox + oy * oy - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            for t in [(-b - sq) / a, (-b + sq) / a] {
                let p = ray.at(t);
                if p.z.abs() <= hh {
                    consider(t, Vec3::new(p.x / r, p.y / r, 0.0));
                }
            }
        }
    }
    // Caps: z = +-hh inside the disc.
    if ray.dir.z.abs() > 1e-12 {
        for (z, nz) in [(hh, 1.0), (-hh, -1.0)] {
            let t = (z - ray.origin.z) / ray.dir.z;
            let p = ray.at(t);
            if p.x * p.x + p.y * p.y <= r * r {
                consider(t, Vec3::new(0.0, 0.0, nz));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray {
            origin: Vec3::new(o[0], o[1], o[2]),
            dir: Vec3::new(d[0], d[1], d[2]),
        }
    }

    /// Guards each primitive's hit distance and normal on axis-aligned rays, including a
    /// non-unit direction (t must scale with it: the tracer relies on t = z-depth).
    #[test]
    fn primitive_hits() {
        let boxed = Shape::Box {
            half: Vec3::new(1.0, 2.0, 3.0),
        };
        let h = boxed
            .intersect(&ray([-5.0, 0.0, 0.0], [2.0, 0.0, 0.0]), 0.0, 1e9)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-12 && h.normal.x == -1.0);
        let cyl = Shape::Cylinder {
            radius: 1.0,
            half_height: 1.0,
        };
        let h = cyl
            .intersect(&ray([0.0, -3.0, 0.5], [0.0, 1.0, 0.0]), 0.0, 1e9)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-12 && (h.normal.y + 1.0).abs() < 1e-12);
        let h = cyl
            .intersect(&ray([0.2, 0.0, 5.0], [0.0, 0.0, -1.0]), 0.0, 1e9)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-12 && h.normal.z == 1.0);
        assert!(cyl
            .intersect(&ray([0.0, -3.0, 1.5], [0.0, 1.0, 0.0]), 0.0, 1e9)
            .is_none());
        let sph = Shape::Sphere { radius: 1.0 };
        let h = sph
            .intersect(&ray([0.0, 0.0, -3.0], [0.0, 0.0, 1.0]), 0.0, 1e9)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-12 && h.normal.z == -1.0);
        assert!(sph
            .intersect(&ray([0.0, 2.0, -3.0], [0.0, 0.0, 1.0]), 0.0, 1e9)
            .is_none());
    }
}
