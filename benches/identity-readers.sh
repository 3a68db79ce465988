#!/bin/bash
# Plans each input at 1 reader thread (the serial readers) and at 2 (the parallel ones),
# and compares the GeoJSON with every `timing*` key removed.
# Usage: benches/identity-readers.sh BINARY FILE [--poses F | --scan-column N] ...
BIN=$1; shift
OUT=/tmp/speed-ident; mkdir -p $OUT
strip() { python3 "$(dirname "$0")/strip_timings.py" "$1"; }
while [ $# -gt 0 ]; do
  f=$1; shift; extra=()
  if [ "$1" = "--poses" ]; then extra=(--poses "$2"); shift 2; fi
  if [ "$1" = "--scan-column" ]; then extra=(--scan-column "$2"); shift 2; fi
  for t in 1 2; do
    RAYON_NUM_THREADS=$t $BIN plan "$f" "${extra[@]}" -o $OUT/t$t.geojson -q || echo "FAIL $f t$t"
  done
  a=$(strip $OUT/t1.geojson | sha256sum); b=$(strip $OUT/t2.geojson | sha256sum)
  echo "$(basename $f): 1 thread vs 2: $( [ "$a" = "$b" ] && echo IDENTICAL || echo DIFFERENT ) $(stat -c %s $OUT/t1.geojson) bytes"
done
rm -rf $OUT
