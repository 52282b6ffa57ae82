#!/usr/bin/env bash
# The rasterizer bench of earlier commits, re-run today beside the current one (the
# 2026-12-04 tables of docs/PERFORMANCE.md): each commit is checked out in a scratch
# worktree, its bench built and copied out, then all are run one after another on an idle
# machine, CPU path and wgpu.
#
#   scripts/raster_history.sh 68385f9 475f64a HEAD          # tables in runs/raster-history
#   OUT=dir SIZES=10000 scripts/raster_history.sh 475f64a HEAD
#   SCHEDULES=auto scripts/raster_history.sh HEAD          # one tile schedule (default: all)
#
# Benches before 37a5503 stopped the clock at `into_data`, which on CubeCL backends returns
# before the kernels run (the read is lazy, done at the bytes' first access): their `time`
# function is patched to touch the read-back bytes first, which waits for every kernel the
# output depends on. Benches from before `--backends`/`--sizes` existed run with `--wgpu
# --max-gaussians` instead (their own sizes up to that cap).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
OUT=${OUT:-runs/raster-history}
SIZES=${SIZES:-10000,100000}
# Tile schedules of the compositing kernels, for benches that have them (`--schedules`).
SCHEDULES=${SCHEDULES:-auto,shared,per-pixel}
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
[ $# -gt 0 ] || { echo "usage: scripts/raster_history.sh COMMIT..." >&2; exit 2; }
mkdir -p "$OUT"
# Absolute: the benches run from crates/splat.
OUT=$(realpath "$OUT")
scratch=$(mktemp -d)
cleanup() {
  for wt in "$scratch"/wt-*; do
    [ -d "$wt" ] && git -C "$root" worktree remove --force "$wt"
  done
  rm -rf "$scratch"
}
trap cleanup EXIT

for commit in "$@"; do
  id=$(git rev-parse --short "$commit")
  wt=$scratch/wt-$id
  git worktree add -q --detach "$wt" "$id"
  # The bench is benches/raster/main.rs from d38583f on, benches/raster.rs before.
  bench_src=$wt/crates/splat/benches/raster.rs
  [ -f "$bench_src" ] || bench_src=$wt/crates/splat/benches/raster/main.rs
  python3 - "$bench_src" <<'PY'
import re, sys
path = sys.argv[1]
src = open(path).read()
sig = re.search(r"fn time<T>\(reps: usize, mut f: impl FnMut\(\) -> T\) -> Duration \{", src)
if sig:
    src = src.replace(sig.group(0), """trait Settle { fn settle(&self); }
impl Settle for SettleData { fn settle(&self) { let _ = self.as_bytes().len(); } }
impl Settle for (SettleData, SettleData) { fn settle(&self) { self.0.settle(); self.1.settle(); } }
fn time<T: Settle>(reps: usize, mut f: impl FnMut() -> T) -> Duration {""")
    start = src.index("fn time<T: Settle>")
    end = src.index("\n}\n", start)
    src = src[:start] + src[start:end].replace("f();", "f().settle();") + src[end:]
    first_use = src.index("\nuse ") + 1
    src = src[:first_use] + "use burn::tensor::TensorData as SettleData;\n" + src[first_use:]
    open(path, "w").write(src)
    print(f"raster_history: {path}: timing patched")
PY
  # The worktrees share one target directory and cargo names their artifacts alike, so each
  # source tree is made newer than the last build and its binary copied out at once.
  find "$wt/crates" -name '*.rs' -exec touch {} +
  bin=$(cd "$wt" && cargo bench -p envision4d-splat --bench raster --no-run 2>&1 \
    | sed -n 's/.*Executable .*(\(.*\))$/\1/p' | tail -1)
  [ -x "$bin" ] || { echo "raster_history: the bench of $id did not build" >&2; exit 1; }
  cp "$bin" "$OUT/raster-$id"
done

: > "$OUT/raster-history.md.part"
for commit in "$@"; do
  id=$(git rev-parse --short "$commit")
  bin=$OUT/raster-$id
  if grep -q -- "--backends" "$bin"; then
    args=(--backends cpu,wgpu --sizes "$SIZES")
  else
    max=$(echo "$SIZES" | tr ',' '\n' | sort -n | tail -1)
    args=(--wgpu --max-gaussians "$max")
  fi
  if grep -q -- "--schedules" "$bin"; then
    args+=(--schedules "$SCHEDULES")
  fi
  {
    echo "### $id ($(git log -1 --format=%cs "$id")): ${args[*]}"
    echo
    (cd crates/splat && "$bin" "${args[@]}") | grep -E '^(\||machine)'
    echo
  } | tee -a "$OUT/raster-history.md.part"
done
mv "$OUT/raster-history.md.part" "$OUT/raster-history.md"
echo "raster_history: wrote $OUT/raster-history.md"
