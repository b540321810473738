//! One module per CLI subcommand: argument struct (clap) and `run`.

pub mod demo;
pub mod ingest;
pub mod inspect;
pub mod render;
pub mod score;
