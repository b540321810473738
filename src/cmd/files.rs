//! What a command may write to: checked before any work, so a bad output fails at once and
//! nothing is rendered for nothing. The rules are the ingest library's
//! ([`stratus_ingest::output`]): only absent or regular files are replaced, and never one of
//! the command's own inputs.

use std::path::{Path, PathBuf};

use stratus_ingest::output::{check_output, ensure_not_input};

/// Refuse `out` when it is not absent or a regular file, or is one of `inputs`.
pub fn check_out(out: &Path, inputs: &[PathBuf]) -> anyhow::Result<()> {
    check_output(out)?;
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    ensure_not_input(out, &inputs)?;
    Ok(())
}

/// The files a CloudMap (or a series) is read from: its sidecar and, as far as the sidecars
/// can be read, its images. (A sidecar that cannot be read fails the command when the map is
/// loaded.)
pub fn map_files(sidecar: &Path) -> Vec<PathBuf> {
    stratus_ingest::series::map_files(sidecar)
}
