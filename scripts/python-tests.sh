#!/usr/bin/env bash
# The Python tests (tests/python, pytest): xarray opens the Zarr stores the CLI writes
# (docs/zarr.md), python -m stratus.batch writes them on a local Dask cluster, and the Python
# package (`pip install ./python`, docs/python.md) equals the CLI. Installs what it needs with
# pip (xarray, zarr >= 3, numpy, pytest, dask[distributed], maturin; zarr 3 needs Python >=
# 3.11), then builds and installs the package from python/ (a release build in target/,
# reusing what `cargo test --workspace --release` built). If anything cannot be installed or
# built (no network, no pip) this fails loudly: it never skips.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "python-tests: $("$PY" --version 2>&1) is older than 3.11, which zarr 3 needs" >&2
    exit 1
fi
have() {
    "$PY" - <<'PYEOF'
import importlib.metadata as m, sys
try:
    import dask, distributed, numpy, pytest, xarray, zarr  # noqa: F401
except ImportError:
    sys.exit(1)
sys.exit(int(m.version("zarr").split(".")[0]) < 3)
PYEOF
}
if ! have; then
    echo "python-tests: installing xarray, zarr>=3, numpy, pytest, dask[distributed] with pip" >&2
    if ! "$PY" -m pip install --quiet --break-system-packages 'xarray' 'zarr>=3' numpy pytest 'dask[distributed]'; then
        "$PY" -m pip install --quiet 'xarray' 'zarr>=3' numpy pytest 'dask[distributed]' || {
            echo "python-tests: FAILED to install the Python test dependencies (is PyPI reachable?)" >&2
            exit 1
        }
    fi
    have || { echo "python-tests: the dependencies are still not importable" >&2; exit 1; }
fi
# pip >= 23 refuses a system Python without --break-system-packages; older pips lack the flag.
bsp=()
"$PY" -m pip install --help 2>/dev/null | grep -q -- --break-system-packages && bsp=(--break-system-packages)
pipi() { "$PY" -m pip install --quiet "${bsp[@]}" "$@"; }
if ! "$PY" -c 'import maturin' 2>/dev/null; then
    echo "python-tests: installing maturin with pip" >&2
    pipi 'maturin>=1.7,<2' || {
        echo "python-tests: FAILED to install maturin (is PyPI reachable?)" >&2
        exit 1
    }
fi
# The package, built here from python/ (no build isolation: the maturin above, no download).
t0=$(date +%s)
pipi --no-build-isolation --force-reinstall --no-deps ./python || {
    echo "python-tests: FAILED to build and install the Python package (pip install ./python)" >&2
    exit 1
}
echo "python-tests: pip install ./python took $(( $(date +%s) - t0 )) s" >&2
"$PY" -c 'import stratus' || { echo "python-tests: the package does not import" >&2; exit 1; }
# The binary `cargo test --release` built; built here only when missing.
[ -x target/release/stratus ] || cargo build --release --bin stratus
"$PY" -m pytest -q tests/python
