//! Draws an images-with-parallax asset on the GPU beside the ray-cast original.
//!
//! Headless by default: precomputes the asset of a bundled shape with the pipeline (or loads an
//! existing asset folder with `--asset`), then writes, under `--out`:
//!
//! * `still-<deg>.png`: impostor (GPU) | ray-cast original, at a few azimuths;
//! * `turntable.gif`: the same pair over a full turn;
//! * prints ms per frame (on lavapipe: CPU emulation, not GPU time) and march steps per fragment.
//!
//! ```text
//! cargo run -p altrep-examples --bin parallax -- --shape truck --out target/examples/parallax
//! ```
//!
//! `--window` (built with `--features window`) opens a winit window instead (drag: azimuth, wheel: zoom; images with parallax are
//! captured from horizontal views, so there is no elevation); without a display it fails with
//! "no display: set DISPLAY or WAYLAND_DISPLAY".

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::parallax::BoundKind;
use altrep::parallax::Reconstruction;
use altrep::parallax::asset::{Parallax, ParallaxData, ParallaxSpec};
use altrep::representation::{Needs, Source};
use altrep_data_gen::{
    BoundingCylinder, Light, RgbaImage, Supersample, TruthParams, render_truth, scene_shape,
};
use altrep_display::Precision;
use altrep_display::load;
use altrep_display::parallax::{DrawParams, ParallaxDisplay};
use altrep_display::{Gpu, to_srgb8};
use altrep_examples::window;
use clap::Parser;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};

#[derive(Parser, Debug)]
#[command(about = "Draw a parallax impostor beside the ray-cast original (headless PNG + GIF)")]
struct Args {
    /// Bundled shape to precompute (and to ray-cast for the comparison).
    #[arg(long, default_value = "truck")]
    shape: String,
    /// Load this asset folder (e.g. out/truck/parallax) instead of precomputing.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "target/examples/parallax")]
    out: PathBuf,
    /// View size when precomputing (texels; the screen is the same size).
    #[arg(long, default_value_t = 64)]
    size: usize,
    /// Bound kind: cylinder, zminmax, pair, best_c, best_c_split.
    #[arg(long, default_value = "best_c")]
    bounds: String,
    /// Frames of the turntable.
    #[arg(long, default_value_t = 48)]
    frames: usize,
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 3)]
    scale: u32,
    /// Open a window with orbit controls (drag: azimuth, wheel: zoom) instead of writing files.
    #[arg(long)]
    window: bool,
}

fn precompute(args: &Args, kind: BoundKind) -> Result<ParallaxData, String> {
    let shape = scene_shape(&args.shape).map_err(|e| e.to_string())?;
    let src = Source {
        name: &args.shape,
        geometry: Some(&shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let spec = ParallaxSpec {
        size: args.size,
        bounds: vec![kind.slug().to_string()],
        ..ParallaxSpec::default()
    };
    let needs = Needs::default();
    // Drawn from the files, through the library's loader, as any user would.
    altrep_examples::precompute::<Parallax>(&spec, &needs, &src, &args.out)
}

fn run(args: &Args) -> Result<(), String> {
    let kind = BoundKind::ALL
        .into_iter()
        .find(|k| k.slug() == args.bounds)
        .ok_or_else(|| format!("unknown --bounds {}", args.bounds))?;
    let data = match &args.asset {
        Some(dir) => load::<Parallax>(dir).map_err(|e| e.to_string())?,
        None => precompute(args, kind)?,
    };
    let p = &data.images.params;
    let (w, h) = (p.width, p.height);
    if args.window {
        return window::run(
            &format!("parallax impostor: {} ({})", args.shape, kind.name()),
            false,
            |gpu| ParallaxDisplay::new(gpu, &data, Precision::F32).map_err(|e| e.to_string()),
            |gpu, disp, orbit| {
                disp.render(
                    gpu,
                    &DrawParams {
                        alpha: orbit.azimuth,
                        kind,
                        width: w,
                        height: h,
                        light: Light::default(),
                        rec: Reconstruction::DEFAULT,
                    },
                )
                .map(|f| f.image)
                .map_err(|e| e.to_string())
            },
        )
        .map_err(|e| e.to_string());
    }
    let gpu = Gpu::headless().map_err(|e| e.to_string())?;
    println!("adapter: {}", gpu.describe());
    let disp = ParallaxDisplay::new(&gpu, &data, Precision::F32).map_err(|e| e.to_string())?;
    let shape = scene_shape(&args.shape).map_err(|e| e.to_string())?;
    let light = Light::default();
    let frame_at = |alpha: f64| -> Result<(RgbaImage, f64, f64), String> {
        let f = disp
            .render(
                &gpu,
                &DrawParams {
                    alpha,
                    kind,
                    width: w,
                    height: h,
                    light,
                    rec: Reconstruction::DEFAULT,
                },
            )
            .map_err(|e| e.to_string())?;
        let truth = render_truth(
            &shape,
            &TruthParams {
                angle: alpha,
                width: w,
                height: h,
                supersample: Supersample::of(3),
                light,
                cylinder: BoundingCylinder::default(),
            },
        )
        .map_err(|e| e.to_string())?;
        let steps: u64 = f.steps.iter().flatten().map(|&s| u64::from(s)).sum();
        let pair = RgbaImage::side_by_side(&[&f.image, &truth]);
        Ok((pair, f.millis, steps as f64 / f.steps.len() as f64))
    };
    std::fs::create_dir_all(&args.out).map_err(|e| e.to_string())?;
    let bg = [0.18, 0.2, 0.23];
    for deg in [0, 30, 100, 200] {
        let (img, _, _) = frame_at(f64::from(deg).to_radians())?;
        let path = args.out.join(format!("still-{deg:03}.png"));
        to_srgb8(&img, bg, args.scale)
            .save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    let gif_path = args.out.join("turntable.gif");
    let file = std::fs::File::create(&gif_path).map_err(|e| e.to_string())?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite)
        .map_err(|e| e.to_string())?;
    let (mut ms, mut steps) = (Vec::new(), 0.0);
    for f in 0..args.frames.max(1) {
        let alpha = std::f64::consts::TAU * f as f64 / args.frames.max(1) as f64;
        let (img, t, s) = frame_at(alpha)?;
        ms.push(t);
        steps += s;
        let frame = Frame::from_parts(
            to_srgb8(&img, bg, args.scale),
            0,
            0,
            Delay::from_numer_denom_ms(60, 1),
        );
        enc.encode_frame(frame).map_err(|e| e.to_string())?;
    }
    let n = ms.len();
    println!(
        "{n} frames of {w}×{h} ({}): {}, {:.2} march steps per fragment (two views)",
        kind.name(),
        altrep_examples::median_frame_time(&gpu, &mut ms),
        steps / n as f64
    );
    println!(
        "wrote {} and still-*.png (impostor | ray-cast original)",
        gif_path.display()
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
