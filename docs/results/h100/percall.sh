#!/usr/bin/env bash
# How the per-call rows (SAXPY n = 10^6, float32, CUDA, every framework and variant) and the
# gradient rows were remeasured on a lent H100 under the repeats protocol (issues 40 and 43): two runs one after
# the other (a, then b), each timing every cell in 6 worker processes in seeded rounds. A call may
# last 10 minutes, so the runs go on in the background (setsid) and each call waits up to WAIT
# seconds, then copies what is finished to $OUT:
#
#   device calls 1..N: bash .gpu/pK/install.sh   (the wheels the GPU image lacks: ../shared/gpu/stage-wheels)
#   device call N+1:   COMMIT=$(git rev-parse HEAD) TREE=$(python -m compare.measuring.environment HEAD) \
#                      bash docs/results/h100/percall.sh start      (both expanded here)
#   (start in a call that carries no wheel part, with docs/results/*/results.json, sweep.json and
#   stress.json in the tree: a run judges its sitting against the quiet sittings those stores hold,
#   and a tree without them judges nothing; leave only the reports and evidence behind)
#   (the device's copy of .git is stale: the records name COMMIT, via COMPARE_GIT_COMMIT, and say
#   clean only where the copy's files are the commit's, by the digest TREE: COMPARE_GIT_TREE)
#   next calls:        bash docs/results/h100/percall.sh          (until it says "ended")
#   e.g. ROWS="gradients particles percall" RUNS=a PROCESSES=3 OVERLAP=auto
#   (3 processes give no 95 % interval of a median: such rows rank only past 1.6x; 6 is the least that does)
#   (issue 56, session 29: the rows its port changes touch, within the lease's time)
# RUNS names the runs (default "a b"); they run in a copy of the tree (/root/tree), so that a later
# call's fresh copy of the working tree cannot change a module under a running worker.
set -u
W=/root/percall
WAIT=${WAIT:-540}
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 COMPARE_GIT_COMMIT=${COMMIT:-} COMPARE_GIT_TREE=${TREE:-}
# ROWS picks the rows, run one after the other, each into its own folder under each run:
#   percall    SAXPY n = 10^6, float32, every variant (the per-call rows)
#   gradients  the batched projectile at the scaling sweep's largest point: batch 2^20, hard
#              contact, 20 iterations (both gradient rows); REPEAT timed calls (default 3)
#   particles  the particle loop at its defaults (n = 256) and at n = 2^24 (both particle rows)
#   defaults   the four scenarios at their defaults, default variants (accuracy, first call)
#   matrix     the four scenarios at their defaults, every variant, host profile: the publish
#              protocol's matrix part (accuracy, first call, per-call and particle rows from one run)
# VARIANTS (default: every variant but fast math, which no row ranks) and PROCESSES (default 6)
# apply to every row; OVERLAP (default 0) sets --overlap.
V=${VARIANTS:-nofast}
P="--processes ${PROCESSES:-6} --overlap ${OVERLAP:-0} --against none --no-plots"
row() {   # the command of row $1, for the variants $V
  local vs=$V
  case $1 in
    percall) echo "python -m compare run saxpy --devices cuda --precision float32 --variants \$(vs saxpy $vs) $P" ;;
    gradients) echo "python -m compare run projectile --devices cuda --precision float32 --set batch=1048576 --set contact=hard --set iters=20 --repeat ${REPEAT:-3} --variants \$(vs projectile $vs) $P" ;;
    particles) echo "python -m compare run particles --devices cuda --precision float32 --variants \$(vs particles $vs) $P" ;;
    particles-large) echo "python -m compare run particles --devices cuda --precision float32 --set n=16777216 --check-sample 4096 --variants \$(vs particles $vs) $P" ;;
    defaults) echo "python -m compare all --devices cuda --precision float32 $P" ;;
    matrix) echo "python -m compare all --devices cuda --precision float32 --variants all --host-profile 12 $P" ;;
    *) echo "ROWS: percall, gradients, particles, particles-large, defaults or matrix" >&2; exit 2 ;;
  esac
}
# every variant any backend offers for a scenario, fast math left out unless VARIANTS names them
# (SKIP: a comma-separated list of variants to leave out as well. Not on a published row: a row ranks
#  each framework's fastest variant, and session 29's SKIP=checkpoint,evaluated,step left out JAX's and
#  Dr.Jit's fastest gradient cells, evidence/session32)
vs() { if [ "$2" = nofast ]; then python -c "import backends,sys; skip={'fastmath',*sys.argv[2].split(',')}; print(','.join(sorted({v for b in backends.BACKENDS.values() for v in b.variants_for(sys.argv[1]) if v not in skip})))" "$1" "${SKIP:-}"; else echo "$2"; fi; }
if [ "${1:-wait}" = start ]; then
  [ -n "${COMMIT:-}" ] && [ -n "${TREE:-}" ] || { echo "name the commit and its tree: COMMIT=<sha> TREE=<sha> bash $0 start"; exit 2; }
  mkdir -p "$W" && rm -rf /root/tree && mkdir /root/tree && tar -c --exclude=./.gpu . | tar -x --no-same-owner -C /root/tree
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$W/gpu.txt"
  script="cd /root/tree; export PYTHONPATH=/tmp/site:/root/tree; $(declare -f vs); "
  for r in ${RUNS:-a b}; do for w in ${ROWS:-percall}; do script+="$(row $w) --out $W/$r/$w; "; done; done
  setsid nohup bash -c "$script echo ALL-DONE" > "$W/log" 2>&1 &
  echo $! > "$W/pid"
fi
end=$((SECONDS + WAIT))
while kill -0 "$(cat "$W/pid")" 2>/dev/null && [ $SECONDS -lt $end ]; do sleep 5; done
kill -0 "$(cat "$W/pid")" 2>/dev/null && echo "still running" || echo "ended"
tar -czf "$OUT/percall.tgz" -C "$W" --exclude='*.npz' --exclude='*.png' --exclude='*.svg' . 2>/dev/null
tail -25 "$W/log"
