#!/usr/bin/env bash
# The GPU runs behind docs/results/h100-lease-9.md (issue 14: what docs/results/h100-stress-8.md
# left). Wheels staged with
#   GPU_PART_MIB=60 ../shared/gpu/stage-wheels warp-lang==1.19.0 'numpy==2.4.*' quadrants==1.3.3 \
#       dill==0.4.1 pydantic pydantic-core annotated-types typing-inspection typing-extensions cffi \
#       pycparser colorama rich markdown-it-py mdurl Pygments
# (no Taichi: no cell here needs it), one part per device call, the tree sent without docs/results
# (too large beside a 60 MiB part): for the lease `git rm -r -q --cached docs/results` and
# `/docs/results/` in .git/info/exclude, afterwards `git reset -q -- docs/results` and the line
# removed (commit nothing in between). This script and the sweep's sweep.json travel in the carried
# folder .lease (also in .git/info/exclude); that sweep.json is h100-sweep-8/sweep/sweep.json less
# Numba's CUDA particle scaling records. Machine 2 ran with the whole tree and NumPy 2.4 alone
# staged (`../shared/gpu/stage-wheels 'numpy==2.4.*'`), .lease holding
# `git show 02b6385~1:backends/numba/particles.py` as numba_particles_old.py:
#   python docs/results/h100-lease-9/ab_numba_particles.py .lease/numba_particles_old.py OUT/ab-numba-particles.json
#   python -m compare particles --backends numba --devices cuda --precision float32,float64 --out DIR --no-plots
# Machine 1's parts run in the project root as
#   COMPARE_GIT_COMMIT=<commit> bash run.sh PART WORK [ARGS]
# WORK (e.g. /tmp/gpuwork) persists while the machine stays warm. Parts:
#   lease SWEEP_JSON BUDGET_S  first, alone on the GPU, timing: `sweep scaling --resume` over the
#            published sweep for quadrants' and PyTorch's missing projectile cells and Numba's
#            particles (the cells of its changed kernel, taken out of the sweep.json sent, so
#            --resume runs them again); then starts the stress experiments the published GPU page
#            still lacks in the background (one process per group, each from its own copy of the
#            tree: the device tool copies the working tree anew at every call), runs Numba's GPU
#            tests (its CUDA particle kernel's source changed; correctness only, so the GPU may be
#            shared) and waits for the groups until BUDGET_S seconds from the part's start
#   wait S [keep]  waits up to S seconds for the stress groups; stops the rest unless keep
# Each part packs WORK into $OUT/<part>.tgz (what a device call brings back).
set -u
part=$1; out=$2
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
mkdir -p "$out"
step() {   # $1: seconds, $2: name; the rest: the command (its output goes to WORK/<name>.txt)
  local limit=$1 name=$2; shift 2
  timeout "$limit" "$@" > "$out/$name.txt" 2>&1
  local rc=$?
  echo "$(date +%T) $name rc=$rc"
}
start_group() {   # $1 devices, $2 backends, $3 experiments: one background `compare stress`
  local name="${3%%,*}-${2//,/-}" snap=/tmp/gpusnap
  [ -d "$snap" ] || { mkdir -p "$snap" && tar --exclude=./.gpu --exclude=./.lease -cf - . | tar -xf - -C "$snap"; }
  setsid nohup bash -c "cd '$snap' && export PYTHONPATH=/tmp/site:'$snap'
    echo \"\$(date +%T) start $3 ($2)\" >> '$out/stress-progress.txt'
    python -m compare stress --devices $1 --backends $2 --only $3 --timeout 900 \
      --out '$out/stress-$name' > '$out/stress-$name.txt' 2>&1
    echo \"\$(date +%T) end $3 ($2) rc=\$?\" >> '$out/stress-progress.txt'" > /dev/null 2>&1 < /dev/null &
}
wait_groups() {   # $1 seconds, $2 keep|stop
  local limit=$1 t=0
  while [ "$t" -lt "$limit" ]; do
    [ "$(grep -c ' end ' "$out/stress-progress.txt")" -ge "$(grep -c ' start ' "$out/stress-progress.txt")" ] && break
    sleep 5; t=$((t + 5))
  done
  if [ "$2" != keep ] && pkill -f "compare stress"; then
    echo "$(date +%T) stopped the groups still running after $limit s" >> "$out/stress-progress.txt"
  fi
  cat "$out/stress-progress.txt"; grep -h "done in" "$out"/stress-*.txt
}
case $part in
  lease)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt"
    mkdir -p "$out/sweep"; cp "$3" "$out/sweep/sweep.json"
    step 330 sweep-scaling python -m compare sweep scaling --backends quadrants,torch,numba \
      --scenarios projectile,particles --devices cuda --resume --out "$out/sweep" --no-plots
    tail -14 "$out/sweep-scaling.txt"
    # the longest first: PyTorch's eager descents (more than 9 minutes in the last lease)
    for g in 'cuda torch projectile-lr' 'cuda quadrants projectile-lr' \
             'cuda warp,torch,cupy,quadrants particles-inf,particles-divergence' \
             'cuda warp,torch,cupy,quadrants projectile-gradient' 'cpu,cuda numpy,quadrants ulps'; do
      start_group $g
    done
    sleep 2; echo "stress started"
    step 240 numba-tests python -m pytest -q -p no:cacheprovider -m numba tests/test_numba.py tests/test_parity.py
    tail -3 "$out/numba-tests.txt"
    left=$(( ${4:-540} - SECONDS )); [ "$left" -gt 0 ] || left=0
    wait_groups "$left" keep ;;
  wait) wait_groups "${3:-300}" "${4:-stop}" ;;
esac
[ -n "${OUT:-}" ] && tar czf "$OUT/$part.tgz" -C "$out" .
