#!/usr/bin/env python3
"""Paired comparison of the model against each baseline in `envision4d eval` runs.

usage: compare_methods.py [--grid] LABEL=DIR[#PREFIX] [LABEL=DIR[#PREFIX] ...]
       (each DIR holds a metrics.json; #PREFIX keeps only clips whose id starts with PREFIX)

For every run and baseline, per metric: the mean of (model - baseline) over clips, its 95%
interval (normal approximation, 1.96 standard errors) and how many clips the model wins.
Samples of one clip (windows `clip@start` from `eval --stride`) overlap in frames, so they
are averaged per clip first: the interval is over independent clips, not windows.
A difference is called a win or a loss only when its interval excludes zero.
`--grid`: one row per run, one cell per (baseline, metric) against copy-last and
constant-velocity: the difference and its verdict.
"""
import json
import math
import sys
from collections import defaultdict

BASELINES = {"copy_last": "copy last frame", "static_cv": "static + CV poses",
             "no_motion": "ours, motion off"}
# metric key, label, +1 when larger is better, digits
METRICS = [("psnr", "PSNR (dB)", 1, 2), ("ssim", "SSIM", 1, 4),
           ("rot_err_deg", "rot err (deg)", -1, 2), ("trans_err", "trans err (m)", -1, 3),
           ("trans_err_unaligned", "trans err, unaligned (m)", -1, 3)]
MARK = {"win": "win", "loss": "**loss**", "level": "level"}


def per_clip(report, prefix):
    """{clip: {method: {metric: mean over the clip's windows}}}."""
    sums = defaultdict(lambda: defaultdict(lambda: defaultdict(list)))
    for sample in report["clips"]:
        clip = sample["clip"].split("@")[0]
        if not clip.startswith(prefix):
            continue
        for m in sample["methods"]:
            for key, *_ in METRICS:
                if m.get(key) is not None:
                    sums[clip][m["method"]][key].append(m[key])
    return {c: {m: {k: sum(v) / len(v) for k, v in ks.items()} for m, ks in ms.items()}
            for c, ms in sums.items()}


def compare(clips, base, key, sign):
    """(model mean, baseline mean, mean difference, 95% half-width, clips won, n, verdict)."""
    pairs = [(c["model"][key], c[base][key]) for c in clips.values()
             if key in c.get("model", {}) and key in c.get(base, {})]
    n = len(pairs)
    if n < 2:
        return None
    d = [a - b for a, b in pairs]
    mean = sum(d) / n
    half = 1.96 * math.sqrt(sum((x - mean) ** 2 for x in d) / (n - 1)) / math.sqrt(n)
    won = sum(1 for x in d if x * sign > 0)
    verdict = "level" if abs(mean) <= half else ("win" if mean * sign > 0 else "loss")
    return (sum(a for a, _ in pairs) / n, sum(b for _, b in pairs) / n, mean, half, won, n,
            verdict)


def load(arg):
    label, spec = arg.rsplit("=", 1)
    path, _, prefix = spec.partition("#")
    return label, per_clip(json.load(open(f"{path}/metrics.json")), prefix)


def table(args):
    print("| run | against | metric | model | baseline | difference (95% interval) | clips won | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, clips = load(arg)
        for base, base_name in BASELINES.items():
            for key, name, sign, digits in METRICS:
                if base == "no_motion" and key in ("rot_err_deg", "trans_err", "trans_err_unaligned"):
                    continue  # same cameras as the model by construction
                r = compare(clips, base, key, sign)
                if r is None:
                    continue
                ma, mb, mean, half, won, n, verdict = r
                print(f"| {label} | {base_name} | {name} | {ma:.{digits}f} | {mb:.{digits}f} | "
                      f"{mean:+.{digits}f} (±{half:.{digits}f}) | {won}/{n} | {verdict} |")


def grid(args):
    bases = ["copy_last", "static_cv"]
    head = [f"{BASELINES[b]}: {name.split(' (')[0]}" for b in bases for _, name, _, _ in METRICS]
    print("| run | " + " | ".join(head) + " |")
    print("|---|" + "---|" * len(head))
    for arg in args:
        label, clips = load(arg)
        cells = []
        for b in bases:
            for key, _, sign, digits in METRICS:
                r = compare(clips, b, key, sign)
                cells.append("n/a" if r is None else
                             f"{r[2]:+.{digits}f} ±{r[3]:.{digits}f} {MARK[r[6]]}")
        print(f"| {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    argv = sys.argv[1:]
    if not argv:
        sys.exit(__doc__)
    if argv[0] == "--grid":
        grid(argv[1:])
    else:
        table(argv)
