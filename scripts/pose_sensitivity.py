#!/usr/bin/env python3
"""Does a checkpoint's pose prediction look at the motion between its context frames?

usage: pose_sensitivity.py CKPT CLIPS_DIR [--start S] [--bin PATH] [--work DIR]

For every clip under CLIPS_DIR (synthetic layout: rgb/*.png + cameras.json) it runs
`envision4d render --outputs poses` three times on frames S, S+1:
- in order: the predicted camera of context frame 1 and of the last future frame;
- with frame S given twice (no motion at all between the two inputs);
- in reverse order (S+1, S: the true motion runs backwards).
It then prints, over the clips, the correlation between predicted and true forward distance driven
(frame 1 and the last future frame) and between predicted and true yaw of frame 1, and how
far the predictions move when the second frame is replaced. A model that perceives ego
motion correlates with the truth *within* one preset (where the scene type cannot give the
speed away), drives ~0 m on identical frames and backwards on reversed ones.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

DEFAULT_BIN = os.path.expanduser("~/.cache/envision4d-target/release/envision4d")


def rigid_inverse(m):
    r = [[m[j][i] for j in range(3)] for i in range(3)]
    t = [-sum(r[i][k] * m[k][3] for k in range(3)) for i in range(3)]
    return [r[i] + [t[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def relative(poses, j):
    """Pose j with frame 0's camera as the world: P_j · P_0⁻¹."""
    return mul(poses[j], rigid_inverse(poses[0]))


def forward(m):
    """Signed forward (z, OpenCV) coordinate of the camera centre -Rᵀt in frame 0's camera."""
    return rigid_inverse(m)[2][3]


def yaw_deg(m):
    """Signed rotation about the camera's y axis (down), from R's antisymmetric part."""
    return math.degrees(math.atan2(m[0][2] - m[2][0], m[0][0] + m[2][2]))


def render(binary, ckpt, frames, out):
    subprocess.run([binary, "render", "--checkpoint", ckpt, "--frames", *frames, "--out", out,
                    "--outputs", "poses"], check=True, capture_output=True)
    with open(os.path.join(out, "poses.json")) as f:
        return [fr["world_to_camera"] for fr in json.load(f)["frames"]]


def corr(xs, ys):
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    sx = math.sqrt(sum((x - mx) ** 2 for x in xs))
    sy = math.sqrt(sum((y - my) ** 2 for y in ys))
    return sxy / (sx * sy) if sx > 0 and sy > 0 else float("nan")


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("ckpt", help="our safetensors checkpoint")
    parser.add_argument("root", help="folder of synthetic-layout clips")
    parser.add_argument("--start", type=int, default=0, help="first context frame")
    parser.add_argument("--bin", default=DEFAULT_BIN, help="the envision4d binary")
    parser.add_argument("--work", help="where the renders go (default: a temp folder)")
    a = parser.parse_args(argv)
    ckpt, root, start, binary = a.ckpt, a.root, a.start, a.bin
    work = a.work or tempfile.mkdtemp(prefix="pose-sensitivity-")
    rows = []
    for clip in sorted(os.listdir(root)):
        rgb = os.path.join(root, clip, "rgb")
        if not os.path.isdir(rgb):
            continue
        names = sorted(os.listdir(rgb))
        a, b = (os.path.join(rgb, names[start + k]) for k in (0, 1))
        with open(os.path.join(root, clip, "cameras.json")) as f:
            gt = [fr["world_to_camera"] for fr in json.load(f)["frames"]][start:]
        runs = {kind: render(binary, ckpt, frames, os.path.join(work, clip, kind))
                for kind, frames in [("order", [a, b]), ("same", [a, a]), ("reverse", [b, a])]}
        last = len(runs["order"]) - 1
        gt = gt[: last + 1]
        rows.append({
            "gt_d1": forward(relative(gt, 1)), "gt_dl": forward(relative(gt, last)),
            "gt_yaw": yaw_deg(relative(gt, 1)),
            **{f"{k}_d1": forward(relative(p, 1)) for k, p in runs.items()},
            "order_dl": forward(relative(runs["order"], last)),
            "order_yaw": yaw_deg(relative(runs["order"], 1)),
            "same_yaw": yaw_deg(relative(runs["same"], 1)),
        })
    if len(rows) < 3:
        sys.exit(f"need at least 3 clips under {root}, found {len(rows)}")
    col = lambda k: [r[k] for r in rows]  # noqa: E731
    mean = lambda k: sum(col(k)) / len(rows)  # noqa: E731
    print(f"{len(rows)} clips of {root}, context frames {start}, {start + 1}")
    print(f"frame 1 forward: truth {mean('gt_d1'):.3f} m, predicted {mean('order_d1'):.3f} m, "
          f"correlation {corr(col('order_d1'), col('gt_d1')):+.2f}")
    print(f"last future frame forward: truth {mean('gt_dl'):.3f} m, predicted "
          f"{mean('order_dl'):.3f} m, correlation {corr(col('order_dl'), col('gt_dl')):+.2f}")
    print(f"frame 1 yaw: truth mean |.| {sum(abs(v) for v in col('gt_yaw')) / len(rows):.3f} deg,"
          f" predicted {sum(abs(v) for v in col('order_yaw')) / len(rows):.3f} deg,"
          f" correlation {corr(col('order_yaw'), col('gt_yaw')):+.2f}")
    print(f"frame 1 forward with the first frame twice: {mean('same_d1'):.3f} m; reversed "
          f"order: {mean('reverse_d1'):.3f} m (a motion-aware model: ~0 m, and about minus the truth)")
    print(f"frame 1 yaw with the first frame twice: mean |.| "
          f"{sum(abs(v) for v in col('same_yaw')) / len(rows):.3f} deg")


if __name__ == "__main__":
    main(sys.argv[1:])
