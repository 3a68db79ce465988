#!/usr/bin/env bash
# p99 of GET /v1/jobs/{id} at 200 requests/s for 15 s while 4 real jobs run on 2 workers.
# The jobs are queued by an API-only server first; the measured server then starts on the same
# data directory with 2 workers, which claim them at once (the queue is durable).
#   asbuilt simulate --building office_3story --points 20000000 --out /tmp/big
#   CLOUD=/tmp/big/cloud.ply deploy/bench/status-latency.sh
# Needs a release build: cargo build --release --bin asbuilt --example load.
set -euo pipefail
CLOUD=${CLOUD:?set CLOUD to a point cloud file}
BIN=${ASBUILT_BIN:-target/release/asbuilt}
LOAD=${ASBUILT_LOAD:-target/release/examples/load}
D=$(mktemp -d)
up() { for _ in $(seq 100); do curl -sf http://127.0.0.1:18600/readyz >/dev/null && return; sleep 0.1; done; }
$BIN serve --data-dir $D --listen 127.0.0.1:18600 --no-workers 2>$D/log0 &
P0=$!; up
ids=()
for i in 1 2 3 4; do
  ids+=($(curl -sf -X POST -T "$CLOUD" "http://127.0.0.1:18600/v1/jobs?filename=big$i.ply" | python3 -c 'import json,sys;print(json.load(sys.stdin)["id"])'))
done
kill $P0; wait $P0 || true
$BIN serve --data-dir $D --listen 127.0.0.1:18600 --workers 2 2>$D/log &
PID=$!
trap 'kill $PID 2>/dev/null || true; rm -rf $D' EXIT
up
count() { curl -sf "http://127.0.0.1:18600/v1/jobs?status=$1" | python3 -c 'import json,sys;print(len(json.load(sys.stdin)["jobs"]))'; }
echo "start $(date +%T.%N): running=$(count running) queued=$(count queued)"
$LOAD http://127.0.0.1:18600 "/v1/jobs/${ids[3]}" 200 15
echo "end $(date +%T.%N): running=$(count running) queued=$(count queued) succeeded=$(count succeeded)"
grep VmHWM /proc/$PID/status
for id in "${ids[@]}"; do
  until curl -sf http://127.0.0.1:18600/v1/jobs/$id | python3 -c 'import json,sys;j=json.load(sys.stdin);sys.exit(0 if j["status"] in ("succeeded","failed") else 1)'; do sleep 0.5; done
  curl -sf http://127.0.0.1:18600/v1/jobs/$id | python3 -c 'import json,sys;j=json.load(sys.stdin);print(j["status"], j["started_at"], j["finished_at"], j["timings_ms"] and j["timings_ms"]["total"])'
done
uptime
