#!/usr/bin/env bash
# Builds the CUDA-enabled benches (and optionally the binary) here and packs them for a GPU
# machine that should not spend its short lease compiling: stripped, solid-compressed tars
# (the benches share LLVM, burn and our kernels, so one 512 MiB xz window stores them once)
# under runs/gpu-pack. docs/PERFORMANCE.md, "Building for CUDA".
#
#   scripts/gpu_pack.sh                 # cuda-benches.tar.xz: raster, forward and train_step
#   WITH_CLI=1 scripts/gpu_pack.sh      # and cuda-cli.tar.xz: the envision4d binary and
#                                       # the rasterizer's tests (run on CUDA there)
#   NVRTC=1 scripts/gpu_pack.sh         # the `cuda-nvrtc` builds: kernels through NVRTC
#                                       # rather than LLVM (the machine then needs libnvrtc)
#
# Two packs, because all four binaries with the working tree are over what one device call
# carries (64 MiB); each pack alone fits, and each is checked against it here. On the GPU
# machine, from the repository root, one call per pack carried (the binary's first: short):
#   scripts/gpu_device_check.sh         # unpacks what was carried, runs its checks
#
# Builds in their own target directory (CUDA_TARGET_DIR), so the everyday one keeps its
# feature set and stays warm. Linking needs LLVM 23.1: tracel's bundle, or
# scripts/llvm_offline.sh where GitHub is out of reach (run here when neither is present).
set -euo pipefail
cd "$(dirname "$0")/.."
PACK=${PACK:-runs/gpu-pack}
export CARGO_TARGET_DIR=${CUDA_TARGET_DIR:-$HOME/.cache/envision4d-cuda-target}
BUNDLE=${XDG_DATA_HOME:-$HOME/.local/share}/tracel/tracel-llvm-23.1.0-4
# The carry limit of the device tool: the working tree and the pack travel together.
CARRY_LIMIT=$((64 * 1024 * 1024))

if [ ! -e "$BUNDLE/.tracel-llvm-installed" ]; then
  scripts/llvm_offline.sh
fi

stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
cuda=cuda${NVRTC:+-nvrtc}
# One feature set for every build below: cargo compiles a crate again for each set it sees,
# and cubecl-cuda with LLVM behind it is the slowest of them.
features=envision4d-splat/$cuda,envision4d-model/$cuda,envision4d-train/$cuda,envision4d-cli/$cuda
cargo bench --workspace --no-run --bench raster --bench forward --bench train_step \
  --features "$features" 2>&1 | tee "$stage/build.log" | grep -E '^(error|warning: unused)' || true
for name in raster forward train_step; do
  # benches/NAME.rs, or benches/NAME/main.rs for a bench with modules (the raster one).
  bin=$(sed -n "s/.*Executable benches\/$name\(\.rs\|\/main\.rs\) (\(.*\))$/\2/p" "$stage/build.log" | tail -1)
  [ -x "$bin" ] || { echo "gpu_pack: the $name bench did not build (log: cargo above)" >&2; exit 1; }
  mkdir -p "$stage/benches"
  cp "$bin" "$stage/benches/$name"
done
packs=(benches)
if [ -n "${WITH_CLI:-}" ]; then
  cargo build --release --workspace --features "$features" --bin envision4d
  mkdir -p "$stage/cli"
  cp "$CARGO_TARGET_DIR/release/envision4d" "$stage/cli/envision4d"
  # The rasterizer's GPU tests (parity of renders and all seven gradients with the CPU
  # oracle, every kernel variant; the device sort), run on CUDA by the device check with
  # ENVISION4D_TEST_GPU=cuda. They share burn and LLVM with the binary, so xz packs them
  # small.
  cargo test --release --workspace --features "$features" --test raster --no-run 2>&1 \
    | tee "$stage/test.log" | grep -E '^error' || true
  tests=$(sed -n 's/.*Executable tests\/raster\/main\.rs (\(.*\))$/\1/p' "$stage/test.log" | tail -1)
  [ -x "$tests" ] || { echo "gpu_pack: the raster tests did not build (log: cargo above)" >&2; exit 1; }
  cp "$tests" "$stage/cli/raster-tests"
  rm "$stage/test.log"
  packs+=(cli)
fi
rm "$stage/build.log"
strip "$stage"/*/*

# CubeCL's LLVM route links NVIDIA's libdevice (nvvm/libdevice/libdevice.10.bc, found under
# CUDA_PATH) into any kernel that calls a math function PTX has no instruction for: our
# projection and rasterizer kernels do. A machine with the driver alone lacks it, so the pack
# carries one: the toolkit's under CUDA_PATH, or the copy in NVIDIA's PyPI wheel of nvcc.
# The same wheel has NVIDIA's PTX assembler, which the check below runs.
libdevice=${CUDA_PATH:-/usr/local/cuda}/nvvm/libdevice/libdevice.10.bc
ptxas=${CUDA_PATH:-/usr/local/cuda}/bin/ptxas
[ -x "$ptxas" ] || ptxas=$(command -v ptxas || true)
if [ ! -f "$libdevice" ] || [ -z "$ptxas" ]; then
  pip download --no-deps --quiet nvidia-cuda-nvcc-cu12 -d "$stage/wheel"
  python3 -c 'import sys, zipfile, glob
z = zipfile.ZipFile(glob.glob(sys.argv[1] + "/*.whl")[0])
for name in ("nvvm/libdevice/libdevice.10.bc", "bin/ptxas"):
    z.extract("nvidia/cuda_nvcc/" + name, sys.argv[1])' "$stage/wheel"
  [ -f "$libdevice" ] || libdevice=$stage/wheel/nvidia/cuda_nvcc/nvvm/libdevice/libdevice.10.bc
  if [ -z "$ptxas" ]; then
    ptxas=$stage/wheel/nvidia/cuda_nvcc/bin/ptxas
    chmod +x "$ptxas"
  fi
fi
mkdir -p "$stage/cuda/nvvm/libdevice"
cp "$libdevice" "$stage/cuda/nvvm/libdevice/"

# Every CubeCL kernel (rasterizer, fused LayerNorm and Adam, finite check) through that route for
# Hopper, here, before a lease is spent on it; then NVIDIA's assembler over each kernel's
# PTX, for the target it names, as the driver's JIT would take it: an instruction, a PTX
# version or a target it refuses fails here.
cargo build --release --workspace --features "$features" --example ptx_check
CUDA_PATH=$stage/cuda "$CARGO_TARGET_DIR/release/examples/ptx_check" 90 "$stage/ptx"
for ptx in "$stage"/ptx/*.ptx; do
  target=$(sed -n 's/^\.target \([a-z0-9_]*\).*/\1/p' "$ptx" | head -1)
  "$ptxas" -arch="$target" "$ptx" -o /dev/null \
    || { echo "gpu_pack: ptxas refused $(basename "$ptx") (target $target)" >&2; exit 1; }
done
echo "gpu_pack: ptxas ($("$ptxas" --version | tail -1)) assembled $(ls "$stage"/ptx/*.ptx | wc -l) kernels"
# The NVRTC builds transpile to CUDA C++ at run time instead: the same kernels through NVRTC
# and ptxas here (NVIDIA's wheels, cached in runs/cuda-wheels).
if [ -n "${NVRTC:-}" ]; then
  "$CARGO_TARGET_DIR/release/examples/ptx_check" 90 "$stage/cpp" --cpp > /dev/null
  # (Its log whole where a kernel fails: NVRTC's messages name the line.)
  scripts/nvrtc_check.py "$stage/cpp" > "$stage/nvrtc.log" \
    || { cat "$stage/nvrtc.log" >&2; exit 1; }
  tail -1 "$stage/nvrtc.log"
  rm -rf "$stage/cpp" "$stage/nvrtc.log"
fi
rm -rf "$stage/wheel" "$stage/ptx"
mkdir -p "$PACK"
# What travels with a pack: tracked and untracked-not-ignored files (deleted ones skipped),
# and the Vulkan loaders in .gl when present (the wgpu demo and rows need them).
tree=$(git ls-files -z -co --exclude-standard | xargs -0 stat -c %s 2>/dev/null \
  | awk '{ s += $1 } END { print s }')
gl=$(du -cb .gl 2>/dev/null | tail -1 | cut -f1)
# Both packs at once (one core each); xz rather than zstd: every Linux has it (and Python's
# lzma reads it where it does not).
pids=()
for p in "${packs[@]}"; do
  # Each pack holds the one staged libdevice beside its binaries.
  tar cf - -C "$stage" cuda -C "$stage/$p" . | xz -T1 --lzma2=preset=9,dict=512MiB \
    > "$PACK/cuda-$p.tar.xz.tmp" &
  pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done
status=0
for p in "${packs[@]}"; do
  mv "$PACK/cuda-$p.tar.xz.tmp" "$PACK/cuda-$p.tar.xz"
  packed=$(stat -c %s "$PACK/cuda-$p.tar.xz")
  extra=$((tree + ${gl:-0}))
  echo "gpu_pack: $PACK/cuda-$p.tar.xz, $((packed / 1048576)) MiB (cuda $(cd "$stage/$p" && ls | tr '\n' ' '))"
  echo "gpu_pack: with the working tree it travels as $(((packed + extra) / 1048576)) MiB of 64"
  if [ $((packed + extra)) -gt $CARRY_LIMIT ]; then
    echo "gpu_pack: cuda-$p.tar.xz is over the device tool's 64 MiB with the tree" >&2
    status=1
  fi
done
echo "gpu_pack: on the GPU machine, one call per pack, carrying it and .gl (git ignores both):"
for p in "${packs[@]}"; do
  echo "gpu_pack:   OUT=<dir> PACK=$PACK/cuda-$p.tar.xz scripts/gpu_device_check.sh"
done
exit $status
