#!/usr/bin/env python3
"""Fits the memory model's coefficients (crates/train/src/memory.rs) to measured peaks.

Reads the training-step benchmark logs that scripts/memory_fit.sh wrote (one per run),
takes from each its "# memory model:" counts and exact terms and its measured peaks (the
first step's and the later steps'), and fits

    peak - exact = runtime + block*B + recomputed*C + dpt*D + render*R + lpips*L

by least squares on relative residuals with every coefficient >= 0 (all subsets of the
coefficients are tried; the best non-negative solution wins). Prints the Rust constants,
then a Markdown table of measured vs estimated peaks.

Usage: memory_fit.py LOG_DIR [--check NAME ...]   (runs named in --check are left out
of the fit and only compared, to show the model predicts what it was not fitted on)
"""
import itertools
import pathlib
import re
import sys

GIB = float(1 << 30)
NAMES = ["runtime", "block", "recomputed", "dpt", "render", "lpips"]


def parse(path):
    text = path.read_text()
    model = re.search(r"# memory model: (.*)", text)
    first = re.search(r"first_step_peak_rss_gib=([0-9.]+)", text)
    later = re.findall(r"train_step_s=([0-9.]+) peak_rss_gib=([0-9.]+)", text)
    if not (model and first and later):
        return None
    kv = dict(p.split("=") for p in model.group(1).split())
    # A log written before the recomputed-block count existed comes from a run that
    # recomputed nothing.
    kv.setdefault("recomputed_token_channels", "0")
    x = [1.0] + [float(kv[k]) for k in
                 ["block_token_channels", "recomputed_token_channels", "dpt_pixel_channels",
                  "rendered_pixels", "lpips_pixels"]]
    header = re.search(r"# train step: (.*)", text).group(1)
    return {
        "name": path.stem,
        "header": header,
        "x": x,
        "exact_first": float(kv["exact_first_bytes"]),
        "exact_later": float(kv["exact_later_bytes"]),
        "first": float(first.group(1)) * GIB,
        "later": float(later[-1][1]) * GIB,
        "step_s": float(later[-1][0]),
    }


def solve(rows, cols):
    """Weighted least squares on the given columns (weights 1/y); None if singular."""
    n = len(cols)
    a = [[0.0] * n for _ in range(n)]
    b = [0.0] * n
    for x, y, w in rows:
        for i, ci in enumerate(cols):
            b[i] += w * w * x[ci] * y
            for j, cj in enumerate(cols):
                a[i][j] += w * w * x[ci] * x[cj]
    # Gaussian elimination with partial pivoting.
    for i in range(n):
        p = max(range(i, n), key=lambda r: abs(a[r][i]))
        if abs(a[p][i]) < 1e-300:
            return None
        a[i], a[p] = a[p], a[i]
        b[i], b[p] = b[p], b[i]
        for r in range(i + 1, n):
            f = a[r][i] / a[i][i]
            for c in range(i, n):
                a[r][c] -= f * a[i][c]
            b[r] -= f * b[i]
    sol = [0.0] * n
    for i in reversed(range(n)):
        sol[i] = (b[i] - sum(a[i][c] * sol[c] for c in range(i + 1, n))) / a[i][i]
    return sol


def fit(runs):
    rows = []
    for r in runs:
        for peak, exact in [(r["first"], r["exact_first"]), (r["later"], r["exact_later"])]:
            rows.append((r["x"], peak - exact, 1.0 / peak))
    best = None
    for k in range(1, len(NAMES) + 1):
        for cols in itertools.combinations(range(len(NAMES)), k):
            sol = solve(rows, list(cols))
            if sol is None or min(sol) < 0:
                continue
            coef = [0.0] * len(NAMES)
            for c, v in zip(cols, sol):
                coef[c] = v
            err = sum((w * (y - sum(c * xi for c, xi in zip(coef, x)))) ** 2 for x, y, w in rows)
            if best is None or err < best[0]:
                best = (err, coef)
    return best[1]


def main():
    args = sys.argv[1:]
    check = set(args[args.index("--check") + 1:]) if "--check" in args else set()
    logs = sorted(pathlib.Path(args[0]).glob("*.log"))
    runs = [r for r in map(parse, logs) if r]
    coef = fit([r for r in runs if r["name"] not in check])
    print("pub const FITTED: Coefficients = Coefficients {")
    for n, c in zip(NAMES, coef):
        print(f"    {n}: {c:.6e},")
    print("};\n")
    print("| run | settings | step s | first step GiB measured / estimated | later steps GiB measured / estimated | fitted on |")
    print("|---|---|---|---|---|---|")
    worst = 1.0
    for r in runs:
        act = sum(c * x for c, x in zip(coef, r["x"]))
        ef, el = (r["exact_first"] + act) / GIB, (r["exact_later"] + act) / GIB
        mf, ml = r["first"] / GIB, r["later"] / GIB
        worst = max(worst, ef / mf, mf / ef, el / ml, ml / el)
        print(f"| {r['name']} | {r['header']} | {r['step_s']:.1f} | {mf:.3f} / {ef:.3f} | "
              f"{ml:.3f} / {el:.3f} | {'no' if r['name'] in check else 'yes'} |")
    print(f"\nlargest ratio between estimate and measurement: {worst:.3f}")


if __name__ == "__main__":
    main()
