//! Per-pixel march bounds (docs/design.md §7.5): cylinder, zmin/zmax, the report's `f_θ` pair, the
//! best-`c` family, and the best-`c` family with separate ranges for θ < 0 and θ > 0.
//!
//! ## How the bounds are made conservative (exact sweep, no sampling margin)
//!
//! For a pixel `X` of a row of view `k`, the visible crossing changes piece only when the ray
//! passes a piece's end point `E`: `x_e(E, θ) = |E| cos(θ − ψ_E) = X`, solved in closed form
//! (`θ = ψ_E ± acos(X/|E|)`). Between two consecutive such **events** the set of pieces the ray
//! meets is fixed (the hit test `x_e(a) ≤ X < x_e(b)` only changes when an end crosses `X`) and so
//! is their order along the ray (pieces are disjoint graphs), hence the visible piece is fixed: it
//! is found by one march at the interval's middle. On that piece the crossing moves continuously
//! along a sub-segment `[P(θ_a), P(θ_b)]` of it, and `z_e = ±√(|P|² − X²)` (since `X = P·u`,
//! `z_e = P·n`), so the **exact** range of `z_e` over the interval is given by the two end values
//! and, when the foot of the perpendicular from the axis lies inside the sub-segment, by the value
//! there. Each event angle itself is evaluated exactly too. This makes zmin/zmax exact (up to a
//! 1e-12 R outward margin for rounding).
//!
//! For `c ≠ −1`, `v = z_e + (1 + c)·X·tan(θ/2)` adds a monotone term; each interval is cut at a
//! uniform grid of `subdivisions` angles per half range and bounded by the box
//! `[min z_e, max z_e] + (1 + c)·X·[tan(θ_a/2), tan(θ_b/2)]`, which contains every `v` of the
//! interval (conservative for every `c`, loose by at most `|(1 + c)X|·Δtan` per box). The stored
//! values are then rounded **outward** to their storage format, so the stored bounds contain the
//! exact ones. [`dense_sweep`] checks this with direct warping at angles 10× finer than the grid.
//!
//! ## The best `c`
//!
//! With `a = (1 + c)·X`, `v_max(a) = max (z + a·τ)` over the boxes' upper corners and
//! `v_min(a) = min (z + a·τ)` over their lower corners: the spread `v_max − v_min` is convex and
//! piecewise linear in `a` (docs/design.md §7.5). Only the upper hull of the upper corners and the
//! lower hull of the lower corners matter; the minimum lies at one of their breakpoints, which are
//! all evaluated (exact, `O(h²)` for hulls of `h` vertices). `c = ±1` are always candidates, so the
//! best `c` is never worse than the pair, and the storage grid of `c` contains `±1` exactly.

use std::f64::consts::PI;
use std::time::{Duration, Instant};

use altrep_data_gen::PixelGrid;
use rayon::prelude::*;

use super::images::{ParallaxImages, TexelGeom};
use super::warp::{cylinder_range, hit_piece, piece, warp_row_direct_impl};
use super::{ParallaxError, finite, in_range, invalid};

/// The kinds of march bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum BoundKind {
    /// (a) Entry and exit of the bounding cylinder; nothing stored.
    Cylinder,
    /// (b) `z_min`, `z_max` (the family with `c = −1`); 2 channels.
    ZMinMax,
    /// (c) The report's two functions (`c = −1` and `c = +1`), the shorter (clipped) interval
    /// chosen per pixel at draw time; 4 channels.
    FPair,
    /// (d) The family with the best `c` per pixel; 3 channels (`c`, `v_min`, `v_max`).
    BestC,
    /// (e) The best-`c` family with separate ranges for θ < 0 and θ ≥ 0; 6 channels.
    BestCSplit,
}

impl BoundKind {
    /// All kinds, in the order (a)–(e).
    pub const ALL: [BoundKind; 5] = [
        BoundKind::Cylinder,
        BoundKind::ZMinMax,
        BoundKind::FPair,
        BoundKind::BestC,
        BoundKind::BestCSplit,
    ];

    /// Short name for tables and files.
    pub fn name(self) -> &'static str {
        match self {
            BoundKind::Cylinder => "cylinder",
            BoundKind::ZMinMax => "zmin/zmax",
            BoundKind::FPair => "f_theta pair",
            BoundKind::BestC => "best c",
            BoundKind::BestCSplit => "best c, split θ",
        }
    }

    /// ASCII identifier for file names and keys.
    pub fn slug(self) -> &'static str {
        match self {
            BoundKind::Cylinder => "cylinder",
            BoundKind::ZMinMax => "zminmax",
            BoundKind::FPair => "pair",
            BoundKind::BestC => "best_c",
            BoundKind::BestCSplit => "best_c_split",
        }
    }

    /// Stored channels per pixel of every view.
    pub fn channels(self) -> usize {
        match self {
            BoundKind::Cylinder => 0,
            BoundKind::ZMinMax => 2,
            BoundKind::FPair => 4,
            BoundKind::BestC => 3,
            BoundKind::BestCSplit => 6,
        }
    }
}

/// Parameters of the bound precomputation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundParams {
    /// Uniform angle grid per half range `[0, Δθ]` cutting the event intervals for `c ≠ −1`
    /// (tightness only; conservativeness does not depend on it). Default 64.
    pub subdivisions: usize,
    /// Storage of every channel: 8 or 16 (unorm with a per-view, per-channel scale and offset,
    /// rounded outward) or 32 (`f32`, rounded outward). Default 8, the report's channel size.
    pub bits: u32,
    /// `|c|` is limited to this (default 32).
    pub c_limit: f64,
}

impl Default for BoundParams {
    fn default() -> Self {
        Self {
            subdivisions: 64,
            bits: 8,
            c_limit: 32.0,
        }
    }
}

impl BoundParams {
    fn validate(&self) -> Result<(), ParallaxError> {
        if self.subdivisions == 0 || self.subdivisions > 1 << 16 {
            return Err(invalid(
                "subdivisions",
                self.subdivisions,
                "must be in 1..=65536",
            ));
        }
        if ![8, 16, 32].contains(&self.bits) {
            return Err(invalid("bound bits", self.bits, "must be 8, 16 or 32"));
        }
        if !(self.c_limit >= 1.0 && self.c_limit <= 1e6) {
            return Err(invalid("c_limit", self.c_limit, "must be in [1, 1e6]"));
        }
        Ok(())
    }
}

/// One stored bound of one pixel: `x1 = f_θ(v_max)`, `x2 = f_θ(v_min)` with
/// `f_θ(v) = (1 + c(1 − cos θ))·X − v·sin θ` (decoded values, exactly representable in storage).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelBound {
    /// The family parameter (`−1` for zmin/zmax).
    pub c: f64,
    /// Smallest `v` (world units).
    pub v_min: f64,
    /// Largest `v` (world units).
    pub v_max: f64,
}

impl PixelBound {
    /// `(x1, x2)` for screen abscissa `x` under θ (`co = cos θ`, `si = sin θ`).
    #[inline]
    pub fn range(&self, x: f64, co: f64, si: f64) -> (f64, f64) {
        let base = (1.0 + self.c * (1.0 - co)) * x;
        (base - self.v_max * si, base - self.v_min * si)
    }
}

/// Bounds of every pixel of every view, for one [`BoundKind`].
#[derive(Clone, Debug)]
pub struct Bounds {
    /// Which bound.
    pub kind: BoundKind,
    /// Parameters used.
    pub params: BoundParams,
    /// Wall time of the precomputation.
    pub precompute: Duration,
    /// Per view, per pixel (row-major): two slots (see [`Bounds::pixel`]); `None` = empty (no
    /// crossing for any θ: the fragment is discarded without marching).
    views: Vec<Vec<[Option<PixelBound>; 2]>>,
    /// Per view, the storage grids the values were quantised on (empty for the cylinder).
    storage: Vec<ViewStorage>,
    march_radius: f64,
    width: usize,
}

/// The storage grids of one view's bounds, as a file stores them: `c = c0 + q·step` (or
/// exactly `±1`), and per slot and channel (`[slot][0]` for `v_min`, `[slot][1]` for `v_max`)
/// `v = lo + q·step`. `None` where the values are 32-bit floats or the channel is empty.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewStorage {
    /// `(c0, step)` of the view's `c` grid (bits 8 and 16 only).
    pub c_grid: Option<(f64, f64)>,
    /// `(lo, step)` of each `v` channel.
    pub v_grid: [[Option<(f64, f64)>; 2]; 2],
}

/// Up to two candidate ranges of one fragment.
pub(crate) enum Candidates {
    /// Nothing can be hit.
    Empty,
    /// One range `(x1, x2)`.
    One((f64, f64)),
    /// Two ranges; the shorter after clipping is used.
    Two((f64, f64), (f64, f64)),
}

#[inline]
fn clip(r: (f64, f64), cyl: (f64, f64), forward: bool) -> Option<(f64, f64)> {
    if forward {
        let (a, b) = (r.0.max(cyl.0), r.1.min(cyl.1));
        (a <= b).then_some((a, b))
    } else {
        let (a, b) = (r.0.min(cyl.0), r.1.max(cyl.1));
        (a >= b).then_some((a, b))
    }
}

impl Bounds {
    /// The stored slots of pixel `(i, j)` of view `k`: zmin/zmax and best c use slot 0; the pair
    /// holds `c = −1` in slot 0 and `c = +1` in slot 1; the split kind holds θ < 0 in slot 0 and
    /// θ ≥ 0 in slot 1. Empty for [`BoundKind::Cylinder`]. Errors: an index out of range.
    pub fn pixel(
        &self,
        k: usize,
        i: usize,
        j: usize,
    ) -> Result<[Option<PixelBound>; 2], ParallaxError> {
        if self.kind == BoundKind::Cylinder {
            return Ok([None, None]);
        }
        let view = &self.views[in_range("view index", k, self.views.len())?];
        let height = view.len() / self.width.max(1);
        in_range("column", i, self.width)?;
        in_range("row", j, height)?;
        Ok(view[j * self.width + i])
    }

    pub(crate) fn candidates(&self, k: usize, idx: usize, x: f64, co: f64, si: f64) -> Candidates {
        let r = |b: &Option<PixelBound>| b.map(|b| b.range(x, co, si));
        match self.kind {
            BoundKind::Cylinder => Candidates::One(cylinder_range(x, co, si, self.march_radius)),
            BoundKind::ZMinMax | BoundKind::BestC => match r(&self.views[k][idx][0]) {
                Some(a) => Candidates::One(a),
                None => Candidates::Empty,
            },
            BoundKind::BestCSplit => match r(&self.views[k][idx][usize::from(si >= 0.0)]) {
                Some(a) => Candidates::One(a),
                None => Candidates::Empty,
            },
            BoundKind::FPair => {
                let s = &self.views[k][idx];
                match (r(&s[0]), r(&s[1])) {
                    (Some(a), Some(b)) => Candidates::Two(a, b),
                    (Some(a), None) | (None, Some(a)) => Candidates::One(a),
                    (None, None) => Candidates::Empty,
                }
            }
        }
    }

    /// The march range `(x1, x2)` of pixel `(i, j)` of view `k` at screen abscissa `x` under
    /// `theta`, clipped to the cylinder range (free in a shader); `None` when nothing can be hit.
    /// For the pair, the shorter clipped interval. Bounds hold for rays at pixel centres.
    /// Errors: an index out of range, a non-finite `x` or `theta`.
    pub fn range(
        &self,
        k: usize,
        i: usize,
        j: usize,
        x: f64,
        theta: f64,
    ) -> Result<Option<(f64, f64)>, ParallaxError> {
        finite("screen abscissa", x)?;
        finite("theta", theta)?;
        self.pixel(k, i, j)?;
        let (k, idx) = if self.kind == BoundKind::Cylinder {
            (0, 0)
        } else {
            (k, j * self.width + i)
        };
        Ok(self.range_cs(k, idx, x, theta.cos(), theta.sin()))
    }

    #[inline]
    pub(crate) fn range_cs(
        &self,
        k: usize,
        idx: usize,
        x: f64,
        co: f64,
        si: f64,
    ) -> Option<(f64, f64)> {
        let cyl = cylinder_range(x, co, si, self.march_radius);
        let fw = si >= 0.0;
        match self.candidates(k, idx, x, co, si) {
            Candidates::Empty => None,
            Candidates::One(a) => clip(a, cyl, fw),
            Candidates::Two(a, b) => match (clip(a, cyl, fw), clip(b, cyl, fw)) {
                (Some(a), Some(b)) => Some(if (a.1 - a.0).abs() <= (b.1 - b.0).abs() {
                    a
                } else {
                    b
                }),
                (a, b) => a.or(b),
            },
        }
    }

    /// A copy with every stored range widened by `margin` world units on both sides
    /// (`v_max + margin`, `v_min − margin`); a negative margin narrows, and a range that becomes
    /// inverted becomes empty. For margin experiments and for checking that [`dense_sweep`]
    /// catches bounds that are too tight; the values are no longer on the storage grid.
    pub fn with_margin(&self, margin: f64) -> Bounds {
        let mut out = self.clone();
        for slot in out.views.iter_mut().flatten().flatten() {
            if let Some(b) = slot {
                b.v_max += margin;
                b.v_min -= margin;
                if b.v_min > b.v_max {
                    *slot = None;
                }
            }
        }
        out
    }

    /// The slots of every pixel of view `k` (row-major), as [`Self::pixel`] returns them; empty
    /// for [`BoundKind::Cylinder`] or `k` out of range.
    pub fn view_slots(&self, k: usize) -> &[[Option<PixelBound>; 2]] {
        self.views.get(k).map_or(&[], |v| v.as_slice())
    }

    /// The storage grids of view `k` (`None` for the cylinder or `k` out of range).
    pub fn view_storage(&self, k: usize) -> Option<&ViewStorage> {
        self.storage.get(k)
    }

    /// Bounds of `kind` for `images` from stored slots (as a loader decodes them): one slot
    /// array per view, row-major. Errors: sizes that do not fit `images`, a non-finite value or
    /// `v_min > v_max`.
    pub fn from_slots(
        images: &ParallaxImages,
        kind: BoundKind,
        params: BoundParams,
        views: Vec<Vec<[Option<PixelBound>; 2]>>,
        storage: Vec<ViewStorage>,
    ) -> Result<Bounds, ParallaxError> {
        params.validate()?;
        let b = Bounds {
            kind,
            params,
            precompute: Duration::ZERO,
            views,
            storage,
            march_radius: images.march_radius(),
            width: images.params.width,
        };
        b.check(images)?;
        for slot in b.views.iter().flatten().flatten().flatten() {
            if !(slot.c.is_finite()
                && slot.v_min.is_finite()
                && slot.v_max.is_finite()
                && slot.v_min <= slot.v_max)
            {
                return Err(invalid(
                    "stored bound",
                    format!("{slot:?}"),
                    "must be finite with v_min <= v_max",
                ));
            }
        }
        Ok(b)
    }

    /// Checks that these bounds were built for `images` (same number and size of views).
    pub fn check(&self, images: &ParallaxImages) -> Result<(), ParallaxError> {
        let p = &images.params;
        let fits = self.kind == BoundKind::Cylinder
            || (self.views.len() == p.views
                && self.width == p.width
                && self.views.iter().all(|v| v.len() == p.width * p.height));
        if fits {
            Ok(())
        } else {
            Err(invalid(
                "bounds",
                self.kind.name(),
                "were built for other images",
            ))
        }
    }

    /// Extra bytes the bounds add to the object: `channels · N·Lx·Ly · bits/8`, plus a scale and
    /// offset (two `f32`) per channel and view for unorm storage.
    pub fn bytes(&self, images: &ParallaxImages) -> usize {
        let ch = self.kind.channels();
        let texels = images.params.views * images.params.width * images.params.height;
        let per_view = if self.params.bits < 32 {
            8 * ch * images.params.views
        } else {
            0
        };
        ch * texels * self.params.bits as usize / 8 + per_view
    }
}

/// Upper and lower corner points `(τ, z_e)` of one half range, ascending in `τ = tan(θ/2)`
/// (the sweep's points as lists, for the tests).
#[cfg(test)]
#[derive(Default, Clone, Debug)]
struct HalfPoints {
    upper: Vec<(f64, f64)>,
    lower: Vec<(f64, f64)>,
}

#[cfg(test)]
impl HalfPoints {
    fn clear(&mut self) {
        self.upper.clear();
        self.lower.clear();
    }
}

/// Where [`pixel_points`] puts the corner points of each half range: kept as lists
/// (`[HalfPoints; 2]`, for the tests) or fed straight into hulls ([`SlotHulls`]). Points of a half
/// arrive in ascending τ, and every point of half 0 arrives before any point of half 1.
trait Corners {
    /// An upper corner point of half `half`.
    fn upper(&mut self, half: usize, p: (f64, f64));
    /// A lower corner point of half `half`.
    fn lower(&mut self, half: usize, p: (f64, f64));
}

#[cfg(test)]
impl Corners for [HalfPoints; 2] {
    #[inline]
    fn upper(&mut self, half: usize, p: (f64, f64)) {
        self[half].upper.push(p);
    }
    #[inline]
    fn lower(&mut self, half: usize, p: (f64, f64)) {
        self[half].lower.push(p);
    }
}

/// A hull's vertices `(τ, z)`, ascending in τ.
type Chain = Vec<(f64, f64)>;

/// The hulls of a pixel's slots built as the sweep pushes its corner points: one slot over both
/// halves, or (`split`) one per half. The same hulls as [`hull`] over the concatenated lists
/// (half 0's points, then half 1's), since the builder takes the same steps on the same
/// sequence of points; without storing the points.
struct SlotHulls {
    split: bool,
    /// `[slot] = (upper, lower)`.
    hulls: [(HullBuilder, HullBuilder); 2],
}

impl SlotHulls {
    fn new(split: bool) -> Self {
        let pair = || (HullBuilder::new(true), HullBuilder::new(false));
        Self {
            split,
            hulls: [pair(), pair()],
        }
    }
    fn clear(&mut self) {
        for (u, l) in &mut self.hulls {
            u.points.clear();
            l.points.clear();
        }
    }
    #[inline]
    fn slot(&self, half: usize) -> usize {
        if self.split { half } else { 0 }
    }
    /// Copies of the upper and lower hulls of `slot` (`None` if no point reached it); the
    /// builders keep their buffers for the next pixel.
    fn hulls_of(&self, slot: usize) -> Option<(Chain, Chain)> {
        let (u, l) = &self.hulls[slot];
        if u.points.is_empty() {
            return None;
        }
        Some((u.points.to_vec(), l.points.to_vec()))
    }
}

impl Corners for SlotHulls {
    #[inline]
    fn upper(&mut self, half: usize, p: (f64, f64)) {
        let s = self.slot(half);
        self.hulls[s].0.push(p);
    }
    #[inline]
    fn lower(&mut self, half: usize, p: (f64, f64)) {
        let s = self.slot(half);
        self.hulls[s].1.push(p);
    }
}

/// Outward rounding margin of the exact sweep (relative to `R`).
const EPS: f64 = 1e-12;

#[inline]
fn wrap(a: f64) -> f64 {
    // Within one turn `rem_euclid` returns its argument unchanged: skip its `fmod` (same value).
    let t = a + PI;
    if (0.0..2.0 * PI).contains(&t) {
        let w = t - PI;
        return if w <= -PI { w + 2.0 * PI } else { w };
    }
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI { w + 2.0 * PI } else { w }
}

/// A piece's end points `((x_a, z_a), (x_b, z_b))`.
type Segment = ((f64, f64), (f64, f64));

/// A row's pieces and end points, prepared once for the event sweeps of all its pixels.
struct RowSweep {
    /// Piece `2i + right` of texel `i`: its end points, `None` if the texel is undefined.
    pieces: Vec<Option<Segment>>,
    /// Ids of the existing pieces.
    existing: Vec<u32>,
    /// End points: `(|E|, ψ_E)` and the one or two pieces they bound (`u32::MAX` = none).
    ends: Vec<(f64, f64, [u32; 2])>,
    /// Per end point, an interval of screen abscissae `X` outside which none of its events
    /// falls in the sweep's window (see [`x_window`]).
    x_windows: Vec<(f64, f64)>,
}

/// Angle margin of [`x_window`] (radians) beyond the sweep's window `±(Δθ + WINDOW)`: far
/// above the error of a computed event angle (below 2e-8 rad even where `acos` is
/// ill-conditioned, `X ≈ ±|E|`), far below the window.
const PREFILTER_MARGIN: f64 = 1e-6;

/// An interval of `X` containing `x_e(E, θ) = |E| cos(θ − ψ_E)` for every `θ` within
/// `Δθ + WINDOW + PREFILTER_MARGIN` of 0 (end values, and `±|E|` where `ψ_E` or `ψ_E + π` lies
/// inside), padded by `1e-9·|E|` for rounding. A pixel whose `X` is outside it has no event of
/// `E` that [`pixel_points`] would keep (its computed events lie within `2e-8` rad of true
/// solutions, and those lie outside the widened window), so the sweep skips `E` without solving
/// for its events: the same events, fewer `acos`.
fn x_window((ex, ez): (f64, f64), rho: f64, psi: f64, delta: f64) -> (f64, f64) {
    let a = delta + WINDOW + PREFILTER_MARGIN;
    let (ca, sa) = (a.cos(), a.sin());
    let (f0, f1) = (ex * ca - ez * sa, ex * ca + ez * sa);
    let (mut lo, mut hi) = (f0.min(f1), f0.max(f1));
    if psi.abs() <= a + PREFILTER_MARGIN {
        hi = rho;
    }
    if wrap(psi + PI).abs() <= a + PREFILTER_MARGIN {
        lo = -rho;
    }
    let pad = 1e-9 * rho;
    (lo - pad, hi + pad)
}

const NONE: u32 = u32::MAX;

impl RowSweep {
    /// The row `row` of a view on `grid`, for sweeps over `[−delta, delta]`.
    fn new(grid: &PixelGrid, row: &[TexelGeom], delta: f64) -> Self {
        let mut pieces = vec![None; 2 * row.len()];
        let mut existing = Vec::new();
        let mut ends = Vec::new();
        let mut x_windows = Vec::new();
        let mut polar = |e: (f64, f64)| {
            let (rho, psi) = (e.0.hypot(e.1), e.1.atan2(e.0));
            x_windows.push(x_window(e, rho, psi, delta));
            (rho, psi)
        };
        for (i, g) in row.iter().enumerate() {
            if !g.defined {
                continue;
            }
            let (l, r) = (2 * i as u32, 2 * i as u32 + 1);
            let left = piece(grid, g, i, false);
            let right = piece(grid, g, i, true);
            pieces[l as usize] = Some(left);
            pieces[r as usize] = Some(right);
            existing.extend([l, r]);
            // A joined left end is the left neighbour's right end, listed there.
            if !g.link_l {
                let (rho, psi) = polar(left.0);
                ends.push((rho, psi, [l, NONE]));
            }
            let (rho, psi) = polar(left.1);
            ends.push((rho, psi, [l, r]));
            let (rho, psi) = polar(right.1);
            ends.push((rho, psi, [r, if g.link_r { r + 1 } else { NONE }]));
        }
        Self {
            pieces,
            existing,
            ends,
            x_windows,
        }
    }

    /// The ray `x` under `(co, si)` against piece `id`: `(t, z_e)` if it is hit.
    #[inline]
    fn eval(&self, id: u32, x: f64, co: f64, si: f64) -> Option<(f64, f64)> {
        let (a, b) = self.pieces[id as usize]?;
        hit_piece(a, b, x, co, si).map(|(t, _, z_e)| (t, z_e))
    }
}

/// Reusable buffers of [`pixel_points`].
#[derive(Default)]
struct Scratch {
    /// `(θ, end point index or NONE)`, sorted.
    events: Vec<(f64, u32)>,
    /// `(cos θ, sin θ)` of each event, computed once.
    trig: Vec<(f64, f64)>,
    /// Whether each piece is met by the ray in the current interval.
    met: Vec<bool>,
    /// The pieces met in the current interval.
    active: Vec<u32>,
}

/// The uniform angle grid `θ_m = m·step` (`step = Δθ / subdivisions`) that cuts the event
/// intervals, with `cos θ_m`, `sin θ_m` and `τ(θ_m) = sin θ_m / (1 + cos θ_m)` computed once per
/// build instead of once per box (the values are the same: the same functions of the same `θ_m`).
struct AngleGrid {
    step: f64,
    /// Index of `m = 0` in `trig`.
    zero: i64,
    /// `(cos θ_m, sin θ_m, τ(θ_m))` for `m = −zero ..= zero`.
    trig: Vec<(f64, f64, f64)>,
}

impl AngleGrid {
    fn new(delta: f64, subdivisions: usize) -> Self {
        let step = delta / subdivisions as f64;
        // One spare point on each side: `⌊θ/step⌋ + 1` may step past ±subdivisions by rounding.
        let zero = subdivisions as i64 + 2;
        let trig = (-zero..=zero)
            .map(|m| {
                let th = m as f64 * step;
                let (co, si) = (th.cos(), th.sin());
                (co, si, si / (1.0 + co))
            })
            .collect();
        Self { step, zero, trig }
    }

    /// `(cos, sin, τ)` of `θ_m`.
    #[inline]
    fn at(&self, m: i64) -> (f64, f64, f64) {
        match usize::try_from(m + self.zero)
            .ok()
            .and_then(|k| self.trig.get(k))
        {
            Some(&t) => t,
            None => {
                let th = m as f64 * self.step;
                let (co, si) = (th.cos(), th.sin());
                (co, si, si / (1.0 + co))
            }
        }
    }
}

/// Half-width of the window of event angles whose pieces are re-tested (radians); far above the
/// rounding error of a computed event (~1e-15), far below any meaningful angle.
const WINDOW: f64 = 1e-9;

/// The exact sweep of one pixel (module docs): fills the corner points of both half ranges,
/// sorted by τ.
///
/// The pieces the ray meets change only at events; the sweep keeps that set, re-testing at each
/// interval's middle only the pieces bounded by the end points of the events at its ends (within
/// [`WINDOW`] of them, which absorbs rounding in the computed event angles: a piece whose true
/// crossing lies near a computed event is re-tested at every interval within the window). The
/// visible piece is the met piece nearest to the camera (largest `z_e`), as the march finds it.
fn pixel_points(
    grid: &PixelGrid,
    rs: &RowSweep,
    x: f64,
    delta: f64,
    angles: &AngleGrid,
    sc: &mut Scratch,
    halves: &mut impl Corners,
) {
    let events = &mut sc.events;
    events.clear();
    events.extend([(-delta, NONE), (0.0, NONE), (delta, NONE)]);
    for (e, (&(rho, psi, _), &(x_lo, x_hi))) in rs.ends.iter().zip(&rs.x_windows).enumerate() {
        if rho < x.abs() || x < x_lo || x > x_hi {
            continue;
        }
        let phi = (x / rho).clamp(-1.0, 1.0).acos();
        for th in [wrap(psi - phi), wrap(psi + phi)] {
            // An event computed within the window outside the range is one at its end (a
            // crossing through an end point at θ = ±Δθ): it is kept there, so that the pieces it
            // bounds are considered at the end's exact evaluation.
            if th > -delta - WINDOW && th < delta + WINDOW {
                events.push((th.clamp(-delta, delta), e as u32));
            }
        }
    }
    events.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let trig = &mut sc.trig;
    trig.clear();
    trig.extend(events.iter().map(|e| (e.0.cos(), e.0.sin())));
    sc.met.clear();
    sc.met.resize(rs.pieces.len(), false);
    sc.active.clear();
    let r = grid.cylinder.radius;
    let pieces_of = |k: usize| {
        let e = events[k].1;
        if e == NONE {
            [NONE, NONE]
        } else {
            rs.ends[e as usize].2
        }
    };
    let n = events.len();
    let (mut idx, mut lo) = (0usize, 0usize);
    while idx < n {
        let th = events[idx].0;
        let mut gend = idx;
        while gend < n && events[gend].0 == th {
            gend += 1;
        }
        while events[lo].0 < th - WINDOW {
            lo += 1;
        }
        // Exact value at this event angle: the nearest met piece among those met just before
        // and those bounded by the events here.
        {
            let (co, si) = trig[idx];
            let mut best: Option<f64> = None;
            let mut consider = |id: u32| {
                if id != NONE
                    && let Some((_, z)) = rs.eval(id, x, co, si)
                {
                    best = Some(best.map_or(z, |b: f64| b.max(z)));
                }
            };
            if idx == 0 {
                rs.existing.iter().for_each(|&id| consider(id));
            } else {
                sc.active.iter().for_each(|&id| consider(id));
                let mut k = lo;
                while k < n && events[k].0 <= th + WINDOW {
                    pieces_of(k).iter().for_each(|&id| consider(id));
                    k += 1;
                }
            }
            if let Some(z) = best {
                push_exact(halves, th, (si / (1.0 + co), z));
            }
        }
        if gend == n {
            break;
        }
        let (ea, eb) = (th, events[gend].0);
        let (trig_a, trig_b) = (trig[idx], trig[gend]);
        idx = gend;
        // Update the met set at the interval's middle.
        let mid = 0.5 * (ea + eb);
        let (co, si) = (mid.cos(), mid.sin());
        let retest = |id: u32, met: &mut Vec<bool>, active: &mut Vec<u32>| {
            if id == NONE {
                return;
            }
            let now = rs.eval(id, x, co, si).is_some();
            if met[id as usize] != now {
                met[id as usize] = now;
                if now {
                    active.push(id);
                } else if let Some(p) = active.iter().position(|&a| a == id) {
                    active.swap_remove(p);
                }
            }
        };
        if ea == -delta {
            for &id in &rs.existing {
                retest(id, &mut sc.met, &mut sc.active);
            }
        } else {
            let mut k = lo;
            while k < n && events[k].0 <= eb + WINDOW {
                for id in pieces_of(k) {
                    retest(id, &mut sc.met, &mut sc.active);
                }
                k += 1;
            }
        }
        // The visible piece: nearest met piece.
        let mut vis: Option<(u32, f64)> = None;
        for &id in &sc.active {
            if let Some((_, z)) = rs.eval(id, x, co, si)
                && vis.is_none_or(|(_, bz)| z > bz)
            {
                vis = Some((id, z));
            }
        }
        let Some((id, _)) = vis else { continue };
        let Some((a, b)) = rs.pieces[id as usize] else {
            continue;
        };
        let half = usize::from(mid >= 0.0);
        push_piece_boxes(halves, half, a, b, x, r, (ea, eb), (trig_a, trig_b), angles);
    }
}

/// Pushes an exact crossing `p = (τ, z_e)` seen at angle `th` as both an upper and a lower
/// point of the half range it belongs to (`θ < 0`: half 0, `θ > 0`: half 1, `θ = 0`: both).
fn push_exact(halves: &mut impl Corners, th: f64, p: (f64, f64)) {
    let which: &[usize] = if th == 0.0 {
        &[0, 1]
    } else if th > 0.0 {
        &[1]
    } else {
        &[0]
    };
    for &half in which {
        halves.upper(half, p);
        halves.lower(half, p);
    }
}

/// Conservative corner points `(τ, z_e)` of the crossing of the screen ray at abscissa `x` with
/// the surface piece `a → b` (view frame, `(x_t, z_t)` pairs), for view angles in the open
/// interval `(ea, eb)` where that piece is the visible one. The interval is cut at the points of
/// the uniform grid of `step` inside it; over each sub-interval the crossing's depth is bounded by
/// its values at both ends and, where the foot of the perpendicular from the axis falls inside
/// the sub-interval's range of piece parameters, by the depth of that foot (the extremum of
/// `|z_e|` along the piece). Each box is widened by `EPS·r`; its corners are its upper and lower
/// values at `τ(s_a)` and `τ(s_b)`. Where two boxes meet (a grid angle), only the outer of
/// their two corners at that τ is pushed, upper and lower: a hull keeps only the extreme of
/// points with equal τ, and pushing the extreme alone leaves [`HullBuilder`] bitwise as pushing
/// both (see [`HullBuilder::push`]), with half the pushes.
#[allow(clippy::too_many_arguments)]
fn push_piece_boxes(
    hp: &mut impl Corners,
    half: usize,
    a: (f64, f64),
    b: (f64, f64),
    x: f64,
    r: f64,
    (ea, eb): (f64, f64),
    (trig_a, trig_b): ((f64, f64), (f64, f64)),
    angles: &AngleGrid,
) {
    let (dx, dz) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dz * dz;
    let t_foot = if len2 > 0.0 {
        -(a.0 * dx + a.1 * dz) / len2
    } else {
        0.0
    };
    // Crossing on the piece's line at the angle with cosine `co` and sine `si`:
    // (t, t, z_e, z_e); a piece seen edge-on (only possible at an interval end) gives both its
    // ends.
    let on_line = |(co, si): (f64, f64)| -> (f64, f64, f64, f64) {
        let xe_a = a.0 * co + a.1 * si;
        let xe_b = b.0 * co + b.1 * si;
        let ze = |t: f64| {
            let (px, pz) = (a.0 + t * dx, a.1 + t * dz);
            pz * co - px * si
        };
        if xe_b - xe_a > 1e-14 * r {
            let t = ((x - xe_a) / (xe_b - xe_a)).clamp(0.0, 1.0);
            let z = ze(t);
            (t, t, z, z)
        } else {
            let (z0, z1) = (ze(0.0), ze(1.0));
            (0.0, 1.0, z0.min(z1), z0.max(z1))
        }
    };
    let tau_of = |(co, si): (f64, f64)| si / (1.0 + co);
    // Boxes over the sub-intervals cut by the uniform grid strictly inside (ea, eb).
    let step = angles.step;
    let mut m = (ea / step).floor() as i64 + 1;
    let mut end_a = on_line(trig_a);
    let mut ta = tau_of(trig_a);
    // The previous box's (lower, upper) values: its corners at `ta`, not pushed yet.
    let mut pending: Option<(f64, f64)> = None;
    loop {
        let gm = m as f64 * step;
        let (last, end_b, tb) = if gm < eb {
            let (co, si, t) = angles.at(m);
            (false, on_line((co, si)), t)
        } else {
            (true, on_line(trig_b), tau_of(trig_b))
        };
        let (t_lo, t_hi) = (end_a.0.min(end_b.0), end_a.1.max(end_b.1));
        let mut zlo = end_a.2.min(end_b.2);
        let mut zhi = end_a.3.max(end_b.3);
        if t_foot > t_lo && t_foot < t_hi {
            let (px, pz) = (a.0 + t_foot * dx, a.1 + t_foot * dz);
            let zf = (px * px + pz * pz - x * x).max(0.0).sqrt();
            if zlo >= 0.0 {
                zlo = zlo.min(zf);
            } else if zhi <= 0.0 {
                zhi = zhi.max(-zf);
            }
        }
        let (zlo, zhi) = (zlo - EPS * r, zhi + EPS * r);
        // At `ta`, the outer of this box's corner and the previous box's (the previous one on
        // a tie, as the hull keeps the first of equal points).
        let (lo_a, hi_a) = match pending {
            Some((plo, phi)) => (
                if zlo < plo { zlo } else { plo },
                if zhi > phi { zhi } else { phi },
            ),
            None => (zlo, zhi),
        };
        hp.upper(half, (ta, hi_a));
        hp.lower(half, (ta, lo_a));
        if last {
            hp.upper(half, (tb, zhi));
            hp.lower(half, (tb, zlo));
            break;
        }
        pending = Some((zlo, zhi));
        end_a = end_b;
        ta = tb;
        m += 1;
    }
}

/// Upper (`upper = true`) or lower convex hull of points sorted by τ (monotone chain; of points
/// with equal τ only the extreme one is kept).
#[cfg(test)]
fn hull(points: impl IntoIterator<Item = (f64, f64)>, upper: bool) -> Vec<(f64, f64)> {
    let mut h = HullBuilder::new(upper);
    for p in points {
        h.push(p);
    }
    h.points
}

/// The upper or lower convex hull of points pushed in ascending τ, kept as they arrive
/// ([`hull`] over the same points gives the same vertices).
struct HullBuilder {
    upper: bool,
    points: Vec<(f64, f64)>,
}

impl HullBuilder {
    fn new(upper: bool) -> Self {
        Self {
            upper,
            points: Vec::with_capacity(16),
        }
    }

    /// Adds `p` (τ not below the last point's): monotone chain, of points with equal τ only
    /// the extreme one (the first among equals) is kept.
    ///
    /// Pushing several points of equal τ in a row leaves the same vertices, bitwise, as
    /// pushing only their extreme (the first among equals): a point that the chord test pops
    /// for a lesser point it also pops for the extreme, because the rounded cross product is
    /// monotone in `p`'s z (`a.τ − o.τ ≥ 0`), and from there both run the same loop.
    #[inline]
    fn push(&mut self, p: (f64, f64)) {
        let upper = self.upper;
        let h = &mut self.points;
        debug_assert!(h.last().is_none_or(|l| l.0 <= p.0), "points out of τ order");
        if let Some(&last) = h.last()
            && last.0 == p.0
        {
            let better = if upper { p.1 > last.1 } else { p.1 < last.1 };
            if !better {
                return;
            }
            h.pop();
        }
        while h.len() >= 2 {
            let (o, a) = (h[h.len() - 2], h[h.len() - 1]);
            let cross = (a.0 - o.0) * (p.1 - o.1) - (a.1 - o.1) * (p.0 - o.0);
            // Keep `a` only if it is strictly outside the chord o–p.
            if (upper && cross < 0.0) || (!upper && cross > 0.0) {
                break;
            }
            h.pop();
        }
        h.push(p);
    }
}

/// `(v_min, v_max)` for `a = (1 + c)·X` over (hulls of) corner points.
#[inline]
fn v_range(upper: &[(f64, f64)], lower: &[(f64, f64)], a: f64) -> (f64, f64) {
    let hi = upper
        .iter()
        .fold(f64::NEG_INFINITY, |m, p| m.max(p.1 + a * p.0));
    let lo = lower
        .iter()
        .fold(f64::INFINITY, |m, p| m.min(p.1 + a * p.0));
    (lo, hi)
}

/// Hulls of one slot of one pixel, with its continuous best `c`.
struct SlotHull {
    upper: Vec<(f64, f64)>,
    lower: Vec<(f64, f64)>,
    c_star: f64,
}

/// `v_max − v_min` of [`v_range`] for the family `c`, for comparing candidates. The extremes are
/// taken with plain comparisons (`maxsd`/`minsd`) instead of `f64::max`/`min` (NaN checks): the
/// same values except possibly the sign of a zero extreme, which no comparison of spreads sees
/// (the stored ranges still come from [`v_range`]).
fn spread(h: &SlotHull, x: f64, c: f64) -> f64 {
    let a = (1.0 + c) * x;
    let hi = h.upper.iter().fold(f64::NEG_INFINITY, |m, p| {
        let v = p.1 + a * p.0;
        if v > m { v } else { m }
    });
    let lo = h.lower.iter().fold(f64::INFINITY, |m, p| {
        let v = p.1 + a * p.0;
        if v < m { v } else { m }
    });
    hi - lo
}

fn best_c(h: &mut SlotHull, x: f64, c_limit: f64) {
    if x == 0.0 {
        h.c_star = -1.0;
        return;
    }
    let mut cands = vec![-1.0, 1.0, -c_limit, c_limit];
    for pts in [&h.upper, &h.lower] {
        for w in pts.windows(2) {
            let a = -(w[1].1 - w[0].1) / (w[1].0 - w[0].0);
            if a.is_finite() {
                cands.push((a / x - 1.0).clamp(-c_limit, c_limit));
            }
        }
    }
    let mut best = (f64::INFINITY, -1.0);
    for c in cands {
        let s = spread(h, x, c);
        if s < best.0 {
            best = (s, c);
        }
    }
    h.c_star = best.1;
}

/// The largest `q` of a stored `c` (the asset format's 16-bit code is `q + 3`).
const MAX_C_LEVEL: i64 = 65532;

/// The storage grid of `c` for one view: `c = c0 + q·step`, `q ∈ [0, L]`, with `±1` on the grid.
#[derive(Clone, Copy, Debug)]
struct CGrid {
    c0: f64,
    step: f64,
    levels: i64,
}

impl CGrid {
    fn new(c_min: f64, c_max: f64, bits: u32) -> Self {
        // A file stores `q + 3` in 16 bits (codes 0, 1, 2: no bound, −1, +1), so `q` stops at
        // 65532; below 16 bits every level fits.
        let levels = ((1i64 << bits) - 1).min(MAX_C_LEVEL);
        let span = (c_max - c_min).max(2.0);
        let m = ((2.0 * (levels - 1) as f64 / span).floor()).max(1.0);
        let step = 2.0 / m;
        let q0 = ((-1.0 - c_min) / step).ceil().max(0.0);
        Self {
            c0: -1.0 - q0 * step,
            step,
            levels,
        }
    }
    fn candidates(&self, c: f64) -> [f64; 4] {
        let q = ((c - self.c0) / self.step)
            .floor()
            .clamp(0.0, self.levels as f64);
        let q1 = (q + 1.0).min(self.levels as f64);
        [self.c0 + q * self.step, self.c0 + q1 * self.step, -1.0, 1.0]
    }
}

/// The next `f32` above (`up`) or below a finite `f`.
fn f32_step(f: f32, up: bool) -> f32 {
    if f == 0.0 {
        let tiny = f32::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let b = f.to_bits();
    f32::from_bits(if (f > 0.0) == up { b + 1 } else { b - 1 })
}

/// Quantises `values` (one channel of one view) outward: up (`v_max`) or down (`v_min`).
fn quantize_channel(values: &mut [&mut f64], up: bool, bits: u32) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    if bits == 32 {
        for v in values.iter_mut() {
            let mut f = **v as f32;
            if up && f64::from(f) < **v {
                f = f32_step(f, true);
            } else if !up && f64::from(f) > **v {
                f = f32_step(f, false);
            }
            **v = f64::from(f);
        }
        return None;
    }
    let lo = values.iter().map(|v| **v).fold(f64::INFINITY, f64::min);
    let hi = values.iter().map(|v| **v).fold(f64::NEG_INFINITY, f64::max);
    let levels = ((1u64 << bits) - 1) as f64;
    let span = (hi - lo).max(1e-9) * (1.0 + 1e-9);
    let step = span / levels;
    for v in values.iter_mut() {
        let u = (**v - lo) / step;
        let mut q = if up { u.ceil() } else { u.floor() }.clamp(0.0, levels);
        if up {
            while lo + q * step < **v && q < levels {
                q += 1.0;
            }
        } else {
            while lo + q * step > **v && q > 0.0 {
                q -= 1.0;
            }
        }
        **v = lo + q * step;
    }
    Some((lo, step))
}

/// Precomputes bounds of `kind` for every pixel of every view (rows in parallel). Cost per pixel:
/// `O(Lx)` event solutions, one march per event interval, `O(subdivisions)` boxes, and the hull
/// search for the best `c` (see the module docs). Errors: invalid parameters.
pub fn build_bounds(
    images: &ParallaxImages,
    kind: BoundKind,
    params: &BoundParams,
) -> Result<Bounds, ParallaxError> {
    params.validate()?;
    let t0 = Instant::now();
    let p = &images.params;
    let (w, h) = (p.width, p.height);
    let grid = images.pixel_grid();
    let r_march = images.march_radius();
    let delta = p.delta_theta();
    // zmin/zmax needs no subdivision: its boxes are exact.
    let subdivisions = if kind == BoundKind::ZMinMax {
        1
    } else {
        params.subdivisions
    };
    let angles = AngleGrid::new(delta, subdivisions);
    let mut views = Vec::new();
    let mut storage = Vec::new();
    if kind != BoundKind::Cylinder {
        // Views in parallel as well as rows: a view's serial passes 2 and 3 overlap other
        // views' sweeps (each view's result is the same either way).
        (views, storage) = images
            .views
            .par_iter()
            .map(|view| {
                // Pass 1: per pixel, slot hulls (or direct ranges).
                let rows: Vec<Vec<[Option<SlotHull>; 2]>> = (0..h)
                    .into_par_iter()
                    .map(|j| {
                        let rs = RowSweep::new(&grid, &view.geom[j * w..(j + 1) * w], delta);
                        let mut scratch = Scratch::default();
                        let mut hulls = SlotHulls::new(kind == BoundKind::BestCSplit);
                        (0..w)
                            .map(|i| {
                                let x = grid.x_at(i as f64 + 0.5);
                                hulls.clear();
                                pixel_points(
                                    &grid,
                                    &rs,
                                    x,
                                    delta,
                                    &angles,
                                    &mut scratch,
                                    &mut hulls,
                                );
                                let slot = |s: usize| -> Option<SlotHull> {
                                    let (upper, lower) = hulls.hulls_of(s)?;
                                    let mut sh = SlotHull {
                                        upper,
                                        lower,
                                        c_star: -1.0,
                                    };
                                    if matches!(kind, BoundKind::BestC | BoundKind::BestCSplit) {
                                        best_c(&mut sh, x, params.c_limit);
                                    }
                                    Some(sh)
                                };
                                match kind {
                                    BoundKind::BestCSplit => [slot(0), slot(1)],
                                    _ => [slot(0), None],
                                }
                            })
                            .collect()
                    })
                    .collect();
                // Pass 2: c per slot on the view's storage grid, then exact v ranges.
                let mut c_min = -1.0f64;
                let mut c_max = 1.0f64;
                for s in rows.iter().flatten().flatten().flatten() {
                    c_min = c_min.min(s.c_star);
                    c_max = c_max.max(s.c_star);
                }
                let cgrid = CGrid::new(c_min, c_max, params.bits.min(16));
                let mut px: Vec<[Option<PixelBound>; 2]> = Vec::with_capacity(w * h);
                for row in &rows {
                    for (i, slots) in row.iter().enumerate() {
                        let x = grid.x_at(i as f64 + 0.5);
                        let mk = |s: &SlotHull, c: f64| {
                            let (v_min, v_max) = v_range(&s.upper, &s.lower, (1.0 + c) * x);
                            PixelBound { c, v_min, v_max }
                        };
                        let choose = |s: &SlotHull| -> PixelBound {
                            let cands: Vec<f64> = if params.bits == 32 {
                                vec![f64::from(s.c_star as f32), -1.0, 1.0]
                            } else {
                                cgrid.candidates(s.c_star).to_vec()
                            };
                            let mut best = (f64::INFINITY, -1.0);
                            for c in cands {
                                let sp = spread(s, x, c);
                                if sp < best.0 {
                                    best = (sp, c);
                                }
                            }
                            mk(s, best.1)
                        };
                        px.push(match kind {
                            BoundKind::ZMinMax => [slots[0].as_ref().map(|s| mk(s, -1.0)), None],
                            BoundKind::FPair => [
                                slots[0].as_ref().map(|s| mk(s, -1.0)),
                                slots[0].as_ref().map(|s| mk(s, 1.0)),
                            ],
                            BoundKind::BestC => [slots[0].as_ref().map(choose), None],
                            _ => [slots[0].as_ref().map(choose), slots[1].as_ref().map(choose)],
                        });
                    }
                }
                // Pass 3: outward quantisation of every v channel.
                let mut store = ViewStorage {
                    c_grid: (params.bits < 32).then_some((cgrid.c0, cgrid.step)),
                    ..ViewStorage::default()
                };
                for slot in 0..2 {
                    for up in [false, true] {
                        let mut vals: Vec<&mut f64> = px
                            .iter_mut()
                            .filter_map(|s| s[slot].as_mut())
                            .map(|b| if up { &mut b.v_max } else { &mut b.v_min })
                            .collect();
                        store.v_grid[slot][usize::from(up)] =
                            quantize_channel(&mut vals, up, params.bits);
                    }
                }
                (px, store)
            })
            .unzip();
    }
    Ok(Bounds {
        kind,
        params: *params,
        precompute: t0.elapsed(),
        views,
        storage,
        march_radius: r_march,
        width: w,
    })
}

/// Checks bounds against direct warping at a dense grid of angles: for every view, row, pixel
/// centre and each of `2·(subdivisions·factor) + 1` angles evenly spaced over `[−Δθ, Δθ]`
/// (`subdivisions` the largest among `bounds`), the crossing found by direct warping must lie in
/// every stored candidate range `[x1, x2]` (unclipped; tolerance 1e-9 R). Returns the number of
/// violations per bound (0 expected). Cost: `O(angles · N · Ly · Lx)`, angles in parallel.
pub fn dense_sweep(
    images: &ParallaxImages,
    bounds: &[&Bounds],
    factor: usize,
) -> Result<Vec<u64>, ParallaxError> {
    for b in bounds {
        b.check(images)?;
    }
    let p = &images.params;
    let sub = bounds
        .iter()
        .map(|b| b.params.subdivisions)
        .max()
        .unwrap_or(1);
    let m = (sub * factor.max(1)) as i64;
    let delta = p.delta_theta();
    let grid = images.pixel_grid();
    let xs: Vec<f64> = (0..p.width).map(|i| grid.x_at(i as f64 + 0.5)).collect();
    let tol = 1e-9 * p.cylinder.radius;
    let tasks: Vec<(usize, i64)> = (0..p.views)
        .flat_map(|k| (-m..=m).map(move |s| (k, s)))
        .collect();
    let counts = tasks
        .par_iter()
        .map(|&(k, s)| {
            let theta = delta * s as f64 / m as f64;
            let (co, si) = (theta.cos(), theta.sin());
            let view = &images.views[k];
            let mut out = vec![None; p.width];
            let mut bad = vec![0u64; bounds.len()];
            for j in 0..p.height {
                let row = &view.geom[j * p.width..(j + 1) * p.width];
                warp_row_direct_impl(&grid, row, co, si, &xs, &mut out);
                for (i, c) in out.iter().enumerate() {
                    let Some(c) = c else { continue };
                    let inside =
                        |r: (f64, f64)| c.x_t >= r.0.min(r.1) - tol && c.x_t <= r.0.max(r.1) + tol;
                    for (b, count) in bounds.iter().zip(bad.iter_mut()) {
                        let ok = match b.candidates(k, j * p.width + i, xs[i], co, si) {
                            Candidates::Empty => false,
                            Candidates::One(r) => inside(r),
                            Candidates::Two(r, q) => inside(r) && inside(q),
                        };
                        *count += u64::from(!ok);
                    }
                }
            }
            bad
        })
        .reduce(
            || vec![0u64; bounds.len()],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    Ok(counts)
}

/// The first version of the sweep, which finds the visible piece of every interval by a full
/// march: slower, kept to cross-check [`pixel_points`].
#[cfg(test)]
mod reference {
    use super::*;
    use crate::parallax::warp::march_row;

    /// Per row: polar coordinates `(|E|, ψ_E)` of every piece end point.
    pub(super) fn row_endpoints(grid: &PixelGrid, row: &[TexelGeom], out: &mut Vec<(f64, f64)>) {
        out.clear();
        for (i, g) in row.iter().enumerate() {
            if !g.defined {
                continue;
            }
            let (a, b) = piece(grid, g, i, false);
            let (_, c) = piece(grid, g, i, true);
            for (x, z) in [a, b, c] {
                out.push((x.hypot(z), z.atan2(x)));
            }
        }
    }

    /// The sweep as first written (trigonometry evaluated per box): the optimised
    /// [`pixel_points`] must give bit-for-bit the same points in the same order.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn pixel_points_v1(
        grid: &PixelGrid,
        rs: &RowSweep,
        x: f64,
        delta: f64,
        subdivisions: usize,
        sc: &mut Scratch,
        halves: &mut [HalfPoints; 2],
    ) {
        halves[0].clear();
        halves[1].clear();
        let events = &mut sc.events;
        events.clear();
        events.extend([(-delta, NONE), (0.0, NONE), (delta, NONE)]);
        for (e, &(rho, psi, _)) in rs.ends.iter().enumerate() {
            if rho < x.abs() {
                continue;
            }
            let phi = (x / rho).clamp(-1.0, 1.0).acos();
            for th in [wrap(psi - phi), wrap(psi + phi)] {
                // An event computed within the window outside the range is one at its end (a
                // crossing through an end point at θ = ±Δθ): it is kept there, so that the
                // pieces it bounds are considered at the end's exact evaluation.
                if th > -delta - WINDOW && th < delta + WINDOW {
                    events.push((th.clamp(-delta, delta), e as u32));
                }
            }
        }
        events.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        sc.met.clear();
        sc.met.resize(rs.pieces.len(), false);
        sc.active.clear();
        let r = grid.cylinder.radius;
        let step = delta / subdivisions as f64;
        let tau = |th: f64| th.sin() / (1.0 + th.cos());
        let pieces_of = |k: usize| {
            let e = events[k].1;
            if e == NONE {
                [NONE, NONE]
            } else {
                rs.ends[e as usize].2
            }
        };
        let n = events.len();
        let (mut idx, mut lo) = (0usize, 0usize);
        while idx < n {
            let th = events[idx].0;
            let mut gend = idx;
            while gend < n && events[gend].0 == th {
                gend += 1;
            }
            while events[lo].0 < th - WINDOW {
                lo += 1;
            }
            // Exact value at this event angle: the nearest met piece among those met just before
            // and those bounded by the events here.
            {
                let (co, si) = (th.cos(), th.sin());
                let mut best: Option<f64> = None;
                let mut consider = |id: u32| {
                    if id != NONE
                        && let Some((_, z)) = rs.eval(id, x, co, si)
                    {
                        best = Some(best.map_or(z, |b: f64| b.max(z)));
                    }
                };
                if idx == 0 {
                    rs.existing.iter().for_each(|&id| consider(id));
                } else {
                    sc.active.iter().for_each(|&id| consider(id));
                    let mut k = lo;
                    while k < n && events[k].0 <= th + WINDOW {
                        pieces_of(k).iter().for_each(|&id| consider(id));
                        k += 1;
                    }
                }
                if let Some(z) = best {
                    push_exact(halves, th, (tau(th), z));
                }
            }
            if gend == n {
                break;
            }
            let (ea, eb) = (th, events[gend].0);
            idx = gend;
            // Update the met set at the interval's middle.
            let mid = 0.5 * (ea + eb);
            let (co, si) = (mid.cos(), mid.sin());
            let retest = |id: u32, met: &mut Vec<bool>, active: &mut Vec<u32>| {
                if id == NONE {
                    return;
                }
                let now = rs.eval(id, x, co, si).is_some();
                if met[id as usize] != now {
                    met[id as usize] = now;
                    if now {
                        active.push(id);
                    } else if let Some(p) = active.iter().position(|&a| a == id) {
                        active.swap_remove(p);
                    }
                }
            };
            if ea == -delta {
                for &id in &rs.existing {
                    retest(id, &mut sc.met, &mut sc.active);
                }
            } else {
                let mut k = lo;
                while k < n && events[k].0 <= eb + WINDOW {
                    for id in pieces_of(k) {
                        retest(id, &mut sc.met, &mut sc.active);
                    }
                    k += 1;
                }
            }
            // The visible piece: nearest met piece.
            let mut vis: Option<(u32, f64)> = None;
            for &id in &sc.active {
                if let Some((_, z)) = rs.eval(id, x, co, si)
                    && vis.is_none_or(|(_, bz)| z > bz)
                {
                    vis = Some((id, z));
                }
            }
            let Some((id, _)) = vis else { continue };
            let Some((a, b)) = rs.pieces[id as usize] else {
                continue;
            };
            let half = usize::from(mid >= 0.0);
            push_piece_boxes_v1(&mut halves[half], a, b, x, r, (ea, eb), step, tau);
        }
        for hp in halves.iter() {
            debug_assert!(hp.upper.windows(2).all(|w| w[0].0 <= w[1].0));
        }
    }

    /// Conservative corner points `(τ, z_e)` of the crossing of the screen ray at abscissa `x` with
    /// the surface piece `a → b` (view frame, `(x_t, z_t)` pairs), for view angles in the open
    /// interval `(ea, eb)` where that piece is the visible one. The interval is cut at the points of
    /// the uniform grid of `step` inside it; over each sub-interval the crossing's depth is bounded by
    /// its values at both ends and, where the foot of the perpendicular from the axis falls inside
    /// the sub-interval's range of piece parameters, by the depth of that foot (the extremum of
    /// `|z_e|` along the piece). Each box is widened by `EPS·r` and pushed as two upper and two lower
    /// corners at `τ(s_a)` and `τ(s_b)`.
    #[allow(clippy::too_many_arguments)]
    fn push_piece_boxes_v1(
        hp: &mut HalfPoints,
        a: (f64, f64),
        b: (f64, f64),
        x: f64,
        r: f64,
        (ea, eb): (f64, f64),
        step: f64,
        tau: impl Fn(f64) -> f64,
    ) {
        let (dx, dz) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dz * dz;
        let t_foot = if len2 > 0.0 {
            -(a.0 * dx + a.1 * dz) / len2
        } else {
            0.0
        };
        // Crossing on the piece's line at angle th: (t, t, z_e, z_e); a piece seen edge-on (only
        // possible at an interval end) gives both its ends.
        let on_line = |th: f64| -> (f64, f64, f64, f64) {
            let (co, si) = (th.cos(), th.sin());
            let xe_a = a.0 * co + a.1 * si;
            let xe_b = b.0 * co + b.1 * si;
            let ze = |t: f64| {
                let (px, pz) = (a.0 + t * dx, a.1 + t * dz);
                pz * co - px * si
            };
            if xe_b - xe_a > 1e-14 * r {
                let t = ((x - xe_a) / (xe_b - xe_a)).clamp(0.0, 1.0);
                let z = ze(t);
                (t, t, z, z)
            } else {
                let (z0, z1) = (ze(0.0), ze(1.0));
                (0.0, 1.0, z0.min(z1), z0.max(z1))
            }
        };
        // Boxes over the sub-intervals cut by the uniform grid strictly inside (ea, eb).
        let mut m = (ea / step).floor() as i64 + 1;
        let mut s_a = ea;
        let mut end_a = on_line(ea);
        loop {
            let gm = m as f64 * step;
            let s_b = if gm < eb { gm } else { eb };
            let end_b = on_line(s_b);
            let (t_lo, t_hi) = (end_a.0.min(end_b.0), end_a.1.max(end_b.1));
            let mut zlo = end_a.2.min(end_b.2);
            let mut zhi = end_a.3.max(end_b.3);
            if t_foot > t_lo && t_foot < t_hi {
                let (px, pz) = (a.0 + t_foot * dx, a.1 + t_foot * dz);
                let zf = (px * px + pz * pz - x * x).max(0.0).sqrt();
                if zlo >= 0.0 {
                    zlo = zlo.min(zf);
                } else if zhi <= 0.0 {
                    zhi = zhi.max(-zf);
                }
            }
            let (ta, tb) = (tau(s_a), tau(s_b));
            let (zlo, zhi) = (zlo - EPS * r, zhi + EPS * r);
            hp.upper.push((ta, zhi));
            hp.upper.push((tb, zhi));
            hp.lower.push((ta, zlo));
            hp.lower.push((tb, zlo));
            if s_b >= eb {
                break;
            }
            s_a = s_b;
            end_a = end_b;
            m += 1;
        }
    }

    /// The exact sweep of one pixel: fills the corner points of both half ranges.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn pixel_points_by_march(
        grid: &PixelGrid,
        row: &[TexelGeom],
        endpoints: &[(f64, f64)],
        x: f64,
        delta: f64,
        subdivisions: usize,
        r_march: f64,
        events: &mut Vec<f64>,
        halves: &mut [HalfPoints; 2],
    ) {
        halves[0].clear();
        halves[1].clear();
        events.clear();
        events.extend([-delta, 0.0, delta]);
        for &(rho, psi) in endpoints {
            if rho < x.abs() {
                continue;
            }
            let phi = (x / rho).clamp(-1.0, 1.0).acos();
            for th in [wrap(psi - phi), wrap(psi + phi)] {
                if th > -delta && th < delta {
                    events.push(th);
                }
            }
        }
        events.sort_unstable_by(f64::total_cmp);
        events.dedup();
        let half_of = |th: f64| usize::from(th >= 0.0);
        let r = grid.cylinder.radius;
        let hit_at = |th: f64| {
            let (co, si) = (th.cos(), th.sin());
            let (x1, x2) = cylinder_range(x, co, si, r_march);
            march_row(grid, row, x, co, si, x1, x2).hit
        };
        let tau = |th: f64| th.sin() / (1.0 + th.cos());
        // Exact values at every event angle.
        for &e in events.iter() {
            if let Some(h) = hit_at(e) {
                push_exact(halves, e, (tau(e), h.z_e));
            }
        }
        // Boxes over the open event intervals.
        for w in events.windows(2) {
            let (ea, eb) = (w[0], w[1]);
            if eb <= ea {
                continue;
            }
            let Some(h) = hit_at(0.5 * (ea + eb)) else {
                continue;
            };
            let g = &row[h.texel];
            let (a, b) = piece(grid, g, h.texel, h.right);
            let half = half_of(0.5 * (ea + eb));
            push_piece_boxes(
                halves,
                half,
                a,
                b,
                x,
                r,
                (ea, eb),
                ((ea.cos(), ea.sin()), (eb.cos(), eb.sin())),
                &AngleGrid::new(delta, subdivisions),
            );
        }
        for hp in halves.iter_mut() {
            hp.upper.sort_by(|p, q| p.0.total_cmp(&q.0));
            hp.lower.sort_by(|p, q| p.0.total_cmp(&q.0));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_sweep_matches_marching_sweep() {
        use crate::parallax::images::{ParallaxImages, ParallaxParams};
        for name in ["truck", "tree", "building", "torus"] {
            let shape = altrep_data_gen::scene_shape(name).unwrap();
            let p = ParallaxParams {
                views: 6,
                width: 24,
                height: 12,
                ..Default::default()
            };
            let images = ParallaxImages::capture(&shape, &p).unwrap();
            let grid = images.pixel_grid();
            let (mut a, mut b) = (
                [HalfPoints::default(), HalfPoints::default()],
                [HalfPoints::default(), HalfPoints::default()],
            );
            let mut sc = Scratch::default();
            let (mut ends, mut ev) = (Vec::new(), Vec::new());
            for view in &images.views {
                for j in 0..p.height {
                    let row = &view.geom[j * p.width..(j + 1) * p.width];
                    let rs = RowSweep::new(&grid, row, p.delta_theta());
                    reference::row_endpoints(&grid, row, &mut ends);
                    for i in 0..p.width {
                        let x = grid.x_at(i as f64 + 0.5);
                        let angles = AngleGrid::new(p.delta_theta(), 4);
                        a.iter_mut().for_each(HalfPoints::clear);
                        pixel_points(&grid, &rs, x, p.delta_theta(), &angles, &mut sc, &mut a);
                        reference::pixel_points_by_march(
                            &grid,
                            row,
                            &ends,
                            x,
                            p.delta_theta(),
                            4,
                            images.march_radius(),
                            &mut ev,
                            &mut b,
                        );
                        for h in 0..2 {
                            for (u, v) in [(&a[h].upper, &b[h].upper), (&a[h].lower, &b[h].lower)] {
                                let mut u = u.clone();
                                u.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
                                let mut v = v.clone();
                                v.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
                                v.dedup();
                                u.dedup();
                                if u != v {
                                    let th = 0.0f64;
                                    for (k, &e) in sc
                                        .events
                                        .iter()
                                        .enumerate()
                                        .filter(|(_, e)| e.0.abs() < 0.2)
                                    {
                                        eprintln!(
                                            "event {k} {e:?} pieces {:?}",
                                            if e.1 == NONE {
                                                [NONE, NONE]
                                            } else {
                                                rs.ends[e.1 as usize].2
                                            }
                                        );
                                    }
                                    for &id in &rs.existing {
                                        if let Some(r) = rs.eval(id, x, th.cos(), th.sin()) {
                                            eprintln!(
                                                "met at 0: piece {id} {r:?} {:?}",
                                                rs.pieces[id as usize]
                                            );
                                        }
                                    }
                                    eprintln!("x = {x}");
                                }
                                assert_eq!(u, v, "{name} row {j} pixel {i} half {h}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// A list of points as bits, for bitwise comparisons.
    fn bits(v: &[(f64, f64)]) -> Vec<(u64, u64)> {
        v.iter().map(|p| (p.0.to_bits(), p.1.to_bits())).collect()
    }

    /// Calls `f(shape, grid, row, X, Δθ, angle grid, subdivisions)` for every pixel of every
    /// row of 8 views of 32 × 16 of the truck, tree, building and torus, at zmin/zmax's single
    /// subdivision and at the default 64.
    fn for_each_test_pixel(
        mut f: impl FnMut(&str, &PixelGrid, &RowSweep, f64, f64, &AngleGrid, usize),
    ) {
        use crate::parallax::images::{ParallaxImages, ParallaxParams};
        for name in ["truck", "tree", "building", "torus"] {
            let shape = altrep_data_gen::scene_shape(name).unwrap();
            let p = ParallaxParams {
                views: 8,
                width: 32,
                height: 16,
                ..Default::default()
            };
            let images = ParallaxImages::capture(&shape, &p).unwrap();
            let grid = images.pixel_grid();
            let delta = p.delta_theta();
            for subdivisions in [1, 64] {
                let angles = AngleGrid::new(delta, subdivisions);
                for view in &images.views {
                    for j in 0..p.height {
                        let row = &view.geom[j * p.width..(j + 1) * p.width];
                        let rs = RowSweep::new(&grid, row, delta);
                        for i in 0..p.width {
                            let x = grid.x_at(i as f64 + 0.5);
                            f(name, &grid, &rs, x, delta, &angles, subdivisions);
                        }
                    }
                }
            }
        }
    }

    /// The optimised sweep (trigonometry cached per event and per grid angle, one corner pushed
    /// where two boxes meet) gives bit-for-bit the hulls of the corner points of the sweep as
    /// first written (every box's four corners), per half and over both halves, at the default
    /// subdivision count and for zmin/zmax's single subdivision.
    #[test]
    fn optimised_sweep_is_bitwise_the_first_sweep() {
        let mut compared = 0usize;
        let (mut sc, mut sc1) = (Scratch::default(), Scratch::default());
        let mut a = [HalfPoints::default(), HalfPoints::default()];
        let mut b = [HalfPoints::default(), HalfPoints::default()];
        for_each_test_pixel(|name, grid, rs, x, delta, angles, subdivisions| {
            a.iter_mut().for_each(HalfPoints::clear);
            pixel_points(grid, rs, x, delta, angles, &mut sc, &mut a);
            reference::pixel_points_v1(grid, rs, x, delta, subdivisions, &mut sc1, &mut b);
            for upper in [true, false] {
                let side = |hp: &HalfPoints| {
                    if upper {
                        hp.upper.clone()
                    } else {
                        hp.lower.clone()
                    }
                };
                for h in 0..2 {
                    let (ha, hb) = (hull(side(&a[h]), upper), hull(side(&b[h]), upper));
                    assert_eq!(bits(&ha), bits(&hb), "{name}, half {h}");
                    compared += ha.len();
                }
                let both =
                    |p: &[HalfPoints; 2]| hull(side(&p[0]).into_iter().chain(side(&p[1])), upper);
                assert_eq!(bits(&both(&a)), bits(&both(&b)), "{name}, both halves");
            }
        });
        assert!(compared > 10_000, "only {compared} hull vertices compared");
    }

    /// The hulls built as the sweep pushes its points are bitwise [`hull`] over the points
    /// listed (half 0's, then half 1's), for one slot over both halves and for one per half.
    #[test]
    fn hulls_built_during_the_sweep_are_bitwise_the_hulls_of_the_lists() {
        let mut compared = 0usize;
        let mut sc = Scratch::default();
        let mut lists = [HalfPoints::default(), HalfPoints::default()];
        let mut sweeps = [SlotHulls::new(false), SlotHulls::new(true)];
        for_each_test_pixel(|name, grid, rs, x, delta, angles, _| {
            lists.iter_mut().for_each(HalfPoints::clear);
            pixel_points(grid, rs, x, delta, angles, &mut sc, &mut lists);
            for hulls in &mut sweeps {
                hulls.clear();
                pixel_points(grid, rs, x, delta, angles, &mut sc, hulls);
                let slots: &[&[usize]] = if hulls.split {
                    &[&[0], &[1]]
                } else {
                    &[&[0, 1]]
                };
                for (s, halves) in slots.iter().enumerate() {
                    let points = |upper: bool| -> Vec<(f64, f64)> {
                        halves
                            .iter()
                            .flat_map(|&h| {
                                let hp = &lists[h];
                                if upper { &hp.upper } else { &hp.lower }.clone()
                            })
                            .collect()
                    };
                    let (up, lo) = (points(true), points(false));
                    match hulls.hulls_of(s) {
                        None => assert!(up.is_empty() && lo.is_empty()),
                        Some((u, l)) => {
                            assert_eq!(bits(&u), bits(&hull(up, true)), "{name}");
                            assert_eq!(bits(&l), bits(&hull(lo, false)), "{name}");
                            compared += u.len() + l.len();
                        }
                    }
                }
                if !hulls.split {
                    assert!(hulls.hulls_of(1).is_none());
                }
            }
        });
        assert!(compared > 10_000, "only {compared} hull vertices compared");
    }

    /// The events that [`pixel_points`] keeps for an end point `E` and a pixel `X`: those
    /// within `WINDOW` of `[−delta, delta]`, computed as it computes them.
    fn kept_events(rho: f64, psi: f64, x: f64, delta: f64) -> Vec<f64> {
        if rho < x.abs() {
            return Vec::new();
        }
        let phi = (x / rho).clamp(-1.0, 1.0).acos();
        [wrap(psi - phi), wrap(psi + phi)]
            .into_iter()
            .filter(|&th| th > -delta - WINDOW && th < delta + WINDOW)
            .collect()
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 4000, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..proptest::prelude::ProptestConfig::default() })]
        /// The prefilter never skips an end point with a kept event: random and adversarial
        /// end points (on the window's edges, at `ψ ± π`) and pixels (at `±|E|` and just
        /// inside, where `acos` is ill-conditioned, and at the window's edge values).
        #[test]
        fn the_event_prefilter_skips_no_kept_event(
            rho in 1e-6f64..2.0,
            psi_kind in 0usize..4,
            psi_raw in -3.2f64..3.2,
            psi_nudge in -1e-7f64..1e-7,
            views in 1usize..40,
            x_kind in 0usize..5,
            x_raw in -1.0f64..1.0,
            x_nudge in -1e-12f64..1e-12,
        ) {
            let delta = PI / views as f64;
            let psi = match psi_kind {
                0 => psi_raw,
                1 => delta + psi_nudge,
                2 => -delta + psi_nudge,
                _ => wrap(PI + psi_nudge),
            };
            let (ex, ez) = (rho * psi.cos(), rho * psi.sin());
            let (rho, psi) = (ex.hypot(ez), ez.atan2(ex));
            let edge = |th: f64| ex * th.cos() + ez * th.sin();
            let x = match x_kind {
                0 => x_raw * rho * 1.1,
                1 => rho * (1.0 - x_nudge.abs()),
                2 => -rho * (1.0 - x_nudge.abs()),
                3 => edge(delta) + x_nudge * rho,
                _ => edge(-delta) + x_nudge * rho,
            };
            let (lo, hi) = x_window((ex, ez), rho, psi, delta);
            if x < lo || x > hi {
                let kept = kept_events(rho, psi, x, delta);
                proptest::prop_assert!(
                    kept.is_empty(),
                    "skipped E = ({ex}, {ez}) at X = {x}: events {kept:?}, window [{lo}, {hi}]"
                );
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 3000, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..proptest::prelude::ProptestConfig::default() })]
        /// [`push_piece_boxes`] pushes one corner per side where two boxes meet, the outer of
        /// the two: the hulls are bitwise those of pushing both corners of every box. Boxes
        /// over random ascending τ with repeated τ, z drawn from a few values (ties, ±0,
        /// collinear runs) or at random, and a hull already holding points.
        #[test]
        fn pushing_the_outer_corner_where_boxes_meet_keeps_the_hulls_bitwise(
            start in proptest::collection::vec((0usize..4, -2.0f64..2.0), 0..4),
            boxes in proptest::collection::vec(
                (0usize..3, 0usize..6, -2.0f64..2.0, 0usize..6, 0.0f64..1.0),
                1..40,
            ),
        ) {
            let pick = |k: usize, raw: f64| match k {
                0 => 0.0,
                1 => -0.0,
                2 => 1.0,
                3 => -1.0,
                4 => 0.5,
                _ => raw,
            };
            for upper in [true, false] {
                let (mut both, mut outer) = (HullBuilder::new(upper), HullBuilder::new(upper));
                let mut tau = -3.0;
                for &(k, raw) in &start {
                    tau += [0.0, 0.25, 0.5, 1.0][k];
                    both.push((tau, raw));
                    outer.push((tau, raw));
                }
                // Box b spans [τ_b, τ_{b+1}] with value z_b (the side's corner value).
                let mut taus = vec![tau + 0.125];
                let mut zs = Vec::new();
                for &(dt, zk, zraw, _, _) in &boxes {
                    let last = *taus.last().unwrap();
                    taus.push(last + [0.0, 0.125, 0.375][dt]);
                    zs.push(pick(zk, zraw));
                }
                for (b, &z) in zs.iter().enumerate() {
                    both.push((taus[b], z));
                    both.push((taus[b + 1], z));
                }
                let mut pending: Option<f64> = None;
                for (b, &z) in zs.iter().enumerate() {
                    let at_a = match pending {
                        Some(p) if upper => if z > p { z } else { p },
                        Some(p) => if z < p { z } else { p },
                        None => z,
                    };
                    outer.push((taus[b], at_a));
                    pending = Some(z);
                }
                outer.push((*taus.last().unwrap(), *zs.last().unwrap()));
                proptest::prop_assert_eq!(bits(&both.points), bits(&outer.points));
            }
        }
    }

    #[test]
    fn hulls_keep_extremes() {
        let pts = [(0.0, 0.0), (1.0, 2.0), (2.0, 1.0), (3.0, 3.0), (3.0, 0.5)];
        let up = hull(pts, true);
        assert_eq!(up, vec![(0.0, 0.0), (1.0, 2.0), (3.0, 3.0)]);
        let low_pts = [(0.0, 0.0), (1.0, -2.0), (2.0, 1.0), (3.0, 0.5)];
        let lo = hull(low_pts, false);
        assert_eq!(lo, vec![(0.0, 0.0), (1.0, -2.0), (3.0, 0.5)]);
        for a in [-3.0, -0.5, 0.0, 0.7, 4.0] {
            let full = v_range(&pts, &low_pts, a);
            let hl = v_range(&up, &lo, a);
            assert!((full.0 - hl.0).abs() < 1e-12 && (full.1 - hl.1).abs() < 1e-12);
        }
    }

    #[test]
    fn c_grid_holds_plus_minus_one() {
        for (lo, hi, bits) in [
            (-1.0, 1.0, 8),
            (-7.3, 3.1, 8),
            (-1.0, 31.9, 8),
            (-32.0, 32.0, 16),
        ] {
            let g = CGrid::new(lo, hi, bits);
            let q = |c: f64| (c - g.c0) / g.step;
            assert!(
                (q(-1.0) - q(-1.0).round()).abs() < 1e-9 && (q(1.0) - q(1.0).round()).abs() < 1e-9
            );
            assert!(g.c0 <= lo + 1e-12 && g.c0 + g.levels as f64 * g.step >= hi - 1e-12);
        }
    }

    #[test]
    fn f32_steps_are_adjacent() {
        for f in [1.0f32, -1.0, 0.3, -2.5e-7, 0.0] {
            let (u, d) = (f32_step(f, true), f32_step(f, false));
            assert!(u > f && d < f);
            assert!(f32_step(u, false) == f || f == 0.0);
            assert!(f32_step(d, true) == f || f == 0.0);
        }
    }

    #[test]
    fn quantisation_is_outward() {
        let data = [0.1234, -0.7, 0.99, 0.5, -0.2];
        let orig = data;
        for bits in [8, 16, 32] {
            let mut up = data;
            let mut refs: Vec<&mut f64> = up.iter_mut().collect();
            quantize_channel(&mut refs, true, bits);
            let mut down = data;
            let mut refs: Vec<&mut f64> = down.iter_mut().collect();
            quantize_channel(&mut refs, false, bits);
            for k in 0..data.len() {
                assert!(up[k] >= orig[k] && down[k] <= orig[k], "bits {bits}");
            }
        }
    }
}
