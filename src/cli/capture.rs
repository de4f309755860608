//! `altrep capture` (being written).
use super::CliResult;
/// Arguments of `altrep capture`.
#[derive(clap::Args, Debug)]
pub struct CaptureArgs {}
/// Runs `altrep capture`.
pub fn run(_args: CaptureArgs) -> CliResult {
    Err("not built yet".into())
}
