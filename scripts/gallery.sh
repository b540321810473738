#!/usr/bin/env bash
# Regenerate docs/gallery/ from the real GFS sample (data-samples/gfs): East Asia at 400 hPa (the
# paper's case) and with all layers; four views each: 10 km above the deck at noon and at
# dusk, inside the layer, and the horizon from the ground, placed where the map has broken cloud. Usage: bash scripts/gallery.sh [preset]
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-high}
gfs=data-samples/gfs/gfs.t12z.pgrbf120.2p5deg.grib2
out=docs/gallery
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"
cargo build --release -q
s=target/release/stratus
$s ingest "$gfs" --region 0,55,39,105 --size 1300x1100 --level 400 --rh-cr 0.65 --out "$tmp/ea400.png" >/dev/null
$s ingest "$gfs" --region 0,55,39,105 --size 1300x1100 --out "$tmp/eaall.png" >/dev/null
# Local solar noon at 80°E is 06:40 UTC; sunset at 36°N in mid-January about 12:00 UTC there.
noon=2011-01-15T06:40:00Z
dusk=2011-01-15T11:50:00Z
r() { $s render --preset "$preset" --size 960x540 "$@" 2> >(grep -v XDG_RUNTIME >&2); }
r --map "$tmp/ea400.json" --camera 33.0,78.0,17600 --heading 20 --pitch -25 --time $noon --out "$out/ea400-above-noon.png"
r --map "$tmp/ea400.json" --camera 33.0,78.0,17600 --heading 20 --pitch -25 --time $dusk --out "$out/ea400-above-dusk.png"
r --map "$tmp/ea400.json" --camera 36.2,80.9,7300 --heading 90 --pitch 0 --time $noon --out "$out/ea400-inside.png"
r --map "$tmp/ea400.json" --camera 34.8,80.0,ground+50 --heading 45 --pitch 12 --time $noon --out "$out/ea400-horizon-ground.png"
r --map "$tmp/eaall.json" --camera 35.0,74.0,26500 --heading 60 --pitch -15 --time $noon --out "$out/all-above-noon.png"
r --map "$tmp/eaall.json" --camera 35.0,74.0,26500 --heading 60 --pitch -15 --time $dusk --out "$out/all-above-dusk.png"
r --map "$tmp/eaall.json" --camera 37.5,81.0,5000 --heading 90 --pitch 0 --time $noon --out "$out/all-inside.png"
r --map "$tmp/eaall.json" --camera 40.0,76.0,ground+50 --heading 120 --pitch 10 --time $noon --out "$out/all-horizon-ground.png"
$s render --map "$tmp/eaall.json" --top-down --size 650x550 --preset "$preset" --out "$out/all-top-down.png"
python3 - "$tmp" "$out" <<'PY' 2>/dev/null || true
import sys
from PIL import Image
tmp, out = sys.argv[1], sys.argv[2]
a = Image.open(f"{tmp}/eaall.png")
a.convert("RGB").resize((650, 550)).save(f"{out}/all-cloudmap.png")
PY
echo "gallery written to $out"
