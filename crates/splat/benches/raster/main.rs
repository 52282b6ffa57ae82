//! Rasterizer benchmark (not a test): forward and forward+backward at 350x518 with 10k,
//! 100k and 362k Gaussians (two frames of per-pixel Gaussians, as Envision4D renders them).
//!
//! `cargo bench -p envision4d-splat --bench raster [-- --wgpu] [--quick] [--max-gaussians N]`
//! `... -- --backends wgpu,cuda --sizes 362600,1000000,3000000 --json FILE` (what
//! `scripts/gpu_bench.sh` runs; `cuda` needs `--features envision4d-splat/cuda`).
//! `--schedules auto,shared,per-pixel` times each tile schedule of the compositing kernels
//! (`TileSchedule`; default `auto`); `--backward-bins keep,recompute` whether the backward
//! reuses the forward's tile lists (`BackwardBins`; default `keep`); `--grad-adds
//! auto,per-pixel,plane` how the backward adds a splat's gradient (`GradCombine`; default
//! `auto`); every combination is timed once (one that runs the kernels of an earlier row
//! on that device is skipped, said on stderr), and a row with an `auto` names what it
//! resolved to (`wgpu (auto → per pixel, per-pixel adds, native atomics)`). `--no-sort` skips the sort and scan table; `--kernels`
//! adds, per row, the device time of each kernel of one forward+backward
//! ([`kernel_times`]).
//! Prints ms per view and Gaussian-tile pairs per second, then the binning's building blocks
//! alone (the stable sort of 32-bit keys and the exclusive scan, results read back); results
//! go to docs/PERFORMANCE.md. Scenes past 362,600 Gaussians take more frames of the street.

mod kernel_times;
mod variants;

use burn::tensor::Device;
use burn::tensor::{DType, Int, Tensor, TensorData};
use envision4d_splat::primitives::{exclusive_scan, sort_pairs};
use envision4d_splat::testkit::{look_at, HostScene, SplitMix64};
use envision4d_splat::{kernel_plan, render, BackwardBins, Cameras, Gaussians, KernelPlan};
use std::time::{Duration, Instant};
use variants::{device, variants, Variant};

const W: u32 = 518;
const H: u32 = 350;
const FOCAL: f64 = 300.0;

/// Per-pixel Gaussians of a street-like depth map (ground plane, two facades, far backdrop),
/// back-projected from `frames` nearby cameras: what the Gaussian head produces.
fn street_scene(frames: usize, seed: u64) -> HostScene {
    let mut rng = SplitMix64::new(seed);
    let mut s = HostScene::default();
    for f in 0..frames {
        let cam_z = f as f64 * 0.8;
        for y in 0..H {
            for x in 0..W {
                let u = (x as f64 + 0.5 - W as f64 / 2.0) / FOCAL;
                let v = (y as f64 + 0.5 - H as f64 / 2.0) / FOCAL;
                // Camera 1.5 m above the road; facades at x = ±6 m; backdrop at 80 m.
                let mut depth: f64 = 80.0;
                if v > 1e-3 {
                    depth = depth.min(1.5 / v);
                }
                if u.abs() > 1e-3 {
                    depth = depth.min(6.0 / u.abs());
                }
                let z = depth * (1.0 + 0.01 * rng.range(-1.0, 1.0));
                let mean = [u * z, v * z, z + cam_z];
                let pix = z / FOCAL;
                let scale = [
                    pix * rng.range(0.5, 1.5),
                    pix * rng.range(0.5, 1.5),
                    pix * rng.range(0.2, 1.0),
                ];
                let quat = [
                    1.0,
                    rng.range(-0.2, 0.2),
                    rng.range(-0.2, 0.2),
                    rng.range(-0.2, 0.2),
                ];
                let color = [rng.unit(), rng.unit(), rng.unit()];
                s.push(mean, quat, scale, rng.range(0.3, 0.95), color);
            }
        }
    }
    s
}

fn subsample(s: &HostScene, n: usize, seed: u64) -> HostScene {
    let mut rng = SplitMix64::new(seed);
    let mut idx: Vec<usize> = (0..s.len()).collect();
    for i in (1..idx.len()).rev() {
        idx.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let mut out = HostScene::default();
    for &i in idx.iter().take(n) {
        let g = |v: &Vec<f64>, k: usize| -> Vec<f64> { v[k * i..k * i + k].to_vec() };
        let (m, q, sc, c) = (
            g(&s.means, 3),
            g(&s.quats, 4),
            g(&s.scales, 3),
            g(&s.colors, 3),
        );
        out.push(
            [m[0], m[1], m[2]],
            [q[0], q[1], q[2], q[3]],
            [sc[0], sc[1], sc[2]],
            s.opacities[i],
            [c[0], c[1], c[2]],
        );
    }
    out
}

fn tensors(s: &HostScene, device: &Device, grad: bool) -> (Gaussians, Cameras) {
    let [m, q, sc, o, c] = s.to_f32();
    let mut g = Gaussians::from_host(m, q, sc, o, c, device).expect("consistent scene");
    if grad {
        g.means = g.means.require_grad();
        g.quats = g.quats.require_grad();
        g.scales = g.scales.require_grad();
        g.opacities = g.opacities.require_grad();
        g.colors = g.colors.require_grad();
    }
    let v = look_at([0.0, 0.0, 0.4], [0.0, 0.0, 10.0]);
    let viewmat = [
        [v[0], v[1], v[2], v[3]],
        [v[4], v[5], v[6], v[7]],
        [v[8], v[9], v[10], v[11]],
        [v[12], v[13], v[14], v[15]],
    ];
    let k = [
        [FOCAL, 0.0, W as f64 / 2.0],
        [0.0, FOCAL, H as f64 / 2.0],
        [0.0, 0.0, 1.0],
    ];
    (g, Cameras::from_host(&[viewmat], &[k], W, H, device))
}

/// The best of `reps` timed runs of `f` after one warm-up, each ending when `device` has
/// finished all the work queued: GPU backends return from launches (and from `into_data`,
/// which reads back lazily) before the work is done, so a clock stopped there measures the
/// launches alone (that once gave a million-key sort in 0.3 ms on lavapipe).
fn time(reps: usize, device: &Device, mut f: impl FnMut() -> usize) -> Duration {
    let mut run = || {
        f();
        device.sync().expect("the device failed during a timed run");
    };
    run(); // warm-up (autotune, kernel compilation, allocations)
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            run();
            t.elapsed()
        })
        .min()
        .unwrap()
}

/// Touches a read-back tensor's bytes, so the device-to-host copy (lazy on CubeCL backends)
/// happens inside the timed run; returns their count.
fn read(data: TensorData) -> usize {
    data.as_bytes().len()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let backends: Vec<String> = match arg(&args, "--backends") {
        Some(list) => list.split(',').map(str::to_owned).collect(),
        None if args.iter().any(|a| a == "--wgpu") => vec!["cpu".into(), "wgpu".into()],
        None => vec!["cpu".into()],
    };
    let devices: Vec<(&str, Device)> = backends.iter().map(|b| device(b)).collect();
    let reps = if quick { 1 } else { 3 };
    // Software Vulkan (lavapipe) is far too slow for the big scenes; let a run cap the size.
    let max_n: usize = arg(&args, "--max-gaussians")
        .map(|v| v.parse().expect("--max-gaussians takes a number"))
        .unwrap_or(usize::MAX);
    let full = street_scene(2, 7);
    let sizes: Vec<usize> = match arg(&args, "--sizes") {
        Some(list) => list
            .split(',')
            .map(|v| v.parse().expect("--sizes takes numbers"))
            .collect(),
        None => vec![10_000, 100_000, full.len()],
    };
    let variants = variants(|flag| arg(&args, flag));
    let mut json_rows = Vec::new();
    let sort_devices = devices.clone();
    let kernels = args.iter().any(|a| a == "--kernels");
    let mut kernel_tables = Vec::new();
    println!(
        "machine: {} logical cores; image {W}x{H}; min of {reps} runs after 1 warm-up",
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    );
    println!("| backend | Gaussians | visible | tile pairs | forward ms/view | fwd+bwd ms/view | fwd pairs/s | fwd+bwd pairs/s |");
    println!("|---|---|---|---|---|---|---|---|");
    // The CPU path has none of the GPU knobs (it picks GPU kernels and keeps nothing for
    // its backward): one row set for it.
    let runs = devices.iter().flat_map(|d| {
        let take = if d.0.starts_with("cpu") {
            1
        } else {
            variants.len()
        };
        variants.iter().take(take).map(move |v| (d, v))
    });
    // Per backend, the kernel plans and bins already timed: a variant whose `auto` resolves
    // to a row already there (on lavapipe, `auto` is the per-pixel schedule) is not timed
    // twice.
    let mut timed: Vec<(String, KernelPlan, BackwardBins)> = Vec::new();
    for ((backend, device), variant) in runs {
        let cfg = variant.config();
        let plan = kernel_plan(device, &cfg);
        if let Some(plan) = plan {
            let key = (backend.to_string(), plan, cfg.backward_bins);
            if timed.contains(&key) {
                // To stderr: a line inside the Markdown table would end it.
                eprintln!(
                    "{backend} ({}) runs the kernels of a row above ({}): not timed again",
                    variant.label(),
                    plan.describe()
                );
                continue;
            }
            timed.push(key);
        }
        let (name, knobs) = match plan {
            None => (backend.to_string(), Variant::json(None, None)),
            Some(plan) => (
                format!("{backend} ({})", variant.label_with(&plan)),
                Variant::json(Some(variant), Some(&plan)),
            ),
        };
        for &n in sizes.iter().filter(|n| **n <= max_n) {
            let scene = scene_of(&full, n);
            let (g, c) = tensors(&scene, device, false);
            let out = render(&g, &c, &cfg).unwrap();
            let counts = out
                .meta
                .counts
                .into_data()
                .convert::<i64>()
                .try_into_vec::<i64>()
                .unwrap();
            // Upper bound of Gaussian-pixel evaluations: every tile pair visits 256 pixels.
            let pairs = counts[1] as f64 * 256.0;
            let fwd = time(reps, device, || {
                read(render(&g, &c, &cfg).unwrap().rgb.into_data())
            });
            let ad = device.clone().autodiff();
            let (ga, ca) = tensors(&scene, &ad, true);
            let fwd_bwd = || {
                let out = render(&ga, &ca, &cfg).unwrap();
                let grads = (out.rgb.sum() + out.depth.sum() * 0.01).backward();
                read(ga.means.grad(&grads).unwrap().into_data())
            };
            let fb = time(reps, device, fwd_bwd);
            if kernels {
                // After the timed runs: compiled, autotuned and allocated already.
                let (rows, method) = kernel_times::per_kernel(device, || {
                    fwd_bwd();
                });
                for k in &rows {
                    json_rows.push(format!(
                        "{{\"kind\":\"kernel\",\"backend\":\"{backend}\",{knobs},\
                         \"gaussians\":{n},\"kernel\":\"{}\",\"launches\":{},\"total_ms\":{:.4}}}",
                        k.name, k.launches, k.total_ms
                    ));
                }
                kernel_tables.push((format!("{name}, {n} Gaussians"), rows, method));
            }
            json_rows.push(format!(
                "{{\"kind\":\"raster\",\"backend\":\"{backend}\",{knobs},\
                 \"gaussians\":{n},\"visible\":{},\"tile_pairs\":{},\"forward_ms\":{:.3},\"fwd_bwd_ms\":{:.3}}}",
                counts[0],
                counts[1],
                fwd.as_secs_f64() * 1e3,
                fb.as_secs_f64() * 1e3
            ));
            println!(
                "| {name} | {n} | {} | {} | {:.1} | {:.1} | {:.2e} | {:.2e} |",
                counts[0],
                counts[1],
                fwd.as_secs_f64() * 1e3,
                fb.as_secs_f64() * 1e3,
                pairs / fwd.as_secs_f64(),
                pairs / fb.as_secs_f64()
            );
        }
    }
    for (title, rows, method) in &kernel_tables {
        let method = method.as_deref().unwrap_or("nothing launched");
        println!();
        println!("Kernels of one forward+backward, {title} ({method}):");
        println!();
        println!("| kernel | launches | total ms | share |");
        println!("|---|---|---|---|");
        let all: f64 = rows.iter().map(|k| k.total_ms).sum();
        for k in rows {
            println!(
                "| {} | {} | {:.3} | {:.1}% |",
                k.name,
                k.launches,
                k.total_ms,
                100.0 * k.total_ms / all.max(f64::MIN_POSITIVE)
            );
        }
    }
    let sort_devices = if args.iter().any(|a| a == "--no-sort") {
        Vec::new()
    } else {
        println!();
        println!(
            "| backend | elements | sort, 32-bit keys, ms | sort, 12-bit keys, ms | scan ms |"
        );
        println!("|---|---|---|---|---|");
        sort_devices
    };
    for (name, device) in sort_devices {
        for n in [100_000usize, 1_000_000] {
            let mut rng = SplitMix64::new(n as u64);
            let keys: Vec<i32> = (0..n).map(|_| rng.next_u64() as u32 as i32).collect();
            let small: Vec<i32> = keys.iter().map(|k| k & 0xFFF).collect();
            let ints = |v: &[i32]| {
                Tensor::<1, Int>::from_data(TensorData::new(v.to_vec(), [n]), (&device, DType::I32))
            };
            let (k32, k12, vals) = (ints(&keys), ints(&small), ints(&small));
            let sort = |k: &Tensor<1, Int>, bits| {
                let (k, v) = sort_pairs(k.clone(), vals.clone(), bits).unwrap();
                read(k.into_data()) + read(v.into_data())
            };
            let t32 = time(reps, &device, || sort(&k32, 32));
            let t12 = time(reps, &device, || sort(&k12, 12));
            let ts = time(reps, &device, || {
                read(exclusive_scan(k12.clone()).unwrap().into_data())
            });
            json_rows.push(format!(
                "{{\"kind\":\"sort\",\"backend\":\"{name}\",\"elements\":{n},\
                 \"sort32_ms\":{:.3},\"sort12_ms\":{:.3},\"scan_ms\":{:.3}}}",
                t32.as_secs_f64() * 1e3,
                t12.as_secs_f64() * 1e3,
                ts.as_secs_f64() * 1e3
            ));
            println!(
                "| {name} | {n} | {:.1} | {:.1} | {:.1} |",
                t32.as_secs_f64() * 1e3,
                t12.as_secs_f64() * 1e3,
                ts.as_secs_f64() * 1e3
            );
        }
    }
    if let Some(path) = arg(&args, "--json") {
        let text = format!("[\n{}\n]\n", json_rows.join(",\n"));
        let tmp = format!("{path}.tmp");
        std::fs::write(&tmp, text).expect("--json: write");
        std::fs::rename(&tmp, &path).expect("--json: rename");
    }
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// `n` Gaussians of the street: a random subset of the two-frame scene, or of as many
/// frames as it takes past that.
fn scene_of(two_frames: &HostScene, n: usize) -> HostScene {
    if n == two_frames.len() {
        return two_frames.clone();
    }
    if n < two_frames.len() {
        return subsample(two_frames, n, 3);
    }
    let frames = n.div_ceil(two_frames.len() / 2);
    subsample(&street_scene(frames, 7), n, 3)
}
