#!/usr/bin/env python3
"""Share of ground-truth moving pixels in a synthetic dataset's training clips.

    python3 scripts/dynamic_coverage.py data/motion-56x84

Reads every `motion-train-*/clip_*/dynamic_mask/*.png` under the folder (the motion
benchmark's training data, scripts/motion_bench.sh) and prints, per preset and over all,
the percentage of pixels on the dynamic mask. docs/TRAINING.md ("Motion diagnostics") sets
`[loss] dynamic_weight` from it: with a share p, a weight w gives the movers
p(1 + w) / (p(1 + w) + 1 − p) of the MSE.
"""
import glob
import os
import sys

from PIL import Image


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    root = sys.argv[1]
    per = {}
    for f in sorted(glob.glob(os.path.join(root, "motion-train-*", "clip_*", "dynamic_mask", "*.png"))):
        preset = os.path.basename(os.path.dirname(os.path.dirname(os.path.dirname(f))))
        with Image.open(f) as im:
            band = im.convert("L")
            hist = band.histogram()
        on, total = sum(hist[1:]), sum(hist)
        acc = per.setdefault(preset, [0, 0])
        acc[0] += on
        acc[1] += total
    if not per:
        print(f"no dynamic masks under {root}/motion-train-*/clip_*/dynamic_mask", file=sys.stderr)
        return 2
    for preset, (on, total) in per.items():
        print(f"{preset}: {100 * on / total:.2f}% of {total} pixels")
    on = sum(v[0] for v in per.values())
    total = sum(v[1] for v in per.values())
    p = on / total
    print(f"all: {100 * p:.2f}%; dynamic_weight w gives the movers p(1+w)/(p(1+w)+1-p): "
          + ", ".join(f"w={w}: {p * (1 + w) / (p * (1 + w) + 1 - p):.2f}" for w in (4, 12, 20)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
