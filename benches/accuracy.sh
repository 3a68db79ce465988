#!/usr/bin/env bash
# The end-to-end cases of crates/plan/tests/e2e.rs through the score example, one block of
# scores per case (IoU, boundary error, completeness, heights, watertightness, arc error).
#   cargo build --release -p asbuilt-plan --example score && benches/accuracy.sh
#   (benches/accuracy.sh | grep "^row" prints the table alone)
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
run curved_lobby 500000 18 --mobile --no-poses
run curved_lobby 500000 18 --mobile --plain

# Every simulated class in the three modes of issue 15: with poses, with scan ids (and times)
# but no poses, and plain x, y, z shuffled. `row |` lines form the table (class, mode, stories
# found/true (+ invented), worst IoU, worst boundary p95 m, worst completeness at 5 cm, worst
# floor/ceiling error m, derived cell size, OGC-valid and watertight, viewpoint source, share
# of the open area that viewpoint evidence forced inside).
for mode in "" --no-poses --plain; do
  run square_room 300000 11 $mode
  run office_3story 1500000 12 $mode
  run curved_lobby 600000 13 --noise 0.002 $mode
  run rotated_l 400000 14 $mode
  run attic_house 600000 31 $mode
  run mezzanine_hall 600000 32 $mode
  run dense_office 1140000 33 $mode
  run dense_office_voxels 4000000 34 $mode
  run ceiling_only 300000 35 $mode
  run partitions 400000 36 $mode
done

# A mobile scan of the office at two densities, in the three modes: at 1.5 M points the plan
# breaks even with the trajectory (issue 12, "any density"); at 5 M it holds.
for points in 1500000 5000000; do
  for mode in "" --no-poses --plain; do
    run office_3story $points 23 --mobile $mode
  done
done
