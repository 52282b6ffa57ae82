#!/usr/bin/env bash
# Scores one checkpoint on the three held-out synthetic sets of docs/RESULTS.md (urban, mix,
# long at T_f = 2, 4, 6) and prints the two tables RESULTS.md shows: metrics per method and
# the paired verdicts against copy-last and constant velocity.
#
# usage: scripts/eval_heldout.sh CHECKPOINT TAG
#   writes runs/eval/TAG-{urban,mix,long}-tf{2,4,6}/ and runs/eval/TAG-tables.md.
# Needs data/synth-heldout, data/synth-heldout-mix and data/synth-heldout-long (commands in
# docs/RESULTS.md). About 10 minutes on a 2-core CPU.
set -euo pipefail
[ $# -eq 2 ] || { echo "usage: $0 CHECKPOINT TAG" >&2; exit 2; }
CKPT=$1
TAG=$2
BIN=${ENVISION4D:-target/release/envision4d}
[ -f "$CKPT" ] || { echo "checkpoint not found: $CKPT" >&2; exit 2; }
for d in data/synth-heldout data/synth-heldout-mix data/synth-heldout-long; do
  [ -d "$d" ] || { echo "held-out set missing: $d (see docs/RESULTS.md)" >&2; exit 2; }
done
mkdir -p runs/eval
declare -A SETS=([urban]="--data data/synth-heldout" [mix]="--data data/synth-heldout-mix"
                 [long]="--data data/synth-heldout-long --stride 2")
tables=()
grid=()
for set in urban mix long; do
  for h in 2 4 6; do
    out="runs/eval/$TAG-$set-tf$h"
    # shellcheck disable=SC2086 # SETS values are option lists
    "$BIN" eval --checkpoint "$CKPT" ${SETS[$set]} --future "$h" --out "$out" > "$out.log" 2>&1 \
      || { echo "eval failed, see $out.log" >&2; exit 1; }
    tables+=("$set T_f=$h=$out")
    grid+=("$set, T_f = $h=$out")
  done
done
{
  python3 scripts/results_table.py "${tables[@]}"
  echo
  python3 scripts/compare_methods.py --grid "${grid[@]}" \
    "long sharp-turn windows, T_f = 6=runs/eval/$TAG-long-tf6#sharp-turn"
} | tee "runs/eval/$TAG-tables.md"
