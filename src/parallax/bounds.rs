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

use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::images::ParallaxImages;
use super::warp::{cylinder_range, warp_row_direct_impl};
use super::{ParallaxError, finite, in_range, invalid};

mod sweep;
use sweep::*;

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
mod reference;
#[cfg(test)]
mod tests;
