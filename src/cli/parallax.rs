//! `altrep parallax` — images with parallax (docs/design.md §7): march steps per bound type, bound
//! violations, precompute time and bytes, and image quality against the ground truth.

use std::path::PathBuf;

use crate::parallax::{
    BoundKind, BoundParams, Bounds, Brim, ParallaxError, ParallaxImages, ParallaxParams,
    QualityParams, QualityRow, RenderParams, StepsReport, SweepRow, Variant, WarpMethod,
    build_bounds, measure_quality, measure_quality_sweep, measure_steps, render,
    render_blend_baseline, render_offset_baseline,
};
use altrep_data_gen::{RgbaImage, Supersample, scene_shape, srgb_to_linear};
use serde_json::json;

use super::CliResult;
use super::capture::load_shape;
use super::demo::{DemoContext, DemoSection, truth_image};
use crate::metrics::{psnr, silhouette_iou};

/// Arguments of `altrep parallax`.
#[derive(clap::Args, Debug)]
pub struct ParallaxArgs {
    /// Mesh to represent (.obj, .gltf or .glb).
    #[arg(long, conflicts_with = "shape", required_unless_present = "shape")]
    pub mesh: Option<PathBuf>,
    /// How the mesh file is read.
    #[command(flatten)]
    pub read: crate::cli::capture::MeshReadArgs,
    /// Procedural shape instead (sphere, box, torus, capsule, pear, truck, chair, tree, building).
    #[arg(long)]
    pub shape: Option<String>,
    /// Number of views N of the steps table, at angles 2πk/N.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(
        *ParallaxParams::VIEW_COUNTS.start() as i64..=*ParallaxParams::VIEW_COUNTS.end() as i64))]
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
    /// Instead of the steps and quality tables: the reconstruction sweep (each option
    /// of the reconstruction alone and all together, the one-step offset, the 64-view blend with
    /// and without the row filter; PSNR, IoU and the error split by distance to the outline),
    /// then the steps and dense-sweep violations of the bounds for the flat and tangent brims.
    #[arg(long)]
    pub quality_sweep: bool,
    /// View sizes of the quality sweep.
    #[arg(long, value_delimiter = ',', default_value = "64")]
    pub quality_sizes: Vec<usize>,
    /// Numbers of views of the quality sweep.
    #[arg(long, value_delimiter = ',', default_value = "4,8,16")]
    pub quality_views: Vec<usize>,
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
        "| bound | mean steps | ratio (a)/· | max steps | mean, footprint fragments | mean, hit fragments | violations | mismatches | precompute ms | bytes |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for s in &t.report.stats {
        md += &format!(
            "| {} | {:.3} | {:.2} | {} | {} | {:.3} | {} | {} | {:.1} | {} |\n",
            s.method,
            s.mean_steps,
            base / s.mean_steps,
            s.max_steps,
            s.mean_steps_footprint
                .map_or("-".to_string(), |m| format!("{m:.3}")),
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

/// The quality sweep in markdown (errors ×1e4, alpha bias in %).
pub fn sweep_markdown(rows: &[SweepRow]) -> String {
    let mut md = String::from(
        "| method | views | size | PSNR dB | IoU | MSE×1e4 band ≤1 px | band 2 px | interior | outside | alpha bias % | bytes |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let s = &r.split;
        md += &format!(
            "| {} | {} | {}² | {:.2} | {:.4} | {:.2} | {:.2} | {:.2} | {:.2} | {:+.2} | {} |\n",
            r.method,
            r.views,
            r.size,
            r.psnr_db,
            r.iou,
            s.band1_mse * 1e4,
            s.band2_mse * 1e4,
            s.interior_mse * 1e4,
            s.outside_mse * 1e4,
            s.alpha_bias * 100.0,
            r.bytes
        );
    }
    md
}

/// `altrep parallax --quality-sweep`.
fn run_sweep(
    args: &ParallaxArgs,
    shape: &dyn altrep_data_gen::Shape,
    base: ParallaxParams,
) -> CliResult {
    let qp = QualityParams {
        angles: args.quality_angles as usize,
        sizes: args.quality_sizes.clone(),
        views: args.quality_views.clone(),
        base,
        ..QualityParams::default()
    };
    if qp.sizes.iter().chain(&qp.views).any(|&v| v == 0) {
        return Err("--quality-sizes and --quality-views must be positive".into());
    }
    let rows = measure_quality_sweep(shape, &qp, &Variant::standard())?;
    println!(
        "{}: reconstruction sweep against the ground truth ({} angles, {}×{} rays per pixel, the warp {} rays across × rows as filtered)\n\n{}",
        shape.name(),
        qp.angles,
        qp.supersample.get(),
        qp.supersample.get(),
        qp.supersample.get(),
        sweep_markdown(&rows)
    );
    let images = ParallaxImages::capture(shape, &base)?;
    let bp = BoundParams {
        subdivisions: args.subdivisions as usize,
        bits: args.bound_bits,
        ..BoundParams::default()
    };
    let mut steps = Vec::new();
    for (label, brim) in [
        ("flat brim", Brim::Flat),
        ("tangent brim", Variant::best().brim),
    ] {
        let t = steps_table(
            images.with_brim(brim)?,
            &bp,
            args.angles as usize,
            args.sweep_factor as usize,
        )?;
        println!(
            "\nMarch steps per fragment and warped view, {label} (N = {}, {}², {} angles; dense sweep {} angles per view)\n\n{}",
            base.views,
            base.width,
            t.report.angles,
            t.report.sweep_angles,
            steps_markdown(&t)
        );
        steps.push(json!({ "surface": label, "steps": t.report }));
    }
    if let Some(path) = &args.json {
        let doc = json!({
            "shape": shape.name(), "angles": qp.angles, "supersample": qp.supersample.get(),
            "variants": Variant::standard(), "quality": rows, "steps": steps,
        });
        super::write_json(path, &doc)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Runs `altrep parallax`.
pub fn run(args: ParallaxArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let shape = load_shape(args.mesh.as_ref(), args.shape.as_deref(), &args.read)?;
    let base = ParallaxParams {
        views: args.views as usize,
        width: args.size as usize,
        height: args.size as usize,
        depth_bits: args.depth_bits,
        continuity_texels: args.continuity,
        ..ParallaxParams::default()
    };
    if args.quality_sweep {
        return run_sweep(&args, shape.as_ref(), base);
    }
    let images = ParallaxImages::capture(shape.as_ref(), &base)?;
    if images.views.iter().all(|v| v.coverage() == 0.0) {
        return Err(ParallaxError::NothingVisible { views: base.views }.into());
    }
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
    let sub = |f: &dyn Fn(&crate::parallax::StepStats) -> f64| {
        (
            f(&s[0]) / f(&s[1]),
            f(&s[0]) / f(&s[2]),
            f(&s[0]) / f(&s[3]),
        )
    };
    let foot = sub(&|x| x.mean_steps_footprint.unwrap_or(f64::NAN));
    let hit = sub(&|x| x.mean_steps_hit);
    println!(
        "same ratios over footprint fragments ({:.1} % of samples): {:.2}, {:.2}, {:.2}; over hit fragments ({:.1} %): {:.2}, {:.2}, {:.2}",
        r.footprint_share.unwrap_or(f64::NAN) * 100.0,
        foot.0,
        foot.1,
        foot.2,
        r.hit_share * 100.0,
        hit.0,
        hit.1,
        hit.2
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
            qp.supersample.get(),
            qp.supersample.get(),
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
                    "mean_steps_hit": b.mean_steps_hit, "mean_steps_footprint": b.mean_steps_footprint,
                    "mismatches": b.mismatches,
                })
            })
            .collect();
        let doc = json!({
            "shape": shape.name(), "views": base.views, "size": base.width, "angles": r.angles,
            "bound_bits": bp.bits, "depth_bits": base.depth_bits, "hit_share": r.hit_share,
            "sweep_angles_per_view": r.sweep_angles,
            "ratios": { "a_over_b": ratio(1), "a_over_c": ratio(2), "a_over_d": ratio(3), "a_over_e": ratio(4) },
            "ratios_footprint": { "a_over_b": foot.0, "a_over_c": foot.1, "a_over_d": foot.2 },
            "ratios_hit": { "a_over_b": hit.0, "a_over_c": hit.1, "a_over_d": hit.2 },
            "footprint_share": r.footprint_share,
            "bounds": bounds, "quality": quality,
        });
        super::write_json(path, &doc)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Nearest-neighbour magnification by `f`, so that small impostors are visible in the report.
fn magnify(img: &RgbaImage, f: usize) -> RgbaImage {
    let mut out = RgbaImage::new(img.width * f, img.height * f);
    for j in 0..out.height {
        for i in 0..out.width {
            out.pixels[j * out.width + i] = img.get(i / f, j / f);
        }
    }
    out
}

/// A heat map of `values` (row-major `w × h`) on a black–blue–magenta–orange–yellow ramp scaled
/// to `max`; zero is black.
fn heat_map(values: &[f64], w: usize, h: usize, max: f64) -> RgbaImage {
    const RAMP: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.13, 0.15, 0.65],
        [0.72, 0.2, 0.62],
        [0.98, 0.55, 0.2],
        [0.99, 0.96, 0.55],
    ];
    let pixels = values
        .iter()
        .map(|&v| {
            let u = (v / max.max(1e-9)).clamp(0.0, 1.0) as f32 * 4.0;
            let k = (u.floor() as usize).min(3);
            let f = u - k as f32;
            let c: [f32; 3] = std::array::from_fn(|c| {
                srgb_to_linear(RAMP[k][c] + f * (RAMP[k + 1][c] - RAMP[k][c]))
            });
            [c[0], c[1], c[2], 1.0]
        })
        .collect();
    RgbaImage {
        width: w,
        height: h,
        pixels,
    }
}

/// Demo section: the views of the truck, reconstructions beside the ground truth, heat maps of
/// march steps per pixel for each bound type, and the steps and quality tables. A few seconds
/// (quick: 32², fewer angles, no dense sweep).
pub fn demo_section(
    ctx: &DemoContext,
) -> Result<DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    let dir = ctx.dir;
    let (size, angles, sweep, zoom) = if ctx.quick {
        (32, 72, 0, 6)
    } else {
        (64, 180, 2, 4)
    };
    let shape = scene_shape("truck")?;
    let params = ParallaxParams {
        width: size,
        height: size,
        ..ParallaxParams::default()
    };
    let images = ParallaxImages::capture(&shape, &params)?;
    let mut md = format!(
        "The truck as {} views of {size}×{size} (colour RGBA8 + normal and 8-bit depth: {} bytes). Views, shaded:\n\n![views](parallax/views.png)\n\n",
        params.views,
        images.bytes()
    );
    let shaded: Vec<RgbaImage> = images.views.iter().map(|v| v.shade(&ctx.light)).collect();
    let refs: Vec<&RgbaImage> = shaded.iter().collect();
    magnify(&RgbaImage::side_by_side(&refs).over([0.1; 3]), 2).write_png(&dir.join("views.png"))?;
    // Reconstructions beside the ground truth.
    let blend = ParallaxImages::capture(
        &shape,
        &ParallaxParams {
            views: 64,
            ..params
        },
    )?;
    let screen = RenderParams {
        width: size,
        height: size,
        supersample: Supersample::of(3),
        light: ctx.light,
        mip: true,
    };
    md += "Left to right: ground truth (3×3 rays), inverse warping, direct warping, one-step offset (same 8 views), blend of 64 views without parallax.\n\n| α (rad) | inverse PSNR dB | direct PSNR dB | offset PSNR dB | blend-64 PSNR dB | inverse IoU |\n|---|---|---|---|---|---|\n";
    let mut quality = Vec::new();
    for (n, alpha) in [0.35, 1.2, 2.6].into_iter().enumerate() {
        let truth = truth_image(
            &shape,
            alpha,
            size,
            Supersample::of(3),
            ctx.light,
            params.cylinder,
        )?;
        let inv = render(&images, alpha, WarpMethod::Inverse, &screen)?;
        let dirw = render(&images, alpha, WarpMethod::Direct, &screen)?;
        let off = render_offset_baseline(&images, alpha, &screen)?;
        let bl = render_blend_baseline(&blend, alpha, &screen)?;
        let p = |i: &RgbaImage| psnr(i, &truth);
        let row = (
            p(&inv)?,
            p(&dirw)?,
            p(&off)?,
            p(&bl)?,
            silhouette_iou(&inv, &truth, 0.5)?,
        );
        md += &format!(
            "| {alpha} | {:.2} | {:.2} | {:.2} | {:.2} | {:.4} |\n",
            row.0, row.1, row.2, row.3, row.4
        );
        quality.push(json!({ "alpha": alpha, "inverse_psnr_db": row.0, "direct_psnr_db": row.1, "offset_psnr_db": row.2, "blend64_psnr_db": row.3, "inverse_iou": row.4 }));
        let strip = RgbaImage::side_by_side(&[&truth, &inv, &dirw, &off, &bl]).over([0.1; 3]);
        magnify(&strip, zoom).write_png(&dir.join(format!("reconstruction_{n}.png")))?;
    }
    md += "\n![α = 0.35](parallax/reconstruction_0.png)\n\n![α = 1.2](parallax/reconstruction_1.png)\n\n![α = 2.6](parallax/reconstruction_2.png)\n\n";
    // Steps per bound type.
    let t = steps_table(images, &BoundParams::default(), angles, sweep)?;
    md += &format!(
        "March steps per fragment and warped view ({angles} display angles, every fragment of the quad, 8-bit bounds{}):\n\n{}\n",
        if sweep > 0 {
            format!(", dense check at {} angles per view", t.report.sweep_angles)
        } else {
            String::new()
        },
        steps_markdown(&t)
    );
    md +=
        "Mean steps per pixel over all angles, one heat map per bound (same scale, black = 0):\n\n";
    let max = t.report.heat.iter().flatten().cloned().fold(0.0, f64::max);
    for (s, h) in t.report.stats.iter().zip(&t.report.heat) {
        let file = format!("steps_{}.png", s.kind.slug());
        magnify(&heat_map(h, size, size, max), zoom).write_png(&dir.join(&file))?;
        md += &format!("![{}](parallax/{file}) ", s.method);
    }
    md += &format!(
        "\n\nScale: 0 to {max:.1} steps. Order: {}.\n",
        t.report
            .stats
            .iter()
            .map(|s| s.method.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(DemoSection {
        name: "parallax".into(),
        json: json!({ "steps": t.report, "quality": quality }),
        markdown: md,
    })
}
