#!/usr/bin/env bash
# The GPU benchmark (docs/PERFORMANCE.md): the rasterizer's forward and forward+backward at
# 350x518 for 362k, 1M and 3M Gaussians, and the device sort and scan, on every GPU backend
# built in; JSON and a Markdown table under OUT (runs/gpu-bench by default).
#
#   scripts/gpu_bench.sh                          # wgpu (and cuda with CUDA=1)
#   CUDA=1 scripts/gpu_bench.sh                   # also --backend cuda (--features cuda build)
#   SIZES=10000,100000 scripts/gpu_bench.sh       # smaller scenes (lavapipe: a CPU)
#   RASTER_BIN=path scripts/gpu_bench.sh          # a prebuilt raster bench (built elsewhere)
#
# Not in it yet: the paper-size model forward, a paper-size training step and peak GPU
# memory (the model's benchmark, crates/model/benches/forward.rs, runs on the CPU only).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/gpu-bench}
SIZES=${SIZES:-362600,1000000,3000000}
BACKENDS=wgpu
FEATURES=()
if [ -n "${CUDA:-}" ]; then
  BACKENDS=wgpu,cuda
  FEATURES=(--features envision4d-splat/cuda)
fi
mkdir -p "$OUT"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
BIN=${RASTER_BIN:-}
if [ -z "$BIN" ]; then
  # The bench binary's path is the last word of cargo's "Executable" line.
  BIN=$(cargo bench --workspace --bench raster --no-run "${FEATURES[@]}" 2>&1 \
    | sed -n 's/.*Executable .*(\(.*\))$/\1/p' | tail -1)
  [ -x "$BIN" ] || { echo "gpu_bench: could not build the raster bench" >&2; exit 1; }
fi
echo "== raster and sort on $BACKENDS, sizes $SIZES ($(date -u +%FT%TZ))"
"$BIN" --backends "$BACKENDS" --sizes "$SIZES" --json "$OUT/raster.json" | tee "$OUT/raster.md.tmp"
# Which GPU: the adapter names the drivers report, where the tools exist.
{
  echo "# GPU benchmark, $(date -u +%F)"
  echo
  if command -v nvidia-smi >/dev/null 2>&1; then
    echo "GPU: $(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | head -1)"
  fi
  if command -v vulkaninfo >/dev/null 2>&1; then
    echo "Vulkan: $(vulkaninfo --summary 2>/dev/null | sed -n 's/.*deviceName *= *//p' | head -1)"
  fi
  echo "Command: scripts/gpu_bench.sh (SIZES=$SIZES, backends $BACKENDS)"
  echo
  cat "$OUT/raster.md.tmp"
} > "$OUT/gpu-bench.md"
rm "$OUT/raster.md.tmp"
echo "wrote $OUT/gpu-bench.md and $OUT/raster.json"
