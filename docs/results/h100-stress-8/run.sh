#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-stress-8.md (issue 14, what the last leases left): the
# SAXPY bandwidth variants' second lease, Warp's recorded launches (variant record_cmd), the
# scaling sweep's missing cells, and the stress suite with eight backends. Run in the project root
# on the lent H100 after ../shared/gpu/stage-wheels' parts (staged as for
# docs/results/h100-regimes-8/run.sh), as
#   COMPARE_GIT_COMMIT=<commit> bash docs/results/h100-stress-8/run.sh PART WORK
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm. Parts:
#   lease    timing: GPU tests of the variants; SAXPY 2^26 and 2^28 with every variant; Warp's
#            record_cmd against its plain launch and graph at the default sizes (host profile)
#   scaling  timing: `sweep scaling --resume` over the committed h100-sweep-8 sweep.json
#   stress   starts the stress suite's particle experiments in the background (lease 1)
#   stress-rest  starts the other experiments, one background process each (lease 2)
#   wait S   waits up to S seconds for the started stress processes, then packs what they have
# Each part packs WORK into $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
mkdir -p "$out"
case $part in
  lease)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    timeout 240 python -m pytest -q -p no:cacheprovider tests/test_cupy.py tests/test_warp.py \
      -k "vector or tile or record_cmd" > "$out/variants-tests.txt" 2>&1
    echo "variant tests: $(tail -1 "$out/variants-tests.txt")"
    timeout 200 python -m compare run saxpy --devices cuda --precision float32 \
      --variants default,vector,tile,record_cmd --set n=67108864 --out "$out/saxpy-2p26" --no-plots \
      > "$out/saxpy-2p26.txt" 2>&1
    echo "saxpy 2^26 rc=$?"
    # 2^28: the variants and their defaults (the other frameworks have two leases at this size)
    timeout 200 python -m compare run saxpy --backends warp,cupy --devices cuda --precision float32 \
      --variants default,vector,tile,record_cmd --set n=268435456 --check-sample 1000000 \
      --out "$out/saxpy-2p28" --no-plots > "$out/saxpy-2p28.txt" 2>&1
    echo "saxpy 2^28 rc=$?"
    timeout 200 python -m compare run saxpy sdf particles launch --backends warp --devices cuda \
      --precision float32 --variants default,record_cmd --host-profile 12 --out "$out/record-cmd" \
      --no-plots > "$out/record-cmd.txt" 2>&1
    echo "record_cmd rc=$?"; grep -E "^warp" "$out/record-cmd.txt" ;;
  scaling)
    mkdir -p "$out/sweep"
    cp docs/results/h100-sweep-8/sweep/sweep.json "$out/sweep/sweep.json"
    timeout 560 python -m compare sweep scaling --devices cuda --resume --out "$out/sweep" \
      --page "$out/sweep/measurement.md" --title 'Measurement sweeps: CUDA (H100), eight backends' \
      > "$out/sweep-scaling.txt" 2>&1
    echo "sweep scaling rc=$?"; tail -3 "$out/sweep-scaling.txt" ;;
  stress)   # lease 1: the particle experiments (this group finished; the projectile group that
            # followed it was cut when the machine went back after 30 minutes)
    setsid nohup bash -c "
      echo \"\$(date +%T) start particles\" >> '$out/stress-progress.txt'
      python -m compare stress --devices cuda --timeout 300 --jobs 8 --out '$out/stress' \
        --only particles-dt,particles-long,particles-inf,particles-divergence >> '$out/stress.txt' 2>&1
      echo \"\$(date +%T) end particles rc=\$?\" >> '$out/stress-progress.txt'
      touch '$out/stress-done'" > /dev/null 2>&1 < /dev/null &
    sleep 2; echo "stress started" ;;
  stress-rest)   # lease 2: the other experiments, each its own process and folder, all at once
                 # (a backend's GPU cells run one at a time within a process, and PyTorch's eager
                 # projectile takes 1-2 s a call: one process per experiment runs its lanes side by
                 # side); ulps and races also on the CPU, for the races' cpu-vs-cuda rows. Merged
                 # afterwards with `compare stress --merge`. A cell or host loop may take 900 s
                 # (the host loops stop at their own 300 s budget; PyTorch needs all of it).
    for g in 'cuda projectile-lr' 'cuda projectile-gradient' 'cuda projectile-horizon' 'cpu,cuda ulps,races'; do
      set -- $g; name=${2%%,*}
      setsid nohup bash -c "
        echo \"\$(date +%T) start $2\" >> '$out/stress-progress.txt'
        python -m compare stress --devices $1 --only $2 --timeout 900 --jobs 8 \
          --out '$out/stress-$name' > '$out/stress-$name.txt' 2>&1
        echo \"\$(date +%T) end $2 rc=\$?\" >> '$out/stress-progress.txt'
        touch '$out/stress-$name-done'" > /dev/null 2>&1 < /dev/null &
    done
    sleep 2; echo "stress-rest started" ;;
  wait)   # until every started group has its done file, or S seconds
    limit=${3:-540}; t=0
    while [ "$t" -lt "$limit" ]; do
      started=$(grep -c ' start ' "$out/stress-progress.txt"); ended=$(grep -c ' end ' "$out/stress-progress.txt")
      [ "$ended" -ge "$started" ] && break
      sleep 10; t=$((t + 10))
    done
    cat "$out/stress-progress.txt"; tail -qn 2 "$out"/stress*.txt | grep -v '^$' ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
