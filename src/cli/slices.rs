//! `altrep slices`: volumetric textures as slices (docs/design.md §9). Builds the four test
//! tiles, cuts them into three stacks with mipmapped merges under every rule, and prints PSNR
//! against the ray-marched volume per view angle, distance and side (all slices, dropped slices
//! and every merge rule at the criterion's level, one direction against three, one sample per
//! pixel with 2D mip-maps), error against level, shells over a cylindrical patch per level and
//! rule, a summary per rule and per tile (merge gain, slices drawn, bytes, build time).

use std::path::PathBuf;

use crate::slices::{
    MeasureReport, MergeRule, SliceMeasureParams, SliceReconstruction, TestTile, measure,
};

use super::CliResult;

/// Arguments of `altrep slices`.
#[derive(clap::Args, Debug)]
pub struct SlicesArgs {
    /// Write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Voxels per side of the tiles (a power of two).
    #[arg(long, default_value_t = 32)]
    pub size: usize,
    /// Tiles, comma-separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "grass,fur,perlin,tree"
    )]
    pub tiles: Vec<TileArg>,
    /// Polar view angles from the surface normal (degrees), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,10,20,30,40,50,60,70,80,85"
    )]
    pub angles: Vec<f64>,
    /// Azimuth of the views (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub azimuth: f64,
    /// Distances as pixel sizes in voxels, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4")]
    pub distances: Vec<f64>,
    /// Visible depth d of the criterion h·tan a / d ≤ 1, in pixels.
    #[arg(long, default_value_t = 1.0)]
    pub d_pixels: f64,
    /// Only views from above (skip the opposite side).
    #[arg(long)]
    pub one_side: bool,
    /// Reconstruction of voxels (truth) and texels (slices): linear (GPU linear filtering) or
    /// nearest (box voxels, which compositing commutes with).
    #[arg(long, value_enum, default_value_t = FilterArg::Linear)]
    pub filter: FilterArg,
    /// Ground-truth march samples per voxel.
    #[arg(long, default_value_t = 8)]
    pub truth_steps: usize,
    /// Seed of the tiles.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print every row of the sweep (default: the rows at the first distance).
    #[arg(long)]
    pub all_rows: bool,
    /// Skip the direction table (the direction chosen by measured error, docs/design.md §9.6):
    /// it costs one truth march per node and a render per stack there, about twice the sweep.
    #[arg(long)]
    pub no_direction_table: bool,
    /// Azimuth step of the direction table's nodes (degrees); the sweep's views lie half a step
    /// from them, at the centre of their cells.
    #[arg(long, default_value_t = 30.0)]
    pub table_azimuth_step: f64,
    /// Write images to this folder: per tile, slices (criterion's choice, default rule) beside
    /// the truth at 0°, 60° and 85°, and the tile over a cylinder (all shells, 8 shells, truth).
    #[arg(long)]
    pub images: Option<PathBuf>,
}

/// The reconstruction ([`SliceReconstruction`]) on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum FilterArg {
    /// Trilinear volume, bilinear slices.
    Linear,
    /// Box voxels and texels.
    Nearest,
}

/// A test tile on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum TileArg {
    /// Grass blades on soil.
    Grass,
    /// Thin cylinders on skin.
    Fur,
    /// Perlin height field.
    Perlin,
    /// data-gen's tree, voxelised.
    Tree,
}

impl From<TileArg> for TestTile {
    fn from(t: TileArg) -> Self {
        match t {
            TileArg::Grass => TestTile::Grass,
            TileArg::Fur => TestTile::Fur,
            TileArg::Perlin => TestTile::Perlin,
            TileArg::Tree => TestTile::Tree,
        }
    }
}

/// A figure in dB for the printed tables, or `—` where it has no views to average (the sweep
/// held none at the angles it is taken over): never `NaN`.
fn db(x: f64, signed: bool) -> String {
    match (x.is_finite(), signed) {
        (false, _) => "—".to_string(),
        (true, true) => format!("{x:+.2}"),
        (true, false) => format!("{x:.2}"),
    }
}

fn print_report(r: &MeasureReport, all_rows: bool) {
    let rules: Vec<&str> = MergeRule::ALL.iter().map(|m| m.name()).collect();
    let def = r.default_rule.name();
    println!(
        "PSNR (dB) against the ray-marched volume ({:?} reconstruction); y stack at the criterion's \
         level (d = {} px), merged = {def}; three = direction by argmin (1/c²−1)h² at its level",
        r.params.filter, r.params.d_pixels
    );
    println!(
        "\n| tile | px/voxel | side | angle | need | y slices | all y | {} | three (axis:slices) | three | three, all | three, 1 spp + 2D mip |",
        rules.join(" | ")
    );
    println!(
        "|---|---|---|---|---|---|---|{}---|---|---|---|",
        "---|".repeat(rules.len())
    );
    let first = r.params.pixel_voxels[0];
    for row in r
        .sweep
        .iter()
        .filter(|row| all_rows || row.pixel_voxels == first)
    {
        let need = if row.one.needed == usize::MAX {
            "∞".to_string()
        } else {
            row.one.needed.to_string()
        };
        let per_rule: Vec<String> = rules
            .iter()
            .map(|n| format!("{:.1}", row.psnr_rule[n]))
            .collect();
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.1} | {} | {}:{} | {:.1} | {:.1} | {:.1} |",
            row.tile.name(),
            row.pixel_voxels,
            row.side,
            row.angle_deg,
            need,
            row.one.slices,
            row.psnr_all,
            per_rule.join(" | "),
            row.three.axis.name(),
            row.three.slices,
            row.psnr_three,
            row.psnr_three_all,
            row.psnr_three_gpu
        );
    }
    println!("\nError against level (y stack, 1 px/voxel, mean over angles and sides):\n");
    println!("| tile | level | slices | {} |", rules.join(" | "));
    println!("|---|---|---|{}", "---|".repeat(rules.len()));
    for l in &r.levels {
        let per_rule: Vec<String> = rules
            .iter()
            .map(|n| format!("{:.1}", l.psnr_rule[n]))
            .collect();
        println!(
            "| {} | {} | {} | {} |",
            l.tile.name(),
            l.level,
            l.slices,
            per_rule.join(" | ")
        );
    }
    println!(
        "\nShells over a cylindrical patch (8 tiles around, 96 px wide, 3×3 sub-samples), PSNR:\n"
    );
    println!("| tile | tilt | level | shells | {} |", rules.join(" | "));
    println!("|---|---|---|---|{}", "---|".repeat(rules.len()));
    for c in &r.curved {
        let per_rule: Vec<String> = rules
            .iter()
            .map(|n| format!("{:.1}", c.psnr_rule[n]))
            .collect();
        println!(
            "| {} | {} | {} | {} | {} |",
            c.tile.name(),
            c.tilt_deg,
            c.level,
            c.slices,
            per_rule.join(" | ")
        );
    }
    println!(
        "\nMerge rules where the criterion merges (level ≥ 1), mean PSNR over tiles, distances, angles:\n"
    );
    println!("| rule | above | below | views per side |");
    println!("|---|---|---|---|");
    for s in &r.rules {
        println!(
            "| {} | {} | {} | {} |",
            s.rule,
            db(s.above_db, false),
            db(s.below_db, false),
            s.views
        );
    }
    println!(
        "\nPer tile (merge gain = {def} − drop at the criterion's level, mean over all views):\n"
    );
    println!(
        "| tile | merge gain | gain where merged | three − one, ≥70° | same, all slices | slices drawn/tile | direction rule below best: worst / mean | bytes (RGBA8, all) | bytes y level 0 | build s | volume s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for t in &r.tiles {
        println!(
            "| {} | {} | {} | {} | {} | {:.1} | {:.2} / {:.2} | {} | {} | {:.3} | {:.3} |",
            t.tile.name(),
            db(t.merge_gain_db, true),
            db(t.merge_gain_merged_views_db, true),
            db(t.three_gain_grazing_db, true),
            db(t.three_gain_grazing_all_db, true),
            t.slices_drawn_mean,
            t.direction_shortfall_max_db,
            t.direction_shortfall_mean_db,
            t.bytes,
            t.bytes_y_level0,
            t.build_seconds,
            t.volume_seconds
        );
    }
    if r.tiles.iter().any(|t| t.table_shortfall_max_db.is_some()) {
        println!(
            "\nDirection chosen by the measured table (nodes between the sweep's views), against the direction rule:\n"
        );
        println!(
            "| tile | rule below best: worst / mean | table below best: worst / mean | slices drawn/tile, rule → table | table s |"
        );
        println!("|---|---|---|---|---|");
        for t in &r.tiles {
            if let (Some(w), Some(m), Some(n), Some(sec)) = (
                t.table_shortfall_max_db,
                t.table_shortfall_mean_db,
                t.table_slices_drawn_mean,
                t.table_seconds,
            ) {
                println!(
                    "| {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.1} → {:.1} | {:.1} |",
                    t.tile.name(),
                    t.direction_shortfall_max_db,
                    t.direction_shortfall_mean_db,
                    w,
                    m,
                    t.slices_drawn_mean,
                    n,
                    sec
                );
            }
        }
    }
    println!("\nmeasured in {:.1} s", r.seconds);
}

/// Writes the comparison images (on a grey background, sRGB PNG).
fn write_images(dir: &std::path::Path, params: &SliceMeasureParams) -> CliResult {
    use crate::slices::{
        CurvedParams, SliceParams, SliceRenderParams, StackView, VolumeTruthParams, build_slices,
        choose, render_curved_slices, render_curved_truth, render_slices, render_truth, test_tile,
    };
    use altrep_data_gen::RgbaImage;
    // Written into a staging folder beside `dir`, then swapped in whole (only over a folder this
    // command wrote: checked before the work and again here).
    check_images_folder(dir)?;
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent)
        .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| format!("--images {} has no folder name", dir.display()))?;
    let staging = parent.join(format!(".{name}.staging{}", std::process::id()));
    if staging.exists() {
        std::fs::remove_dir_all(&staging)
            .map_err(|e| format!("cannot clear {}: {e}", staging.display()))?;
    }
    std::fs::create_dir(&staging)
        .map_err(|e| format!("cannot create {}: {e}", staging.display()))?;
    let written = std::cell::RefCell::new(Vec::new());
    let grey = [0.5f32; 3];
    let save = |name: String, images: &[&RgbaImage]| -> CliResult {
        let row: Vec<RgbaImage> = images.iter().map(|i| i.over(grey)).collect();
        let refs: Vec<&RgbaImage> = row.iter().collect();
        RgbaImage::side_by_side(&refs).write_png(&staging.join(&name))?;
        println!("wrote {}", dir.join(&name).display());
        written.borrow_mut().push(name);
        Ok(())
    };
    let drawn = (|| -> CliResult {
        for &tile in &params.tiles {
            let volume = test_tile(tile, params.size, params.seed)?;
            let (data, _) = build_slices(&volume, &SliceParams::default())?;
            let rp = SliceRenderParams {
                width: 96,
                height: 96,
                filter: params.filter,
                ..SliceRenderParams::default()
            };
            let truth_params = VolumeTruthParams {
                steps_per_voxel: params.truth_steps,
                filter: params.filter,
            };
            for polar in [0.0, 60.0, 85.0] {
                let view = StackView::degrees(polar, params.azimuth_deg);
                let c = choose(
                    &volume,
                    view.vector(),
                    params.d_pixels * volume.voxel_size(),
                    [true; 3],
                )?;
                let slices = render_slices(&data, c.axis, c.level, &view, &rp)?;
                let truth = render_truth(&volume, &view, &rp, &truth_params)?;
                save(
                    format!(
                        "{}-{polar}deg-{}{}-vs-truth.png",
                        tile.name(),
                        c.axis.name(),
                        c.slices
                    ),
                    &[&slices, &truth],
                )?;
            }
            let cp = CurvedParams {
                tilt_deg: 30.0,
                width: 192,
                truth_steps: params.truth_steps,
                ..CurvedParams::default()
            };
            let all = render_curved_slices(&data, 0, &cp)?;
            let merged = render_curved_slices(&data, 2, &cp)?;
            let truth = render_curved_truth(&volume, &cp)?;
            save(
                format!("{}-cylinder-all-8shells-truth.png", tile.name()),
                &[&all, &merged, &truth],
            )?;
        }
        Ok(())
    })();
    if let Err(e) = drawn {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    let listing = serde_json::json!({
        "written_by": "altrep slices --images",
        "files": written.into_inner(),
    });
    let listed = super::write_json(&staging.join(IMAGES_LIST), &listing)
        .and_then(|()| check_images_folder(dir).map_err(Into::into));
    if let Err(e) = listed {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    crate::asset::replace_dir(&staging, dir)?;
    Ok(())
}

/// The list of the images `--images` wrote, in their folder.
const IMAGES_LIST: &str = "images.json";

/// Whether the `--images` folder may be replaced ([`super::check_replaceable`]): one this
/// command wrote holds `images.json`, listing the images.
fn check_images_folder(dir: &std::path::Path) -> Result<(), String> {
    super::check_replaceable(dir, "altrep slices --images", IMAGES_LIST, |d| {
        let bytes = std::fs::read(d.join(IMAGES_LIST)).ok()?;
        let v: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
        if v["written_by"] != "altrep slices --images" {
            return None;
        }
        let files = v["files"].as_array()?;
        Some(
            files
                .iter()
                .filter_map(|f| f.as_str().map(String::from))
                .chain([IMAGES_LIST.to_string()])
                .collect(),
        )
    })
}

/// Runs `altrep slices`.
pub fn run(args: SlicesArgs) -> CliResult {
    // Output paths are checked before the work, not after it.
    if let Some(path) = &args.json {
        super::precompute::check_writable(path)?;
    }
    if let Some(dir) = &args.images {
        check_images_folder(dir)?;
    }
    let params = SliceMeasureParams {
        size: args.size,
        tiles: args.tiles.iter().map(|t| TestTile::from(*t)).collect(),
        angles_deg: args.angles.clone(),
        azimuth_deg: args.azimuth,
        pixel_voxels: args.distances.clone(),
        d_pixels: args.d_pixels,
        both_sides: !args.one_side,
        truth_steps: args.truth_steps,
        filter: match args.filter {
            FilterArg::Linear => SliceReconstruction::Linear,
            FilterArg::Nearest => SliceReconstruction::Nearest,
        },
        seed: args.seed,
        direction_table: !args.no_direction_table,
        table_azimuth_step_deg: args.table_azimuth_step,
        ..SliceMeasureParams::default()
    };
    let report = measure(&params)?;
    print_report(&report, args.all_rows);
    if let Some(dir) = &args.images {
        write_images(dir, &params)?;
    }
    if let Some(path) = &args.json {
        super::write_json(path, &report)?;
    }
    Ok(())
}
