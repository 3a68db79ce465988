#!/usr/bin/env bash
# The end-to-end cases of crates/plan/tests/e2e.rs through the score example, one block of
# scores per case (IoU, boundary error, completeness, heights, watertightness, arc error).
#   cargo build --release -p asbuilt-plan --example score && benches/accuracy.sh
set -u
S=${ASBUILT_SCORE:-target/release/examples/score}
run() { echo "### $*"; "$S" "$@" 2>&1 | tail -n 20; }
run office_3story 1500000 12
run curved_lobby 600000 13 --noise 0.002
run rotated_l 400000 14
run rotated_l 400000 15 --no-poses
run office_3story 1500000 19 --no-poses
run curved_lobby 600000 20 --noise 0.002 --no-poses
run curved_lobby 600000 21 --registration 0.01,0.1
run rotated_l 400000 21 --registration 0.01,0.1
run office_3story 1200000 17 --registration 0.01,0.1
run curved_lobby 500000 18 --mobile
