//! Volumetric textures as slices (docs/design.md §9) beside the ray-marched volume — a **CPU
//! render**: no GPU display of slice stacks exists yet, so the stacks are drawn by the library's
//! CPU renderer (`altrep::slices::render_slices`, the one `altrep slices --images` uses) and the
//! truth by `altrep::slices::render_truth`. The pipeline writes no slice asset yet either: the
//! stacks are built in memory with `build_slices`.
//!
//! Writes under `--out`:
//!
//! * `<tile>-<polar>deg.png`: slices (direction and merge level chosen by the criterion) | truth;
//! * `turntable-<tile>.gif`: the same pair over a full turn of azimuth at `--turntable-polar`;
//! * prints PSNR against the truth per tile and view, and the slices drawn.
//!
//! ```text
//! cargo run -p altrep-examples --bin slices -- --out target/examples/slices
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::metrics::psnr;
use altrep::slices::{
    SliceParams, SliceRenderParams, StackView, TestTile, VolumeTruthParams, build_slices, choose,
    render_slices, render_truth, test_tile,
};
use altrep_data_gen::RgbaImage;
use altrep_display::to_srgb8;
use clap::Parser;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame};

#[derive(Parser, Debug)]
#[command(about = "Draw slice stacks beside the ray-marched volume (CPU renders, PNG + GIF)")]
struct Args {
    /// Output folder.
    #[arg(long, default_value = "target/examples/slices")]
    out: PathBuf,
    /// Tiles (grass, fur, perlin, tree), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "grass,fur,perlin,tree")]
    tiles: Vec<String>,
    /// Voxels per side of the tiles (a power of two).
    #[arg(long, default_value_t = 32)]
    size: usize,
    /// Polar view angles from the tile normal (degrees), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,30,60,85")]
    polars: Vec<f64>,
    /// Azimuth of the stills (degrees).
    #[arg(long, default_value_t = 30.0)]
    azimuth: f64,
    /// Image side (pixels, one voxel per pixel).
    #[arg(long, default_value_t = 96)]
    pixels: usize,
    /// Tile of the turntable ("none" for no GIF).
    #[arg(long, default_value = "grass")]
    turntable: String,
    /// Polar angle of the turntable (degrees).
    #[arg(long, default_value_t = 60.0)]
    turntable_polar: f64,
    /// Frames of the turntable.
    #[arg(long, default_value_t = 24)]
    frames: usize,
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 2)]
    scale: u32,
    /// Seed of the tiles.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

fn run(args: &Args) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let rp = SliceRenderParams {
        width: args.pixels,
        height: args.pixels,
        ..SliceRenderParams::default()
    };
    let bg = [0.5; 3];
    println!(
        "CPU renders (no GPU display of slices yet); PSNR (dB) of the slices against the ray-marched volume, {}² px:",
        args.pixels
    );
    for name in &args.tiles {
        let tile = TestTile::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or_else(|| format!("unknown tile {name} (grass, fur, perlin, tree)"))?;
        let volume = test_tile(tile, args.size, args.seed).map_err(|x| e(&x))?;
        let (data, _) = build_slices(&volume, &SliceParams::default()).map_err(|x| e(&x))?;
        // The criterion of `altrep slices`: visible depth of one pixel.
        let depth = volume.voxel_size();
        let pair = |view: &StackView| -> Result<(RgbaImage, f64, String), String> {
            let c = choose(&volume, view.vector(), depth, [true; 3]).map_err(|x| e(&x))?;
            let slices = render_slices(&data, c.axis, c.level, view, &rp).map_err(|x| e(&x))?;
            let truth = render_truth(&volume, view, &rp, &VolumeTruthParams::default())
                .map_err(|x| e(&x))?;
            let db = psnr(&slices, &truth).map_err(|x| e(&x))?;
            let what = format!("{}:{}", c.axis.name(), c.slices);
            Ok((RgbaImage::side_by_side(&[&slices, &truth]), db, what))
        };
        let mut line = format!("  {:<7}", tile.name());
        for &polar in &args.polars {
            let (img, db, what) = pair(&StackView::degrees(polar, args.azimuth))?;
            line += &format!("  {polar}° {db:.1} ({what})");
            let path = args.out.join(format!("{}-{polar}deg.png", tile.name()));
            to_srgb8(&img, bg, args.scale)
                .save(&path)
                .map_err(|x| format!("{}: {x}", path.display()))?;
        }
        println!("{line}");
        if *name == args.turntable {
            let path = args.out.join(format!("turntable-{}.gif", tile.name()));
            let file = std::fs::File::create(&path).map_err(|x| e(&x))?;
            let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
            enc.set_repeat(Repeat::Infinite).map_err(|x| e(&x))?;
            let n = args.frames.max(1);
            let mut worst = f64::INFINITY;
            for f in 0..n {
                let az = 360.0 * f as f64 / n as f64;
                let (img, db, _) = pair(&StackView::degrees(args.turntable_polar, az))?;
                worst = worst.min(db);
                enc.encode_frame(Frame::from_parts(
                    to_srgb8(&img, bg, args.scale),
                    0,
                    0,
                    Delay::from_numer_denom_ms(80, 1),
                ))
                .map_err(|x| e(&x))?;
            }
            println!(
                "  wrote {} ({n} frames at {}°, worst PSNR {worst:.1} dB)",
                path.display(),
                args.turntable_polar
            );
        }
    }
    println!(
        "wrote {}/<tile>-<polar>deg.png (slices | ray-marched volume)",
        args.out.display()
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
