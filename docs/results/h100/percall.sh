#!/usr/bin/env bash
# How the per-call rows (SAXPY n = 10^6, float32, CUDA, every framework and variant) and the
# gradient rows were remeasured on a lent H100 under the repeats protocol (issues 40 and 43): two runs one after
# the other (a, then b), each timing every cell in 6 worker processes in seeded rounds. A call may
# last 10 minutes, so the runs go on in the background (setsid) and each call waits up to WAIT
# seconds, then copies what is finished to $OUT:
#
#   device calls 1..N: bash .gpu/pK/install.sh   (the wheels the GPU image lacks: ../shared/gpu/stage-wheels)
#   device call N:     ... && COMMIT=$(git rev-parse HEAD) TREE=$(python -m compare.measuring.environment HEAD) \
#                      bash docs/results/h100/percall.sh start      (both expanded here)
#   (the device's copy of .git is stale: the records name COMMIT, via COMPARE_GIT_COMMIT, and say
#   clean only where the copy's files are the commit's, by the digest TREE: COMPARE_GIT_TREE)
#   next calls:        bash docs/results/h100/percall.sh          (until it says "ended")
# RUNS names the runs (default "a b"); they run in a copy of the tree (/root/tree), so that a later
# call's fresh copy of the working tree cannot change a module under a running worker.
set -u
W=/root/percall
WAIT=${WAIT:-540}
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 COMPARE_GIT_COMMIT=${COMMIT:-} COMPARE_GIT_TREE=${TREE:-}
# ROW picks the rows: percall (SAXPY n = 10^6, every variant), defaults, or gradients (the batched projectile
# at the scaling sweep's largest point: batch 2^20, hard contact, 20 iterations; both gradient rows).
case ${ROW:-percall} in
  percall) run="python -m compare run saxpy --devices cuda --precision float32 --variants all --processes 6 --no-plots" ;;
  gradients) run="python -m compare run projectile --devices cuda --precision float32 --set batch=1048576 --set contact=hard --set iters=20 --processes 6 --against none --no-plots" ;;
  # defaults: the four scenarios at their defaults, default variants (the accuracy and first-call rows)
  defaults) run="python -m compare all --devices cuda --precision float32 --processes ${PROCESSES:-3} --against none --no-plots" ;;
  *) echo "ROW: percall, gradients or defaults"; exit 2 ;;
esac
if [ "${1:-wait}" = start ]; then
  [ -n "${COMMIT:-}" ] && [ -n "${TREE:-}" ] || { echo "name the commit and its tree: COMMIT=<sha> TREE=<sha> bash $0 start"; exit 2; }
  mkdir -p "$W" && rm -rf /root/tree && mkdir /root/tree && tar -c --exclude=./.gpu . | tar -x --no-same-owner -C /root/tree
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$W/gpu.txt"
  script="cd /root/tree; export PYTHONPATH=/tmp/site:/root/tree; "
  for r in ${RUNS:-a b}; do script+="$run --out $W/$r; "; done
  setsid nohup bash -c "$script echo ALL-DONE" > "$W/log" 2>&1 &
  echo $! > "$W/pid"
fi
end=$((SECONDS + WAIT))
while kill -0 "$(cat "$W/pid")" 2>/dev/null && [ $SECONDS -lt $end ]; do sleep 5; done
kill -0 "$(cat "$W/pid")" 2>/dev/null && echo "still running" || echo "ended"
tar -czf "$OUT/percall.tgz" -C "$W" --exclude='*.npz' --exclude='*.png' --exclude='*.svg' . 2>/dev/null
tail -25 "$W/log"
