//! `altrep parallax` — images with parallax (SPEC §7): march steps per bound type, bound
//! violations, precompute time and bytes, and image quality against the ground truth.

use std::path::PathBuf;

use crate::parallax::{
    BoundKind, BoundParams, Bounds, ParallaxImages, ParallaxParams, QualityParams, QualityRow,
    StepsReport, build_bounds, measure_quality, measure_steps,
};
use serde_json::json;

use super::CliResult;
use super::capture::load_shape;

/// Arguments of `altrep parallax`.
#[derive(clap::Args, Debug)]
pub struct ParallaxArgs {
    /// OBJ mesh to represent.
    #[arg(long, conflicts_with = "shape", required_unless_present = "shape")]
    pub mesh: Option<PathBuf>,
    /// Procedural shape instead (sphere, box, torus, capsule, pear, truck, chair, tree, building).
    #[arg(long)]
    pub shape: Option<String>,
    /// Number of views N of the steps table, at angles 2πk/N.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(3..=1024))]
    pub views: u32,
    /// Width and height of each view of the steps table, in pixels.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(2..=1024))]
    pub size: u32,
    /// Display angles of the steps table (evenly spaced).
    #[arg(long, default_value_t = 360, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub angles: u32,
    /// Storage bits of every bound channel: 8, 16 or 32 (f32).
    #[arg(long, default_value_t = 8)]
    pub bound_bits: u32,
    /// Bits of the stored depth: 8 or 16.
    #[arg(long, default_value_t = 8)]
    pub depth_bits: u32,
    /// Uniform angle grid per half range used to cut the bound sweep (tightness for c ≠ −1).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub subdivisions: u32,
    /// The dense check of the bounds uses this many times more angles than the build grid (0: skip).
    #[arg(long, default_value_t = 10)]
    pub sweep_factor: u32,
    /// Continuity threshold in texel widths.
    #[arg(long, default_value_t = 3.0)]
    pub continuity: f64,
    /// Skip the quality table (PSNR / IoU for N = 4, 8, 16 and 32², 64², 128²).
    #[arg(long)]
    pub no_quality: bool,
    /// Display angles of the quality table.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub quality_angles: u32,
    /// Write the tables as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Steps, bounds and the report's ratios, as printed and written.
pub struct StepsTable {
    /// The representation measured.
    pub images: ParallaxImages,
    /// The bounds, in the order (a)–(e).
    pub bounds: Vec<Bounds>,
    /// The measurement.
    pub report: StepsReport,
}

/// Builds every bound kind for `images` and measures them (shared with the demo).
pub fn steps_table(
    images: ParallaxImages,
    params: &BoundParams,
    angles: usize,
    sweep_factor: usize,
) -> Result<StepsTable, Box<dyn std::error::Error + Send + Sync>> {
    let bounds = BoundKind::ALL
        .iter()
        .map(|&k| build_bounds(&images, k, params))
        .collect::<Result<Vec<_>, _>>()?;
    let report = measure_steps(&images, &bounds, angles, sweep_factor)?;
    Ok(StepsTable {
        images,
        bounds,
        report,
    })
}

/// The steps table in markdown.
pub fn steps_markdown(t: &StepsTable) -> String {
    let base = t.report.stats[0].mean_steps;
    let mut md = String::from(
        "| bound | mean steps | ratio (a)/· | max steps | mean steps (hit fragments) | violations | mismatches | precompute ms | bytes |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for s in &t.report.stats {
        md += &format!(
            "| {} | {:.3} | {:.2} | {} | {:.3} | {} | {} | {:.1} | {} |\n",
            s.method,
            s.mean_steps,
            base / s.mean_steps,
            s.max_steps,
            s.mean_steps_hit,
            s.violations
                .map_or("not run".to_string(), |v| v.to_string()),
            s.mismatches,
            s.precompute_ms,
            s.bytes
        );
    }
    md
}

/// The quality table in markdown.
pub fn quality_markdown(rows: &[QualityRow]) -> String {
    let mut md = String::from(
        "| method | views | size | PSNR dB | IoU | bytes |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        md += &format!(
            "| {} | {} | {}² | {:.2} | {:.4} | {} |\n",
            r.method, r.views, r.size, r.psnr_db, r.iou, r.bytes
        );
    }
    md
}

/// Runs `altrep parallax`.
pub fn run(args: ParallaxArgs) -> CliResult {
    let shape = load_shape(args.mesh.as_ref(), args.shape.as_deref())?;
    let base = ParallaxParams {
        views: args.views as usize,
        width: args.size as usize,
        height: args.size as usize,
        depth_bits: args.depth_bits,
        continuity_texels: args.continuity,
        ..ParallaxParams::default()
    };
    let images = ParallaxImages::capture(shape.as_ref(), &base)?;
    let capture_ms = images.capture_time.as_secs_f64() * 1e3;
    let bp = BoundParams {
        subdivisions: args.subdivisions as usize,
        bits: args.bound_bits,
        ..BoundParams::default()
    };
    let t = steps_table(
        images,
        &bp,
        args.angles as usize,
        args.sweep_factor as usize,
    )?;
    let r = &t.report;
    println!(
        "{}: N = {}, {}×{}, capture {capture_ms:.0} ms, {} display angles, {} samples (fragments × 2 warped views × angles), {:.1} % of them hit; bounds stored in {} bits; dense sweep {} angles per view",
        shape.name(),
        base.views,
        base.width,
        base.height,
        r.angles,
        r.samples,
        r.hit_share * 100.0,
        bp.bits,
        r.sweep_angles
    );
    println!(
        "\nMarch steps per fragment and warped view\n\n{}",
        steps_markdown(&t)
    );
    let s = &r.stats;
    let ratio = |i: usize| s[0].mean_steps / s[i].mean_steps;
    println!(
        "ratios of mean steps: (a)/(b) zmin/zmax = {:.2} (report: 5), (a)/(c) pair = {:.2} (report: 12), (a)/(d) best c = {:.2}, (a)/(e) split = {:.2}; best c vs pair: {:+.1} %",
        ratio(1),
        ratio(2),
        ratio(3),
        ratio(4),
        (s[3].mean_steps / s[2].mean_steps - 1.0) * 100.0
    );
    let quality = if args.no_quality {
        Vec::new()
    } else {
        let qp = QualityParams {
            angles: args.quality_angles as usize,
            base,
            ..QualityParams::default()
        };
        let rows = measure_quality(shape.as_ref(), &qp)?;
        println!(
            "\nImage quality against the ground truth ({} angles, {}×{} rays per pixel)\n\n{}",
            qp.angles,
            qp.supersample,
            qp.supersample,
            quality_markdown(&rows)
        );
        rows
    };
    if let Some(path) = &args.json {
        let bounds: Vec<_> = s
            .iter()
            .map(|b| {
                json!({
                    "method": b.method, "mean_steps": b.mean_steps, "max_steps": b.max_steps,
                    "violations": b.violations, "precompute_ms": b.precompute_ms, "bytes": b.bytes,
                    "mean_steps_hit": b.mean_steps_hit, "mismatches": b.mismatches,
                })
            })
            .collect();
        let doc = json!({
            "shape": shape.name(), "views": base.views, "size": base.width, "angles": r.angles,
            "bound_bits": bp.bits, "depth_bits": base.depth_bits, "hit_share": r.hit_share,
            "sweep_angles_per_view": r.sweep_angles,
            "ratios": { "a_over_b": ratio(1), "a_over_c": ratio(2), "a_over_d": ratio(3), "a_over_e": ratio(4) },
            "bounds": bounds, "quality": quality,
        });
        std::fs::write(path, serde_json::to_string_pretty(&doc)?)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
