//! `altrep cylinder` — captures a cylindrical texture of a mesh or a procedural shape, fits its
//! offset texture and prints the table of every renderer against the ground truth (and, with
//! `--sweep`, the sweep of the offset grid).

use std::path::PathBuf;

use altrep_data_gen::{RgbaImage, scene_shape};
use serde_json::json;

use super::CliResult;
use super::capture::load_shape;
use super::demo::{DemoContext, DemoSection, truth_image};
use crate::cylinder::{
    CylindricalTexture, EvalParams, ExactMethod, OffsetMode, OffsetParams, OffsetTexture,
    RadiusModel, RenderParams, SWEEP_GRIDS, evaluate, render_exact, sweep, sweep_markdown,
};

/// Arguments of `altrep cylinder`.
#[derive(clap::Args, Debug)]
pub struct CylinderArgs {
    /// OBJ mesh to represent.
    #[arg(long, conflicts_with = "shape", required_unless_present = "shape")]
    pub mesh: Option<PathBuf>,
    /// Procedural shape instead (sphere, box, torus, capsule, pear, truck, chair, tree, building).
    #[arg(long)]
    pub shape: Option<String>,
    /// Cells of the fitted offset grid, `AxxAyxAα` (x, rows, angles; the angle axis is periodic).
    #[arg(long, default_value = "15x8x16", value_parser = parse_grid)]
    pub grid: [usize; 3],
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

/// Parses `15x8x16` (or `15×8×16`) into cell counts, each at least 1.
pub fn parse_grid(s: &str) -> Result<[usize; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X', '×']).collect();
    let bad = || format!("expected AxxAyxAα with three positive integers, like 15x8x16; got '{s}'");
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut cells = [0; 3];
    for (c, p) in cells.iter_mut().zip(&parts) {
        *c = p.trim().parse::<usize>().map_err(|_| bad())?;
        if *c == 0 || *c > 256 {
            return Err(format!("grid sizes must be in 1..=256; got '{s}'"));
        }
    }
    Ok(cells)
}

/// Runs `altrep cylinder`.
pub fn run(args: CylinderArgs) -> CliResult {
    let shape = load_shape(args.mesh.as_ref(), args.shape.as_deref())?;
    let params = EvalParams {
        offset: OffsetParams {
            cells: args.grid,
            ..OffsetParams::default()
        },
        angles: args.angles as usize,
        size: args.size as usize,
        ..EvalParams::default()
    };
    let report = evaluate(shape.as_ref(), &params)?;
    println!("{}", report.markdown());
    let sweep_rows = if args.sweep {
        let rows = sweep(shape.as_ref(), &params, &SWEEP_GRIDS)?;
        println!("{}", sweep_markdown(shape.name(), &rows));
        Some(rows)
    } else {
        None
    };
    if let Some(path) = &args.json {
        let out = json!({
            "shape": report.shape,
            "params": params,
            "texture": {
                "size": report.texture_size,
                "coverage": report.coverage,
                "negative_share": report.negative_share,
                "capture_ms": report.capture_ms,
                "bytes": report.texture_bytes,
            },
            "offset": report.offset,
            "renderers": report.rows.iter().map(|r| r.json()).collect::<Vec<_>>(),
            "sweep": sweep_rows,
        });
        std::fs::write(path, serde_json::to_string_pretty(&out)?)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The demo section: the pear's cylindrical texture (shaded and signed radius), reconstructions
/// at three angles beside the ground truth (truth | mesh | inverse | fitted | hybrid m = 2), and
/// the table of every renderer (pear in quick mode; pear and truck otherwise).
pub fn demo_section(
    ctx: &DemoContext,
) -> Result<DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    let dir = ctx.out.join("cylinder");
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
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
        let p = RenderParams {
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

#[cfg(test)]
mod tests {
    use super::parse_grid;

    #[test]
    fn grids_parse() {
        assert_eq!(parse_grid("15x8x16"), Ok([15, 8, 16]));
        assert_eq!(parse_grid("8×4×8"), Ok([8, 4, 8]));
        assert!(parse_grid("15x8").is_err());
        assert!(parse_grid("0x8x16").is_err());
        assert!(parse_grid("ax8x16").is_err());
    }
}
