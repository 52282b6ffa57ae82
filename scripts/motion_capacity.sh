#!/usr/bin/env bash
# Capacity check of the motion head (docs/RESULTS.md, "Motion diagnostics"): the exact flow as
# a direct, balanced target (configs/motion/cml-flow-capacity.toml) on a growing number of
# training windows of the motion-constant preset. Fitting one window says the head can
# express the suite's object motion at this size; the windows count at which the fit breaks
# says how far that is from learning motion in general.
#
#   scripts/motion_capacity.sh                       # 1, 8 and 32 windows at 56x84 (~1 h here)
#   WINDOWS="1" scripts/motion_capacity.sh           # one run
#   FREEZE=none WINDOWS="32" scripts/motion_capacity.sh   # the encoder trained as well
#   WINDOWS="all" scripts/motion_capacity.sh          # every training clip of the benchmark
#   BATCH=2 WINDOWS="8" scripts/motion_capacity.sh    # two windows a step (the benchmark's)
#   STEPS=2000 WINDOWS="all" scripts/motion_capacity.sh   # five times the steps
#   SIZE=112x168 WINDOWS="1" scripts/motion_capacity.sh   # the shipped model at 112x168
#
# Data: the training and held-out clips of the motion benchmark's motion-constant preset
# (the same seeds as scripts/motion_bench.sh, made here when missing). Windows: N = 1 is
# clip 0's first window (stride 16); N >= 2 are the first N/2 clips, two windows each
# (stride 8); "all" is every clip of all five motion types (160 windows, the benchmark's
# training clips; held out, still the motion-constant clips). Each run is evaluated on its own windows (the fit) and on the 8 held-out
# clips (generalisation); the table goes to runs/motion-capacity[-SIZE][-sSTEPS][-bB][-unfrozen]/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${ENVISION4D:-${CARGO_TARGET_DIR:-$ROOT/target}/release/envision4d}
SIZE=${SIZE:-56x84}
WINDOWS=${WINDOWS:-"1 8 32"}
FREEZE=${FREEZE:-frozen}
BATCH=${BATCH:-1}
STEPS=${STEPS:-400}
PRESET=motion-constant
case "$FREEZE" in
  frozen) SUFFIX="" ;;
  none) SUFFIX="-unfrozen" ;;
  *) echo "FREEZE must be frozen or none, not '$FREEZE'" >&2; exit 2 ;;
esac
case "$BATCH" in
  1) ;;
  ''|*[!0-9]*|0) echo "BATCH must be a whole number >= 1, not '$BATCH'" >&2; exit 2 ;;
  *) SUFFIX="-b$BATCH$SUFFIX" ;;
esac
case "$STEPS" in
  400) ;;
  ''|*[!0-9]*|0) echo "STEPS must be a whole number >= 1, not '$STEPS'" >&2; exit 2 ;;
  *) SUFFIX="-s$STEPS$SUFFIX" ;;
esac
case "$SIZE" in
  56x84) SUFFIX="$SUFFIX" ;;
  *x*) SUFFIX="-$SIZE$SUFFIX" ;;
  *) echo "SIZE must be HxW, not '$SIZE'" >&2; exit 2 ;;
esac
DATA=$ROOT/data/motion-$SIZE
RUNS=$ROOT/runs/motion-capacity$SUFFIX
mkdir -p "$RUNS"
# The motion benchmark's seeds for this preset (its first): 100 training, 2100 held out.
if [ ! -d "$DATA/motion-train-$PRESET" ]; then
  "$BIN" synth --out "$DATA/motion-train-$PRESET" --clips 16 --frames 16 --size "$SIZE" \
    --preset "$PRESET" --seed 100
fi
if [ ! -d "$DATA/motion-heldout/$PRESET" ]; then
  "$BIN" synth --out "$DATA/motion-heldout/$PRESET" --clips 8 --frames 8 --size "$SIZE" \
    --preset "$PRESET" --seed 2100
fi
h=${SIZE%x*} w=${SIZE#*x}
for n in $WINDOWS; do
  case "$n" in
    all) ;;
    ''|*[!0-9]*|0) echo "WINDOWS holds whole numbers >= 1 or 'all', not '$n'" >&2; exit 2 ;;
  esac
  run="$RUNS/w$n"
  if [ "$n" = all ]; then
    # Every motion type's training clips (the benchmark's training folder), two windows each.
    if [ ! -d "$DATA/motion-train" ]; then
      echo "no $DATA/motion-train: WINDOWS=all reads the motion benchmark's training clips (BASE=shipped scripts/motion_bench.sh makes them)" >&2
      exit 2
    fi
    stride=8
    [ -e "$run/data" ] || { mkdir -p "$run"; ln -s "$DATA/motion-train" "$run/data"; }
  else
    if [ "$n" = 1 ]; then clips=1 stride=16; else clips=$(((n + 1) / 2)) stride=8; fi
  fi
  if [ "$n" != all ] && [ ! -d "$run/data" ]; then
    mkdir -p "$run/data.tmp"
    for i in $(seq 0 $((clips - 1))); do
      ln -s "$DATA/motion-train-$PRESET/$(printf clip_%06d "$i")" "$run/data.tmp/"
    done
    mv "$run/data.tmp" "$run/data"
  fi
  sed -e "s#^root = .*#root = \"$run/data\"#" \
      -e "s#^out_dir = .*#out_dir = \"$run\"#" \
      -e "s#^image_size = .*#image_size = [$h, $w]#" \
      -e "s#^stride = .*#stride = $stride#" \
      -e "s#^batch_size = .*#batch_size = $BATCH#" \
      -e "s#^iterations = .*#iterations = $STEPS#" \
      -e "s#^init_checkpoint = .*#init_checkpoint = \"$ROOT/models/envision4d-synth-tiny.safetensors\"#" \
      "$ROOT/configs/motion/cml-flow-capacity.toml" > "$run.toml"
  if [ "$FREEZE" = none ]; then
    sed -i -e 's#^freeze = .*#freeze = []#' "$run.toml"
  fi
  if [ ! -f "$run/model.safetensors" ]; then
    resume=()
    if [ -d "$run/checkpoints" ]; then resume=(--resume "$run"); fi
    echo "== $n window(s), $SIZE, encoder $FREEZE"
    "$BIN" train --config "$run.toml" "${resume[@]}"
  fi
  [ -f "$run/eval-fit/metrics.json" ] || "$BIN" eval --checkpoint "$run/model.safetensors" \
    --data "$run/data" --stride "$stride" --out "$run/eval-fit" > "$run/eval-fit.txt"
  [ -f "$run/eval-heldout/metrics.json" ] || "$BIN" eval --checkpoint "$run/model.safetensors" \
    --data "$DATA/motion-heldout/$PRESET" --out "$run/eval-heldout" > "$run/eval-heldout.txt"
done
python3 - "$RUNS" $WINDOWS <<'PY' | tee "$RUNS/table.md"
import json, os, sys
runs, windows = sys.argv[1], sys.argv[2:]
print("| windows | flow term, first / last 20 logged steps | fit: rel EPE moving | fit: static EPE (m) | fit: mask IoU | held out: rel EPE moving | held out: static EPE (m) |")
print("|---|---|---|---|---|---|---|")
for n in windows:
    d = os.path.join(runs, f"w{n}")
    flows = [r["flow"] for r in map(json.loads, open(os.path.join(d, "log.jsonl")))
             if r.get("kind") == "step" and r.get("flow") is not None]
    m = lambda xs: sum(xs) / len(xs)
    cells = [n, f"{m(flows[:20]):.3f} / {m(flows[-20:]):.3f}"]
    for ev in ("eval-fit", "eval-heldout"):
        mo = json.load(open(os.path.join(d, ev, "metrics.json")))["mean"]["motion"]
        cells += [f"{mo['rel_epe_dynamic']:.3f}", f"{mo['epe_static']:.3f}"]
        if ev == "eval-fit":
            cells.append(f"{mo['mask_iou']:.3f}")
    print("| " + " | ".join(map(str, cells)) + " |")
PY
