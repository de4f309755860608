//! Draws a minified checkerboard plane at grazing angles with three pyramid lookups on the GPU,
//! side by side with the supersampled truth: mip | rip | fip | truth.
//!
//! Headless: precomputes a mipmap asset and a ripmap asset of the texture with the pipeline
//! (`PyramidRepr` plan, build, write), loads them back through the library's loader, builds the
//! fipmap database with `FipMap::build` (the pipeline does not write fipmaps yet), draws each view
//! with `altrep-display`, and writes under `--out`:
//!
//! * `tilt-<deg>.png`: mip | rip | fip (GPU) | supersampled truth (CPU), one view;
//! * `all-tilts.png`: those rows stacked;
//! * prints, per view and sampler, the PSNR against the truth (GPU and CPU twin) and the median
//!   milliseconds per frame (on lavapipe: CPU emulation, not GPU time).
//!
//! ```text
//! cargo run -p altrep-examples --bin pyramid -- --out target/examples/pyramid
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use altrep::asset::{AssetWriter, Conventions};
use altrep::pyramid::asset::{PyramidAsset, PyramidRepr};
use altrep::pyramid::truth::{PlaneView, footprints, supersampled_truth};
use altrep::pyramid::{FipMap, PyramidData, PyramidParams, Texture, WrapMode};
use altrep::representation::{Needs, Representation, Source};
use altrep_data_gen::{Light, RgbaImage};
use altrep_display::load;
use altrep_display::pyramid::{PyramidDisplay, Sampler, value_psnr, values_to_image};
use altrep_display::{Gpu, to_srgb8};
use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    about = "Draw mip | rip | fip lookups of a grazing checkerboard plane beside the supersampled truth (headless PNG)"
)]
struct Args {
    /// Output folder.
    #[arg(long, default_value = "target/examples/pyramid")]
    out: PathBuf,
    /// Texels per side of the checkerboard texture (8 × 8 squares).
    #[arg(long, default_value_t = 128)]
    size: usize,
    /// Image side of each panel (pixels).
    #[arg(long, default_value_t = 96)]
    pixels: usize,
    /// Texels per pixel at normal incidence.
    #[arg(long, default_value_t = 1.0)]
    texels_per_pixel: f64,
    /// Tilts from the plane normal (degrees), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,60,80,85,88")]
    tilts: Vec<f64>,
    /// Azimuth of the camera from the texture's u axis (degrees).
    #[arg(long, default_value_t = 30.0)]
    azimuth: f64,
    /// Cap on truth samples per pixel.
    #[arg(long, default_value_t = 4096)]
    truth_samples: usize,
    /// Pixel repetition of the written images.
    #[arg(long, default_value_t = 2)]
    scale: u32,
    /// Open a window with orbit controls (not implemented yet).
    #[arg(long)]
    window: bool,
}

/// A periodic grey checkerboard of 8 × 8 squares, values 0.1 and 0.9.
fn checkerboard(n: usize) -> Result<Texture, String> {
    let sq = (n / 8).max(1);
    let data = (0..n * n)
        .map(|k| {
            let (i, j) = (k % n / sq, k / n / sq);
            if (i + j).is_multiple_of(2) { 0.9 } else { 0.1 }
        })
        .collect();
    Texture::new(n, n, 1, data).map_err(|e| e.to_string())
}

fn params() -> PyramidParams {
    PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..PyramidParams::default()
    }
}

/// The asset the planner writes for views up to `grazing` degrees (every level kept), loaded
/// back through the library's loader.
fn precompute(args: &Args, tex: &Texture, grazing: f64) -> Result<PyramidAsset, String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let name = format!("checker-{grazing}");
    let src = Source {
        name: &name,
        geometry: None,
        texture: Some(tex),
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let needs = Needs {
        grazing_deg: grazing,
        screen_px: [1.0, tex.width as f64],
        ..Needs::default()
    };
    let (_, dec) = PyramidRepr::plan(&params(), &needs, &src).map_err(|x| e(&x))?;
    let (data, _) = PyramidRepr::build(&params(), &needs, &dec, &src).map_err(|x| e(&x))?;
    let dir = args.out.join("asset");
    let mut w = AssetWriter::new(&dir, &name, PyramidRepr::NAME).map_err(|x| e(&x))?;
    let meta = PyramidRepr::write(&data, &mut w).map_err(|x| e(&x))?;
    w.commit(
        PyramidRepr::NAME,
        &name,
        "example",
        Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .map_err(|x| e(&x))?;
    load::<PyramidRepr>(&dir.join(&name).join(PyramidRepr::NAME)).map_err(|x| e(&x))
}

/// The CPU twin of a panel (the library's samplers at the same pixel footprints).
fn cpu_values(
    sampler: Sampler,
    view: &PlaneView,
    tex: &Texture,
    pixels: usize,
    mip: &PyramidAsset,
    rip: &PyramidAsset,
    fip: &FipMap,
) -> Vec<f64> {
    let mut out = vec![0.0; pixels * pixels];
    let mut buf = [0.0f32];
    for (k, fp) in footprints(view, tex, pixels).iter().enumerate() {
        let Some(fp) = fp else { continue };
        let [u, v] = fp.uv;
        match sampler {
            Sampler::Mip => mip.sample_into(u, v, fp.derivs, &mut buf),
            Sampler::Rip => rip.sample_into(u, v, fp.derivs, &mut buf),
            Sampler::Fip => {
                let [ux, vx, uy, vy] = fp.derivs;
                fip.sample_into(fip.decide(fp.dir), u, v, ux, vx, uy, vy, None, &mut buf);
            }
        }
        out[k] = f64::from(buf[0]);
    }
    out
}

fn run(args: &Args) -> Result<(), String> {
    if args.window {
        return Err(
            "--window is not implemented yet (no winit front end); the headless output is the \
             supported mode"
                .into(),
        );
    }
    if args.tilts.is_empty() || args.pixels == 0 || args.size == 0 {
        return Err("--tilts, --pixels and --size must not be empty or zero".into());
    }
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let tex = checkerboard(args.size)?;
    let mip = precompute(args, &tex, 0.0)?;
    let rip = precompute(args, &tex, 79.0)?; // 80° and more: the planner writes a fipmap
    if !matches!(mip.data, PyramidData::Mip(_)) || !matches!(rip.data, PyramidData::Rip(_)) {
        return Err("the planner chose other pyramid kinds than expected".into());
    }
    let fip = FipMap::build(tex.clone(), params()).map_err(|x| e(&x))?;
    let gpu = Gpu::headless().map_err(|x| e(&x))?;
    let emulated = gpu.info.device_type == altrep_display::wgpu::DeviceType::Cpu;
    println!("adapter: {}", gpu.describe());
    let disp = PyramidDisplay::new(&gpu, &[&mip, &rip], Some(&fip)).map_err(|x| e(&x))?;
    std::fs::create_dir_all(&args.out).map_err(|x| e(&x))?;
    let bg = [0.0; 3];
    let mut rows = Vec::new();
    let mut ms: Vec<Vec<f64>> = vec![Vec::new(); 3];
    println!(
        "PSNR (dB, peak 1) against the supersampled truth ({}² px, ≤ {} samples/px), GPU (CPU twin):",
        args.pixels, args.truth_samples
    );
    for &tilt in &args.tilts {
        let view = PlaneView {
            texels_per_pixel: args.texels_per_pixel,
            tilt_deg: tilt,
            azimuth_deg: args.azimuth,
        };
        let t = supersampled_truth(&view, &tex, args.pixels, args.truth_samples, 1);
        let truth = values_to_image(&t, 1, args.pixels).map_err(|x| e(&x))?;
        let mut panels = Vec::new();
        let mut line = format!("  tilt {tilt:>4}°:");
        for (k, sampler) in Sampler::ALL.into_iter().enumerate() {
            let f = disp
                .render(&gpu, sampler, &view, args.pixels)
                .map_err(|x| e(&x))?;
            ms[k].push(f.millis);
            let cpu = values_to_image(
                &cpu_values(sampler, &view, &tex, args.pixels, &mip, &rip, &fip),
                1,
                args.pixels,
            )
            .map_err(|x| e(&x))?;
            let db = value_psnr(&f.image, &truth, 1).map_err(|x| e(&x))?;
            let db_cpu = value_psnr(&cpu, &truth, 1).map_err(|x| e(&x))?;
            line += &format!("  {} {db:.2} ({db_cpu:.2})", sampler.name());
            panels.push(f.image);
        }
        println!("{line}");
        panels.push(truth);
        let refs: Vec<&RgbaImage> = panels.iter().collect();
        let row = to_srgb8(&RgbaImage::side_by_side(&refs), bg, args.scale);
        let path = args.out.join(format!("tilt-{tilt}.png"));
        row.save(&path)
            .map_err(|x| format!("{}: {x}", path.display()))?;
        rows.push(row);
    }
    if let Some(first) = rows.first() {
        let (w, h) = first.dimensions();
        let mut all = image::RgbaImage::new(w, h * rows.len() as u32);
        for (k, r) in rows.iter().enumerate() {
            image::imageops::replace(&mut all, r, 0, i64::from(h) * k as i64);
        }
        let path = args.out.join("all-tilts.png");
        all.save(&path)
            .map_err(|x| format!("{}: {x}", path.display()))?;
    }
    for (k, sampler) in Sampler::ALL.into_iter().enumerate() {
        let m = &mut ms[k];
        m.sort_by(f64::total_cmp);
        println!(
            "{}: median {:.2} ms per {}² frame incl. read-back ({})",
            sampler.name(),
            m[m.len() / 2],
            args.pixels,
            if emulated {
                "CPU emulation, not GPU time"
            } else {
                "GPU"
            }
        );
    }
    println!(
        "wrote {}/tilt-*.png and all-tilts.png (mip | rip | fip | supersampled truth)",
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
