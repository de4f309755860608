//! The exact event sweep of one pixel: the corner points `(τ, z_e)` of the visible crossing over
//! a view's angle range, pushed as conservative boxes into hulls (see the parent module's docs).

use std::f64::consts::PI;

use altrep_data_gen::PixelGrid;

use super::HullBuilder;
use crate::parallax::images::TexelGeom;
use crate::parallax::warp::{hit_piece, piece};

/// Upper and lower corner points `(τ, z_e)` of one half range, ascending in `τ = tan(θ/2)`
/// (the sweep's points as lists, for the tests).
#[cfg(test)]
#[derive(Default, Clone, Debug)]
pub(super) struct HalfPoints {
    pub(super) upper: Vec<(f64, f64)>,
    pub(super) lower: Vec<(f64, f64)>,
}

#[cfg(test)]
impl HalfPoints {
    pub(super) fn clear(&mut self) {
        self.upper.clear();
        self.lower.clear();
    }
}

/// Where [`pixel_points`] puts the corner points of each half range: kept as lists
/// (`[HalfPoints; 2]`, for the tests) or fed straight into hulls ([`SlotHulls`]). Points of a half
/// arrive in ascending τ, and every point of half 0 arrives before any point of half 1.
pub(super) trait Corners {
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
pub(super) type Chain = Vec<(f64, f64)>;

/// The hulls of a pixel's slots built as the sweep pushes its corner points: one slot over both
/// halves, or (`split`) one per half. The same hulls as [`hull`] over the concatenated lists
/// (half 0's points, then half 1's), since the builder takes the same steps on the same
/// sequence of points; without storing the points.
pub(super) struct SlotHulls {
    pub(super) split: bool,
    /// `[slot] = (upper, lower)`.
    pub(super) hulls: [(HullBuilder, HullBuilder); 2],
}

impl SlotHulls {
    pub(super) fn new(split: bool) -> Self {
        let pair = || (HullBuilder::new(true), HullBuilder::new(false));
        Self {
            split,
            hulls: [pair(), pair()],
        }
    }
    pub(super) fn clear(&mut self) {
        for (u, l) in &mut self.hulls {
            u.points.clear();
            l.points.clear();
        }
    }
    #[inline]
    pub(super) fn slot(&self, half: usize) -> usize {
        if self.split { half } else { 0 }
    }
    /// Copies of the upper and lower hulls of `slot` (`None` if no point reached it); the
    /// builders keep their buffers for the next pixel.
    pub(super) fn hulls_of(&self, slot: usize) -> Option<(Chain, Chain)> {
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
pub(super) const EPS: f64 = 1e-12;

#[inline]
pub(super) fn wrap(a: f64) -> f64 {
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
pub(super) type Segment = ((f64, f64), (f64, f64));

/// A row's pieces and end points, prepared once for the event sweeps of all its pixels.
pub(super) struct RowSweep {
    /// Piece `2i + right` of texel `i`: its end points, `None` if the texel is undefined.
    pub(super) pieces: Vec<Option<Segment>>,
    /// Ids of the existing pieces.
    pub(super) existing: Vec<u32>,
    /// End points: `(|E|, ψ_E)` and the one or two pieces they bound (`u32::MAX` = none).
    pub(super) ends: Vec<(f64, f64, [u32; 2])>,
    /// Per end point, an interval of screen abscissae `X` outside which none of its events
    /// falls in the sweep's window (see [`x_window`]).
    pub(super) x_windows: Vec<(f64, f64)>,
}

/// Angle margin of [`x_window`] (radians) beyond the sweep's window `±(Δθ + WINDOW)`: far
/// above the error of a computed event angle (below 2e-8 rad even where `acos` is
/// ill-conditioned, `X ≈ ±|E|`), far below the window.
pub(super) const PREFILTER_MARGIN: f64 = 1e-6;

/// An interval of `X` containing `x_e(E, θ) = |E| cos(θ − ψ_E)` for every `θ` within
/// `Δθ + WINDOW + PREFILTER_MARGIN` of 0 (end values, and `±|E|` where `ψ_E` or `ψ_E + π` lies
/// inside), padded by `1e-9·|E|` for rounding. A pixel whose `X` is outside it has no event of
/// `E` that [`pixel_points`] would keep (its computed events lie within `2e-8` rad of true
/// solutions, and those lie outside the widened window), so the sweep skips `E` without solving
/// for its events: the same events, fewer `acos`.
pub(super) fn x_window((ex, ez): (f64, f64), rho: f64, psi: f64, delta: f64) -> (f64, f64) {
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

pub(super) const NONE: u32 = u32::MAX;

impl RowSweep {
    /// The row `row` of a view on `grid`, for sweeps over `[−delta, delta]`.
    pub(super) fn new(grid: &PixelGrid, row: &[TexelGeom], delta: f64) -> Self {
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
    pub(super) fn eval(&self, id: u32, x: f64, co: f64, si: f64) -> Option<(f64, f64)> {
        let (a, b) = self.pieces[id as usize]?;
        hit_piece(a, b, x, co, si).map(|(t, _, z_e)| (t, z_e))
    }
}

/// Reusable buffers of [`pixel_points`].
#[derive(Default)]
pub(super) struct Scratch {
    /// `(θ, end point index or NONE)`, sorted.
    pub(super) events: Vec<(f64, u32)>,
    /// `(cos θ, sin θ)` of each event, computed once.
    pub(super) trig: Vec<(f64, f64)>,
    /// Whether each piece is met by the ray in the current interval.
    pub(super) met: Vec<bool>,
    /// The pieces met in the current interval.
    pub(super) active: Vec<u32>,
}

/// The uniform angle grid `θ_m = m·step` (`step = Δθ / subdivisions`) that cuts the event
/// intervals, with `cos θ_m`, `sin θ_m` and `τ(θ_m) = sin θ_m / (1 + cos θ_m)` computed once per
/// build instead of once per box (the values are the same: the same functions of the same `θ_m`).
pub(super) struct AngleGrid {
    pub(super) step: f64,
    /// Index of `m = 0` in `trig`.
    pub(super) zero: i64,
    /// `(cos θ_m, sin θ_m, τ(θ_m))` for `m = −zero ..= zero`.
    pub(super) trig: Vec<(f64, f64, f64)>,
}

impl AngleGrid {
    pub(super) fn new(delta: f64, subdivisions: usize) -> Self {
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
    pub(super) fn at(&self, m: i64) -> (f64, f64, f64) {
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
pub(super) const WINDOW: f64 = 1e-9;

/// The exact sweep of one pixel (module docs): fills the corner points of both half ranges,
/// sorted by τ.
///
/// The pieces the ray meets change only at events; the sweep keeps that set, re-testing at each
/// interval's middle only the pieces bounded by the end points of the events at its ends (within
/// [`WINDOW`] of them, which absorbs rounding in the computed event angles: a piece whose true
/// crossing lies near a computed event is re-tested at every interval within the window). The
/// visible piece is the met piece nearest to the camera (largest `z_e`), as the march finds it.
pub(super) fn pixel_points(
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
pub(super) fn push_exact(halves: &mut impl Corners, th: f64, p: (f64, f64)) {
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
pub(super) fn push_piece_boxes(
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
