//! Slice stacks and their mipmapped merges: level `k` of an axis holds `N/2^k` slices, slice `j`
//! the composite of layers `j·2^k … (j+1)·2^k − 1` by the [`MergeRule`]; every slice is also a
//! 2D mip pyramid ([`crate::mip`]) for distance. See the module conventions for sides and rules.

use std::time::Instant;

use rayon::prelude::*;

use super::filtered::{Direction, StackChoice, fit_target, reconstruct, slab_target};
use super::volume::{over, rescale_thickness};
use super::{Axis, SliceError, TexelVolume};
use crate::mip::{Pyramid, PyramidParams, Texture, WrapMode};

/// How a slab of `2^k` layers becomes one slice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum MergeRule {
    /// Composite as seen from the plus side (higher layers over lower ones).
    FrontOverBack,
    /// Composite as seen from the minus side (lower layers over higher ones).
    BackOverFront,
    /// Both composites stored; the renderer reads the one of the viewer's side (twice the bytes
    /// of the merged levels).
    PerSide,
    /// The mean of the two composites: one stack for both sides, opacity still exact.
    Symmetric,
    /// Baseline, not a merge: keep layer `j·2^k + 2^(k−1)` with its opacity raised to the slab's
    /// thickness.
    Drop,
}

impl MergeRule {
    /// Every rule, merges first.
    pub const ALL: [MergeRule; 5] = [
        MergeRule::FrontOverBack,
        MergeRule::BackOverFront,
        MergeRule::PerSide,
        MergeRule::Symmetric,
        MergeRule::Drop,
    ];

    /// Short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            MergeRule::FrontOverBack => "front-over-back",
            MergeRule::BackOverFront => "back-over-front",
            MergeRule::PerSide => "per-side",
            MergeRule::Symmetric => "symmetric",
            MergeRule::Drop => "drop",
        }
    }
}

/// The side of a stack the viewer is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Side {
    /// `v_i > 0`: higher slice indices are in front.
    Plus,
    /// `v_i ≤ 0`: lower slice indices are in front.
    Minus,
}

/// Parameters of [`build_slices`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SliceParams {
    /// Axes to build stacks for (`[x, y, z]`); a direction no view selects need not be built.
    pub axes: [bool; 3],
    /// Merge levels to build on every built axis (`0` = all `N` slices, `k` = `N/2^k`); `None`
    /// builds every level down to one slice. [`SliceParams::for_views`] fills it with the levels
    /// the scene's views select.
    pub levels: Option<Vec<usize>>,
    /// Merge rule of the levels above 0.
    pub rule: MergeRule,
    /// Count the 2D mip levels of each slice in the bytes (the pyramids are always built).
    pub mip_2d: bool,
    /// The volume tiles (repeats along `x` and `z`, the module conventions): slices wrap in
    /// those directions when filtered. Off for a volume holding one object: every direction
    /// clamps to the edge texel (the renderer draws nothing outside the volume's box).
    pub tiled: bool,
    /// Fit the merged slices (levels ≥ 1, every rule but [`MergeRule::Drop`]) to the bilinear
    /// filter that reads them (docs/design.md §9.5): least squares against the slab composited
    /// from the bilinearly read layers; a stack keeps its composites instead where, straight on
    /// from the viewer's side, they draw it closer to its layers. Cost: about twice the
    /// composites' build per fitted stack. Off: the composites at the texel centres, exact for
    /// nearest reconstruction ([`super::SliceReconstruction::Nearest`]).
    pub fit_bilinear: bool,
}

impl Default for SliceParams {
    /// All three axes, every level, [`MergeRule::PerSide`] (the most accurate rule from both
    /// sides in `altrep slices`; see the README's "Measured" section), 2D mip-maps counted, a
    /// tiling volume, merged slices fitted to bilinear filtering.
    fn default() -> Self {
        Self {
            axes: [true; 3],
            levels: None,
            rule: MergeRule::PerSide,
            mip_2d: true,
            tiled: true,
            fit_bilinear: true,
        }
    }
}

impl SliceParams {
    /// Errors: no axis, an empty level list.
    pub fn validate(&self) -> Result<(), SliceError> {
        if !self.axes.iter().any(|a| *a) {
            return Err(SliceError::InvalidParameter {
                name: "axes",
                value: format!("{:?}", self.axes),
                reason: "at least one axis must be built",
            });
        }
        if self.levels.as_ref().is_some_and(|l| l.is_empty()) {
            return Err(SliceError::ZeroSize { what: "levels" });
        }
        Ok(())
    }

    /// Parameters that build only the axes and levels `views` select (docs/design.md §9: what no
    /// view selects is not built): the direction and level [`super::choose`] picks for each view
    /// with visible depth `depth` (world units) among all three axes, every other field as given in
    /// `base`. Errors: no view, invalid views or depth.
    pub fn for_views(
        volume: &TexelVolume,
        views: &[super::StackView],
        depth: f64,
        base: &SliceParams,
    ) -> Result<SliceParams, SliceError> {
        if views.is_empty() {
            return Err(SliceError::ZeroSize { what: "views" });
        }
        let mut axes = [false; 3];
        let mut levels = Vec::new();
        for view in views {
            view.validate()?;
            let c = super::choose(volume, view.vector(), depth, [true; 3])?;
            axes[c.axis.index()] = true;
            if !levels.contains(&c.level) {
                levels.push(c.level);
            }
        }
        levels.sort_unstable();
        Ok(SliceParams {
            axes,
            levels: Some(levels),
            ..base.clone()
        })
    }
}

/// One stack: the slices of one axis at one merge level.
#[derive(Clone, Debug)]
pub struct Stack {
    axis: Axis,
    level: usize,
    spacing: f64,
    plus: Vec<Pyramid>,
    minus: Option<Vec<Pyramid>>,
}

impl Stack {
    /// Slice direction.
    pub fn axis(&self) -> Axis {
        self.axis
    }

    /// Merge level `k`.
    pub fn level(&self) -> usize {
        self.level
    }

    /// Slice spacing `h_k = 2^k·s` (world units).
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Slices per tile.
    pub fn count(&self) -> usize {
        self.plus.len()
    }

    /// Whether a separate stack is stored for the minus side ([`MergeRule::PerSide`], levels ≥ 1).
    pub fn per_side(&self) -> bool {
        self.minus.is_some()
    }

    /// The slices to draw from `side`, index `j` in the plane `q = (j + ½)·h_k`; each a 2D
    /// pyramid whose level 0 is `w × h` texels of premultiplied RGBA f32 (see [`Axis::plane_axes`]).
    pub fn slices(&self, side: Side) -> &[Pyramid] {
        match (side, &self.minus) {
            (Side::Minus, Some(m)) => m,
            _ => &self.plus,
        }
    }

    fn bytes(&self, mip_2d: bool) -> usize {
        let sides = 1 + usize::from(self.minus.is_some());
        let one: usize = self
            .plus
            .iter()
            .map(|p| {
                if mip_2d {
                    p.bytes(1)
                } else {
                    let t = &p.levels()[0];
                    t.width * t.height * t.channels
                }
            })
            .sum();
        sides * one
    }
}

/// The slice data of a texel volume: stacks per built axis and level.
#[derive(Clone, Debug)]
pub struct SliceData {
    dims: [usize; 3],
    voxel: f64,
    rule: MergeRule,
    tiled: bool,
    stacks: Vec<Stack>,
}

impl SliceData {
    /// Voxels of the source volume along `x, y, z`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxel edge `s` (world units).
    pub fn voxel_size(&self) -> f64 {
        self.voxel
    }

    /// The merge rule of the levels above 0.
    pub fn rule(&self) -> MergeRule {
        self.rule
    }

    /// Whether the volume tiles along `x` and `z` ([`SliceParams::tiled`]).
    pub fn tiled(&self) -> bool {
        self.tiled
    }

    /// Every stack, by axis then level.
    pub fn stacks(&self) -> &[Stack] {
        &self.stacks
    }

    /// The stack of `axis` at `level`. Errors: not built.
    pub fn stack(&self, axis: Axis, level: usize) -> Result<&Stack, SliceError> {
        self.stacks
            .iter()
            .find(|s| s.axis == axis && s.level == level)
            .ok_or(SliceError::MissingStack { axis, level })
    }

    /// The stack of `axis` with exactly `slices` slices. Errors: more slices than voxels,
    /// a count that is not `N/2^k`, a stack not built.
    pub fn stack_with(&self, axis: Axis, slices: usize) -> Result<&Stack, SliceError> {
        let n = self.dims[axis.index()];
        if slices > n {
            return Err(SliceError::TooManySlices {
                axis,
                slices,
                voxels: n,
            });
        }
        if slices == 0 || !slices.is_power_of_two() {
            return Err(SliceError::InvalidParameter {
                name: "slice count",
                value: format!("{slices}"),
                reason: "must be N/2^k for some level k",
            });
        }
        self.stack(axis, (n / slices).trailing_zeros() as usize)
    }
}

/// Costs and the opacity check of [`build_slices`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SliceReport {
    /// Wall time of the build (seconds).
    pub build_seconds: f64,
    /// Bytes of every stack at RGBA8 (2D mip levels included when [`SliceParams::mip_2d`]).
    pub bytes: usize,
    /// Bytes of the level-0 stacks alone at RGBA8 (no 2D mip levels): the unmerged slices.
    pub bytes_level0: usize,
    /// `(axis, level, slices per tile)` of each stack built.
    pub stacks: Vec<(Axis, usize, usize)>,
    /// Largest `|a_slice − (1 − Π(1 − a_layer))|` over every texel of every merged slice before
    /// the fit to bilinear filtering (opacity conservation; 0 up to rounding for every merge
    /// rule, large for `Drop`).
    pub opacity_error_max: f64,
    /// `(axis, level, side)` of each merged stack side that kept its fit to bilinear filtering
    /// ([`SliceParams::fit_bilinear`]); the others hold their composites (a stack built for
    /// both sides by one rule is listed under [`Side::Plus`]).
    pub fitted: Vec<(Axis, usize, Side)>,
}

/// The premultiplied value of the slab of `layers` (lowest index first) under `rule` seen from
/// `side`.
pub(crate) fn merge_column(layers: &[[f64; 4]], rule: MergeRule, side: Side) -> [f64; 4] {
    let plus = || layers.iter().fold([0.0; 4], |acc, l| over(*l, acc));
    let minus = || layers.iter().rev().fold([0.0; 4], |acc, l| over(*l, acc));
    match (rule, side) {
        (MergeRule::FrontOverBack, _) | (MergeRule::PerSide, Side::Plus) => plus(),
        (MergeRule::BackOverFront, _) | (MergeRule::PerSide, Side::Minus) => minus(),
        (MergeRule::Symmetric, _) => {
            let (a, b) = (plus(), minus());
            std::array::from_fn(|k| 0.5 * (a[k] + b[k]))
        }
        (MergeRule::Drop, _) => {
            let g = layers.len();
            rescale_thickness(layers[g / 2], g as f64)
        }
    }
}

/// Builds the slices of `axis` at `level` for `side`, with the worst opacity error.
fn build_stack_side(
    volume: &TexelVolume,
    (axis, level): (Axis, usize),
    rule: MergeRule,
    side: Side,
    (tiled, fit): (bool, bool),
) -> Result<(Vec<Pyramid>, f64, bool), SliceError> {
    let dims = volume.dims();
    let (ua, va) = axis.plane_axes();
    let (w, h) = (dims[ua], dims[va]);
    let g = 1usize << level;
    let count = dims[axis.index()] / g;
    let params = slice_pyramid_params(axis, tiled);
    let fit = if fit && level > 0 && rule != MergeRule::Drop {
        Some((
            Direction::new(w, params.wrap[0])?,
            Direction::new(h, params.wrap[1])?,
        ))
    } else {
        None
    };
    // The composites of every slice, with their worst opacity error, and their fits.
    let built: Vec<(Vec<f32>, Option<Vec<f32>>, f64)> = (0..count)
        .into_par_iter()
        .map(|j| {
            let mut data = Vec::with_capacity(w * h * 4);
            let mut err = 0.0f64;
            let mut layers = vec![[0.0f64; 4]; g];
            for tv in 0..h {
                for tu in 0..w {
                    let mut c = [0usize; 3];
                    c[ua] = tu;
                    c[va] = tv;
                    let mut transmit = 1.0f64;
                    for (l, layer) in layers.iter_mut().enumerate() {
                        c[axis.index()] = j * g + l;
                        let v = volume.get(c[0], c[1], c[2]);
                        *layer = v.map(f64::from);
                        transmit *= 1.0 - layer[3];
                    }
                    let m = merge_column(&layers, rule, side);
                    err = err.max((m[3] - (1.0 - transmit)).abs());
                    data.extend(m.iter().map(|x| *x as f32));
                }
            }
            let fitted = fit.as_ref().map(|d| {
                fit_target(
                    &slab_target(volume, axis, j * g..(j + 1) * g, (rule, side), (&d.0, &d.1)),
                    (&d.0, &d.1),
                )
            });
            (data, fitted, err)
        })
        .collect();
    // Keep the fitted slices, or the composites where they draw the stack closer to its layers
    // straight on from the viewer's side (docs/design.md §9.5).
    let mut worst = 0.0f64;
    let mut parts = Vec::with_capacity(count);
    for (data, fitted, e) in built {
        worst = worst.max(e);
        parts.push((data, fitted));
    }
    let keep_fit = match &fit {
        Some((du, dv)) => {
            let mut choice = StackChoice::new(du.taps_len(), du.taps_len() * dv.taps_len());
            let plus_first = side == Side::Plus && rule != MergeRule::BackOverFront
                || rule == MergeRule::FrontOverBack;
            let order: Vec<usize> = if plus_first {
                (0..count).rev().collect()
            } else {
                (0..count).collect()
            };
            for j in order {
                let (data, fitted) = &parts[j];
                let fitted = fitted
                    .as_ref()
                    .expect("every slice is fitted when the stack is");
                let target = slab_target(volume, axis, j * g..(j + 1) * g, (rule, side), (du, dv));
                let (rf, rc) = (reconstruct(fitted, (du, dv)), reconstruct(data, (du, dv)));
                choice.add(&target, &rf, &rc);
            }
            choice.fit_is_better()
        }
        None => false,
    };
    let texels: Vec<Vec<f32>> = parts
        .into_iter()
        .map(|(data, fitted)| match fitted {
            Some(f) if keep_fit => f,
            _ => data,
        })
        .collect();
    let built: Vec<Result<Pyramid, SliceError>> = texels
        .into_par_iter()
        .map(|t| Ok(Pyramid::build(Texture::new(w, h, 4, t)?, params)?))
        .collect();
    let mut slices = Vec::with_capacity(count);
    for b in built {
        slices.push(b?);
    }
    Ok((slices, worst, keep_fit))
}

/// Cuts `volume` into stacks along the axes asked for, every level merged by `params.rule`.
/// Cost: one pass over the volume per level and axis (a level-`k` texel composites `2^k` layers),
/// plus a 2D pyramid per slice; slices in parallel.
///
/// Errors: invalid parameters, a level beyond one slice, a dimension that is not a power of
/// two.
pub fn build_slices(
    volume: &TexelVolume,
    params: &SliceParams,
) -> Result<(SliceData, SliceReport), SliceError> {
    params.validate()?;
    let start = Instant::now();
    let dims = volume.dims();
    for axis in Axis::ALL {
        let n = dims[axis.index()];
        if !n.is_power_of_two() {
            return Err(SliceError::NotPowerOfTwo { axis, value: n });
        }
    }
    let mut stacks = Vec::new();
    let mut fitted = Vec::new();
    let mut opacity_error_max = 0.0f64;
    for axis in Axis::ALL {
        if !params.axes[axis.index()] {
            continue;
        }
        // A shell's opacity depends on the crossing axis: each stack from its own.
        let along = volume.along(axis);
        let volume = along.as_ref();
        let n = dims[axis.index()];
        let all: Vec<usize> = (0..=n.trailing_zeros() as usize).collect();
        let levels = params.levels.as_ref().unwrap_or(&all);
        if let Some(&k) = levels.iter().find(|k| **k >= all.len()) {
            return Err(SliceError::InvalidParameter {
                name: "level",
                value: format!("{k} on axis {}", axis.name()),
                reason: "beyond the coarsest level log2(N) of one slice",
            });
        }
        for &level in levels {
            let two_sides = level > 0 && params.rule == MergeRule::PerSide;
            let at = (axis, level);
            let how = (params.tiled, params.fit_bilinear);
            let (plus, e1, f1) = build_stack_side(volume, at, params.rule, Side::Plus, how)?;
            if f1 {
                fitted.push((axis, level, Side::Plus));
            }
            let minus = if two_sides {
                let (m, e2, f2) = build_stack_side(volume, at, params.rule, Side::Minus, how)?;
                opacity_error_max = opacity_error_max.max(e2);
                if f2 {
                    fitted.push((axis, level, Side::Minus));
                }
                Some(m)
            } else {
                None
            };
            opacity_error_max = opacity_error_max.max(e1);
            stacks.push(Stack {
                axis,
                level,
                spacing: volume.voxel_size() * (1usize << level) as f64,
                plus,
                minus,
            });
        }
    }
    let bytes = stacks.iter().map(|s| s.bytes(params.mip_2d)).sum();
    let bytes_level0 = stacks
        .iter()
        .filter(|s| s.level == 0)
        .map(|s| s.bytes(false))
        .sum();
    let report = SliceReport {
        build_seconds: start.elapsed().as_secs_f64(),
        bytes,
        bytes_level0,
        stacks: stacks
            .iter()
            .map(|s| (s.axis, s.level, s.count()))
            .collect(),
        opacity_error_max,
        fitted,
    };
    let data = SliceData {
        dims,
        voxel: volume.voxel_size(),
        rule: params.rule,
        tiled: params.tiled,
        stacks,
    };
    Ok((data, report))
}

/// The 2D pyramid parameters of a slice normal to `axis`: its height direction (`y`) clamps,
/// the surface directions repeat when the volume tiles and clamp when it does not.
fn slice_pyramid_params(axis: Axis, tiled: bool) -> PyramidParams {
    let (ua, va) = axis.plane_axes();
    let wrap = |a: usize| {
        if a == 1 || !tiled {
            WrapMode::Clamp
        } else {
            WrapMode::Repeat
        }
    };
    PyramidParams {
        wrap: [wrap(ua), wrap(va)],
        ..PyramidParams::default()
    }
}

/// The stored slices of one stack, as a reader hands them to [`SliceData::from_stored`]: level-0
/// textures (premultiplied linear RGBA f32, `w × h` of the axis's plane, see
/// [`Axis::plane_axes`]), for the plus side and, for a per-side stack, the minus side.
#[derive(Clone, Debug)]
pub struct StoredStack {
    /// Slice direction.
    pub axis: Axis,
    /// Merge level `k` (`N/2^k` slices).
    pub level: usize,
    /// The slices seen from the plus side (or both sides).
    pub plus: Vec<Texture>,
    /// The slices seen from the minus side, when stored apart.
    pub minus: Option<Vec<Texture>>,
}

impl SliceData {
    /// Slice data from stored stacks (an asset file's reader): each slice's 2D pyramid is
    /// rebuilt as [`build_slices`] builds it, so data read back draws exactly as the data
    /// written (from the same level-0 texels). Cost: one 2D pyramid per slice, in parallel.
    ///
    /// Errors: a dimension that is not a power of two, a voxel size that is not positive, a
    /// stack at a level beyond one slice, with a slice count other than `N/2^k`, slices of
    /// another size than the axis's plane or not 4 channels, a minus side on a rule that
    /// stores one, a stack given twice, a non-finite texel (through the pyramid).
    pub fn from_stored(
        dims: [usize; 3],
        voxel: f64,
        rule: MergeRule,
        tiled: bool,
        stored: Vec<StoredStack>,
    ) -> Result<SliceData, SliceError> {
        for axis in Axis::ALL {
            let n = dims[axis.index()];
            if !n.is_power_of_two() {
                return Err(SliceError::NotPowerOfTwo { axis, value: n });
            }
        }
        super::check_range(
            "voxel size",
            voxel,
            f64::MIN_POSITIVE,
            f64::MAX,
            "finite and > 0",
        )?;
        let bad = |value: String, reason: &'static str| SliceError::InvalidParameter {
            name: "stored stack",
            value,
            reason,
        };
        let mut stacks = Vec::with_capacity(stored.len());
        for s in stored {
            let (axis, level) = (s.axis, s.level);
            let at = format!("axis {} level {level}", axis.name());
            let n = dims[axis.index()];
            if level > n.trailing_zeros() as usize {
                return Err(bad(at, "level beyond the coarsest (one slice)"));
            }
            if stacks
                .iter()
                .any(|t: &Stack| t.axis == axis && t.level == level)
            {
                return Err(bad(at, "given twice"));
            }
            let (ua, va) = axis.plane_axes();
            let pyramids = |slices: Vec<Texture>| -> Result<Vec<Pyramid>, SliceError> {
                if slices.len() != n >> level {
                    return Err(bad(
                        format!("{at}: {} slices", slices.len()),
                        "a level-k stack holds N/2^k slices",
                    ));
                }
                if slices
                    .iter()
                    .any(|t| (t.width, t.height, t.channels) != (dims[ua], dims[va], 4))
                {
                    return Err(bad(
                        at.clone(),
                        "every slice is the axis's plane of voxels, RGBA",
                    ));
                }
                let params = slice_pyramid_params(axis, tiled);
                slices
                    .into_par_iter()
                    .map(|t| Ok(Pyramid::build(t, params)?))
                    .collect()
            };
            let plus = pyramids(s.plus)?;
            let minus = match s.minus {
                Some(m) if level > 0 && rule == MergeRule::PerSide => Some(pyramids(m)?),
                Some(_) => {
                    return Err(bad(
                        at,
                        "a minus side is stored by the per-side rule above level 0 only",
                    ));
                }
                None if level > 0 && rule == MergeRule::PerSide => {
                    return Err(bad(
                        at,
                        "the per-side rule stores a minus side above level 0",
                    ));
                }
                None => None,
            };
            stacks.push(Stack {
                axis,
                level,
                spacing: voxel * (1usize << level) as f64,
                plus,
                minus,
            });
        }
        stacks.sort_by_key(|s| (s.axis.index(), s.level));
        Ok(SliceData {
            dims,
            voxel,
            rule,
            tiled,
            stacks,
        })
    }
}
