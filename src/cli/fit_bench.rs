//! `altrep fit-bench`: the trilinear least-squares fit on a piecewise-smooth test function with
//! a discontinuity and undefined regions — one table per solver, one per λ, optional JSON,
//! dense reference and MatrixMarket export (for `bench/scipy_compare.py`).

use std::path::PathBuf;
use std::time::Instant;

use altrep_solvers::{BlockedCsr, Method, PreconditionerKind, SolveParams, io, solve};
use serde_json::json;

use super::{CliResult, parse_sizes};
use crate::fit::{
    DEFAULT_LAMBDA, DENSE_MAX_NODES, DesignMatrix, FitParams, FitSamples, Fitter, TrilinearGrid,
    dense_min_norm, error_stats,
};
use crate::stats::{EvenMedian, median};

/// Arguments of `altrep fit-bench`.
#[derive(clap::Args, Debug)]
pub struct FitBenchArgs {
    /// Coarse grid cells `AxxAyxAz`.
    #[arg(long, default_value = "15x8x16", value_parser = parse_sizes)]
    pub grid: [usize; 3],
    /// Fine sample grid `NxxNyxNz` (the default is about 2 million samples).
    #[arg(long, default_value = "128x64x256", value_parser = parse_sizes)]
    pub samples: [usize; 3],
    /// Periodic axes, among the letters x, y, z (`none` for none). z is the angle axis.
    #[arg(long, default_value = "z")]
    pub periodic: String,
    /// Regularisation weights λ for the λ table (comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,1e-6,1e-5,1e-4,1e-3,1e-2,1e-1"
    )]
    pub lambda: Vec<f64>,
    /// Solver relative tolerance.
    #[arg(long, default_value_t = 1e-10)]
    pub tolerance: f64,
    /// Solves per solver; the table shows the median time.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Test function: `step` (piecewise smooth with a jump) or `smooth` (the same without the
    /// jump, to see the bias that λ puts on a function the grid can follow).
    #[arg(long, default_value = "step", value_parser = ["step", "smooth"])]
    pub function: String,
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Also compute the dense minimum-norm solution (small grids only).
    #[arg(long)]
    pub dense: bool,
    /// Write the systems at the default λ as MatrixMarket files into this folder:
    /// normal.mtx, normal_rhs.mtx (normal equations), design.mtx, design_rhs.mtx (LSQR/LSMR).
    #[arg(long)]
    pub export_mm: Option<PathBuf>,
}

fn parse_periodic(s: &str) -> Result<[bool; 3], String> {
    let mut p = [false; 3];
    if s == "none" {
        return Ok(p);
    }
    for ch in s.chars() {
        match ch {
            'x' => p[0] = true,
            'y' => p[1] = true,
            'z' => p[2] = true,
            ',' | ' ' => {}
            _ => {
                return Err(format!(
                    "--periodic takes letters among x, y, z or `none`, got {s:?}"
                ));
            }
        }
    }
    Ok(p)
}

/// The test function: think of `x` as a screen abscissa, `y` a height and `z` a view angle
/// (periodic). Undefined outside a wobbling silhouette `|x − ½| < r(y, θ)` and in a slot
/// (`0.30 < y < 0.42`, `x > ½`); smooth inside, with a jump of 2 across a curve that moves with
/// the angle.
pub fn test_function(p: [f64; 3]) -> Option<f64> {
    test_function_with(p, true)
}

/// [`test_function`] with or without its jump.
pub fn test_function_with(p: [f64; 3], with_jump: bool) -> Option<f64> {
    let [x, y, z] = p;
    let theta = std::f64::consts::TAU * z;
    let r = 0.32 + 0.08 * theta.sin() + 0.05 * (3.0 * theta + 4.0 * y).cos();
    let dx = x - 0.5;
    if dx.abs() >= r || (y > 0.30 && y < 0.42 && dx > 0.0) {
        return None;
    }
    let smooth = 3.0 * dx * theta.cos() + 2.0 * y * y + (theta + 3.0 * y).sin();
    let jump = if with_jump && dx > 0.12 * (theta + 1.0).sin() + 0.04 {
        2.0
    } else {
        0.0
    };
    Some(smooth + jump)
}

/// The solver configurations of the solver table (and of `altrep report`): (method,
/// preconditioner).
pub fn configurations() -> Vec<(Method, PreconditionerKind)> {
    use PreconditionerKind::{Jacobi, None, Ssor};
    vec![
        (Method::Pbicg, Jacobi),
        (Method::Pcg, Jacobi),
        (Method::Pcg, Ssor { omega: 1.0 }),
        (Method::Pcg, None),
        (Method::Bicgstab, Jacobi),
        (Method::Lsqr, Jacobi),
        (Method::Lsmr, Jacobi),
    ]
}

/// Runs `altrep fit-bench`.
pub fn run(args: FitBenchArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let periodic = parse_periodic(&args.periodic)?;
    let cells = args.grid;
    let t0 = Instant::now();
    let with_jump = args.function == "step";
    let samples = FitSamples::from_fn(args.samples, |p| test_function_with(p, with_jump))?;
    let sampling_ms = t0.elapsed().as_secs_f64() * 1e3;
    let fitter = Fitter::new(&samples, cells, periodic)?;
    let assembly_ms = fitter.assembly_s() * 1e3;
    let ne = fitter.normal_equations();
    let data = *ne.data();
    let total: usize = args.samples.iter().product();
    let axes: String = ['x', 'y', 'z']
        .iter()
        .zip(periodic)
        .filter(|(_, p)| *p)
        .map(|(c, _)| *c)
        .collect();
    println!(
        "altrep fit-bench ({} function): {}x{}x{} samples ({} defined, {:.1}%), grid {}x{}x{} cells (periodic: {}) = {} nodes, {} untouched",
        args.function,
        args.samples[0],
        args.samples[1],
        args.samples[2],
        data.count,
        100.0 * data.count as f64 / total as f64,
        cells[0],
        cells[1],
        cells[2],
        if axes.is_empty() { "none" } else { &axes },
        ne.layout().node_count(),
        ne.untouched_nodes(),
    );
    println!(
        "data range [{:.4}, {:.4}], constant-fit RMS {:.4}; sampling {:.1} ms, assembly {:.1} ms (2 threads: {})",
        data.min,
        data.max,
        data.std_dev,
        sampling_ms,
        assembly_ms,
        rayon::current_num_threads()
    );

    // Solver table at the default λ.
    let base = FitParams {
        cells,
        periodic,
        lambda: DEFAULT_LAMBDA,
        tolerance: args.tolerance,
        ..FitParams::default()
    };
    let c = DEFAULT_LAMBDA * ne.laplacian_scale();
    let matrix = ne.matrix(DEFAULT_LAMBDA);
    let t_design = Instant::now();
    let design = DesignMatrix::build(&samples, cells, periodic, c)?;
    let design_ms = t_design.elapsed().as_secs_f64() * 1e3;
    println!(
        "\nsolvers at λ = {DEFAULT_LAMBDA:e} (tolerance {:e}; residual = ‖Aᵀd − (AᵀA+cL)a‖/‖Aᵀd‖ for all; solve ms = median of {}, square methods with the build of the lane-blocked matrix; LSQR/LSMR design matrix {}×{} built in {:.1} ms)",
        args.tolerance,
        args.repeat.max(1),
        design.matrix.rows(),
        design.matrix.cols(),
        design_ms
    );
    println!(
        "{:<18} {:>6} {:>8} {:>12} {:>9} {:>10} {:>10} {:>9}",
        "solver", "iters", "products", "residual", "solve ms", "RMS err", "max err", "converged"
    );
    let mut solver_rows = Vec::new();
    for (method, pc) in configurations() {
        let params = FitParams {
            solver: method,
            preconditioner: pc,
            quantize_bits: vec![],
            ..base.clone()
        };
        let fitted = fitter.fit(&params)?;
        let sp = SolveParams {
            tolerance: args.tolerance,
            preconditioner: pc,
            ..SolveParams::default()
        };
        let mut times: Vec<f64> = (0..args.repeat.max(1))
            .map(|_| {
                if method.is_least_squares() {
                    solve(method, &design.matrix, &design.rhs, &sp).map(|s| s.report.time_s * 1e3)
                } else {
                    // As the fit solves: through the lane-blocked matrix, its build timed too.
                    let m = matrix.clone();
                    let t = Instant::now();
                    BlockedCsr::new(m)
                        .and_then(|op| solve(method, &op, ne.rhs(), &sp))
                        .map(|_| t.elapsed().as_secs_f64() * 1e3)
                }
            })
            .collect::<Result<_, _>>()?;
        // Upper median: a time that was measured (`times` has `repeat.max(1)` entries).
        let solve_ms = median(&mut times, EvenMedian::Upper).unwrap_or(0.0);
        let r = &fitted.report;
        let name = format!("{}+{}", method.name(), pc.name());
        println!(
            "{:<18} {:>6} {:>8} {:>12.3e} {:>9.2} {:>10.5} {:>10.5} {:>9}",
            name,
            r.solver.iterations,
            r.solver.operator_applications,
            r.normal_residual,
            solve_ms,
            r.error.rms,
            r.error.max,
            if r.solver.converged {
                "yes".to_string()
            } else {
                format!("no: {:?}", r.solver.stop_reason)
            }
        );
        solver_rows.push(json!({
            "solver": name,
            "method": method.name(),
            "preconditioner": pc.name(),
            "iterations": r.solver.iterations,
            "operator_applications": r.solver.operator_applications,
            "rel_residual": r.normal_residual,
            "solver_rel_residual": r.solver.relative_residual,
            "solve_ms": solve_ms,
            "rms_error": r.error.rms,
            "max_error": r.error.max,
            "p99_error": r.error.p99,
            "converged": r.solver.converged,
            "stop_reason": format!("{:?}", r.solver.stop_reason),
        }));
    }

    // Time split of one complete default fit.
    let default_fit = fitter.fit(&base)?;
    let tm = default_fit.report.timing;
    println!(
        "\ntime split of the default fit ({}+{}, λ = {DEFAULT_LAMBDA:e}): sampling {:.1} ms, assembly {:.1} ms, solve {:.1} ms, evaluation (errors, 8/16-bit quantisation) {:.1} ms",
        base.solver.name(),
        base.preconditioner.name(),
        sampling_ms,
        tm.assembly_s * 1e3,
        tm.solve_s * 1e3,
        tm.evaluation_s * 1e3
    );

    // λ table with the default solver.
    println!(
        "\nλ sweep ({}+{}; data range [{:.4}, {:.4}])",
        base.solver.name(),
        base.preconditioner.name(),
        data.min,
        data.max
    );
    println!(
        "{:<8} {:>10} {:>10} {:>10} {:>10} {:>10} {:>11} {:>11} {:>6}",
        "λ",
        "RMS err",
        "max err",
        "p99 err",
        "coef min",
        "coef max",
        "RMS 8-bit",
        "RMS 16-bit",
        "iters"
    );
    let mut lambda_rows = Vec::new();
    for &lambda in &args.lambda {
        let fitted = fitter.fit(&FitParams {
            lambda,
            ..base.clone()
        })?;
        let r = &fitted.report;
        let q = |bits: u32| {
            r.quantized
                .iter()
                .find(|q| q.bits == bits)
                .map(|q| q.error)
                .unwrap_or(r.error)
        };
        println!(
            "{:<8.0e} {:>10.5} {:>10.5} {:>10.5} {:>10.4} {:>10.4} {:>11.5} {:>11.5} {:>6}",
            lambda,
            r.error.rms,
            r.error.max,
            r.error.p99,
            r.coef_min,
            r.coef_max,
            q(8).rms,
            q(16).rms,
            r.solver.iterations
        );
        lambda_rows.push(json!({
            "lambda": lambda,
            "rms_error": r.error.rms,
            "max_error": r.error.max,
            "p99_error": r.error.p99,
            "coef_min": r.coef_min,
            "coef_max": r.coef_max,
            "rms_error_8bit": q(8).rms,
            "max_error_8bit": q(8).max,
            "rms_error_16bit": q(16).rms,
            "iterations": r.solver.iterations,
            "converged": r.solver.converged,
        }));
    }

    let mut dense_rms = None;
    if args.dense {
        let n = ne.layout().node_count();
        if n > DENSE_MAX_NODES {
            println!(
                "\ndense reference skipped: {n} nodes > {DENSE_MAX_NODES} (use a smaller --grid)"
            );
        } else {
            let t = Instant::now();
            let x = dense_min_norm(ne, DEFAULT_LAMBDA)?;
            let g = TrilinearGrid::new(cells, periodic, x)?;
            let e = error_stats(&samples, &g);
            let it = fitter.fit(&base)?;
            let diff = it
                .grid
                .values()
                .iter()
                .zip(g.values())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            println!(
                "\ndense min-norm reference (λ = {DEFAULT_LAMBDA:e}, eigen-decomposition, {:.0} ms): RMS {:.6} (iterative {:.6}), max node difference {:.2e}",
                t.elapsed().as_secs_f64() * 1e3,
                e.rms,
                it.report.error.rms,
                diff
            );
            dense_rms = Some(e.rms);
        }
    }

    if let Some(dir) = &args.export_mm {
        std::fs::create_dir_all(dir)?;
        io::write_matrix_market(dir.join("normal.mtx"), matrix.view())?;
        io::write_vector(dir.join("normal_rhs.mtx"), ne.rhs())?;
        io::write_matrix_market(dir.join("design.mtx"), design.matrix.view())?;
        io::write_vector(dir.join("design_rhs.mtx"), &design.rhs)?;
        println!(
            "\nwrote normal.mtx, normal_rhs.mtx, design.mtx, design_rhs.mtx to {}",
            dir.display()
        );
    }

    if let Some(path) = &args.json {
        let doc = json!({
            "function": args.function,
            "grid": cells,
            "samples": args.samples,
            "periodic": periodic,
            "nodes": ne.layout().node_count(),
            "defined_samples": data.count,
            "untouched_nodes": ne.untouched_nodes(),
            "sampling_ms": sampling_ms,
            "assembly_ms": assembly_ms,
            "design_matrix_ms": design_ms,
            "default_fit_ms": {
                "sampling": sampling_ms,
                "assembly": tm.assembly_s * 1e3,
                "solve": tm.solve_s * 1e3,
                "evaluation": tm.evaluation_s * 1e3,
            },
            "tolerance": args.tolerance,
            "threads": rayon::current_num_threads(),
            "data_min": data.min,
            "data_max": data.max,
            "constant_fit_rms": data.std_dev,
            "default_lambda": DEFAULT_LAMBDA,
            "solvers": solver_rows,
            "lambdas": lambda_rows,
            "dense_reference_rms": dense_rms,
        });
        super::write_json(path, &doc)?;
        println!("\nwrote {}", path.display());
    }
    Ok(())
}
