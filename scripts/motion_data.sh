#!/usr/bin/env bash
# The motion suite's clips (docs/DATA.md) with the motion benchmark's seeds, made where
# missing; shared by scripts/motion_bench.sh and scripts/motion_capacity.sh so both read the
# same worlds. Preset i of PRESETS gets training seed 100 + i and held-out seed 2100 + i.
#
#   BIN=... DATA=data/motion-56x84 SIZE=56x84 scripts/motion_data.sh
#
# Writes DATA/motion-train-<preset> (TRAIN_CLIPS clips of FRAMES frames, for the presets of
# TRAIN_PRESETS), DATA/HELDOUT/<preset> (HELDOUT_CLIPS clips of HELDOUT_FRAMES frames, every
# preset) and, when every preset was trained, DATA/motion-train: each training clip as
# <preset>_clip_XXXXXX, a link to its folder.
set -euo pipefail
: "${BIN:?BIN names the envision4d binary}" "${DATA:?DATA names the output folder}" "${SIZE:?SIZE is HxW}"
PRESETS=${PRESETS:-"motion-constant motion-accelerating motion-turning motion-crossing motion-stop-and-go"}
TRAIN_PRESETS=${TRAIN_PRESETS:-$PRESETS}
TRAIN_CLIPS=${TRAIN_CLIPS:-16}
FRAMES=${FRAMES:-16}
HELDOUT=${HELDOUT:-motion-heldout}
HELDOUT_CLIPS=${HELDOUT_CLIPS:-8}
HELDOUT_FRAMES=${HELDOUT_FRAMES:-8}
i=0
for p in $PRESETS; do
  case " $TRAIN_PRESETS " in
    *" $p "*)
      [ -d "$DATA/motion-train-$p" ] || "$BIN" synth --out "$DATA/motion-train-$p" \
        --clips "$TRAIN_CLIPS" --frames "$FRAMES" --size "$SIZE" --preset "$p" --seed $((100 + i)) ;;
  esac
  [ -d "$DATA/$HELDOUT/$p" ] || "$BIN" synth --out "$DATA/$HELDOUT/$p" \
    --clips "$HELDOUT_CLIPS" --frames "$HELDOUT_FRAMES" --size "$SIZE" --preset "$p" \
    --seed $((2100 + i))
  i=$((i + 1))
done
if [ "$TRAIN_PRESETS" = "$PRESETS" ] && [ ! -d "$DATA/motion-train" ]; then
  rm -rf "$DATA/motion-train.tmp"
  mkdir -p "$DATA/motion-train.tmp"
  for p in $PRESETS; do
    for d in "$DATA/motion-train-$p"/clip_*; do
      ln -s "$(cd "$d" && pwd)" "$DATA/motion-train.tmp/${p}_$(basename "$d")"
    done
  done
  mv "$DATA/motion-train.tmp" "$DATA/motion-train"
fi
