#!/usr/bin/env bash
# How docs/results/h100-regimes was produced on the lent H100 (after ../shared/gpu/stage-wheels and
# `export PYTHONPATH=/tmp/site:$PWD`). Part A: every CUDA cell in both regimes with the hardware
# yardstick and SAXPY at 2^26 (a kernel-dominated size); part C: the clock validation under Nsight
# Compute (run.sh ncu). Part B (run.sh sweeps): the bandwidth and scaling sweeps.
set -u
OUT=${OUT:-/tmp/out}
export PYTHONUNBUFFERED=1
if [ "${1:-}" = "sweeps" ]; then        # part B
  python -m compare sweep bandwidth --devices cuda --out "$OUT/sweep" > "$OUT/sweep.log" 2>&1
  echo "sweep bandwidth rc=$?"
  python -m compare sweep scaling --devices cuda --out "$OUT/sweep" >> "$OUT/sweep.log" 2>&1
  echo "sweep scaling rc=$?"
  exit 0
fi
if [ "${1:-}" = "lease2" ]; then        # part D (see the end of this file)
  python -m compare all --devices cuda --precision float32 --out "$OUT/lease2" --no-plots > "$OUT/lease2.log" 2>&1
  echo "lease2 all rc=$?"
  for n in 67108864 268435456; do
    python -m compare run saxpy --devices cuda --precision float32 --set n=$n --out "$OUT/lease2-saxpy-$n" \
      --no-plots >> "$OUT/lease2.log" 2>&1
    echo "lease2 saxpy $n rc=$?"
  done
  python -m compare run particles --devices cuda --precision float32 --set n=16777216 \
    --out "$OUT/lease2-particles" --no-plots >> "$OUT/lease2.log" 2>&1
  echo "lease2 particles rc=$?"
  exit 0
fi
if [ "${1:-}" = "ncu" ]; then           # part C
  # Clock validation: the GPU time Nsight Compute measures for the kernels of one small (n = 1e6)
  # and one large (n = 2^26) SAXPY cell per framework (the worker alone, so no probe or yardstick
  # process is profiled), steady-state launches only (skip the first 10 kernels: first call and
  # warm-up); compared on the page with the same cells' CUDA event and wall-clock medians from the
  # unprofiled runs above.
  for b in warp taichi jax numba; do
    for n in 1000000 67108864; do
      mkdir -p "/tmp/ncu-$b-$n"
      echo "[{\"scenario\": \"saxpy\", \"backend\": \"$b\", \"device\": \"cuda\", \"precision\": \"float32\",
        \"params\": {\"n\": $n}, \"repeat\": 40, \"min_time\": 0, \"throughput\": false}]" > "/tmp/ncu-$b-$n/spec.json"
      ncu --metrics gpu__time_duration.sum --csv --launch-skip 10 --launch-count 20 \
          python -m compare.worker "/tmp/ncu-$b-$n/spec.json" "/tmp/ncu-$b-$n" > "/tmp/ncu-$b-$n.csv" 2>/dev/null
      grep '"gpu__time_duration.sum"' "/tmp/ncu-$b-$n.csv" | sed "s/^/$b,$n,/" >> "$OUT/ncu.csv"
    done
  done
  echo "ncu rows: $(wc -l < "$OUT/ncu.csv")"
  exit 0
fi
python -m compare all --devices cuda --variants all --out "$OUT/all" --no-plots > "$OUT/all.log" 2>&1
echo "all rc=$?"
python -m compare run saxpy --devices cuda --precision float32 --set n=67108864 --out "$OUT/large" \
  --no-plots > "$OUT/large.log" 2>&1
echo "large rc=$?"
# Part D (run.sh lease2), on a second lease, for the headline's lease-to-lease spread: the
# headline cells again (default sizes, SAXPY 2^26 and 2^28, particles 2^24).
