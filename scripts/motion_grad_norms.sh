#!/usr/bin/env bash
# Where the rendering loss's gradient goes while the motion benchmark's CML variant trains
# (the motion head learns no object motion, whatever the schedule length or seed:
# docs/RESULTS.md, "Motion"). Trains configs/motion/cml.toml as scripts/motion_bench.sh
# BASE=shipped does (56x84, from the shipped tiny model, motion head and temporal blocks
# fresh) for its 600 steps, once as configured (Adam eps 1e-5) and once with PyTorch's
# eps 1e-8, summarises log.jsonl's per-module gradient norms (`grad_norms`, `grad_rms`,
# before clipping) by phase with scripts/motion_grad_norms.py, and scores both on the five
# held-out motion presets (dynamic relative EPE, future PSNR). Needs the suite's data
# (motion_bench.sh makes it in data/motion-56x84).
#
#   scripts/motion_grad_norms.sh [OUT_DIR]     (default runs/motion-grad-norms; ~30 min)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/motion-grad-norms}
BIN=${ENVISION4D:-${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}/release/envision4d}
DATA=data/motion-56x84
PRESETS="motion-constant motion-accelerating motion-turning motion-crossing motion-stop-and-go"
[ -d "$DATA/motion-train" ] || {
  echo "no $DATA/motion-train: run scripts/motion_bench.sh BASE=shipped first" >&2
  exit 2
}

# run NAME EPS: trains one run into $OUT/NAME (resuming a started one) and evaluates it.
run() {
  local name=$1 eps=$2 dir="$OUT/$1"
  if [ ! -f "$dir/model.safetensors" ]; then
    local resume=()
    [ -d "$dir/checkpoints" ] && resume=(--resume "$dir")
    "$BIN" train --config configs/motion/cml.toml --seed 0 --out-dir "$dir" "${resume[@]}" \
      --set init_checkpoint='"models/envision4d-synth-tiny.safetensors"' \
      --set 'init_fresh=["motion_head", "time_blocks"]' \
      --set 'model.image_size=[56, 84]' \
      --set data.root="\"$DATA/motion-train\"" \
      --set run.log_every=10 \
      --set optim.adam_epsilon="$eps"
  fi
  for p in $PRESETS; do
    [ -f "$dir/eval-$p/metrics.json" ] ||
      "$BIN" eval --checkpoint "$dir/model.safetensors" --data "$DATA/motion-heldout/$p" \
        --out "$dir/eval-$p" > "$dir/eval-$p.txt"
  done
}

run eps-1e-5 1e-5
run eps-1e-8 1e-8
for name in eps-1e-5 eps-1e-8; do
  echo "## $name"
  python3 scripts/motion_grad_norms.py "$OUT/$name/log.jsonl"
  echo
done | tee "$OUT/grad_norms.md"
python3 - "$OUT" $PRESETS <<'PY' | tee -a "$OUT/grad_norms.md"
import json, sys
out, presets = sys.argv[1], sys.argv[2:]
print("| run | " + " | ".join(f"{p}: rel EPE dyn / future PSNR" for p in presets) + " |")
print("|---|" + "---|" * len(presets))
for name in ["eps-1e-5", "eps-1e-8"]:
    cells = []
    for p in presets:
        m = json.load(open(f"{out}/{name}/eval-{p}/metrics.json"))["mean"]
        epe = (m.get("motion") or {}).get("rel_epe_dynamic")
        epe = "-" if epe is None else f"{epe:.3f}"
        cells.append(f"{epe} / {m['methods'][0]['psnr']:.2f}")
    print(f"| {name} | " + " | ".join(cells) + " |")
PY
