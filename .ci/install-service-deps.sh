#!/usr/bin/env bash
# What the service tests need beyond Rust: node + npm and Debian's chromium for the browser
# test (tests/service/browser.rs), and the pinned playwright-core from tests/browser/package-lock.json.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
command -v node >/dev/null || missing+=(nodejs)
command -v npm >/dev/null || missing+=(npm)
command -v chromium >/dev/null || missing+=(chromium)
# docs/integrating.md's walkthrough (tests/service/integrating.rs) runs curl and jq.
command -v curl >/dev/null || missing+=(curl)
command -v jq >/dev/null || missing+=(jq)
if [ ${#missing[@]} -gt 0 ]; then
    echo "== apt-get install ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}"
fi

echo "== npm ci (tests/browser)"
# playwright-core never downloads a browser; the test uses /usr/bin/chromium.
(cd tests/browser && npm ci --no-audit --no-fund)
