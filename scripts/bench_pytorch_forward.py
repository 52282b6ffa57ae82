#!/usr/bin/env python3
"""Times the official Envision4D backbone (VGGT with the Envision4D heads) on the CPU.

The PyTorch half of `scripts/bench_vs_pytorch.sh` (docs/PERFORMANCE.md, "Side by side with
PyTorch"). It imports the model from a checkout of the public release, builds it at the
paper's widths or at the tiny widths of our test fixtures, runs it on the images stored in
`--images` (written by `--write-images` so that both sides see the same pixels) and prints
one machine-readable line per timed pass:

    forward_warm_s=<s> peak_rss_gib=<g>          (--mode forward: no_grad, eval)
    train_step_s=<s> peak_rss_gib=<g>            (--mode train: forward + backward)

"Warm" means the weights are already drawn and one untimed pass has run. The heads are the
release's `EncoderEnvi4D` set: camera (with the future-pose blocks), depth, Gaussians and
motion; no point or track head. The training pass runs the same graph with gradients on
(eval mode, so no activation checkpointing: the plain cost of forward + backward) and
backpropagates the sum of every output's mean, as our bench does.
"""

import argparse
import functools
import resource
import sys
import time


def peak_rss_gib() -> float:
    # ru_maxrss is KiB on Linux.
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / (1024.0 * 1024.0)


def tiny_widths(models_pkg, layers_pkg):
    """Monkeypatches constructor defaults to the fixtures' tiny widths (64-d, DINO depth 2)."""
    aggregator_mod = models_pkg.aggregator
    vggt_mod = models_pkg.vggt
    vit = layers_pkg.vision_transformer

    def vit_tiny(patch_size=16, num_register_tokens=0, **kwargs):
        return vit.DinoVisionTransformer(
            patch_size=patch_size,
            embed_dim=64,
            depth=2,
            num_heads=4,
            mlp_ratio=4.0,
            block_fn=functools.partial(vit.Block, attn_class=layers_pkg.MemEffAttention),
            num_register_tokens=num_register_tokens,
            **kwargs,
        )

    aggregator_mod.vit_large = vit_tiny
    vggt_mod.Aggregator = functools.partial(aggregator_mod.Aggregator, num_heads=4)
    vggt_mod.DPTHead = functools.partial(
        vggt_mod.DPTHead, features=32, out_channels=[16, 32, 64, 64]
    )
    return 64


def build(release: str, preset: str, num_frames: int):
    import importlib

    # Import the `envision4d` package on its own: the release's `src/model/encoder/__init__`
    # pulls in the whole training stack, which a forward does not need.
    sys.path.insert(0, f"{release}/src/model/encoder")
    models_pkg = importlib.import_module("envision4d.models")
    importlib.import_module("envision4d.models.aggregator")
    importlib.import_module("envision4d.models.vggt")
    layers_pkg = importlib.import_module("envision4d.layers")
    importlib.import_module("envision4d.layers.vision_transformer")
    embed_dim = 1024
    if preset == "tiny":
        embed_dim = tiny_widths(models_pkg, layers_pkg)
    elif preset != "paper":
        raise SystemExit(f"--preset {preset!r}: use tiny or paper")
    return models_pkg.vggt.VGGT(
        embed_dim=embed_dim,
        gaussian_dim=11,
        num_frames=num_frames,
        enable_gs=True,
        enable_camera=True,
        enable_point=False,
        enable_depth=True,
        enable_track=False,
        enable_extra=True,
    )


def outputs_mean_sum(pred) -> "torch.Tensor":
    keys = ["pose_enc", "depth", "depth_conf", "gaussians", "motion_enc"]
    total = 0.0
    for k in keys:
        total = total + pred[k].float().mean()
    return total


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--release", help="checkout of the official Envision4D release")
    p.add_argument("--preset", default="tiny")
    p.add_argument("--mode", default="forward", choices=["forward", "train"])
    p.add_argument("--images", required=True, help="safetensors file with an `images` tensor")
    p.add_argument("--write-images", metavar="B,S,H,W", help="write seeded images and exit")
    p.add_argument("--future", type=int, default=2, help="future frames (sets num_frames)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()

    import numpy as np
    import torch
    from safetensors.numpy import load_file, save_file

    if args.write_images:
        b, s, h, w = (int(v) for v in args.write_images.split(","))
        rng = np.random.default_rng(5678)
        images = rng.random((b, s, 3, h, w), dtype=np.float32)
        save_file({"images": images}, args.images)
        return
    if not args.release:
        raise SystemExit("--release PATH is required")

    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    images = torch.from_numpy(load_file(args.images)["images"])
    model = build(args.release, args.preset, images.shape[1] + args.future).eval()
    print(
        f"# torch {torch.__version__}, {args.preset}, "
        f"{sum(p.numel() for p in model.parameters()) / 1e9:.3f} B params, "
        f"images {list(images.shape)}, {args.threads} threads",
        flush=True,
    )

    def forward_once():
        with torch.no_grad():
            model(images)

    def train_once():
        model.zero_grad(set_to_none=True)
        outputs_mean_sum(model(images)).backward()

    step, label = (forward_once, "forward_warm_s") if args.mode == "forward" else (
        train_once,
        "train_step_s",
    )
    step()  # untimed warm-up: allocator and thread pool
    for _ in range(args.repeats):
        t = time.perf_counter()
        step()
        print(f"{label}={time.perf_counter() - t:.4f} peak_rss_gib={peak_rss_gib():.2f}", flush=True)


if __name__ == "__main__":
    main()
