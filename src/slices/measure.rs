//! Measurements against the ray-marched ground truth (docs/design.md §9): PSNR of every merge
//! rule and of dropped slices at the level the criterion picks, over a sweep of view angles,
//! distances and both sides; one slice direction against three; error against level for every rule;
//! slices drawn, bytes and build time.
//!
//! A view's **distance** is its pixel size in voxels `p`; the visible depth of the criterion is
//! `d = d_pixels · p · s`. The slices and the truth are both rendered with
//! `k = ⌈2p⌉` sub-samples per pixel side (sub-samples half a voxel apart), so the error measured
//! is the slicing's, not the texture filter's.

use std::collections::BTreeMap;
use std::time::Instant;

use altrep_data_gen::Supersample;

use super::build::{TestTile, test_tile};
use super::curved::{CurvedParams, render_curved_slices, render_curved_truth};
use super::direction::{DirectionGrid, DirectionTable};
use super::merge::{MergeRule, SliceData, SliceParams, build_slices};
use super::render::{SliceRenderParams, StackView, render_slices};
use super::stack::{Axis, ViewChoice, choose};
use super::truth::{VolumeTruthParams, render_truth};
use super::volume::SliceReconstruction;
use super::{SliceError, TexelVolume};
use crate::metrics::psnr;

/// Cap on reported PSNR (identical images).
const PSNR_CAP: f64 = 99.0;

/// Parameters of [`measure`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SliceMeasureParams {
    /// Voxels per side of the test tiles (a power of two).
    pub size: usize,
    /// Tiles measured.
    pub tiles: Vec<TestTile>,
    /// Polar view angles from the surface normal (degrees, each in `[0, 89]`).
    pub angles_deg: Vec<f64>,
    /// Azimuth of the views (degrees).
    pub azimuth_deg: f64,
    /// Distances as pixel sizes in voxels.
    pub pixel_voxels: Vec<f64>,
    /// Visible depth `d` of the criterion in pixels.
    pub d_pixels: f64,
    /// Image side in voxels (the image has `image_voxels / p` pixels per side).
    pub image_voxels: f64,
    /// Also measure from below (polar `180° − θ`, azimuth `+180°`: the opposite side of every
    /// axis).
    pub both_sides: bool,
    /// Truth march samples per voxel.
    pub truth_steps: usize,
    /// Reconstruction of the voxels in the truth and of the texels in the slices.
    pub filter: SliceReconstruction,
    /// Seed of the tiles.
    pub seed: u64,
    /// Also choose the direction by a measured [`DirectionTable`] and measure that choice. Its
    /// nodes lie between the sweep's views, so every choice is interpolated: polar angles at 0°,
    /// the midpoints of the sweep's angles and 88° on each side, azimuths half of
    /// [`Self::table_azimuth_step_deg`] either side of the sweep's (the cell's centre, the
    /// farthest from its nodes), the sweep's pixel sizes.
    pub direction_table: bool,
    /// Azimuth step of the direction table's nodes (degrees, in `(0, 180]`).
    pub table_azimuth_step_deg: f64,
}

impl Default for SliceMeasureParams {
    /// 32³ tiles, all four; angles 0–80° by 10° and 85°; azimuth 30°; distances 1, 2, 4 voxels
    /// per pixel; `d` one pixel; 48-voxel images; both sides; 8 truth steps per voxel; linear
    /// reconstruction; seed 1; the direction table measured, nodes 30° apart in azimuth.
    fn default() -> Self {
        Self {
            size: 32,
            tiles: TestTile::ALL.to_vec(),
            angles_deg: vec![0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0],
            azimuth_deg: 30.0,
            pixel_voxels: vec![1.0, 2.0, 4.0],
            d_pixels: 1.0,
            image_voxels: 48.0,
            both_sides: true,
            truth_steps: 8,
            filter: SliceReconstruction::Linear,
            seed: 1,
            direction_table: true,
            table_azimuth_step_deg: 30.0,
        }
    }
}

impl SliceMeasureParams {
    /// Errors: a size that is not a power of two ≥ 2, empty lists, angles outside `[0, 89]`,
    /// non-positive distances, `d` or image size, zero truth steps.
    pub fn validate(&self) -> Result<(), SliceError> {
        if self.size < 2 || !self.size.is_power_of_two() {
            return Err(SliceError::InvalidParameter {
                name: "tile size",
                value: format!("{}", self.size),
                reason: "must be a power of two ≥ 2",
            });
        }
        for (empty, what) in [
            (self.tiles.is_empty(), "tiles"),
            (self.angles_deg.is_empty(), "angles"),
            (self.pixel_voxels.is_empty(), "distances"),
            (self.truth_steps == 0, "truth steps"),
        ] {
            if empty {
                return Err(SliceError::ZeroSize { what });
            }
        }
        for a in &self.angles_deg {
            super::check_range("view angle", *a, 0.0, 89.0, "in [0°, 89°]")?;
        }
        super::check_range("azimuth", self.azimuth_deg, -1e4, 1e4, "finite")?;
        for p in &self.pixel_voxels {
            super::check_range("pixel size", *p, 1e-3, 64.0, "in [0.001, 64] voxels")?;
        }
        super::check_range("d (pixels)", self.d_pixels, 1e-3, 1e3, "in [0.001, 1000]")?;
        super::check_range(
            "direction table azimuth step",
            self.table_azimuth_step_deg,
            1e-3,
            180.0,
            "in (0°, 180°]",
        )?;
        super::check_range(
            "image size",
            self.image_voxels,
            1.0,
            4096.0,
            "in [1, 4096] voxels",
        )?;
        Ok(())
    }
}

/// One view of one tile at one distance.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SliceSweepRow {
    /// Tile.
    pub tile: TestTile,
    /// Pixel size in voxels.
    pub pixel_voxels: f64,
    /// `"above"` or `"below"`.
    pub side: &'static str,
    /// Polar angle from the surface normal on the viewer's side (degrees).
    pub angle_deg: f64,
    /// The height-axis (`y`) stack's choice by the criterion.
    pub one: ViewChoice,
    /// The choice among three directions.
    pub three: ViewChoice,
    /// PSNR of all `y` slices (level 0).
    pub psnr_all: f64,
    /// PSNR of the `y` stack at the criterion's level, per rule (`drop` included).
    pub psnr_rule: BTreeMap<&'static str, f64>,
    /// PSNR of the three-direction choice at its criterion level, default rule.
    pub psnr_three: f64,
    /// PSNR of the three-direction choice with all its slices.
    pub psnr_three_all: f64,
    /// PSNR of the three-direction choice at its level drawn as a GPU would: one sample per
    /// pixel, slices read with trilinear 2D mip filtering.
    pub psnr_three_gpu: f64,
    /// PSNR of each direction (`X`, `Y`, `Z`) at the level the criterion picks for it, default
    /// rule: what the direction rule chooses among (`psnr_three` is one of them).
    pub psnr_axis: [f64; 3],
    /// The choice of the measured [`DirectionTable`] (same levels as the criterion's), when
    /// measured.
    pub table: Option<ViewChoice>,
}

impl SliceSweepRow {
    /// How far the direction rule's choice falls below the best direction (dB, ≥ 0).
    pub fn direction_shortfall_db(&self) -> f64 {
        let best = self.psnr_axis.iter().copied().fold(f64::MIN, f64::max);
        (best - self.psnr_three).max(0.0)
    }

    /// How far the [`DirectionTable`]'s choice falls below the best direction (dB, ≥ 0), when
    /// measured.
    pub fn table_shortfall_db(&self) -> Option<f64> {
        let best = self.psnr_axis.iter().copied().fold(f64::MIN, f64::max);
        self.table
            .map(|c| (best - self.psnr_axis[c.axis.index()]).max(0.0))
    }
}

/// Mean PSNR of the `y` stack per level and rule (first distance, every angle and side).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LevelRow {
    /// Tile.
    pub tile: TestTile,
    /// Level `k`.
    pub level: usize,
    /// Slices per tile, `N/2^k`.
    pub slices: usize,
    /// Mean PSNR per rule.
    pub psnr_rule: BTreeMap<&'static str, f64>,
}

/// PSNR of the shells over a cylindrical patch ([`super::curved`]) per level and rule (always
/// linear reconstruction).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CurvedRow {
    /// Tile.
    pub tile: TestTile,
    /// View tilt toward the axis (degrees).
    pub tilt_deg: f64,
    /// Level `k`.
    pub level: usize,
    /// Shells, `N/2^k`.
    pub slices: usize,
    /// PSNR per rule.
    pub psnr_rule: BTreeMap<&'static str, f64>,
}

/// Error of one view of any volume ([`view_errors`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ViewError {
    /// The view.
    pub view: StackView,
    /// Direction and level drawn.
    pub choice: ViewChoice,
    /// PSNR against the ray-marched truth (dB, capped at 99).
    pub psnr_db: f64,
    /// Root mean square error of the premultiplied channels.
    pub rmse: f64,
}

/// For each view, the direction and level the criterion picks (visible depth `depth` world
/// units, among the built axes of `data`) and the error of that stack against the ray-marched
/// truth of `volume`: the measurement a pipeline stores beside the slices. Cost: one truth
/// march and one slice render per view.
///
/// Errors: invalid views or parameters, `data` not cut from a volume of `volume`'s size.
pub fn view_errors(
    volume: &TexelVolume,
    data: &SliceData,
    views: &[StackView],
    depth: f64,
    render: &SliceRenderParams,
    truth: &VolumeTruthParams,
) -> Result<Vec<ViewError>, SliceError> {
    check_cut_from(data, volume)?;
    let allowed = Axis::ALL.map(|a| data.stack(a, 0).is_ok());
    views
        .iter()
        .map(|view| {
            view.validate()?;
            let choice = choose(volume, view.vector(), depth, allowed)?;
            let reference = render_truth(volume, view, render, truth)?;
            let img = render_slices(data, choice.axis, choice.level, view, render)?;
            let e = crate::metrics::compare(&img, &reference, &Default::default())?;
            Ok(ViewError {
                view: *view,
                choice,
                psnr_db: capped(e.psnr_db),
                rmse: e.rmse,
            })
        })
        .collect()
}

/// Per-tile summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TileSummary {
    /// Tile.
    pub tile: TestTile,
    /// Mean over every view of `PSNR(merged, default rule) − PSNR(drop)` at the criterion level.
    pub merge_gain_db: f64,
    /// The same over the views where the criterion picks a level above 0.
    pub merge_gain_merged_views_db: f64,
    /// Mean PSNR of three directions minus one at grazing views (≥ 70°), each at its level.
    pub three_gain_grazing_db: f64,
    /// The same with all slices of each direction.
    pub three_gain_grazing_all_db: f64,
    /// Mean slices drawn per tile over the sweep (three directions, criterion's level; all
    /// slices would be `N`).
    pub slices_drawn_mean: f64,
    /// How far below the best of the three directions (each at its criterion level) the
    /// direction rule's choice falls: the worst view of the sweep (dB, ≥ 0).
    pub direction_shortfall_max_db: f64,
    /// The same, mean over the sweep.
    pub direction_shortfall_mean_db: f64,
    /// How far below the best direction the [`DirectionTable`]'s choice falls: the worst view
    /// (dB, ≥ 0), when measured.
    pub table_shortfall_max_db: Option<f64>,
    /// The same, mean over the sweep.
    pub table_shortfall_mean_db: Option<f64>,
    /// Mean slices drawn per tile over the sweep with the table's choice.
    pub table_slices_drawn_mean: Option<f64>,
    /// Time to measure the direction tables (seconds), when measured.
    pub table_seconds: Option<f64>,
    /// The direction tables measured: above, and below when both sides are measured.
    pub direction_tables: Option<Vec<DirectionTable>>,
    /// Bytes of the default rule's stacks (RGBA8, all levels and axes, 2D mips).
    pub bytes: usize,
    /// Bytes of the level-0 `y` stack alone (RGBA8).
    pub bytes_y_level0: usize,
    /// Build time of the default rule's stacks (seconds).
    pub build_seconds: f64,
    /// Build time of the texel volume (seconds).
    pub volume_seconds: f64,
}

/// Per-rule summary over every tile, distance and angle where the criterion merges (level ≥ 1).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RuleSummary {
    /// Rule name.
    pub rule: &'static str,
    /// Mean PSNR viewed from above.
    pub above_db: f64,
    /// Mean PSNR viewed from below.
    pub below_db: f64,
    /// Views averaged per side.
    pub views: usize,
}

/// Everything [`measure`] found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MeasureReport {
    /// Parameters used.
    pub params: SliceMeasureParams,
    /// The default merge rule measured as "merged".
    pub default_rule: MergeRule,
    /// One row per tile, distance, side and angle.
    pub sweep: Vec<SliceSweepRow>,
    /// Error against level.
    pub levels: Vec<LevelRow>,
    /// Shells over a cylindrical patch (8 tiles around), error against level and rule.
    pub curved: Vec<CurvedRow>,
    /// Per tile.
    pub tiles: Vec<TileSummary>,
    /// Per rule.
    pub rules: Vec<RuleSummary>,
    /// Wall time of the whole measurement (seconds).
    pub seconds: f64,
}

/// Errors: `data` not cut from a volume of `volume`'s size.
pub(crate) fn check_cut_from(data: &SliceData, volume: &TexelVolume) -> Result<(), SliceError> {
    if data.dims() != volume.dims() {
        return Err(SliceError::InvalidParameter {
            name: "slice data",
            value: format!("{:?} vs volume {:?}", data.dims(), volume.dims()),
            reason: "must be cut from a volume of the same size",
        });
    }
    Ok(())
}

/// A PSNR capped at [`PSNR_CAP`] (identical images).
pub(crate) fn capped(x: f64) -> f64 {
    x.min(PSNR_CAP)
}

fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = xs.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

struct TileData {
    by_rule: Vec<(MergeRule, SliceData)>,
}

impl TileData {
    fn get(&self, rule: MergeRule) -> &SliceData {
        &self
            .by_rule
            .iter()
            .find(|(r, _)| *r == rule)
            .expect("every rule is built")
            .1
    }
}

/// Measures every tile of `params` (see the module docs). Cost: per tile, distance, side and
/// angle one truth march and about ten slice renders; levels: one render per level and rule.
pub fn measure(params: &SliceMeasureParams) -> Result<MeasureReport, SliceError> {
    params.validate()?;
    let start = Instant::now();
    let default_rule = SliceParams::default().rule;
    let mut sweep = Vec::new();
    let mut levels = Vec::new();
    let mut curved = Vec::new();
    let mut tiles = Vec::new();
    for &tile in &params.tiles {
        let t0 = Instant::now();
        let volume = test_tile(tile, params.size, params.seed)?;
        let volume_seconds = t0.elapsed().as_secs_f64();
        let mut by_rule = Vec::new();
        let mut default_report = None;
        for rule in MergeRule::ALL {
            let (data, report) = build_slices(
                &volume,
                &SliceParams {
                    rule,
                    fit_bilinear: params.filter == SliceReconstruction::Linear,
                    ..SliceParams::default()
                },
            )?;
            if rule == default_rule {
                default_report = Some(report);
            }
            by_rule.push((rule, data));
        }
        let report = default_report.expect("the default rule is among MergeRule::ALL");
        let td = TileData { by_rule };
        let t0 = Instant::now();
        let tables = if params.direction_table {
            Some(direction_tables(&volume, td.get(default_rule), params)?)
        } else {
            None
        };
        let table_seconds = tables.as_ref().map(|_| t0.elapsed().as_secs_f64());
        let (rows, level_rows) =
            sweep_tile(tile, &volume, &td, params, default_rule, tables.as_deref())?;
        levels.extend(level_rows);
        curved.extend(curved_rows(tile, &volume, &td, params)?);
        let merge_gain = |only_merged: bool| {
            mean(
                rows.iter()
                    .filter(|r| !only_merged || r.one.level > 0)
                    .map(|r| r.psnr_rule[default_rule.name()] - r.psnr_rule["drop"]),
            )
        };
        let grazing = |all: bool| {
            mean(rows.iter().filter(|r| r.angle_deg >= 70.0).map(|r| {
                if all {
                    r.psnr_three_all - r.psnr_all
                } else {
                    r.psnr_three - r.psnr_rule[default_rule.name()]
                }
            }))
        };
        let y0 = td.get(default_rule).stack(Axis::Y, 0)?;
        tiles.push(TileSummary {
            tile,
            merge_gain_db: merge_gain(false),
            merge_gain_merged_views_db: merge_gain(true),
            three_gain_grazing_db: grazing(false),
            three_gain_grazing_all_db: grazing(true),
            slices_drawn_mean: mean(rows.iter().map(|r| r.three.slices as f64)),
            direction_shortfall_max_db: rows
                .iter()
                .map(|r| r.direction_shortfall_db())
                .fold(0.0, f64::max),
            direction_shortfall_mean_db: mean(rows.iter().map(|r| r.direction_shortfall_db())),
            table_shortfall_max_db: tables.as_ref().map(|_| {
                rows.iter()
                    .filter_map(|r| r.table_shortfall_db())
                    .fold(0.0, f64::max)
            }),
            table_shortfall_mean_db: tables
                .as_ref()
                .map(|_| mean(rows.iter().filter_map(|r| r.table_shortfall_db()))),
            table_slices_drawn_mean: tables
                .as_ref()
                .map(|_| mean(rows.iter().filter_map(|r| r.table.map(|c| c.slices as f64)))),
            table_seconds,
            direction_tables: tables,
            bytes: report.bytes,
            bytes_y_level0: y0
                .slices(super::Side::Plus)
                .iter()
                .map(|p| p.levels()[0].data.len())
                .sum(),
            build_seconds: report.build_seconds,
            volume_seconds,
        });
        sweep.extend(rows);
    }
    let rules = MergeRule::ALL
        .iter()
        .map(|rule| {
            let side_mean = |side: &str| {
                let v: Vec<f64> = sweep
                    .iter()
                    .filter(|r| r.side == side && r.one.level > 0)
                    .map(|r| r.psnr_rule[rule.name()])
                    .collect();
                (mean(v.iter().copied()), v.len())
            };
            let (above_db, views) = side_mean("above");
            let (below_db, _) = side_mean("below");
            RuleSummary {
                rule: rule.name(),
                above_db,
                below_db,
                views,
            }
        })
        .collect();
    Ok(MeasureReport {
        params: params.clone(),
        default_rule,
        sweep,
        levels,
        curved,
        tiles,
        rules,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The views of the sweep: `(side, polar angle on that side, view)`.
fn views(params: &SliceMeasureParams) -> Vec<(&'static str, f64, StackView)> {
    let mut out = Vec::new();
    for &a in &params.angles_deg {
        out.push(("above", a, StackView::degrees(a, params.azimuth_deg)));
        if params.both_sides {
            out.push((
                "below",
                a,
                StackView::degrees(180.0 - a, params.azimuth_deg + 180.0),
            ));
        }
    }
    out
}

/// The direction tables of one tile: above, and below when both sides are measured (see
/// [`SliceMeasureParams::direction_table`]).
fn direction_tables(
    volume: &TexelVolume,
    data: &SliceData,
    params: &SliceMeasureParams,
) -> Result<Vec<DirectionTable>, SliceError> {
    let mut angles = params.angles_deg.clone();
    angles.sort_by(f64::total_cmp);
    angles.dedup();
    let mut polar = vec![0.0];
    polar.extend(angles.windows(2).map(|w| 0.5 * (w[0] + w[1])));
    if polar.last().is_some_and(|&p| p < 88.0) {
        polar.push(88.0);
    }
    polar.dedup();
    let mut pixels = params.pixel_voxels.clone();
    pixels.sort_by(f64::total_cmp);
    pixels.dedup();
    let truth = VolumeTruthParams {
        steps_per_voxel: params.truth_steps,
        filter: params.filter,
    };
    let (az, half) = (params.azimuth_deg, 0.5 * params.table_azimuth_step_deg);
    let render = |p: f64| (render_params(params, p), render_params(params, p));
    let above = DirectionGrid {
        polar_deg: polar.clone(),
        azimuth_deg: vec![az - half, az + half],
        pixel_voxels: pixels.clone(),
    };
    let below = DirectionGrid {
        polar_deg: polar.iter().rev().map(|p| 180.0 - p).collect(),
        azimuth_deg: vec![az + 180.0 - half, az + 180.0 + half],
        pixel_voxels: pixels,
    };
    let mut tables = vec![DirectionTable::measure(
        volume,
        data,
        &above,
        params.d_pixels,
        &render,
        &truth,
    )?];
    if params.both_sides {
        tables.push(DirectionTable::measure(
            volume,
            data,
            &below,
            params.d_pixels,
            &render,
            &truth,
        )?);
    }
    Ok(tables)
}

/// Shells over the cylindrical patch at tilts 0° and 45°: every level and rule.
fn curved_rows(
    tile: TestTile,
    volume: &TexelVolume,
    td: &TileData,
    params: &SliceMeasureParams,
) -> Result<Vec<CurvedRow>, SliceError> {
    let n = volume.len(Axis::Y);
    let mut rows = Vec::new();
    for tilt_deg in [0.0, 45.0] {
        let cp = CurvedParams {
            tilt_deg,
            truth_steps: params.truth_steps,
            ..CurvedParams::default()
        };
        let truth = render_curved_truth(volume, &cp)?;
        for level in 0..=n.trailing_zeros() as usize {
            let mut psnr_rule = BTreeMap::new();
            for rule in MergeRule::ALL {
                let img = render_curved_slices(td.get(rule), level, &cp)?;
                psnr_rule.insert(rule.name(), capped(psnr(&img, &truth)?));
            }
            rows.push(CurvedRow {
                tile,
                tilt_deg,
                level,
                slices: n >> level,
                psnr_rule,
            });
        }
    }
    Ok(rows)
}

fn render_params(params: &SliceMeasureParams, p: f64) -> SliceRenderParams {
    let px = (params.image_voxels / p).round().max(1.0) as usize;
    SliceRenderParams {
        width: px,
        height: px,
        pixel_voxels: p,
        supersample: Supersample::new((2.0 * p).ceil().max(1.0) as usize)
            .unwrap_or(Supersample::ONE),
        filter: params.filter,
        ..SliceRenderParams::default()
    }
}

/// The sweep of one tile, and the error against level at the first distance (from the same
/// truth images).
fn sweep_tile(
    tile: TestTile,
    volume: &TexelVolume,
    td: &TileData,
    params: &SliceMeasureParams,
    default_rule: MergeRule,
    tables: Option<&[DirectionTable]>,
) -> Result<(Vec<SliceSweepRow>, Vec<LevelRow>), SliceError> {
    let truth = VolumeTruthParams {
        steps_per_voxel: params.truth_steps,
        filter: params.filter,
    };
    let s = volume.voxel_size();
    let n = volume.len(Axis::Y);
    let level_count = n.trailing_zeros() as usize + 1;
    let first = params.pixel_voxels[0];
    let mut level_sums = vec![BTreeMap::<&'static str, f64>::new(); level_count];
    let mut level_views = 0usize;
    let mut rows = Vec::new();
    // Views one after the other; each image is parallel over its rows.
    for &p in &params.pixel_voxels {
        let rp = render_params(params, p);
        for (side, angle_deg, view) in views(params) {
            let reference = render_truth(volume, &view, &rp, &truth)?;
            let err = |data: &SliceData, axis: Axis, level: usize| -> Result<f64, SliceError> {
                let img = render_slices(data, axis, level, &view, &rp)?;
                Ok(capped(psnr(&img, &reference)?))
            };
            let depth = params.d_pixels * p * s;
            let v = view.vector();
            let one = choose(volume, v, depth, [false, true, false])?;
            let three = choose(volume, v, depth, [true; 3])?;
            let table = match tables {
                Some(t) => {
                    let t = &t[usize::from(side == "below")];
                    Some(t.choose(td.get(default_rule), &view, p, [true; 3])?)
                }
                None => None,
            };
            let def = td.get(default_rule);
            let mut psnr_axis = [0.0; 3];
            for (k, e) in psnr_axis.iter_mut().enumerate() {
                let mut only = [false; 3];
                only[k] = true;
                let c = choose(volume, v, depth, only)?;
                *e = err(def, c.axis, c.level)?;
            }
            let mut psnr_rule = BTreeMap::new();
            for rule in MergeRule::ALL {
                psnr_rule.insert(rule.name(), err(td.get(rule), Axis::Y, one.level)?);
            }
            if p == first {
                level_views += 1;
                for (level, sums) in level_sums.iter_mut().enumerate() {
                    for rule in MergeRule::ALL {
                        let e = if level == one.level {
                            psnr_rule[rule.name()]
                        } else {
                            err(td.get(rule), Axis::Y, level)?
                        };
                        *sums.entry(rule.name()).or_insert(0.0) += e;
                    }
                }
            }
            rows.push(SliceSweepRow {
                tile,
                pixel_voxels: p,
                side,
                angle_deg,
                one,
                three,
                psnr_all: err(def, Axis::Y, 0)?,
                psnr_rule,
                psnr_three: psnr_axis[three.axis.index()],
                psnr_three_all: err(def, three.axis, 0)?,
                psnr_three_gpu: {
                    let gpu = SliceRenderParams {
                        supersample: Supersample::ONE,
                        mip_2d: true,
                        filter: SliceReconstruction::Linear,
                        ..rp.clone()
                    };
                    let img = render_slices(def, three.axis, three.level, &view, &gpu)?;
                    capped(psnr(&img, &reference)?)
                },
                psnr_axis,
                table,
            });
        }
    }
    let levels = level_sums
        .into_iter()
        .enumerate()
        .map(|(level, sums)| LevelRow {
            tile,
            level,
            slices: n >> level,
            psnr_rule: sums
                .into_iter()
                .map(|(k, v)| (k, v / level_views as f64))
                .collect(),
        })
        .collect();
    Ok((rows, levels))
}
