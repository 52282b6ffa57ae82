#!/usr/bin/env python3
"""The Motion table of docs/RESULTS.md from the motion benchmark's evaluations.

Reads runs/motion/<variant>-s<seed>/eval-<preset>/metrics.json (written by
scripts/motion_bench.sh) and prints, per motion type (suite preset), each variant's mean over
seeds and held-out clips of:
  - dyn PSNR: future-frame PSNR on the ground-truth dynamic mask (dB),
  - EPE: scene-flow end-point error on moving pixels, future pairs (m),
  - rel: EPE relative to the true displacement (1 = no better than no motion),
  - IoU: dynamic-mask IoU of thresholded motion,
  - PSNR: whole-image future PSNR (dB),
and, against the reference variant (CML, the paper's), the paired difference per held-out
clip (each clip's value averaged over seeds first) with a 95% t-interval over clips.
"cml-zeroed" is the CML runs with their displacements zeroed at test time (the eval's
`no_motion` method): its EPE is the true displacement and its IoU 0. "cml-oracle" is the CML
runs' Gaussians moved by the exact scene flow (the eval's `oracle_motion` method): its EPE is
0 by construction, its PSNR the most any motion could add to that reconstruction.
"motion-off" is the variant trained without motion. Without "cml" among the variants the
paired columns are left out.

Standard library only. Usage: motion_table.py RUNS_DIR "variants" "seeds" "presets"
"""
import math
import os
import sys

from motion_keep import read_metrics

# Two-sided 95% quantiles of Student's t, df 1..30; larger df interpolate towards 1.96.
T975 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
        2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
        2.060, 2.056, 2.052, 2.048, 2.045, 2.042]
REFERENCE = "cml"
# Rows computed from the reference's runs: test-time zeroed and oracle displacements.
DERIVED = {"cml-zeroed": "no_motion", "cml-oracle": "oracle_motion"}



def t975(df):
    if df <= 0:
        return float("nan")
    if df <= len(T975):
        return T975[df - 1]
    # 40: 2.021, 60: 2.000, 120: 1.980, inf: 1.960 — within 0.005 of 1.96 + 2.4/df.
    return 1.96 + 2.4 / df


def model_values(clip, method):
    """The five numbers of one clip for the model, or one of its derived methods."""
    m = next((x for x in clip["methods"] if x["method"] == method), None)
    if m is None:
        sys.exit(f"clip {clip['clip']} has no '{method}' method (evaluated before the "
                 f"eval had it? delete that eval-*/ folder and rerun scripts/motion_bench.sh)")
    motion = clip.get("motion") or {}
    if method == "no_motion":
        epe = motion.get("true_displacement")
        rel = 1.0 if epe is not None else None
        iou = 0.0 if motion.get("mask_iou") is not None else None
    elif method == "oracle_motion":
        has = motion.get("epe_dynamic") is not None
        epe, rel, iou = (0.0 if has else None), (0.0 if has else None), None
    else:
        epe, rel, iou = (motion.get(k) for k in ("epe_dynamic", "rel_epe_dynamic", "mask_iou"))
    return {"dyn": m.get("dynamic_psnr"), "epe": epe, "rel": rel, "iou": iou, "psnr": m["psnr"]}


def load(runs, variant, seed, preset):
    src = REFERENCE if variant in DERIVED else variant
    method = DERIVED.get(variant, "model")
    report = read_metrics(os.path.join(runs, f"{src}-s{seed}", f"eval-{preset}"))
    return {c["clip"]: model_values(c, method) for c in report["clips"]}


def per_clip(runs, variant, seeds, preset):
    """clip -> metric -> mean over seeds (None when no seed has it)."""
    by_seed = [load(runs, variant, s, preset) for s in seeds]
    out = {}
    for clip in by_seed[0]:
        out[clip] = {}
        for k in by_seed[0][clip]:
            vals = [r[clip][k] for r in by_seed if clip in r and r[clip][k] is not None]
            out[clip][k] = sum(vals) / len(vals) if vals else None
    return out


def mean(xs):
    xs = [x for x in xs if x is not None]
    return sum(xs) / len(xs) if xs else None


def paired(a, b, key):
    """Mean of b − a over clips with both, and the 95% half-width."""
    d = [b[c][key] - a[c][key] for c in a if c in b and a[c][key] is not None and b[c][key] is not None]
    if len(d) < 2:
        return None, None, len(d)
    m = sum(d) / len(d)
    sd = math.sqrt(sum((x - m) ** 2 for x in d) / (len(d) - 1))
    return m, t975(len(d) - 1) * sd / math.sqrt(len(d)), len(d)


def fmt(x, digits):
    return "n/a" if x is None else f"{x:.{digits}f}"


def main():
    runs, variants, seeds, presets = sys.argv[1], sys.argv[2].split(), sys.argv[3].split(), sys.argv[4].split()
    keys = [("dyn", 2, "dyn PSNR (dB)"), ("epe", 3, "EPE moving (m)"), ("rel", 3, "rel EPE"),
            ("iou", 3, "mask IoU"), ("psnr", 2, "PSNR (dB)")]
    lines = [f"Seeds {', '.join(seeds)}; means over seeds and held-out clips. Paired columns: "
             f"variant − {REFERENCE} per clip (seeds averaged first), mean ± 95% t half-width "
             f"over clips.", ""]
    for preset in presets:
        table = {v: per_clip(runs, v, seeds, preset) for v in variants}
        ref = table.get(REFERENCE)
        clips = len(next(iter(table.values())))
        lines.append(f"### {preset} ({clips} held-out clips)")
        lines.append("")
        head = " | ".join(k[2] for k in keys)
        lines.append(f"| variant | {head} | Δ dyn PSNR | Δ EPE |")
        lines.append("|---|" + "---|" * (len(keys) + 2))
        for v in variants:
            t = table[v]
            cells = [fmt(mean(c[k] for c in t.values()), d) for k, d, _ in keys]
            deltas = []
            for key, digits in (("dyn", 2), ("epe", 3)):
                if v == REFERENCE or ref is None:
                    deltas.append("")
                    continue
                m, h, _ = paired(ref, t, key)
                deltas.append("n/a" if m is None else f"{m:+.{digits}f} ±{h:.{digits}f}")
            lines.append(f"| {v} | " + " | ".join(cells + deltas) + " |")
        lines.append("")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
