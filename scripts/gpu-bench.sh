#!/usr/bin/env bash
# The GPU figures for docs/performance.md, on a machine with a GPU (the device machine some
# sessions are lent). Usage, from the repository root, with a release binary built elsewhere:
#   bash scripts/gpu-bench.sh [path/to/stratus]     (default: target/release/stratus)
# Writes everything under $OUT (or ./gpu-bench-out): the adapter, `stratus bench` as a table and
# as JSON, and full-HD / 4K frame timings at every preset on the real GFS sample (timestamps are
# trusted on GPUs, so these are GPU times, not wall times). The frames themselves go to $RENDERS
# (default $OUT/renders): the device tool brings back at most 8 files from $OUT, so a device run
# sets RENDERS=/tmp/renders and keeps only the text and JSON in $OUT.
set -euo pipefail
cd "$(dirname "$0")/.."
S=${1:-target/release/stratus}
OUT=${OUT:-gpu-bench-out}
RENDERS=${RENDERS:-$OUT/renders}
mkdir -p "$OUT" "$RENDERS"
G=data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2
[ -e "$G" ] || G=data-samples/gfs-2011011012-f120-2p5.grib2

"$S" ingest "$G" --region 0,55,39,105 --size 1300x1100 --out "$RENDERS/ea.png" | tee "$OUT/ingest.txt"
"$S" bench | tee "$OUT/bench.md"
"$S" bench --json > "$OUT/bench.json"
# Every preset at full HD and 4K, marching every pixel and with reprojection (each frame after
# the first marches the preset's subset and reprojects the rest; the march time then spans the
# subset march and the reproject stage).
for size in 1920x1080 3840x2160; do
  for preset in fast balanced high reference; do
    for rp in off on; do
      echo "== $size $preset reprojection $rp" | tee -a "$OUT/frames.txt"
      "$S" render --map "$RENDERS/ea.json" --camera 35,74,12000 --heading 60 --pitch -15 \
        --size "$size" --preset "$preset" --reprojection "$rp" --timings --repeat 9 \
        --time 2011-01-15T06:40:00Z --out "$RENDERS/ea-$size-$preset-$rp.png" \
        2>&1 | tee -a "$OUT/frames.txt"
    done
  done
done
"$S" bench --reprojection --map "$RENDERS/ea.json" --chart "$RENDERS/reprojection.png" | tee "$OUT/reprojection.md"
"$S" score --map "$RENDERS/ea.json" --json > "$OUT/score.json"
echo "done: $OUT"
