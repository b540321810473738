//! The command line: one module per subcommand (its clap arguments and `run`), and the options
//! and parsers they share (`options`). Only the binary sees this module.

pub mod bench;
pub mod demo;
pub mod flight;
pub mod fly;
pub mod ingest;
pub mod inspect;
pub mod options;
pub mod render;
pub mod score;
