#!/usr/bin/env bash
# What CI runs: formatting, lints, then every test. Run it before pushing.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release -- -D warnings
cargo test --workspace --release
