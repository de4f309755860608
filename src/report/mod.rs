//! # Run time against error (docs/design.md §13, `altrep report`)
//!
//! For each representation, a sweep of its main parameters through the existing measurement
//! functions (nothing is re-measured here: each sweep calls the function the representation's
//! own command calls), gathered into one table of [`Point`]s: what a setting **costs**
//! (precompute time, bytes, shader steps) against what it **loses** (PSNR against the ray-cast or
//! ray-marched ground truth, or an error in the representation's own unit). [`write`](fn@write) stores the
//! table as CSV and JSON and draws one plot per representation ([`plot`]), SVG and PNG, with the
//! source documents' operating points marked.
//!
//! | representation | swept | measured by |
//! |---|---|---|
//! | `fit` | grid, λ, solver + preconditioner, tolerance | [`crate::fit::Fitter`] on `fit-bench`'s test function |
//! | `parallax` | views N, view size, bound kind | [`crate::parallax::measure_steps`], [`crate::parallax::measure_quality`] |
//! | `cylinder` | offset grid, λ, renderer (exact, fitted, hybrid, bounded) | [`crate::cylinder::sweep`], [`crate::cylinder::evaluate`] |
//! | `slices` | slice count (level), merge rule | [`crate::slices::measure`](fn@crate::slices::measure) |
//! | `octree` | leaf resolution, filter rule | the pipeline's octree build and measurement |
//! | `pyramid` | prefilter, lookup (mip, rip, fip, EWA) | [`crate::pyramid::measure_sweep`] |
//!
//! Cost: the default sweep takes a few minutes in release on 2 cores; [`ReportParams::quick`]
//! a few seconds (tests).

pub mod plot;
mod sweeps;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

pub use sweeps::{cylinder, fit, octree, parallax, pyramid, slices};

/// Errors of a report: a measurement that failed (its message), or a file that could not be
/// written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A sweep's measurement failed.
    #[error("{representation}: {message}")]
    Measure {
        /// The representation swept.
        representation: &'static str,
        /// The measurement's error.
        message: String,
    },
    /// A file could not be written.
    #[error("cannot write {}: {message}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A plot could not be drawn.
    #[error("plot {name}: {message}")]
    Plot {
        /// The plot.
        name: String,
        /// Why.
        message: String,
    },
    /// An unknown representation name.
    #[error("unknown representation '{0}': use {known}", known = REPRESENTATIONS.join(", "))]
    Unknown(String),
}

/// One sweep: the function measuring a representation's settings (see the table above).
type SweepFn = fn(&ReportParams) -> Result<RepresentationReport, ReportError>;

/// The report's one list of sweeps, in order: the names the command takes, its default, its
/// error message and [`run`] all come from it.
const SWEEPS: [(&str, SweepFn); 6] = [
    ("fit", |p| fit(p.quick)),
    ("parallax", |p| parallax(p.quick, p.mesh.as_deref())),
    ("cylinder", |p| cylinder(p.quick, p.mesh.as_deref())),
    ("slices", |p| slices(p.quick)),
    ("octree", |p| octree(p.quick)),
    ("pyramid", |p| pyramid(p.quick)),
];

/// The representations of the report, in order.
pub const REPRESENTATIONS: [&str; SWEEPS.len()] = {
    let mut names = [""; SWEEPS.len()];
    let mut i = 0;
    while i < SWEEPS.len() {
        names[i] = SWEEPS[i].0;
        i += 1;
    }
    names
};

/// What the report sweeps.
#[derive(Clone, Debug)]
pub struct ReportParams {
    /// A tiny sweep (seconds, for tests) instead of the default (minutes).
    pub quick: bool,
    /// Representations to sweep (names of [`REPRESENTATIONS`]). Default all.
    pub only: Vec<String>,
    /// The object of the parallax and cylinder sweeps: an OBJ file, or `None` for the
    /// procedural `truck` (parallax) and `pear` (cylinder).
    pub mesh: Option<PathBuf>,
}

impl Default for ReportParams {
    fn default() -> Self {
        Self {
            quick: false,
            only: REPRESENTATIONS.iter().map(|s| s.to_string()).collect(),
            mesh: None,
        }
    }
}

/// A cost axis of the plots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cost {
    /// Precompute time, milliseconds.
    PrecomputeMs,
    /// Bytes stored.
    Bytes,
    /// Shader work per fragment or lookup (steps, slices drawn, solver iterations, ns).
    Steps,
}

/// One measured setting: its parameters, its costs and its error.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Representation (`fit`, `parallax`, …).
    pub representation: &'static str,
    /// Series in the plots (what varies along a curve: "grid", "best c", "mip", …).
    pub series: String,
    /// The setting, short ("15×8×16", "N=8 64²", "box").
    pub label: String,
    /// Precompute time (ms), when the representation precomputes.
    pub precompute_ms: Option<f64>,
    /// Bytes stored.
    pub bytes: Option<f64>,
    /// Shader work, in the representation's [`RepresentationReport::steps_label`] unit.
    pub steps: Option<f64>,
    /// PSNR against the ground truth (dB), when images are compared.
    pub psnr_db: Option<f64>,
    /// Error in the representation's [`RepresentationReport::error_label`] unit.
    pub error: Option<f64>,
    /// Set when this setting is a source document's operating point: which one.
    pub operating_point: Option<String>,
}

impl Point {
    /// A point with no figure yet.
    pub fn new(
        representation: &'static str,
        series: impl Into<String>,
        label: impl Into<String>,
    ) -> Self {
        Self {
            representation,
            series: series.into(),
            label: label.into(),
            precompute_ms: None,
            bytes: None,
            steps: None,
            psnr_db: None,
            error: None,
            operating_point: None,
        }
    }

    /// The value of cost axis `c`.
    pub fn cost(&self, c: Cost) -> Option<f64> {
        match c {
            Cost::PrecomputeMs => self.precompute_ms,
            Cost::Bytes => self.bytes,
            Cost::Steps => self.steps,
        }
    }
}

/// A claim of a source document that is not one measured setting: drawn as a vertical line at
/// `value` on the panel of cost `cost`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Reference {
    /// The cost axis.
    pub cost: Cost,
    /// Where the line stands, in that axis' unit.
    pub value: f64,
    /// What the source claims.
    pub label: String,
}

/// One representation's sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RepresentationReport {
    /// Name (`fit`, `parallax`, …).
    pub name: &'static str,
    /// Title of the plot (what was swept, on which object).
    pub title: String,
    /// The error plotted: `"PSNR (dB)"` when images were compared, or the unit of
    /// [`Point::error`].
    pub error_label: String,
    /// Whether the plots use [`Point::psnr_db`] (higher is better) or [`Point::error`] (lower is
    /// better).
    pub uses_psnr: bool,
    /// Unit of [`Point::steps`].
    pub steps_label: String,
    /// Cost axes drawn, one panel each.
    pub panels: Vec<Cost>,
    /// Measured settings.
    pub points: Vec<Point>,
    /// Source claims drawn as lines.
    pub references: Vec<Reference>,
    /// Notes for the reader (how the figures were taken).
    pub notes: Vec<String>,
    /// Wall seconds the sweep took.
    pub seconds: f64,
}

impl RepresentationReport {
    /// The error value plotted for `p`.
    pub fn error_of(&self, p: &Point) -> Option<f64> {
        if self.uses_psnr { p.psnr_db } else { p.error }
    }

    /// The axis label of cost `c`.
    pub fn cost_label(&self, c: Cost) -> String {
        match c {
            Cost::PrecomputeMs => "precompute time (ms)".into(),
            Cost::Bytes => "bytes stored".into(),
            Cost::Steps => self.steps_label.clone(),
        }
    }
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Quick (tiny) sweep or default.
    pub quick: bool,
    /// Threads of the rayon pool.
    pub threads: usize,
    /// One entry per representation swept.
    pub representations: Vec<RepresentationReport>,
    /// Wall seconds of the whole report.
    pub seconds: f64,
}

/// Runs the sweeps `params` asks for, printing one line per representation to stderr when
/// `progress` is set. Errors: an unknown name, a failed measurement.
pub fn run(params: &ReportParams, progress: bool) -> Result<Report, ReportError> {
    for name in &params.only {
        if !REPRESENTATIONS.contains(&name.as_str()) {
            return Err(ReportError::Unknown(name.clone()));
        }
    }
    let t0 = Instant::now();
    let mut representations = Vec::new();
    for (name, sweep) in SWEEPS {
        if !params.only.iter().any(|n| n == name) {
            continue;
        }
        let t = Instant::now();
        let mut r = sweep(params)?;
        r.seconds = t.elapsed().as_secs_f64();
        if progress {
            eprintln!(
                "altrep report: {name}: {} settings in {:.1} s",
                r.points.len(),
                r.seconds
            );
        }
        representations.push(r);
    }
    Ok(Report {
        quick: params.quick,
        threads: rayon::current_num_threads(),
        representations,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The CSV header of [`csv`].
pub const CSV_HEADER: &str =
    "representation,series,label,precompute_ms,bytes,steps,psnr_db,error,operating_point";

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The points of `reports` as CSV ([`CSV_HEADER`]; empty fields where a figure does not apply).
pub fn csv<'a>(reports: impl IntoIterator<Item = &'a RepresentationReport>) -> String {
    let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in reports {
        for p in &r.points {
            s += &format!(
                "{},{},{},{},{},{},{},{},{}\n",
                p.representation,
                csv_field(&p.series),
                csv_field(&p.label),
                num(p.precompute_ms),
                num(p.bytes),
                num(p.steps),
                num(p.psnr_db),
                num(p.error),
                csv_field(p.operating_point.as_deref().unwrap_or("")),
            );
        }
    }
    s
}

/// A Markdown summary: per representation, its points as a table.
pub fn markdown(report: &Report) -> String {
    let num = |v: Option<f64>, d: usize| v.map_or("–".to_string(), |v| format!("{v:.d$}"));
    let mut s = format!(
        "# altrep report: run time against error\n\n{} sweep, {} threads, {:.1} s.\n",
        if report.quick { "quick" } else { "default" },
        report.threads,
        report.seconds
    );
    for r in &report.representations {
        s += &format!(
            "\n## {}\n\n{}\n\n![{}]({}.png)\n\n| series | setting | precompute ms | bytes | {} | {} | source point |\n|---|---|---|---|---|---|---|\n",
            r.name, r.title, r.name, r.name, r.steps_label, r.error_label
        );
        for p in &r.points {
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                p.series,
                p.label,
                num(p.precompute_ms, 1),
                num(p.bytes, 0),
                num(p.steps, 2),
                num(r.error_of(p), 3),
                p.operating_point.as_deref().unwrap_or("")
            );
        }
        for n in &r.notes {
            s += &format!("\n{n}\n");
        }
        for rf in &r.references {
            s += &format!(
                "\nSource claim: {} (at {:.3} on the {} axis).\n",
                rf.label,
                rf.value,
                r.cost_label(rf.cost)
            );
        }
    }
    s
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    std::fs::write(path, bytes).map_err(|e| ReportError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes `report.json`, `report.csv`, `report.md`, and per representation `NAME.csv`,
/// `NAME.svg` and `NAME.png` into `dir` (created). Returns the paths written.
pub fn write(report: &Report, dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::Write {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut written = Vec::new();
    let mut put = |name: String, bytes: &[u8]| -> Result<(), ReportError> {
        let path = dir.join(name);
        write_file(&path, bytes)?;
        written.push(path);
        Ok(())
    };
    let json = serde_json::to_vec_pretty(report).map_err(|e| ReportError::Write {
        path: dir.join("report.json"),
        message: e.to_string(),
    })?;
    put("report.json".into(), &json)?;
    put("report.csv".into(), csv(&report.representations).as_bytes())?;
    put("report.md".into(), markdown(report).as_bytes())?;
    for r in &report.representations {
        put(format!("{}.csv", r.name), csv([r]).as_bytes())?;
        put(format!("{}.svg", r.name), plot::svg(r)?.as_bytes())?;
        put(format!("{}.png", r.name), &plot::png(r)?)?;
    }
    Ok(written)
}
