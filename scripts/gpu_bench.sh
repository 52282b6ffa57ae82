#!/usr/bin/env bash
# The GPU benchmark (docs/PERFORMANCE.md): the rasterizer's forward and forward+backward at
# 350x518 for 362k, 1M and 3M Gaussians, and the device sort and scan, on every GPU backend
# built in; JSON and a Markdown table under OUT (runs/gpu-bench by default).
#
#   scripts/gpu_bench.sh                          # wgpu (and cuda with CUDA=1)
#   CUDA=1 scripts/gpu_bench.sh                   # also --backend cuda (--features cuda build)
#   SIZES=10000,100000 scripts/gpu_bench.sh       # smaller scenes (lavapipe: a CPU)
#   RASTER_BIN=path FORWARD_BIN=path STEP_BIN=path scripts/gpu_bench.sh   # prebuilt benches
#   MODEL_PRESET=tiny MODEL_IMAGE=56x84 scripts/gpu_bench.sh  # a small model (lavapipe)
#   MODEL_MODES=forward scripts/gpu_bench.sh      # no training step
#   PRECISIONS=f32 scripts/gpu_bench.sh           # the forward in f32 only (default f32 f16 bf16)
#   SKIP_MODEL=1 scripts/gpu_bench.sh             # the rasterizer only
#   BACKENDS=cuda CUDA=1 scripts/gpu_bench.sh     # one backend only
#   COMPARE_AT=100000 scripts/gpu_bench.sh        # schedules, bins and gradient adds compared here
#                                                 # (default 362600; empty: not compared)
#
# Each backend runs whole (rasterizer, then model) before the next, CUDA first, and the
# table is rewritten after every section: a run stopped by a timeout keeps what it measured.
# The model part runs on each GPU backend: crates/model/benches/forward.rs for the paper-size
# forward (VGGT-1B widths, 2 context frames at 350x518, random weights; the aggregator in
# each of PRECISIONS), and
# crates/train/benches/train_step.rs for one real training step of configs/waymo.toml
# (batch 1 x 4 frames at 350x518, the paper's freeze list and losses, init = "random").
# Memory: the host's peak RSS, and the device pool's reserved bytes after the pass.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/gpu-bench}
SIZES=${SIZES:-362600,1000000,3000000}
DEFAULT_BACKENDS=wgpu
FEATURES=()
MODEL_FEATURES=()
STEP_FEATURES=()
if [ -n "${CUDA:-}" ]; then
  # CUDA first: on a short lease its rows are the ones that matter most.
  DEFAULT_BACKENDS=cuda,wgpu
  FEATURES=(--features envision4d-splat/cuda)
  MODEL_FEATURES=(--features envision4d-model/cuda)
  STEP_FEATURES=(--features envision4d-train/cuda)
fi
MODEL_PRESET=${MODEL_PRESET:-paper}
MODEL_IMAGE=${MODEL_IMAGE:-350x518}
MODEL_MODES=${MODEL_MODES:-forward train}
# The aggregator's float formats the forward runs in (`--precision`; a device without one
# gets a NaN row: wgpu has no bf16).
PRECISIONS=${PRECISIONS:-f32 f16 bf16}
BACKENDS=${BACKENDS:-$DEFAULT_BACKENDS}
# One scene rendered with both tile schedules of the compositing kernels (`TileSchedule`),
# each with the backward reusing the forward's tile lists and binning again
# (`BackwardBins`), and the shared batches' backward adding every pixel's gradient or plane
# sums (`GradCombine`): the evidence for what `auto` picks on each device, and what keeping
# the lists and summing per plane save there.
COMPARE_AT=${COMPARE_AT-362600}
mkdir -p "$OUT"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
# A bench binary: the given path, or built here (its path ends cargo's "Executable" line).
bench_bin() {
  local given=$1 name=$2
  shift 2
  if [ -n "$given" ]; then
    echo "$given"
    return
  fi
  local bin
  bin=$(cargo bench --workspace --bench "$name" --no-run "$@" 2>&1 \
    | sed -n 's/.*Executable .*(\(.*\))$/\1/p' | tail -1)
  [ -x "$bin" ] || { echo "gpu_bench: could not build the $name bench" >&2; exit 1; }
  echo "$bin"
}
BIN=$(bench_bin "${RASTER_BIN:-}" raster "${FEATURES[@]}")
FWD=""
STEP=""
# A model bench that does not build costs its own rows ("failed"), not the rasterizer's.
if [ -z "${SKIP_MODEL:-}" ]; then
  FWD=$(bench_bin "${FORWARD_BIN:-}" forward "${MODEL_FEATURES[@]}") || FWD=false
  case " $MODEL_MODES " in
    *" train "*) STEP=$(bench_bin "${STEP_BIN:-}" train_step "${STEP_FEATURES[@]}") || STEP=false ;;
  esac
fi
: > "$OUT/raster.md.tmp"
: > "$OUT/model.md.tmp"
if [ -z "${SKIP_MODEL:-}" ]; then
  {
    echo
    echo "| backend | model | mode | seconds | host peak RSS GiB | device reserved GiB |"
    echo "|---|---|---|---|---|---|"
  } >> "$OUT/model.md.tmp"
fi
# The table's header, once: which GPU (the adapter names the drivers report) and how.
{
  echo "# GPU benchmark, $(date -u +%F)"
  echo
  if command -v nvidia-smi >/dev/null 2>&1; then
    echo "GPU: $(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | head -1)"
  fi
  if command -v vulkaninfo >/dev/null 2>&1; then
    echo "Vulkan: $(vulkaninfo --summary 2>/dev/null | sed -n 's/.*deviceName *= *//p' | head -1)"
  fi
  echo "Command: scripts/gpu_bench.sh (SIZES=$SIZES, backends $BACKENDS; model $MODEL_PRESET at $MODEL_IMAGE, modes: ${SKIP_MODEL:+none}${SKIP_MODEL:-$MODEL_MODES})"
  echo
} > "$OUT/header.md.tmp"
# The table as measured so far.
write_table() {
  cat "$OUT/header.md.tmp" "$OUT/raster.md.tmp" "$OUT/model.md.tmp" > "$OUT/gpu-bench.md.part"
  mv "$OUT/gpu-bench.md.part" "$OUT/gpu-bench.md"
}
# One table row from a bench's `*_s=... peak_rss_gib=... device_reserved_gib=...` line
# (NaN where the device lacks a precision; "failed" where the bench printed none).
row() {
  local secs rss dev
  secs=$(echo "$3" | sed -n 's/.*_s=\([0-9.NaN]*\).*/\1/p')
  rss=$(echo "$3" | sed -n 's/.*peak_rss_gib=\([0-9.NaN]*\).*/\1/p')
  dev=$(echo "$3" | sed -n 's/.*device_reserved_gib=\([0-9.a-zA-Z]*\).*/\1/p')
  echo "| $1 | $MODEL_PRESET, $MODEL_IMAGE | $2 | ${secs:-failed} | $rss | $dev |" >> "$OUT/model.md.tmp"
  write_table
}
# One process per bench and backend, so a backend that cannot start (no Vulkan driver, no
# CUDA driver) costs its own rows only; its exit status lands in the table.
for b in ${BACKENDS//,/ }; do
  echo "== raster and sort on $b, sizes $SIZES ($(date -u +%FT%TZ))"
  echo -e "\n### $b\n" >> "$OUT/raster.md.tmp"
  # --kernels: every size also gets the device time of each kernel of one forward+backward
  # (whether the sorts, the binning or the compositing dominate here), in the same process.
  "$BIN" --backends "$b" --sizes "$SIZES" --kernels --json "$OUT/raster-$b.json" \
    | tee -a "$OUT/raster.md.tmp" \
    || echo "raster bench on $b failed (exit ${PIPESTATUS[0]}; its messages are in the run's log)" | tee -a "$OUT/raster.md.tmp"
  write_table
  if [ -n "$COMPARE_AT" ]; then
    echo "== tile schedules, backward bins and gradient adds on $b at $COMPARE_AT Gaussians"
    echo -e "\nTile schedules, backward bins and gradient adds compared:\n" >> "$OUT/raster.md.tmp"
    "$BIN" --backends "$b" --sizes "$COMPARE_AT" --schedules shared,per-pixel \
      --backward-bins keep,recompute --grad-adds per-pixel,plane --no-sort \
      --json "$OUT/schedules-$b.json" | tee -a "$OUT/raster.md.tmp" \
      || echo "schedule comparison on $b failed (exit ${PIPESTATUS[0]})" | tee -a "$OUT/raster.md.tmp"
    write_table
  fi
  [ -z "${SKIP_MODEL:-}" ] || continue
  for mode in $MODEL_MODES; do
    echo "== model $MODEL_PRESET at $MODEL_IMAGE, $mode, $b"
    if [ "$mode" = train ]; then
      # --launches: the most launched kernels go to the log; their total to the row.
      line=$("$STEP" --config configs/waymo.toml --preset "$MODEL_PRESET" --image "$MODEL_IMAGE" \
        --batch 1 --device "$b" --repeats 1 --launches | tee -a /dev/stderr |
        grep -E '^train_step_s=' | tail -1) || line=""
      launches=$(echo "$line" | sed -n 's/.*kernel_launches=\([0-9]*\).*/\1/p')
      row "$b" "$mode${launches:+, $launches kernel launches}" "$line"
    else
      for p in $PRECISIONS; do
        echo "== model $MODEL_PRESET at $MODEL_IMAGE, forward, aggregator in $p, $b"
        line=$("$FWD" --preset "$MODEL_PRESET" --image "$MODEL_IMAGE" --device "$b" \
          --mode "$mode" --precision "$p" --repeats 1 --launches | tee -a /dev/stderr |
          grep -E '^forward_warm_s=' | tail -1) || line=""
        launches=$(echo "$line" | sed -n 's/.*kernel_launches=\([0-9]*\).*/\1/p')
        row "$b" "$mode ($p)${launches:+, $launches kernel launches}" "$line"
      done
    fi
  done
done
write_table
rm "$OUT/header.md.tmp" "$OUT/raster.md.tmp" "$OUT/model.md.tmp"
echo "wrote $OUT/gpu-bench.md and $OUT/raster-{${BACKENDS}}.json"
