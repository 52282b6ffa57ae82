#!/usr/bin/env bash
# The motion benchmark (docs/RESULTS.md, "Motion"): from nothing to the Motion table.
#
#   scripts/motion_bench.sh                      # the whole benchmark (hours on 2 CPU cores)
#   SEEDS="0" VARIANTS="cml linear-velocity" scripts/motion_bench.sh   # a part of it
#   SMOKE=1 scripts/motion_bench.sh              # every stage for a few steps (CI, minutes)
#   BASE=shipped scripts/motion_bench.sh         # the variants on the shipped reconstruction
#   LENGTH=5 BASE=shipped scripts/motion_bench.sh   # every schedule 5x longer (own runs dir)
#
# BASE=backbone (default) trains a stage-1 backbone on the suite at 112x168 and every variant
# from it. BASE=shipped skips stage 1: every variant starts from the shipped model
# (models/envision4d-synth-tiny.safetensors, 56x84, its size) with its motion head and
# temporal blocks back at their fresh init (`init_fresh`), so all variants learn motion from
# scratch on one trained reconstruction (docs/RESULTS.md, "Motion", says why both exist);
# its data and runs go to data/motion-56x84 and runs/motion-shipped.
#
# 1. data: the motion suite (one preset per motion type, docs/DATA.md) at the benchmark's
#    resolution; training clips (seeds 100-104) and held-out clips (seeds 2100-2104), never
#    the same worlds;
# 2. stage 1: one backbone on the training clips (configs/motion/backbone.toml);
# 3. stage 2: every variant (configs/motion/<variant>.toml) from that backbone, once per seed;
# 4. evaluation of every run on each motion type's held-out clips: future frames, the
#    dynamic/static regions, scene-flow EPE and dynamic-mask IoU against exact truth
#    (docs/EVAL.md);
# 5. the table (scripts/motion_table.py): per motion type, each variant's means and its
#    paired difference to CML per held-out clip with 95% intervals.
#
# Finished runs and evaluations are kept: rerunning the script continues where it stopped
# (an interrupted training resumes from its last checkpoint; a run whose evaluations are all
# there is not trained again). KEEP=dir also keeps every finished evaluation, slimmed to what
# the tables read (scripts/motion_keep.py), as dir/<run>/eval-<preset>/metrics.json.gz and
# reads them back from there first, so a benchmark longer than one machine's life continues
# on the next (the Motion tables of docs/RESULTS.md are rebuilt from
# docs/results/motion-shipped this way).
set -euo pipefail
BIN=${ENVISION4D:-${CARGO_TARGET_DIR:-target}/release/envision4d}
ROOT=${MOTION_ROOT:-.}
BASE=${BASE:-backbone}
SHIPPED=${SHIPPED:-$(cd "$(dirname "$0")/.." && pwd)/models/envision4d-synth-tiny.safetensors}
case "$BASE" in
  backbone) SIZE=${SIZE:-112x168} DATA="$ROOT/data" RUNS="$ROOT/runs/motion" ;;
  shipped) SIZE=${SIZE:-56x84} DATA="$ROOT/data/motion-56x84" RUNS="$ROOT/runs/motion-shipped" ;;
  *) echo "BASE must be backbone or shipped, not '$BASE'" >&2; exit 2 ;;
esac
# Schedule length: iterations, warm-up and S_max of every stage-2 config times LENGTH; a
# longer schedule gets its own runs folder (runs/motion-shipped-x5), so runs never mix.
LENGTH=${LENGTH:-1}
case "$LENGTH" in
  ''|*[!0-9]*|0) echo "LENGTH must be a whole number >= 1, not '$LENGTH'" >&2; exit 2 ;;
esac
if [ "$LENGTH" != 1 ]; then
  RUNS="$RUNS-x$LENGTH"
fi
SEEDS=${SEEDS:-"0 1 2"}
VARIANTS=${VARIANTS:-"cml motion-off linear-velocity no-temporal post-layer"}
PRESETS=${PRESETS:-"motion-constant motion-accelerating motion-turning motion-crossing motion-stop-and-go"}
TRAIN_CLIPS=${TRAIN_CLIPS:-16}
HELDOUT_CLIPS=${HELDOUT_CLIPS:-8}
FRAMES=${FRAMES:-16}
CONFIGS=$(cd "$(dirname "$0")/../configs/motion" && pwd)
if [ -n "${SMOKE:-}" ]; then
  # Every stage, a few steps each, tiny data: checks the pipeline, not the result.
  SIZE=56x84 SEEDS="0" TRAIN_CLIPS=1 HELDOUT_CLIPS=1 FRAMES=8
  STOP=(--stop-at 2)
else
  STOP=()
fi
mkdir -p "$DATA" "$RUNS"
KEEP=${KEEP:-}
if [ -n "$KEEP" ] && [ -d "$KEEP" ]; then
  # Evaluations finished elsewhere count as finished here.
  (cd "$KEEP" && find . -path '*/eval-*/metrics.json.gz') | while read -r f; do
    dst="$RUNS/${f%.gz}"
    if [ ! -f "$dst" ]; then
      mkdir -p "$(dirname "$dst")"
      gzip -dc "$KEEP/$f" > "$dst.tmp"
      mv "$dst.tmp" "$dst"
    fi
  done
fi

# A config of configs/motion with the paths of this run (and the smoke's size); on the
# shipped base, initialised from the shipped model with fresh motion.
config() {
  local name=$1 out=$2
  local h=${SIZE%x*} w=${SIZE#*x}
  local init="$RUNS/backbone/model.safetensors" fresh=""
  if [ "$BASE" = shipped ]; then
    init=$SHIPPED
    fresh='init_fresh = ["motion_head", "time_blocks"]'
  fi
  sed -e "s#^root = .*#root = \"$DATA/motion-train\"#" \
      -e "s#^init_checkpoint = .*#init_checkpoint = \"$init\"\n$fresh#" \
      -e "s#^image_size = .*#image_size = [$h, $w]#" \
      -e "s#^out_dir = .*#out_dir = \"$RUNS/$name\"#" \
      "$CONFIGS/$name.toml" > "$out"
  if [ "$LENGTH" != 1 ] && [ "$name" != backbone ]; then
    python3 - "$out" "$LENGTH" <<'PY'
import re, sys
path, k = sys.argv[1], int(sys.argv[2])
text = open(path).read()
for key in ("iterations", "warmup_iterations", "s_max"):
    text = re.sub(rf"(?m)^{key} = (\d+)", lambda m: f"{key} = {int(m.group(1)) * k}", text)
open(path, "w").write(text)
PY
  fi
}

# True when every preset's evaluation of a run is there (then its training is not needed).
evaluated() {
  local p
  for p in $PRESETS; do
    [ -f "$RUNS/$1/eval-$p/metrics.json" ] || return 1
  done
}

# Trains one config into runs/motion/<run> unless it finished; resumes a started run.
train() {
  local cfg=$1 run=$2 seed=$3
  local dir="$RUNS/$run"
  if [ -f "$dir/model.safetensors" ] && [ -z "${SMOKE:-}" ]; then
    return
  fi
  local resume=()
  if [ -d "$dir/checkpoints" ] && [ -z "${SMOKE:-}" ]; then
    resume=(--resume "$dir")
  fi
  "$BIN" train --config "$cfg" --seed "$seed" --out-dir "$dir" "${STOP[@]}" "${resume[@]}"
}

echo "== data ($SIZE, $FRAMES frames)"
# Every preset's training and held-out clips, and one training folder of every motion type.
BIN="$BIN" DATA="$DATA" SIZE="$SIZE" PRESETS="$PRESETS" TRAIN_CLIPS="$TRAIN_CLIPS" \
  FRAMES="$FRAMES" HELDOUT_CLIPS="$HELDOUT_CLIPS" "$(dirname "$0")/motion_data.sh"

if [ "$BASE" = backbone ]; then
  echo "== stage 1: backbone"
  config backbone "$RUNS/backbone.toml"
  train "$RUNS/backbone.toml" backbone 0
fi

for v in $VARIANTS; do
  config "$v" "$RUNS/$v.toml"
  for s in $SEEDS; do
    echo "== stage 2: $v, seed $s"
    if [ -n "${SMOKE:-}" ] || ! evaluated "$v-s$s"; then
      train "$RUNS/$v.toml" "$v-s$s" "$s"
    fi
    for p in $PRESETS; do
      out="$RUNS/$v-s$s/eval-$p"
      if [ ! -f "$out/metrics.json" ] || [ -n "${SMOKE:-}" ]; then
        "$BIN" eval --checkpoint "$RUNS/$v-s$s/model.safetensors" --data "$DATA/motion-heldout/$p" \
          --out "$out" > "$RUNS/$v-s$s/eval-$p.txt"
      fi
      if [ -n "$KEEP" ] && [ -z "${SMOKE:-}" ] && [ ! -f "$KEEP/$v-s$s/eval-$p/metrics.json.gz" ]; then
        mkdir -p "$KEEP/$v-s$s/eval-$p"
        python3 "$(dirname "$0")/motion_keep.py" "$out/metrics.json" \
          "$KEEP/$v-s$s/eval-$p/metrics.json.gz"
      fi
    done
  done
done

echo "== table"
# With CML trained, its displacements zeroed at test time and replaced by the exact flow are
# rows too ("cml-zeroed", "cml-oracle").
TABLE_ROWS=$VARIANTS
case " $VARIANTS " in *" cml "*) TABLE_ROWS="$VARIANTS cml-zeroed cml-oracle" ;; esac
python3 "$(dirname "$0")/motion_table.py" "$RUNS" "$TABLE_ROWS" "$SEEDS" "$PRESETS" \
  | tee "$RUNS/motion-table.md"
# Where the future-frame error goes (cameras, exact motion, the model's motion; EVAL.md's
# oracle renders), per variant and motion type, first seed.
first=${SEEDS%% *}
args=()
for v in $VARIANTS; do
  for p in $PRESETS; do args+=("$v-s$first/$p=$RUNS/$v-s$first/eval-$p"); done
done
python3 "$(dirname "$0")/motion_headroom.py" "${args[@]}" | tee "$RUNS/motion-headroom.md"
