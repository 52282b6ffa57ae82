#!/usr/bin/env bash
# The same release binaries on a CPU without AVX-512: runs the forward bench and the forward
# parity tests under QEMU's user-mode emulation of a Haswell CPU (AVX2 + FMA, no AVX-512), so
# gemm's and our kernels' run-time dispatch must take their AVX2 paths (docs/PERFORMANCE.md,
# "AVX-512 at run time"). Needs `qemu-user` (Debian: apt-get install qemu-user).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}
cd "$root"
bench=$(cargo bench -q -p envision4d-model --bench forward --no-run --message-format=json 2>/dev/null |
  python3 -c 'import json,sys; print([m["executable"] for m in map(json.loads, sys.stdin) if m.get("executable")][-1])')
parity=$(cargo test --release -q -p envision4d-model --test parity --no-run --message-format=json 2>/dev/null |
  python3 -c 'import json,sys; print([m["executable"] for m in map(json.loads, sys.stdin) if m.get("executable")][-1])')
echo "host:     $("$bench" --preset tiny --image 56x84 --repeats 1 | head -1)"
echo "emulated: $(qemu-x86_64 -cpu Haswell "$bench" --preset tiny --image 56x84 --repeats 1 2>/dev/null | head -1)"
cd crates/model
qemu-x86_64 -cpu Haswell "$parity" tiny_full_forward tiny_backbone dpt_ block_ rope 2>/dev/null | tail -3
