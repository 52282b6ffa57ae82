#!/usr/bin/env bash
# Where the rendering loss's gradient goes while the motion benchmark's CML variant trains
# (issue: the motion head learns no object motion, whatever the schedule length or seed).
# Trains configs/motion/cml.toml as scripts/motion_bench.sh BASE=shipped does (56x84, from
# the shipped tiny model, motion head and temporal blocks fresh) for its 600 steps, then
# summarises log.jsonl's per-module gradient norms (`grad_norms`, before clipping) by
# phase with scripts/motion_grad_norms.py. Needs the suite's data (motion_bench.sh makes it
# in data/motion-56x84).
#
#   scripts/motion_grad_norms.sh [OUT_DIR]     (default runs/motion-grad-norms; ~8 min)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/motion-grad-norms}
BIN=${ENVISION4D:-${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}/release/envision4d}
DATA=data/motion-56x84/motion-train
[ -d "$DATA" ] || { echo "no $DATA: run scripts/motion_bench.sh BASE=shipped first" >&2; exit 2; }
if [ ! -f "$OUT/model.safetensors" ]; then
  resume=()
  [ -d "$OUT/checkpoints" ] && resume=(--resume "$OUT")
  "$BIN" train --config configs/motion/cml.toml --seed 0 --out-dir "$OUT" "${resume[@]}" \
    --set init_checkpoint='"models/envision4d-synth-tiny.safetensors"' \
    --set 'init_fresh=["motion_head", "time_blocks"]' \
    --set 'model.image_size=[56, 84]' \
    --set data.root="\"$DATA\"" \
    --set run.log_every=10
fi
python3 scripts/motion_grad_norms.py "$OUT/log.jsonl" | tee "$OUT/grad_norms.md"
