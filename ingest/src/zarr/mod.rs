//! The Zarr v3 CloudMap store (`stratus ingest … --out STORE.zarr`, docs/zarr.md): one map or
//! a forecast series as one store that `xarray.open_zarr` opens with no extra code, and that
//! every `--map` command reads back into the same CloudMap the PNG set gives.
//!
//! - [`array`]: one Zarr v3 array — `zarr.json`, chunk keys, the `bytes` + `gzip` codecs
//!   (hand-written, not the `zarrs` crate: docs/zarr.md says why);
//! - [`vars`]: the variables — names, dimensions, CF attributes, and each plane taken from a
//!   CloudMap and put back (the PNG map's samples, so the two agree value for value);
//! - [`layout`]: which arrays a store holds (dimensions, shapes, chunks, CF attributes), its
//!   coordinates' values and the group's attributes, defined once for the writer and the
//!   Python package;
//! - [`read`]: [`Store::open`], a step's map whole or only the chunks around one point;
//! - [`write`]: a new store (staged, then renamed into place) and `--append` (under a lock:
//!   new chunks first, metadata last);
//! - [`motion`]: the motion between steps (`motion_u`, `motion_v`, `motion_scale`), the
//!   samples a PNG series' motion images hold, read back instead of estimated;
//! - [`batch`]: one store written by many processes (a Dask cluster): `--plan` (metadata
//!   for every step, from headers; the run's lock), `--step K`, `--motion K`, `--finish`.
//!
//! The group's attributes hold the run's CF attributes and, for this reader, the series
//! sidecar and every step's map sidecar ([`STEPS_ATTR`], [`SERIES_ATTR`]): what a PNG set keeps
//! in its JSON files.

pub mod array;
pub mod batch;
pub mod layout;
pub mod motion;
pub mod read;
pub mod vars;
pub mod write;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicU64;

use crate::error::IngestError;
use crate::meta::CloudMapMeta;
use crate::series::SeriesMeta;

pub use read::ReadStats;

/// The store's own format tag (group attribute `stratus_format`).
pub const STORE_FORMAT: &str = "stratus-zarr/1";
/// Group attribute: the series sidecar of the steps the store holds.
pub const SERIES_ATTR: &str = "stratus_series";
/// Group attribute: each step's map sidecar, in time order.
pub const STEPS_ATTR: &str = "stratus_steps";
/// Chunk side (pixels) of the lattice dimensions: 512 × 512 × one layer × one time, about
/// 512 KiB of 16-bit samples before compression (docs/zarr.md, "Chunks").
pub const CHUNK_SIDE: u64 = 512;

/// An opened store: its run, its steps' sidecars and its arrays' metadata, checked; chunks
/// are read when a map is asked for, and counted.
#[derive(Debug)]
pub struct Store {
    pub path: PathBuf,
    pub series: SeriesMeta,
    pub steps: Vec<CloudMapMeta>,
    arrays: BTreeMap<String, array::ArrayMeta>,
    bytes_read: AtomicU64,
    chunks_read: AtomicU64,
}

/// Whether `path` names a store: a folder named `*.zarr`, or a folder holding `zarr.json`.
pub fn is_store(path: &Path) -> bool {
    let named = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("zarr"));
    named || (path.is_dir() && path.join("zarr.json").is_file())
}

/// A store fault: one line naming the store (or its file) and what is wrong.
pub(crate) fn fault(path: &Path, msg: impl std::fmt::Display) -> IngestError {
    IngestError::series(path, msg)
}
