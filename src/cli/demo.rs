//! `altrep demo` (being written).
use super::CliResult;
/// Arguments of `altrep demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {}
/// Runs `altrep demo`.
pub fn run(_args: DemoArgs) -> CliResult {
    Err("not built yet".into())
}
