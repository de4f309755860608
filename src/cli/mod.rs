//! Subcommands of the `altrep` binary. Each subcommand lives in its own file with a
//! `clap::Args` struct and a `run` function; `src/main.rs` only dispatches.

pub mod capture;
pub mod cylinder;
pub mod demo;
pub mod ellipsoid_bench;
pub mod fit_bench;
pub mod parallax;
pub mod precompute;
pub mod pyramid;
pub mod slices;

/// Error type of the command-line layer: a message for the user, already formatted.
pub type CliResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;
