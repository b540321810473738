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
# Its hashes are of content: a PNG's header and decoded pixels (not its text chunks, which carry
# the per-write image id), a JSON file without `image_id` and with the scratch folder's path
# replaced; every other file as it is.
python3 - "$w" docs > "$list" <<'PY'
import hashlib, json, pathlib, struct, sys, zlib

scratch, docs = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])

def png(b):
    i, head, data = 8, b"", b""
    while i < len(b):
        n = struct.unpack(">I", b[i:i + 4])[0]
        t, d = b[i + 4:i + 8], b[i + 8:i + 8 + n]
        head += d if t in (b"IHDR", b"PLTE") else b""
        data += d if t == b"IDAT" else b""
        i += 12 + n
    return head + zlib.decompress(data)

def js(b):
    def strip(j):
        if isinstance(j, dict):
            return {k: strip(v) for k, v in j.items() if k != "image_id"}
        if isinstance(j, list):
            return [strip(v) for v in j]
        return j
    text = json.dumps(strip(json.loads(b)), sort_keys=True)
    return text.replace(str(scratch), "SCRATCH").encode()

def content(p):
    b = p.read_bytes()
    return png(b) if p.suffix == ".png" else js(b) if p.suffix == ".json" else b

for base, names in ((docs, ("gallery", "sections")), (scratch, (".",))):
    for name in names:
        for p in sorted((base / name).rglob("*")):
            if p.is_file() and p.suffix != ".mp4" and (base is scratch or p.suffix == ".png"):
                rel = p.relative_to(base)
                print(hashlib.sha256(content(p)).hexdigest(), rel)
PY
echo "$(wc -l < "$list") files fingerprinted into $list"
