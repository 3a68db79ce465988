#!/usr/bin/env bash
# Rooms (and windows) rows of every class with truth rooms, with poses and without.
S=${ASBUILT_SCORE:-target/release/examples/score}
for mode in "" --no-poses; do
  for args in "square_room 300000 11" "office_3story 1500000 12" "curved_lobby 600000 13 --noise 0.002" "rotated_l 400000 14" "attic_house 600000 31" "mezzanine_hall 600000 32" "dense_office 1140000 33" "dense_office_voxels 4000000 34" "ceiling_only 300000 35" "partitions 400000 36"; do
    out=$($S $args $mode 2>&1)
    echo "$out" | grep -E "^(rooms|windows|row) "
    echo "$out" | grep -oE '\("rooms", [0-9]+\)' | sed "s/^/time $args $mode /"
  done
done
