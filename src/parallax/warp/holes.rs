//! Where both bracketing views miss: the fallback views' coverage and the filling of holes hidden
//! in both views ([`Reconstruction::soft_fallback`], [`Reconstruction::fill_holes`]).

use super::*;

/// Depth window of [`Reconstruction::carve_brims`], in texel pitches: the other view's texel
/// beside the point must lie within it of the point's depth in that view (measured:
/// 2 beats 4, which carved true surface on the sphere at N = 16).
pub const CARVE_DEPTH_TEXELS: f64 = 2.0;

/// Coverage of a doubtful fallback hit ([`Reconstruction::soft_fallback`]).
pub const DOUBTFUL_FALLBACK_COVERAGE: f32 = 0.5;

/// The factor on the premultiplied colour of the fallback views' combination `c` (crossings of
/// the views `outer` on the ray `x` of row `j`, which both bracketing views `pair` missed):
/// [`DOUBTFUL_FALLBACK_COVERAGE`] under [`Reconstruction::soft_fallback`] where one fallback
/// view alone hits, on a brim sticking out past a bracketing view's outline ([`sticks_out`]
/// asked of each bracketing view), else 1.
pub(super) fn fallback_coverage(
    images: &ParallaxImages,
    pair: &[(usize, f64, f64); 2],
    outer: &[(usize, f64, f64); 2],
    j: usize,
    x: f64,
    c: [&Option<Crossing>; 2],
    rec: &Reconstruction,
) -> f32 {
    let doubtful = |slot: usize, a: &Crossing| {
        pair.iter()
            .any(|&near| sticks_out(images, &[outer[slot], near], 0, j, x, a))
    };
    let doubt = rec.soft_fallback
        && match c {
            [Some(a), None] => doubtful(0, a),
            [None, Some(b)] => doubtful(1, b),
            _ => false,
        };
    if doubt {
        DOUBTFUL_FALLBACK_COVERAGE
    } else {
        1.0
    }
}

/// [`Reconstruction::carve_brims`]: whether the crossing `a` of view `views[slot]` on the ray `x`
/// of row `j`, which the other view `views[1 − slot]` misses, is a brim sticking out past the
/// other view's outline: `a` lies on a brim, and its point projects in the other view onto an
/// undefined texel beside a defined one (`±1`) whose depth is within [`CARVE_DEPTH_TEXELS`] of
/// the point's. Cost: three texel reads.
pub(super) fn sticks_out(
    images: &ParallaxImages,
    views: &[(usize, f64, f64); 2],
    slot: usize,
    j: usize,
    x: f64,
    a: &Crossing,
) -> bool {
    if !on_brim(&images.views[views[slot].0], j, a) {
        return false;
    }
    let (kb, theta) = (views[1 - slot].0, views[1 - slot].1);
    let (u, zt) = project(images, theta, x, a.z_e);
    let grid = images.pixel_grid();
    let v = &images.views[kb];
    let at = |i: f64| (i >= 0.0 && i < v.width as f64).then(|| &v.geom[j * v.width + i as usize]);
    let i = u.floor();
    if at(i).is_some_and(|g| g.defined) {
        return false;
    }
    let window = CARVE_DEPTH_TEXELS * grid.pitch_x();
    [i - 1.0, i + 1.0]
        .into_iter()
        .any(|n| at(n).is_some_and(|g| g.defined && (g.z - zt).abs() <= window))
}

/// The screen point `(x, z_e)` (ray `x`, screen depth `z_e`) in the frame of a view seen under
/// `theta`: its texel coordinate `u` (texel `i` spans `[i, i + 1)`) and its depth `z_t`.
pub(super) fn project(images: &ParallaxImages, theta: f64, x: f64, z_e: f64) -> (f64, f64) {
    let grid = images.pixel_grid();
    let (co, si) = (theta.cos(), theta.sin());
    let xt = x * co - z_e * si;
    let zt = x * si + z_e * co;
    ((xt + grid.cylinder.radius) / grid.pitch_x(), zt)
}

/// Whether the point `(x, z_e)` of the screen (ray `x`, screen depth `z_e`) lies below the
/// surface of a defined texel of row `j` of view `k` seen under `theta`: hidden from that view.
pub(super) fn hidden_in(
    images: &ParallaxImages,
    k: usize,
    theta: f64,
    j: usize,
    x: f64,
    z_e: f64,
) -> bool {
    let (u, zt) = project(images, theta, x, z_e);
    let v = &images.views[k];
    if !(0.0..v.width as f64).contains(&u) {
        return false;
    }
    let i = u.floor() as usize;
    let g = &v.geom[j * v.width + i];
    if !g.defined {
        return false;
    }
    let f = u - i as f64;
    let h = if f < 0.5 {
        g.zl + (g.z - g.zl) * 2.0 * f
    } else {
        g.z + (g.zr - g.z) * (2.0 * f - 1.0)
    };
    zt < h
}

/// [`Reconstruction::fill_holes`] for the ray `x` on row `j`: in each view of `pair`, marched
/// from the cylinder, the first front-facing wall whose crossing the other view also hides; the
/// nearer of the two, shaded opaque with the texel on the far side of the wall. Also returns
/// the steps of both scans (cells tested plus fetches of the other view).
pub(crate) fn hole_fill(
    images: &ParallaxImages,
    pair: &[(usize, f64, f64); 2],
    j: usize,
    x: f64,
    light: &Light,
) -> (Option<Vec4>, u64) {
    let grid = images.pixel_grid();
    // Every wall of row `j` lies in the disc of the row's radius.
    let r = images.march_radius().min(images.row_radius(j));
    let mut best: Option<(usize, Crossing)> = None;
    let mut steps = 0u64;
    for (slot, &(k, theta, _)) in pair.iter().enumerate() {
        let (co, si) = (theta.cos(), theta.sin());
        let v = &images.views[k];
        let row = &v.geom[j * v.width..(j + 1) * v.width];
        let (x1, x2) = cylinder_range(x, co, si, r);
        let (ko, to) = (pair[1 - slot].0, pair[1 - slot].1);
        let accept = |c: &Crossing| hidden_in(images, ko, to, j, x, c.z_e);
        let (found, n) = first_wall(&grid, row, x, co, si, x1, x2, accept);
        steps += u64::from(n);
        if let Some(c) = found
            && best.is_none_or(|(_, b)| c.z_e > b.z_e)
        {
            best = Some((k, c));
        }
    }
    let col = best.map(|(k, c)| {
        let col = shade_crossing(&images.views[k], j, &c, light);
        Vec4::new(col.x, col.y, col.z, 1.0)
    });
    (col, steps)
}
