#!/usr/bin/env bash
# How this store's `compare publish` parts ran on a lent H100 (issue 28): the machine allows 10
# minutes a call and stays warm about 30 s after one, so the publish runs in the background and
# each call waits for it up to WAIT seconds (setsid: a call's end kills its process group), then copies what it has so far to $OUT:
#
#   device call 1..7: bash .gpu/pK/install.sh                (Warp, Taichi, quadrants wheels)
#   device call 7:    ... && bash docs/results/h100/publish.sh start
#   next calls:       bash docs/results/h100/publish.sh wait  (until publish.log says it ended)
#
# then, here: merge $OUT's results.json into docs/results/h100 (python -m compare report is not
# needed: a later record of a cell replaces the earlier one) and copy publish.json beside it.
set -u
W=/root/publish
WAIT=${WAIT:-540}
export PYTHONPATH=/tmp/site:$PWD
if [ "${1:-wait}" = start ]; then
  mkdir -p "$W"
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$W/gpu.txt"
  setsid nohup python -m compare publish --out "$W" --devices cuda --part all,large > "$W/publish.log" 2>&1 &
  sleep 1; pgrep -f "compare publish --out $W" | head -1 > "$W/pid"
fi
end=$((SECONDS + WAIT))
while kill -0 "$(cat "$W/pid")" 2>/dev/null && [ $SECONDS -lt $end ]; do sleep 5; done
kill -0 "$(cat "$W/pid")" 2>/dev/null && echo "publish still running" || echo "publish ended"
for f in results.json publish.json publish.log gpu.txt; do [ -f "$W/$f" ] && cp "$W/$f" "$OUT/"; done
tail -5 "$W/publish.log"
