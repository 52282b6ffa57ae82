#!/usr/bin/env bash
# Renders the figures of docs/RESULTS.md with one checkpoint and writes them to docs/results/:
# contact sheets (rows: the clip's 8 frames, our 2 context + 6 future renders, our depth) of
# held-out urban clip 3 (frames 0-7), held-out long sharp-turn clip 2 in its bend (frames
# 8-15) and the first 8 frames of two real clips, plus the metric-vs-horizon plot of the mix
# set at T_f = 6 (from runs/eval/TAG-mix-tf6, written by scripts/eval_heldout.sh).
#
# usage: scripts/results_figures.sh CHECKPOINT TAG
# Needs Pillow for scripts/contact_sheet.py (PYTHON=... to pick an interpreter that has it).
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 CHECKPOINT TAG" >&2; exit 2; }
CKPT=$1
TAG=$2
BIN=${ENVISION4D:-target/release/envision4d}
PY=${PYTHON:-python3}
OUT=runs/render-$TAG
REAL=../shared/data/real

# sheet NAME FRAMES_DIR START RENDER_DIR: rows of 8 frames / 8 views / 8 depth maps.
sheet() {
  local name=$1 frames=$2 start=$3 render=$4
  local gt views depth
  gt=$(ls "$frames"/*.png | sort | tail -n +$((start + 1)) | head -8 | paste -sd,)
  views=$(ls "$render"/views/*.png | sort | paste -sd,)
  depth=$(ls "$render"/depth/*.png | sort | paste -sd,)
  "$PY" scripts/contact_sheet.py "docs/results/$name.png" 2 "$gt" "$views" "$depth"
}
render() {
  local name=$1 frames=$2 start=$3
  "$BIN" render --checkpoint "$CKPT" --frames "$frames" --start "$start" \
    --out "$OUT/$name" --outputs views,depth,poses > /dev/null
  sheet "$4" "$frames" "$start" "$OUT/$name"
}
render urban3 data/synth-heldout/clip_000003/rgb 0 heldout-urban-clip3
render turn2 data/synth-heldout-long/sharp-turn_clip_000002/rgb 8 heldout-sharp-turn-bend
for c in street_taxi_pan street_cars_square; do
  render "$c" "$REAL/$c" 0 "real-$c"
done
cp "runs/eval/$TAG-mix-tf6/metrics_vs_horizon.png" docs/results/heldout-metrics-vs-horizon.png
echo "wrote docs/results/{heldout-urban-clip3,heldout-sharp-turn-bend,real-street_taxi_pan,real-street_cars_square,heldout-metrics-vs-horizon}.png"
