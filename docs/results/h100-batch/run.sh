#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-batch.md (issues 15 and 16): every backend's CUDA parity
# for the batched projectile and the new ports, `compare all` on CUDA with eight backends, the
# gradient-throughput sweep (batch 1 ... 2^20) and the horizon sweep. Run in the project root on
# the lent H100 after ../shared/gpu/stage-wheels' parts (Warp, Taichi and quadrants travel as
# wheels; JAX, numba-cuda, PyTorch and CuPy are the image's), one part per device call. Staged with
#   ../shared/gpu/stage-wheels + quadrants==1.3.3 pydantic pydantic-core annotated-types \
#       typing-inspection typing-extensions cffi pycparser colorama rich markdown-it-py mdurl Pygments
#   bash docs/results/h100-batch/run.sh parity|all|scaling|horizon WORK
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm; each part ends by packing it
# into $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD
mkdir -p "$out"
case $part in
  parity)   # the projectile on every backend, and every scenario of the three new CUDA ports
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    timeout 420 python -m pytest -q -p no:cacheprovider -rs tests/test_parity.py \
      -k "cuda and (projectile or cupy or torch or quadrants)" > "$out/parity.txt" 2>&1
    tail -3 "$out/parity.txt" ;;
  all)      # default sizes, default variants, every backend that has CUDA
    timeout 560 python -m compare all --devices cuda --out "$out/all" > "$out/all.txt" 2>&1
    tail -40 "$out/all.txt" ;;
  scaling)  # gradient throughput against batch, float32, hard contact
    timeout 560 python -m compare sweep scaling --scenarios projectile --devices cuda \
      --out "$out/sweep" --title "Batched projectile on the H100" > "$out/scaling.txt" 2>&1
    tail -5 "$out/scaling.txt" ;;
  horizon)  # memory and FD agreement against the horizon, float32 (float64 on the CPU page);
            # PyTorch eager pays ~45 launches per step (4.5 s a call at 10 000 steps): left out here
    timeout 560 python -m compare sweep horizon --devices cuda --precision float32 \
      --backends warp,taichi,jax,numba,cupy,quadrants --repeat 3 --min-time 0.05 \
      --out "$out/sweep" --resume --title "Batched projectile on the H100" > "$out/horizon.txt" 2>&1
    tail -5 "$out/horizon.txt" ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
