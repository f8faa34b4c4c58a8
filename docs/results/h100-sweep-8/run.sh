#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-sweep-8.md (issue 14): the SAXPY bandwidth variants
# (CuPy "vector", Warp "tile") at the headline sizes, and the bandwidth and scaling sweeps with all
# eight backends, then the stress suite. Run in the project root on the lent H100 after
# ../shared/gpu/stage-wheels' parts (as for docs/results/h100-regimes-8/run.sh), as
#   COMPARE_GIT_COMMIT=<commit> bash docs/results/h100-sweep-8/run.sh PART WORK
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm; each part packs its output into
# $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
mkdir -p "$out"
sweep() {   # $1: kind; one sweep.json and page for both kinds
  timeout 560 python -m compare sweep "$1" --devices cuda --resume --out "$out/sweep" \
    --page "$out/sweep/measurement.md" --title 'Measurement sweeps: CUDA (H100), eight backends' \
    > "$out/sweep-$1.txt" 2>&1
  echo "sweep $1 rc=$?"; tail -2 "$out/sweep-$1.txt"
}
case $part in
  variants)   # the new variants against the default kernel on the GPU, then at the headline sizes
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    timeout 200 python -m pytest -q -p no:cacheprovider tests/test_cupy.py tests/test_warp.py \
      -k "vector or tile" > "$out/variants-tests.txt" 2>&1
    echo "variant tests: $(tail -1 "$out/variants-tests.txt")"
    for n in 67108864 268435456; do
      timeout 200 python -m compare run saxpy --devices cuda --precision float32 \
        --variants default,graph,vector,tile --set n=$n --out "$out/saxpy-$n" --no-plots \
        > "$out/saxpy-$n.txt" 2>&1
      echo "saxpy $n rc=$?"
    done ;;
  bandwidth|scaling) sweep "$part" ;;
  stress*)  # the stress groups as in the last lease's script (it packs its own output)
    exec bash docs/results/h100-regimes-8/run.sh "$part" "$out" ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
