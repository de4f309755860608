//! Slices of an object in the pipeline (docs/design.md §9.4): the asset's shape or mesh is
//! voxelised in its box `[−1, 1] × [0, 2] × [−1, 1]` (the bounding cylinder's), its colours
//! shaded with the scene's light, and cut into the stacks and merge levels the needed views and
//! screen sizes draw.
//!
//! ## Files
//!
//! One 8-bit RGBA PNG atlas per stack and side: `slices-{axis}{level}.png` (role `{axis}{level}`),
//! and `slices-{axis}{level}-minus.png` (role `{axis}{level}-minus`) for the minus side of a
//! per-side merge. The atlas is the stack's `N/2^level` slices one under another: slice `j`
//! (lying in the plane `q_axis = (j + ½)·h`, `h = 2^level·s`, from the box's lower corner)
//! fills rows `j·H … (j + 1)·H − 1`; texel `(i, j)` of a slice is voxel `u = i`, `v = j` of the
//! axis's plane ([`super::Axis::plane_axes`]). Colour is straight sRGB, alpha the slice's opacity
//! at normal incidence (linear): premultiply on load, and raise alpha to `1/|cos|` at an
//! oblique view (the module conventions). The metadata gives `dims`, `voxel` (edge, object
//! units), `box_min`, the merge `rule`, `depth_px` (the criterion's visible depth in pixels,
//! for choosing the level per view) and the `stacks`.

use std::time::Instant;

use altrep_data_gen::{Fill, RgbaImage, Supersample};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::build::{ShapeParams, SliceLighting, from_shape};
use super::direction::{DirectionGrid, DirectionTable};
use super::merge::{MergeRule, Side, SliceData, SliceParams, StoredStack, build_slices};
use super::object::{choose_stored, render_object};
use super::render::{SliceRenderParams, StackView, render_slices};
use super::stack::{Axis, choose_direction, level_for_slices, slices_needed};
use super::truth::{VolumeTruthParams, render_truth};
use crate::asset::{AssetReader, AssetWriter, Channel, CodeImage, Encoding};
use crate::mip::Texture;
use crate::representation::{
    Estimate, InputSize, Lighting, Measurement, Needs, Picture, PipelineError, Plan,
    Representation, Source, Window, elevation_note, fold, linear_bytes, measure_angles,
    measure_views, score, secs,
};

/// Lower corner of the voxelised box (object units): the bounding cylinder's box.
pub const BOX_MIN: [f64; 3] = [-1.0, 0.0, -1.0];
/// Edge of the voxelised box (object units).
const BOX_EDGE: f64 = 2.0;

/// Manifest parameters of slices (`[asset.slices]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlicesSpec {
    /// Voxels per side of the box (power of two, 4–256; default 64). The planner lowers it to the
    /// closest footprint (the largest screen size rounded up to a power of two).
    pub resolution: usize,
    /// Merge rule of the coarser levels: `per-side` (default), `symmetric`, `front-over-back`,
    /// `back-over-front`, or `drop` (the baseline that keeps one layer in `2^k`).
    pub rule: String,
    /// Inside tests per voxel edge when voxelising ([`Supersample`]: `k³` per voxel; 1–4,
    /// default 2).
    pub supersample: Supersample,
    /// Visible depth `d` of Meyer & Neyret's criterion `h·tan a / d ≤ 1`, in pixels of the
    /// screen size (in `[0.25, 16]`; default 1): the planner builds, and a display draws, the
    /// coarsest level that keeps the parallax error of a view under `d`.
    pub depth_px: f64,
    /// Fit the merged slices to the bilinear filter that draws them (docs/design.md §9.5):
    /// `true` or `false`; absent (default): on for a tile (strands and leaves gain 5–11 dB
    /// straight on against the ray-marched tile), off for an object (the tree and the chair
    /// lose 1.67 and 1.47 dB against their ray-cast truth when fitted).
    pub fit_bilinear: Option<bool>,
    /// Choose the direction drawn per view by measured error (docs/design.md §9.6), not by the
    /// direction rule alone: the build measures a [`DirectionTable`] over the needed views (polar
    /// nodes at most 10° apart from the normal to `grazing_deg`, azimuths at most 30° apart, three
    /// screen sizes), one truth march per node and one render per built stack there, and a
    /// display draws, among the built axes, the stack it predicts closest to the truth. The
    /// planner then builds every axis at the levels its own criterion asks for the needed views,
    /// not only the axis the rule picks. A tile only (the table is measured against the
    /// ray-marched tile). Default `false`: it costs one truth march per node and one render
    /// per stack there, and every axis takes bytes (the 32³ fur tile at 8 px up to 80°, 36
    /// nodes: 4.9 s beside 0.4 s for the slices, 1.54 MB of stacks against 1.02 MB).
    pub direction_table: bool,
    /// How a mesh is voxelised ([`Fill`]): `solid` (its inside, by ray parity), `shell` (the
    /// share of rays its surface stops in each voxel: open meshes, alpha-masked leaves) or
    /// `auto` (default: solid when the mesh is closed and no material cuts rays, shell
    /// otherwise). Ignored for a procedural tile.
    pub fill: Fill,
}

impl Default for SlicesSpec {
    fn default() -> Self {
        Self {
            resolution: 64,
            rule: MergeRule::PerSide.name().into(),
            supersample: Supersample::of(2),
            depth_px: 1.0,
            fit_bilinear: None,
            direction_table: false,
            fill: Fill::Auto,
        }
    }
}

fn rule_of(name: &str) -> Option<MergeRule> {
    MergeRule::ALL.into_iter().find(|r| r.name() == name)
}

impl SlicesSpec {
    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !self.resolution.is_power_of_two() || !(4..=256).contains(&self.resolution) {
            return Err(format!(
                "slices.resolution = {} must be a power of two in 4..=256",
                self.resolution
            ));
        }
        if rule_of(&self.rule).is_none() {
            let names: Vec<_> = MergeRule::ALL.iter().map(|r| r.name()).collect();
            return Err(format!(
                "slices.rule = '{}' must be one of {}",
                self.rule,
                names.join(", ")
            ));
        }
        if !(1..=4).contains(&self.supersample.get()) {
            return Err(format!(
                "slices.supersample = {} must be in 1..=4",
                self.supersample.get()
            ));
        }
        if !(self.depth_px.is_finite() && (0.25..=16.0).contains(&self.depth_px)) {
            return Err(format!(
                "slices.depth_px = {} must be in [0.25, 16]",
                self.depth_px
            ));
        }
        Ok(())
    }
}

/// What the planner decided for the slices.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlicesDecisions {
    /// Voxels per side actually built.
    pub resolution: usize,
    /// Axes whose stacks some needed view draws (`x, y, z`).
    pub axes: [bool; 3],
    /// Merge levels some needed view and screen size draws, ascending (every built axis).
    pub levels: Vec<usize>,
    /// Built from a tile (repeated over a surface) rather than an object.
    #[serde(default)]
    pub tiled: bool,
    /// Picture side (pixels) of the measurement: the voxels per side for an object, the largest
    /// screen size of one tile for a tile.
    #[serde(default)]
    pub measure_px: usize,
    /// Nodes of the direction table to measure ([`SlicesSpec::direction_table`]), if asked.
    #[serde(default)]
    pub direction_grid: Option<DirectionGrid>,
}

/// Slices as loaded from an asset folder: the stacks and the criterion's visible depth.
#[derive(Clone, Debug)]
pub struct SlicesAsset {
    /// The stacks, over the box of lower corner [`BOX_MIN`].
    pub slices: SliceData,
    /// Visible depth of the criterion in pixels ([`SlicesSpec::depth_px`]).
    pub depth_px: f64,
    /// The merged slices were fitted to bilinear filtering ([`SlicesSpec::fit_bilinear`]);
    /// recorded, not needed to draw them.
    pub fitted: bool,
    /// The measured direction table ([`SlicesSpec::direction_table`]), if built: then
    /// [`Self::choose`] draws the direction it predicts closest to the truth.
    pub direction: Option<DirectionTable>,
}

impl SlicesAsset {
    /// The stack a display draws for `view` (unit, toward the camera) at screen size `size_px`
    /// (pixels across the box's width): the criterion's depth is `depth_px` pixels of that size.
    /// The direction is the table's ([`DirectionTable::choose`]) when the asset has one and the
    /// view is at least 1° from the surface plane, else the direction rule's
    /// ([`choose_stored`]); the level is the criterion's for that direction.
    pub fn choose(
        &self,
        view: DVec3,
        size_px: f64,
    ) -> Result<super::ViewChoice, super::SliceError> {
        let n = self.slices.dims()[0] as f64;
        let width = n * self.slices.voxel_size();
        if let Some(table) = &self.direction
            && view.is_finite()
            && view.length_squared() > 1e-24
        {
            let v = view.normalize();
            let sv = StackView {
                polar: v.y.clamp(-1.0, 1.0).acos(),
                azimuth: v.z.atan2(v.x),
            };
            let p = n / size_px;
            if sv.validate().is_ok() && p.is_finite() && (1e-3..=64.0).contains(&p) {
                return table.choose(&self.slices, &sv, p, [true; 3]);
            }
        }
        choose_stored(&self.slices, view, self.depth_px * width / size_px)
    }
}

/// Slices of an object for the pipeline.
pub struct SlicesRepr;

/// The box resolution the closest footprint needs: the largest screen size rounded up to a power
/// of two, at least 4.
fn closest_resolution(needs: &Needs) -> usize {
    (needs.screen_px[1].ceil() as usize)
        .next_power_of_two()
        .max(4)
}

/// Unit view vectors (toward the camera) sampling the needed azimuths and the elevations
/// `[e0, e1]` (degrees): 72 azimuths round a full circle, else 37 over the range, ends included;
/// 9 elevations over a range, ends included.
fn sampled_views(needs: &Needs, [e0, e1]: [f64; 2]) -> Vec<DVec3> {
    let [a0, a1] = needs.azimuth_deg;
    let azimuths: Vec<f64> = if needs.all_azimuths() {
        (0..72).map(|k| f64::from(k) * 5.0).collect()
    } else {
        (0..=36)
            .map(|k| a0 + (a1 - a0) * f64::from(k) / 36.0)
            .collect()
    };
    let elevations: Vec<f64> = if e0 == e1 {
        vec![e0]
    } else {
        (0..=8)
            .map(|k| e0 + (e1 - e0) * f64::from(k) / 8.0)
            .collect()
    };
    let mut v = Vec::with_capacity(azimuths.len() * elevations.len());
    for e in &elevations {
        for a in &azimuths {
            let (a, e) = (a.to_radians(), e.to_radians());
            v.push(DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin()));
        }
    }
    v
}

/// The views of an object: [`sampled_views`] over the needed elevations.
fn needed_views(needs: &Needs) -> Vec<DVec3> {
    sampled_views(needs, needs.elevation_deg)
}

/// The views of a tile lying on a surface (normal `+y`), from the normal to `grazing_deg` away
/// from it: [`sampled_views`] over the elevations `90° − grazing_deg` to `90°` (a view at polar
/// angle `θ` from the normal has elevation `90° − θ`: `v = (sin θ cos φ, cos θ, sin θ sin φ)`,
/// the slices module's convention).
fn tile_views(needs: &Needs) -> Vec<DVec3> {
    sampled_views(needs, [90.0 - needs.grazing_deg, 90.0])
}

/// Nine screen sizes from the smallest needed to the largest, spaced geometrically.
fn needed_sizes(needs: &Needs) -> Vec<f64> {
    let [p0, p1] = needs.screen_px;
    (0..=8)
        .map(|k| p0 * (p1 / p0).powf(f64::from(k) / 8.0))
        .collect()
}

/// The nodes of a tile's direction table ([`SlicesSpec::direction_table`]): polar angles from
/// the normal to `grazing_deg` (at most 88°), at most 10° apart; the needed azimuths at most 30°
/// apart (12 round a full circle); the pixel sizes (voxels per pixel, `n` voxels across a tile)
/// of the smallest, middle and largest needed screen sizes.
fn tile_grid(needs: &Needs, n: usize) -> DirectionGrid {
    let spread = |a: f64, b: f64, step: f64| -> Vec<f64> {
        let k = ((b - a) / step).ceil().max(0.0) as usize;
        if k == 0 {
            return vec![a];
        }
        (0..=k).map(|i| a + (b - a) * i as f64 / k as f64).collect()
    };
    let polar_deg = spread(0.0, needs.grazing_deg.clamp(0.0, 88.0), 10.0);
    let azimuth_deg = if needs.all_azimuths() {
        (0..12).map(|k| f64::from(k) * 30.0).collect()
    } else {
        let [a0, a1] = needs.azimuth_deg;
        let mut a = spread(a0, a1.min(a0 + 359.0), 30.0);
        a.dedup();
        a
    };
    let [s0, s1] = needs.screen_px;
    let mut pixel_voxels: Vec<f64> = [s1, (s0 * s1).sqrt(), s0]
        .iter()
        .map(|s| (n as f64 / s).clamp(1e-3, 64.0))
        .collect();
    pixel_voxels.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * b.abs());
    DirectionGrid {
        polar_deg,
        azimuth_deg,
        pixel_voxels,
    }
}

/// How a tile is drawn and its truth rendered at `p` voxels per pixel (`n` voxels across a
/// tile), for the direction table and [`measure_tile`] alike: the slices at one sample per pixel
/// with trilinear 2D reads, as a display draws them, in a window of 1.5 tiles (8 to 384 pixels),
/// the truth with `⌈2p⌉²` rays per pixel (at most 8 × 8).
fn tile_render(n: usize, p: f64) -> (SliceRenderParams, SliceRenderParams) {
    let px = n as f64 / p;
    let side = ((1.5 * px).ceil() as usize).clamp(8, 384);
    let k = ((2.0 * p).ceil() as usize).clamp(1, 8);
    let draw = SliceRenderParams {
        width: side,
        height: side,
        pixel_voxels: p,
        supersample: Supersample::ONE,
        mip_2d: true,
        ..SliceRenderParams::default()
    };
    let fine = SliceRenderParams {
        supersample: Supersample::of(k),
        ..draw.clone()
    };
    (draw, fine)
}

impl Representation for SlicesRepr {
    const NAME: &'static str = "slices";
    const CASTS_RAYS: bool = false;
    const RELIGHTS: bool = false;
    const FROM_TILE: bool = true;
    type Spec = SlicesSpec;
    type Data = SlicesAsset;
    type Decisions = SlicesDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px": needs.screen_px, "azimuth_deg": needs.azimuth_deg,
                "elevation_deg": needs.elevation_deg, "lighting": needs.lighting })
    }

    fn estimate(spec: &SlicesSpec, needs: &Needs, input: &InputSize) -> Estimate {
        // ~150 B per voxel at 64³ (data-gen's voxelisation, the volume, the f32 slices with
        // their 2D mips and minus sides, the read-back copy), fitted to the peaks
        // `tests/memory.rs` measures, and a few MB of fixed cost.
        // A tile is cut at its own size (and not voxelised here).
        let n = input
            .tile
            .unwrap_or_else(|| closest_resolution(needs).min(spec.resolution))
            as f64;
        let ss = spec.supersample.get() as f64 / 2.0;
        // A tile is measured on pictures of 1.5 tiles at up to 256 px a tile: the truth, the
        // drawing and their working copies, ~8 RGBA f32 images.
        let pictures = if input.tile.is_some() {
            let side = 1.5 * needs.screen_px[1].clamp(8.0, 256.0);
            8.0 * 16.0 * side * side
        } else {
            0.0
        };
        // The fit to bilinear filtering (on for a tile by default) holds each slab's target and
        // fit besides: ~100 B per voxel more (the 64³ fur tile peaks at ~256 B per voxel).
        let fit = if spec.fit_bilinear.unwrap_or(input.tile.is_some()) {
            100.0
        } else {
            0.0
        };
        Estimate {
            peak_bytes: linear_bytes(3e6 + pictures, 40.0 * ss.max(1.0) + 110.0 + fit, n * n * n),
            // RGBA8, three axes, level 0 plus merged levels on two sides (≤ 2 N³ texels).
            output_bytes: linear_bytes(0.0, 3.0 * 4.0 * 3.0, n * n * n),
        }
    }

    fn plan(
        spec: &SlicesSpec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, SlicesDecisions), PipelineError> {
        let mut plan = Plan::default();
        // An object: its box at the closest footprint's resolution, seen from the needed
        // azimuths and elevations, `screen_px` across the box. A tile: at its own resolution,
        // seen from the surface's side up to the grazing angle, `screen_px` across one tile.
        let (resolution, voxel, lengths, views, across) = match source.tile {
            Some(tile) => {
                let d = tile.dims();
                let s = tile.voxel_size();
                let l = [d[0] as f64 * s, d[1] as f64 * s, d[2] as f64 * s];
                (d[0], s, l, tile_views(needs), l[0])
            }
            None => {
                let r = closest_resolution(needs).min(spec.resolution);
                let views = needed_views(needs);
                (r, BOX_EDGE / r as f64, [BOX_EDGE; 3], views, BOX_EDGE)
            }
        };
        let tiled = source.tile.is_some();
        let mut decisions = SlicesDecisions {
            resolution,
            axes: [false; 3],
            levels: Vec::new(),
            tiled,
            measure_px: if tiled {
                (needs.screen_px[1].ceil() as usize).clamp(8, 256)
            } else {
                resolution
            },
            direction_grid: None,
        };
        if spec.direction_table {
            if !tiled {
                return Err(PipelineError::WrongSource {
                    asset: source.name.into(),
                    needed: "a tile (`tile = { kind, size, seed }`) for `direction_table = true`: \
                             the table is measured against the ray-marched tile",
                });
            }
            let grid = tile_grid(needs, resolution);
            plan.build(format!(
                "direction table: {} polar angles × {} azimuths × {} screen sizes = {} nodes, \
                 one truth march and one render per built stack each (docs/design.md §9.6)",
                grid.polar_deg.len(),
                grid.azimuth_deg.len(),
                grid.pixel_voxels.len(),
                grid.polar_deg.len() * grid.azimuth_deg.len() * grid.pixel_voxels.len()
            ));
            decisions.direction_grid = Some(grid);
        }
        if needs.lighting == Lighting::Dynamic {
            plan.refuse(
                "slices store colour with the light baked in (no normals), and the needs ask for \
                 dynamic lighting: set lighting = \"baked\", or use the octree or images with \
                 parallax, which relight"
                    .into(),
            );
            return Ok((plan, decisions));
        }
        let mut l = spec.resolution;
        while !tiled && l > resolution {
            plan.skip(
                format!("{l}³ voxels"),
                format!(
                    "finer than the closest footprint: the largest screen size is {} px",
                    needs.screen_px[1]
                ),
            );
            l /= 2;
        }
        let s = voxel;
        let mut range: [Option<(usize, usize)>; 3] = [None; 3];
        // The rule's axis for each view; with a direction table, every axis (the table chooses
        // among the built ones by measured error), each at the levels its criterion asks.
        for v in views {
            let rule = choose_direction(v, [s; 3], [true; 3])?;
            for axis in Axis::ALL {
                if axis != rule && !spec.direction_table {
                    continue;
                }
                let i = axis.index();
                let n = (lengths[i] / s).round() as usize;
                for px in needed_sizes(needs) {
                    let depth = spec.depth_px * across / px;
                    let needed = slices_needed(lengths[i], v[i].abs().min(1.0).acos(), depth)?;
                    let level = level_for_slices(axis, n, needed, false)?;
                    range[i] = Some(
                        range[i].map_or((level, level), |(a, b)| (a.min(level), b.max(level))),
                    );
                }
            }
        }
        let lo = range.iter().flatten().map(|r| r.0).min().unwrap_or(0);
        let hi = range.iter().flatten().map(|r| r.1).max().unwrap_or(0);
        let top = resolution.trailing_zeros() as usize;
        for axis in Axis::ALL {
            let i = axis.index();
            if range[i].is_some() {
                plan.build(format!(
                    "{} stack of {resolution}³ voxels, levels {lo}–{hi} ({}–{} slices, rule {})",
                    axis.name(),
                    resolution >> lo,
                    resolution >> hi,
                    spec.rule
                ));
            } else {
                plan.skip(
                    format!("{} stack", axis.name()),
                    "no needed view draws it: the direction rule picks another axis for every one"
                        .into(),
                );
            }
        }
        if lo > 0 {
            plan.skip(
                format!(
                    "levels 0–{} ({}–{} slices)",
                    lo - 1,
                    resolution,
                    resolution >> (lo - 1)
                ),
                "no needed view and screen size asks for that many slices".into(),
            );
        }
        if hi < top {
            plan.skip(
                format!(
                    "levels {}–{top} ({}–1 slices)",
                    hi + 1,
                    resolution >> (hi + 1)
                ),
                "too few slices for every needed view and screen size".into(),
            );
        }
        decisions.axes = [0, 1, 2].map(|i| range[i].is_some());
        decisions.levels = (lo..=hi).collect();
        Ok((plan, decisions))
    }

    fn build(
        spec: &SlicesSpec,
        _needs: &Needs,
        decisions: &SlicesDecisions,
        source: &Source,
    ) -> Result<(SlicesAsset, serde_json::Value), PipelineError> {
        let n = decisions.resolution;
        let rule = rule_of(&spec.rule).ok_or_else(|| PipelineError::Spec(spec.rule.clone()))?;
        let t0 = Instant::now();
        let voxelised;
        let volume = match source.tile {
            Some(tile) => tile,
            None => {
                let voxelising = crate::profile::timer("voxelise");
                voxelised = from_shape(
                    source.shape()?,
                    &ShapeParams {
                        dims: [n; 3],
                        voxel: BOX_EDGE / n as f64,
                        min: BOX_MIN,
                        supersample: spec.supersample,
                        lighting: SliceLighting {
                            direction: source.light.direction.to_array(),
                            ambient: source.light.ambient,
                        },
                        tiled: false,
                        fill: spec.fill,
                    },
                )?;
                voxelising.stop();
                &voxelised
            }
        };
        let voxelize_s = secs(t0);
        if volume.rgba().iter().all(|v| v[3] <= 0.0) {
            return Err(PipelineError::Invisible {
                asset: source.name.into(),
                what: format!("the {n}³ voxels"),
            });
        }
        let fitted = spec.fit_bilinear.unwrap_or(source.tile.is_some());
        let cutting = crate::profile::timer("slices");
        let (slices, report) = build_slices(
            volume,
            &SliceParams {
                axes: decisions.axes,
                levels: Some(decisions.levels.clone()),
                rule,
                mip_2d: true,
                tiled: source.tile.is_some(),
                fit_bilinear: fitted,
            },
        )?;
        cutting.stop();
        let t1 = Instant::now();
        let direction = match (&decisions.direction_grid, source.tile) {
            (Some(grid), Some(tile)) => {
                let measuring = crate::profile::timer("direction table");
                let table = DirectionTable::measure(
                    tile,
                    &slices,
                    grid,
                    spec.depth_px,
                    &|p| tile_render(tile.dims()[0], p),
                    &VolumeTruthParams::default(),
                )?;
                measuring.stop();
                Some(table)
            }
            (Some(_), None) => {
                return Err(PipelineError::WrongSource {
                    asset: source.name.into(),
                    needed: "the volume tile the direction table is measured against",
                });
            }
            (None, _) => None,
        };
        let direction_s = secs(t1);
        Ok((
            SlicesAsset {
                slices,
                depth_px: spec.depth_px,
                fitted,
                direction,
            },
            json!({ "voxelize_s": voxelize_s, "build_s": report.build_seconds,
                    "fill": source.tile.map_or(if volume.has_axis_alpha() { "shell" } else { "solid" }, |_| "tile"),
                    "stacks": report.stacks.iter().map(|(a, l, c)| format!("{}{l}: {c} slices", a.name())).collect::<Vec<_>>(),
                    "bytes_rgba8": report.bytes, "opacity_error_max": report.opacity_error_max,
                    "direction_table_s": decisions.direction_grid.as_ref().map(|_| direction_s),
                    "fitted": report.fitted.iter().map(|(a, l, side)| format!("{}{l}{}", a.name(),
                        if *side == Side::Minus { "-minus" } else { "" })).collect::<Vec<_>>() }),
        ))
    }

    fn write(asset: &SlicesAsset, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let data = &asset.slices;
        let ch = |name: &str, encoding: Encoding| Channel {
            name: name.into(),
            encoding,
        };
        let channels = || {
            vec![
                ch("colour.r", Encoding::Srgb),
                ch("colour.g", Encoding::Srgb),
                ch("colour.b", Encoding::Srgb),
                ch(
                    "alpha",
                    Encoding::Linear {
                        scale: 1.0 / 255.0,
                        offset: 0.0,
                    },
                ),
            ]
        };
        let mut stacks = Vec::new();
        for stack in data.stacks() {
            let role = format!("{}{}", stack.axis().name(), stack.level());
            let mut sides = vec![(Side::Plus, role.clone())];
            if stack.per_side() {
                sides.push((Side::Minus, format!("{role}-minus")));
            }
            for (side, r) in &sides {
                w.png8(
                    r,
                    &format!("slices-{r}.png"),
                    &atlas_of(stack.slices(*side)),
                    channels(),
                )?;
            }
            stacks.push(json!({ "axis": stack.axis().name(), "level": stack.level(),
                                "slices": stack.count(), "plus": role,
                                "minus": stack.per_side().then(|| format!("{role}-minus")) }));
        }
        let box_min = if data.tiled() { [0.0; 3] } else { BOX_MIN };
        Ok(
            json!({ "dims": data.dims(), "voxel": data.voxel_size(), "box_min": box_min,
                   "tiled": data.tiled(), "rule": data.rule().name(),
                   "merged_fit": if asset.fitted { "bilinear" } else { "none" },
                   "depth_px": asset.depth_px, "stacks": stacks,
                   "direction_table": asset.direction }),
        )
    }

    fn read(r: &AssetReader) -> Result<SlicesAsset, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let field = |k: &str| r.content(format!("metadata.{k} missing or malformed"));
        let dims: [usize; 3] =
            serde_json::from_value(m["dims"].clone()).map_err(|_| field("dims"))?;
        let voxel = m["voxel"].as_f64().ok_or_else(|| field("voxel"))?;
        let tiled = match &m["tiled"] {
            serde_json::Value::Null => false,
            t => t.as_bool().ok_or_else(|| field("tiled"))?,
        };
        let box_min: [f64; 3] =
            serde_json::from_value(m["box_min"].clone()).map_err(|_| field("box_min"))?;
        let expected = if tiled { [0.0; 3] } else { BOX_MIN };
        if box_min != expected {
            return Err(r
                .content(format!(
                    "metadata.box_min = {box_min:?}, expected {expected:?}"
                ))
                .into());
        }
        let rule = m["rule"]
            .as_str()
            .and_then(rule_of)
            .ok_or_else(|| field("rule"))?;
        let depth_px = m["depth_px"]
            .as_f64()
            .filter(|d| d.is_finite() && *d > 0.0)
            .ok_or_else(|| field("depth_px"))?;
        let fitted = match m["merged_fit"].as_str() {
            None | Some("none") => false,
            Some("bilinear") => true,
            Some(_) => return Err(field("merged_fit").into()),
        };
        let list = m["stacks"].as_array().ok_or_else(|| field("stacks"))?;
        let mut stored = Vec::with_capacity(list.len());
        for s in list {
            let axis = match s["axis"].as_str() {
                Some("x") => Axis::X,
                Some("y") => Axis::Y,
                Some("z") => Axis::Z,
                _ => return Err(field("stacks[].axis").into()),
            };
            let level = s["level"].as_u64().ok_or_else(|| field("stacks[].level"))? as usize;
            let slices = s["slices"]
                .as_u64()
                .ok_or_else(|| field("stacks[].slices"))? as usize;
            let plus = s["plus"].as_str().ok_or_else(|| field("stacks[].plus"))?;
            let (ua, va) = axis.plane_axes();
            let (w, h) = (dims[ua], dims[va]);
            let side = |role: &str| -> Result<Vec<Texture>, PipelineError> {
                let img = r.png8(role)?;
                if img.width != w || img.height != h * slices || slices == 0 {
                    return Err(r
                        .content(format!(
                            "{role}: a {}×{} atlas, expected {w}×{} ({slices} slices of {w}×{h})",
                            img.width,
                            img.height,
                            h * slices
                        ))
                        .into());
                }
                let px = img
                    .to_premultiplied()
                    .map_err(|c| r.content(format!("{role}: {c} channels, expected 4")))?;
                px.chunks_exact(w * h * 4)
                    .map(
                        |c| Ok(Texture::new(w, h, 4, c.to_vec()).map_err(super::SliceError::from)?),
                    )
                    .collect()
            };
            let minus = match s["minus"].as_str() {
                Some(role) => Some(side(role)?),
                None => None,
            };
            stored.push(StoredStack {
                axis,
                level,
                plus: side(plus)?,
                minus,
            });
        }
        let slices = SliceData::from_stored(dims, voxel, rule, tiled, stored)
            .map_err(|e| r.content(format!("metadata.stacks: {e}")))?;
        let direction = match &m["direction_table"] {
            serde_json::Value::Null => None,
            t => {
                let table: DirectionTable =
                    serde_json::from_value(t.clone()).map_err(|_| field("direction_table"))?;
                table
                    .check()
                    .map_err(|e| r.content(format!("metadata.direction_table: {e}")))?;
                if table.dims() != dims || !tiled {
                    return Err(r
                        .content(format!(
                            "metadata.direction_table: measured on {:?} voxels{}, the slices are {dims:?}",
                            table.dims(),
                            if tiled { "" } else { " of a tile" }
                        ))
                        .into());
                }
                Some(table)
            }
        };
        Ok(SlicesAsset {
            slices,
            depth_px,
            fitted,
            direction,
        })
    }

    fn measure_size(d: &SlicesDecisions) -> usize {
        if d.measure_px > 0 {
            d.measure_px
        } else {
            d.resolution
        }
    }

    fn measure(
        asset: &SlicesAsset,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        if asset.slices.tiled() {
            return measure_tile(asset, needs, size, source);
        }
        let size = size.max(1);
        let window = Window::for_needs(needs, size);
        let side = window.side();
        let min = DVec3::from_array(BOX_MIN);
        let views = measure_views(needs, 4);
        let mut scores = Vec::new();
        let mut steps = 0.0;
        let mut images: Vec<RgbaImage> = Vec::new();
        let mut drawn = Vec::new();
        for (k, &v) in views.iter().enumerate() {
            let frame = window.frame(v);
            let choice = asset.choose(frame.dir, size as f64)?;
            let reference = window.truth(source, v, Supersample::of(3))?;
            let at = |level: usize| {
                render_object(
                    &asset.slices,
                    (choice.axis, level),
                    &frame,
                    min,
                    (side, side),
                    Supersample::ONE,
                )
            };
            let drawing = at(choice.level)?;
            scores.push(window.score(&drawing.image, &reference)?);
            steps += drawing.steps_per_pixel;
            drawn.push(format!("{}{}", choice.axis.name(), choice.level));
            if k == 0 {
                images.push(reference);
                images.push(drawing.image);
                // The next coarser stored levels of the same axis, for the picture.
                for s in asset.slices.stacks() {
                    if s.axis() == choice.axis && s.level() > choice.level && images.len() < 4 {
                        images.push(at(s.level())?.image);
                    }
                }
            }
        }
        let refs: Vec<_> = images.iter().collect();
        let first = views[0];
        let picture = Picture {
            file: format!("{}-slices.png", source.name),
            caption: format!(
                "{}: ground truth | slices {} and coarser merge levels of the same axis, azimuth {:.0}°, elevation {:.0}°",
                source.name,
                drawn[0],
                first.azimuth.to_degrees(),
                first.elevation.to_degrees()
            ),
            image: RgbaImage::side_by_side(&refs),
        };
        let n = asset.slices.dims()[0];
        let method = format!(
            "slices of {n}³ voxels ({}), the stack the direction rule and the criterion (d = {} px) pick per view ({}), \
             trilinear 2D filtering, 1 sample per pixel, {size}² px at {} needed directions, vs truth 3×3 supersampled{}",
            asset.slices.rule().name(),
            asset.depth_px,
            drawn.join(", "),
            scores.len(),
            elevation_note(needs, window)
        );
        let mut m = fold(method, &scores, Some(steps / views.len().max(1) as f64));
        m.size = size;
        Ok((m, vec![picture]))
    }
}

/// Measures slices cut from a tile against the ray-marched tile (docs/design.md §9): 4 views at
/// the needed azimuths ([`measure_angles`]) and polar angles spread over `[0, grazing_deg]`,
/// one tile `size` pixels across in a window of 1.5 tiles, the stack the direction rule and the
/// criterion pick per view, 1 sample per pixel with trilinear 2D reads (as a display draws);
/// the truth marches the tile's trilinear medium with `⌈2p⌉²` rays per pixel (`p` voxels per
/// pixel).
fn measure_tile(
    asset: &SlicesAsset,
    needs: &Needs,
    size: usize,
    source: &Source,
) -> Result<(Measurement, Vec<Picture>), PipelineError> {
    let volume = source.tile.ok_or_else(|| PipelineError::WrongSource {
        asset: source.name.into(),
        needed: "the volume tile the slices were cut from",
    })?;
    let data = &asset.slices;
    let px = size.max(1) as f64;
    let p = data.dims()[0] as f64 / px;
    let (draw, fine) = tile_render(data.dims()[0], p);
    let (side, k) = (draw.width, fine.supersample.get());
    let (mut scores, mut images, mut drawn) = (Vec::new(), Vec::new(), Vec::new());
    let azimuths = measure_angles(needs, 4);
    for (i, a) in azimuths.iter().enumerate() {
        let polar = needs.grazing_deg * (i as f64 + 0.5) / azimuths.len() as f64;
        let view = StackView::degrees(polar, a.to_degrees());
        let c = asset.choose(view.vector(), px)?;
        let img = render_slices(data, c.axis, c.level, &view, &draw)?;
        let truth = render_truth(volume, &view, &fine, &VolumeTruthParams::default())?;
        if truth.pixels.iter().all(|q| q[3] <= 0.0) {
            return Err(PipelineError::Invisible {
                asset: source.name.into(),
                what: format!("the tile at {polar:.0}° from its normal"),
            });
        }
        scores.push(score(&img, &truth)?);
        drawn.push(format!("{:.0}°: {}{}", polar, c.axis.name(), c.level));
        if i == 0 {
            images.push(truth);
            images.push(img);
        }
    }
    let refs: Vec<_> = images.iter().collect();
    let picture = Picture {
        file: format!("{}-slices.png", source.name),
        caption: format!(
            "{}: ray-marched tile | slices, {}",
            source.name,
            drawn.first().map_or("", String::as_str)
        ),
        image: RgbaImage::side_by_side(&refs),
    };
    let method = format!(
        "slices of a {}³ tile ({}), the stack the {} and the criterion (d = {} px) pick per view ({}), \
         trilinear 2D filtering, 1 sample per pixel, one tile {size} px across in a {side}² window, vs the \
         ray-marched tile with {k}×{k} rays per pixel",
        data.dims()[0],
        data.rule().name(),
        if asset.direction.is_some() {
            "measured direction table"
        } else {
            "direction rule"
        },
        asset.depth_px,
        drawn.join(", ")
    );
    let mut m = fold(method, &scores, None);
    m.size = size;
    Ok((m, vec![picture]))
}

/// The atlas of a stack's slices (level 0 of each), one under another, as RGBA8.
fn atlas_of(slices: &[crate::mip::Pyramid]) -> CodeImage<u8> {
    let first = &slices[0].levels()[0];
    let (w, h) = (first.width, first.height);
    let mut data = Vec::with_capacity(w * h * 4 * slices.len());
    for p in slices {
        data.extend_from_slice(&p.levels()[0].data);
    }
    CodeImage::from_premultiplied(w, h * slices.len(), 4, &data)
}
