#!/usr/bin/env bash
# GPU-aware scale-out on the lent two-GPU H200 (issue 18): the same sweep on both GPUs (one Dask
# worker per GPU, each pinned to its GPU and half the cores) and on one GPU (CUDA_VISIBLE_DEVICES=0,
# one worker), wall time of each, records compared in status and error afterwards
# (docs/results/h200x2-scaleout/report). Backends: those the image has (JAX, numba-cuda, CuPy; numpy
# 2.4, Dask and its dependencies staged with ../shared/gpu/stage-wheels).
#   bash docs/results/h200x2-scaleout/run.sh WORK
set -u
w=$1; mkdir -p "$w"
export PYTHONPATH=/tmp/site:$PWD
nvidia-smi --query-gpu=index,name,driver_version --format=csv > "$w/gpus.txt"
sweep=(python -m compare sweep bandwidth --quick --backends jax,numba,cupy --devices cuda --scheduler local)
t0=$(date +%s.%N)
timeout 250 "${sweep[@]}" --out "$w/two" > "$w/two.txt" 2>&1; echo "two GPUs rc=$?" >> "$w/wall.txt"
t1=$(date +%s.%N)
CUDA_VISIBLE_DEVICES=0 timeout 250 "${sweep[@]}" --out "$w/one" > "$w/one.txt" 2>&1; echo "one GPU rc=$?" >> "$w/wall.txt"
t2=$(date +%s.%N)
python -c "print(f'wall: two GPUs {$t1-$t0:.1f} s, one GPU {$t2-$t1:.1f} s')" >> "$w/wall.txt"
cat "$w/wall.txt"
[ -n "${OUT:-}" ] && tar czf "$OUT/scaleout.tgz" -C "$w" .
