//! The first version of the sweep, which finds the visible piece of every interval by a full
//! march: slower, kept to cross-check the event sweep in the tests.

use altrep_data_gen::PixelGrid;

use super::*;
use crate::parallax::images::TexelGeom;
use crate::parallax::warp::march_row;
use crate::parallax::warp::piece;

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
