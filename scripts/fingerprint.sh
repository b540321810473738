#!/usr/bin/env bash
# Checksums of everything Stratus produces, for a refactor that must change nothing (issue 29):
# every gallery script's pictures and the sections (written into docs/ as the scripts do; restore
# them with `git checkout docs/` afterwards), the demo, a map's PNG pair, a GeoTIFF, a 0.25°
# three-step series, a render and a section of that series between steps, probe --json, score
# --json, and a short headless flight. Run it on the code before and after and diff the lists.
# Usage: bash scripts/fingerprint.sh LIST.sha256   (uses target/release/stratus, built here)
set -euo pipefail
cd "$(dirname "$0")/.."
list=$(realpath -m "${1:?usage: fingerprint.sh LIST.sha256}")
cargo build --release -q
export STRATUS=target/release/stratus
S=$STRATUS
w=$(mktemp -d)
trap 'rm -rf "$w"' EXIT
quiet() { "$@" 2> >(grep -v XDG_RUNTIME >&2) >/dev/null; }

for g in gallery gallery-light gallery-regimes gallery-timelapse sections; do
  quiet bash "scripts/$g.sh"
done

gfs=data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2
pl=data-samples/gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25
quiet $S demo --out "$w/demo" --size 320x180
quiet $S ingest "$gfs" --region 30,65,-60,10 --size 512x256 --out "$w/natl.png"
quiet $S ingest "$gfs" --region 30,65,-60,10 --size 512x256 --out "$w/natl.tif"
quiet $S ingest "$pl.f000" "$pl.f006" "$pl.f012" --region 48,56,13,25 --size 240x160 --out "$w/pl.png"
quiet $S render --map "$w/pl.json" --time 2020-08-04T21:00:00Z --camera 52,19,9000 --heading 80 \
  --pitch -12 --size 320x180 --preset fast --out "$w/pl-render.png"
quiet $S section --map "$w/pl.json" --time 2020-08-04T21:00:00Z --from 52,14 --to 52,24 \
  --size 300x120 --out "$w/pl-section.png"
$S probe --map "$w/pl.json" --time 2020-08-04T21:00:00Z --at 52,19 --json > "$w/pl-probe.json"
$S probe --map "$w/natl.json" --at 52.5,-25 --json > "$w/natl-probe.json"
$S score --map "$w/natl.json" --json > "$w/natl-score.json" 2>/dev/null
quiet $S flight --map "$w/natl.json" --path docs/flights/natl-timelapse.json --out "$w/flight" \
  --size 160x90 --fps 0.1 --preset fast --exposure 0

# The listing names files relative to where they were made, so two runs compare line by line.
{
  (cd docs && find gallery sections -type f -name '*.png' -print0 | sort -z | xargs -0 sha256sum)
  (cd "$w" && find . -type f ! -name '*.mp4' -print0 | sort -z | xargs -0 sha256sum)
} > "$list"
echo "$(wc -l < "$list") files fingerprinted into $list"
