#!/usr/bin/env bash
# CI: the image, built and run. Called by .ci/run after the release build.
#
# No Docker engine and no registry of base images are reachable here, so podman builds the
# Dockerfile's runtime stage around the release binary CI just built, on a Debian base made with
# debootstrap from Debian's package mirror. Then the image is run and checked: it runs as its own
# non-root user, its HEALTHCHECK passes, a simulated scan plans end to end through the published
# port, and the job and its plan survive a new container on the same volume.
#
# The debootstrap base is cached as a tarball in $ASBUILT_CI_CACHE (default
# /var/cache/asbuilt-ci, rebuilt after 7 days) and podman's own layer cache keeps the rest; with
# neither, the script starts cold.
set -euo pipefail
cd "$(dirname "$0")/.."

export CONTAINERS_CONF="$PWD/.ci/containers.conf"
bin="${CARGO_TARGET_DIR:-target}/release/asbuilt"
cache="${ASBUILT_CI_CACHE:-/var/cache/asbuilt-ci}"
mirror="${ASBUILT_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
suite=bookworm
base_tar="$cache/debian-$suite-minbase.tar"
base_image="localhost/asbuilt-ci-base:$suite-slim"
image="localhost/asbuilt:ci"
start=$SECONDS
step() { echo "== container: $* (+$((SECONDS - start)) s)"; }
fail() { echo "container check failed: $*" >&2; exit 1; }

[ -x "$bin" ] || fail "$bin is missing: run the release build first"

missing=()
command -v podman >/dev/null || missing+=(podman)
command -v runc >/dev/null || missing+=(runc)
command -v debootstrap >/dev/null || missing+=(debootstrap)
command -v curl >/dev/null || missing+=(curl)
if [ ${#missing[@]} -gt 0 ]; then
    step "apt-get install ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

work="$(mktemp -d)"
volume="asbuilt-ci-$$"
names=("asbuilt-ci-$$-a" "asbuilt-ci-$$-b" "asbuilt-ci-$$-c" "asbuilt-ci-$$-idle")
cleanup() {
    for n in "${names[@]}"; do podman rm -f -v -t 2 "$n" >/dev/null 2>&1 || true; done
    podman volume rm -f "$volume" >/dev/null 2>&1 || true
    rm -rf "$work"
}
trap cleanup EXIT

# ----- the base: Debian minbase, slimmed the way Debian's -slim images are -----
if [ ! -s "$base_tar" ] || [ -n "$(find "$base_tar" -mtime +7 2>/dev/null)" ]; then
    step "debootstrap $suite (cold)"
    mkdir -p "$cache"
    rootfs="$work/rootfs"
    debootstrap --variant=minbase "$suite" "$rootfs" "$mirror" >"$work/debootstrap.log" 2>&1 \
        || { tail -30 "$work/debootstrap.log"; fail "debootstrap"; }
    # What the -slim images leave out; dpkg keeps leaving it out for later installs.
    cat >"$rootfs/etc/dpkg/dpkg.cfg.d/docker-slim" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/locale/*
EOF
    find "$rootfs/usr/share/doc" -mindepth 1 -not -name copyright -not -type d -delete
    find "$rootfs/usr/share/doc" -mindepth 1 -type d -empty -delete
    rm -rf "$rootfs"/usr/share/{man,groff,info,lintian,linda,locale}/*
    # Debian's images keep apt's caches and downloaded packages out of every layer.
    cat >"$rootfs/etc/apt/apt.conf.d/docker-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
Acquire::Languages "none";
Acquire::GzipIndexes "true";
EOF
    cat >"$rootfs/etc/apt/sources.list" <<EOF
deb $mirror $suite main
deb $mirror $suite-updates main
deb ${mirror%/debian}/debian-security $suite-security main
EOF
    rm -rf "$rootfs"/var/cache/apt/*.bin "$rootfs"/var/cache/apt/archives/*.deb \
        "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/log/*.log "$rootfs"/var/log/apt/* \
        "$rootfs"/etc/resolv.conf "$rootfs"/etc/hostname
    tar --numeric-owner -C "$rootfs" -cf "$base_tar.tmp" .
    mv "$base_tar.tmp" "$base_tar"
    rm -rf "$rootfs"
fi
base_sum="$(sha256sum "$base_tar" | cut -c1-16)"
if [ "$(podman image inspect --format '{{index .Labels "asbuilt.base"}}' "$base_image" 2>/dev/null)" != "$base_sum" ]; then
    step "import the base"
    old_base="$(podman image inspect --format '{{.Id}}' "$base_image" 2>/dev/null || true)"
    podman import --change 'CMD ["bash"]' --change "LABEL asbuilt.base=$base_sum" \
        --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
        "$base_tar" "$base_image" >/dev/null
    [ -z "$old_base" ] || podman rmi "$old_base" >/dev/null 2>&1 || true
fi

# ----- the image: the Dockerfile's runtime stage, verbatim but for its base -----
step "build the image"
grep -qx 'FROM debian:bookworm-slim AS runtime' Dockerfile \
    || fail "the runtime stage is no longer debian:bookworm-slim; make the base to match"
ctx="$work/context"
mkdir -p "$ctx"
cp "$bin" "$ctx/asbuilt"
# The build stage is CI's own release build (the same cargo command, tests/service/deploy_manifests.rs).
{
    echo "FROM scratch AS build"
    echo "LABEL asbuilt.ci=build-stage"
    echo "COPY asbuilt /src/target/release/asbuilt"
    sed -n '/^FROM debian:bookworm-slim AS runtime$/,$p' Dockerfile \
        | sed "1s|^FROM debian:bookworm-slim |FROM $base_image |"
} >"$ctx/Containerfile"
old_image="$(podman image inspect --format '{{.Id}}' "$image" 2>/dev/null || true)"
# Docker format keeps HEALTHCHECK (OCI image configs have no place for it). The host network
# only serves the RUN step's apt-get.
podman build --quiet --format docker --pull=never --network host -t "$image" \
    -f "$ctx/Containerfile" "$ctx" >"$work/build.log" 2>&1 \
    || { tail -40 "$work/build.log"; fail "podman build"; }
new_image="$(podman image inspect --format '{{.Id}}' "$image")"
# The build stage's image is only a carrier for the binary; drop the ones no longer tagged.
podman image prune -f --filter label=asbuilt.ci=build-stage >/dev/null
if [ -n "$old_image" ] && [ "$old_image" != "$new_image" ]; then
    podman rmi "$old_image" >/dev/null 2>&1 || true
fi
podman image inspect "$image" >"$work/image.json"
python3 - "$work/image.json" <<'EOF'
import json, sys
img = json.load(open(sys.argv[1]))[0]
cfg = img["Config"]
hc = img.get("Healthcheck") or {}
assert cfg.get("User") == "10001:10001", f"image user: {cfg.get('User')!r}"
assert hc.get("Test") == ["CMD", "asbuilt", "healthcheck"], f"HEALTHCHECK lost: {hc!r}"
assert cfg.get("Entrypoint") == ["asbuilt"] and cfg.get("Cmd") == ["serve"], cfg
print(f"image {img['Id'][:12]}: {img['Size'] / 1e6:.1f} MB, user {cfg['User']}, healthcheck {hc['Test']}")
EOF
echo "binary in the image: $(stat -c %s "$bin") bytes"

# ----- running it -----
secret="ci-$(head -c 16 /dev/urandom | od -An -tx1 | tr -d ' \n')"
podman volume create "$volume" >/dev/null
port=""
# run NAME [podman run options]: a server on the volume, answering /healthz on 127.0.0.1:$port.
run() {
    local name="$1"
    shift
    # Keys make the server listen on every address, so the published port reaches it. Without
    # systemd podman cannot schedule the HEALTHCHECK itself and says so on stderr; the checks
    # below run it with `podman healthcheck run`.
    podman run -d --name "$name" -p 127.0.0.1::8080 -v "$volume:/var/lib/asbuilt" \
        -e ASBUILT_API_KEYS="ci:$secret" "$@" "$image" >/dev/null 2>>"$work/podman.log" \
        || { cat "$work/podman.log"; fail "podman run $name"; }
    port="$(podman port "$name" 8080/tcp | head -1)"
    port="${port##*:}"
    for _ in $(seq 1 60); do
        curl -sf "http://127.0.0.1:$port/healthz" >/dev/null && return 0
        [ "$(podman inspect --format '{{.State.Running}}' "$name")" = true ] \
            || { podman logs "$name"; fail "$name exited"; }
        sleep 0.5
    done
    podman logs "$name"
    fail "$name does not answer /healthz on 127.0.0.1:$port"
}
# stop NAME: SIGTERM, as an orchestrator stops it, then the container is removed.
stop() {
    podman stop -t 20 "$1" >/dev/null 2>>"$work/podman.log"
    podman rm "$1" >/dev/null 2>>"$work/podman.log"
}
healthy() {
    podman healthcheck run "$1" >/dev/null 2>&1 || fail "$1: the HEALTHCHECK fails"
    [ "$(podman inspect --format '{{.State.Health.Status}}' "$1")" = healthy ] \
        || fail "$1: not healthy after its HEALTHCHECK"
}
api() { curl -sS -f -H "Authorization: Bearer $secret" "$@"; }
field() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])' "$@"; }
# submit DIR: a job for the simulated scan in DIR (cloud + poses as multipart); prints its id.
submit() {
    api -F "cloud=@$1/cloud.ply" -F "poses=@$1/poses.json" "http://127.0.0.1:$port/v1/jobs" >"$work/job.json"
    field "$work/job.json" id
}
status() {
    api "http://127.0.0.1:$port/v1/jobs/$1" >"$work/job.json"
    field "$work/job.json" status
}
# planned JOB DIR NAME: waits for JOB to succeed, fetches its results and checks the plan
# against DIR's truth: as many stories, each within 2 % of the true area.
planned() {
    local st=""
    for _ in $(seq 1 240); do
        st="$(status "$1")"
        case "$st" in succeeded | failed | cancelled) break ;; esac
        sleep 0.5
    done
    [ "$st" = succeeded ] || { cat "$work/job.json"; podman logs "$3" | tail -20; fail "job $1: $st"; }
    api "http://127.0.0.1:$port/v1/jobs/$1/plan.geojson" -o "$work/$1.geojson"
    api "http://127.0.0.1:$port/v1/jobs/$1/plan.svg" -o /dev/null
    api "http://127.0.0.1:$port/v1/jobs/$1/plan.dxf" -o /dev/null
    python3 - "$work/$1.geojson" "$2/truth.json" <<'EOF'
import json, sys
def stories(path):
    fc = json.load(open(path))
    return [f["properties"]["area_m2"] for f in fc["features"] if f["properties"].get("kind") == "story"]
plan, truth = stories(sys.argv[1]), stories(sys.argv[2])
assert len(plan) == len(truth), (plan, truth)
for p, t in zip(plan, truth):
    assert abs(p - t) / t < 0.02, f"story area {p:.2f} m² against {t:.2f} m² of truth"
print("plan: stories of " + ", ".join(f"{p:.2f} m² (truth {t:.2f})" for p, t in zip(plan, truth)))
EOF
}

step "run a server"
run "${names[0]}"
healthy "${names[0]}"
pid="$(podman inspect --format '{{.State.Pid}}' "${names[0]}")"
uid="$(stat -c %u "/proc/$pid")"
user="$(podman exec "${names[0]}" id -un)"
if [ "$uid" != 10001 ] || [ "$user" != asbuilt ]; then
    fail "the server runs as uid $uid ($user), not asbuilt (10001)"
fi
echo "HEALTHCHECK healthy; the server runs as uid $uid ($user) (the host's /proc/$pid)"
[ "$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/v1/jobs")" = 401 ] \
    || fail "the published port answers without a key"
# The HEALTHCHECK can fail: the same image with nothing listening is unhealthy.
podman run -d --name "${names[3]}" --entrypoint sleep "$image" 60 >/dev/null 2>>"$work/podman.log"
! podman healthcheck run "${names[3]}" >/dev/null 2>&1 || fail "HEALTHCHECK passes with no server"
podman rm -f -v -t 0 "${names[3]}" >/dev/null 2>>"$work/podman.log"

step "plan a simulated scan through 127.0.0.1:$port"
"$bin" simulate --building rotated_l --points 300000 --out "$work/scan1" >/dev/null
"$bin" simulate --building square_room --points 200000 --out "$work/scan2" >/dev/null
job1="$(submit "$work/scan1")"
planned "$job1" "$work/scan1" "${names[0]}"
plan_sum="$(sha256sum <"$work/$job1.geojson")"

step "a new container on the same volume, API only: job $job1 is still there; a new job waits"
stop "${names[0]}"
run "${names[1]}" -e ASBUILT_WORKERS=0
healthy "${names[1]}"
[ "$(status "$job1")" = succeeded ] || fail "job $job1 after the restart: $(status "$job1")"
[ "$(api "http://127.0.0.1:$port/v1/jobs/$job1/plan.geojson" | sha256sum)" = "$plan_sum" ] \
    || fail "job $job1's plan changed across containers"
job2="$(submit "$work/scan2")"
sleep 1
[ "$(status "$job2")" = queued ] || fail "job $job2 on a server without workers: $(status "$job2")"

step "a third container with workers plans the queued job $job2"
stop "${names[1]}"
run "${names[2]}"
planned "$job2" "$work/scan2" "${names[2]}"
[ "$(status "$job1")" = succeeded ] || fail "job $job1 in the third container: $(status "$job1")"
echo "both jobs and their plans outlived the containers that made them"
step "done"
