//! `altrep cylinder` — captures a cylindrical texture of a mesh or a procedural shape, fits its
//! offset texture and prints the table of every renderer against the ground truth (and, with
//! `--sweep`, the sweep of the offset grid). `--suite` does it for the six evaluation shapes and
//! adds a summary across them.

use std::path::PathBuf;

use altrep_data_gen::{Mesh, MeshLoadOptions, RgbaImage, Shape, scene_shape};
use serde_json::json;

use super::capture::load_shape;
use super::demo::{DemoContext, DemoSection, truth_image};
use super::{CliResult, parse_sizes_upto};
use crate::cylinder::{
    BoundsParams, CylinderError, CylinderRenderParams, CylindricalTexture, EvalParams, EvalReport,
    ExactMethod, LambdaRule, OffsetMode, OffsetParams, OffsetTexture, RadiusModel, SWEEP_GRIDS,
    evaluate, render_exact, sweep, sweep_markdown,
};

/// Arguments of `altrep cylinder`.
#[derive(clap::Args, Debug)]
pub struct CylinderArgs {
    /// Mesh to represent, .obj, .gltf or .glb (repeat for several; with `--shape` too, a summary follows).
    #[arg(long, conflicts_with = "suite", required_unless_present_any = ["shape", "suite"])]
    pub mesh: Vec<PathBuf>,
    /// How the mesh file is read.
    #[command(flatten)]
    pub read: crate::cli::capture::MeshReadArgs,
    /// Procedural shape instead (sphere, box, torus, capsule, pear, truck, chair, tree,
    /// building); repeat for several.
    #[arg(long, conflicts_with = "suite")]
    pub shape: Vec<String>,
    /// Measure the evaluation shapes (truck, pear, tree, chair, and the teapot, beetle and
    /// stanford-bunny meshes of `--meshes`, skipped with a message when absent) and print a
    /// summary.
    #[arg(long)]
    pub suite: bool,
    /// Folder of the evaluation meshes for `--suite`.
    #[arg(long, default_value = "../shared/data/meshes")]
    pub meshes: PathBuf,
    /// Cells of the fitted offset grid, `AxxAyxAα` (x, rows, angles; the angle axis is periodic).
    #[arg(long, default_value = "15x8x16", value_parser = parse_sizes_upto::<256>)]
    pub grid: [usize; 3],
    /// Regularisation λ of the offset fit, fixed; by default it is chosen per fit (the smallest
    /// that keeps the coefficients within twice the data range).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Cells of the march bounds, `BxxGxBα` (abscissae, texture rows per cell, angles).
    #[arg(long, default_value = "64x2x64", value_parser = parse_sizes_upto::<256>)]
    pub bounds: [usize; 3],
    /// Camera angles measured.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=360))]
    pub angles: u32,
    /// Image size in pixels (square, 3 × 3 sub-samples per pixel).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(8..=1024))]
    pub size: u32,
    /// Also sweep the offset grid from 8×4×8 to 31×16×32.
    #[arg(long)]
    pub sweep: bool,
    /// Write the results as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `altrep cylinder`.
pub fn run(args: CylinderArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let shapes: Vec<Box<dyn Shape>> = if args.suite {
        let mut shapes = Vec::new();
        for name in ["truck", "pear", "tree", "chair"] {
            shapes.push(Box::new(scene_shape(name)?) as Box<dyn Shape>);
        }
        for name in ["teapot", "beetle", "stanford-bunny"] {
            let path = args.meshes.join(format!("{name}.obj"));
            match Mesh::load(&path, &MeshLoadOptions::default()) {
                Ok(mesh) => shapes.push(Box::new(mesh)),
                Err(e) => eprintln!("altrep: skipping {name}: {e}"),
            }
        }
        shapes
    } else {
        let mut shapes = Vec::new();
        for path in &args.mesh {
            shapes.push(load_shape(Some(path), None, &args.read)?);
        }
        for name in &args.shape {
            shapes.push(load_shape(None, Some(name), &args.read)?);
        }
        shapes
    };
    let params = EvalParams {
        offset: OffsetParams {
            cells: args.grid,
            lambda: args
                .lambda
                .map_or(OffsetParams::default().lambda, LambdaRule::Fixed),
            ..OffsetParams::default()
        },
        bounds: BoundsParams {
            cells_x: args.bounds[0],
            rows_per_cell: args.bounds[1],
            cells_alpha: args.bounds[2],
        },
        angles: args.angles as usize,
        size: args.size as usize,
        ..EvalParams::default()
    };
    let mut results = Vec::new();
    let mut reports = Vec::new();
    let several = shapes.len() > 1;
    for shape in &shapes {
        let report = match evaluate(shape.as_ref(), &params) {
            Ok(r) => r,
            // With several shapes, one the representation cannot hold is skipped with the reason.
            Err(
                e @ (CylinderError::NotRepresentable { .. } | CylinderError::NothingVisible { .. }),
            ) if several => {
                eprintln!("altrep: skipping {}: {e}", shape.name());
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        println!("{}", report.markdown());
        let sweep_rows = if args.sweep {
            let rows = sweep(shape.as_ref(), &params, &SWEEP_GRIDS)?;
            println!("{}", sweep_markdown(shape.name(), &rows));
            Some(rows)
        } else {
            None
        };
        results.push(json!({
            "shape": report.shape,
            "texture": {
                "size": report.texture_size,
                "coverage": report.coverage,
                "negative_share": report.negative_share,
                "capture_ms": report.capture_ms,
                "bytes": report.texture_bytes,
            },
            "held": report.held,
            "silhouette": report.silhouette,
            "bounds": report.bounds,
            "offset": report.offset,
            "renderers": report.rows.iter().map(|r| r.json()).collect::<Vec<_>>(),
            "minification": report.minification,
            "sweep": sweep_rows,
        }));
        reports.push(report);
    }
    if reports.len() > 1 {
        println!("{}", summary_markdown(&reports));
    }
    if let Some(path) = &args.json {
        let out = if results.len() == 1 {
            let mut one = results.remove(0);
            one["params"] = json!(params);
            one
        } else {
            json!({ "params": params, "shapes": results })
        };
        super::write_json(path, &out)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Two summary tables across shapes: PSNR against the ground truth (and IoU) per renderer, then
/// the offsets' error split and costs.
pub fn summary_markdown(reports: &[EvalReport]) -> String {
    let methods: Vec<&str> = reports[0].rows.iter().map(|r| r.method.as_str()).collect();
    let mut s = String::from("PSNR dB against the ground truth (silhouette IoU):\n\n| shape |");
    for m in &methods {
        s += &format!(" {m} |");
    }
    s += "\n|---|";
    s += &"---|".repeat(methods.len());
    s += "\n";
    for r in reports {
        s += &format!("| {} |", r.shape);
        for m in &methods {
            s += &r.row(m).map_or(" – |".to_string(), |x| {
                format!(" {:.1} ({:.3}) |", x.psnr_db, x.iou)
            });
        }
        s += "\n";
    }
    s += "\nOffsets (texels, RMS / p99; away from / near discontinuities), vs inverse warping, \
          costs:\n\n| shape | fitted all | away | near | hybrid m=4 all | fitted / m=4 / bounded vs inverse dB | \
          inverse steps | m=4 steps | bounded steps | precompute ms (capture, sampling, assembly, solve, quantisation) | bytes | λ | coefficients / data range |\n\
          |---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for r in reports {
        let (Some(f), Some(h), Some(i), Some(b)) = (
            r.row("fitted"),
            r.row("hybrid-m4"),
            r.row("inverse"),
            r.row("bounded"),
        ) else {
            continue;
        };
        let vs = |x: f64| {
            if x.is_finite() {
                format!("{x:.1}")
            } else {
                "=".into()
            }
        };
        s += &format!(
            "| {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.1} / {:.1} / {} | {:.1} | {:.2} | {:.2} | {:.0} ({:.0}, {:.0}, {:.1}, {:.1}, {:.1}) | {} | {:.1e} | {:.0}…{:.0} / {:.0}…{:.0} |\n",
            r.shape,
            f.offset.rms,
            f.offset.p99,
            f.offset_away.rms,
            f.offset_away.p99,
            f.offset_near.rms,
            f.offset_near.p99,
            h.offset.rms,
            h.offset.p99,
            f.psnr_vs_inverse_db,
            h.psnr_vs_inverse_db,
            vs(b.psnr_vs_inverse_db),
            i.mean_steps.unwrap_or(0.0),
            h.mean_steps.unwrap_or(0.0),
            b.mean_steps.unwrap_or(0.0),
            f.precompute_ms,
            r.capture_ms,
            r.offset.sampling_s * 1e3,
            r.offset.assembly_s * 1e3,
            r.offset.solve_s * 1e3,
            r.offset.quantization_s * 1e3,
            f.bytes,
            r.offset.lambda,
            r.offset.fit.coef_min,
            r.offset.fit.coef_max,
            r.offset.fit.data.min,
            r.offset.fit.data.max,
        );
    }
    s
}

/// The demo section: the pear's cylindrical texture (shaded and signed radius), reconstructions
/// at three angles beside the ground truth (truth | mesh | inverse | fitted | hybrid m = 2), and
/// the table of every renderer (pear in quick mode; pear and truck otherwise).
pub fn demo_section(
    ctx: &DemoContext,
) -> Result<DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    let dir = ctx.dir;
    let params = if ctx.quick {
        EvalParams {
            angles: 2,
            size: 32,
            minify_sizes: vec![16],
            light: ctx.light,
            ..EvalParams::default()
        }
    } else {
        EvalParams {
            angles: 8,
            size: 64,
            light: ctx.light,
            ..EvalParams::default()
        }
    };
    let pear = scene_shape("pear")?;
    let texture = CylindricalTexture::capture(&pear, &params.texture, params.prefilter)?;
    texture
        .shade(&ctx.light)
        .write_png(&dir.join("pear_texture.png"))?;
    texture
        .radius_image()
        .write_png(&dir.join("pear_radius.png"))?;
    let offsets = OffsetTexture::fit(&texture, &params.offset)?;
    let mut md = String::from(
        "The pear's cylindrical texture (256 × 64, shaded; signed radius: red positive, blue \
         negative), then at three angles: ground truth | mesh reference | inverse warping | \
         fitted offsets | hybrid m = 2.\n\n![texture](cylinder/pear_texture.png) \
         ![radius](cylinder/pear_radius.png)\n\n",
    );
    let size = params.size;
    for (n, angle) in [0.4, 2.0, 4.4].into_iter().enumerate() {
        let p = CylinderRenderParams {
            angle,
            width: size,
            height: size,
            supersample: params.supersample,
            light: ctx.light,
        };
        let truth = truth_image(
            &pear,
            angle,
            size,
            params.supersample,
            ctx.light,
            texture.cylinder(),
        )?;
        let mesh = render_exact(&texture, ExactMethod::Mesh, &p)?.image;
        let inverse = render_exact(&texture, ExactMethod::Inverse(RadiusModel::General), &p)?.image;
        let fitted = offsets
            .render(&texture, OffsetMode::Plain, params.tolerance_px, &p)?
            .image;
        let hybrid = offsets
            .render(
                &texture,
                OffsetMode::Hybrid { steps: 2 },
                params.tolerance_px,
                &p,
            )?
            .image;
        let row = RgbaImage::side_by_side(&[&truth, &mesh, &inverse, &fitted, &hybrid]);
        let file = format!("pear_angle{n}.png");
        row.over([0.1, 0.1, 0.12]).write_png(&dir.join(&file))?;
        md += &format!("α = {angle}: ![pear at {angle}](cylinder/{file})\n\n");
    }
    let shapes: &[&str] = if ctx.quick {
        &["pear"]
    } else {
        &["pear", "truck"]
    };
    let mut results = Vec::new();
    for name in shapes {
        let shape = scene_shape(name)?;
        let report = evaluate(&shape, &params)?;
        md += &report.markdown();
        md += "\n";
        results.push(json!({
            "shape": name,
            "renderers": report.rows.iter().map(|r| r.json()).collect::<Vec<_>>(),
            "offset": report.offset,
            "minification": report.minification,
        }));
    }
    Ok(DemoSection {
        name: "cylinder".into(),
        json: json!(results),
        markdown: md,
    })
}
