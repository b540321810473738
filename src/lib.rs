//! `stratus`: the renderer, the scorer and the app around a CloudMap made by `stratus-ingest`.

pub mod app;
pub mod bench;
pub mod cmd;
pub mod flight;
pub mod render;
pub mod score;
pub mod sun;
