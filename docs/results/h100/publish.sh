#!/usr/bin/env bash
# How this store's `compare publish` parts ran on a lent H100 (issues 28, 32): the machine allows
# 10 minutes a call and stays warm about 30 s after one, so the publish runs in the background and
# each call waits for it up to WAIT seconds (setsid: a call's end kills its process group), then
# copies what it has so far to $OUT:
#
#   device calls 1..N: bash .gpu/pK/install.sh   (wheels the GPU image lacks: ../shared/gpu/stage-wheels)
#   device call N:     ... && COMMIT=$(git rev-parse HEAD) TREE=$(python -m compare.measuring.environment HEAD) \
#                      bash docs/results/h100/publish.sh start "BACKENDS:PARTS" ...   (both expanded here)
#   (the device's copy of .git is stale: the records name COMMIT, via COMPARE_GIT_COMMIT, and publish
#   checks the copy's files against the digest TREE, COMPARE_GIT_TREE: commit first, nothing untracked)
#   (a later machine: unpack the last publish.tgz into .pubstate/ and carry it in that call)
#   (the unfinished error sweep's is kept in evidence/error-partial/: cp its sweep.json and publish.json into .pubstate/)
#   next calls:        bash docs/results/h100/publish.sh wait     (until it says "publish ended")
#   to cut the running part short (the next in the list then starts): publish.sh stop, then wait
#   (it interrupts `compare publish`, which records the part as cut off; a pattern that is not
#   anchored would match the device call's own shell, whose command line names it too)
#
# Each "BACKENDS:PARTS[:FLAGS]" argument is one `compare publish` run into the same --out, in order
# (FLAGS: more publish options, e.g. --allow-noisy-sitting); with no argument: all backends, parts all
# and large. A "chains:P,P|P,P|..." argument runs those parts' own commands (as `publish --list` prints
# them), each chain in order, the chains side by side, and waits for all: only for parts that rank no
# time (the stress experiments: verdicts, not timings), so they carry no sitting check, and publish's
# part stress-merge, named after them, merges what they wrote (issue 57, session 34). A stress experiment
# does not resume and a cut-off one is left out of the merge (session 45 lost a lease so): list the
# parts that resume first. Then, here: merge $OUT's results.json / sweep.json /
# stress.json into docs/results/h100 (a later record of a cell replaces the earlier one) and keep
# publish.json beside them.
# On an H200 lease (no H100 to be had) the same script runs the parts; what they wrote goes into
# docs/results/h200, a store of its own kind, never into this one (session 43).
set -u
W=/root/publish
WAIT=${WAIT:-540}
export PYTHONPATH=/tmp/site:/root/tree COMPARE_GIT_COMMIT=${COMMIT:-} COMPARE_GIT_TREE=${TREE:-} PYTHONUNBUFFERED=1
if [ "${1:-wait}" = stop ]; then
  pkill -INT -f '^python -m compare publish ' && echo "interrupted the running part" || echo "no part running"
  shift; set -- wait
fi
if [ "${1:-wait}" = start ]; then
  shift
  [ -n "${COMMIT:-}" ] && [ -n "${TREE:-}" ] || { echo "name the commit and its tree: COMMIT=<sha> TREE=<sha> bash $0 start ..."; exit 2; }
  mkdir -p "$W"
  # the parts run in a copy of the tree (/root/tree): a later call's fresh copy of the working tree
  # cannot change a module under a running worker
  rm -rf /root/tree && mkdir /root/tree && tar -c --exclude=./.gpu --exclude=./.pubstate . | tar -x --no-same-owner -C /root/tree
  # a carried .pubstate/ (an earlier machine's --out, unpacked) lets --resume skip what it finished
  [ -d .pubstate ] && cp -r .pubstate/. "$W"/ && rm -f "$W"/.*.lock
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$W/gpu.txt"
  [ "$#" -gt 0 ] || set -- "all:all,large"
  script="cd /root/tree; "
  for run in "$@"; do
    case $run in
      chains:*) script+="python -m compare publish --out $W --devices cuda --list > $W/parts.txt; "
                IFS='|' read -ra chains <<< "${run#chains:}"
                for c in "${chains[@]}"; do
                  script+="( for p in ${c//,/ }; do grep -A1 \"^  \$p: \" $W/parts.txt | tail -1 | bash; done ) & "
                done
                script+="wait; " ;;
      *) IFS=: read -r b parts flags <<< "$run"
         script+="python -m compare publish --out $W --devices cuda --backends $b --part $parts ${flags:-}; " ;;
    esac
  done
  setsid nohup bash -c "$script echo ALL-DONE" > "$W/publish.log" 2>&1 &
  echo $! > "$W/pid"
fi
end=$((SECONDS + WAIT))
while kill -0 "$(cat "$W/pid")" 2>/dev/null && [ $SECONDS -lt $end ]; do sleep 5; done
kill -0 "$(cat "$W/pid")" 2>/dev/null && echo "publish still running" || echo "publish ended"
cd "$W" && tar -czf "$OUT/publish.tgz" --exclude='*.npz' --exclude='*.png' --exclude='*.svg' . 2>/dev/null
tail -5 "$W/publish.log"
