//! `altrep pyramid-bench` — the two tables a user needs to choose a pyramid, from one run: the
//! error/time table of mip, rip, fip and EWA lookups against the supersampled truth over
//! distances and tilts up to 89° ([`crate::pyramid::measure_sweep`]), and the build-speed table of
//! an RGBA8 sRGB mip chain, box and Kaiser, ours against the `image` crate and
//! `fast_image_resize` ([`crate::pyramid::speed`]); plus the quad-tree fusion PSNR.

use std::path::PathBuf;

use serde_json::json;

use super::CliResult;
use crate::pyramid::fast::simd_available;
use crate::pyramid::fusion::fusion_experiment;
use crate::pyramid::speed::{BUILDERS, compare_builds};
use crate::pyramid::truth::{METHODS, test_texture};
use crate::pyramid::{Filter, PyramidParams, SweepParams, WrapMode, measure_sweep};

/// Arguments of `altrep pyramid-bench`.
#[derive(clap::Args, Debug)]
pub struct PyramidBenchArgs {
    /// Side of the square test texture of the error/time sweep, in texels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(4..=2048))]
    pub size: u32,
    /// Image side of each view of the sweep, in pixels.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub pixels: u32,
    /// Cap on supersampled truth samples per pixel.
    #[arg(long, default_value_t = 8192, value_parser = clap::value_parser!(u32).range(16..=1_048_576))]
    pub max_samples: u32,
    /// Side of the RGBA8 sRGB level 0 whose mip chain is timed (0: skip the build table).
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(0..=16384))]
    pub build_size: u32,
    /// Timed runs per builder and filter (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=50))]
    pub repeats: u32,
    /// Write every figure as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs the sweep, the build comparison and the fusion experiment; prints the tables.
pub fn run(args: PyramidBenchArgs) -> CliResult {
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let params = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..Default::default()
    };
    let sweep = SweepParams {
        pixels: args.pixels as usize,
        max_samples_per_pixel: args.max_samples as usize,
        ..Default::default()
    };
    let tex = test_texture(args.size as usize, 7);
    let report = measure_sweep(&tex, &params, &sweep)?;
    super::pyramid::print_sweep(&report, args.size, params.filter, args.pixels);
    let mean =
        |k: usize| report.rows.iter().map(|r| r.rms[k]).sum::<f64>() / report.rows.len() as f64;
    let ns = |k: usize| {
        let mut v: Vec<f64> = report.rows.iter().map(|r| r.ns_per_sample[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "summary over {} views: mean RMS mip {:.4}, rip {:.4}, fip {:.4}, ewa {:.4}; median ns/lookup mip {:.0}, rip {:.0}, fip {:.0}, ewa {:.0}",
        report.rows.len(),
        mean(0),
        mean(1),
        mean(2),
        mean(3),
        ns(0),
        ns(1),
        ns(2),
        ns(3)
    );

    let mut builds = Vec::new();
    if args.build_size > 0 {
        let n = args.build_size as usize;
        println!(
            "\nmip chain build, {n}×{n} RGBA8 sRGB, linear light, straight alpha premultiplied for filtering, \
             median of {} runs (s), all cores ({} threads); \
             difference from the exact definition (f64) in 8-bit steps, max / mean",
            args.repeats,
            rayon::current_num_threads()
        );
        println!(
            "{:>7} | {:>8} {:>8} {:>8} | {:>11} {:>11} | {:>13} {:>13} {:>13}",
            "filter",
            "ours",
            "image",
            "fir",
            "ours/image",
            "ours/fir",
            "ours diff",
            "image diff",
            "fir diff"
        );
        for f in [Filter::Box, Filter::Kaiser] {
            let row = compare_builds(n, f, args.repeats as usize)?;
            println!(
                "{:>7} | {:>8.3} {:>8.3} {:>8.3} | {:>11.2} {:>11.2} | {:>7} {:>5.3} {:>7} {:>5.3} {:>7} {:>5.3}",
                format!("{f:?}"),
                row.seconds[0],
                row.seconds[1],
                row.seconds[2],
                row.seconds[0] / row.seconds[1],
                row.seconds[0] / row.seconds[2],
                row.max_diff_u8[0],
                row.mean_diff_u8[0],
                row.max_diff_u8[1],
                row.mean_diff_u8[1],
                row.max_diff_u8[2],
                row.mean_diff_u8[2],
            );
            builds.push(row);
        }
        println!(
            "(ours: {} kernels, box by exact 2×2 halving on power-of-two sizes, Kaiser every level from level 0; \
             image: thumbnail (its +½ float bias removed) for box, Lanczos3 for Kaiser, f32 linear, \
             every level from level 0, levels in parallel; \
             fir = fast_image_resize: 16-bit linear via its sRGB mapper, Box / custom Kaiser, \
             every level from level 0, levels in parallel)",
            if simd_available() {
                "AVX2+FMA"
            } else {
                "portable"
            }
        );
    }

    let fusion = fusion_experiment(128, 3)?;
    println!(
        "\nquad-tree fusion, 128×128 RGB, 5 views, occluder in 2: PSNR {:.2} dB with median rejection, {:.2} dB without",
        fusion.psnr_with_rejection, fusion.psnr_without_rejection
    );

    if let Some(path) = &args.json {
        let doc = json!({
            "methods": METHODS,
            "sweep": report,
            "texture_size": args.size,
            "builders": BUILDERS,
            "builds": builds,
            "threads": rayon::current_num_threads(),
            "simd": simd_available(),
            "fusion": fusion,
        });
        super::write_json(path, &doc)?;
    }
    Ok(())
}
