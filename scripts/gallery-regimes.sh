#!/usr/bin/env bash
# Regenerate docs/gallery/regimes/: five cloud regimes from the real GFS sample (valid
# 2011-01-15 12 UTC, North Atlantic), each as one side-by-side PNG: the previous renderer
# (left, bands) and the present one (right, per-column base/top and per-genus profiles).
#
# The left halves were made with the renderer at commit 12472f1 (the cumulus shots': 5d97f77,
# the genus columns before the cumulus cells). Give that binary as OLD_STRATUS=/path/to/old/
# stratus (PREV_STRATUS for the cumulus shots) to re-render them too; without it, the left half
# of each existing picture is kept and only the right half is re-rendered.
# STRATUS=/path/to/stratus uses a prebuilt present renderer instead of `cargo build --release`.
# Usage: [OLD_STRATUS=...] [STRATUS=...] bash scripts/gallery-regimes.sh
set -euo pipefail
cd "$(dirname "$0")/.."
gfs=data-samples/gfs-2011011012-f120-2p5.grib2
out=docs/gallery/regimes
. scripts/gallery-setup.sh
old=${OLD_STRATUS:-}
# The new binary writes the map and its structure images; the old one reads the same map
# (it ignores the structure images and draws each layer as a band).
"$STRATUS" ingest "$gfs" --region 30,65,-60,10 --size 1024x512 --out "$tmp/natl.png" >/dev/null
# 13:40 UTC: local noon near 25°W; the Sun is about 18° up at 50°N in January.
time=2011-01-15T13:40:00Z

# shot NAME render-args...: right half always, left half with OLD_STRATUS only.
shot() {
  local name=$1; shift
  local old=${old_for_shot-$old}
  local args=(--map "$tmp/natl.json" --preset balanced --size 960x540 --time "$time" "$@")
  "$STRATUS" render "${args[@]}" --out "$tmp/after.png" 2> >(grep -v XDG_RUNTIME >&2)
  if [ -n "$old" ]; then
    "$old" render "${args[@]}" --out "$tmp/before.png" 2> >(grep -v XDG_RUNTIME >&2)
    python3 scripts/side-by-side.py "$out/$name.png" "$tmp/after.png" "$tmp/before.png"
  else
    python3 scripts/side-by-side.py "$out/$name.png" "$tmp/after.png"
  fi
}

# 1, 2: a stratocumulus overcast (46.5N 50W: low 1.0, 643-2432 m, nothing above), from 6 km
# above looking NNE and from the ground looking up 20°.
shot overcast-above --camera 46.0,-50.5,6000 --heading 20 --pitch -20
shot overcast-below --camera 46.5,-50.0,50 --heading 20 --pitch 20
# 3: cumulus, 45N 47.5W (low 0.72, 827-1585 m), from 3 km looking down 25°.
# 3b, 3c: the same field straight down, and scattered cumulus at 40.3N 40.5W (low 0.11,
# 1972-2517 m) from 3.8 km; with the renderer before the cumulus cells on the left.
old_for_shot=${PREV_STRATUS:-} shot cumulus --camera 44.8,-47.8,3000 --heading 30 --pitch -25
old_for_shot=${PREV_STRATUS:-} shot cumulus-nadir --camera 44.8,-47.8,3000 --heading 30 --pitch -89
old_for_shot=${PREV_STRATUS:-} shot cumulus-scattered --camera 40.3,-40.5,3800 --heading 30 --pitch -30
# 4: the cumulonimbus cluster at 49-51.5N 26-22W (towers through GFS's convective cloud under
# their anvils), from 1 km in the clear air at its south-western edge, looking NE and 12° up.
shot cumulonimbus --camera 49.4,-25.5,1000 --heading 40 --pitch 12
# 5: cirrus, 44N 3.5W (high 0.29, 10.1-12.9 km, nothing below), from 300 m (the ground there
# stands at 254 m since issue 14) looking N 30° up.
shot cirrus --camera 44.0,-3.5,300 --heading 0 --pitch 30
echo "gallery written to $out"
