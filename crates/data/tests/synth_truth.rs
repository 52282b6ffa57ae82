//! The synthetic world's ground truth must be true: cameras + depth explain the images,
//! flow follows the tracks, the mask is exactly the moving objects, and output is
//! byte-identical for a seed.

use envision4d_data::layout::synth::{read_json, TracksFile, INSTANCE_DIR, MASK_DIR, TRACKS_FILE};
use envision4d_data::synth::{render_clip, write_clip, Preset, SynthConfig};
use envision4d_data::{ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, Image, Layout, Vec3};
use std::path::Path;

const H: usize = 48;
const W: usize = 64;

fn make(dir: &Path, preset: Preset, seed: u64, frames: usize) {
    let cfg = SynthConfig {
        width: W,
        height: H,
        frames,
        preset,
        seed,
        supersample: 2,
    };
    let clip = render_clip(&cfg, 0, || {}).unwrap();
    write_clip(&dir.join("clip_000000"), &clip).unwrap();
}

fn open(dir: &Path, frames: usize) -> std::sync::Arc<envision4d_data::Clip> {
    let cfg = DatasetConfig {
        layout: Layout::Synth { stride: 1 },
        spec: ClipSpec {
            context: 1,
            future: frames - 1,
            frame_step: 1,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: H,
            width: W,
        },
        cache_clips: 0,
    };
    ClipDataset::open(dir, cfg).unwrap().load(0).unwrap()
}

fn bilinear(img: &Image, x: f64, y: f64) -> Option<[f32; 3]> {
    // Continuous pixel coords -> sample grid (centres at +0.5).
    let (fx, fy) = (x - 0.5, y - 0.5);
    if fx < 0.0 || fy < 0.0 || fx > (img.width - 1) as f64 || fy > (img.height - 1) as f64 {
        return None;
    }
    let (c0, r0) = (fx.floor() as usize, fy.floor() as usize);
    let (c1, r1) = ((c0 + 1).min(img.width - 1), (r0 + 1).min(img.height - 1));
    let (a, b) = ((fx - c0 as f64) as f32, (fy - r0 as f64) as f32);
    let p = |r, c| img.pixel(r, c);
    Some([0, 1, 2].map(|k| {
        (p(r0, c0)[k] * (1.0 - a) + p(r0, c1)[k] * a) * (1.0 - b)
            + (p(r1, c0)[k] * (1.0 - a) + p(r1, c1)[k] * a) * b
    }))
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Guards cameras, depth and rendering agreeing (photometric consistency): static pixels
/// of frame 0 lifted with GT depth and projected with GT cameras into frame 4 show the same
/// colour; using the wrong camera (frame 0's for frame 4) is clearly worse.
#[test]
fn reprojection_is_photometrically_consistent() {
    let dir = tempfile::tempdir().unwrap();
    // Frames 0.4 s apart, so the ego has moved a few metres.
    make(dir.path(), Preset::Static, 3, 5);
    let clip = open(dir.path(), 5);
    let (g0, g1) = (&clip.gt[0], &clip.gt[4]);
    let k = g0.intrinsics.unwrap();
    let c2w0 = g0.world_to_camera.unwrap().rigid_inverse();
    let errs = |w2c1: envision4d_data::Mat4| {
        let d1 = &g1.depth.as_ref().unwrap().map;
        let mut errs = Vec::new();
        let d0 = &g0.depth.as_ref().unwrap().map;
        for v in 0..H {
            for u in 0..W {
                let z = d0.get(v, u, 0) as f64;
                if z <= 0.0 {
                    continue;
                }
                let pw = c2w0.transform_point(k.unproject(u as f64 + 0.5, v as f64 + 0.5, z));
                let pc = w2c1.transform_point(pw);
                let Some((x, y)) = k.project(pc) else {
                    continue;
                };
                let Some(col) = bilinear(&clip.frames[4], x, y) else {
                    continue;
                };
                // Skip points hidden at t+1 (occlusion) by checking the depth there.
                let z1 = d1.get((y as usize).min(H - 1), (x as usize).min(W - 1), 0) as f64;
                if (z1 - pc.z).abs() > 0.05 * pc.z {
                    continue;
                }
                let c0 = clip.frames[0].pixel(v, u);
                errs.push((0..3).map(|i| (c0[i] - col[i]).abs()).sum::<f32>() / 3.0);
            }
        }
        errs
    };
    let good = errs(g1.world_to_camera.unwrap());
    assert!(
        good.len() > H * W / 3,
        "too few valid pixels: {}",
        good.len()
    );
    let wrong = errs(g0.world_to_camera.unwrap());
    let (mg, mw) = (median(good), median(wrong));
    assert!(mg < 0.02, "median colour error with GT cameras {mg}");
    assert!(
        mg * 2.0 < mw,
        "GT cameras {mg} not clearly better than wrong ones {mw}"
    );
}

fn rotz(yaw: f64, p: Vec3) -> Vec3 {
    let (s, c) = yaw.sin_cos();
    Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z)
}

fn read_u16_png(path: &Path) -> Vec<u16> {
    image::open(path).unwrap().into_luma16().into_raw()
}

/// Guards scene flow and the dynamic mask against the object tracks: every agent pixel's
/// flow equals the rigid motion of its track from t to t+1, static pixels have zero flow,
/// the mask is exactly the pixels of moving tracks, and those pixels lie inside the track's
/// box (static ones inside none).
#[test]
fn flow_and_mask_follow_tracks() {
    let dir = tempfile::tempdir().unwrap();
    make(dir.path(), Preset::Urban, 5, 3);
    let clip = open(dir.path(), 3);
    let clip_dir = dir.path().join("clip_000000");
    let tracks: TracksFile = read_json(&clip_dir.join(TRACKS_FILE)).unwrap();
    let mut dynamic_pixels = 0;
    for t in 0..3 {
        let gt = &clip.gt[t];
        let k = gt.intrinsics.unwrap();
        let c2w = gt.world_to_camera.unwrap().rigid_inverse();
        let depth = &gt.depth.as_ref().unwrap().map;
        let flow = gt.flow.as_ref().unwrap();
        let inst = read_u16_png(&clip_dir.join(INSTANCE_DIR).join(format!("{t:06}.png")));
        let mask = image::open(clip_dir.join(MASK_DIR).join(format!("{t:06}.png")))
            .unwrap()
            .into_luma8()
            .into_raw();
        for v in 0..H {
            for u in 0..W {
                let i = v * W + u;
                let f = Vec3::new(
                    flow.get(v, u, 0) as f64,
                    flow.get(v, u, 1) as f64,
                    flow.get(v, u, 2) as f64,
                );
                let z = depth.get(v, u, 0) as f64;
                let p = c2w.transform_point(k.unproject(u as f64 + 0.5, v as f64 + 0.5, z));
                let inside = |tr: &envision4d_data::layout::synth::Track, margin: f64| {
                    let s = &tr.states[t];
                    let q = rotz(
                        -s.yaw,
                        p - Vec3::new(s.position[0], s.position[1], s.position[2]),
                    );
                    (0..3).all(|a| q.get(a).abs() <= tr.size[a] / 2.0 + margin)
                };
                if inst[i] == 0 {
                    assert_eq!(f, Vec3::ZERO, "static pixel ({v},{u}) t {t} has flow");
                    assert_eq!(mask[i], 0);
                    if z > 0.0 {
                        let hit = tracks
                            .tracks
                            .iter()
                            .find(|tr| tr.states[t].moving && inside(tr, -0.01));
                        assert!(
                            hit.is_none(),
                            "static pixel ({v},{u}) inside moving track {:?}",
                            hit.map(|h| h.id)
                        );
                    }
                    continue;
                }
                let tr = tracks
                    .tracks
                    .iter()
                    .find(|tr| tr.id == inst[i])
                    .expect("instance has a track");
                let (s0, s1) = (&tr.states[t], &tr.states[t]);
                let c0 = Vec3::new(s0.position[0], s0.position[1], s0.position[2]);
                let c1 = c0 + Vec3::new(s1.velocity[0], s1.velocity[1], s1.velocity[2]) * 0.1;
                let yaw1 = if t + 1 < tr.states.len() {
                    tr.states[t + 1].yaw
                } else {
                    s0.yaw
                };
                if t + 1 < tr.states.len() {
                    let expect = rotz(yaw1, rotz(-s0.yaw, p - c0)) + c1 - p;
                    let tol = 2e-3 + 1e-5 * z * z;
                    assert!(
                        (expect - f).norm() < tol,
                        "pixel ({v},{u}) t {t}: flow {f:?} vs track {expect:?}"
                    );
                }
                assert!(
                    inside(tr, 0.02),
                    "pixel ({v},{u}) of track {} lies outside its box",
                    tr.id
                );
                assert_eq!(mask[i] == 255, s0.moving, "mask at ({v},{u}) t {t}");
                dynamic_pixels += usize::from(s0.moving);
            }
        }
    }
    assert!(
        dynamic_pixels > 20,
        "the urban preset shows too few moving pixels: {dynamic_pixels}"
    );
}

/// Guards "non-linear motion": constant-velocity extrapolation of the tracks is wrong by
/// more than a few centimetres within a few frames for at least one agent.
#[test]
fn agent_motion_is_not_constant_velocity() {
    let cfg = SynthConfig {
        width: 8,
        height: 6,
        frames: 6,
        preset: Preset::Urban,
        seed: 9,
        supersample: 1,
    };
    let clip = render_clip(&cfg, 0, || {}).unwrap();
    let worst = clip
        .tracks
        .iter()
        .map(|tr| {
            let c = |t: usize| {
                Vec3::new(
                    tr.states[t].position[0],
                    tr.states[t].position[1],
                    tr.states[t].position[2],
                )
            };
            let predicted = c(1) + (c(1) - c(0)) * 4.0;
            (predicted - c(5)).norm()
        })
        .fold(0.0, f64::max);
    assert!(
        worst > 0.05,
        "all agents move at constant velocity (max error {worst} m)"
    );
}

fn all_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// Guards determinism: the same seed gives byte-identical files (PNG, EXR, JSON); another
/// seed gives a different world.
#[test]
fn same_seed_same_bytes() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    make(a.path(), Preset::CrossingTruck, 11, 2);
    make(b.path(), Preset::CrossingTruck, 11, 2);
    make(c.path(), Preset::CrossingTruck, 12, 2);
    let (fa, fb, fc) = (
        all_files(a.path()),
        all_files(b.path()),
        all_files(c.path()),
    );
    assert_eq!(fa.len(), 2 * 5 + 3);
    assert!(fa == fb, "same seed produced different bytes");
    assert!(fa != fc, "different seeds produced identical output");
    assert!(
        !fa.iter().any(|(n, _)| n.contains(".tmp")),
        "temp files left behind"
    );
}

/// Guards every preset rendering without error and producing finite, in-range output.
#[test]
fn every_preset_renders() {
    for preset in Preset::ALL {
        let cfg = SynthConfig {
            width: 16,
            height: 12,
            frames: 2,
            preset,
            seed: 1,
            supersample: 1,
        };
        let clip = render_clip(&cfg, 0, || {}).unwrap();
        let f = &clip.frames[1];
        assert!(
            f.rgb
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0 && *v <= 1.5),
            "{}",
            preset.name()
        );
        assert!(f.depth.iter().all(|d| d.is_finite() && *d >= 0.0));
        assert_eq!(Preset::from_name(preset.name()), Some(preset));
    }
}

/// Guards ground-truth pairing by frame number: with frame 2 of 6 deleted, no window spans
/// the gap, and a window after it gets the cameras of its own frame numbers (not of the
/// positions in the listing).
#[test]
fn missing_frame_never_shifts_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    make(dir.path(), Preset::Urban, 21, 6);
    let rgb = dir.path().join("clip_000000/rgb");
    let removed = std::fs::read_dir(&rgb)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_stem().and_then(|s| s.to_str()) == Some("000002"))
        .collect::<Vec<_>>();
    assert_eq!(
        removed.len(),
        1,
        "frame 2 exists before the test removes it"
    );
    std::fs::remove_file(&removed[0]).unwrap();
    let cfg = DatasetConfig {
        layout: Layout::Synth { stride: 1 },
        spec: ClipSpec {
            context: 1,
            future: 1,
            frame_step: 1,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: H,
            width: W,
        },
        cache_clips: 0,
    };
    let ds = ClipDataset::open(dir.path(), cfg).unwrap();
    // Frames 0,1,3,4,5: windows (0,1), (3,4), (4,5); (1,3) spans the gap and is skipped.
    assert_eq!(ds.len(), 3);
    assert_eq!(ds.skipped(), 1);
    let full = {
        let d2 = tempfile::tempdir().unwrap();
        make(d2.path(), Preset::Urban, 21, 6);
        let cfg = DatasetConfig {
            layout: Layout::Synth { stride: 1 },
            spec: ClipSpec {
                context: 1,
                future: 1,
                frame_step: 1,
            },
            fit: Fit {
                mode: FitMode::Resize,
                height: H,
                width: W,
            },
            cache_clips: 0,
        };
        ClipDataset::open(d2.path(), cfg).unwrap().load(3).unwrap()
    };
    let shifted = ds.load(1).unwrap();
    assert!(
        shifted.frame_paths[0].ends_with("000003.png"),
        "{:?}",
        shifted.frame_paths
    );
    // Window (3,4) of the gapped clip equals window (3,4) of the full clip, GT included.
    let gt_a = format!(
        "{:?}",
        shifted
            .gt
            .iter()
            .map(|g| g.world_to_camera)
            .collect::<Vec<_>>()
    );
    let gt_b = format!(
        "{:?}",
        full.gt
            .iter()
            .map(|g| g.world_to_camera)
            .collect::<Vec<_>>()
    );
    assert_eq!(gt_a, gt_b);
}
