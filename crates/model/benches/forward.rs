//! Forward (and forward + backward) benchmark of the network (not a test), on the CPU backend
//! or a GPU (`--device wgpu`, or `cuda` with `--features envision4d-model/cuda`).
//!
//! ```text
//! cargo bench -p envision4d-model --bench forward -- [--preset paper|tiny]
//!     [--mode forward|train] [--heads all|none|depth|gaussians|motion] [--image HxW]
//!     [--future N] [--images FILE.safetensors] [--repeats N] [--chunk N] [--profile]
//!     [--device cpu|wgpu|cuda] [--precision f32|f16|bf16] [--launches]
//!     [--launch-sites NAME] [--norm fused|burn] [--softmax fused|burn] [--rope fused|burn] [--residual fused|burn]
//!     [--qkv fused|burn] [--split fused|burn] [--gelu fused|burn]
//! ```
//!
//! The peak RSS is the host process's; on a GPU `device_reserved_gib` is the device memory
//! pool's reserved bytes after the pass (`nan` on the CPU, whose memory is the RSS), and
//! `kernel_launches` the kernels the pass launched (0 on the CPU; `--launches` lists the
//! most launched ones, `--launch-sites Copy` where those named like `Copy` came from).
//!
//! The weights are drawn (and every lazy parameter materialised) before any clock starts,
//! then one untimed pass warms the allocator and the thread pool. Each timed pass prints a
//! machine-readable line, `forward_warm_s=<s> peak_rss_gib=<g>` (or `train_step_s=` in
//! `--mode train`: forward + backward of the sum of every output's mean, all parameters
//! trainable). `--images` reads the `images` tensor `[B, T_c, 3, H, W]` that
//! `scripts/bench_pytorch_forward.py --write-images` wrote, so the official PyTorch code and
//! this bench see the same pixels (`scripts/bench_vs_pytorch.sh` runs both in alternation).
//! `--profile` adds one pass per head set (poses only, + depth, + Gaussians, + motion), which
//! splits the time by module.

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Distribution, Tensor, TensorData};
use envision4d_model::bench::{arg, device_reserved_gib, peak_rss_gib, watch_launches, Launches};
use envision4d_model::model::{Heads, Predictions};
use envision4d_model::precision::Precision;
use envision4d_model::{Envision4d, ModelConfig};
use std::time::Instant;

/// Kernels listed by `--launches` after each timed pass.
const TOP_KERNELS: usize = 16;

/// Touches every parameter so that lazy initialisation (drawing random weights) happens
/// here and not inside the first timed pass.
struct Materialise;
impl ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let _ = param.val();
    }
}

fn read_images(path: &str, device: &Device) -> Tensor<5> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("--images {path}: {e}"));
    let st = safetensors::SafeTensors::deserialize(&bytes)
        .unwrap_or_else(|e| panic!("--images {path}: {e}"));
    let view = st
        .tensor("images")
        .unwrap_or_else(|e| panic!("--images {path}: no `images` tensor ({e})"));
    assert_eq!(
        view.dtype(),
        safetensors::Dtype::F32,
        "{path}: images must be F32"
    );
    let shape: [usize; 5] = view
        .shape()
        .try_into()
        .unwrap_or_else(|_| panic!("{path}: images must be [B, T_c, 3, H, W]"));
    let data: Vec<f32> = view
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Tensor::from_data(TensorData::new(data, shape), device)
}

/// Sum of the means of every output a pass produced: what `--mode train` backpropagates
/// (the PyTorch side backpropagates the same sum).
fn outputs_mean_sum(p: &Predictions) -> Tensor<1> {
    let mut total = p.backbone.pose_enc().mean();
    if let Some(d) = &p.depth {
        total = total + d.clone().mean();
    }
    if let Some(c) = &p.depth_conf {
        total = total + c.clone().mean();
    }
    if let Some(g) = &p.gaussians {
        total = total + g.clone().mean();
    }
    if let Some(m) = &p.motion_enc {
        total = total + m.clone().mean();
    }
    total
}

/// One pass; returns its wall time in seconds. The clock stops when the device has finished
/// all the pass's work: GPU backends return from launches, and from `into_data` (a lazy
/// read), before it is done.
fn pass(model: &Envision4d, images: &Tensor<5>, heads: Heads, train: bool) -> f64 {
    let t = Instant::now();
    let out = model.forward(images.clone(), heads);
    let loss = outputs_mean_sum(&out);
    if train {
        let grads = loss.backward();
        drop(grads);
    } else {
        // The bytes touched, so the read-back itself is timed too.
        let _ = loss.into_data().as_bytes().len();
    }
    images
        .device()
        .sync()
        .expect("the device failed during a timed pass");
    t.elapsed().as_secs_f64()
}

fn main() {
    let tuned = envision4d_model::alloc::keep_freed_memory();
    let args: Vec<String> = std::env::args().collect();
    let preset = arg(&args, "--preset").unwrap_or_else(|| "paper".into());
    let mut cfg = ModelConfig::preset(&preset).expect("preset");
    // Both presets are timed at the paper's image size unless told otherwise.
    cfg.image_size = [350, 518];
    if let Some(s) = arg(&args, "--image") {
        let (h, w) = s.split_once('x').expect("--image HxW");
        cfg.image_size = [h.parse().expect("--image H"), w.parse().expect("--image W")];
    }
    if let Some(f) = arg(&args, "--future") {
        cfg.future_frames = f.parse().expect("--future N");
    }
    let train = match arg(&args, "--mode").as_deref() {
        None | Some("forward") => false,
        Some("train") => true,
        Some(m) => panic!("--mode {m}: use forward or train"),
    };
    let heads = match arg(&args, "--heads").as_deref() {
        None | Some("all") => Heads::ALL,
        Some("none") => Heads::NONE,
        Some(h) => panic!("--heads {h}: use all or none"),
    };
    let repeats: usize = arg(&args, "--repeats").map_or(3, |r| r.parse().expect("--repeats N"));
    let base = envision4d_model::bench::device(arg(&args, "--device").as_deref())
        .unwrap_or_else(|e| panic!("{e}"));
    let device = if train { base.autodiff() } else { base };
    let images = match arg(&args, "--images") {
        Some(p) => read_images(&p, &device),
        None => {
            let [h, w] = cfg.image_size;
            Tensor::<5>::random(
                [1, cfg.context_frames, 3, h, w],
                Distribution::Uniform(0.0, 1.0),
                &device,
            )
        }
    };
    let [b, tc, _, h, w] = images.dims();
    cfg.context_frames = tc;
    cfg.image_size = [h, w];
    cfg.validate().expect("valid config");

    // `--precision`: the aggregator's float format (forward mode; training stays f32). A
    // device without it prints a NaN row, so a benchmark table records the gap.
    let precision = arg(&args, "--precision").map_or(Precision::F32, |p| {
        Precision::from_name(&p).unwrap_or_else(|| panic!("--precision {p}: use f32, f16 or bf16"))
    });
    assert!(
        !(train && precision != Precision::F32),
        "--precision applies to --mode forward"
    );
    if let Err(e) = precision.check(&device) {
        println!("# {e}");
        println!("forward_warm_s=NaN peak_rss_gib=NaN device_reserved_gib=NaN");
        return;
    }
    let t = Instant::now();
    let mut model = Envision4d::new(&cfg, &device).with_precision(precision);
    if let Some(c) = arg(&args, "--chunk") {
        model.dpt_frame_chunk = c.parse().expect("--chunk N");
    }
    model.visit(&mut Materialise);
    let t_init = t.elapsed().as_secs_f64();
    println!(
        "# envision4d {preset}, {:.3} B params, images [{b}, {tc}, 3, {h}, {w}], {} future, \
         {} mode, aggregator in {}, weights drawn in {t_init:.1} s, allocator kept freed memory: {tuned}, \
         CPU kernels: {:?}",
        model.num_params() as f64 / 1e9,
        cfg.future_frames,
        if train { "train" } else { "forward" },
        precision.name(),
        envision4d_model::layers::cpu_attention::Isa::detect(),
    );
    let label = if train {
        "train_step_s"
    } else {
        "forward_warm_s"
    };
    let counter = || Launches::from_args(&args);
    envision4d_model::bench::choose_layer_norm(&args);
    envision4d_model::bench::choose_softmax(&args);
    envision4d_model::bench::choose_rope(&args);
    envision4d_model::bench::choose_residual(&args);
    envision4d_model::bench::choose_qkv(&args);
    envision4d_model::bench::choose_split(&args);
    envision4d_model::bench::choose_gelu(&args);
    pass(&model, &images, heads, train); // untimed warm-up
    for _ in 0..repeats {
        let (s, launches) = watch_launches(counter(), || pass(&model, &images, heads, train));
        println!(
            "{label}={s:.4} peak_rss_gib={:.2} device_reserved_gib={:.2} kernel_launches={}",
            peak_rss_gib(),
            device_reserved_gib(&device),
            launches.total()
        );
        launches.print_top(TOP_KERNELS);
        launches.print_sites(TOP_KERNELS);
    }
    if args.iter().any(|a| a == "--profile") {
        let only = |depth, gaussians, motion| Heads {
            depth,
            gaussians,
            motion,
        };
        let sets = [
            (
                "poses only (aggregator, future pose, camera head)",
                Heads::NONE,
            ),
            ("+ depth head", only(true, false, false)),
            ("+ Gaussian head", only(false, true, false)),
            ("+ motion head", only(false, false, true)),
        ];
        let mut base = 0.0;
        for (i, (name, set)) in sets.iter().enumerate() {
            let best = (0..repeats.max(1))
                .map(|_| pass(&model, &images, *set, train))
                .fold(f64::INFINITY, f64::min);
            if i == 0 {
                base = best;
                println!("profile {name}: {best:.3} s");
            } else {
                println!("profile {name}: {:.3} s", best - base);
            }
        }
    }
}
