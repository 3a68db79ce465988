#!/bin/bash
# Plans each input with two builds (before and after a change), at 1 and 2 reader threads,
# and compares the GeoJSON with every `timing*` key removed, and the `info` reports.
# Usage: benches/identity-binaries.sh BEFORE AFTER FILE [--poses F | --trajectory F | --scan-column N] ...
A=$1; B=$2; shift 2
OUT=$(mktemp -d)
strip() { python3 "$(dirname "$0")/strip_timings.py" "$1"; }
while [ $# -gt 0 ]; do
  f=$1; shift; extra=()
  case "$1" in --poses|--trajectory|--scan-column) extra=("$1" "$2"); shift 2 ;; esac
  for t in 1 2; do
    failed=0
    rm -f $OUT/A.* $OUT/B.*
    for b in A B; do
      bin=${!b}
      RAYON_NUM_THREADS=$t $bin plan "$f" "${extra[@]}" -o $OUT/$b.geojson -q || { echo "FAIL $b $f t$t"; failed=1; }
      RAYON_NUM_THREADS=$t $bin info "$f" "${extra[@]}" > $OUT/$b.info || { echo "FAIL info $b $f t$t"; failed=1; }
    done
    # A run that failed compares as nothing: two failures must not read as the same plan.
    if [ $failed = 1 ]; then
      echo "$f threads $t: FAILED"
      continue
    fi
    a=$(strip $OUT/A.geojson | sha256sum); b=$(strip $OUT/B.geojson | sha256sum)
    same=$( [ "$a" = "$b" ] && cmp -s $OUT/A.info $OUT/B.info && echo IDENTICAL || echo DIFFERENT )
    echo "$(basename $(dirname $f))/$(basename $f) threads $t: before vs after: $same ($(stat -c %s $OUT/A.geojson) bytes)"
  done
done
rm -rf $OUT
