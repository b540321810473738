//! `stratus`: the renderer, the scorer and the window around a CloudMap made by
//! `stratus-ingest`. The command line lives in the binary (`src/main.rs`, `src/cmd/`), so
//! nothing here depends on clap or indicatif.
//!
//! # Layers
//!
//! Bottom first: a module uses only modules on its own line or on the lines above it.
//!
//! 1. `sun`, `picture` — the leaves: the Sun and Moon for a moment, PNG files written atomically
//! 2. `render` — the wgpu renderer: settings, targets, the stages of a frame and their shaders, and its embedding in a host's renderer
//! 3. `timeline`, `flight`, `follow`, `scenes`, `score`, `scaled` — what feeds or measures the renderer
//! 4. `scene`, `bench`, `app` — what commands start from: a `--map` opened once, the bench, the window
//! 5. `reprojection_bench`, `footprint_bench` — reprojection along a flight and pixel footprints against supersampling, with the bench's measures

pub mod app;
pub mod bench;
pub mod flight;
pub mod follow;
pub mod footprint_bench;
pub mod picture;
pub mod render;
pub mod reprojection_bench;
pub mod scaled;
pub mod scene;
pub mod scenes;
pub mod score;
pub mod sun;
pub mod timeline;
