#!/usr/bin/env bash
# Does the rendering loss point the motion head toward the true motion? (docs/RESULTS.md,
# "Motion diagnostics"). For each motion type's held-out clips of the motion benchmark
# (scripts/motion_bench.sh BASE=shipped makes them), the gradient of the future frames' MSE
# with respect to every Gaussian's displacement against the way to the exact displacement
# (crates/train/examples/motion_gradient.rs), under four conditions:
#   start      zero displacement, the model's cameras, the real frames (where training starts)
#   true-cams  the same through the true cameras (the cameras' error taken out)
#   control    the same, with the targets replaced by the model's own render with the exact
#              displacements (the optimum is the truth by construction)
#   control-0.9  the control with the displacements already at 0.9 x the truth
#
#   scripts/motion_gradient.sh                 # writes docs/results/motion-gradient.md
#   CHECKPOINT=runs/x/model.safetensors OUT=/tmp/g.md scripts/motion_gradient.sh
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
EX=${MOTION_GRADIENT:-$TARGET/release/examples/motion_gradient}
CHECKPOINT=${CHECKPOINT:-$ROOT/models/envision4d-synth-tiny.safetensors}
DATA=${DATA:-$ROOT/data/motion-56x84/motion-heldout}
PRESETS=${PRESETS:-"motion-constant motion-accelerating motion-turning motion-crossing motion-stop-and-go"}
OUT=${OUT:-$ROOT/docs/results/motion-gradient.md}
if [ ! -x "$EX" ]; then
  (cd "$ROOT" && cargo build --release --workspace --examples)
fi
for p in $PRESETS; do
  if [ ! -d "$DATA/$p" ]; then
    echo "no held-out clips at $DATA/$p: run BASE=shipped scripts/motion_bench.sh first (its data stage)" >&2
    exit 2
  fi
done
tmp=$(mktemp)
{
  echo "# Rendering-loss gradient against the way to the exact motion"
  echo
  echo "\`scripts/motion_gradient.sh\`, checkpoint \`$(basename "$CHECKPOINT")\`, held-out clips of the motion benchmark."
  echo "Cosines are aggregate (Σ(−g)·e / sqrt(Σ|g|²Σ|e|²)) over the moving pixels of each target"
  echo "timestamp; image plane = the parts across the target camera's ray."
  for p in $PRESETS; do
    for cond in start true-cams control control-0.9; do
      case $cond in
        start) args=(--zero-motion) ;;
        true-cams) args=(--zero-motion --true-cameras) ;;
        control) args=(--zero-motion --true-cameras --self-target) ;;
        control-0.9) args=(--toward 0.9 --true-cameras --self-target) ;;
      esac
      echo
      echo "## $p, $cond"
      echo
      "$EX" "$CHECKPOINT" "$DATA/$p" "${args[@]}"
    done
  done
} > "$tmp"
mkdir -p "$(dirname "$OUT")"
mv "$tmp" "$OUT"
echo "wrote $OUT"
