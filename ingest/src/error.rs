//! Typed errors of the ingest library. Each renders as one line naming the file and the fault.

use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum IngestError {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {msg}")]
    Grib { path: PathBuf, msg: String },
    #[error("no relative humidity in {path}; it holds: {holds}")]
    NoRelativeHumidity { path: PathBuf, holds: String },
    #[error("{path}: no relative humidity at {level} hPa; levels present: {present}")]
    LevelAbsent {
        path: PathBuf,
        level: f64,
        present: String,
    },
    #[error("bad region: {0}")]
    BadRegion(String),
    #[error("bad size: {0}")]
    BadSize(String),
    #[error("bad critical humidity: {0}")]
    BadRhCr(String),
    #[error("{path}: cannot write: {msg}")]
    Write { path: PathBuf, msg: String },
    #[error("{path}: bad CloudMap: {msg}")]
    BadCloudMap { path: PathBuf, msg: String },
}

pub type Result<T, E = IngestError> = std::result::Result<T, E>;
