#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-stress-8.md (issue 14, what the earlier leases left), all in
# one lease of the H100: the SAXPY bandwidth variants' second lease, Warp's recorded launches
# (variant record_cmd), quadrants' missing scaling cells, and the stress suite for the backends the
# published GPU stress page lacks (PyTorch, CuPy, quadrants; Warp again, the reference that the
# cross-backend rows compare with), merged afterwards into docs/results/stress-gpu with
# `compare stress --merge` (per experiment, backend and device). Wheels staged with
#   ../shared/gpu/stage-wheels warp-lang==1.19.0 'numpy==2.4.*' quadrants==1.3.3 dill==0.4.1 pydantic \
#       pydantic-core annotated-types typing-inspection typing-extensions cffi pycparser colorama \
#       rich markdown-it-py mdurl Pygments
# (no Taichi: no cell here needs it), one part per device call. Run in the project root as
#   COMPARE_GIT_COMMIT=<commit> SWEEP_JSON=<h100-sweep-8's sweep.json> bash run.sh PART WORK
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm. Parts:
#   lease    timing, alone on the GPU: the variants' GPU tests; SAXPY 2^26 and 2^28 with every
#            variant (Warp, CuPy); Warp's record_cmd against its plain launch and graph at the
#            default sizes (host profile); then `sweep scaling --resume` for quadrants
#   stress   starts the stress suite in the background, one process per experiment group
#   stress-rest  what `wait 560` had stopped, one backend a process (run on a fresh machine: see
#            docs/results/h100-stress-8.md)
#   stress-next  what is still missing, for the next lease
#   wait S [keep]  waits up to S seconds for the stress processes, stops what still runs (unless
#            keep: it runs on into the next call), packs
# Each part packs WORK into $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
mkdir -p "$out"
step() {   # $1: seconds, $2: name; the rest: the command (its output goes to WORK/<name>.txt)
  local limit=$1 name=$2; shift 2
  timeout "$limit" "$@" > "$out/$name.txt" 2>&1
  local rc=$?     # (read before $(date) runs: the lease's log printed date's 0 for two timeouts)
  echo "$(date +%T) $name rc=$rc"
}
start_group() {   # $1 devices, $2 backends, $3 experiments: one background `compare stress`
  # It runs from its own copy of the tree: each device call copies the working tree anew, and in
  # this lease that copy, made under the groups still running from the last call, made six
  # workers that started during it fail to import (their rows say `error ... ModuleNotFoundError`).
  local name="${3%%,*}-${2//,/-}" snap=/tmp/gpusnap
  [ -d "$snap" ] || { mkdir -p "$snap" && tar --exclude=./.gpu -cf - . | tar -xf - -C "$snap"; }
  setsid nohup bash -c "cd '$snap' && export PYTHONPATH=/tmp/site:'$snap'
    echo \"\$(date +%T) start $3 ($2)\" >> '$out/stress-progress.txt'
    python -m compare stress --devices $1 --backends $2 --only $3 --timeout 300 \
      --out '$out/stress-$name' > '$out/stress-$name.txt' 2>&1
    echo \"\$(date +%T) end $3 ($2) rc=\$?\" >> '$out/stress-progress.txt'" > /dev/null 2>&1 < /dev/null &
}
case $part in
  lease)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    step 100 variants-tests python -m pytest -q -p no:cacheprovider tests/test_cupy.py tests/test_warp.py \
      -k "vector or tile or record_cmd"
    tail -1 "$out/variants-tests.txt"
    step 90 saxpy-2p26 python -m compare run saxpy --backends warp,cupy --devices cuda --precision float32 \
      --variants default,vector,tile,record_cmd --set n=67108864 --out "$out/saxpy-2p26" --no-plots
    step 90 saxpy-2p28 python -m compare run saxpy --backends warp,cupy --devices cuda --precision float32 \
      --variants default,vector,tile,record_cmd --set n=268435456 --check-sample 1000000 \
      --out "$out/saxpy-2p28" --no-plots
    step 100 record-cmd python -m compare run saxpy sdf particles launch --backends warp --devices cuda \
      --precision float32 --variants default,record_cmd --host-profile 12 --out "$out/record-cmd" --no-plots
    grep -E "^(warp|backend) " "$out/record-cmd.txt" | head -16
    mkdir -p "$out/sweep"; cp "$SWEEP_JSON" "$out/sweep/sweep.json"
    step 170 sweep-scaling python -m compare sweep scaling --backends quadrants --devices cuda --resume \
      --out "$out/sweep" --no-plots
    tail -2 "$out/sweep-scaling.txt" ;;
  stress)   # one process per group, side by side (a backend's GPU cells run one at a time within a
            # process); ulps and races also on the CPU, for their cpu-vs-cuda rows
    for g in 'cuda warp,torch,cupy,quadrants particles-dt,particles-long,particles-inf,particles-divergence' \
             'cuda warp,torch,cupy,quadrants projectile-lr' \
             'cuda warp,torch,cupy,quadrants projectile-gradient,projectile-horizon' \
             'cpu,cuda warp,numpy,torch,cupy,quadrants ulps,races'; do
      start_group $g
    done
    sleep 2; echo "stress started" ;;
  stress-rest)   # the same lease, after `wait 560` stopped the particle group in particles-inf and
                 # projectile-lr unfinished (PyTorch's eager descents): those, one backend a process
    for g in 'cuda warp,torch,cupy,quadrants particles-inf,particles-divergence' 'cuda torch projectile-lr' \
             'cuda quadrants projectile-lr' 'cuda cupy projectile-lr'; do
      start_group $g
    done
    sleep 2; echo "stress-rest started" ;;
  stress-next)   # for the next lease (not run yet): what this one left. PyTorch's projectile-lr
                 # needs more than one 10-minute call: its group runs on from its snapshot while
                 # later calls `wait`; the vs-Warp rows need Warp in the same run.
    for g in 'cuda warp,torch,cupy,quadrants particles-inf,particles-divergence' 'cuda torch projectile-lr' \
             'cuda quadrants projectile-lr' 'cuda warp,torch,cupy,quadrants projectile-gradient' \
             'cpu,cuda numpy,quadrants ulps'; do
      start_group $g
    done
    sleep 2; echo "stress-next started" ;;
  wait)   # until every started group has ended, or S seconds; then stop the rest (each group's
          # stress.json holds the experiments it finished)
    limit=${3:-300}; t=0
    while [ "$t" -lt "$limit" ]; do
      [ "$(grep -c ' end ' "$out/stress-progress.txt")" -ge "$(grep -c ' start ' "$out/stress-progress.txt")" ] && break
      sleep 5; t=$((t + 5))
    done
    if [ "${4:-stop}" != keep ] && pkill -f "compare stress"; then
      echo "$(date +%T) stopped the groups still running after $limit s" >> "$out/stress-progress.txt"
    fi
    cat "$out/stress-progress.txt"; grep -h "done in" "$out"/stress-*.txt ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
