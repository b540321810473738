#!/usr/bin/env bash
# Regenerate docs/gallery/light/: the light, sky and ground of issue 14 on the real GFS sample
# (valid 2011-01-15 12 UTC), each view beside the previous renderer's (left).
#
# The left halves were made with the renderer at commit ba64ff5 (before issue 14). Give that
# binary as OLD_STRATUS=/path/to/old/stratus to re-render them too; without it, the left half of
# each existing picture is kept and only the right half is re-rendered.
# STRATUS=/path/to/stratus uses a prebuilt present renderer instead of `cargo build --release`.
# Usage: [OLD_STRATUS=...] [STRATUS=...] bash scripts/gallery-light.sh
set -euo pipefail
cd "$(dirname "$0")/.."
gfs=data-samples/gfs-2011011012-f120-2p5.grib2
out=docs/gallery/light
. scripts/gallery-setup.sh
old=${OLD_STRATUS:-}
"$STRATUS" ingest "$gfs" --region 30,65,-60,10 --size 1024x512 --out "$tmp/natl.png" >/dev/null
"$STRATUS" ingest "$gfs" --level 400 --region 0,55,39,105 --size 1300x1100 --out "$tmp/ea400.png" >/dev/null

# shot NAME MAP TIME render-args...: right half always, left half with OLD_STRATUS only (the
# old renderer has no `ground` camera altitudes: such views give it the metres instead, OLDCAM).
shot() {
  local name=$1 map=$2 time=$3; shift 3
  local args=(--map "$tmp/$map.json" --preset balanced --size 960x540 --time "$time")
  "$STRATUS" render "${args[@]}" "$@" --out "$tmp/after.png" 2> >(grep -v XDG_RUNTIME >&2)
  if [ -n "$old" ]; then
    local old_args=("$@")
    [ -n "${OLDCAM:-}" ] && old_args=("${@/${NEWCAM:-}/$OLDCAM}")
    "$old" render "${args[@]}" "${old_args[@]}" --out "$tmp/before.png" 2> >(grep -v XDG_RUNTIME >&2)
    python3 scripts/side-by-side.py "$out/$name.png" "$tmp/after.png" "$tmp/before.png"
  else
    python3 scripts/side-by-side.py "$out/$name.png" "$tmp/after.png"
  fi
}

noon=2011-01-15T13:40:00Z   # local noon near 25°W: the Sun 17° up at 52.5°N
# 1, 2: the overcast at 52.5N 25W (cwat 0.86 kg/m²) from below and from above.
shot overcast-below natl $noon --camera 52.5,-25,50 --heading 180 --pitch 25
shot overcast-above natl $noon --camera 52.0,-25.5,12000 --heading 30 --pitch -25
# 3: dusk at 44N 3.5W looking east, the Sun just below the horizon behind the camera.
NEWCAM=44,-3.5,ground+2 OLDCAM=44,-3.5,260 \
  shot dusk-east natl 2011-01-15T17:00:00Z --camera 44,-3.5,ground+2 --heading 90 --pitch 4
# 3b: the Earth's shadow: over the clear Balearic Sea (38N 1E) looking east 20 minutes after
# sunset (Sun 3-4° down), at a fixed exposure 8 stops over daylight's (auto exposure keeps dusk
# dark, as a camera would). The old renderer had no such exposure scale: it gets its own default.
"$STRATUS" render --map "$tmp/natl.json" --preset balanced --size 960x540 --time 2011-01-15T17:20:00Z \
  --camera 38,1,ground+2 --heading 90 --pitch 8 --exposure 8 --out "$tmp/after.png" 2> >(grep -v XDG_RUNTIME >&2)
if [ -n "$old" ]; then
  "$old" render --map "$tmp/natl.json" --preset balanced --size 960x540 --time 2011-01-15T17:20:00Z \
    --camera 38,1,2 --heading 90 --pitch 8 --out "$tmp/before.png" 2> >(grep -v XDG_RUNTIME >&2)
  python3 scripts/side-by-side.py "$out/earth-shadow.png" "$tmp/after.png" "$tmp/before.png"
else
  python3 scripts/side-by-side.py "$out/earth-shadow.png" "$tmp/after.png"
fi
# 4: night, the waxing gibbous Moon 68° up in the south-south-east.
NEWCAM=44,-3.5,ground+2 OLDCAM=44,-3.5,260 \
  shot night-moon natl 2011-01-15T20:00:00Z --camera 44,-3.5,ground+2 --heading 156 --pitch 40
# 4b: the Moon itself through a 2° field of view (10.8 days old, 85 % lit), at a fixed exposure
# 6 stops over daylight's: the night's adapted exposure leaves the disc a white blot.
NEWCAM=44,-3.5,ground+2 OLDCAM=44,-3.5,260 \
  shot moon-phase natl 2011-01-15T20:00:00Z --camera 44,-3.5,ground+2 --heading 155.6 --pitch 67.23 --fov 2 --exposure 6
# 5: the 400 hPa cloud over Tibet from 1.5 km above the plateau's southern rim, looking north.
NEWCAM=30.5,84,ground+1500 OLDCAM=30.5,84,6500 \
  shot tibet ea400 2011-01-15T06:00:00Z --camera 30.5,84,ground+1500 --heading 0 --pitch 8
# 6: broken cloud and its shadows on the sea west of Ireland from 14 km, looking down.
shot shadows natl $noon --camera 50,-20,14000 --heading 200 --pitch -35
# The section through Tibet along 85°E: the cloud over the terrain.
"$STRATUS" section --map "$tmp/ea400.json" --from 25,85 --to 40,85 --size 900x300 --top-m 12000 \
  --out "$out/tibet-section.png" 2> >(grep -v XDG_RUNTIME >&2)
echo "gallery written to $out"
