#!/usr/bin/env bash
# The server's memory while 1 GiB and 2 GiB clouds stream in (raw with a length, chunked and
# multipart): VmRSS idle, then VmHWM of each upload alone (the mark is reset between them).
#   deploy/bench/upload-memory.sh      (needs 3 GiB free in TMPDIR and 9 GiB for the blobs)
set -euo pipefail
DIR=$(mktemp -d)
# A PLY header, then zeros: the server only recognises the format from the first bytes.
ply_of() { { printf 'ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n'; head -c "$1" /dev/zero; } >"$DIR/$2.ply"; }
ply_of $((1 << 30)) 1g
ply_of $((2 << 30)) 2g
BIN=${ASBUILT_BIN:-target/release/asbuilt}
D=$(mktemp -d)
$BIN serve --data-dir $D --listen 127.0.0.1:18601 --workers 0 --max-upload 8G 2>$D/log &
PID=$!
trap 'kill $PID 2>/dev/null || true; rm -rf $D $DIR' EXIT
for _ in $(seq 50); do curl -sf http://127.0.0.1:18601/readyz >/dev/null && break; sleep 0.1; done
mem() { awk '/VmRSS|VmHWM/ {printf "%s %d MB  ", $1, $2/1024}' /proc/$PID/status; echo; }
# Reset the high-water mark so each step is measured on its own (Linux: write 5 to clear_refs).
reset() { echo 5 > /proc/$PID/clear_refs; }
echo "idle: $(mem)"
for f in 1g 2g; do
  reset
  curl -sS -o /dev/null -w "raw $f: HTTP %{http_code} %{size_upload} B in %{time_total} s  " -X POST -T "$DIR/$f.ply" http://127.0.0.1:18601/v1/jobs; mem
  reset
  curl -sS -o /dev/null -w "chunked $f: HTTP %{http_code} %{size_upload} B in %{time_total} s  " -X POST -T "$DIR/$f.ply" -H "Transfer-Encoding: chunked" http://127.0.0.1:18601/v1/jobs; mem
  reset
  curl -sS -o /dev/null -w "multipart $f: HTTP %{http_code} %{size_upload} B in %{time_total} s  " -F cloud=@"$DIR/$f.ply" http://127.0.0.1:18601/v1/jobs; mem
done
du -sh $D/blobs
