//! Draws images with parallax from any direction on the GPU, beside the engines' octahedral
//! impostor built from the same frames and the ray-cast original.
//!
//! Headless by default: precomputes the frames of a bundled shape with the pipeline (or loads an
//! existing asset folder with `--asset`), reads them back through the library's loader, then
//! writes, under `--out`:
//!
//! * `still-<azimuth>-<elevation>.png`: exact warp (GPU) | engine blend (CPU) | ray-cast original,
//!   from the horizon to straight down;
//! * `orbit.gif`: the same triple along a path that circles the object while rising from the
//!   horizon to the zenith;
//! * prints, per still, the PSNR of both against the original, and the median ms per frame (on
//!   lavapipe: CPU emulation, not GPU time) and texel fetches per ray of the GPU draw.
//!
//! ```text
//! cargo run -p altrep-examples --bin sphere -- --shape truck --out target/examples/sphere
//! ```
//!
//! `--window` (built with `--features window`) opens a winit window instead (drag: azimuth and elevation, wheel: zoom); without a
//! display it fails with "no display: set DISPLAY or WAYLAND_DISPLAY".

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::metrics::psnr;
use altrep::representation::{Needs, Source};
use altrep::sphere::asset::{SphereRepr, SphereSpec};
use altrep::sphere::{
    SphereImages, SphereRenderParams, azimuth_elevation, render_engine_baseline, truth_images,
};
use altrep_data_gen::{Light, RgbaImage, Supersample, scene_shape};
use altrep_display::Precision;
use altrep_display::load;
use altrep_display::sphere::{SphereDisplay, SphereDraw};
use altrep_display::{Gpu, to_srgb8};
use altrep_examples::window;
use clap::Parser;
use glam::DVec3;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};

#[derive(Parser, Debug)]
#[command(
    about = "Draw any-direction images with parallax beside the engine impostor and the ray-cast original (headless PNG + GIF)"
)]
struct Args {
    /// Bundled shape to precompute (and to ray-cast for the comparison).
    #[arg(long, default_value = "truck")]
    shape: String,
    /// Load this asset folder (e.g. out/truck-from-above/sphere) instead of precomputing; its
    /// frames must have been captured from `--shape` for the comparison to mean anything.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "target/examples/sphere")]
    out: PathBuf,
    /// Frames per side of the hemi-octahedral grid when precomputing.
    #[arg(long, default_value_t = 8)]
    grid: usize,
    /// Frames asked beyond the three enclosing ones where none of those sees the point found
    /// (0 to 8; `altrep::sphere::SphereRenderParams::extra_frames`).
    #[arg(long, default_value_t = altrep::sphere::DEFAULT_EXTRA_FRAMES)]
    extra_frames: usize,
    /// Cap each ray's fetches at this many (0: no cap; `altrep::sphere::SphereRenderParams::max_steps`):
    /// bounds the time a few long rays hold up the fragments shaded beside them.
    #[arg(long, default_value_t = 0)]
    max_steps: u32,
    /// Texels per frame side when precomputing.
    #[arg(long, default_value_t = 64)]
    size: usize,
    /// Screen size in pixels.
    #[arg(long, default_value_t = 96)]
    screen: usize,
    /// Frames of the orbit.
    #[arg(long, default_value_t = 36)]
    frames: usize,
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 3)]
    scale: u32,
    /// Open a window with orbit controls instead of writing files.
    #[arg(long)]
    window: bool,
}

fn precompute(args: &Args) -> Result<SphereImages, String> {
    let shape = scene_shape(&args.shape).map_err(|e| e.to_string())?;
    let src = Source {
        name: &args.shape,
        geometry: Some(&shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let spec = SphereSpec {
        grid: args.grid,
        size: args.size,
        ..SphereSpec::default()
    };
    spec.validate()?;
    let needs = Needs {
        elevation_deg: [0.0, 90.0],
        screen_px: [1.0, args.size as f64],
        ..Needs::default()
    };
    // Drawn from the files, through the library's loader, as any user would.
    altrep_examples::precompute::<SphereRepr>(&spec, &needs, &src, &args.out)
}

fn run(args: &Args) -> Result<(), String> {
    let images = match &args.asset {
        Some(dir) => load::<SphereRepr>(dir).map_err(|e| e.to_string())?,
        None => precompute(args)?,
    };
    let screen = args.screen;
    let draw = |d: DVec3| SphereDraw {
        extra_frames: args.extra_frames,
        max_steps: (args.max_steps != 0).then_some(args.max_steps),
        ..SphereDraw::new(d, screen)
    };
    if !(1..=4096).contains(&screen) {
        return Err(format!("--screen {screen} must be in 1..=4096"));
    }
    let (g, f) = (images.params.set.grid, images.params.size);
    if args.window {
        return window::run(
            &format!(
                "any-direction impostor: {} ({g}×{g} frames of {f}²)",
                args.shape
            ),
            true,
            |gpu| SphereDisplay::new(gpu, &images, Precision::F32).map_err(|e| e.to_string()),
            |gpu, disp, orbit| {
                // Below the horizon a hemisphere has no frames: the elevation stops at 0.
                let d = azimuth_elevation(
                    orbit.azimuth,
                    orbit.elevation.clamp(0.0, std::f64::consts::FRAC_PI_2),
                );
                disp.render(gpu, &draw(d))
                    .map(|f| f.image)
                    .map_err(|e| e.to_string())
            },
        )
        .map_err(|e| e.to_string());
    }
    let gpu = Gpu::headless().map_err(|e| e.to_string())?;
    println!("adapter: {}", gpu.describe());
    println!("frames: {g}×{g} of {f}² ({:?})", images.params.set.coverage);
    let disp = SphereDisplay::new(&gpu, &images, Precision::F32).map_err(|e| e.to_string())?;
    let shape = scene_shape(&args.shape).map_err(|e| e.to_string())?;
    let light = Light::default();
    let cpu = SphereRenderParams {
        size: screen,
        ..SphereRenderParams::default()
    };
    // (impostor | engine | original, ms, fetches per ray, PSNR ours, PSNR engine)
    let triple = |d: DVec3| -> Result<(RgbaImage, f64, f64, f64, f64), String> {
        let fr = disp.render(&gpu, &draw(d)).map_err(|e| e.to_string())?;
        let engine = render_engine_baseline(&images, d, &cpu).map_err(|e| e.to_string())?;
        let truth = truth_images(&shape, &[d], screen, Supersample::of(3), &light)
            .map_err(|e| e.to_string())?
            .remove(0);
        let ours_db = psnr(&fr.image, &truth).map_err(|e| e.to_string())?;
        let engine_db = psnr(&engine.image, &truth).map_err(|e| e.to_string())?;
        let img = RgbaImage::side_by_side(&[&fr.image, &engine.image, &truth]);
        Ok((img, fr.millis, fr.mean_steps(), ours_db, engine_db))
    };
    std::fs::create_dir_all(&args.out).map_err(|e| e.to_string())?;
    let bg = [0.18, 0.2, 0.23];
    for (az, el) in [(30, 5), (120, 30), (210, 60), (0, 90)] {
        let d = azimuth_elevation(f64::from(az).to_radians(), f64::from(el).to_radians());
        let (img, _, steps, ours, engine) = triple(d)?;
        let path = args.out.join(format!("still-{az:03}-{el:02}.png"));
        to_srgb8(&img, bg, args.scale)
            .save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        println!(
            "azimuth {az:3}°, elevation {el:2}°: PSNR exact warp {ours:.2} dB, engine blend {engine:.2} dB; {steps:.1} fetches per ray"
        );
    }
    let gif_path = args.out.join("orbit.gif");
    let file = std::fs::File::create(&gif_path).map_err(|e| e.to_string())?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite)
        .map_err(|e| e.to_string())?;
    let n = args.frames.max(1);
    let (mut ms, mut steps) = (Vec::new(), 0.0);
    for k in 0..n {
        let u = k as f64 / n as f64;
        let d = azimuth_elevation(std::f64::consts::TAU * u, 1.55 * u);
        let (img, t, s, _, _) = triple(d)?;
        ms.push(t);
        steps += s;
        let frame = Frame::from_parts(
            to_srgb8(&img, bg, args.scale),
            0,
            0,
            Delay::from_numer_denom_ms(80, 1),
        );
        enc.encode_frame(frame).map_err(|e| e.to_string())?;
    }
    let n = ms.len();
    println!(
        "{n} frames of {screen}²: {}, {:.1} texel fetches per ray",
        altrep_examples::median_frame_time(&gpu, &mut ms),
        steps / n as f64
    );
    println!(
        "wrote {} and still-*.png (exact warp | engine blend | ray-cast original)",
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
