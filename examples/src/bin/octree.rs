//! The ellipsoid octree (docs/design.md §8) drawn on the GPU (`altrep_display::octree`, the twin
//! of the library's volume renderer `Octree::render_view_counted`, the one the pipeline's
//! measurement uses) beside the ray-cast original.
//!
//! Precomputes the octree asset of a bundled shape with the pipeline (`OctreeRepr` plan, build,
//! write), or takes an existing asset folder (`--asset`), loads it back through the library's
//! loader and writes under `--out`:
//!
//! * `still-<azimuth>-<elevation>.png`: ray-cast original | octree levels 0, 1, 2 (coarser levels
//!   drawn at the leaves' resolution, so every panel compares pixel for pixel), from below the
//!   horizon to straight down;
//! * `orbit.gif`: the original beside level 0 along a path that circles the object while rising
//!   from 30° below the horizon to the zenith;
//! * prints the PSNR and silhouette IoU of each level against the original, the samples marched
//!   per pixel, and the median ms per frame (on lavapipe: CPU emulation, not GPU time).
//!
//! ```text
//! cargo run -p altrep-examples --bin octree -- --shape tree --out target/examples/octree
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::asset::{AssetReader, AssetWriter, Conventions};
use altrep::ellipsoid::asset::{OctreeRepr, OctreeSpec};
use altrep::ellipsoid::octree::{OctreeRenderParams, OctreeView};
use altrep::metrics::{psnr, silhouette_iou};
use altrep::representation::{Needs, Representation, Source};
use altrep::sphere::azimuth_elevation;
use altrep_data_gen::{Light, OrthoFrame, RgbaImage, Supersample, render_truth_frame, scene_shape};
use altrep_display::octree::OctreeDisplay;
use altrep_display::{Gpu, to_srgb8};
use clap::Parser;
use glam::DVec3;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};

#[derive(Parser, Debug)]
#[command(
    about = "Draw the ellipsoid octree's levels on the GPU beside the ray-cast original (PNG + GIF)"
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
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 3)]
    scale: u32,
    /// Frames of the orbit.
    #[arg(long, default_value_t = 36)]
    frames: usize,
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
                tile: None,
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
    let mut params = OctreeRenderParams {
        ambient: f64::from(light.ambient),
        ..OctreeRenderParams::default()
    };
    params.light.x = f64::from(light.direction.x);
    params.light.y = f64::from(light.direction.y);
    params.light.z = f64::from(light.direction.z);
    let gpu = Gpu::headless().map_err(|x| e(&x))?;
    println!("adapter: {}", gpu.describe());
    let disp = OctreeDisplay::new(&gpu, &tree).map_err(|x| e(&x))?;
    // The window of the bounding cylinder along `d`, as the original and as the tree's cube.
    let at = |d: DVec3| -> Result<(OrthoFrame, OctreeView), String> {
        let frame = OrthoFrame::new(DVec3::Y, 1.0, d).map_err(|x| e(&x))?;
        let half = 0.5 * side as f64;
        let view = OctreeView {
            dir: frame.dir.to_array(),
            right: frame.right.to_array(),
            up: frame.up.to_array(),
            centre: [half; 3],
            half_width: half * frame.radius,
            width: side,
            height: side,
        };
        Ok((frame, view))
    };
    let truth_of = |frame: &OrthoFrame| {
        render_truth_frame(&shape, frame, side, side, Supersample::of(3), &light).map_err(|x| e(&x))
    };
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let bg = [0.18, 0.2, 0.23];
    println!(
        "{} octree of {side}³ leaves on the GPU against the ray-cast original ({side}² px):",
        args.shape
    );
    for (az, el) in [(30, -20), (75, 0), (120, 30), (210, 60), (0, 90)] {
        let d = azimuth_elevation(f64::from(az).to_radians(), f64::from(el).to_radians());
        let (frame, view) = at(d)?;
        let truth = truth_of(&frame)?;
        let mut panels = vec![truth.clone()];
        let mut line = format!("  azimuth {az:3}°, elevation {el:+3}°:");
        for level in 0..=args.levels.min(tree.depth()) {
            let f = disp
                .render(&gpu, level, &params, &view)
                .map_err(|x| e(&x))?;
            let db = psnr(&f.image, &truth).map_err(|x| e(&x))?;
            let iou = silhouette_iou(&f.image, &truth, 0.5).map_err(|x| e(&x))?;
            let steps = f.steps.iter().map(|&s| f64::from(s)).sum::<f64>() / f.steps.len() as f64;
            line += &format!(" level {level} {db:.2} dB, IoU {iou:.3}, {steps:.1} samples/px;");
            panels.push(f.image);
        }
        println!("{line}");
        let refs: Vec<&RgbaImage> = panels.iter().collect();
        let path = args.out.join(format!("still-{az:03}-{el:+03}.png"));
        to_srgb8(&RgbaImage::side_by_side(&refs), bg, args.scale)
            .save(&path)
            .map_err(|x| format!("{}: {x}", path.display()))?;
    }
    let gif_path = args.out.join("orbit.gif");
    let file = std::fs::File::create(&gif_path).map_err(|x| e(&x))?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite).map_err(|x| e(&x))?;
    let frames = args.frames.max(1);
    let mut ms = Vec::new();
    for k in 0..frames {
        let u = k as f64 / frames as f64;
        let el = (-30.0 + 120.0 * u).min(90.0).to_radians();
        let (frame, view) = at(azimuth_elevation(std::f64::consts::TAU * u, el))?;
        let f = disp.render(&gpu, 0, &params, &view).map_err(|x| e(&x))?;
        ms.push(f.millis);
        let img = RgbaImage::side_by_side(&[&truth_of(&frame)?, &f.image]);
        enc.encode_frame(Frame::from_parts(
            to_srgb8(&img, bg, args.scale),
            0,
            0,
            Delay::from_numer_denom_ms(80, 1),
        ))
        .map_err(|x| e(&x))?;
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "{frames} frames of {side}²: median {:.2} ms per frame incl. the host's shading and read-back ({})",
        ms[ms.len() / 2],
        if gpu.info.device_type == altrep_display::wgpu::DeviceType::Cpu {
            "CPU emulation, not GPU time"
        } else {
            "GPU"
        },
    );
    println!(
        "wrote {} and still-*.png (ray-cast original | octree levels 0–{})",
        gif_path.display(),
        args.levels.min(tree.depth())
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
