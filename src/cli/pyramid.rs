//! `altrep pyramid` — pyramids for minification (docs/design.md §10): the error/time table of mip,
//! rip, fip and EWA lookups against the supersampled truth over distances and tilts, build times
//! per prefilter, and the PSNR of quad-tree texture fusion with and without median rejection.

use std::path::PathBuf;
use std::time::Instant;

use serde_json::json;

use super::CliResult;
use crate::pyramid::fusion::fusion_experiment;
use crate::pyramid::truth::{METHODS, test_texture};
use crate::pyramid::{
    AlphaMode, ColourSpace, Filter, Pyramid, PyramidParams, SweepParams, SweepReport, Texture,
    WrapMode, measure_sweep,
};

/// Arguments of `altrep pyramid`.
#[derive(clap::Args, Debug)]
pub struct PyramidArgs {
    /// Side of the square test texture of the sweep, in texels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(4..=2048))]
    pub size: u32,
    /// Prefilter of every pyramid: box, triangle, kaiser or lanczos.
    #[arg(long, default_value = "box")]
    pub filter: String,
    /// Image side of each view, in pixels.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub pixels: u32,
    /// Cap on supersampled truth samples per pixel.
    #[arg(long, default_value_t = 8192)]
    pub max_samples: u32,
    /// Side of the RGBA sRGB texture whose mip chain is timed per filter (0: skip).
    #[arg(long, default_value_t = 1024)]
    pub build_size: u32,
    /// Side of the fused texture (a power of two).
    #[arg(long, default_value_t = 128)]
    pub fusion_size: u32,
    /// Write every figure as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Parses a filter name (box, triangle, kaiser, lanczos; any case).
pub fn parse_filter(s: &str) -> Result<Filter, String> {
    match s.to_ascii_lowercase().as_str() {
        "box" => Ok(Filter::Box),
        "triangle" => Ok(Filter::Triangle),
        "kaiser" => Ok(Filter::Kaiser),
        "lanczos" => Ok(Filter::Lanczos),
        _ => Err(format!(
            "unknown filter {s:?}: use box, triangle, kaiser or lanczos"
        )),
    }
}

/// Runs the sweep, the build timings and the fusion experiment; prints the tables.
pub fn run(args: PyramidArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let filter = parse_filter(&args.filter)?;
    let params = PyramidParams {
        filter,
        wrap: [WrapMode::Repeat; 2],
        ..Default::default()
    };
    let sweep = SweepParams {
        pixels: args.pixels as usize,
        max_samples_per_pixel: args.max_samples as usize,
        ..Default::default()
    };
    let tex = test_texture(args.size as usize, 7);
    let report = measure_sweep(&tex, &params, &sweep)?;
    print_sweep(&report, args.size, filter, args.pixels);

    // Build time of an RGBA sRGB straight-alpha mip chain per filter.
    let mut builds = Vec::new();
    if args.build_size > 0 {
        let n = args.build_size as usize;
        let data: Vec<f32> = (0..n * n * 4)
            .map(|k| ((k * 7919) % 251) as f32 / 250.0)
            .collect();
        let base = Texture::new(n, n, 4, data)?;
        println!(
            "mip chain build, {n}×{n} RGBA, sRGB in linear light, straight alpha (dev profile, all cores):"
        );
        for f in [
            Filter::Box,
            Filter::Triangle,
            Filter::Kaiser,
            Filter::Lanczos,
        ] {
            let p = PyramidParams {
                filter: f,
                colour: ColourSpace::Srgb,
                alpha: AlphaMode::Straight,
                ..Default::default()
            };
            let start = Instant::now();
            let pyr = Pyramid::build(base.clone(), p)?;
            let s = start.elapsed().as_secs_f64();
            // The same filter on the `image` crate (RGBA8, no linear light, kernel point-sampled
            // at texel centres where ours integrates it over each texel), each level resized from
            // level 0; its largest difference from our linear-colour levels in 8-bit steps.
            let image_filter = match f {
                Filter::Triangle => Some(image::imageops::FilterType::Triangle),
                Filter::Lanczos => Some(image::imageops::FilterType::Lanczos3),
                _ => None,
            };
            let mut line = format!("  {f:?}: {s:.3} s, {} levels", pyr.levels().len());
            let mut entry = json!({"filter": format!("{f:?}"), "seconds": s, "size": n});
            if let Some(ft) = image_filter {
                let bytes: Vec<u8> = base
                    .data
                    .iter()
                    .map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
                    .collect();
                let img = image::RgbaImage::from_raw(n as u32, n as u32, bytes)
                    .ok_or("image buffer size")?;
                let start = Instant::now();
                let theirs: Vec<image::RgbaImage> = pyr.levels()[1..]
                    .iter()
                    .map(|l| image::imageops::resize(&img, l.width as u32, l.height as u32, ft))
                    .collect();
                let t_image = start.elapsed().as_secs_f64();
                let linear = Pyramid::build(
                    base.clone(),
                    PyramidParams {
                        filter: f,
                        ..Default::default()
                    },
                )?;
                let max_diff = linear.levels()[1..]
                    .iter()
                    .zip(&theirs)
                    .flat_map(|(a, b)| {
                        a.data.iter().zip(b.as_raw()).map(|(x, y)| {
                            ((x.clamp(0.0, 1.0) * 255.0).round() - f32::from(*y)).abs()
                        })
                    })
                    .fold(0.0f32, f32::max);
                line += &format!(
                    "; image crate {ft:?} (8-bit, gamma space, one thread) {t_image:.3} s, ratio ours/image {:.2}, largest difference from our linear-colour levels {max_diff} of 255",
                    s / t_image
                );
                entry["image_seconds"] = json!(t_image);
                entry["image_max_diff_u8"] = json!(max_diff);
            }
            println!("{line}");
            builds.push(entry);
        }
    }

    let fusion = fusion_experiment(args.fusion_size as usize, 3)?;
    println!(
        "quad-tree fusion, {0}×{0} RGB, 5 views (scales 0,0,0,1,1), occluder in 2: PSNR {1:.2} dB with median rejection, {2:.2} dB without; rejected per level {3:?} of {4:?}",
        args.fusion_size,
        fusion.psnr_with_rejection,
        fusion.psnr_without_rejection,
        fusion.report.rejected,
        fusion.report.offered
    );

    if let Some(path) = &args.json {
        let doc = json!({
            "methods": METHODS,
            "sweep": report,
            "filter": format!("{filter:?}"),
            "texture_size": args.size,
            "builds": builds,
            "fusion": fusion,
        });
        super::write_json(path, &doc)?;
    }
    Ok(())
}

/// Prints the sweep table of [`measure_sweep`] (RMS error against the supersampled truth and ns
/// per lookup of mip, rip, fip and EWA per view) and the per-method win counts.
pub fn print_sweep(report: &SweepReport, size: u32, filter: Filter, pixels: u32) {
    let args_size = size;
    let args_pixels = pixels;
    println!(
        "pyramid sweep: {0}×{0} grey test texture, {1:?} prefilter, {2}×{2} pixels per view; \
         RMS error against the supersampled truth (texel-value units) and ns per lookup \
         (one thread); truth noise = RMS noise of the reference",
        args_size, filter, args_pixels
    );
    println!(
        "{:>6} {:>6} {:>5} {:>9} | {:>8} {:>8} {:>8} {:>8} | {:>6} {:>6} {:>6} {:>6} | decision",
        "D0", "tilt", "az", "truth±", "mip", "rip", "fip", "ewa", "ns mip", "rip", "fip", "ewa",
    );
    for r in &report.rows {
        println!(
            "{:>6.1} {:>6.1} {:>5.1} {:>9.5} | {:>8.5} {:>8.5} {:>8.5} {:>8.5} | {:>6.0} {:>6.0} {:>6.0} {:>6.0} | {:?}",
            r.view.texels_per_pixel,
            r.view.tilt_deg,
            r.view.azimuth_deg,
            r.truth_noise,
            r.rms[0],
            r.rms[1],
            r.rms[2],
            r.rms[3],
            r.ns_per_sample[0],
            r.ns_per_sample[1],
            r.ns_per_sample[2],
            r.ns_per_sample[3],
            r.scheme
        );
    }
    let wins = |k: usize| {
        report
            .rows
            .iter()
            .filter(|r| (0..4).all(|j| r.rms[k] <= r.rms[j]))
            .count()
    };
    println!(
        "best per row: mip {}, rip {}, fip {}, ewa {} of {}; bytes (f32): mip {}, rip {}, fip database {}; fip build {:.2} s",
        wins(0),
        wins(1),
        wins(2),
        wins(3),
        report.rows.len(),
        report.mip_bytes,
        report.rip_bytes,
        report.fip_bytes,
        report.build_seconds
    );
}

/// A black/white checkerboard of `n × n` texels with squares of `square` texels (one channel,
/// linear values 0 and 1, periodic).
pub fn checkerboard(n: usize, square: usize) -> Result<Texture, crate::pyramid::MipError> {
    let data = (0..n * n)
        .map(|k| (((k % n) / square + (k / n) / square) % 2) as f32)
        .collect();
    Texture::new(n, n, 1, data)
}

/// Demo section: a checkerboard plane seen at grazing angles, mip, rip and fip lookups side by
/// side with the supersampled truth (one PNG per tilt: truth | mip | rip | fip), and the RMS
/// error of each against the truth.
pub fn demo_section(
    ctx: &super::demo::DemoContext,
) -> Result<super::demo::DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    use crate::pyramid::FipMap;
    use crate::pyramid::truth::{
        LookupMethod, PlaneView, footprints, lookup_all, rms, supersampled_truth,
    };
    let dir = ctx.dir;
    let (pixels, samples) = if ctx.quick { (32, 256) } else { (64, 1024) };
    let tex = checkerboard(64, 8)?;
    let params = PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..Default::default()
    };
    let fip = FipMap::build(tex.clone(), params)?;
    let mut rows = Vec::new();
    let mut md = format!(
        "A 64² black/white checkerboard (8-texel squares, periodic) on a plane seen at grazing \
         angles, azimuth 30° from the `u` axis, {pixels}² px, 2 texels per pixel face on; each \
         image: supersampled truth (≤ {samples} samples/px) | trilinear mipmap | ripmap | fipmap \
         (per-pixel mip/rip/fip decision). RMS error against the truth (values in [0, 1]).\n\n\
         | tilt | mip | rip | fip | fip's choice at the centre |\n|---|---|---|---|---|\n"
    );
    let grey = |v: &[f64]| altrep_data_gen::RgbaImage {
        width: pixels,
        height: pixels,
        pixels: v
            .iter()
            .map(|&g| {
                let g = g.clamp(0.0, 1.0) as f32;
                [g, g, g, 1.0]
            })
            .collect(),
    };
    for tilt in [75.0, 85.0, 89.0] {
        let view = PlaneView {
            texels_per_pixel: 2.0,
            tilt_deg: tilt,
            azimuth_deg: 30.0,
        };
        let truth = supersampled_truth(&view, &tex, pixels, samples, 1);
        let fps = footprints(&view, &tex, pixels);
        let mut errs = Vec::new();
        let mut images = vec![grey(&truth)];
        for m in [LookupMethod::Mip, LookupMethod::Rip, LookupMethod::Fip] {
            let (vals, _) = lookup_all(&fip, m, &fps, 1);
            errs.push(rms(&vals, &truth));
            images.push(grey(&vals));
        }
        let centre = fps[(pixels / 2) * pixels + pixels / 2].map(|f| fip.decide(f.dir));
        let file = format!("checker-tilt{tilt:.0}.png");
        altrep_data_gen::RgbaImage::side_by_side(&images.iter().collect::<Vec<_>>())
            .write_png(&dir.join(&file))?;
        md += &format!(
            "| {tilt:.0}° | {:.4} | {:.4} | {:.4} | {centre:?} |\n",
            errs[0], errs[1], errs[2]
        );
        rows.push(json!({ "tilt_deg": tilt, "rms": { "mip": errs[0], "rip": errs[1], "fip": errs[2] },
                          "centre_scheme": format!("{centre:?}"), "image": format!("pyramids/{file}") }));
    }
    md += "\n";
    for tilt in [75, 85, 89] {
        md += &format!("![checkerboard at {tilt}°](pyramids/checker-tilt{tilt}.png)\n\n");
    }
    Ok(super::demo::DemoSection {
        name: "pyramids".into(),
        json: json!(rows),
        markdown: md,
    })
}
