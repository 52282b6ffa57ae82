#!/usr/bin/env bash
# Trains the eight small-scale ablation variants (configs/ablation/*.toml, 400 steps each from
# the stage-1 backbone) and evaluates each on the held-out synthetic clips; writes
# runs/ablation-summary.md. Needs runs/synth-backbone/model.safetensors and
# data/synth-heldout (docs/TRAINING.md). About 50 minutes on a 2-core CPU.
set -euo pipefail
BIN=${ENVISION4D:-target/release/envision4d}
VARIANTS=${VARIANTS:-"paper linear-velocity-no-temporal linear-velocity no-temporal post-layer no-progressive no-warmup no-warmup-no-progressive"}
for v in $VARIANTS; do
  if [ ! -f "runs/ablation-$v/model.safetensors" ]; then
    "$BIN" train --config "configs/ablation/$v.toml"
  fi
  "$BIN" eval --checkpoint "runs/ablation-$v/model.safetensors" --data data/synth-heldout \
    --out "runs/ablation-$v/eval" > "runs/ablation-$v/eval.txt"
done
python3 - "$VARIANTS" <<'PY'
import json, sys
rows = ["| variant | future PSNR (dB) | SSIM | rot err (deg) | trans err (m) | context PSNR (dB) |",
        "|---|---|---|---|---|---|"]
for v in sys.argv[1].split():
    m = json.load(open(f"runs/ablation-{v}/eval/metrics.json"))["mean"]
    model = next(x for x in m["methods"] if x["method"] == "model")
    ctx = m["context"]
    f = lambda x, d: "n/a" if x is None else f"{x:.{d}f}"
    rows.append(f"| {v} | {f(model['psnr'],2)} | {f(model['ssim'],4)} | {f(model['rot_err_deg'],2)} | "
                f"{f(model['trans_err'],3)} | {f(ctx['psnr'],2)} |")
open("runs/ablation-summary.md", "w").write("\n".join(rows) + "\n")
print("\n".join(rows))
PY
