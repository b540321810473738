//! `stratus`: the renderer, the scorer and the window around a CloudMap made by
//! `stratus-ingest`. The command line lives in the binary (`src/main.rs`, `src/cmd/`), so
//! nothing here depends on clap or indicatif.

pub mod app;
pub mod bench;
pub mod flight;
pub mod follow;
pub mod footprint_bench;
pub mod picture;
pub mod render;
pub mod reprojection_bench;
pub mod scaled;
pub mod scenes;
pub mod score;
pub mod sun;
pub mod timeline;
