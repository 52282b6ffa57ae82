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
#   STEP=2 WINDOWS="all" scripts/motion_capacity.sh   # every other frame: twice the motion
#   CONTEXT=3 WINDOWS="all" scripts/motion_capacity.sh  # three context frames instead of two
#
# Data: the motion benchmark's clips at SIZE (the same seeds as scripts/motion_bench.sh, made
# here when missing). Windows: N = 1 is
# clip 0's first window (stride 16); N >= 2 are the first N/2 clips, two windows each
# (stride 8); "all" is every clip of all five motion types (160 windows, the benchmark's
# training clips). Each run is evaluated on its own windows (the fit), on the 8 held-out
# motion-constant clips (generalisation) and on the 8 held-out clips of each other motion type
# (does it read motion off the frames, or a type's prior?); the table goes to
# runs/motion-capacity[-SIZE][-cCONTEXT][-fSTEP][-sSTEPS][-bB][-unfrozen]/table.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${ENVISION4D:-${CARGO_TARGET_DIR:-$ROOT/target}/release/envision4d}
SIZE=${SIZE:-56x84}
WINDOWS=${WINDOWS:-"1 8 32"}
FREEZE=${FREEZE:-frozen}
BATCH=${BATCH:-1}
STEPS=${STEPS:-400}
# Source frames between the model's frames (data.frame_step): 2 doubles the motion a mover
# shows between the two context frames (the window must fit twice in a 16-frame clip).
STEP=${STEP:-1}
# Context frames T_c (model.context_frames; T_f stays the shipped model's 6).
CONTEXT=${CONTEXT:-2}
PRESET=motion-constant
case "$FREEZE" in
  frozen) SUFFIX="" ;;
  none) SUFFIX="-unfrozen" ;;
  *) echo "FREEZE must be frozen or none, not '$FREEZE'" >&2; exit 2 ;;
esac
# A whole-number knob NAME=value with default DEFAULT: validated, and (when not the default)
# named in the runs folder as -TAGvalue.
knob() {
  local name=$1 value=$2 default=$3 tag=$4
  case "$value" in
    "$default") ;;
    ''|*[!0-9]*|0) echo "$name must be a whole number >= 1, not '$value'" >&2; exit 2 ;;
    *) SUFFIX="-$tag$value$SUFFIX" ;;
  esac
}
knob BATCH "$BATCH" 1 b
knob STEPS "$STEPS" 400 s
knob STEP "$STEP" 1 f
knob CONTEXT "$CONTEXT" 2 c
case "$SIZE" in
  56x84) ;;
  *x*) SUFFIX="-$SIZE$SUFFIX" ;;
  *) echo "SIZE must be HxW, not '$SIZE'" >&2; exit 2 ;;
esac
DATA=$ROOT/data/motion-$SIZE
RUNS=$ROOT/runs/motion-capacity$SUFFIX
mkdir -p "$RUNS"
# Windows of CONTEXT + 6 frames, every STEP-th source frame: SPAN source frames each; two per
# 16-frame training clip are WSTRIDE apart. Held-out clips are 8 frames (the benchmark's) for
# a window of 8, one window of SPAN frames otherwise (the same seeds).
SPAN=$(((CONTEXT + 5) * STEP + 1))
if [ "$SPAN" -gt 15 ]; then
  echo "a window of $((CONTEXT + 6)) frames taken every $STEP source frames spans $SPAN of the 16 training frames; two windows per clip need at most 15" >&2
  exit 2
fi
WSTRIDE=$((16 - SPAN))
if [ "$SPAN" = 8 ]; then HELDOUT=motion-heldout; else HELDOUT=motion-heldout-${SPAN}f; fi
# The motion benchmark's data at SIZE, with its seeds (scripts/motion_data.sh). Every
# preset's held-out clips are made, for the cross-type scores; training clips of the other
# presets only for WINDOWS=all.
ALL_PRESETS="motion-constant motion-accelerating motion-turning motion-crossing motion-stop-and-go"
case " $WINDOWS " in *" all "*) TRAIN_PRESETS=$ALL_PRESETS ;; *) TRAIN_PRESETS=$PRESET ;; esac
BIN="$BIN" DATA="$DATA" SIZE="$SIZE" PRESETS="$ALL_PRESETS" TRAIN_PRESETS="$TRAIN_PRESETS" \
  HELDOUT="$HELDOUT" HELDOUT_FRAMES="$SPAN" "$ROOT/scripts/motion_data.sh"
h=${SIZE%x*} w=${SIZE#*x}
for n in $WINDOWS; do
  case "$n" in
    all) ;;
    ''|*[!0-9]*|0) echo "WINDOWS holds whole numbers >= 1 or 'all', not '$n'" >&2; exit 2 ;;
  esac
  run="$RUNS/w$n"
  if [ "$n" = all ]; then
    # Every motion type's training clips (the benchmark's training folder), two windows each.
    stride=$WSTRIDE
    [ -e "$run/data" ] || { mkdir -p "$run"; ln -s "$DATA/motion-train" "$run/data"; }
  else
    if [ "$n" = 1 ]; then clips=1 stride=16; else clips=$(((n + 1) / 2)) stride=$WSTRIDE; fi
    if [ ! -d "$run/data" ]; then
      rm -rf "$run/data.tmp"
      mkdir -p "$run/data.tmp"
      for i in $(seq 0 $((clips - 1))); do
        ln -s "$DATA/motion-train-$PRESET/$(printf clip_%06d "$i")" "$run/data.tmp/"
      done
      mv "$run/data.tmp" "$run/data"
    fi
  fi
  sed -e "s#^root = .*#root = \"$run/data\"#" \
      -e "s#^out_dir = .*#out_dir = \"$run\"#" \
      -e "s#^image_size = .*#image_size = [$h, $w]#" \
      -e "s#^context_frames = .*#context_frames = $CONTEXT#" \
      -e "s#^stride = .*#stride = $stride\nframe_step = $STEP#" \
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
    --data "$run/data" --stride "$stride" --frame-step "$STEP" --out "$run/eval-fit" \
    > "$run/eval-fit.txt"
  # Held out: the trained preset's clips (eval-heldout), then every other type's
  # (eval-heldout-<preset>): a model that reads motion off the frames scores on all of them.
  for p in $ALL_PRESETS; do
    ev=eval-heldout
    [ "$p" = "$PRESET" ] || ev="eval-heldout-$p"
    [ -f "$run/$ev/metrics.json" ] || "$BIN" eval --checkpoint "$run/model.safetensors" \
      --data "$DATA/$HELDOUT/$p" --frame-step "$STEP" --out "$run/$ev" > "$run/$ev.txt"
  done
done
python3 - "$RUNS" $WINDOWS <<'PY' | tee "$RUNS/table.md"
import json, os, sys
runs, windows = sys.argv[1], sys.argv[2:]
others = ["motion-accelerating", "motion-turning", "motion-crossing", "motion-stop-and-go"]
print("| windows | flow term, first / last 20 logged steps | fit: rel EPE moving | fit: static EPE (m) "
      "| fit: mask IoU | held out: rel EPE moving | held out: static EPE (m) | "
      + " | ".join(f"held out {o[len('motion-'):]}: rel EPE moving" for o in others) + " |")
print("|---" * (7 + len(others)) + "|")
motion = lambda d, ev: json.load(open(os.path.join(d, ev, "metrics.json")))["mean"]["motion"]
for n in windows:
    d = os.path.join(runs, f"w{n}")
    flows = [r["flow"] for r in map(json.loads, open(os.path.join(d, "log.jsonl")))
             if r.get("kind") == "step" and r.get("flow") is not None]
    m = lambda xs: sum(xs) / len(xs)
    cells = [n, f"{m(flows[:20]):.3f} / {m(flows[-20:]):.3f}"]
    for ev in ("eval-fit", "eval-heldout"):
        mo = motion(d, ev)
        cells += [f"{mo['rel_epe_dynamic']:.3f}", f"{mo['epe_static']:.3f}"]
        if ev == "eval-fit":
            cells.append(f"{mo['mask_iou']:.3f}")
    cells += [f"{motion(d, 'eval-heldout-' + o)['rel_epe_dynamic']:.3f}" for o in others]
    print("| " + " | ".join(map(str, cells)) + " |")
PY
