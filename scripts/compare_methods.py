#!/usr/bin/env python3
"""Paired comparison of the model against each baseline in `envision4d eval` runs.

usage: compare_methods.py LABEL=DIR [LABEL=DIR ...]   (each DIR holds a metrics.json)

For every run and baseline, per metric: the mean of (model - baseline) over clips, its 95%
interval (normal approximation, 1.96 standard errors) and how many clips the model wins.
Samples of one clip (windows `clip@start` from `eval --stride`) overlap in frames, so they
are averaged per clip first: the interval is over independent clips, not windows.
A difference is called a win or a loss only when its interval excludes zero.
"""
import json
import math
import sys
from collections import defaultdict

BASELINES = {"copy_last": "copy last frame", "static_cv": "static + CV poses",
             "no_motion": "ours, motion off"}
# metric key, label, +1 when larger is better, digits
METRICS = [("psnr", "PSNR (dB)", 1, 2), ("ssim", "SSIM", 1, 4),
           ("rot_err_deg", "rot err (deg)", -1, 2), ("trans_err_m", "trans err (m)", -1, 3)]


def per_clip(report):
    """{clip: {method: {metric: mean over the clip's windows}}}."""
    sums = defaultdict(lambda: defaultdict(lambda: defaultdict(list)))
    for sample in report["clips"]:
        clip = sample["clip"].split("@")[0]
        for m in sample["methods"]:
            for key, *_ in METRICS:
                if m.get(key) is not None:
                    sums[clip][m["method"]][key].append(m[key])
    return {c: {m: {k: sum(v) / len(v) for k, v in ks.items()} for m, ks in ms.items()}
            for c, ms in sums.items()}


def verdict(mean, half, sign):
    if abs(mean) <= half:
        return "level"
    return "win" if mean * sign > 0 else "loss"


def main(args):
    print("| run | against | metric | model | baseline | difference (95% interval) | clips won | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, path = arg.rsplit("=", 1)
        clips = per_clip(json.load(open(f"{path}/metrics.json")))
        for base, base_name in BASELINES.items():
            for key, name, sign, digits in METRICS:
                if base == "no_motion" and key in ("rot_err_deg", "trans_err_m"):
                    continue  # same cameras as the model by construction
                pairs = [(c["model"][key], c[base][key]) for c in clips.values()
                         if key in c.get("model", {}) and key in c.get(base, {})]
                if len(pairs) < 2:
                    continue
                d = [a - b for a, b in pairs]
                n = len(d)
                mean = sum(d) / n
                sd = math.sqrt(sum((x - mean) ** 2 for x in d) / (n - 1))
                half = 1.96 * sd / math.sqrt(n)
                won = sum(1 for x in d if x * sign > 0)
                ma = sum(a for a, _ in pairs) / n
                mb = sum(b for _, b in pairs) / n
                print(f"| {label} | {base_name} | {name} | {ma:.{digits}f} | {mb:.{digits}f} | "
                      f"{mean:+.{digits}f} (±{half:.{digits}f}) | {won}/{n} | "
                      f"{verdict(mean, half, sign)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
