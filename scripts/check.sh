#!/usr/bin/env bash
# What CI runs, and the README's test command: install what is missing (scripts/deps.sh), then
# formatting, lints and every test. Run it before pushing.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
export RUST_LOG=${RUST_LOG:-warn}
# Mesa's device-select layer probes for a Wayland display and prints an "error" line where there
# is none; the tests pick their adapter themselves (the binary switches it off the same way).
export NODEVICE_SELECT=${NODEVICE_SELECT:-1}
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release -- -D warnings
cargo test --workspace --release
# The Python tests: xarray opens the Zarr stores the CLI writes (installs its deps, fails if it cannot).
bash scripts/python-tests.sh
