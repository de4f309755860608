//! The `altrep` command-line tool: see `altrep --help`.

use altrep::cli;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "altrep",
    version,
    about = "Precompute and fit compact stand-ins for complex geometry"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job: precompute the bundled scene (scenes/demo.toml), then the measured sections; writes a report.
    Demo(cli::demo::DemoArgs),
    /// Capture N orthographic views (colour, depth, normals) of an OBJ mesh.
    Capture(cli::capture::CaptureArgs),
    /// Cylindrical texture of a mesh or shape: exact and fitted-offset renderers against ground truth.
    Cylinder(cli::cylinder::CylinderArgs),
    /// Ellipsoid micro-primitives: eigen-solver, filter rules, sin²θ law and octree report.
    EllipsoidBench(cli::ellipsoid_bench::EllipsoidBenchArgs),
    /// Benchmark the trilinear least-squares fit: solvers, regularisation λ, quantisation.
    FitBench(cli::fit_bench::FitBenchArgs),
    /// Images with parallax: march steps per bound type, violations, bytes, and quality vs ground truth.
    Parallax(cli::parallax::ParallaxArgs),
    /// The offline step: plan, build, write and measure the representations a scene manifest asks for.
    Precompute(cli::precompute::PrecomputeArgs),
    /// Pyramids: mip/rip/fip/EWA error and time against supersampled truth, filters, fusion PSNR.
    Pyramid(cli::pyramid::PyramidArgs),
    /// Pyramids benchmark: lookup error/time table and RGBA8 sRGB mip-chain build speed vs image and fast_image_resize.
    PyramidBench(cli::pyramid_bench::PyramidBenchArgs),
    /// Run time against error: sweep every representation's parameters, write CSV, JSON and plots.
    Report(cli::report::ReportArgs),
    /// Volumetric textures as slices: merge rules, levels and directions vs a ray-marched volume.
    Slices(cli::slices::SlicesArgs),
    /// Images with parallax from any direction: exact warp of octahedral frames vs the engines' impostor, memory vs PSNR.
    Sphere(cli::sphere::SphereArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Capture(args) => cli::capture::run(args),
        Command::Cylinder(args) => cli::cylinder::run(args),
        Command::EllipsoidBench(args) => cli::ellipsoid_bench::run(args),
        Command::FitBench(args) => cli::fit_bench::run(args),
        Command::Parallax(args) => cli::parallax::run(args),
        Command::Precompute(args) => cli::precompute::run(args),
        Command::Pyramid(args) => cli::pyramid::run(args),
        Command::PyramidBench(args) => cli::pyramid_bench::run(args),
        Command::Report(args) => cli::report::run(args),
        Command::Slices(args) => cli::slices::run(args),
        Command::Sphere(args) => cli::sphere::run(args),
    };
    if let Err(e) = result {
        eprintln!("altrep: error: {e}");
        std::process::exit(1);
    }
}
