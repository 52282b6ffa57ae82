#!/usr/bin/env bash
# Seconds per training step of the motion benchmark's variants at its resolution
# (configs/motion/*.toml), in the progressive phase (self-exclusive renders of all 2 x 8
# frames with motion), from random weights with no labels, so no backbone is needed.
#
#   scripts/motion_step_timing.sh [BIN] [OUT] [VARIANTS] [SIZE] [STEPS] [PHASE]
#   (defaults: target/release/envision4d, runs/motion-timing, "cml linear-velocity
#    motion-off", 112x168, 14, progressive; PHASE=warmup times the static warm-up instead)
#
# Makes 16 clips of 16 frames of two suite presets at SIZE, trains each variant for STEPS
# steps (geometric warm-up 2 steps), and prints the median `seconds` of the steps after the
# warm-up from log.jsonl: the compute of a step once its batch is in hand.
set -euo pipefail
BIN=${1:-${CARGO_TARGET_DIR:-target}/release/envision4d}
OUT=${2:-runs/motion-timing}
VARIANTS=${3:-"cml linear-velocity motion-off"}
SIZE=${4:-112x168}
STEPS=${5:-14}
PHASE=${6:-progressive}
WARMUP=2
if [ "$PHASE" = warmup ]; then WARMUP=$STEPS; fi
ROOT=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
DATA="$OUT/data-$SIZE"
if [ ! -d "$DATA" ]; then
  for p in motion-turning motion-accelerating; do
    "$BIN" synth --out "$OUT/src-$SIZE-$p" --clips 8 --frames 16 --size "$SIZE" --preset "$p" \
      --seed 1 >/dev/null 2>&1
  done
  mkdir -p "$DATA.tmp"
  for p in motion-turning motion-accelerating; do
    for d in "$OUT/src-$SIZE-$p"/clip_*; do ln -s "$d" "$DATA.tmp/${p}_$(basename "$d")"; done
  done
  mv "$DATA.tmp" "$DATA"
fi
for v in $VARIANTS; do
  run="$OUT/run-$v-$SIZE"
  rm -rf "$run"
  sed -e '/^init_checkpoint = /d' \
      -e 's/^teacher = .*/teacher = "none"/' \
      -e "s/^iterations = .*/iterations = $STEPS/" \
      -e "s/^warmup_iterations = .*/warmup_iterations = $WARMUP/" \
      -e "s/^s_max = .*/s_max = $STEPS/" \
      -e "s/^image_size = .*/image_size = [${SIZE%x*}, ${SIZE#*x}]/" \
      -e "s#^root = .*#root = \"$DATA\"#" \
      -e "s#^out_dir = .*#out_dir = \"$run\"#" \
      -e 's/^log_every = .*/log_every = 1/' \
      -e "s/^checkpoint_every = .*/checkpoint_every = $STEPS/" \
      "$ROOT/configs/motion/$v.toml" > "$OUT/$v-$SIZE.toml"
  "$BIN" train --config "$OUT/$v-$SIZE.toml" >/dev/null 2>&1
  python3 - "$run/log.jsonl" "$v" "$SIZE" "$PHASE" <<'PY'
import json, statistics, sys
steps = [r for r in map(json.loads, open(sys.argv[1])) if r["kind"] == "step"]
late = [r["seconds"] for r in steps if r["step"] > 3 and r["phase"] == sys.argv[4]]
print(f"{sys.argv[2]:<16} {sys.argv[3]}: {len(late)} {sys.argv[4]} steps, median "
      f"{statistics.median(late):.3f} s/step, fastest {min(late):.3f} s")
PY
done
