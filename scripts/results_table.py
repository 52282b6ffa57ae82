#!/usr/bin/env python3
"""Markdown table of `envision4d eval` runs: one row per (horizon run, method).

usage: results_table.py LABEL=DIR [LABEL=DIR ...]   (each DIR holds a metrics.json)
"""
import json
import sys

NAMES = {"model": "Envision4D (ours)", "copy_last": "copy last frame",
         "static_cv": "static + constant-velocity poses", "no_motion": "ours, motion off"}


def fmt(x, digits):
    return "n/a" if x is None else f"{x:.{digits}f}"


def main(args):
    print("| run | method | PSNR (dB) | SSIM | rot err (deg) | trans err, scale-aligned (m) | "
          "trans err, unaligned (m) | AUC@30 | time (s/clip) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, path = arg.rsplit("=", 1)
        m = json.load(open(f"{path}/metrics.json"))["mean"]
        for x in m["methods"]:
            auc = x.get("camera_auc30")
            print(f"| {label} | {NAMES.get(x['method'], x['method'])} | {fmt(x['psnr'], 2)} | "
                  f"{fmt(x['ssim'], 4)} | {fmt(x['rot_err_deg'], 2)} | {fmt(x['trans_err'], 3)} | "
                  f"{fmt(x.get('trans_err_unaligned'), 3)} | "
                  f"{fmt(None if auc is None else 100 * auc, 1)} | {fmt(x['time_s'], 3)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
