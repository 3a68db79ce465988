# syntax=docker/dockerfile:1
#
# The asbuilt image: one binary, run as `serve`, `serve --no-workers`, `worker` or `migrate`.
#   docker build -t asbuilt .
#   key=$(openssl rand -hex 16)
#   docker run -p 8080:8080 -e ASBUILT_API_KEYS="me:$key" -v asbuilt-data:/var/lib/asbuilt asbuilt
#   curl -H "Authorization: Bearer $key" http://127.0.0.1:8080/v1/jobs
# An API key is what lets the server listen beyond the container's own loopback: without one it
# runs in development mode, bound to 127.0.0.1 inside the container, and the port is unreachable.
# See deploy/README.md for the settings that matter; .ci/container.sh builds and runs this image.

# Build stage. Its cargo command is the one .ci/run runs on every change
# (tests/service/deploy_manifests.rs checks that they stay equal), so it is known to work.
# No default features: the image leaves out `asbuilt bench`, a developer's tool.
FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked --no-default-features --bin asbuilt

# Runtime stage: Debian slim plus the CA roots for TLS to S3; nothing is fetched at run time.
FROM debian:bookworm-slim AS runtime
# Debian's stable suite only receives security fixes, so the package is not pinned.
# hadolint ignore=DL3008
RUN apt-get update \
    && apt-get install -y --no-install-recommends ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && groupadd --system --gid 10001 asbuilt \
    && useradd --system --uid 10001 --gid 10001 --home-dir /var/lib/asbuilt --create-home \
        --shell /usr/sbin/nologin asbuilt
COPY --from=build /src/target/release/asbuilt /usr/local/bin/asbuilt
USER 10001:10001
WORKDIR /var/lib/asbuilt
ENV ASBUILT_LISTEN=0.0.0.0:8080 \
    ASBUILT_DATA_DIR=/var/lib/asbuilt \
    ASBUILT_LOG=info
VOLUME ["/var/lib/asbuilt"]
EXPOSE 8080
# `asbuilt healthcheck` asks ASBUILT_LISTEN for /healthz over loopback; workers serve it too.
HEALTHCHECK --interval=30s --timeout=5s --start-period=15s --retries=3 \
    CMD ["asbuilt", "healthcheck"]
ENTRYPOINT ["asbuilt"]
CMD ["serve"]
