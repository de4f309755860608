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
    // Every file the report may write, for any --only: checked before the sweeps, written into
    // a staging folder, renamed into place; those of an older run this one does not write go.
    let entries = ["report.json", "report.csv", "report.md"]
        .into_iter()
        .map(String::from)
        .chain(
            REPRESENTATIONS
                .iter()
                .flat_map(|r| ["csv", "svg", "png"].map(|ext| format!("{r}.{ext}"))),
        )
        .collect();
    let claim = crate::asset::OutputClaim::new(&args.out, "report", entries);
    claim.check()?;
    let params = ReportParams {
        quick: args.quick,
        only: args.only.clone(),
        mesh: args.mesh.clone(),
    };
    let report = run_report(&params, true)?;
    let staging = claim.begin()?;
    let written = write(&report, &staging)?;
    claim.commit()?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", markdown(&report));
        println!("\nwrote {} files to {}", written.len(), args.out.display());
    }
    Ok(())
}
