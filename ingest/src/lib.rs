//! `stratus-ingest`: GFS GRIB2 relative humidity → CloudMap (DESIGN §1). No GPU.
//!
//! Pipeline: [`grib`] scans and validates messages and decodes only the RH (and gh) fields
//! needed → [`spline`] upsamples onto the region's pixel grid → [`pipeline`] applies the
//! critical-humidity formula per layer and writes the 16-bit RGBA PNG plus its [`meta`] sidecar,
//! or ([`geotiff`]) one tiled, georeferenced GeoTIFF with overviews; [`cloudmap`] loads a map
//! back.
//! Beside the coverage, [`weather`] derives per grid point and layer the cloud base and top
//! (GFS's cloud layer, the RH column, or the band), a WMO cloud type and the layer wind, which
//! the pipeline samples onto the pixels and stores in the images [`structure`] describes
//! (sidecar format 3); [`CloudMap::probe`] reads them back at a point.
//!
//! Files: [`input`] reads every input with a cap; [`output`] writes atomically, never over
//! what is not a regular file or is an input, commits a map's PNG and sidecar as a pair, and
//! accounts for its temporary files.
//!
//! Under the clouds, [`ground`] holds the terrain and surface from the forecast's orography,
//! land cover, ice, snow and albedo, and the column's cloud water, on the structure lattice.
//!
//! [`fetch`] downloads the messages a GFS run's steps need by byte range, from the run's `.idx`
//! inventory, and validates each before writing a step's file.

pub mod cloudmap;
pub mod encode;
pub mod error;
pub mod fetch;
pub mod forecast;
pub mod geotiff;
pub mod grib;
pub mod ground;
pub mod input;
pub mod meta;
pub mod output;
pub mod pipeline;
pub mod region;
pub mod series;
pub mod spline;
pub mod structure;
pub mod weather;

pub use cloudmap::CloudMap;
pub use error::{IngestError, Result};
pub use meta::{CloudMapMeta, LayerKind, LayerMeta};
pub use region::Region;
