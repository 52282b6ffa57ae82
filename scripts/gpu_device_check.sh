#!/usr/bin/env bash
# The checks for a lent GPU machine, run from the repository root with a pack from
# scripts/gpu_pack.sh carried along (runs/gpu-pack/cuda-cli.tar.xz or cuda-benches.tar.xz;
# one per call, as one call cannot carry both). Writes its logs and the benchmark tables
# under OUT, flat, so a tool that returns only a few top-level files gets them all.
#
#   OUT=/some/dir scripts/gpu_device_check.sh
#   SKIP_BENCH=1 scripts/gpu_device_check.sh     # the CUDA start-up checks only
#   DEMO_BACKENDS=cuda scripts/gpu_device_check.sh
#   PACK=runs/gpu-pack/cuda-benches.tar.xz scripts/gpu_device_check.sh   # that pack only
#
# What runs follows what was carried:
# 1. the binary (cuda-cli): the demo end to end on each of DEMO_BACKENDS (cuda, then wgpu
#    where a Vulkan driver is present), which reports its own quality and timings;
#    then the example scene rendered on cuda and on the CPU and compared, and the
#    rasterizer's GPU tests run on cuda (TESTS_S seconds; SKIP_SPLAT=1 skips both;
#    SANITIZE=1 adds compute-sanitizer's four tools on the cuda render);
# 2. the benches (cuda-benches): CUDA=1 scripts/gpu_bench.sh (wgpu and cuda rows).
# Vulkan loaders: where `ldconfig -p` lists no libvulkan and a .gl folder of loader .debs was
# carried, they are unpacked first (the device tool's notes say how to fetch them).
# Each phase runs under a timeout (DEMO_S, BENCH_S seconds) so one that hangs, say a kernel
# the driver will not load, leaves the lease to the next and its log still comes back.
set -uo pipefail
cd "$(dirname "$0")/.."
# The binary's library messages (Burn, CubeCL, wgpu) go to the log too.
export RUST_LOG=${RUST_LOG:-warn}
OUT=${OUT:-runs/device}
DEMO_S=${DEMO_S:-120}
TESTS_S=${TESTS_S:-90}
BENCH_S=${BENCH_S:-420}
DEMO_BACKENDS=${DEMO_BACKENDS:-cuda wgpu}
PACK=${PACK:-runs/gpu-pack}
mkdir -p "$OUT"
bins=$(mktemp -d)
log="$OUT/device-check.log"
: > "$log"
say() { echo "== $*" | tee -a "$log"; }

# PACK: a pack, or a folder whose packs are all unpacked (a warm machine keeps ignored files
# from an earlier call, so name the pack itself where that matters).
if [ -f "$PACK" ]; then packs=("$PACK"); else packs=("$PACK"/cuda-*.tar.xz); fi
if [ ! -f "${packs[0]}" ]; then
  say "no pack under $PACK: run scripts/gpu_pack.sh here and carry one"
  exit 2
fi
for pack in "${packs[@]}"; do
  if command -v xz > /dev/null; then
    xz -dc "$pack" | tar xf - -C "$bins"
  else
    python3 -c 'import lzma, sys, tarfile; tarfile.open(fileobj=lzma.open(sys.argv[1])).extractall(sys.argv[2])' \
      "$pack" "$bins"
  fi
done
say "unpacked: $(ls "$bins" | tr '\n' ' ')"
# libdevice for CubeCL's LLVM route (scripts/gpu_pack.sh): the machine's toolkit if it has one.
if [ ! -f "${CUDA_PATH:-/usr/local/cuda}/nvvm/libdevice/libdevice.10.bc" ]; then
  export CUDA_PATH="$bins/cuda"
  say "CUDA_PATH=$CUDA_PATH (the packed libdevice)"
fi
# (grep reads a process substitution: under pipefail, `ldconfig -p | grep -q` can fail with
# SIGPIPE when grep stops reading early, and would unpack the loaders needlessly.)
if ! grep -q libvulkan < <(ldconfig -p) && [ -d .gl ]; then
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
  for backend in $DEMO_BACKENDS; do
    say "demo --backend $backend"
    start=$(date +%s)
    timeout "$DEMO_S" "$bins/envision4d" demo --backend "$backend" --seed 7 \
      --out "$bins/demo-$backend" >> "$log" 2>&1
    say "demo --backend $backend: exit $?, $(($(date +%s) - start)) s"
    # Its quality and timing tables come back (flat); the images stay behind.
    for f in metrics.json metrics.md; do
      [ -f "$bins/demo-$backend/$f" ] && cp "$bins/demo-$backend/$f" "$OUT/demo-$backend-$f"
    done
  done
fi

# The rasterizer on the GPU against the CPU path, on the example scene (518x350): the
# renders' 8-bit difference goes to the log. With SANITIZE=1 the CUDA render then runs under
# each of compute-sanitizer's tools (out-of-bounds and uninitialised reads, shared-memory
# races, barrier misuse), where the machine has it; each takes SANITIZE_S at most.
if [ -x "$bins/envision4d" ] && [ -z "${SKIP_SPLAT:-}" ]; then
  scene=(splat --ply examples/scene.ply --camera examples/camera.json)
  for backend in cpu cuda; do
    timeout "$DEMO_S" "$bins/envision4d" "${scene[@]}" --out "$bins/splat-$backend.png" \
      --backend "$backend" >> "$log" 2>&1
    say "splat --backend $backend: exit $?"
  done
  # (Through tee, so the comparison also shows in the call's output.)
  python3 - "$bins/splat-cpu.png" "$bins/splat-cuda.png" 2>&1 <<'PY' | tee -a "$log"
import os, sys
if not all(os.path.exists(p) for p in sys.argv[1:]):
    sys.exit("splat parity: a render is missing, not compared")
try:
    from PIL import Image
except ImportError:
    sys.exit("splat parity: no PIL on this machine, not compared")
a, b = (Image.open(p).convert("RGB") for p in sys.argv[1:])
if a.size != b.size:
    sys.exit(f"splat parity: sizes differ, {a.size} vs {b.size}")
d = [abs(x - y) for x, y in zip(a.tobytes(), b.tobytes())]
print(f"== splat parity, cuda vs cpu, {a.size[0]}x{a.size[1]}: max {max(d)}/255, "
      f"mean {sum(d) / len(d):.4f}/255, {sum(x > 1 for x in d)} of {len(d)} values off by more than 1")
PY
  # The rasterizer's GPU tests on CUDA: renders, counts, radii and all seven gradients
  # against the CPU oracle for every kernel variant (shared batches with plane sums and with
  # per-pixel adds, the per-pixel kernels, kept and recomputed tile lists, CAS atomics), the
  # readback counts, and the device sort. Two tests assume lavapipe and are skipped: which
  # kernels `Auto` picks there, and wgpu's binding limit.
  if [ -x "$bins/raster-tests" ]; then
    say "raster tests on cuda"
    ENVISION4D_TEST_GPU=cuda timeout "$TESTS_S" "$bins/raster-tests" wgpu device_sort \
      --skip wgpu_tile_schedule_picks_the_compositing_kernels \
      --skip wgpu_oversized_buffer_fails_loudly 2>&1 | tee -a "$log" | grep -E '^test result|FAILED|panicked'
    say "raster tests on cuda: exit ${PIPESTATUS[0]}"
  fi
  if [ -n "${SANITIZE:-}" ] && command -v compute-sanitizer > /dev/null; then
    for tool in memcheck initcheck racecheck synccheck; do
      timeout "${SANITIZE_S:-120}" compute-sanitizer --tool "$tool" --error-exitcode 3 \
        "$bins/envision4d" "${scene[@]}" --out "$bins/splat-sanitized.png" --backend cuda \
        >> "$log" 2>&1
      say "compute-sanitizer --tool $tool: exit $? (3: it found errors, listed above)"
    done
  fi
fi

if [ -z "${SKIP_BENCH:-}" ] && [ -x "$bins/raster" ]; then
  say "gpu_bench.sh"
  CUDA=1 OUT="$OUT" RASTER_BIN="$bins/raster" FORWARD_BIN="$bins/forward" \
    STEP_BIN="$bins/train_step" timeout "$BENCH_S" scripts/gpu_bench.sh >> "$log" 2>&1
  say "gpu_bench.sh: exit $?"
fi
rm -rf "$bins"
