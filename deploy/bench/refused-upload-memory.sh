#!/usr/bin/env bash
# A 2 GiB upload over a 1 GiB limit: 413 with a JSON body (a declared length is refused before
# any byte; a chunked body when the limit is crossed, then drained for up to 5 s so the client
# reads the answer), memory flat, nothing kept.
#   deploy/bench/refused-upload-memory.sh
set -euo pipefail
DIR=$(mktemp -d)
# A PLY header, then zeros: the server only recognises the format from the first bytes.
ply_of() { { printf 'ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n'; head -c "$1" /dev/zero; } >"$DIR/$2.ply"; }
ply_of $((2 << 30)) 2g
BIN=${ASBUILT_BIN:-target/release/asbuilt}
D=$(mktemp -d)
$BIN serve --data-dir $D --listen 127.0.0.1:18602 --workers 0 --max-upload 1G 2>$D/log &
PID=$!
trap 'kill $PID 2>/dev/null || true; rm -rf $D $DIR' EXIT
for _ in $(seq 50); do curl -sf http://127.0.0.1:18602/readyz >/dev/null && break; sleep 0.1; done
mem() { awk '/VmRSS|VmHWM/ {printf "%s %d MB  ", $1, $2/1024}' /proc/$PID/status; echo; }
echo "idle: $(mem)"
curl -sS -w "\n  declared: HTTP %{http_code}, sent %{size_upload} B in %{time_total} s  " -X POST -T "$DIR/2g.ply" http://127.0.0.1:18602/v1/jobs; mem
curl -sS -w "\n  chunked: HTTP %{http_code}, sent %{size_upload} B in %{time_total} s  " -X POST -T "$DIR/2g.ply" -H "Transfer-Encoding: chunked" http://127.0.0.1:18602/v1/jobs; mem
curl -sS -w "\n  chunked, no Expect: HTTP %{http_code}, sent %{size_upload} B in %{time_total} s  " -X POST -T "$DIR/2g.ply" -H "Transfer-Encoding: chunked" -H "Expect:" http://127.0.0.1:18602/v1/jobs; mem
curl -sS -w "\n  multipart: HTTP %{http_code}, sent %{size_upload} B in %{time_total} s  " -F cloud=@"$DIR/2g.ply" http://127.0.0.1:18602/v1/jobs; mem
echo "left in blobs: $(find $D/blobs -type f | wc -l) files"
curl -sS http://127.0.0.1:18602/metrics | grep rejected
