//! `stratus`: the renderer, the scorer and the app around a CloudMap made by `stratus-ingest`.

pub mod cmd;
pub mod render;
pub mod score;
pub mod sun;
