#!/usr/bin/env bash
# How long a running real pipeline takes to stop after DELETE, by the stage it is in.
#   asbuilt simulate --building office_3story --points 20000000 --out /tmp/big
#   CLOUD=/tmp/big/cloud.ply deploy/bench/cancel-latency.sh
set -euo pipefail
CLOUD=${CLOUD:?set CLOUD to a point cloud file}
BIN=${ASBUILT_BIN:-target/release/asbuilt}
D=$(mktemp -d)
ASBUILT_LOG=info $BIN serve --data-dir $D --listen 127.0.0.1:18603 --workers 1 2>$D/log &
PID=$!
trap 'kill $PID 2>/dev/null || true; rm -rf $D' EXIT
for _ in $(seq 50); do curl -sf http://127.0.0.1:18603/readyz >/dev/null && break; sleep 0.1; done
for stage in read stories samples label; do
  id=$(curl -sf -X POST -T "$CLOUD" http://127.0.0.1:18603/v1/jobs | python3 -c 'import json,sys;print(json.load(sys.stdin)["id"])')
  until [ "$(curl -sf http://127.0.0.1:18603/v1/jobs/$id | python3 -c 'import json,sys;print(json.load(sys.stdin)["stage"])')" = "$stage" ]; do sleep 0.02; done
  t0=$(date +%s.%N)
  curl -sf -o /dev/null -X DELETE http://127.0.0.1:18603/v1/jobs/$id
  until grep -q "\(cancelled or taken over\|job succeeded\).*job=$id" <(sed 's/\x1b\[[0-9;]*m//g' $D/log) ; do sleep 0.02; done
  t1=$(date +%s.%N)
  awk -v s="$t0" -v e="$t1" -v st="$stage" 'BEGIN { printf "cancelled in %-8s stopped after %.2f s\n", st, e - s }'
done
