#!/usr/bin/env bash
# Nsight Compute over one steady-state run of the batched projectile (B = 2^18, hard contact, 21
# evaluations, float32) for the backends whose throughput the memory figures did not explain.
# In the project root on the lent H100 after the staged wheels: bash profile.sh BACKEND...
set -u
export PYTHONPATH=/tmp/site:$PWD
for b in "$@"; do
  timeout 200 ncu --profile-from-start off --launch-count 600 --csv --metrics \
    gpu__time_duration.sum,dram__bytes_read.sum,dram__bytes_write.sum,lts__t_bytes.sum,l1tex__t_bytes_pipe_lsu_mem_local_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_local_op_st.sum,launch__grid_size,launch__block_size,launch__registers_per_thread \
    python docs/results/h100/evidence/ad-profile/profile.py "$b" > "$OUT/ncu-$b.csv" 2> "$OUT/ncu-$b.err"
  tail -2 "$OUT/ncu-$b.err"
done
