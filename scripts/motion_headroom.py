#!/usr/bin/env python3
"""Where a model's future-frame error goes (docs/RESULTS.md, "Motion"): for each evaluation
folder (written by `envision4d eval` on synthetic clips, which adds the oracle renders of
docs/EVAL.md), the mean future-frame PSNR and dynamic-region PSNR of:
  copy-last, the model, motion zeroed, the exact motion (oracle), and the same three at the
  true cameras,
then the gains that split the gap: cameras (true cameras − model), exact motion at the
model's cameras (oracle − no motion), exact motion at the true cameras, and the model's own
motion at the true cameras (true-cams model − true-cams no motion).

Standard library only. Usage: motion_headroom.py LABEL=EVAL_DIR [LABEL=EVAL_DIR ...]
"""
import sys

from motion_keep import read_metrics

METHODS = ["copy_last", "model", "no_motion", "oracle_motion",
           "true_cameras_no_motion", "true_cameras", "true_cameras_oracle_motion"]
SHORT = ["copy-last", "model", "zeroed", "oracle", "T no-mot", "T model", "T oracle"]



def load(path):
    report = read_metrics(path)
    clips = len(report["clips"])
    by = {m["method"]: m for m in report["mean"]["methods"]}
    missing = [m for m in METHODS if m not in by]
    if missing:
        sys.exit(f"{path}: no {', '.join(missing)} (not synthetic, or evaluated before the "
                 f"oracle renders existed: evaluate again)")
    return clips, by


def cell(x):
    return "n/a" if x is None else f"{x:.2f}"


def main():
    pairs = [a.split("=", 1) for a in sys.argv[1:]]
    if not pairs or any(len(p) != 2 for p in pairs):
        sys.exit(__doc__)
    rows = [(label, *load(path)) for label, path in pairs]
    print("Future-frame PSNR (dB), whole image / dynamic region; T = at the true cameras.\n")
    print("| set | clips | " + " | ".join(SHORT) + " |")
    print("|---|---|" + "---|" * len(SHORT))
    for label, n, by in rows:
        cells = [f"{cell(by[m]['psnr'])} / {cell(by[m]['dynamic_psnr'])}" for m in METHODS]
        print(f"| {label} | {n} | " + " | ".join(cells) + " |")
    print("\nGains (dB), whole image / dynamic region.\n")
    gains = [("cameras", "true_cameras", "model"),
             ("model's motion", "model", "no_motion"),
             ("exact motion", "oracle_motion", "no_motion"),
             ("model's motion, T", "true_cameras", "true_cameras_no_motion"),
             ("exact motion, T", "true_cameras_oracle_motion", "true_cameras_no_motion")]
    print("| set | " + " | ".join(g[0] for g in gains) + " |")
    print("|---|" + "---|" * len(gains))
    for label, _, by in rows:
        out = []
        for _, a, b in gains:
            d = by[a]["psnr"] - by[b]["psnr"]
            da, db = by[a]["dynamic_psnr"], by[b]["dynamic_psnr"]
            dd = "n/a" if da is None or db is None else f"{da - db:+.2f}"
            out.append(f"{d:+.2f} / {dd}")
        print(f"| {label} | " + " | ".join(out) + " |")


if __name__ == "__main__":
    main()
