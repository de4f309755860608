//! `altrep sphere` — images with parallax from any direction (docs/design.md §7b): the exact warp
//! of octahedral frames against the engines' octahedral impostor, memory against PSNR.

use std::path::PathBuf;

use altrep_data_gen::Supersample;
use serde_json::json;

use super::CliResult;
use super::capture::load_shape;
use crate::sphere::{
    Coverage, HoleFill, SphereImages, SphereMeasureParams, SphereMeasurement, SphereParams,
    SphereRenderParams, Storage, SurfaceModel, ViewSet, budget_table, check_bounds,
    fibonacci_directions, measure_stored, truth_images,
};

/// Arguments of `altrep sphere`.
#[derive(clap::Args, Debug)]
pub struct SphereArgs {
    /// Mesh to represent (.obj, .gltf or .glb).
    #[arg(long, conflicts_with = "shape", required_unless_present = "shape")]
    pub mesh: Option<PathBuf>,
    /// How the mesh file is read.
    #[command(flatten)]
    pub read: crate::cli::capture::MeshReadArgs,
    /// Procedural shape instead (sphere, box, torus, capsule, pear, truck, chair, tree, building).
    #[arg(long)]
    pub shape: Option<String>,
    /// Cover the whole sphere instead of the upper hemisphere.
    #[arg(long)]
    pub full_sphere: bool,
    /// Frames per side G of the octahedral grids to measure. 3 is in the default: over the upper
    /// hemisphere its 9 frames (the zenith and 8 around the horizon) give the exact warp its
    /// best mean PSNR at 0.5–2 MiB on opaque meshes (bench/RESULTS.md, "Fewer, larger frames").
    #[arg(long, value_delimiter = ',', default_value = "3,4,8,16")]
    pub grids: Vec<usize>,
    /// Texels per frame side F to measure.
    #[arg(long, value_delimiter = ',', default_value = "32,64,128")]
    pub sizes: Vec<usize>,
    /// Test directions (Fibonacci spiral).
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub directions: u32,
    /// Output image side in pixels.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub out_size: u32,
    /// Rays per output pixel edge, both methods: k × k rays per pixel.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub supersample: u32,
    /// Rays per pixel edge of the ground truth: k × k rays per pixel.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub truth_supersample: u32,
    /// Flat texel tops instead of tangent planes.
    #[arg(long)]
    pub flat: bool,
    /// March the whole chord of the bounding sphere (no bounds) — to measure what the bounds save.
    #[arg(long)]
    pub no_bounds: bool,
    /// Also check the bounds on a sweep of this many times more directions (0: skip), at a
    /// quarter of the output size.
    #[arg(long, default_value_t = 0)]
    pub check_factor: u32,
    /// Memory budgets (MiB) of the summary table.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8,16,32")]
    pub budgets: Vec<f64>,
    /// Instead of `--sizes`, measure for each grid and budget the largest frame size that fits
    /// the budget, once for the exact warp's bytes and once for the baseline's (equal memory),
    /// capped at `--max-size`.
    #[arg(long)]
    pub fit_budgets: bool,
    /// Count and draw the frames block-compressed as a GPU samples them (docs/design.md §7b,
    /// "Compressed memory"): the baseline's two BC7 atlases (2 bytes per texel), the exact
    /// warp's BC7 albedo, BC5 normals, raw depth and bounds rebuilt from the decoded frames (6
    /// bytes per texel). `--fit-budgets` then fits the compressed bytes.
    #[arg(long)]
    pub compressed: bool,
    /// With `--compressed`, bits of the exact warp's stored depth: 16 (default) or 8 (an R8
    /// texture, the baseline's depth precision: one byte per texel less).
    #[arg(long, default_value_t = 16, requires = "compressed", value_parser = clap::builder::TypedValueParser::map(clap::builder::PossibleValuesParser::new(["8", "16"]), |s| if s == "8" { 8u32 } else { 16 }))]
    pub depth_bits: u32,
    /// Print, per configuration, the directions where the exact warp scores lowest (elevation,
    /// azimuth, PSNR of both methods, share of rays no frame sees).
    #[arg(long, default_value_t = 0)]
    pub worst: usize,
    /// Print, per configuration, where each method's error lies: MSE ×10⁴ in the silhouette
    /// band (≤ 1 px, 2 px), the interior and outside, and the alpha bias (mean alpha minus the
    /// truth's; negative: missing coverage).
    #[arg(long)]
    pub split: bool,
    /// How the exact warp draws a ray whose surface point no frame sees (a hole): `offsets`
    /// draws it from the enclosing frames' one-step offsets, read where the march stopped;
    /// `nearest` colours it from the nearest frame surface, within `--hole-depth`
    /// (`SphereRenderParams::holes`).
    #[arg(long, default_value = "offsets", value_parser = clap::builder::TypedValueParser::map(clap::builder::PossibleValuesParser::new(["offsets", "nearest"]), |s| if s == "nearest" { HoleFill::Nearest } else { HoleFill::Offsets }))]
    pub holes: HoleFill,
    /// With `--holes nearest`: take a hole as empty when the nearest frame surface lies farther
    /// than this from it (frame units, sphere radius 1); 0 colours every hole.
    #[arg(long, default_value_t = crate::sphere::DEFAULT_HOLE_DEPTH)]
    pub hole_depth: f64,
    /// Where no enclosing frame sees the point found, ask up to this many more frames (the
    /// nearest to the direction first); 0 asks only the three enclosing frames.
    #[arg(long, default_value_t = crate::sphere::DEFAULT_EXTRA_FRAMES)]
    pub extra_frames: usize,
    /// Cap each ray's march fetches of the exact warp at this many (0: no cap): a ray that
    /// reaches it stops marching and is drawn as the engine blend draws it, from the one-step
    /// offsets of its enclosing frames (`SphereRenderParams::max_steps`).
    #[arg(long, default_value_t = 0)]
    pub max_steps: u32,
    /// Frame texels per side of one cone-bounds texel: 1, 2 or 4. Coarser bounds store fewer
    /// bytes (2 per bounds texel) for the same pictures; the march reads more texels
    /// (docs/design.md §7b, "Coarser bounds").
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4))]
    pub bounds_block: u32,
    /// Largest frame size `--fit-budgets` may choose.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub max_size: u32,
    /// Write the tables as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `altrep sphere`.
pub fn run(args: SphereArgs) -> CliResult {
    // Check the output path before the work.
    if let Some(path) = &args.json {
        if path.is_dir() {
            return Err(format!("--json {} is a folder", path.display()).into());
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
        }
    }
    let shape = load_shape(args.mesh.as_ref(), args.shape.as_deref(), &args.read)?;
    let coverage = if args.full_sphere {
        Coverage::Sphere
    } else {
        Coverage::Hemisphere
    };
    let params = SphereMeasureParams {
        directions: args.directions as usize,
        render: SphereRenderParams {
            size: args.out_size as usize,
            supersample: Supersample::of(args.supersample as usize),
            use_bounds: !args.no_bounds,
            holes: args.holes,
            hole_depth: (args.hole_depth != 0.0).then_some(args.hole_depth),
            extra_frames: args.extra_frames,
            max_steps: (args.max_steps != 0).then_some(args.max_steps),
            ..SphereRenderParams::default()
        },
        truth_supersample: Supersample::of(args.truth_supersample as usize),
    };
    // Bad render parameters (e.g. too many extra frames) are refused before the truths are cast.
    params.render.validate()?;
    let model = if args.flat {
        SurfaceModel::Flat
    } else {
        SurfaceModel::DEFAULT
    };
    let storage = if args.compressed && args.depth_bits == 8 {
        Storage::CompressedDepth8
    } else if args.compressed {
        Storage::Compressed
    } else {
        Storage::Raw
    };
    let dirs = fibonacci_directions(params.directions, coverage);
    let t = std::time::Instant::now();
    let truths = truth_images(
        shape.as_ref(),
        &dirs,
        params.render.size,
        params.truth_supersample,
        &params.render.light,
    )?;
    // The truth again at the drawings' own rays, where its rays are others: the error without
    // the difference in sampling (MethodStats::psnr_same_positions_mean).
    let same = (params.truth_supersample != params.render.supersample)
        .then(|| {
            truth_images(
                shape.as_ref(),
                &dirs,
                params.render.size,
                params.render.supersample,
                &params.render.light,
            )
        })
        .transpose()?;
    let same_positions = same.as_deref().or(Some(&truths[..]));
    println!(
        "{}: {} directions over the {}, truth {}² with {}×{} rays per pixel ({:.1} s); both methods draw {}² with {}×{} rays per pixel",
        shape.name(),
        dirs.len(),
        if args.full_sphere {
            "sphere"
        } else {
            "upper hemisphere"
        },
        params.render.size,
        params.truth_supersample.get(),
        params.truth_supersample.get(),
        t.elapsed().as_secs_f64(),
        params.render.size,
        params.render.supersample.get(),
        params.render.supersample.get()
    );
    // Bytes per texel of each method, from the byte counts themselves: a 4 × 4 frame is one
    // whole block, and its bounds texels (1, 2 or 4 per side) cover it exactly.
    let unit = SphereParams {
        set: ViewSet::new(coverage, 2)?,
        size: 4,
        model,
        bounds_block: args.bounds_block as usize,
    };
    let per_texel = |bytes: usize| bytes as f64 / (unit.set.len() * 16) as f64;
    println!(
        "memory counted {}: {} bytes per texel (exact warp, depth in {} bits), {} (baseline){}; bounds over {b} × {b} texels",
        if storage.is_compressed() {
            "block-compressed"
        } else {
            "raw"
        },
        per_texel(unit.warp_bytes(storage)),
        storage.warp_depth_bits(),
        per_texel(unit.baseline_bytes(storage)),
        if storage.is_compressed() {
            ", sides padded to whole 4 × 4 blocks"
        } else {
            ""
        },
        b = args.bounds_block
    );
    println!(
        "{:>3} {:>4} | {:>9} {:>7} {:>7} {:>6} {:>6} {:>5} | {:>9} {:>7} {:>7} {:>6} | {:>6} {:>6} {:>6}",
        "G",
        "F",
        "ours MiB",
        "PSNR",
        "min",
        "IoU",
        "steps",
        "max",
        "base MiB",
        "PSNR",
        "min",
        "IoU",
        "cap s",
        "bnd s",
        "holes"
    );
    let configs = configurations(&args, coverage, storage)?;
    let mut rows: Vec<SphereMeasurement> = Vec::new();
    let mut checks = Vec::new();
    for &(g, f) in &configs {
        let sp = SphereParams {
            set: ViewSet::new(coverage, g)?,
            size: f,
            model,
            bounds_block: args.bounds_block as usize,
        };
        let images = SphereImages::capture(shape.as_ref(), &sp)?;
        let m = measure_stored(&images, storage, &dirs, &truths, same_positions, &params)?;
        let mib = |b: usize| b as f64 / (1024.0 * 1024.0);
        println!(
            "{:>3} {:>4} | {:>9.3} {:>7.2} {:>7.2} {:>6.3} {:>6.1} {:>5} | {:>9.3} {:>7.2} {:>7.2} {:>6.3} | {:>6.2} {:>6.2} {:>6.4}",
            g,
            f,
            mib(m.bytes_ours),
            m.ours.psnr_mean,
            m.ours.psnr_min,
            m.ours.iou_mean,
            m.ours.steps_mean,
            m.ours.steps_max,
            mib(m.bytes_baseline),
            m.baseline.psnr_mean,
            m.baseline.psnr_min,
            m.baseline.iou_mean,
            m.capture_s,
            m.bounds_s,
            m.ours.hole_share
        );
        if args.split {
            for (name, st) in [
                ("ours", &m.ours),
                ("baseline", &m.baseline),
                ("2-step", &m.baseline_two_step),
            ] {
                let e = &st.split;
                println!(
                    "        split {name:>8}: MSE×1e4 band≤1px {:7.3}, band 2px {:6.3}, interior {:7.3}, outside {:6.3}; alpha bias {:+.4}",
                    e.band1_mse * 1e4,
                    e.band2_mse * 1e4,
                    e.interior_mse * 1e4,
                    e.outside_mse * 1e4,
                    e.alpha_bias
                );
            }
        }
        if args.worst > 0 {
            let mut order: Vec<usize> = (0..m.directions.len()).collect();
            order.sort_by(|&a, &b| {
                m.ours.psnr_per_direction[a].total_cmp(&m.ours.psnr_per_direction[b])
            });
            for &k in order.iter().take(args.worst) {
                let [x, y, z] = m.directions[k];
                println!(
                    "        worst: elevation {:5.1}° azimuth {:6.1}°: ours {:6.2} dB, baseline {:6.2} dB, rays no frame sees {:.4}",
                    y.clamp(-1.0, 1.0).asin().to_degrees(),
                    z.atan2(x).to_degrees(),
                    m.ours.psnr_per_direction[k],
                    m.baseline.psnr_per_direction[k],
                    m.ours.holes_per_direction[k]
                );
            }
        }
        if args.check_factor > 0 {
            let fine = fibonacci_directions(dirs.len() * args.check_factor as usize, coverage);
            let c = check_bounds(&images, &fine, (params.render.size / 4).max(8))?;
            println!(
                "        bounds check: {} directions, {} marches, {} violations (worst excess {:.2e})",
                c.directions, c.marches, c.violations, c.worst_excess
            );
            checks.push(json!({"grid": g, "size": f, "check": c}));
        }
        if storage.is_compressed() {
            println!(
                "          block compression of both layouts: {:.2} s; the warp's bounds from the decoded frames: {:.2} s",
                m.encode_s, m.bounds_s
            );
        }
        println!(
            "          two-step baseline: {:>7.2} {:>7.2} {:>6.3}",
            m.baseline_two_step.psnr_mean,
            m.baseline_two_step.psnr_min,
            m.baseline_two_step.iou_mean
        );
        let reads = |s: &crate::sphere::MethodStats| {
            format!(
                "{:.1} / {:.1} / {}",
                s.reads_mean, s.reads_hit_mean, s.reads_max
            )
        };
        let db = crate::sphere::asset::decibels;
        println!(
            "          FLIP mean (lower is better): ours {:.4}, one-step {:.4}, two-step {:.4}; colour PSNR where both cover: ours {}, one-step {}, two-step {}",
            m.ours.flip_mean,
            m.baseline.flip_mean,
            m.baseline_two_step.flip_mean,
            db(m.ours.colour_psnr_mean),
            db(m.baseline.colour_psnr_mean),
            db(m.baseline_two_step.colour_psnr_mean)
        );
        println!(
            "          PSNR against the truth cast at the drawings' own rays: ours {}, one-step {}, two-step {}",
            db(m.ours.psnr_same_positions_mean),
            db(m.baseline.psnr_same_positions_mean),
            db(m.baseline_two_step.psnr_same_positions_mean)
        );
        println!(
            "          texel reads per ray, mean / over hits / max: ours {}, one-step {}, two-step {}",
            reads(&m.ours),
            reads(&m.baseline),
            reads(&m.baseline_two_step)
        );
        if params.render.max_steps.is_some() {
            println!(
                "          rays stopped by the cap of {} fetches: {:.5}",
                args.max_steps, m.ours.capped_share
            );
        }
        rows.push(m);
    }
    let budgets = budget_table(&rows, &args.budgets);
    println!(
        "\nbest mean PSNR within each memory budget (same selection rule for all; the gain is \
         over the better of the two baselines), with that configuration's mean FLIP:"
    );
    println!(
        "{:>8} | {:>25} | {:>27} | {:>27} | {:>7}",
        "MiB",
        "ours (G, F) PSNR FLIP",
        "baseline (G, F) PSNR FLIP",
        "2-step (G, F) PSNR FLIP",
        "gain"
    );
    let flip =
        |g: usize, f: usize, which: fn(&SphereMeasurement) -> &crate::sphere::MethodStats| {
            rows.iter()
                .find(|m| (m.grid, m.size) == (g, f))
                .map_or("—".to_string(), |m| format!("{:.4}", which(m).flip_mean))
        };
    let cell = |x: Option<(usize, usize, f64)>,
                which: fn(&SphereMeasurement) -> &crate::sphere::MethodStats| {
        x.map_or("—".to_string(), |(g, f, p)| {
            format!("({g:>2}, {f:>3}) {p:6.2} {}", flip(g, f, which))
        })
    };
    for b in &budgets {
        let strongest = [b.baseline, b.baseline_two_step]
            .into_iter()
            .flatten()
            .map(|s| s.2)
            .reduce(f64::max);
        let gain = match (b.ours, strongest) {
            (Some(o), Some(s)) => format!("{:+.2}", o.2 - s),
            _ => "—".into(),
        };
        println!(
            "{:>8} | {:>25} | {:>27} | {:>27} | {:>7}",
            b.budget_mib,
            cell(b.ours, |m| &m.ours),
            cell(b.baseline, |m| &m.baseline),
            cell(b.baseline_two_step, |m| &m.baseline_two_step),
            gain
        );
    }
    if let Some(path) = &args.json {
        let doc = json!({
            "shape": shape.name(),
            "params": params,
            "rows": rows,
            "budgets": budgets,
            "bounds_checks": checks,
        });
        super::write_json(path, &doc)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The `(G, F)` pairs to measure: `--grids × --sizes`, or with `--fit-budgets` the largest size
/// of each grid that fits each budget for either method (sorted, without repeats).
fn configurations(
    args: &SphereArgs,
    coverage: Coverage,
    storage: Storage,
) -> Result<Vec<(usize, usize)>, String> {
    let mut v = Vec::new();
    for &g in &args.grids {
        if !args.fit_budgets {
            v.extend(args.sizes.iter().map(|&f| (g, f)));
            continue;
        }
        let set = ViewSet::new(coverage, g).map_err(|e| e.to_string())?;
        let frames = set.len();
        for &b in &args.budgets {
            if !(b.is_finite() && b > 0.0) {
                return Err(format!("budget {b} MiB must be finite and positive"));
            }
            let bytes = b * 1024.0 * 1024.0;
            let params = |size| SphereParams {
                set,
                size,
                model: SurfaceModel::DEFAULT,
                bounds_block: args.bounds_block as usize,
            };
            let methods: [fn(&SphereParams, Storage) -> usize; 2] =
                [SphereParams::warp_bytes, SphereParams::baseline_bytes];
            for bytes_of in methods {
                // The largest size within the budget: from the bytes per texel (of a frame of
                // one whole block), then down while the padding to whole blocks overflows it.
                let per_texel = bytes_of(&params(4), storage) as f64 / (frames * 16) as f64;
                let mut f = (bytes / (frames as f64 * per_texel)).sqrt().floor() as usize;
                f = f.min(args.max_size as usize);
                while f >= 8 && bytes_of(&params(f), storage) as f64 > bytes {
                    f -= 1;
                }
                if f >= 8 {
                    v.push((g, f));
                }
            }
        }
    }
    v.sort_unstable();
    v.dedup();
    Ok(v)
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        args: SphereArgs,
    }

    #[test]
    fn budgets_are_fitted_with_the_bytes_of_the_storage() {
        // `--fit-budgets` at 0.5 MiB on 16 frames, with bounds over `block × block` texels.
        let fit = |block: &str, storage| {
            let args = Command::try_parse_from([
                "sphere",
                "--shape",
                "chair",
                "--grids",
                "4",
                "--fit-budgets",
                "--budgets",
                "0.5",
                "--bounds-block",
                block,
            ])
            .unwrap()
            .args;
            configurations(&args, Coverage::Hemisphere, storage).unwrap()
        };
        // Raw, 10 and 8 bytes per texel give 57² and 64².
        assert_eq!(fit("1", Storage::Raw), vec![(4, 57), (4, 64)]);
        // Compressed, 6 and 2 bytes per texel: 73² would fit unpadded, but its blocks cover
        // 76² and overflow the budget, so the warp gets 72²; the baseline 128².
        assert_eq!(fit("1", Storage::Compressed), vec![(4, 72), (4, 128)]);
        // Bounds over 2 × 2 texels: 8.5 and 4.5 bytes per texel for the warp, 62² and 84²
        // (85² would pad to 88² and overflow); the baseline's sizes do not change.
        assert_eq!(fit("2", Storage::Raw), vec![(4, 62), (4, 64)]);
        assert_eq!(fit("2", Storage::Compressed), vec![(4, 84), (4, 128)]);
    }
}
