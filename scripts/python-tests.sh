#!/usr/bin/env bash
# The Python tests (tests/python, pytest): xarray opens the Zarr stores the CLI writes, and
# python -m stratus.batch writes them on a local Dask cluster (docs/zarr.md). Installs what it
# needs with pip (xarray, zarr >= 3, numpy, pytest, dask[distributed]; zarr 3
# needs Python >= 3.11). If they cannot be installed (no network, no pip) this fails loudly:
# it never skips.
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
# The binary `cargo test --release` built; built here only when missing.
[ -x target/release/stratus ] || cargo build --release --bin stratus
"$PY" -m pytest -q tests/python
