#!/usr/bin/env bash
# The checks for a lent GPU machine, run from the repository root with runs/gpu-pack carried
# along (scripts/gpu_pack.sh builds it where compiling is cheap). Writes its logs and the
# benchmark tables under OUT, flat, so a tool that returns only a few top-level files gets
# them all.
#
#   OUT=/some/dir scripts/gpu_device_check.sh
#   SKIP_BENCH=1 scripts/gpu_device_check.sh     # the CUDA start-up checks only
#
# 1. the binary (when packed) on --backend cuda: the demo end to end, which reports its own
#    quality and timings, then the same on wgpu where a Vulkan driver is present;
# 2. CUDA=1 scripts/gpu_bench.sh with the packed benches (wgpu and cuda rows).
# Vulkan loaders: where `ldconfig -p` lists no libvulkan and a .gl folder of loader .debs was
# carried, they are unpacked first (the device tool's notes say how to fetch them).
# Each phase runs under a timeout (DEMO_S, BENCH_S seconds) so one that hangs, say a kernel
# the driver will not load, leaves the lease to the next and its log still comes back.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/device}
DEMO_S=${DEMO_S:-120}
BENCH_S=${BENCH_S:-420}
PACK=${PACK:-runs/gpu-pack}
mkdir -p "$OUT"
bins=$(mktemp -d)
log="$OUT/device-check.log"
: > "$log"
say() { echo "== $*" | tee -a "$log"; }

if command -v xz > /dev/null; then
  xz -dc "$PACK/cuda-bins.tar.xz" | tar xf - -C "$bins"
else
  python3 -c 'import lzma, sys, tarfile; tarfile.open(fileobj=lzma.open(sys.argv[1])).extractall(sys.argv[2])' \
    "$PACK/cuda-bins.tar.xz" "$bins"
fi
say "unpacked: $(ls "$bins" | tr '\n' ' ')"
# libdevice for CubeCL's LLVM route (scripts/gpu_pack.sh): the machine's toolkit if it has one.
if [ ! -f "${CUDA_PATH:-/usr/local/cuda}/nvvm/libdevice/libdevice.10.bc" ]; then
  export CUDA_PATH="$bins/cuda"
  say "CUDA_PATH=$CUDA_PATH (the packed libdevice)"
fi
if ! ldconfig -p | grep -q libvulkan && [ -d .gl ]; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  say "Vulkan loaders unpacked from .gl"
fi
# Where the NVIDIA driver's Vulkan and EGL manifests sit outside the loaders' search paths.
nv=/usr/local/nvidia/share
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -f "$nv/vulkan/icd.d/nvidia_icd.json" ]; then
  export VK_DRIVER_FILES=$nv/vulkan/icd.d/nvidia_icd.json
  say "VK_DRIVER_FILES=$VK_DRIVER_FILES"
fi
if command -v nvidia-smi > /dev/null; then
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader >> "$log" 2>&1
fi

if [ -x "$bins/envision4d" ]; then
  for backend in cuda wgpu; do
    say "demo --backend $backend"
    start=$(date +%s)
    timeout "$DEMO_S" "$bins/envision4d" demo --backend "$backend" --seed 7 \
      --out "$bins/demo-$backend" >> "$log" 2>&1
    say "demo --backend $backend: exit $?, $(($(date +%s) - start)) s"
  done
fi

if [ -z "${SKIP_BENCH:-}" ]; then
  say "gpu_bench.sh"
  CUDA=1 OUT="$OUT" RASTER_BIN="$bins/raster" FORWARD_BIN="$bins/forward" \
    STEP_BIN="$bins/train_step" timeout "$BENCH_S" scripts/gpu_bench.sh >> "$log" 2>&1
  say "gpu_bench.sh: exit $?"
fi
rm -rf "$bins"
