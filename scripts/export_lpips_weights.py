#!/usr/bin/env python3
"""Export LPIPS weights (backbone + learned lin layers) to safetensors for envision4d-losses.

Run this where torchvision's pretrained ImageNet weights can be downloaded (or are cached):

    pip install torch torchvision lpips safetensors
    python scripts/export_lpips_weights.py --net vgg --out lpips_vgg.safetensors
    python scripts/export_lpips_weights.py --net alex --out lpips_alex.safetensors

The file holds the `lpips.LPIPS(net=...)` state_dict under the package's own key names
(`scaling_layer.shift/scale`, `net.slice{s}.{i}.weight/bias`, `lin{k}.model.1.weight`, and
the duplicate `lins.{k}.model.1.weight`), all float32. `LpipsWeights::from_safetensors`
(crates/losses) reads exactly these keys. Two extra tensors, `check/input0`, `check/input1`
([2, 3, 64, 64] in [0, 1]) and `check/lpips` ([2]), record the package's own output
(`normalize=True`) so a port can verify itself against the exported weights.

Without such a file envision4d reports LPIPS as unavailable; it never computes LPIPS with
random weights.
"""

import argparse
import sys

CHECK_SEED = 1357
CHECK_SHAPE = (2, 3, 64, 64)


def build_state(net: str):
    import torch
    import lpips

    # pretrained=True: the package's shipped lin weights; pnet_rand=False: torchvision's
    # ImageNet backbone (downloaded on first use).
    model = lpips.LPIPS(net=net, pretrained=True, pnet_rand=False, verbose=False).eval()
    tensors = {}
    for key, value in model.state_dict().items():
        # clone(): `lins.k` and `link` are the same Parameter; safetensors refuses shared
        # storage, so every entry gets its own copy.
        tensors[key] = value.detach().to(torch.float32).contiguous().clone()

    generator = torch.Generator().manual_seed(CHECK_SEED)
    x0 = torch.rand(CHECK_SHAPE, generator=generator)
    x1 = torch.rand(CHECK_SHAPE, generator=generator)
    with torch.no_grad():
        check = model(x0, x1, normalize=True).reshape(-1)
    tensors["check/input0"] = x0
    tensors["check/input1"] = x1
    tensors["check/lpips"] = check.to(torch.float32)
    return tensors


def validate(tensors: dict, net: str) -> None:
    channels = {"vgg": [64, 128, 256, 512, 512], "alex": [64, 192, 384, 256, 256]}[net]
    for k, ch in enumerate(channels):
        lin = tensors.get(f"lin{k}.model.1.weight")
        if lin is None or tuple(lin.shape) != (1, ch, 1, 1):
            sys.exit(f"unexpected lin{k} weight: {None if lin is None else tuple(lin.shape)}")
        if (lin < 0).any():
            sys.exit(f"lin{k} has negative weights; not the shipped lpips v0.1 weights")
    if "net.slice1.0.weight" not in tensors:
        sys.exit("backbone weights missing from the LPIPS state_dict")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--net", choices=["vgg", "alex"], default="vgg")
    parser.add_argument("--out", required=True, help="output .safetensors path")
    args = parser.parse_args()

    import lpips
    import torch
    import torchvision
    from safetensors.torch import save_file

    tensors = build_state(args.net)
    validate(tensors, args.net)
    metadata = {
        "format": "envision4d-lpips-v1",
        "net": args.net,
        "lpips_version": getattr(lpips, "__version__", "unknown"),
        "torch_version": torch.__version__,
        "torchvision_version": torchvision.__version__,
        "check_seed": str(CHECK_SEED),
    }
    save_file(tensors, args.out, metadata=metadata)
    print(f"wrote {len(tensors)} tensors to {args.out} (net={args.net})")


if __name__ == "__main__":
    main()
