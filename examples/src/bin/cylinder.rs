//! Draws a cylindrical-texture impostor on the GPU beside the ray-cast original.
//!
//! Headless by default: precomputes the asset of a bundled shape with the pipeline (or loads an
//! existing asset folder with `--asset`), reads it back through the library's loader, then
//! writes, under `--out`:
//!
//! * `still-<deg>.png`: impostor (GPU) | ray-cast original, at a few azimuths;
//! * `turntable.gif`: the same pair over a full turn;
//! * prints ms per frame (on lavapipe: CPU emulation, not GPU time) and sector tests per
//!   fragment.
//!
//! `--mode bounded` (default) draws the exact march within the asset's stored bounds;
//! `--mode fitted` and `--mode hybrid` draw from offsets the library fits on the loaded texture
//! (the display itself fits nothing).
//!
//! ```text
//! cargo run -p altrep-examples --bin cylinder -- --shape pear --out target/examples/cylinder
//! cargo run -p altrep-examples --features window --bin cylinder -- --shape pear --window
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::asset::{AssetWriter, Conventions};
use altrep::cylinder::asset::{Cylinder, CylinderData, CylinderSpec};
use altrep::cylinder::{OffsetParams, OffsetTexture};
use altrep::representation::{Needs, Representation, Source};
use altrep_data_gen::{
    BoundingCylinder, Light, RgbaImage, Supersample, TruthParams, render_truth, scene_shape,
};
use altrep_display::Precision;
use altrep_display::cylinder::{CylinderDisplay, CylinderDraw, CylinderMode};
use altrep_display::load;
use altrep_display::{Gpu, to_srgb8};
use altrep_examples::window;
use clap::Parser;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};

#[derive(Parser, Debug)]
#[command(
    about = "Draw a cylindrical-texture impostor beside the ray-cast original (headless PNG + GIF)"
)]
struct Args {
    /// Bundled shape to precompute (and to ray-cast for the comparison).
    #[arg(long, default_value = "pear")]
    shape: String,
    /// Load this asset folder (e.g. out/pear/cylinder) instead of precomputing.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "target/examples/cylinder")]
    out: PathBuf,
    /// Texture columns when precomputing (rows are a quarter).
    #[arg(long, default_value_t = 256)]
    columns: usize,
    /// Screen size (pixels, square).
    #[arg(long, default_value_t = 64)]
    size: usize,
    /// Renderer: bounded, fitted or hybrid.
    #[arg(long, default_value = "bounded")]
    mode: String,
    /// Sector tests of the hybrid mode.
    #[arg(long, default_value_t = 4)]
    m: u32,
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

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

fn precompute(args: &Args) -> Result<CylinderData, String> {
    let shape = scene_shape(&args.shape).map_err(err)?;
    let src = Source {
        name: &args.shape,
        geometry: Some(&shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let spec = CylinderSpec {
        columns: args.columns,
        rows: (args.columns / 4).max(2),
        ..CylinderSpec::default()
    };
    let needs = Needs::default();
    let (plan, dec) = Cylinder::plan(&spec, &needs, &src).map_err(err)?;
    if let Some(reason) = &plan.refused {
        return Err(format!("the pipeline refuses {}: {reason}", args.shape));
    }
    let (data, _) = Cylinder::build(&spec, &needs, &dec, &src).map_err(err)?;
    let dir = args.out.join("asset");
    let mut w = AssetWriter::new(&dir, &args.shape, Cylinder::NAME).map_err(err)?;
    let meta = Cylinder::write(&data, &mut w).map_err(err)?;
    w.commit(
        Cylinder::NAME,
        &args.shape,
        "example",
        Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .map_err(err)?;
    // Drawn from the files, through the library's loader, as any user would.
    load::<Cylinder>(&dir.join(&args.shape).join(Cylinder::NAME)).map_err(err)
}

fn run(args: &Args) -> Result<(), String> {
    let mode = match args.mode.as_str() {
        "bounded" => CylinderMode::Bounded,
        "fitted" => CylinderMode::Fitted,
        "hybrid" => CylinderMode::Hybrid { steps: args.m },
        other => return Err(format!("unknown --mode {other} (bounded, fitted, hybrid)")),
    };
    if args.size == 0 || args.size > 4096 {
        return Err(format!("--size {} must be in 1..=4096", args.size));
    }
    let data = match &args.asset {
        Some(dir) => load::<Cylinder>(dir).map_err(err)?,
        None => precompute(args)?,
    };
    // The library fits the offsets of the loaded texture (the fitted and hybrid modes only).
    let offsets = match mode {
        CylinderMode::Bounded => None,
        _ => Some(OffsetTexture::fit(&data.texture, &OffsetParams::default()).map_err(err)?),
    };
    let size = args.size;
    let light = Light::default();
    let draw = |alpha: f64| CylinderDraw {
        alpha,
        width: size,
        height: size,
        mode,
        tolerance_px: 1.0,
        light,
    };
    if args.window {
        return window::run(
            &format!("cylindrical impostor: {} ({})", args.shape, mode.name()),
            false,
            |gpu| CylinderDisplay::new(gpu, &data, offsets.as_ref(), Precision::F32).map_err(err),
            |gpu, disp, orbit| {
                disp.render(gpu, &draw(orbit.azimuth))
                    .map(|f| f.image)
                    .map_err(err)
            },
        )
        .map_err(err);
    }
    let gpu = Gpu::headless().map_err(err)?;
    println!("adapter: {}", gpu.describe());
    let disp = CylinderDisplay::new(&gpu, &data, offsets.as_ref(), Precision::F32).map_err(err)?;
    let shape = scene_shape(&args.shape).map_err(err)?;
    let frame_at = |alpha: f64| -> Result<(RgbaImage, f64, f64), String> {
        let f = disp.render(&gpu, &draw(alpha)).map_err(err)?;
        let truth = render_truth(
            &shape,
            &TruthParams {
                angle: alpha,
                width: size,
                height: size,
                supersample: Supersample::of(3),
                light,
                cylinder: BoundingCylinder::default(),
            },
        )
        .map_err(err)?;
        let steps: u64 = f.steps.iter().map(|s| u64::from(s[0])).sum();
        let pair = RgbaImage::side_by_side(&[&f.image, &truth]);
        Ok((pair, f.millis, steps as f64 / f.steps.len() as f64))
    };
    std::fs::create_dir_all(&args.out).map_err(err)?;
    let bg = [0.18, 0.2, 0.23];
    for deg in [0, 30, 100, 200] {
        let (img, _, _) = frame_at(f64::from(deg).to_radians())?;
        let path = args.out.join(format!("still-{deg:03}.png"));
        to_srgb8(&img, bg, args.scale)
            .save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    let gif_path = args.out.join("turntable.gif");
    let file = std::fs::File::create(&gif_path).map_err(err)?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite).map_err(err)?;
    let (mut ms, mut steps) = (Vec::new(), 0.0);
    let frames = args.frames.max(1);
    for f in 0..frames {
        let alpha = std::f64::consts::TAU * f as f64 / frames as f64;
        let (img, t, s) = frame_at(alpha)?;
        ms.push(t);
        steps += s;
        let frame = Frame::from_parts(
            to_srgb8(&img, bg, args.scale),
            0,
            0,
            Delay::from_numer_denom_ms(60, 1),
        );
        enc.encode_frame(frame).map_err(err)?;
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "{} frames of {size}×{size} ({}, texture {} × {}): median {:.2} ms per frame incl. read-back ({}), {:.2} sector tests per fragment",
        ms.len(),
        mode.name(),
        data.texture.columns(),
        data.texture.rows(),
        ms[ms.len() / 2],
        if gpu.info.device_type == altrep_display::wgpu::DeviceType::Cpu {
            "CPU emulation, not GPU time"
        } else {
            "GPU"
        },
        steps / ms.len() as f64
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
