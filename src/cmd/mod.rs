//! One module per CLI subcommand: argument struct (clap) and `run`.

pub mod ingest;
pub mod inspect;
pub mod render;
