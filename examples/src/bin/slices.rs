//! Draws a tile's slices over a ground patch on the GPU (docs/design.md §9, §9.4), beside the
//! ray-marched volume: a lawn from grazing to straight down.
//!
//! Headless by default: precomputes the slices of a procedural tile (`--tile`: grass, fur,
//! perlin or tree) with the pipeline's verbs, as `tile = { … }` with `[asset.slices]` in a
//! manifest does (or loads an existing tile asset with `--asset`, such as the demo's
//! `lawn/slices`), reads them back through the library's loader, then writes, under `--out`:
//!
//! * `still-<polar>.png`: the unbounded patch (GPU) | the ray-marched tile, from straight down
//!   to grazing, `--tiles-across` tiles across the screen;
//! * `field.png`: a bounded field of `--field × --field` tiles seen at `--turntable-polar`;
//! * `turntable.gif`: the pair over a full turn of azimuth at `--turntable-polar`;
//! * prints, per still, the PSNR against the ray-marched tile, the stack drawn (axis and merge
//!   level) and the slices read per pixel, and the median ms per frame (on lavapipe: CPU
//!   emulation, not GPU time).
//!
//! ```text
//! cargo run -p altrep-examples --bin slices -- --tile grass --out target/examples/slices
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::metrics::psnr;
use altrep::representation::{Lighting, Needs, Source};
use altrep::slices::asset::{SlicesAsset, SlicesRepr, SlicesSpec};
use altrep::slices::{
    SliceLighting, SliceRenderParams, StackView, TestTile, VolumeTruthParams, render_truth,
    test_tile_lit,
};
use altrep_data_gen::{Light, RgbaImage, Supersample};
use altrep_display::Gpu;
use altrep_display::load;
use altrep_display::slices::{SlicesDisplay, SlicesDraw};
use altrep_display::to_srgb8;
use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    about = "Draw a tile's slices over a ground patch on the GPU beside the ray-marched tile (headless PNG + GIF)"
)]
struct Args {
    /// Procedural tile to precompute (grass, fur, perlin, tree).
    #[arg(long, default_value = "grass")]
    tile: String,
    /// Load this tile asset folder (e.g. altrep-out/scene/lawn/slices) instead of precomputing;
    /// the comparison marches `--tile` with `--size` and `--seed`, so they must match it.
    #[arg(long)]
    asset: Option<PathBuf>,
    /// Voxels per side of the tile (a power of two).
    #[arg(long, default_value_t = 32)]
    size: usize,
    /// Seed of the tile.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder.
    #[arg(long, default_value = "target/examples/slices")]
    out: PathBuf,
    /// Screen size in pixels.
    #[arg(long, default_value_t = 96)]
    screen: usize,
    /// Tiles across the screen of the stills and the turntable.
    #[arg(long, default_value_t = 2.0)]
    tiles_across: f64,
    /// Polar angles of the stills from the ground's normal (degrees), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,30,60,80")]
    polars: Vec<f64>,
    /// Azimuth of the stills (degrees).
    #[arg(long, default_value_t = 30.0)]
    azimuth: f64,
    /// Polar angle of the turntable and of the field (degrees).
    #[arg(long, default_value_t = 60.0)]
    turntable_polar: f64,
    /// Frames of the turntable.
    #[arg(long, default_value_t = 24)]
    frames: usize,
    /// Tiles per side of the bounded field.
    #[arg(long, default_value_t = 4)]
    field: u32,
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 2)]
    scale: u32,
}

/// The tile, lit by the scene's default light as the pipeline lights a `tile` source.
fn tile_volume(args: &Args) -> Result<altrep::slices::TexelVolume, String> {
    let tile = TestTile::ALL
        .into_iter()
        .find(|t| t.name() == args.tile)
        .ok_or_else(|| format!("--tile {}: one of grass, fur, perlin, tree", args.tile))?;
    let light = Light::default();
    let lighting = SliceLighting {
        direction: light.direction.to_array(),
        ambient: light.ambient,
    };
    test_tile_lit(tile, args.size, args.seed, &lighting).map_err(|e| e.to_string())
}

/// Plans, builds, writes and loads back the slices of `volume` as the pipeline does for a tile
/// seen from its normal to 85°, from 8 pixels across a tile to one pixel per voxel.
fn precompute(args: &Args, volume: &altrep::slices::TexelVolume) -> Result<SlicesAsset, String> {
    let src = Source {
        name: &args.tile,
        geometry: None,
        texture: None,
        tile: Some(volume),
        light: Light::default(),
        placement: None,
    };
    let spec = SlicesSpec::default();
    let needs = Needs {
        screen_px: [8.0, args.size as f64],
        grazing_deg: 85.0,
        lighting: Lighting::Baked,
        ..Needs::default()
    };
    // Drawn from the files, through the library's loader, as any user would.
    altrep_examples::precompute::<SlicesRepr>(&spec, &needs, &src, &args.out)
}

fn run(args: &Args) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let screen = args.screen;
    if !(1..=4096).contains(&screen) {
        return Err(format!("--screen {screen} must be in 1..=4096"));
    }
    if !(args.tiles_across.is_finite() && args.tiles_across > 0.0) {
        return Err(format!("--tiles-across {} must be > 0", args.tiles_across));
    }
    let volume = tile_volume(args)?;
    let asset = match &args.asset {
        Some(dir) => load::<SlicesRepr>(dir).map_err(|x| e(&x))?,
        None => precompute(args, &volume)?,
    };
    if asset.slices.dims() != volume.dims() {
        return Err(format!(
            "the asset holds {:?} voxels, the tile {:?}: give the asset's --size",
            asset.slices.dims(),
            volume.dims()
        ));
    }
    let gpu = Gpu::headless().map_err(|x| e(&x))?;
    println!("adapter: {}", gpu.describe());
    let n = asset.slices.dims()[0] as f64;
    let stacks: Vec<String> = asset
        .slices
        .stacks()
        .iter()
        .map(|s| format!("{}{}", s.axis().name(), s.level()))
        .collect();
    println!(
        "slices of a {n}³ {} tile, rule {}, stacks {}",
        args.tile,
        asset.slices.rule().name(),
        stacks.join(" ")
    );
    let disp = SlicesDisplay::new(&gpu, &asset).map_err(|x| e(&x))?;
    // Voxels per pixel, and the truth's rays per pixel side (half a voxel apart).
    let p = n * args.tiles_across / screen as f64;
    let truth_params = SliceRenderParams {
        width: screen,
        height: screen,
        pixel_voxels: p,
        supersample: Supersample::of(((2.0 * p).ceil() as usize).clamp(1, 8)),
        ..SliceRenderParams::default()
    };
    // (slices | truth, ms, slices per pixel, PSNR, stack)
    let pair = |view: &StackView| -> Result<(RgbaImage, f64, f64, f64, String), String> {
        let draw = SlicesDraw::over_tile(&asset, view, screen, p, [0.0; 2]).map_err(|x| e(&x))?;
        let fr = disp.render(&gpu, &draw).map_err(|x| e(&x))?;
        let truth = render_truth(&volume, view, &truth_params, &VolumeTruthParams::default())
            .map_err(|x| e(&x))?;
        let db = psnr(&fr.image, &truth).map_err(|x| e(&x))?;
        let stack = format!("{}{}", fr.stack.0.name(), fr.stack.1);
        let img = RgbaImage::side_by_side(&[&fr.image, &truth]);
        Ok((img, fr.millis, fr.steps_per_pixel(), db, stack))
    };
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let bg = [0.5; 3];
    for &polar in &args.polars {
        let (img, _, steps, db, stack) = pair(&StackView::degrees(polar, args.azimuth))?;
        let path = args.out.join(format!("still-{polar:02}.png"));
        to_srgb8(&img, bg, args.scale)
            .save(&path)
            .map_err(|x| format!("{}: {x}", path.display()))?;
        println!(
            "polar {polar:4.1}°, azimuth {}°: PSNR {db:.2} dB, stack {stack}, {steps:.1} slices per pixel",
            args.azimuth
        );
    }
    // A bounded field, framed round its centre with room for its height at the angle.
    let field = args.field.max(1);
    let view = StackView::degrees(args.turntable_polar, args.azimuth);
    let l = n * asset.slices.voxel_size();
    let half = 0.5 * f64::from(field) * l;
    let mut draw =
        SlicesDraw::over_tile(&asset, &view, screen, 1.0, [0.0; 2]).map_err(|x| e(&x))?;
    draw.frame.centre = glam::DVec3::new(half, 0.5 * l, half);
    draw.frame.radius = 1.5 * half;
    draw.choose_px = screen as f64 / (1.5 * f64::from(field));
    draw.patch = [field, field];
    let fr = disp.render(&gpu, &draw).map_err(|x| e(&x))?;
    let path = args.out.join("field.png");
    to_srgb8(&fr.image, bg, args.scale)
        .save(&path)
        .map_err(|x| format!("{}: {x}", path.display()))?;
    println!(
        "field of {field}×{field} tiles at {}°: stack {}{}",
        args.turntable_polar,
        fr.stack.0.name(),
        fr.stack.1
    );
    let gif_path = args.out.join("turntable.gif");
    let (mut ms, worst) =
        altrep_examples::write_turntable(&gif_path, args.frames, bg, args.scale, |u| {
            let (img, t, _, db, _) = pair(&StackView::degrees(args.turntable_polar, 360.0 * u))?;
            Ok((img, t, db))
        })?;
    println!(
        "{} frames of {screen}²: {}, worst PSNR {worst:.2} dB",
        ms.len(),
        altrep_examples::median_frame_time(&gpu, &mut ms)
    );
    println!(
        "wrote {}, {} and still-*.png (slices | ray-marched tile)",
        gif_path.display(),
        path.display()
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
