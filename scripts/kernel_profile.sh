#!/usr/bin/env bash
# Time per CubeCL kernel: runs the rasterizer bench under CubeCL's own profiler (which waits
# for every launch and logs its duration) and sums the log per kernel, slowest first.
#
#   scripts/kernel_profile.sh --backends wgpu --sizes 100000 --quick
#   scripts/kernel_profile.sh --backends wgpu --sizes 100000 --quick --schedules shared
#   RASTER_BIN=path OUT=dir scripts/kernel_profile.sh --backends cuda --sizes 362600 --quick
#
# Arguments go to the bench (crates/splat/benches/raster.rs). Writes OUT/kernels.log (CubeCL's
# log: each kernel's source at its first compilation, then one line per launch) and
# OUT/kernels.md. The first launch of each kernel includes its compilation, and every launch
# is followed by a wait, so the sums exceed the bench's own (unprofiled) times: compare
# kernels with each other, not with the bench table. CubeCL's logger writes from a queue of
# its own, and what is still queued when the bench exits is lost (at 10 000 Gaussians most of
# the short launches): read the means, not the launch counts.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/kernel-profile}
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
bin=${RASTER_BIN:-}
if [ -z "$bin" ]; then
  bin=$(cargo bench -p envision4d-splat --bench raster --no-run 2>&1 \
    | sed -n 's/.*Executable .*(\(.*\))$/\1/p' | tail -1)
fi
[ -x "$bin" ] || { echo "kernel_profile: no raster bench binary (${bin:-none})" >&2; exit 1; }
bin=$(realpath "$bin")
rm -f "$OUT/kernels.log"
# From the splat crate, where `cargo bench` runs it.
(cd crates/splat && CUBECL_DEBUG_OPTION=profile CUBECL_DEBUG_LOG="$OUT/kernels.log" \
  "$bin" "$@") | tee "$OUT/bench.md"
# Launch lines look like "| 12.3ms | RasterizeForward_eb4b83ea" (a generic kernel adds
# "| NativeAdd_..."); durations come in s, ms, µs or ns.
python3 - "$OUT/kernels.log" "$OUT/kernels.md.tmp" "$*" <<'PY'
import re, sys
log, out, args = sys.argv[1:]
unit = {"s": 1e3, "ms": 1.0, "µs": 1e-3, "us": 1e-3, "ns": 1e-6}
line = re.compile(r"^\| ([0-9.]+)(s|ms|µs|us|ns) \| (.+)$")
sums = {}
for text in open(log, encoding="utf-8", errors="replace"):
    m = line.match(text.rstrip("\n"))
    if not m:
        continue
    name = " | ".join(re.sub(r"_[0-9a-f]{8}$", "", p.strip()) for p in m.group(3).split("|"))
    ms = float(m.group(1)) * unit[m.group(2)]
    total, count = sums.get(name, (0.0, 0))
    sums[name] = (total + ms, count + 1)
rows = sorted(sums.items(), key=lambda kv: -kv[1][0])
with open(out, "w") as f:
    f.write(f"Kernels of `raster {args}` under CUBECL_DEBUG_OPTION=profile\n\n")
    f.write("| kernel | launches | total ms | mean ms |\n|---|---|---|---|\n")
    for name, (total, count) in rows:
        f.write(f"| {name} | {count} | {total:.1f} | {total / count:.2f} |\n")
PY
mv "$OUT/kernels.md.tmp" "$OUT/kernels.md"
cat "$OUT/kernels.md"
