#!/usr/bin/env bash
# Seconds per training step, and how much of it is waiting for data, for one binary.
#
#   scripts/train_step_timing.sh [BIN] [OUT]     (defaults: target/release/envision4d, runs/step-timing)
#
# Makes 80 synthetic clips of 8 frames at 350x518 (decoded and resized to the model's 56x84
# by the loader, as real data is), then trains the tiny stage-2 model from scratch for 30
# steps of batch 2 with no labels (teacher = "none"): 60 windows, more clips than fit the
# dataset's clip cache, so every window is decoded. Prints the median compute time of a step
# (`seconds` in log.jsonl, measured after the batch is in hand), the wall time per step
# (1 / the final `steps_per_second`), and their difference: the time a step waited for data.
set -euo pipefail
BIN=${1:-${CARGO_TARGET_DIR:-target}/release/envision4d}
OUT=${2:-runs/step-timing}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
if [ ! -d "$OUT/data" ]; then
  "$BIN" synth --out "$OUT/data" --clips 80 --frames 8 --size 350x518 --seed 11 >/dev/null
fi
rm -rf "$OUT/run"
sed -e '/^init_checkpoint = /d' \
    -e 's/^teacher = .*/teacher = "none"/' \
    -e 's/^iterations = .*/iterations = 30/' \
    -e 's/^warmup_iterations = .*/warmup_iterations = 4/' \
    -e 's/^s_max = .*/s_max = 8/' \
    -e "s#^root = .*#root = \"$OUT/data\"#" \
    -e "s#^out_dir = .*#out_dir = \"$OUT/run\"#" \
    -e 's/^log_every = .*/log_every = 1/' \
    -e 's/^checkpoint_every = .*/checkpoint_every = 30/' \
    -e 's/^val_every = .*/val_every = 0/' \
    "$ROOT/configs/synth-tiny.toml" > "$OUT/config.toml"
"$BIN" train --config "$OUT/config.toml" >/dev/null
python3 - "$OUT/run/log.jsonl" <<'EOF'
import json, statistics, sys
steps = [r for r in map(json.loads, open(sys.argv[1])) if r["kind"] == "step"]
compute = [r["seconds"] for r in steps]
wall = 1.0 / steps[-1]["steps_per_second"]
mean = sum(compute) / len(compute)
print(f"{len(steps)} steps: compute median {statistics.median(compute):.3f} s, "
      f"mean {mean:.3f} s; wall {wall:.3f} s/step; waiting for data {wall - mean:.3f} s/step")
EOF
