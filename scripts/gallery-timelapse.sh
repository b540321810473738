#!/usr/bin/env bash
# Regenerate docs/gallery/timelapse/: a 6 h time-lapse of the real GFS series (run 2015-09-12
# 18 UTC, steps +0 h and +6 h) over the North Atlantic and Europe, from a fixed camera above the
# Bay of Biscay looking north-east (docs/flights/natl-timelapse.json): one frame per simulated
# 10 minutes (37 frames), the two steps blended on the GPU along the motion between them.
#
# The Sun is held (--sun-dir) and the exposure fixed, so that only the weather changes: over
# these 6 h the real Sun sets over Europe (the whole view would go dark).
# Needs the series in data-samples/gfs-series/ and python3 with PIL.
# STRATUS=/path/to/stratus uses a prebuilt renderer instead of `cargo build --release`.
# Usage: [STRATUS=...] bash scripts/gallery-timelapse.sh
set -euo pipefail
cd "$(dirname "$0")/.."
series=data-samples/gfs-series/gfs.t18z.pgrb2.2p50
out=docs/gallery/timelapse
. scripts/gallery-setup.sh
"$STRATUS" ingest "$series.f000" "$series.f006" --region 30,70,-60,40 --size 1024x512 \
  --out "$tmp/na.png" >/dev/null
# fps 1 over the path's 36 s: frame i is at +10·i minutes.
"$STRATUS" flight --map "$tmp/na.json" --path docs/flights/natl-timelapse.json \
  --out "$tmp/frames" --size 480x270 --fps 1 --preset balanced \
  --sun-dir 0.5,-0.5,0.7 --exposure 0 2> >(grep -v XDG_RUNTIME >&2)

python3 - "$tmp/frames" "$out" <<'PY'
import sys
from pathlib import Path
from PIL import Image, ImageDraw

frames, out = Path(sys.argv[1]), Path(sys.argv[2])
shots = sorted(frames.glob("frame-*.png"))
assert len(shots) == 37, f"expected 37 frames, got {len(shots)}"

def label(i):
    m = 18 * 60 + 10 * i
    return f"{(m // 60) % 24:02d}:{m % 60:02d} UTC (+{i * 10 // 60} h {i * 10 % 60:02d})"

imgs = []
for i, p in enumerate(shots):
    im = Image.open(p).convert("RGB")
    d = ImageDraw.Draw(im)
    d.rectangle((4, 4, 150, 20), fill=(0, 0, 0))
    d.text((8, 6), label(i), fill=(255, 255, 255))
    imgs.append(im)

# Contact sheet: every third frame (every 30 simulated minutes), 4 across, at half size.
pick = imgs[::3]
tw, th, cols = 240, 135, 4
rows = (len(pick) + cols - 1) // cols
sheet = Image.new("RGB", (cols * tw, rows * th), (20, 20, 20))
for k, im in enumerate(pick):
    sheet.paste(im.resize((tw, th), Image.LANCZOS), ((k % cols) * tw, (k // cols) * th))
sheet.save(out / "contact-sheet.png", optimize=True)

# The animation: one palette for all frames (no flicker between frames' palettes).
pal = imgs[len(imgs) // 2].quantize(colors=128, method=Image.MEDIANCUT)
gif = [im.quantize(palette=pal, dither=Image.Dither.NONE) for im in imgs]
gif[0].save(out / "timelapse.gif", save_all=True, append_images=gif[1:], duration=150,
            loop=0, optimize=True)
for name in ("contact-sheet.png", "timelapse.gif"):
    print(out / name, (out / name).stat().st_size, "bytes")
PY
