//! `altrep report` — run time against error for every representation (docs/design.md §13): sweeps,
//! CSV, JSON and plots (SVG, PNG) with the source documents' operating points marked. See
//! [`crate::report`].

use std::path::PathBuf;

use crate::report::{REPRESENTATIONS, ReportParams, markdown, run as run_report, write};

use super::CliResult;

/// Arguments of `altrep report`.
#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Output folder: report.json, report.csv, report.md, and per representation NAME.csv,
    /// NAME.svg, NAME.png.
    #[arg(long, default_value = "altrep-out/report")]
    pub out: PathBuf,
    /// Print the report as JSON on standard output (instead of the Markdown tables).
    #[arg(long)]
    pub json: bool,
    /// A tiny sweep (seconds; for tests) instead of the default (minutes).
    #[arg(long)]
    pub quick: bool,
    /// Representations to sweep, comma-separated.
    #[arg(long, value_delimiter = ',', default_values = REPRESENTATIONS)]
    pub only: Vec<String>,
    /// Mesh (.obj, .gltf or .glb) for the parallax and cylinder sweeps (default: the procedural truck and pear).
    #[arg(long)]
    pub mesh: Option<PathBuf>,
}

/// Runs `altrep report`.
pub fn run(args: ReportArgs) -> CliResult {
    for name in &args.only {
        if !REPRESENTATIONS.contains(&name.as_str()) {
            return Err(crate::report::ReportError::Unknown(name.clone()).into());
        }
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    super::precompute::check_writable(&args.out.join("report.json"))?;
    let params = ReportParams {
        quick: args.quick,
        only: args.only.clone(),
        mesh: args.mesh.clone(),
    };
    let report = run_report(&params, true)?;
    let written = write(&report, &args.out)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", markdown(&report));
        println!("\nwrote {} files to {}", written.len(), args.out.display());
    }
    Ok(())
}
