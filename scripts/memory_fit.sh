#!/usr/bin/env bash
# Measures the peak memory of one training step on a grid of small configs and fits the
# memory model's coefficients (crates/train/src/memory.rs, docs/PERFORMANCE.md "Memory
# model"). Every run is the training-step benchmark (the paper's step from
# configs/waymo.toml with random weights: frozen teacher, LPIPS, the paper's freeze list) at
# small widths and sizes, with the frozen blocks kept or recomputed; three runs are left out
# of the fit and only predicted.
#
#   scripts/memory_fit.sh [OUT_DIR]        (default runs/memory-fit; ~10 min on 2 cores)
#
# Logs land in OUT_DIR/<run>.log; the fit and the table are printed and kept in
# OUT_DIR/fit.md. Runs whose log is complete are not run again (delete a log to redo it).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-runs/memory-fit}
mkdir -p "$OUT"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}
# The benchmark binary cargo built just now (not an older one with other features).
BENCH=$(cargo bench --workspace --bench train_step --no-run --message-format=json \
    2> "$OUT/build.log" | python3 -c '
import json, sys
exe = [m["executable"] for m in map(json.loads, sys.stdin)
       if m.get("reason") == "compiler-artifact" and m.get("executable")
       and m["target"]["name"] == "train_step"]
print(exe[-1])')

KEPT=(--set run.recompute_frozen_blocks=false)
TINY=("${KEPT[@]}" --set model.preset=tiny)
WIDE=("${KEPT[@]}" --set model.preset=tiny --set model.embed_dim=192 --set model.num_heads=4
      --set model.dino.embed_dim=192 --set model.dino.depth=4 --set model.dpt.features=64
      --set "model.dpt.out_channels=[32,64,128,128]")
RECOMPUTE=(--set run.recompute_frozen_blocks=true)

run() {
    local name=$1
    shift
    if grep -q '^train_step_s=' "$OUT/$name.log" 2>/dev/null; then
        return
    fi
    echo "== $name: $*"
    "$BENCH" --repeats 1 "$@" > "$OUT/$name.tmp"
    mv "$OUT/$name.tmp" "$OUT/$name.log"
}

run tiny-56x84 "${TINY[@]}" --image 56x84 --batch 1
run tiny-112x168 "${TINY[@]}" --image 112x168 --batch 1
run tiny-112x168-b2 "${TINY[@]}" --image 112x168 --batch 2
run tiny-224x336 "${TINY[@]}" --image 224x336 --batch 1
run tiny-224x336-recompute "${TINY[@]}" --image 224x336 "${RECOMPUTE[@]}" --batch 1
run tiny-224x336-nolpips "${TINY[@]}" --image 224x336 --set loss.lambda_lpips=0.0 --batch 1
run tiny-112x168-tf4 "${TINY[@]}" --image 112x168 --set model.future_frames=4 --batch 1
run wide-112x168 "${WIDE[@]}" --image 112x168 --batch 1
run wide-224x336 "${WIDE[@]}" --image 224x336 --batch 1
run wide-224x336-recompute "${WIDE[@]}" --image 224x336 "${RECOMPUTE[@]}" --batch 1
run wide-168x252-b2 "${WIDE[@]}" --image 168x252 --batch 2

python3 scripts/memory_fit.py "$OUT" --check tiny-112x168-tf4 tiny-112x168-b2 \
    wide-168x252-b2 | tee "$OUT/fit.md"
