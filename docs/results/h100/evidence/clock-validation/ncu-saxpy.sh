#!/usr/bin/env bash
# Clock validation (docs/measurement.md, "Clock validation"): the GPU time Nsight Compute measures
# for the kernels of one small (n = 1e6) and one large (n = 2^26) float32 SAXPY cell per framework,
# the worker alone (no probe or yardstick process profiled), steady-state launches only (the first
# 10 kernels, first call and warm-ups, skipped; the next 20 kept). The `ncu` parts of the two lease
# scripts that made the CSVs beside this file, joined: they ran
#   warp taichi jax numba    -> ncu-warp-taichi-jax-numba.csv   (commit d2b3cb6)
#   cupy torch quadrants     -> ncu-cupy-torch-quadrants.csv    (commit 9ed922e; the first run had no `timeout 200`)
# Run in the project root on the GPU machine: OUT=DIR bash ncu-saxpy.sh BACKEND...
set -u
OUT=${OUT:-/tmp/out}
for b in "$@"; do
  for n in 1000000 67108864; do
    mkdir -p "/tmp/ncu-$b-$n"
    echo "[{\"scenario\": \"saxpy\", \"backend\": \"$b\", \"device\": \"cuda\", \"precision\": \"float32\",
      \"params\": {\"n\": $n}, \"repeat\": 40, \"min_time\": 0, \"throughput\": false}]" > "/tmp/ncu-$b-$n/spec.json"
    timeout 200 ncu --metrics gpu__time_duration.sum --csv --launch-skip 10 --launch-count 20 \
        python -m compare.running.worker "/tmp/ncu-$b-$n/spec.json" "/tmp/ncu-$b-$n" > "/tmp/ncu-$b-$n.csv" 2>/dev/null
    grep '"gpu__time_duration.sum"' "/tmp/ncu-$b-$n.csv" | sed "s/^/$b,$n,/" >> "$OUT/ncu.csv"
  done
done
echo "ncu rows: $(wc -l < "$OUT/ncu.csv")"
