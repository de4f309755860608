//! Draws the slices of an object on the GPU (docs/design.md §9.4), beside the ray-cast original.
//!
//! Headless by default: precomputes the slices of a bundled shape with the pipeline's verbs (or
//! loads an existing asset folder with `--asset`, such as the demo's `tree/slices`), reads them
//! back through the library's loader, then writes, under `--out`:
//!
//! * `still-<azimuth>-<elevation>.png`: slices (GPU) | ray-cast original, from below the horizon
//!   to straight down;
//! * `orbit.gif`: the same pair along a path that circles the object while rising from 30° below
//!   the horizon to the zenith;
//! * prints, per still, the PSNR against the original, the stack drawn (axis and merge level)
//!   and the slices read per covered pixel, and the median ms per frame (on lavapipe: CPU
//!   emulation, not GPU time).
//!
//! ```text
//! cargo run -p altrep-examples --bin slices-object -- --shape tree --out target/examples/slices-object
//! ```
//!
//! `--window` (built with `--features window`) opens a winit window instead (drag: azimuth and elevation, wheel: zoom); without a
//! display it fails with "no display: set DISPLAY or WAYLAND_DISPLAY".

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::metrics::psnr;
use altrep::representation::{Lighting, Needs, Source};
use altrep::slices::asset::{SlicesAsset, SlicesRepr, SlicesSpec};
use altrep::sphere::azimuth_elevation;
use altrep_data_gen::{Light, RgbaImage, Supersample, render_truth_frame, scene_shape};
use altrep_display::Gpu;
use altrep_display::load;
use altrep_display::slices::{SlicesDisplay, SlicesDraw};
use altrep_display::to_srgb8;
use altrep_examples::window;
use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    about = "Draw the slices of an object on the GPU beside the ray-cast original (headless PNG + GIF)"
)]
struct Args {
    /// Bundled shape to precompute (and to ray-cast for the comparison).
    #[arg(long, default_value = "tree")]
    shape: String,
    /// Load this asset folder (e.g. altrep-out/scene/tree/slices) instead of precomputing; it
    /// must hold slices of `--shape` for the comparison to mean anything.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "target/examples/slices-object")]
    out: PathBuf,
    /// Voxels per side when precomputing (a power of two, 4 to 256).
    #[arg(long, default_value_t = 64)]
    resolution: usize,
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

fn precompute(args: &Args) -> Result<SlicesAsset, String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let shape = scene_shape(&args.shape).map_err(|x| e(&x))?;
    let src = Source {
        name: &args.shape,
        geometry: Some(&shape),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let spec = SlicesSpec {
        resolution: args.resolution,
        ..SlicesSpec::default()
    };
    spec.validate()?;
    // Every direction, from below to above, up to the resolution on screen: all three axes
    // and every merge level.
    let needs = Needs {
        elevation_deg: [-90.0, 90.0],
        screen_px: [1.0, args.resolution as f64],
        lighting: Lighting::Baked,
        ..Needs::default()
    };
    // Drawn from the files, through the library's loader, as any user would.
    altrep_examples::precompute::<SlicesRepr>(&spec, &needs, &src, &args.out)
}

fn run(args: &Args) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let asset = match &args.asset {
        Some(dir) => load::<SlicesRepr>(dir).map_err(|x| e(&x))?,
        None => precompute(args)?,
    };
    let screen = args.screen;
    if !(1..=4096).contains(&screen) {
        return Err(format!("--screen {screen} must be in 1..=4096"));
    }
    let n = asset.slices.dims()[0];
    if args.window {
        return window::run(
            &format!("slices: {} ({n}³ voxels)", args.shape),
            true,
            |gpu| SlicesDisplay::new(gpu, &asset).map_err(|x| e(&x)),
            |gpu, disp, orbit| {
                let d = azimuth_elevation(orbit.azimuth, orbit.elevation);
                let draw = SlicesDraw::new(d, screen).map_err(|x| e(&x))?;
                disp.render(gpu, &draw).map(|f| f.image).map_err(|x| e(&x))
            },
        )
        .map_err(|x| e(&x));
    }
    let gpu = Gpu::headless().map_err(|x| e(&x))?;
    println!("adapter: {}", gpu.describe());
    let stacks: Vec<String> = asset
        .slices
        .stacks()
        .iter()
        .map(|s| format!("{}{}", s.axis().name(), s.level()))
        .collect();
    println!(
        "slices: {n}³ voxels, rule {}, stacks {}",
        asset.slices.rule().name(),
        stacks.join(" ")
    );
    let disp = SlicesDisplay::new(&gpu, &asset).map_err(|x| e(&x))?;
    let shape = scene_shape(&args.shape).map_err(|x| e(&x))?;
    // (slices | original, ms, slices per pixel, PSNR, stack)
    let pair = |az: f64, el: f64| -> Result<(RgbaImage, f64, f64, f64, String), String> {
        let draw = SlicesDraw::new(azimuth_elevation(az, el), screen).map_err(|x| e(&x))?;
        let fr = disp.render(&gpu, &draw).map_err(|x| e(&x))?;
        let truth = render_truth_frame(
            &shape,
            &draw.frame,
            screen,
            screen,
            Supersample::of(3),
            &Light::default(),
        )
        .map_err(|x| e(&x))?;
        let db = psnr(&fr.image, &truth).map_err(|x| e(&x))?;
        let stack = format!("{}{}", fr.stack.0.name(), fr.stack.1);
        let img = RgbaImage::side_by_side(&[&fr.image, &truth]);
        Ok((img, fr.millis, fr.steps_per_pixel(), db, stack))
    };
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let bg = [0.18, 0.2, 0.23];
    for (az, el) in [(30, -20), (75, 0), (120, 30), (210, 60), (0, 90)] {
        let (img, _, steps, db, stack) =
            pair(f64::from(az).to_radians(), f64::from(el).to_radians())?;
        let path = args.out.join(format!("still-{az:03}-{el:+03}.png"));
        to_srgb8(&img, bg, args.scale)
            .save(&path)
            .map_err(|x| format!("{}: {x}", path.display()))?;
        println!(
            "azimuth {az:3}°, elevation {el:+3}°: PSNR {db:.2} dB, stack {stack}, {steps:.1} slices per pixel"
        );
    }
    let gif_path = args.out.join("orbit.gif");
    let (mut ms, worst) =
        altrep_examples::write_turntable(&gif_path, args.frames, bg, args.scale, |u| {
            let el = (-30.0 + 120.0 * u).min(90.0).to_radians();
            let (img, t, _, db, _) = pair(std::f64::consts::TAU * u, el)?;
            Ok((img, t, db))
        })?;
    println!(
        "{} frames of {screen}²: {}, worst PSNR {worst:.2} dB",
        ms.len(),
        altrep_examples::median_frame_time(&gpu, &mut ms)
    );
    println!(
        "wrote {} and still-*.png (slices | ray-cast original)",
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
