//! `stratus-ingest`: GFS GRIB2 relative humidity → CloudMap (DESIGN §1). No GPU.
//!
//! # Layers
//!
//! Bottom first: a module uses only modules on its own line or on the lines above it.
//!
//! 1. `error`, `region`, `spline`, `output`, `input` — the bottom: typed errors and how messages show paths and numbers, the region and the one size rule, the spline, files written atomically and inputs read with a cap
//! 2. `grib`, `encode` — GRIB2: scanning, validating and decoding messages, and encoding them for fixtures
//! 3. `layer`, `cloud`, `lattice`, `sample` — the shared vocabulary: layer kinds and the rh_cr rule, cloud types, the structure lattice, the images' sample encodings
//! 4. `weather`, `ground`, `forecast` — the inputs: the weather and ground fields a forecast holds besides RH, and the forecast's RH levels
//! 5. `meta`, `structure`, `cloudmap` — the map: the sidecar schema, the structure images, the map with its PNG I/O and point probe
//! 6. `geotiff` — the writers' format: tiled, georeferenced GeoTIFF with overviews (the PNG writer is the pipeline's own)
//! 7. `pipeline` — forecast → map: the formula, the resampling plan, the band-streaming PNG and GeoTIFF writers, statistics
//! 8. `series`, `fetch` — on top: forecast series (steps, blending, advection) and downloading GFS runs
//! 9. `zarr` — the Zarr v3 store: a map or a series as one store xarray opens, written from the PNG set's maps and read back into them
//!
//! Pipeline: [`grib`] scans and validates messages and decodes only the RH (and gh) fields
//! needed → [`spline`] upsamples onto the region's pixel grid → [`pipeline`] applies the
//! critical-humidity formula per layer and writes the 16-bit RGBA PNG plus its [`meta`] sidecar,
//! or ([`geotiff`]) one tiled, georeferenced GeoTIFF with overviews; [`cloudmap`] loads a map
//! back.
//! Beside the coverage, [`weather`] derives per grid point and layer the cloud base and top
//! (GFS's cloud layer, the RH column, or the band), a WMO cloud type ([`cloud`]) and the layer
//! wind, which the pipeline samples onto the pixels of the [`lattice`] and stores in the images
//! [`structure`] describes, in the encodings of [`sample`] (sidecar format 3);
//! [`CloudMap::probe`] reads them back at a point. [`layer`] holds the layer kinds and their
//! critical-humidity rule every stage shares.
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

pub mod cloud;
pub mod cloudmap;
pub mod encode;
pub mod error;
pub mod fetch;
pub mod forecast;
pub mod geotiff;
pub mod grib;
pub mod ground;
pub mod input;
pub mod lattice;
pub mod layer;
pub mod meta;
pub mod output;
pub mod pipeline;
pub mod region;
pub mod sample;
pub mod series;
pub mod spline;
pub mod structure;
pub mod weather;
pub mod zarr;

pub use cloudmap::CloudMap;
pub use error::{IngestError, Result};
pub use layer::LayerKind;
pub use meta::{CloudMapMeta, LayerMeta};
pub use region::Region;
