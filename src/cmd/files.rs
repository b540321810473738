//! What a command may write to: checked before any work, so a bad output fails at once and
//! nothing is rendered for nothing, and the output folders it creates. The rules are the
//! ingest library's ([`stratus_ingest::output`], the program's one file-commit module): only
//! absent or regular files are replaced, never one of the command's own inputs, and a folder
//! a run created is removed again when it is left empty by an error or a signal.

use std::path::{Path, PathBuf};

use anyhow::Context;
use stratus_ingest::error::shown;
use stratus_ingest::output::{check_output, ensure_not_input};

/// Refuse `out` when it is not absent or a regular file, or is one of `inputs`.
pub fn check_out(out: &Path, inputs: &[PathBuf]) -> anyhow::Result<()> {
    check_output(out)?;
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    ensure_not_input(out, &inputs)?;
    Ok(())
}

/// Create the output folder `out` and any missing parents; returns the folders created,
/// outermost first, each removed on a signal if still empty
/// ([`stratus_ingest::output::create_folder`]); on an error the command removes them
/// ([`stratus_ingest::output::remove_if_empty`]).
pub fn create_folder(out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    stratus_ingest::output::create_folder(out)
        .with_context(|| format!("{}: cannot create", shown(out)))
}
