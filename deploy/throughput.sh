#!/usr/bin/env bash
# Jobs per minute with 1, 2 and 4 worker processes sharing PostgreSQL and S3, on one cloud.
# The jobs are queued first; the clock runs from starting the workers (each process starting,
# checking the schema and claiming counts) until the last job finishes.
#
#   deploy/throughput.sh CLOUD [JOBS] [WORKER_COUNTS...]
#   deploy/throughput.sh /tmp/office/cloud.ply 12 1 2 4
#
# Needs ASBUILT_TEST_POSTGRES and ASBUILT_TEST_S3_ENDPOINT (source .ci/backends.sh) and a built
# binary (ASBUILT_BIN, default target/release/asbuilt). Extra flags for every process, such as
# `--fake-pipeline-ms 100 --fake-pipeline-spin` to time the queue alone, go in ASBUILT_FLAGS.
# POSES=FILE sends that pose sidecar with each cloud (multipart).
# Each run uses its own schema and prefix and removes them afterwards. Loopback only.
set -euo pipefail

cloud=${1:?usage: throughput.sh CLOUD [JOBS] [WORKER_COUNTS...]}
jobs=${2:-12}
shift $(( $# >= 2 ? 2 : 1 ))
counts=("$@")
[ ${#counts[@]} -gt 0 ] || counts=(1 2 4)
bin=${ASBUILT_BIN:-target/release/asbuilt}
pg=${ASBUILT_TEST_POSTGRES:?set ASBUILT_TEST_POSTGRES}
s3=${ASBUILT_TEST_S3_ENDPOINT:?set ASBUILT_TEST_S3_ENDPOINT}
read -r -a extra <<<"${ASBUILT_FLAGS:-}"

export PGOPTIONS=--client-min-messages=warning
export AWS_ENDPOINT=$s3 AWS_ALLOW_HTTP=true AWS_REGION=us-east-1
export AWS_ACCESS_KEY_ID=${AWS_ACCESS_KEY_ID:-asbuilt-test} AWS_SECRET_ACCESS_KEY=${AWS_SECRET_ACCESS_KEY:-asbuilt-test}
curl -s -o /dev/null -X PUT "$s3/asbuilt-throughput" || true
work=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

wait_ready() {
    for _ in $(seq 1 100); do
        curl -sf "http://127.0.0.1:$1/readyz" >/dev/null && return 0
        sleep 0.1
    done
    echo "port $1 never became ready" >&2
    return 1
}

for n in "${counts[@]}"; do
    schema="throughput_$(date +%s%N)"
    psql "$pg" -qc "CREATE SCHEMA $schema"
    db="$pg?options=-c%20search_path%3D$schema"
    storage="s3://asbuilt-throughput/$schema"
    "$bin" migrate --database-url "$db" 2>/dev/null
    common=(--database-url "$db" --storage "$storage" --workers 1 "${extra[@]}")
    "$bin" serve --no-workers --listen 127.0.0.1:18181 --data-dir "$work/api" "${common[@]}" \
        2>"$work/api.log" &
    pids=($!)
    wait_ready 18181

    # Queue every job first, so the timing below is the workers' alone (claim, download,
    # pipeline, results), not the uploads'.
    up_start=$(date +%s.%N)
    for _ in $(seq 1 "$jobs"); do
        if [ -n "${POSES:-}" ]; then
            curl -sf -o /dev/null -F "cloud=@$cloud" -F "poses=@$POSES" http://127.0.0.1:18181/v1/jobs
        else
            curl -sf -o /dev/null -X POST -T "$cloud" http://127.0.0.1:18181/v1/jobs
        fi
    done
    up_end=$(date +%s.%N)

    start=$(date +%s.%N)
    for i in $(seq 1 "$n"); do
        "$bin" worker --listen "127.0.0.1:$((18190 + i))" --data-dir "$work/w$i" "${common[@]}" \
            2>"$work/w$i.log" &
        pids+=($!)
    done
    while :; do
        done_=$(psql "$pg" -tAc "SELECT count(*) FROM $schema.jobs WHERE status IN ('succeeded','failed')")
        [ "$done_" -ge "$jobs" ] && break
        sleep 0.2
    done
    end=$(date +%s.%N)
    failed=$(psql "$pg" -tAc "SELECT count(*) FROM $schema.jobs WHERE status = 'failed'")
    awk -v n="$n" -v j="$jobs" -v s="$start" -v e="$end" -v f="$failed" -v us="$up_start" -v ue="$up_end" \
        'BEGIN { printf "%d worker(s): %d jobs in %.1f s = %.1f jobs/min (%d failed); queueing them took %.1f s\n", n, j, e - s, 60 * j / (e - s), f, ue - us }'

    # Deleting through the API removes each job's objects too.
    for id in $(psql "$pg" -tAc "SELECT id FROM $schema.jobs"); do
        curl -sf -o /dev/null -X DELETE "http://127.0.0.1:18181/v1/jobs/$id"
    done
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    pids=()
    psql "$pg" -qc "DROP SCHEMA $schema CASCADE"
done
