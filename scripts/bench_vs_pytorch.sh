#!/usr/bin/env bash
# Side by side with the official PyTorch code: the same network, inputs, threads and heads,
# run in alternation, medians printed with the ratio (docs/PERFORMANCE.md, "Side by side
# with PyTorch"). Not part of CI: it needs a checkout of the public release and downloads
# torch into a venv.
#
#   scripts/bench_vs_pytorch.sh RELEASE_CHECKOUT [options]
#     --preset tiny|paper   widths (default tiny)
#     --mode forward|train  no_grad forward, or forward + backward (default forward)
#     --shape B,S,H,W       images (default 1,2,350,518)
#     --future N            future frames the network predicts (default 2)
#     --threads N           threads on both sides (default 2)
#     --rounds N            alternations (default 3); each runs --repeats timed passes
#     --repeats N           timed passes per process after one warm-up (default 3)
#     --features LIST       extra cargo features for our side (e.g. envision4d-model/x86-v4)
#
# Environment: VENV (default $HOME/.cache/envision4d-bench-venv), CARGO_TARGET_DIR.
set -euo pipefail

release=${1:?usage: scripts/bench_vs_pytorch.sh RELEASE_CHECKOUT [options]}
shift
preset=tiny mode=forward shape=1,2,350,518 future=2 threads=2 rounds=3 repeats=3 features=""
while [ $# -gt 0 ]; do
  case "$1" in
    --preset) preset=$2 ;;
    --mode) mode=$2 ;;
    --shape) shape=$2 ;;
    --future) future=$2 ;;
    --threads) threads=$2 ;;
    --rounds) rounds=$2 ;;
    --repeats) repeats=$2 ;;
    --features) features=$2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
  shift 2
done
[ -d "$release/src/model/encoder/envision4d" ] || {
  echo "$release: not a checkout of the Envision4D release (no src/model/encoder/envision4d)" >&2
  exit 2
}
root=$(cd "$(dirname "$0")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/envision4d-target}
venv=${VENV:-$HOME/.cache/envision4d-bench-venv}
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  # The versions the fixtures were made with (torch from the default registry).
  "$venv/bin/pip" install -q torch==2.8.0 numpy einops jaxtyping huggingface_hub omegaconf \
    pyyaml safetensors
fi
py="$venv/bin/python $root/scripts/bench_pytorch_forward.py"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
images="$work/images.safetensors"
$py --images "$images" --write-images "$shape"
IFS=, read -r _ _ h w <<<"$shape"

feature_args=()
[ -n "$features" ] && feature_args=(--features "$features")
(cd "$root" && cargo bench -q -p envision4d-model --bench forward "${feature_args[@]}" --no-run)
ours() {
  (cd "$root" && RAYON_NUM_THREADS=$threads cargo bench -q -p envision4d-model --bench forward \
    "${feature_args[@]}" -- --preset "$preset" --mode "$mode" --images "$images" \
    --future "$future" --repeats "$repeats")
}
theirs() {
  OMP_NUM_THREADS=$threads MKL_NUM_THREADS=$threads $py --release "$release" --preset "$preset" \
    --mode "$mode" --images "$images" --future "$future" --threads "$threads" \
    --repeats "$repeats"
}
for r in $(seq 1 "$rounds"); do
  theirs | tee -a "$work/theirs.log" | sed "s/^/pytorch round $r: /"
  ours | tee -a "$work/ours.log" | sed "s/^/ours    round $r: /"
done
"$venv/bin/python" - "$work/ours.log" "$work/theirs.log" "$preset" "$mode" "$shape" "$threads" <<'EOF'
import re, statistics, sys
ours, theirs, preset, mode, shape, threads = sys.argv[1:]
def read(path):
    t, m = [], []
    for line in open(path):
        g = re.match(r"(?:forward_warm_s|train_step_s)=([\d.]+) peak_rss_gib=([\d.]+)", line)
        if g:
            t.append(float(g[1])); m.append(float(g[2]))
    return statistics.median(t), max(m), len(t)
(o, om, on), (p, pm, pn) = read(ours), read(theirs)
print("| preset | pass | images B,S,H,W | threads | ours median s (n) | PyTorch median s (n) | ours / PyTorch | peak RSS GiB ours / PyTorch |")
print("|---|---|---|---|---|---|---|---|")
print(f"| {preset} | {mode} | {shape} | {threads} | {o:.3f} ({on}) | {p:.3f} ({pn}) | {o / p:.2f} | {om:.2f} / {pm:.2f} |")
EOF
