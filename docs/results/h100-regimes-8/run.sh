#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-regimes-8.md (issue 14, eight backends): both timing
# regimes, the host's share of a call and where it goes (cProfile), the graph paths (Warp, CuPy,
# PyTorch capture; Numba through driver stream capture; JAX command buffers), the kernel-dominated
# headline sizes, Nsight Compute's clock for the new backends, and the stress suite. Run in the
# project root on the lent H100 after ../shared/gpu/stage-wheels' parts (staged with
#   ../shared/gpu/stage-wheels + quadrants==1.3.3 pydantic pydantic-core annotated-types \
#       typing-inspection typing-extensions cffi pycparser colorama rich markdown-it-py mdurl Pygments
# one part per device call), as
#   COMPARE_GIT_COMMIT=<commit> bash docs/results/h100-regimes-8/run.sh PART WORK
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm; each part ends by packing its
# output into $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
mkdir -p "$out"
large() {   # kernel-dominated sizes, default and graph variants, float32; $1: a name for this lease
  for n in 67108864 268435456; do
    timeout 250 python -m compare run saxpy --devices cuda --precision float32 --variants default,graph \
      --set n=$n --out "$out/$1-saxpy-$n" --no-plots > "$out/$1-saxpy-$n.txt" 2>&1
    echo "$1 saxpy $n rc=$?"
  done
  # 2^24 particles: the float64 oracle of every particle takes minutes, so 4096 evenly spaced ones
  timeout 250 python -m compare run particles --devices cuda --precision float32 --variants default,graph \
    --set n=16777216 --check-sample 4096 --out "$out/$1-particles" --no-plots > "$out/$1-particles.txt" 2>&1
  echo "$1 particles rc=$?"
}
case $part in
  all32|all64)   # every CUDA cell, every variant, with the host profile of the throughput regime
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    timeout 570 python -m compare all --devices cuda --precision float${part#all} --variants all \
      --host-profile 12 --out "$out/$part" --no-plots > "$out/$part.txt" 2>&1
    echo "$part rc=$?"; tail -5 "$out/$part.txt" ;;
  large)  # the headline sizes; then the JAX projectile's graph variant, which the first all32/all64
          # refused (its kernel file did not list the variant; fixed in the commit of this run)
    large lease1
    timeout 120 python -m compare run projectile --backends jax --devices cuda --variants graph \
      --host-profile 12 --out "$out/jax-projectile-graph" --no-plots > "$out/jax-projectile-graph.txt" 2>&1
    echo "jax projectile graph rc=$?" ;;
  lease2)   # a second lease: the headline cells again, for the lease-to-lease spread
    large lease2
    timeout 300 python -m compare all --devices cuda --precision float32 --out "$out/lease2-all" \
      --no-plots > "$out/lease2-all.txt" 2>&1
    echo "lease2 all rc=$?"
    # the one-kernel PyTorch SAXPY (this run's commit) against the oracle and Warp on CUDA
    timeout 200 python -m pytest -q -p no:cacheprovider tests/test_parity.py -k "cuda and saxpy" \
      > "$out/lease2-parity.txt" 2>&1
    echo "lease2 parity: $(tail -1 "$out/lease2-parity.txt")" ;;
  ncu)      # Nsight Compute's kernel time for one small and one large SAXPY per new CUDA backend
            # (docs/results/h100-regimes/run.sh did Warp, Taichi, JAX and Numba the same way)
    for b in cupy torch quadrants; do
      for n in 1000000 67108864; do
        mkdir -p "/tmp/ncu-$b-$n"
        echo "[{\"scenario\": \"saxpy\", \"backend\": \"$b\", \"device\": \"cuda\", \"precision\": \"float32\",
          \"params\": {\"n\": $n}, \"repeat\": 40, \"min_time\": 0, \"throughput\": false}]" > "/tmp/ncu-$b-$n/spec.json"
        timeout 200 ncu --metrics gpu__time_duration.sum --csv --launch-skip 10 --launch-count 20 \
          python -m compare.worker "/tmp/ncu-$b-$n/spec.json" "/tmp/ncu-$b-$n" > "/tmp/ncu-$b-$n.csv" 2>/dev/null
        grep '"gpu__time_duration.sum"' "/tmp/ncu-$b-$n.csv" | sed "s/^/$b,$n,/" >> "$out/ncu.csv"
      done
    done
    echo "ncu rows: $(wc -l < "$out/ncu.csv")" ;;
  stress*)  # the stress suite on CUDA, all eight backends, in groups that fit one call
    case $part in
      stress1) only=particles-dt,particles-long,particles-inf,particles-divergence ;;
      stress2) only=projectile-lr,projectile-gradient,projectile-horizon ;;
      stress3) only=ulps,races ;;
    esac
    timeout 570 python -m compare stress --devices cuda --only $only --timeout 300 --jobs 4 \
      --out "$out/$part" > "$out/$part.txt" 2>&1
    echo "$part rc=$?"; tail -3 "$out/$part.txt" ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
