//! `stratus-ingest`: GFS GRIB2 relative humidity → CloudMap (DESIGN §1). No GPU.
//!
//! Pipeline: [`grib`] scans and validates messages and decodes only the RH (and gh) fields
//! needed → [`spline`] upsamples onto the region's pixel grid → [`cloudmap`] applies the
//! critical-humidity formula per layer and writes the 16-bit RGBA PNG plus its [`meta`] sidecar.

pub mod cloudmap;
pub mod encode;
pub mod error;
pub mod forecast;
pub mod grib;
pub mod meta;
pub mod pipeline;
pub mod region;
pub mod spline;

pub use cloudmap::CloudMap;
pub use error::{IngestError, Result};
pub use meta::{CloudMapMeta, LayerKind, LayerMeta};
pub use region::Region;
