# Sourced by the gallery scripts once they have set `out`: a temporary folder removed on exit,
# the output folder, and the renderer (STRATUS if given, else a release build of this checkout).
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"
if [ -z "${STRATUS:-}" ]; then
  cargo build --release -q
  STRATUS=target/release/stratus
fi
