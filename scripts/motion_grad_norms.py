"""Summarises the per-module gradient norms of a training log (log.jsonl `grad_norms` and
`grad_rms`, before clipping) by phase: the median of each module's norm, its median share
of the total, and the median root mean square of its elements, over the logged steps of the
warm-up, the first and second half of the progressive phase. Pure Python (no numpy).

    python3 scripts/motion_grad_norms.py runs/motion-grad-norms/log.jsonl
"""
import json
import statistics
import sys


def main(path):
    steps = [json.loads(l) for l in open(path) if '"kind":"step"' in l]
    steps = [s for s in steps if s.get("grad_norms")]
    if not steps:
        sys.exit(f"{path}: no step with grad_norms")
    prog = [s for s in steps if s["phase"] != "warmup"]
    half = prog[len(prog) // 2]["step"] if prog else 0
    phases = [
        ("warm-up", [s for s in steps if s["phase"] == "warmup"]),
        ("progressive, 1st half", [s for s in prog if s["step"] < half]),
        ("progressive, 2nd half", [s for s in prog if s["step"] >= half]),
    ]
    groups = sorted({k for s in steps for k in s["grad_norms"]})
    phases = [(name, rows) for name, rows in phases if rows]

    def norm_cell(rows, g):
        vals = [s["grad_norms"][g] for s in rows if g in s["grad_norms"]]
        shares = [s["grad_norms"][g] / s["grad_norm"] for s in rows
                  if g in s["grad_norms"] and s["grad_norm"]]
        return (f"{statistics.median(vals):.3g} ({100 * statistics.median(shares):.0f}%)"
                if vals else "-")

    def rms_cell(rows, g):
        vals = [s["grad_rms"][g] for s in rows if g in s.get("grad_rms", {})]
        return f"{statistics.median(vals):.2g}" if vals else "-"

    print(f"Gradient norms before clipping, median over logged steps ({path})\n")
    print("| phase | steps | total | " + " | ".join(groups) + " |")
    print("|---|---|---|" + "---|" * len(groups))
    for name, rows in phases:
        total = statistics.median(s["grad_norm"] for s in rows)
        span = f"{rows[0]['step']}-{rows[-1]['step']}"
        cells = [norm_cell(rows, g) for g in groups]
        print(f"| {name} | {span} | {total:.3g} | " + " | ".join(cells) + " |")
    print("\n(share: a module's norm / the total norm, median over steps)\n")
    print("Root mean square of a gradient element (`grad_rms`), median over logged steps; "
          "Adam's epsilon is the config's `optim.adam_epsilon`\n")
    print("| phase | " + " | ".join(groups) + " |")
    print("|---|" + "---|" * len(groups))
    for name, rows in phases:
        print(f"| {name} | " + " | ".join(rms_cell(rows, g) for g in groups) + " |")

if __name__ == "__main__":
    main(sys.argv[1])
