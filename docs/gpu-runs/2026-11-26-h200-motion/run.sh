#!/usr/bin/env bash
# Issue 31 on the device machine: the per-frame cost of the blend along the motion. The real
# +0/+6 h North Atlantic series ingested at 1024x512 (motion estimated at ingest), then the same
# view rendered at +3 h on the series (FLAG_BLEND: two steps, the motion lookups) and on the
# +0 h step map alone (no blend), GPU timestamps, median of 9. Usage from the repository root:
#   OUT=dir bash docs/gpu-runs/2026-11-26-h200-motion/run.sh [stratus]
set -uo pipefail
S=${1:-target/release/stratus}
OUT=${OUT:-gpu-motion-out}
R=/tmp/motion-renders
mkdir -p "$OUT" "$R"
(nvidia-smi -L; nproc) > "$OUT/gpu.txt" 2>&1
D=data-samples/gfs-series
/usr/bin/time -f "ingest wall %e s, max RSS %M KB" "$S" ingest "$D/gfs.t18z.pgrb2.2p50.f000" \
  "$D/gfs.t18z.pgrb2.2p50.f006" --region 30,70,-60,40 --size 1024x512 --out "$R/na.png" \
  > "$OUT/ingest.txt" 2>&1
python3 - "$R" <<'PY'
import json, sys
d = json.load(open(sys.argv[1] + "/na.json"))
for s in d["steps"]:
    s.pop("motion", None)
json.dump(d, open(sys.argv[1] + "/old.json", "w"))
PY
for size in 1920x1080 3840x2160; do
  for preset in balanced high; do
    for m in na na-f000 old; do
      echo "== $m $size $preset" >> "$OUT/frames.txt"
      /usr/bin/time -f "wall %e s" "$S" render --map "$R/$m.json" --camera 45,-3,250000 \
        --heading 45 --pitch -50 --size "$size" --preset "$preset" --reprojection off \
        --timings --repeat 9 --time 2015-09-12T21:00:00Z --out "$R/$m-$size-$preset.png" \
        >> "$OUT/frames.txt" 2>&1
    done
  done
done
echo done >> "$OUT/frames.txt"
