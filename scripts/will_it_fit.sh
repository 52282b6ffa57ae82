#!/usr/bin/env bash
# The "Will it fit?" table of docs/TRAINING.md: the memory model's estimate
# (crates/train/src/memory.rs) of a paper-size training step (configs/waymo.toml: VGGT-1B
# widths, the paper's freeze list, LPIPS, the frozen teacher) at several batches, frame
# counts and image sizes, with and without run.recompute_frozen_blocks, read from
# `envision4d train --dry-run` (about 30 s and 5.5 GB each: the dry run builds the model).
#
#   scripts/will_it_fit.sh [ENVISION4D_BINARY]     (default: the release build)
#
# The device column includes the tile lists the GPU rasterizer keeps for its backward (the
# default; `run.recompute_raster_bins` drops them), the host column has none.
# A GPU "fits" when the estimated device memory is at most 90% of its memory: the rest is
# left to the CUDA/Vulkan context and the allocator's slack, which no GPU measured yet.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}/release/envision4d}

row() {
    local label=$1
    shift
    local out
    out=$("$BIN" train --config configs/waymo.toml --dry-run "$@" 2>&1) || {
        printf 'dry run failed (%s):\n%s\n' "$*" "$out" >&2
        exit 1
    }
    local device host
    device=$(grep -o 'on a GPU: about [0-9.]*' <<< "$out" | grep -o '[0-9.]*$' || true)
    host=$(grep -o 'later steps [0-9.]*' <<< "$out" | grep -o '[0-9.]*$' || true)
    if [ -z "$device" ] || [ -z "$host" ]; then
        printf 'no memory estimate in the dry run (%s):\n%s\n' "$*" "$out" >&2
        exit 1
    fi
    local cells=""
    for gb in 24 40 80; do
        # GB of a GPU's box as GiB (24 GB cards hold 24 GiB; A100/H100 40/80 GB likewise).
        if awk -v d="$device" -v g="$gb" 'BEGIN { exit !(d <= 0.9 * g) }'; then
            cells="$cells | yes"
        else
            cells="$cells | no"
        fi
    done
    echo "| $label | $device | $host$cells |"
}

echo "| batch per device, frames (T_c + T_f), image, frozen blocks | device GiB | CPU host GiB | 24 GB | 40 GB | 80 GB |"
echo "|---|---|---|---|---|---|"
for recompute in false true; do
    what=$([ "$recompute" = true ] && echo "recomputed" || echo "kept")
    sets=(--set "run.recompute_frozen_blocks=$recompute")
    row "1, 2 + 2, 350x518, $what" "${sets[@]}" --set optim.batch_size=1
    row "2, 2 + 2, 350x518, $what (the paper's batch)" "${sets[@]}" --set optim.batch_size=2
    row "1, 2 + 4, 350x518, $what" "${sets[@]}" --set optim.batch_size=1 --set model.future_frames=4
    row "4, 2 + 2, 350x518, $what" "${sets[@]}" --set optim.batch_size=4
    row "1, 2 + 2, 518x784, $what" "${sets[@]}" --set optim.batch_size=1 \
        --set "model.image_size=[518,784]"
done
