#!/usr/bin/env bash
# Installs what the tests need and a fresh Debian machine with Rust lacks: a Vulkan driver
# (Mesa's lavapipe, the CPU driver, when no GPU driver is installed), the Vulkan loader, Xvfb for
# the window test, GDAL's command-line tools (gdal-bin: the GeoTIFF test reads the file with a
# real GIS client), Python with pip (the Zarr store's xarray test), and rustfmt/clippy. Does nothing when all is there; needs root (or sudo) to
# install. Called by scripts/check.sh, so the README's test command is the whole set-up.
set -euo pipefail

need=()
if ! ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 && ! ls /etc/vulkan/icd.d/*.json >/dev/null 2>&1; then
  need+=(mesa-vulkan-drivers)
fi
ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1' || need+=(libvulkan1)
command -v Xvfb >/dev/null 2>&1 || need+=(xvfb)
dpkg -s libxkbcommon-x11-0 >/dev/null 2>&1 || need+=(libxkbcommon-x11-0)
command -v gdalinfo >/dev/null 2>&1 || need+=(gdal-bin)
# The Python tests (scripts/python-tests.sh) pip-install xarray and zarr: Python and pip first.
command -v python3 >/dev/null 2>&1 || need+=(python3)
python3 -m pip --version >/dev/null 2>&1 || need+=(python3-pip)

if [ ${#need[@]} -gt 0 ]; then
  echo "scripts/deps.sh: installing ${need[*]}" >&2
  sudo=()
  [ "$(id -u)" -eq 0 ] || sudo=(sudo)
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get update -qq
  "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

for c in rustfmt clippy; do
  rustup component list --installed 2>/dev/null | grep -q "^$c" || rustup component add "$c"
done
