//! `altrep ellipsoid-bench`: the eigen-solver table, the filter-rule table, the sin²θ fit and the
//! octree report of docs/design.md §8, printed and optionally written as JSON.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::ellipsoid::FilterRule;
use crate::ellipsoid::SphereQuadrature;
use crate::ellipsoid::octree::OctreeParams;
use crate::ellipsoid::report::{
    EigenRow, EllipsoidBenchReport, FilterRow, OctreeRow, SIN2_THETAS, eigen_table, filter_table,
    octree_row, report_quadrature, sin2_fits,
};

use super::CliResult;

/// Arguments of `altrep ellipsoid-bench`.
#[derive(clap::Args, Debug)]
pub struct EllipsoidBenchArgs {
    /// Write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Seed of every random case (rotations, grass jitter, lawn).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Octree volumes: altrep-data-gen scene shapes (tree, building, sphere, …) or the analytic
    /// `lawn` and `sphere-torus`, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "tree,building,lawn")]
    pub volumes: Vec<String>,
    /// Octree sizes (voxels per side), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "128,256")]
    pub sizes: Vec<usize>,
    /// Filter rule of the octree's coarser levels.
    #[arg(long, value_enum, default_value_t = RuleArg::Sggx)]
    pub rule: RuleArg,
    /// Timing passes per eigen method (the median is reported).
    #[arg(long, default_value_t = 21)]
    pub batches: usize,
    /// Sections to run, comma-separated (default: all).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "eigen,filter,sin2,octree"
    )]
    pub sections: Vec<Section>,
}

/// A part of the report.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Section {
    /// Eigen-solver table.
    Eigen,
    /// Filter-rule table.
    Filter,
    /// sin²θ fit.
    Sin2,
    /// Octree report.
    Octree,
}

/// Filter rule on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum RuleArg {
    /// Weighted mean of Q⁻¹ (Neyret 1995).
    Seed1995,
    /// Weighted mean of the SGGX matrix S (Heitz et al. 2015).
    Sggx,
}

impl From<RuleArg> for FilterRule {
    fn from(r: RuleArg) -> Self {
        match r {
            RuleArg::Seed1995 => FilterRule::Seed1995,
            RuleArg::Sggx => FilterRule::Sggx,
        }
    }
}

fn winner_line(rows: &[FilterRow], case: &str) -> Option<String> {
    let a = rows
        .iter()
        .find(|r| r.case == case && r.rule == "seed1995")?;
    let b = rows.iter().find(|r| r.case == case && r.rule == "sggx")?;
    let verdict = |name: &str, x: f64, y: f64| {
        let (w, ratio) = if x <= y {
            ("seed1995", y / x)
        } else {
            ("sggx", x / y)
        };
        format!("{name}: {w} ({ratio:.1}x smaller)")
    };
    Some(format!(
        "  {case:<20} {}; {}; {}",
        verdict("L1", a.l1_error, b.l1_error),
        verdict("shape", a.l1_shape_error, b.l1_shape_error),
        verdict("area", a.area_error, b.area_error)
    ))
}

/// Runs `altrep ellipsoid-bench`.
pub fn run(args: EllipsoidBenchArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    let on = |s: Section| args.sections.contains(&s);
    let mut report = EllipsoidBenchReport {
        eigen: Vec::new(),
        filter: Vec::new(),
        sin2_exponent: BTreeMap::new(),
        sin2_points: BTreeMap::new(),
        octree: Vec::new(),
    };
    if on(Section::Eigen) {
        report.eigen = print_eigen(&args)?;
    }
    let quad = report_quadrature();
    if on(Section::Filter) {
        report.filter = print_filter(&args, &quad)?;
    }
    if on(Section::Sin2) {
        (report.sin2_exponent, report.sin2_points) = print_sin2(&quad)?;
    }
    if on(Section::Octree) {
        report.octree = print_octree(&args)?;
    }
    if let Some(path) = &args.json {
        super::write_json(path, &report)?;
        println!();
        println!("wrote {}", path.display());
    }
    Ok(())
}

type Sin2Maps = (BTreeMap<String, f64>, BTreeMap<String, Vec<(f64, f64)>>);

fn print_eigen(
    args: &EllipsoidBenchArgs,
) -> Result<Vec<EigenRow>, Box<dyn std::error::Error + Send + Sync>> {
    let eigen = eigen_table(args.seed, args.batches)?;
    println!("3x3 symmetric eigen-decomposition");
    println!(
        "  accuracy: adversarial suite ({} f64 / {} f32 matrices); speed: 4096 random symmetric, single thread, median and best of {} passes",
        eigen[0].cases, eigen[2].cases, args.batches
    );
    println!(
        "  {:<14} {:>9} {:>9} {:>22} {:>18}  worst case",
        "method", "ns/op", "best", "worst |A-VLV'|/|A|", "worst |V'V-I|"
    );
    for r in &eigen {
        println!(
            "  {:<14} {:>9.1} {:>9.1} {:>22.2e} {:>18.2e}  {}",
            r.method,
            r.ns_per_op,
            r.ns_per_op_best,
            r.worst_reconstruction,
            r.worst_orthogonality,
            r.worst_case
        );
    }
    println!(
        "  speed-up over nalgebra (fastest interleaved passes): f64 {:.1}x, f32 {:.1}x",
        eigen[0].speedup_vs_nalgebra, eigen[2].speedup_vs_nalgebra
    );
    Ok(eigen)
}

fn print_filter(
    args: &EllipsoidBenchArgs,
    quad: &SphereQuadrature,
) -> Result<Vec<FilterRow>, Box<dyn std::error::Error + Send + Sync>> {
    let filter = filter_table(args.seed, quad)?;
    println!();
    println!(
        "Filtering k weighted ellipsoids (relative L1 over the sphere; adaptive quadrature base {}, depth {}, tol {:e})",
        quad.base, quad.max_depth, quad.tolerance
    );
    println!(
        "  {:<20} {:<9} {:>10} {:>10} {:>10}  filtered lengths",
        "case", "rule", "L1 normals", "L1 shape", "area"
    );
    for r in &filter {
        println!(
            "  {:<20} {:<9} {:>10.4} {:>10.4} {:>10.4}  ({:.3}, {:.3}, {:.3})",
            r.case,
            r.rule,
            r.l1_error,
            r.l1_shape_error,
            r.area_error,
            r.lengths[0],
            r.lengths[1],
            r.lengths[2]
        );
    }
    println!("  winner per case:");
    let mut cases: Vec<&str> = filter.iter().map(|r| r.case.as_str()).collect();
    cases.dedup();
    for c in cases {
        if let Some(line) = winner_line(&filter, c) {
            println!("{line}");
        }
    }
    Ok(filter)
}

fn print_sin2(
    quad: &SphereQuadrature,
) -> Result<Sin2Maps, Box<dyn std::error::Error + Send + Sync>> {
    let fits = sin2_fits(quad)?;
    println!();
    println!(
        "sin^2(theta) law (rotated pair, theta = {:?} rad): fitted k in L1 error ~ (sin^2 theta)^k",
        SIN2_THETAS
    );
    let mut sin2_exponent = BTreeMap::new();
    let mut sin2_points = BTreeMap::new();
    for f in &fits {
        let errs: Vec<String> = f.points.iter().map(|(_, e)| format!("{e:.2e}")).collect();
        println!(
            "  {:<9} k = {:.3}   (errors {})",
            f.rule.name(),
            f.exponent,
            errs.join(", ")
        );
        sin2_exponent.insert(f.rule.name().to_string(), f.exponent);
        sin2_points.insert(f.rule.name().to_string(), f.points.clone());
    }
    Ok((sin2_exponent, sin2_points))
}

fn print_octree(
    args: &EllipsoidBenchArgs,
) -> Result<Vec<OctreeRow>, Box<dyn std::error::Error + Send + Sync>> {
    let params = OctreeParams {
        rule: args.rule.into(),
        ..Default::default()
    };
    println!();
    println!(
        "Octree (rule {}, leaf flatness {}, pruning tolerance {:e}, {} bytes/node)",
        params.rule.name(),
        params.leaf_flatness,
        params.tolerance,
        std::mem::size_of::<crate::ellipsoid::octree::OctreeNode>()
    );
    println!(
        "  {:<18} {:>9} {:>9} {:>11} {:>12} {:>14} {:>10} {:>9}",
        "volume", "nodes", "leaves", "compression", "bytes", "dense bytes", "voxelize s", "build s"
    );
    let mut octree = Vec::new();
    for &n in &args.sizes {
        for name in &args.volumes {
            let row = octree_row(name, n, args.seed, &params)?;
            let r = &row.report;
            println!(
                "  {:<18} {:>9} {:>9} {:>10.2}% {:>12} {:>14} {:>10.2} {:>9.2}",
                r.volume,
                r.nodes,
                r.leaves,
                100.0 * r.compression,
                r.bytes,
                r.dense_bytes,
                row.voxelize_seconds,
                r.build_seconds
            );
            octree.push(row);
        }
    }
    Ok(octree)
}

/// `altrep demo` section: the octree of the scene's `tree` (64³, quick: 32³) built with each filter
/// rule, levels 0–3 rendered side by side (`ellipsoid/tree_<rule>_levels.png`), and its report.
pub fn demo_section(
    ctx: &super::demo::DemoContext,
) -> Result<super::demo::DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    use crate::ellipsoid::octree::{Octree, OctreeRenderParams};
    use altrep_data_gen::{Supersample, VoxelParams, scene_shape, voxelize};

    let (n, supersample) = if ctx.quick {
        (32, Supersample::ONE)
    } else {
        (64, Supersample::of(2))
    };
    let shape = scene_shape("tree")?;
    let volume = voxelize(
        &shape,
        &VoxelParams {
            dims: [n; 3],
            min: glam::DVec3::new(-1.0, 0.0, -1.0),
            max: glam::DVec3::new(1.0, 2.0, 1.0),
            periodic: [false; 3],
            supersample,
            fill: altrep_data_gen::Fill::Auto,
        },
    )?;
    let dir = ctx.dir;
    let d = ctx.light.direction;
    let render = OctreeRenderParams {
        light: nalgebra::Vector3::new(f64::from(d.x), f64::from(d.y), f64::from(d.z)),
        ambient: f64::from(ctx.light.ambient),
        ..Default::default()
    };
    let mut md = format!(
        "Multiscale octree of the `tree` voxelised at {n}³ (×{supersample}³ samples): leaves are flat \
         ellipsoids along the surface normal, coarser levels filtered by each rule; images show \
         levels 0–3 (left to right) rendered with the micro-primitives' diffuse reflectance.\n\n\
         | rule | nodes | leaves | compression | bytes | build ms |\n|---|---|---|---|---|---|\n"
    );
    let mut rows = Vec::new();
    let mut images = String::new();
    for rule in FilterRule::ALL {
        let params = OctreeParams {
            rule,
            ..Default::default()
        };
        let (tree, report) = Octree::build(&volume, &params)?;
        let levels: Vec<_> = (0..=tree.depth().min(3))
            .map(|l| tree.render_level(l, &render))
            .collect::<Result<_, _>>()?;
        let refs: Vec<&altrep_data_gen::RgbaImage> = levels.iter().collect();
        let file = format!("tree_{}_levels.png", rule.name());
        altrep_data_gen::RgbaImage::side_by_side(&refs)
            .over([1.0, 1.0, 1.0])
            .write_png(&dir.join(&file))?;
        md += &format!(
            "| {} | {} | {} | {:.1} % | {} | {:.0} |\n",
            rule.name(),
            report.nodes,
            report.leaves,
            100.0 * report.compression,
            report.bytes,
            report.build_seconds * 1e3
        );
        images += &format!("{}: ![{}](ellipsoid/{file})\n\n", rule.name(), rule.name());
        rows.push(report);
    }
    md += "\n";
    md += &images;
    Ok(super::demo::DemoSection {
        name: "ellipsoid".into(),
        json: serde_json::to_value(&rows)?,
        markdown: md,
    })
}
