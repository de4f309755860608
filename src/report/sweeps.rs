//! The six sweeps of the report. Each calls the measurement function the representation's own
//! command calls and only reshapes its rows into [`Point`]s.

use std::path::Path;

use altrep_data_gen::{Mesh, MeshLoadOptions, Shape, scene_shape};

use super::{Cost, Point, Reference, ReportError, RepresentationReport};

fn err<E: std::fmt::Display>(representation: &'static str) -> impl Fn(E) -> ReportError {
    move |e| ReportError::Measure {
        representation,
        message: e.to_string(),
    }
}

/// The object of a sweep: the mesh at `mesh`, or the procedural shape `default`.
fn object(
    representation: &'static str,
    mesh: Option<&Path>,
    default: &str,
) -> Result<Box<dyn Shape>, ReportError> {
    match mesh {
        Some(path) => Ok(Box::new(
            Mesh::load(path, &MeshLoadOptions::default()).map_err(err(representation))?,
        )),
        None => Ok(Box::new(scene_shape(default).map_err(err(representation))?)),
    }
}

fn grid_label(c: [usize; 3]) -> String {
    format!("{}×{}×{}", c[0], c[1], c[2])
}

/// The trilinear fit of `altrep fit-bench`'s test function (step, z periodic): the grid at the
/// default λ and solver, then at 15×8×16 the λ ladder, every solver configuration and a range of
/// tolerances. Cost: assembly + solve (ms), coefficient bytes at 16 bits, solver iterations;
/// error: RMS over the defined samples. Operating point: the source's 15×8×16 grid.
pub fn fit(quick: bool) -> Result<RepresentationReport, ReportError> {
    use crate::cli::fit_bench::{configurations, test_function};
    use crate::fit::{DEFAULT_LAMBDA, FitParams, FitSamples, Fitter};
    const R: &str = "fit";
    let e = err::<crate::fit::FitError>(R);
    let samples_dims = if quick { [32, 16, 32] } else { [128, 64, 256] };
    let samples = FitSamples::from_fn(samples_dims, test_function).map_err(&e)?;
    let periodic = [false, false, true];
    let source = [15, 8, 16];
    let grids: Vec<[usize; 3]> = if quick {
        vec![[4, 2, 4], [8, 4, 8], source]
    } else {
        vec![[8, 4, 8], [11, 6, 12], source, [23, 12, 24], [31, 16, 32]]
    };
    let point = |series: &str, label: String, fitter: &Fitter, params: &FitParams| {
        let f = fitter.fit(params)?;
        let r = &f.report;
        let mut p = Point::new(R, series, label);
        p.precompute_ms = Some((fitter.assembly_s() + r.timing.solve_s) * 1e3);
        p.bytes = Some((f.grid.values().len() * 2) as f64);
        p.steps = Some(r.solver.iterations as f64);
        p.error = Some(r.error.rms);
        Ok::<_, crate::fit::FitError>(p)
    };
    let base = |cells| FitParams {
        cells,
        periodic,
        lambda: DEFAULT_LAMBDA,
        quantize_bits: vec![],
        ..FitParams::default()
    };
    let mut points = Vec::new();
    for &cells in &grids {
        let fitter = Fitter::new(&samples, cells, periodic).map_err(&e)?;
        let mut p = point("grid", grid_label(cells), &fitter, &base(cells)).map_err(&e)?;
        if cells == source {
            p.operating_point = Some("source: 15×8×16 (\"acceptable\")".into());
        }
        points.push(p);
    }
    let fitter = Fitter::new(&samples, source, periodic).map_err(&e)?;
    let lambdas: &[f64] = if quick {
        &[0.0, 1e-4, 1e-2]
    } else {
        &[0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1]
    };
    for &lambda in lambdas {
        let params = FitParams {
            lambda,
            ..base(source)
        };
        points.push(point("λ at 15×8×16", format!("λ={lambda:e}"), &fitter, &params).map_err(&e)?);
    }
    for (method, pc) in configurations() {
        if quick && method.is_least_squares() {
            continue;
        }
        let params = FitParams {
            solver: method,
            preconditioner: pc,
            ..base(source)
        };
        let name = format!("{}+{}", method.name(), pc.name());
        points.push(point("solver at 15×8×16", name, &fitter, &params).map_err(&e)?);
    }
    for tolerance in [1e-2, 1e-4, 1e-6, 1e-8, 1e-10] {
        let params = FitParams {
            tolerance,
            ..base(source)
        };
        points.push(
            point(
                "PCG+Jacobi tolerance at 15×8×16",
                format!("tol={tolerance:e}"),
                &fitter,
                &params,
            )
            .map_err(&e)?,
        );
    }
    Ok(RepresentationReport {
        name: R,
        title: format!(
            "Trilinear least-squares fit of fit-bench's step function ({}×{}×{} samples, angle axis periodic): grid, λ, solver and tolerance",
            samples_dims[0], samples_dims[1], samples_dims[2]
        ),
        error_label: "fit RMS error (function units)".into(),
        uses_psnr: false,
        steps_label: "solver iterations".into(),
        panels: vec![Cost::PrecomputeMs, Cost::Bytes, Cost::Steps],
        points,
        references: vec![],
        notes: vec![
            "Precompute = assembly of the normal equations + solve (sampling the function excluded); bytes = coefficients at 16 bits."
                .into(),
        ],
        seconds: 0.0,
    })
}

/// Images with parallax: for every number of views and view size, capture, build every bound
/// kind ([`crate::parallax::build_bounds`]) and count march steps
/// ([`crate::parallax::measure_steps`]); the PSNR of inverse warping (the same for every bound:
/// bounds never change the image) and of the two baselines from
/// [`crate::parallax::measure_quality`]. Operating point: N = 8 views of 64² (source), best-c
/// bounds; Baboud's ÷5 (zmin/zmax) and ÷12 (two functions) step claims as lines at the
/// cylinder bound's mean steps divided by 5 and 12.
pub fn parallax(quick: bool, mesh: Option<&Path>) -> Result<RepresentationReport, ReportError> {
    use crate::parallax::{
        BoundKind, BoundParams, ParallaxImages, ParallaxParams, QualityParams, build_bounds,
        measure_quality, measure_steps,
    };
    const R: &str = "parallax";
    let e = err::<crate::parallax::ParallaxError>(R);
    let shape = object(R, mesh, "truck")?;
    let (views, sizes, angles, quality_angles) = if quick {
        (vec![4, 8], vec![32], 16, 4)
    } else {
        (vec![4, 8, 16], vec![32, 64, 128], 90, 16)
    };
    let qp = QualityParams {
        angles: quality_angles,
        views: views.clone(),
        sizes: sizes.clone(),
        ..QualityParams::default()
    };
    let quality = measure_quality(shape.as_ref(), &qp).map_err(&e)?;
    let psnr = |method: &str, n: usize, size: usize| {
        quality
            .iter()
            .find(|q| q.method.starts_with(method) && q.views == n && q.size == size)
            .map(|q| q.psnr_db)
    };
    let mut points = Vec::new();
    let mut references = Vec::new();
    for &size in &sizes {
        for &n in &views {
            let p = ParallaxParams {
                views: n,
                width: size,
                height: size,
                ..ParallaxParams::default()
            };
            let images = ParallaxImages::capture(shape.as_ref(), &p).map_err(&e)?;
            let capture_ms = images.capture_time.as_secs_f64() * 1e3;
            let bounds = BoundKind::ALL
                .iter()
                .map(|&k| build_bounds(&images, k, &BoundParams::default()))
                .collect::<Result<Vec<_>, _>>()
                .map_err(&e)?;
            let steps = measure_steps(&images, &bounds, angles, 0).map_err(&e)?;
            let label = format!("N={n} {size}²");
            let source = n == 8 && size == 64;
            for s in &steps.stats {
                let mut pt = Point::new(R, s.method.clone(), label.clone());
                pt.precompute_ms = Some(capture_ms + s.precompute_ms);
                pt.bytes = Some(s.bytes as f64);
                pt.steps = Some(s.mean_steps);
                pt.psnr_db = psnr("inverse", n, size);
                if source && s.kind == BoundKind::BestC {
                    pt.operating_point = Some("source: N = 8 views of 64²".into());
                }
                points.push(pt);
            }
            if source {
                let cyl = steps.stats[0].mean_steps;
                references.push(Reference {
                    cost: Cost::Steps,
                    value: cyl / 5.0,
                    label: format!("seed: zmin/zmax ÷5 ({:.2})", cyl / 5.0),
                });
                references.push(Reference {
                    cost: Cost::Steps,
                    value: cyl / 12.0,
                    label: format!("seed: two functions ÷12 ({:.2})", cyl / 12.0),
                });
            }
            let mut off = Point::new(R, "one-step offset", label.clone());
            off.precompute_ms = Some(capture_ms);
            off.bytes = Some(images.bytes() as f64);
            off.steps = Some(1.0);
            off.psnr_db = psnr("one-step", n, size);
            points.push(off);
        }
        if let Some(q) = quality
            .iter()
            .find(|q| q.method.starts_with("blend") && q.size == size)
        {
            let mut b = Point::new(R, q.method.clone(), format!("{size}²"));
            b.bytes = Some(q.bytes as f64);
            b.psnr_db = Some(q.psnr_db);
            points.push(b);
        }
    }
    Ok(RepresentationReport {
        name: R,
        title: format!(
            "Images with parallax of the {}: views N and view size per bound kind ({angles} display angles for steps, {quality_angles} for PSNR)",
            shape.name()
        ),
        error_label: "PSNR (dB)".into(),
        uses_psnr: true,
        steps_label: "mean march steps per fragment and view".into(),
        panels: vec![Cost::Steps, Cost::Bytes, Cost::PrecomputeMs],
        points,
        references,
        notes: vec![
            "PSNR of inverse warping against the supersampled ray-cast truth; a bound changes the steps, never the image. Precompute = capture + bounds.".into(),
        ],
        seconds: 0.0,
    })
}

/// Cylindrical textures: the offset-grid sweep of [`crate::cylinder::sweep`] (plain fitted
/// offsets and hybrid m = 2), fixed λ at 15×8×16 through the same sweep, and every renderer of
/// [`crate::cylinder::evaluate`] at the default grid and bounds (inverse warping, bounded
/// march, fitted, hybrid). Operating point: the source's 15×8×16 offsets.
pub fn cylinder(quick: bool, mesh: Option<&Path>) -> Result<RepresentationReport, ReportError> {
    use crate::cylinder::{
        EvalParams, LambdaRule, MethodRow, OffsetParams, SWEEP_GRIDS, evaluate, sweep,
    };
    const R: &str = "cylinder";
    let e = err::<crate::cylinder::CylinderError>(R);
    let shape = object(R, mesh, "pear")?;
    let params = if quick {
        EvalParams {
            angles: 2,
            size: 32,
            minify_sizes: vec![16],
            hybrid_steps: vec![2],
            ..EvalParams::default()
        }
    } else {
        EvalParams::default()
    };
    let source = [15, 8, 16];
    let grids: Vec<[usize; 3]> = if quick {
        vec![[8, 4, 8], source]
    } else {
        SWEEP_GRIDS.to_vec()
    };
    let from_row = |series: &str, label: String, r: &MethodRow| {
        let mut p = Point::new(R, series, label);
        p.precompute_ms = Some(r.precompute_ms);
        p.bytes = Some(r.bytes as f64);
        p.steps = r.mean_steps;
        p.psnr_db = r.psnr_db.is_finite().then_some(r.psnr_db);
        p.error = Some(r.offset.rms);
        p
    };
    let mut points = Vec::new();
    for row in sweep(shape.as_ref(), &params, &grids).map_err(&e)? {
        let mut p = from_row("fitted offsets (grid)", grid_label(row.cells), &row.plain);
        if row.cells == source {
            p.operating_point = Some("source: 15×8×16 offsets".into());
        }
        points.push(p);
        points.push(from_row(
            "hybrid m=2 (grid)",
            grid_label(row.cells),
            &row.hybrid,
        ));
    }
    let lambdas: &[f64] = if quick {
        &[1e-4, 1e-1]
    } else {
        &[1e-6, 1e-4, 1e-2, 1e-1, 1.0]
    };
    for &lambda in lambdas {
        let p = EvalParams {
            offset: OffsetParams {
                lambda: LambdaRule::Fixed(lambda),
                ..params.offset
            },
            ..params.clone()
        };
        for row in sweep(shape.as_ref(), &p, &[source]).map_err(&e)? {
            points.push(from_row(
                "fitted offsets (λ at 15×8×16)",
                format!("λ={lambda:e}"),
                &row.plain,
            ));
        }
    }
    let report = evaluate(shape.as_ref(), &params).map_err(&e)?;
    for r in &report.rows {
        if r.method == "inverse"
            || r.method == "bounded"
            || r.method.starts_with("hybrid")
            || r.method == "fitted"
        {
            points.push(from_row(
                "renderer (default grid, bounds)",
                r.method.clone(),
                r,
            ));
        }
    }
    Ok(RepresentationReport {
        name: R,
        title: format!(
            "Cylindrical texture of the {} (256×64): offset grid, λ and renderer ({} angles, {}² images)",
            shape.name(),
            params.angles,
            params.size
        ),
        error_label: "PSNR (dB)".into(),
        uses_psnr: true,
        steps_label: "mean sector tests per sub-sample".into(),
        panels: vec![Cost::Steps, Cost::Bytes, Cost::PrecomputeMs],
        points,
        references: vec![],
        notes: vec![
            "PSNR against the supersampled ray-cast truth; `error` in the CSV is the offset RMS in texels against exact inverse warping. Precompute = capture + offset sampling, fit and quantisation (or bounds).".into(),
        ],
        seconds: 0.0,
    })
}

/// Slices: [`crate::slices::measure`](fn@crate::slices::measure)'s error against level (slice count) for every merge rule,
/// averaged over the tiles, and the criterion's choice among three directions as the
/// operating point (Meyer & Neyret's rule `h·tan a / d ≤ 1`).
pub fn slices(quick: bool) -> Result<RepresentationReport, ReportError> {
    use crate::slices::{MergeRule, SliceMeasureParams, TestTile, measure};
    const R: &str = "slices";
    let e = err::<crate::slices::SliceError>(R);
    let params = if quick {
        SliceMeasureParams {
            size: 8,
            tiles: vec![TestTile::Perlin],
            angles_deg: vec![0.0, 60.0],
            pixel_voxels: vec![1.0],
            both_sides: false,
            truth_steps: 4,
            direction_table: false,
            ..SliceMeasureParams::default()
        }
    } else {
        SliceMeasureParams {
            tiles: vec![TestTile::Grass, TestTile::Perlin, TestTile::Tree],
            angles_deg: vec![0.0, 20.0, 40.0, 60.0, 70.0, 80.0],
            pixel_voxels: vec![1.0],
            direction_table: false,
            ..SliceMeasureParams::default()
        }
    };
    let report = measure(&params).map_err(&e)?;
    let n = params.size;
    let mut points = Vec::new();
    let levels = n.trailing_zeros() as usize + 1;
    for rule in MergeRule::ALL {
        for level in 0..levels {
            let rows: Vec<f64> = report
                .levels
                .iter()
                .filter(|l| l.level == level)
                .filter_map(|l| l.psnr_rule.get(rule.name()).copied())
                .collect();
            if rows.is_empty() {
                continue;
            }
            let slices = n >> level;
            let mut p = Point::new(R, rule.name(), format!("{slices} slices"));
            p.steps = Some(slices as f64);
            p.bytes = Some((slices * n * n * 4) as f64);
            p.psnr_db = Some(rows.iter().sum::<f64>() / rows.len() as f64);
            if level == 0 && rule == report.default_rule {
                p.operating_point = Some(format!("all {n} slices (the seed draws every slice)"));
            }
            points.push(p);
        }
    }
    // The criterion's choice among three directions, per view: mean slices drawn and PSNR.
    let rows = &report.sweep;
    if !rows.is_empty() {
        let k = rows.len() as f64;
        let mut p = Point::new(R, "criterion, three directions", "h·tan a/d ≤ 1");
        p.steps = Some(rows.iter().map(|r| r.three.slices as f64).sum::<f64>() / k);
        p.bytes = Some(
            report.tiles.iter().map(|t| t.bytes as f64).sum::<f64>()
                / report.tiles.len().max(1) as f64,
        );
        p.precompute_ms = Some(
            report
                .tiles
                .iter()
                .map(|t| t.build_seconds * 1e3)
                .sum::<f64>()
                / report.tiles.len().max(1) as f64,
        );
        p.psnr_db = Some(rows.iter().map(|r| r.psnr_three).sum::<f64>() / k);
        p.operating_point = Some("seed: slices chosen by h·tan a/d ≤ 1, d = 1 px".into());
        points.push(p);
    }
    Ok(RepresentationReport {
        name: R,
        title: format!(
            "Volumetric texture as slices ({n}³ tiles: {}): slice count (merge level) per merge rule, against the ray-marched volume",
            params.tiles.iter().map(|t| t.name()).collect::<Vec<_>>().join(", ")
        ),
        error_label: "PSNR (dB)".into(),
        uses_psnr: true,
        steps_label: "slices drawn per tile".into(),
        panels: vec![Cost::Steps, Cost::Bytes],
        points,
        references: vec![],
        notes: vec![
            "Rule points: the y stack at each level, mean PSNR over tiles, angles and sides at one voxel per pixel; bytes = that level's slices at RGBA8. Criterion point: the three-direction choice, mean over the sweep; its bytes are every stack and level with 2D mips.".into(),
        ],
        seconds: 0.0,
    })
}

/// The ellipsoid octree through the pipeline's own build and measurement
/// ([`crate::ellipsoid::asset::OctreeRepr`]): leaf resolution per filter rule, of the `tree`
/// shape. Cost: voxelisation + build, bytes of the node array; error: PSNR of level 0 against
/// the ray-cast truth. Neyret 1995's claims (91–93 % compression at 128³, 8 s to build 256³) as
/// lines.
pub fn octree(quick: bool) -> Result<RepresentationReport, ReportError> {
    use crate::ellipsoid::asset::{NODE_BYTES, OctreeRepr, OctreeSpec};
    use crate::pipeline::{Needs, Representation, Source};
    const R: &str = "octree";
    let e = err::<crate::pipeline::PipelineError>(R);
    let shape = scene_shape("tree").map_err(err(R))?;
    let source = Source {
        name: "tree",
        geometry: Some(&shape),
        texture: None,
        tile: None,
        light: altrep_data_gen::Light::default(),
        placement: None,
    };
    let needs = Needs {
        screen_px: [1.0, 4096.0],
        ..Needs::default()
    };
    let runs: Vec<(usize, &str)> = if quick {
        vec![(8, "sggx"), (16, "sggx"), (16, "seed1995")]
    } else {
        let mut v: Vec<(usize, &str)> = [16, 32, 64, 128, 256]
            .iter()
            .map(|&n| (n, "sggx"))
            .collect();
        v.extend([16, 32, 64, 128].iter().map(|&n| (n, "seed1995")));
        v
    };
    let mut points = Vec::new();
    for (n, rule) in runs {
        let spec = OctreeSpec {
            resolution: n,
            rule: rule.into(),
            ..OctreeSpec::default()
        };
        let (_, decisions) = OctreeRepr::plan(&spec, &needs, &source).map_err(&e)?;
        let (tree, build) = OctreeRepr::build(&spec, &needs, &decisions, &source).map_err(&e)?;
        let (m, _) =
            OctreeRepr::measure(&tree, &needs, OctreeRepr::measure_size(&decisions), &source)
                .map_err(&e)?;
        let secs =
            build["voxelize_s"].as_f64().unwrap_or(0.0) + build["build_s"].as_f64().unwrap_or(0.0);
        let mut p = Point::new(R, rule, format!("{n}³"));
        p.precompute_ms = Some(secs * 1e3);
        p.bytes = Some((tree.nodes().len() * NODE_BYTES) as f64);
        p.psnr_db = Some(m.psnr_db);
        p.error = build["compression"].as_f64();
        if n == 128 && rule == "sggx" {
            p.operating_point = Some("seed: 128³ (91–93 % compression)".into());
        }
        points.push(p);
    }
    let voxels_128 = (128usize.pow(3)) as f64;
    Ok(RepresentationReport {
        name: R,
        title: "Ellipsoid octree of the tree (pipeline build, ×2 supersampled voxelisation): leaf resolution per filter rule".into(),
        error_label: "PSNR (dB)".into(),
        uses_psnr: true,
        steps_label: "n/a".into(),
        panels: vec![Cost::PrecomputeMs, Cost::Bytes],
        points,
        references: vec![
            Reference {
                cost: Cost::PrecomputeMs,
                value: 8000.0,
                label: "seed 1995: 256³ built in 8 s".into(),
            },
            Reference {
                cost: Cost::Bytes,
                value: 0.08 * voxels_128 * NODE_BYTES as f64,
                label: "seed: 92 % compression of 128³ (at 52 B/node)".into(),
            },
        ],
        notes: vec![
            "PSNR of the volume rendering of level 0 against the ray-cast truth, mean over 4 azimuths around the object, at the leaves' resolution (so the error of each resolution is at its own pixel size). `error` in the CSV is the compression 1 − nodes/voxels.".into(),
        ],
        seconds: 0.0,
    })
}

/// Pyramids: [`crate::pyramid::measure_sweep`] per prefilter; per lookup scheme the mean RMS
/// error against the supersampled truth over the sweep's views, its mean time per lookup and its
/// bytes. Operating point: Williams' box-filtered mipmap.
pub fn pyramid(quick: bool) -> Result<RepresentationReport, ReportError> {
    use crate::pyramid::truth::{METHODS, test_texture};
    use crate::pyramid::{Filter, PyramidParams, SweepParams, WrapMode, measure_sweep};
    const R: &str = "pyramid";
    let e = err::<crate::pyramid::MipError>(R);
    let (size, sweep) = if quick {
        (
            32,
            SweepParams {
                texels_per_pixel: vec![1.0, 4.0],
                tilts_deg: vec![0.0, 75.0],
                azimuths_deg: vec![0.0],
                pixels: 4,
                max_samples_per_pixel: 64,
                ..SweepParams::default()
            },
        )
    } else {
        (256, SweepParams::default())
    };
    let tex = test_texture(size, 7);
    let mut points = Vec::new();
    for filter in [
        Filter::Box,
        Filter::Triangle,
        Filter::Kaiser,
        Filter::Lanczos,
    ] {
        let params = PyramidParams {
            filter,
            wrap: [WrapMode::Repeat; 2],
            ..PyramidParams::default()
        };
        let report = measure_sweep(&tex, &params, &sweep).map_err(&e)?;
        let k = report.rows.len().max(1) as f64;
        for (m, method) in METHODS.iter().enumerate() {
            let name = format!("{method:?}").to_lowercase();
            let mut p = Point::new(R, name.clone(), format!("{filter:?}").to_lowercase());
            p.steps = Some(report.rows.iter().map(|r| r.ns_per_sample[m]).sum::<f64>() / k);
            p.error = Some(report.rows.iter().map(|r| r.rms[m]).sum::<f64>() / k);
            p.bytes = Some(match name.as_str() {
                "rip" => report.rip_bytes,
                "fip" => report.fip_bytes,
                _ => report.mip_bytes,
            } as f64);
            p.precompute_ms = Some(report.build_seconds * 1e3);
            if filter == Filter::Box && name == "mip" {
                p.operating_point = Some("Williams 1983: box-filtered mipmap, trilinear".into());
            }
            points.push(p);
        }
    }
    Ok(RepresentationReport {
        name: R,
        title: format!(
            "Pyramids of a {size}² grey test texture: lookup scheme per prefilter, mean over {} views (distances × tilts × azimuths)",
            sweep.texels_per_pixel.len() * sweep.tilts_deg.len() * sweep.azimuths_deg.len()
        ),
        error_label: "RMS error vs supersampled truth (texel values)".into(),
        uses_psnr: false,
        steps_label: "ns per lookup (one thread)".into(),
        panels: vec![Cost::Steps, Cost::Bytes],
        points,
        references: vec![],
        notes: vec![
            "Bytes at 4 bytes per channel; the fipmap database holds the mipmap and the ripmap. Precompute (CSV) = the fipmap database's build.".into(),
        ],
        seconds: 0.0,
    })
}
