#!/usr/bin/env bash
# Regenerate docs/sections/: vertical sections of the rendered cloud through the places whose
# probe values docs/ingest.md checks against ecCodes (North Atlantic and western Pacific
# cumulonimbus, the overcast at 55°N 37.5°E, the cirrus at 45°N 5°W), from the real GFS sample.
# Usage: bash scripts/sections.sh [preset]
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-balanced}
gfs=data-samples/gfs-2011011012-f120-2p5.grib2
out=docs/sections
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"
cargo build --release -q
s=target/release/stratus
$s ingest "$gfs" --region 30,70,-60,40 --size 1600x640 --out "$tmp/natl.png" >/dev/null
$s ingest "$gfs" --region -10,30,120,180 --size 1200x800 --out "$tmp/wpac.png" >/dev/null
# c ARGS...: one section, 1000x400 unless size=WxH is set for the call.
c() { $s section --preset "$preset" --size "${size:-1000x400}" --time 2011-01-15T12:00:00Z "$@" 2> >(grep -v XDG_RUNTIME >&2); }
c --map "$tmp/natl.json" --from 50,-45 --to 50,-5 --top-m 14000 --out "$out/natl-cb-50n.png"
# Issue 13's towers: across the band of convective cells north of 50N, 25-22W, at 0.4 km a pixel.
size=800x300 c --map "$tmp/natl.json" --from 48.7,-23.5 --to 51.5,-24.5 --top-m 10000 --out "$out/natl-cb-towers.png"
c --map "$tmp/natl.json" --from 30,-25 --to 65,-25 --top-m 14000 --out "$out/natl-25w-meridian.png"
c --map "$tmp/natl.json" --from 55,20 --to 55,40 --top-m 12000 --out "$out/russia-overcast-55n.png"
c --map "$tmp/natl.json" --from 45,-20 --to 45,10 --top-m 15000 --out "$out/biscay-cirrus-45n.png"
c --map "$tmp/wpac.json" --from 5,140 --to 5,170 --top-m 19000 --out "$out/wpac-cb-5n.png"
c --map "$tmp/wpac.json" --from 5,137.5 --to 25,137.5 --top-m 19000 --out "$out/wpac-cb-137e.png"
for p in 50,-25 55,37.5 45,-5; do $s probe --map "$tmp/natl.json" --at $p; done
for p in 5,155 15,137.5; do $s probe --map "$tmp/wpac.json" --at $p; done
