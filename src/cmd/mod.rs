//! One module per CLI subcommand: argument struct (clap) and `run`.

pub mod bench;
pub mod demo;
pub mod flight;
pub mod fly;
pub mod ingest;
pub mod inspect;
pub mod render;
pub mod score;
