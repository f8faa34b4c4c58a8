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
#   stress   starts the stress suite (three groups, one output folder) in the background
#   wait S   waits up to S seconds for the stress suite, then packs what it has
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
  stress)   # three groups into one folder (--only keeps the other groups' rows); ulps and races
            # also on the CPU, for the races experiment's cpu-vs-cuda rows
    setsid nohup bash -c "
      for g in 'cuda particles-dt,particles-long,particles-inf,particles-divergence' \
               'cuda projectile-lr,projectile-gradient,projectile-horizon' 'cpu,cuda ulps,races'; do
        set -- \$g
        echo \"\$(date +%T) start \$2\" >> '$out/stress-progress.txt'
        python -m compare stress --devices \$1 --only \$2 --timeout 300 --jobs 8 \
          --out '$out/stress' >> '$out/stress.txt' 2>&1
        echo \"\$(date +%T) end \$2 rc=\$?\" >> '$out/stress-progress.txt'
      done
      touch '$out/stress-done'" > /dev/null 2>&1 < /dev/null &
    sleep 2; echo "stress started" ;;
  wait)
    limit=${3:-540}; t=0
    while [ ! -e "$out/stress-done" ] && [ "$t" -lt "$limit" ]; do sleep 10; t=$((t + 10)); done
    cat "$out/stress-progress.txt"; tail -3 "$out/stress.txt" ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
