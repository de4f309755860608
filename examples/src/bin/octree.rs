//! The ellipsoid octree (docs/design.md §8) beside the ray-cast original — a **CPU render**: no GPU
//! display of the octree exists yet, so its levels are drawn by the library's CPU volume renderer
//! (`Octree::render_level`, the one the pipeline's measurement uses).
//!
//! Precomputes the octree asset of a bundled shape with the pipeline (`OctreeRepr` plan, build,
//! write), or takes an existing asset folder (`--asset`), loads it back through the library's
//! loader (`AssetReader::open` + `OctreeRepr::read`) and writes under `--out`:
//!
//! * `<shape>-octree.png`: ray-cast original | octree levels 0, 1, 2 (coarser levels drawn at the
//!   leaves' resolution, so every panel compares pixel for pixel);
//! * prints the PSNR and silhouette IoU of each level against the original.
//!
//! `render_level` looks down `−z` only (the original's azimuth 90°), so there is no turntable.
//!
//! ```text
//! cargo run -p altrep-examples --bin octree -- --shape tree --out target/examples/octree
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::asset::{AssetReader, AssetWriter, Conventions};
use altrep::ellipsoid::asset::{OctreeRepr, OctreeSpec};
use altrep::ellipsoid::octree::OctreeRenderParams;
use altrep::metrics::{psnr, silhouette_iou};
use altrep::representation::{Needs, Representation, Source};
use altrep_data_gen::{
    BoundingCylinder, Light, RgbaImage, Supersample, TruthParams, render_truth, scene_shape,
};
use altrep_display::to_srgb8;
use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    about = "Draw the ellipsoid octree's levels beside the ray-cast original (CPU renders, PNG)"
)]
struct Args {
    /// Bundled shape to precompute and ray-cast.
    #[arg(long, default_value = "tree")]
    shape: String,
    /// Load this octree asset folder (e.g. out/tree/octree) instead of precomputing.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Leaf resolution when precomputing (voxels per side, a power of two).
    #[arg(long, default_value_t = 64)]
    resolution: usize,
    /// Coarsest level drawn.
    #[arg(long, default_value_t = 2)]
    levels: u32,
    /// Output folder.
    #[arg(long, default_value = "target/examples/octree")]
    out: PathBuf,
    /// Pixel repetition of the written image.
    #[arg(long, default_value_t = 3)]
    scale: u32,
}

fn run(args: &Args) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let shape = scene_shape(&args.shape).map_err(|x| e(&x))?;
    let light = Light::default();
    let dir = match &args.asset {
        Some(d) => d.clone(),
        None => {
            let src = Source {
                name: &args.shape,
                geometry: Some(&shape),
                texture: None,
                light,
                placement: None,
            };
            let spec = OctreeSpec {
                resolution: args.resolution,
                ..OctreeSpec::default()
            };
            spec.validate()?;
            let needs = Needs::default();
            let (_, dec) = OctreeRepr::plan(&spec, &needs, &src).map_err(|x| e(&x))?;
            let (tree, _) = OctreeRepr::build(&spec, &needs, &dec, &src).map_err(|x| e(&x))?;
            let root = args.out.join("asset");
            let mut w =
                AssetWriter::new(&root, &args.shape, OctreeRepr::NAME).map_err(|x| e(&x))?;
            let meta = OctreeRepr::write(&tree, &mut w).map_err(|x| e(&x))?;
            w.commit(
                OctreeRepr::NAME,
                &args.shape,
                "example",
                Conventions::new(1.0, 2.0),
                meta,
                serde_json::Value::Null,
            )
            .map_err(|x| e(&x))?;
            root.join(&args.shape).join(OctreeRepr::NAME)
        }
    };
    // Drawn from the files, through the library's loader.
    let reader = AssetReader::open(&dir).map_err(|x| format!("{}: {x}", dir.display()))?;
    let tree = OctreeRepr::read(&reader).map_err(|x| format!("{}: {x}", dir.display()))?;
    let side = 1usize << tree.depth();
    // render_level looks down −z with x to the right: the original's view at azimuth 90°.
    let truth = render_truth(
        &shape,
        &TruthParams {
            angle: std::f64::consts::FRAC_PI_2,
            width: side,
            height: side,
            supersample: Supersample::of(3),
            light,
            cylinder: BoundingCylinder::default(),
        },
    )
    .map_err(|x| e(&x))?;
    let mut params = OctreeRenderParams {
        ambient: f64::from(light.ambient),
        ..OctreeRenderParams::default()
    };
    params.light.x = f64::from(light.direction.x);
    params.light.y = f64::from(light.direction.y);
    params.light.z = f64::from(light.direction.z);
    println!(
        "CPU renders (no GPU display of the octree yet): {} octree of {side}³ leaves against the ray-cast original ({side}² px, azimuth 90°):",
        args.shape
    );
    let mut panels = vec![truth.clone()];
    for level in 0..=args.levels.min(tree.depth()) {
        let t0 = std::time::Instant::now();
        let img = tree.render_level(level, &params).map_err(|x| e(&x))?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let db = psnr(&img, &truth).map_err(|x| e(&x))?;
        let iou = silhouette_iou(&img, &truth, 0.5).map_err(|x| e(&x))?;
        println!(
            "  level {level} ({}³ cells): PSNR {db:.2} dB, IoU {iou:.3}, {ms:.0} ms",
            side >> level
        );
        panels.push(img);
    }
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let refs: Vec<&RgbaImage> = panels.iter().collect();
    let path = args.out.join(format!("{}-octree.png", args.shape));
    to_srgb8(
        &RgbaImage::side_by_side(&refs),
        [0.18, 0.2, 0.23],
        args.scale,
    )
    .save(&path)
    .map_err(|x| format!("{}: {x}", path.display()))?;
    println!(
        "wrote {} (ray-cast original | octree levels 0–{})",
        path.display(),
        panels.len() - 2
    );
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
