//! The ray tracer: nearest hit against the ground plane and the posed objects, Lambertian
//! shading with a sun (hard shadows) and ambient light, a sky gradient, n x n supersampled
//! colour, and exact per-pixel truth (z-depth, instance, scene flow) from the pixel-centre ray.

use super::camera::Camera;
use super::motion::Pose;
use super::shapes::{sphere_t, Ray};
use super::texture::{albedo, ground, Rgb};
use super::world::World;
use crate::geom::Vec3;
use rayon::prelude::*;

/// Ground hits beyond this are shown as sky (the plane would alias to noise at the horizon).
const GROUND_FAR: f64 = 400.0;
/// Offset along the normal for shadow rays, against self-intersection.
const SHADOW_BIAS: f64 = 1e-4;

/// An object placed at one time, with its pose at the next frame for scene flow.
struct Posed {
    object: usize,
    pose: Pose,
    next: Pose,
    bound_centre: Vec3,
    bound_radius: f64,
}

fn to_local(pose: &Pose, p: Vec3) -> Vec3 {
    let (s, c) = pose.yaw.sin_cos();
    let d = p - pose.position;
    Vec3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z)
}

fn dir_to_local(pose: &Pose, d: Vec3) -> Vec3 {
    let (s, c) = pose.yaw.sin_cos();
    Vec3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z)
}

fn from_local(pose: &Pose, q: Vec3) -> Vec3 {
    let (s, c) = pose.yaw.sin_cos();
    pose.position + Vec3::new(c * q.x - s * q.y, s * q.x + c * q.y, q.z)
}

/// What a ray hit.
struct Surface {
    t: f64,
    point: Vec3,
    normal: Vec3,
    colour: Rgb,
    /// Index into `Scene::posed`, or None for the ground.
    posed: Option<usize>,
}

/// One frame's scene: the world with every object posed at time t.
pub struct Scene<'a> {
    world: &'a World,
    posed: Vec<Posed>,
}

impl<'a> Scene<'a> {
    pub fn at(world: &'a World, t_s: f64) -> Scene<'a> {
        let posed = world
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let pose = o.motion.pose(&world.road, t_s);
                Posed {
                    object: i,
                    pose,
                    next: o.motion.pose(&world.road, t_s + world.dt),
                    bound_centre: from_local(&pose, o.bound.0),
                    bound_radius: o.bound.1,
                }
            })
            .collect();
        Scene { world, posed }
    }

    /// Pose of object `i` now and at the next frame.
    pub fn pose_of(&self, object: usize) -> Option<(Pose, Pose)> {
        self.posed
            .iter()
            .find(|p| p.object == object)
            .map(|p| (p.pose, p.next))
    }

    fn nearest(&self, ray: &Ray, t_max: f64) -> Option<Surface> {
        let mut best: Option<Surface> = None;
        let mut t_best = t_max;
        if ray.dir.z < 0.0 {
            let t = -ray.origin.z / ray.dir.z;
            if t > 0.0 && t < t_best.min(GROUND_FAR) {
                let p = ray.at(t);
                let (s, lat) = self.world.road.coords(p.x, p.y);
                t_best = t;
                best = Some(Surface {
                    t,
                    point: p,
                    normal: Vec3::new(0.0, 0.0, 1.0),
                    colour: ground(s, lat, p.x, p.y),
                    posed: None,
                });
            }
        }
        for (pi, posed) in self.posed.iter().enumerate() {
            if sphere_t(ray, posed.bound_centre, posed.bound_radius, 0.0, t_best).is_none() {
                continue;
            }
            let obj = &self.world.objects[posed.object];
            let local = Ray {
                origin: to_local(&posed.pose, ray.origin),
                dir: dir_to_local(&posed.pose, ray.dir),
            };
            for part in &obj.parts {
                let pr = Ray {
                    origin: local.origin - part.offset,
                    dir: local.dir,
                };
                if let Some(hit) = part.shape.intersect(&pr, 0.0, t_best) {
                    let q = pr.at(hit.t);
                    t_best = hit.t;
                    let normal_local = hit.normal;
                    let (s, c) = posed.pose.yaw.sin_cos();
                    let n = Vec3::new(
                        c * normal_local.x - s * normal_local.y,
                        s * normal_local.x + c * normal_local.y,
                        normal_local.z,
                    );
                    best = Some(Surface {
                        t: hit.t,
                        point: ray.at(hit.t),
                        normal: n,
                        colour: albedo(&part.material, q, normal_local),
                        posed: Some(pi),
                    });
                }
            }
        }
        best
    }

    /// True when something blocks the ray before t_max.
    fn occluded(&self, ray: &Ray) -> bool {
        self.posed.iter().any(|posed| {
            if sphere_t(
                ray,
                posed.bound_centre,
                posed.bound_radius,
                0.0,
                f64::INFINITY,
            )
            .is_none()
            {
                return false;
            }
            let local = Ray {
                origin: to_local(&posed.pose, ray.origin),
                dir: dir_to_local(&posed.pose, ray.dir),
            };
            self.world.objects[posed.object].parts.iter().any(|part| {
                let pr = Ray {
                    origin: local.origin - part.offset,
                    dir: local.dir,
                };
                part.shape.intersect(&pr, 0.0, f64::INFINITY).is_some()
            })
        })
    }

    fn shade(&self, s: &Surface) -> Rgb {
        let light = &self.world.light;
        let n_dot_l = s.normal.dot(light.sun_dir).max(0.0);
        let lit = n_dot_l > 0.0 && {
            let shadow = Ray {
                origin: s.point + s.normal * SHADOW_BIAS,
                dir: light.sun_dir,
            };
            !self.occluded(&shadow)
        };
        let sun = if lit { n_dot_l as f32 } else { 0.0 };
        // Ambient from the sky: faces looking up get more of it.
        let sky = (0.75 + 0.25 * s.normal.z) as f32;
        let mut out = [0.0f32; 3];
        for c in 0..3 {
            out[c] = s.colour[c] * (light.ambient[c] * sky + light.sun[c] * sun);
        }
        out
    }

    fn sky(&self, dir: Vec3) -> Rgb {
        let l = &self.world.light;
        let e = (dir.z / dir.norm()).clamp(0.0, 1.0).sqrt() as f32;
        [0, 1, 2].map(|c| l.sky_horizon[c] * (1.0 - e) + l.sky_zenith[c] * e)
    }
}

/// One rendered frame: RGB (HWC), z-depth (0 = sky), scene flow to the next frame (world
/// frame, metres, HW3), and instance ids (0 = static scenery, ground or sky).
pub struct FrameRender {
    pub rgb: Vec<f32>,
    pub depth: Vec<f32>,
    pub flow: Vec<f32>,
    pub instance: Vec<u16>,
}

struct PixelOut {
    rgb: Rgb,
    depth: f32,
    flow: [f32; 3],
    instance: u16,
}

/// Renders `scene` through `camera` with `ss` x `ss` colour samples per pixel.
pub fn render(
    scene: &Scene,
    camera: &Camera,
    width: usize,
    height: usize,
    ss: usize,
) -> FrameRender {
    let ss = ss.max(1);
    let rows: Vec<Vec<PixelOut>> = (0..height)
        .into_par_iter()
        .map(|v| (0..width).map(|u| pixel(scene, camera, u, v, ss)).collect())
        .collect();
    let mut out = FrameRender {
        rgb: Vec::with_capacity(width * height * 3),
        depth: Vec::with_capacity(width * height),
        flow: Vec::with_capacity(width * height * 3),
        instance: Vec::with_capacity(width * height),
    };
    for px in rows.into_iter().flatten() {
        out.rgb.extend_from_slice(&px.rgb);
        out.depth.push(px.depth);
        out.flow.extend_from_slice(&px.flow);
        out.instance.push(px.instance);
    }
    out
}

fn pixel(scene: &Scene, camera: &Camera, u: usize, v: usize, ss: usize) -> PixelOut {
    let mut rgb = [0.0f32; 3];
    for i in 0..ss {
        for j in 0..ss {
            let x = u as f64 + (j as f64 + 0.5) / ss as f64;
            let y = v as f64 + (i as f64 + 0.5) / ss as f64;
            let ray = camera.ray(x, y);
            let c = match scene.nearest(&ray, f64::INFINITY) {
                Some(s) => scene.shade(&s),
                None => scene.sky(ray.dir),
            };
            (0..3).for_each(|k| rgb[k] += c[k]);
        }
    }
    let n = (ss * ss) as f32;
    for c in &mut rgb {
        *c /= n;
    }
    // Truth from the pixel-centre ray.
    let ray = camera.ray(u as f64 + 0.5, v as f64 + 0.5);
    let (depth, flow, instance) = match scene.nearest(&ray, f64::INFINITY) {
        None => (0.0, [0.0; 3], 0),
        Some(s) => match s.posed.map(|i| &scene.posed[i]) {
            None => (s.t as f32, [0.0; 3], 0),
            Some(p) if scene.world.objects[p.object].track_id == 0 => (s.t as f32, [0.0; 3], 0),
            Some(p) => {
                let q = to_local(&p.pose, s.point);
                let f = from_local(&p.next, q) - s.point;
                let id = scene.world.objects[p.object].track_id;
                (s.t as f32, [f.x as f32, f.y as f32, f.z as f32], id)
            }
        },
    };
    PixelOut {
        rgb,
        depth,
        flow,
        instance,
    }
}
