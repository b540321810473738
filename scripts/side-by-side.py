"""A gallery pair: the previous renderer's view (left) beside the present one's (right), 8 px of
white between. Usage: side-by-side.py OUT AFTER [BEFORE]. Without BEFORE the left half is taken
from OUT as it stands (the previous renderer is not rebuilt for every regeneration)."""
import sys

from PIL import Image

out, after = sys.argv[1], Image.open(sys.argv[2]).convert("RGB")
if len(sys.argv) > 3:
    before = Image.open(sys.argv[3]).convert("RGB")
else:
    try:
        before = Image.open(out).convert("RGB").crop((0, 0, after.width, after.height))
    except FileNotFoundError:
        sys.exit(f"no {out} to take the left half from: set OLD_STRATUS")
pair = Image.new("RGB", (before.width + 8 + after.width, after.height), (255, 255, 255))
pair.paste(before, (0, 0))
pair.paste(after, (before.width + 8, 0))
pair.save(out, optimize=True)
print(out)
