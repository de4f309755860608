//! Direct and inverse warping of one view, and the combination of two warped views.
//!
//! Both warps share one piece test ([`hit_piece`]) so they agree exactly (see the module docs of
//! [`crate::parallax`]).

use altrep_data_gen::{Light, PixelGrid, RgbaImage};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

use super::images::{ParallaxImages, TexelGeom, View};
use super::{ParallaxError, finite, in_range, invalid};

mod holes;
mod params;
use holes::*;
pub use holes::{CARVE_DEPTH_TEXELS, DOUBTFUL_FALLBACK_COVERAGE};
pub use params::{Reconstruction, RenderParams, RowFilter, WarpMethod};

/// Where a ray crosses a view's height field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// Column of the texel owning the piece that was hit.
    pub texel: usize,
    /// Whether the piece is the texel's right half (`[x_i, x_i + δx/2]`) or its left half.
    pub right: bool,
    /// Position along the piece, `0 ≤ t < 1` from its left end.
    pub t: f64,
    /// Abscissa of the crossing in the view frame, `x_t` (world units).
    pub x_t: f64,
    /// Depth of the crossing in the screen frame, `z_e` (world units, toward the camera).
    pub z_e: f64,
}

/// Outcome of one march.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarchResult {
    /// The first crossing, if the ray meets the height field within the range.
    pub hit: Option<Crossing>,
    /// Cells visited (one texel fetch each); 0 when the range is empty.
    pub steps: u32,
}

/// Entry and exit abscissae `(x1, x2)` of the ray `X` seen under θ through the cylinder of radius
/// `r` (module docs: `x1 = X cos θ − h sin θ`, `x2 = X cos θ + h sin θ`).
#[inline]
pub fn cylinder_range(x: f64, cos_t: f64, sin_t: f64, r: f64) -> (f64, f64) {
    let h = (r * r - x * x).max(0.0).sqrt();
    (x * cos_t - h * sin_t, x * cos_t + h * sin_t)
}

/// End points `((x_a, z_a), (x_b, z_b))`, `x_a < x_b`, of a texel's half piece.
#[inline]
pub(crate) fn piece(
    grid: &PixelGrid,
    g: &TexelGeom,
    i: usize,
    right: bool,
) -> ((f64, f64), (f64, f64)) {
    let xc = grid.x_at(i as f64 + 0.5);
    if right {
        ((xc, g.z), (grid.x_at(i as f64 + 1.0), g.zr))
    } else {
        ((grid.x_at(i as f64), g.zl), (xc, g.z))
    }
}

/// The ray `X` under θ against one piece: `Some((t, x_t, z_e))` iff `x_e(a) ≤ X < x_e(b)`.
#[inline]
pub(crate) fn hit_piece(
    a: (f64, f64),
    b: (f64, f64),
    x: f64,
    co: f64,
    si: f64,
) -> Option<(f64, f64, f64)> {
    let ea = a.0 * co + a.1 * si;
    let eb = b.0 * co + b.1 * si;
    if ea <= x && x < eb {
        let t = (x - ea) / (eb - ea);
        let xt = a.0 + t * (b.0 - a.0);
        let zt = a.1 + t * (b.1 - a.1);
        Some((t, xt, zt * co - xt * si))
    } else {
        None
    }
}

#[inline]
fn try_piece(
    grid: &PixelGrid,
    row: &[TexelGeom],
    i: usize,
    right: bool,
    x: f64,
    co: f64,
    si: f64,
) -> Option<Crossing> {
    let g = &row[i];
    if !g.defined {
        return None;
    }
    let (a, b) = piece(grid, g, i, right);
    hit_piece(a, b, x, co, si).map(|(t, x_t, z_e)| Crossing {
        texel: i,
        right,
        t,
        x_t,
        z_e,
    })
}

/// Cell index `c ∈ [−1, W−1]` of abscissa `x` (cell `c` spans `[x_c, x_{c+1}]`).
#[inline]
fn cell(grid: &PixelGrid, x: f64) -> i64 {
    let u = (x + grid.cylinder.radius) / grid.pitch_x() - 0.5;
    (u.floor().max(-1.0) as i64).min(grid.width as i64 - 1)
}

/// Marches one row of a view: cells from the one holding `x1` to the one holding `x2` (toward
/// +x when `sin θ ≥ 0`), testing in each the pieces in the ray's order, and stops at the first
/// crossing. `co, si` are `cos θ, sin θ`.
pub(crate) fn march_row(
    grid: &PixelGrid,
    row: &[TexelGeom],
    x: f64,
    co: f64,
    si: f64,
    x1: f64,
    x2: f64,
) -> MarchResult {
    let w = grid.width as i64;
    // Widen by a hair so that an end lying on a cell boundary (a texel centre) visits the cell
    // holding the piece that starts there, whatever the rounding of `cell`.
    let eps = 1e-9 * grid.pitch_x();
    let mut steps = 0u32;
    if si >= 0.0 {
        if x1 > x2 {
            return MarchResult {
                hit: None,
                steps: 0,
            };
        }
        let (c1, c2) = (cell(grid, x1 - eps), cell(grid, x2 + eps));
        for c in c1..=c2 {
            steps += 1;
            if c >= 0
                && let Some(h) = try_piece(grid, row, c as usize, true, x, co, si)
            {
                return MarchResult {
                    hit: Some(h),
                    steps,
                };
            }
            if c + 1 < w
                && let Some(h) = try_piece(grid, row, (c + 1) as usize, false, x, co, si)
            {
                return MarchResult {
                    hit: Some(h),
                    steps,
                };
            }
        }
    } else {
        if x1 < x2 {
            return MarchResult {
                hit: None,
                steps: 0,
            };
        }
        let (c1, c2) = (cell(grid, x1 + eps), cell(grid, x2 - eps));
        for c in (c2..=c1).rev() {
            steps += 1;
            if c + 1 < w
                && let Some(h) = try_piece(grid, row, (c + 1) as usize, false, x, co, si)
            {
                return MarchResult {
                    hit: Some(h),
                    steps,
                };
            }
            if c >= 0
                && let Some(h) = try_piece(grid, row, c as usize, true, x, co, si)
            {
                return MarchResult {
                    hit: Some(h),
                    steps,
                };
            }
        }
    }
    MarchResult { hit: None, steps }
}

/// Inverse warping of one ray (the shader's algorithm): row `j` of view `k` seen under `theta`,
/// screen abscissa `x`, marched from `range.0` (`x1`) toward `range.1` (`x2`), one cell per step.
/// Pass [`cylinder_range`] with [`ParallaxImages::march_radius`] for the unbounded march.
/// Cost: `O(steps)`. Errors: an index out of range, a non-finite input.
pub fn march(
    images: &ParallaxImages,
    k: usize,
    j: usize,
    x: f64,
    theta: f64,
    range: (f64, f64),
) -> Result<MarchResult, ParallaxError> {
    let v = &images.views[in_range("view index", k, images.views.len())?];
    in_range("row", j, v.height)?;
    for (name, value) in [
        ("screen abscissa", x),
        ("theta", theta),
        ("x1", range.0),
        ("x2", range.1),
    ] {
        finite(name, value)?;
    }
    let row = &v.geom[j * v.width..(j + 1) * v.width];
    Ok(march_row(
        &images.pixel_grid(),
        row,
        x,
        theta.cos(),
        theta.sin(),
        range.0,
        range.1,
    ))
}

/// Direct warping of row `j` of view `k` under `theta` onto the screen abscissae `xs` (ascending):
/// the front-facing pieces are drawn back to front (decreasing `x_t` for θ ≥ 0, increasing for
/// θ < 0), each over the rays with `x_e(a) ≤ X < x_e(b)`; the last drawn wins. `out[s]` gets the
/// crossing seen by ray `xs[s]`. Cost: `O(Lx + len(xs))` per row.
///
/// Errors: an index out of range, `out` shorter than `xs`, a non-finite `theta` or abscissa,
/// abscissae not ascending.
pub fn warp_row_direct(
    images: &ParallaxImages,
    k: usize,
    j: usize,
    theta: f64,
    xs: &[f64],
    out: &mut [Option<Crossing>],
) -> Result<(), ParallaxError> {
    let v = &images.views[in_range("view index", k, images.views.len())?];
    in_range("row", j, v.height)?;
    finite("theta", theta)?;
    if out.len() < xs.len() {
        return Err(invalid(
            "output length",
            out.len(),
            "must be at least the number of abscissae",
        ));
    }
    if xs.iter().any(|x| !x.is_finite()) || xs.windows(2).any(|w| w[0] > w[1]) {
        return Err(invalid(
            "screen abscissae",
            xs.len(),
            "must be finite and ascending",
        ));
    }
    let row = &v.geom[j * v.width..(j + 1) * v.width];
    warp_row_direct_impl(&images.pixel_grid(), row, theta.cos(), theta.sin(), xs, out);
    Ok(())
}

pub(crate) fn warp_row_direct_impl(
    grid: &PixelGrid,
    row: &[TexelGeom],
    co: f64,
    si: f64,
    xs: &[f64],
    out: &mut [Option<Crossing>],
) {
    out[..xs.len()].fill(None);
    let mut draw = |i: usize, right: bool| {
        let g = &row[i];
        if !g.defined {
            return;
        }
        let (a, b) = piece(grid, g, i, right);
        let ea = a.0 * co + a.1 * si;
        let eb = b.0 * co + b.1 * si;
        if eb <= ea {
            return; // seen from behind or edge-on
        }
        let start = xs.partition_point(|&x| x < ea);
        let end = xs.partition_point(|&x| x < eb);
        for s in start..end {
            if let Some((t, x_t, z_e)) = hit_piece(a, b, xs[s], co, si) {
                out[s] = Some(Crossing {
                    texel: i,
                    right,
                    t,
                    x_t,
                    z_e,
                });
            }
        }
    };
    if si >= 0.0 {
        for i in (0..row.len()).rev() {
            draw(i, true);
            draw(i, false);
        }
    } else {
        for i in 0..row.len() {
            draw(i, false);
            draw(i, true);
        }
    }
}

/// Albedo and (unnormalised) normal at a crossing of row `j` of `view`: linear interpolation along
/// joined segments, the texel's own values on flat ends.
pub(crate) fn crossing_attributes(view: &View, j: usize, c: &Crossing) -> (Vec3, Vec3) {
    let base = j * view.width;
    let k = base + c.texel;
    let g = &view.geom[k];
    let t = c.t as f32;
    let (a, n) = (view.albedo[k], view.normal[k]);
    if c.right {
        if g.link_r {
            let s = 0.5 * t;
            (
                a + s * (view.albedo[k + 1] - a),
                n + s * (view.normal[k + 1] - n),
            )
        } else {
            (a, n)
        }
    } else if g.link_l {
        let (ma, mn) = (
            0.5 * (view.albedo[k - 1] + a),
            0.5 * (view.normal[k - 1] + n),
        );
        (ma + t * (a - ma), mn + t * (n - mn))
    } else {
        (a, n)
    }
}

/// Coverage of a crossing for [`Reconstruction::soft_edges`]: `1 − u/2` on an unjoined half piece
/// (`u` the fraction from the texel centre outward), 1 elsewhere.
fn edge_coverage(view: &View, j: usize, c: &Crossing) -> f32 {
    let g = &view.geom[j * view.width + c.texel];
    let u = match (c.right, g.link_r, g.link_l) {
        (true, false, _) => c.t,
        (false, _, false) => 1.0 - c.t,
        _ => return 1.0,
    };
    (1.0 - 0.5 * u) as f32
}

/// The first front-facing wall met by the ray `X` marched from `x1` toward `x2` in one row (see
/// [`Reconstruction::fill_walls`]): a step between defined, unjoined neighbours `i`, `i + 1` at
/// the cell boundary `x_b`, crossed by the ray between the two piece ends, facing the ray. Returns
/// the crossing on the far (lower) texel's end and its screen depth. Cost: one test per cell.
#[allow(clippy::too_many_arguments)]
pub(crate) fn first_wall(
    grid: &PixelGrid,
    row: &[TexelGeom],
    x: f64,
    co: f64,
    si: f64,
    x1: f64,
    x2: f64,
    accept: impl Fn(&Crossing) -> bool,
) -> (Option<Crossing>, u32) {
    if si == 0.0 {
        return (None, 0);
    }
    let w = grid.width;
    let steps = std::cell::Cell::new(0u32);
    let test = |i: usize| -> Option<Crossing> {
        // One step per cell tested (its two texels), one more per fetch of the other view.
        steps.set(steps.get() + 1);
        let (a, b) = (&row[i], &row[i + 1]);
        if !(a.defined && b.defined) || a.link_r {
            return None;
        }
        let xb = grid.x_at(i as f64 + 1.0);
        let z = (x - xb * co) / si;
        // Toward +x the ray meets a wall rising to the right; toward −x one rising to the left.
        let (lo, hi, lower, right) = if si > 0.0 {
            (a.zr, b.zl, i, true)
        } else {
            (b.zl, a.zr, i + 1, false)
        };
        let c = Crossing {
            texel: lower,
            right,
            t: if right { 1.0 } else { 0.0 },
            x_t: xb,
            z_e: z * co - xb * si,
        };
        (lo <= z && z < hi && {
            steps.set(steps.get() + 1);
            accept(&c)
        })
        .then_some(c)
    };
    let (c1, c2) = (cell(grid, x1), cell(grid, x2));
    let last = w as i64 - 2;
    let found = if si > 0.0 {
        (c1.max(0)..=c2.min(last)).find_map(|c| test(c as usize))
    } else {
        (c2.max(0)..=c1.min(last))
            .rev()
            .find_map(|c| test(c as usize))
    };
    (found, steps.get())
}

/// Whether a crossing lies on an unjoined half piece (a brim: silhouette or depth jump).
fn on_brim(view: &View, j: usize, c: &Crossing) -> bool {
    let g = &view.geom[j * view.width + c.texel];
    if c.right { !g.link_r } else { !g.link_l }
}

/// Shaded linear RGB at a crossing.
pub(crate) fn shade_crossing(view: &View, j: usize, c: &Crossing, light: &Light) -> Vec3 {
    let (a, n) = crossing_attributes(view, j, c);
    light.shade(a, n.normalize_or_zero())
}

/// Warps view `k` alone under `theta` onto a screen: returns the crossing of every ray
/// (`height` rows of `width·supersample` rays) and the shaded image (alpha = share of rays that
/// hit). Inverse warping marches from the cylinder of [`ParallaxImages::march_radius`].
///
/// Errors: `k` out of range, a zero screen size, a non-finite `theta`.
pub fn warp_view(
    images: &ParallaxImages,
    k: usize,
    theta: f64,
    method: WarpMethod,
    screen: &RenderParams,
) -> Result<(Vec<Option<Crossing>>, RgbaImage), ParallaxError> {
    screen.validate()?;
    finite("theta", theta)?;
    if k >= images.views.len() {
        return Err(invalid(
            "view index",
            k,
            "must be below the number of views",
        ));
    }
    let xs = screen.sample_xs(images.params.cylinder.radius);
    let n = xs.len();
    let view = &images.views[k];
    let mut crossings = vec![None; n * screen.height];
    crossings
        .par_chunks_mut(n)
        .enumerate()
        .for_each(|(js, out)| {
            let j = screen.view_row(js, view.height);
            warp_row_into(images, k, j, theta, method, &xs, out);
        });
    let mut img = RgbaImage::new(screen.width, screen.height);
    let inv = 1.0 / screen.supersample.get() as f32;
    for js in 0..screen.height {
        let j = screen.view_row(js, view.height);
        for (s, c) in crossings[js * n..(js + 1) * n].iter().enumerate() {
            if let Some(c) = c {
                let col = shade_crossing(view, j, c, &screen.light) * inv;
                let p = &mut img.pixels[js * screen.width + s / screen.supersample.get()];
                p[0] += col.x;
                p[1] += col.y;
                p[2] += col.z;
                p[3] += inv;
            }
        }
    }
    Ok((crossings, img))
}

fn warp_row_into(
    images: &ParallaxImages,
    k: usize,
    j: usize,
    theta: f64,
    method: WarpMethod,
    xs: &[f64],
    out: &mut [Option<Crossing>],
) {
    match method {
        WarpMethod::Direct => {
            let v = &images.views[k];
            let row = &v.geom[j * v.width..(j + 1) * v.width];
            warp_row_direct_impl(&images.pixel_grid(), row, theta.cos(), theta.sin(), xs, out);
        }
        WarpMethod::Inverse => {
            let (co, si) = (theta.cos(), theta.sin());
            let v = &images.views[k];
            let row = &v.geom[j * v.width..(j + 1) * v.width];
            let grid = images.pixel_grid();
            let r = images.march_radius();
            for (o, &x) in out.iter_mut().zip(xs) {
                let (x1, x2) = cylinder_range(x, co, si, r);
                *o = march_row(&grid, row, x, co, si, x1, x2).hit;
            }
        }
    }
}

/// Renders the object at display angle `alpha` with the default reconstruction
/// ([`Reconstruction::DEFAULT`]; [`render_with`] selects another, [`Reconstruction::ORIGINAL`]
/// the original path): the two bracketing views are warped and combined per ray —
/// undefined in both: the next views out; defined in one: that one, its silhouette brims with
/// partial coverage; in both: the shaded colours blended by angular proportion
/// ([`ParallaxImages::bracketing`]) — and view rows are filtered linearly. Returns
/// premultiplied linear RGBA. When the screen is coarser than the views and `screen.mip` is set,
/// a mip level is warped instead ([`RenderParams::mip_level`]). Cost: `height·width·supersample`
/// rays times the view rows read (1 at native size with one ray per pixel, 2 with 3 rays), two
/// warps each (`O(steps)` inverse, `O(Lx)` per row direct) plus two for rays missed by both
/// views, rows in parallel.
///
/// Errors: a zero screen size, a non-finite angle.
pub fn render(
    images: &ParallaxImages,
    alpha: f64,
    method: WarpMethod,
    screen: &RenderParams,
) -> Result<RgbaImage, ParallaxError> {
    render_with(images, alpha, method, screen, &Reconstruction::DEFAULT)
}

/// [`render_with`] under [`Reconstruction::ORIGINAL`]: the two bracketing views warped and
/// combined per ray — undefined in both: nothing; defined in one: that one; in both: the shaded
/// colours blended by angular proportion — reading the nearest view row.
fn render_original(
    images: &ParallaxImages,
    alpha: f64,
    method: WarpMethod,
    screen: &RenderParams,
) -> Result<RgbaImage, ParallaxError> {
    screen.validate()?;
    let level = screen
        .mip_level(images.params.width, images.params.height)
        .min(images.mip_levels() - 1);
    if level > 0 {
        let coarse = images.level(level)?;
        let screen = RenderParams {
            mip: false,
            ..*screen
        };
        return render_original(&coarse, alpha, method, &screen);
    }
    let [(k1, t1, w1), (k2, t2, w2)] = images.bracketing(alpha)?;
    let xs = screen.sample_xs(images.params.cylinder.radius);
    let n = xs.len();
    let mut img = RgbaImage::new(screen.width, screen.height);
    let inv = 1.0 / screen.supersample.get() as f32;
    img.pixels
        .par_chunks_mut(screen.width)
        .enumerate()
        .for_each(|(js, px)| {
            let mut a = vec![None; n];
            let mut b = vec![None; n];
            let (v1, v2) = (&images.views[k1], &images.views[k2]);
            let j1 = screen.view_row(js, v1.height);
            let j2 = screen.view_row(js, v2.height);
            warp_row_into(images, k1, j1, t1, method, &xs, &mut a);
            warp_row_into(images, k2, j2, t2, method, &xs, &mut b);
            for s in 0..n {
                let col = match (&a[s], &b[s]) {
                    (None, None) => continue,
                    (Some(c), None) => shade_crossing(v1, j1, c, &screen.light),
                    (None, Some(c)) => shade_crossing(v2, j2, c, &screen.light),
                    (Some(c), Some(d)) => {
                        w1 as f32 * shade_crossing(v1, j1, c, &screen.light)
                            + w2 as f32 * shade_crossing(v2, j2, d, &screen.light)
                    }
                } * inv;
                let p = &mut px[s / screen.supersample.get()];
                p[0] += col.x;
                p[1] += col.y;
                p[2] += col.z;
                p[3] += inv;
            }
        });
    Ok(img)
}

/// [`render`] with the options of `rec` (see [`Reconstruction`]). Per ray the two bracketing views are combined as in [`render`], except
/// that with `depth_test` two crossings further apart in depth than the continuity threshold keep
/// the nearer, and with `fallback` a ray missed by both reads the next two views out. With
/// [`RowFilter::Linear`] each screen row combines several view rows by their weights. Returns
/// premultiplied linear RGBA. Cost: as [`render`] times the rows read per screen row, plus two
/// marches per missing ray with `fallback`.
///
/// Errors: a zero screen size, a non-finite angle.
pub fn render_with(
    images: &ParallaxImages,
    alpha: f64,
    method: WarpMethod,
    screen: &RenderParams,
    rec: &Reconstruction,
) -> Result<RgbaImage, ParallaxError> {
    if *rec == Reconstruction::ORIGINAL {
        return render_original(images, alpha, method, screen);
    }
    screen.validate()?;
    let level = screen
        .mip_level(images.params.width, images.params.height)
        .min(images.mip_levels() - 1);
    if level > 0 {
        let coarse = images.level(level)?;
        let screen = RenderParams {
            mip: false,
            ..*screen
        };
        return render_with(&coarse, alpha, method, &screen, rec);
    }
    let pair = images.bracketing(alpha)?;
    let outer = images.outer(&pair);
    let tol = images.params.continuity_texels * images.pixel_grid().pitch_x();
    let xs = screen.sample_xs(images.params.cylinder.radius);
    let n = xs.len();
    let vh = images.params.height;
    let mut img = RgbaImage::new(screen.width, screen.height);
    let inv = 1.0 / screen.supersample.get() as f32;
    img.pixels
        .par_chunks_mut(screen.width)
        .enumerate()
        .for_each(|(js, px)| {
            let mut hits = [vec![None; n], vec![None; n]];
            let mut far = [vec![None; n], vec![None; n]];
            for (j, wr) in screen.row_weights(js, vh, rec.rows) {
                for (slot, &(k, theta, _)) in pair.iter().enumerate() {
                    warp_row_into(images, k, j, theta, method, &xs, &mut hits[slot]);
                }
                if rec.fallback {
                    for (slot, &(k, theta, _)) in outer.iter().enumerate() {
                        warp_row_into(images, k, j, theta, method, &xs, &mut far[slot]);
                    }
                }
                let wall = |s: usize| {
                    // Beyond the row's stored geometry every wall scan misses.
                    (xs[s].abs() <= images.row_radius(j))
                        .then(|| hole_fill(images, &pair, j, xs[s], &screen.light).0)
                        .flatten()
                };
                let pick = |views: &[(usize, f64, f64); 2], s: usize, c: [&Option<Crossing>; 2]| {
                    combine(images, views, j, xs[s], c, rec, &screen.light, tol)
                };
                for s in 0..n {
                    let col = pick(&pair, s, [&hits[0][s], &hits[1][s]])
                        .or_else(|| {
                            rec.fallback
                                .then(|| {
                                    let c = [&far[0][s], &far[1][s]];
                                    pick(&outer, s, c).map(|col| {
                                        col * fallback_coverage(
                                            images, &pair, &outer, j, xs[s], c, rec,
                                        )
                                    })
                                })
                                .flatten()
                        })
                        .or_else(|| rec.fill_holes.then(|| wall(s)).flatten());
                    let Some(col) = col else { continue };
                    let col = col * (inv * wr);
                    let p = &mut px[s / screen.supersample.get()];
                    p[0] += col.x;
                    p[1] += col.y;
                    p[2] += col.z;
                    p[3] += col.w;
                }
            }
        });
    Ok(img)
}

/// Combines the crossings `c` of the ray `x` in the two views `views` (`(k, θ, weight)`) on view
/// row `j` into premultiplied RGBA (`None` where both miss), by the options of `rec`: one view
/// hits: its colour, with the brim coverage under `soft_edges`, or a miss where `carve_brims`
/// finds its brim sticking out past the other view's outline; both hit: blended by weight,
/// nearer only under `depth_test` when their depths differ by more than `tol`, with brim
/// coverage under `soft_edges` when both are on brims, else opaque.
#[allow(clippy::too_many_arguments)]
pub(crate) fn combine(
    images: &ParallaxImages,
    views: &[(usize, f64, f64); 2],
    j: usize,
    x: f64,
    c: [&Option<Crossing>; 2],
    rec: &Reconstruction,
    light: &Light,
    tol: f64,
) -> Option<Vec4> {
    // Shaded colour and coverage of a crossing.
    let shade = |slot: usize, c: &Crossing| {
        let view = &images.views[views[slot].0];
        let col = shade_crossing(view, j, c, light);
        let cov = if rec.soft_edges {
            edge_coverage(view, j, c)
        } else {
            1.0
        };
        (col, cov)
    };
    let soft = |(col, cov): (Vec3, f32)| {
        let col = col * cov;
        Vec4::new(col.x, col.y, col.z, cov)
    };
    let (w1, w2) = (views[0].2 as f32, views[1].2 as f32);
    if rec.carve_brims {
        let cut = match c {
            [Some(a), None] => sticks_out(images, views, 0, j, x, a),
            [None, Some(b)] => sticks_out(images, views, 1, j, x, b),
            _ => false,
        };
        if cut {
            return None;
        }
    }
    match c {
        [None, None] => None,
        [Some(a), None] => Some(soft(shade(0, a))),
        [None, Some(b)] => Some(soft(shade(1, b))),
        [Some(a), Some(b)] => Some(if rec.depth_test && (a.z_e - b.z_e).abs() > tol {
            if a.z_e > b.z_e {
                soft(shade(0, a))
            } else {
                soft(shade(1, b))
            }
        } else if rec.soft_edges
            && on_brim(&images.views[views[0].0], j, a)
            && on_brim(&images.views[views[1].0], j, b)
        {
            w1 * soft(shade(0, a)) + w2 * soft(shade(1, b))
        } else {
            let col = w1 * shade(0, a).0 + w2 * shade(1, b).0;
            Vec4::new(col.x, col.y, col.z, 1.0)
        }),
    }
}

/// [`render_bounded_with`] under the default reconstruction: the image and the march steps of
/// the two bracketing views (fallback marches not included).
///
/// Errors: bounds built for other images, a non-finite angle.
pub fn render_bounded(
    images: &ParallaxImages,
    bounds: &super::Bounds,
    alpha: f64,
    light: &Light,
) -> Result<(RgbaImage, u64), ParallaxError> {
    let r = render_bounded_with(images, bounds, alpha, light, &Reconstruction::DEFAULT)?;
    Ok((r.image, r.steps))
}

/// What [`render_bounded_with`] returns.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundedRender {
    /// Premultiplied linear RGBA at the views' size.
    pub image: RgbaImage,
    /// March steps of the two bracketing views over all pixels, within the stored bounds (what
    /// the step tables count).
    pub steps: u64,
    /// March steps of the fallback views (two marches from the cylinder per pixel missed by
    /// both bracketing views; 0 without [`Reconstruction::fallback`]).
    pub fallback_steps: u64,
    /// Steps of the hole-filling wall scans (two scans from the cylinder per pixel every view
    /// missed, each counting the cells it tests and its fetches of the other view; 0 without
    /// [`Reconstruction::fill_holes`]).
    pub hole_steps: u64,
}

/// Renders at the views' own resolution (one ray per pixel centre, where stored bounds are valid)
/// with the march ranges of `bounds` for the two bracketing views: the shader's path. Pixels are
/// combined by `rec` as in [`render_with`] (the row filter reads the one row at this size); the
/// fallback views are marched from the cylinder. With bounds of any kind the image is the same
/// as [`render_with`]'s at native resolution with one ray per pixel; only the steps differ.
///
/// Errors: bounds built for other images, a non-finite angle.
pub fn render_bounded_with(
    images: &ParallaxImages,
    bounds: &super::Bounds,
    alpha: f64,
    light: &Light,
    rec: &Reconstruction,
) -> Result<BoundedRender, ParallaxError> {
    bounds.check(images)?;
    let p = &images.params;
    let (w, h) = (p.width, p.height);
    let grid = images.pixel_grid();
    let pair = images.bracketing(alpha)?;
    let outer = images.outer(&pair);
    let tol = p.continuity_texels * grid.pitch_x();
    let r = images.march_radius();
    let mut image = RgbaImage::new(w, h);
    let (steps, fallback_steps, hole_steps) = image
        .pixels
        .par_chunks_mut(w)
        .enumerate()
        .map(|(j, px)| {
            let (mut steps, mut fsteps, mut hsteps) = (0u64, 0u64, 0u64);
            for (i, pixel) in px.iter_mut().enumerate() {
                let x = grid.x_at(i as f64 + 0.5);
                let mut hits = [None, None];
                for (slot, &(k, theta, _)) in pair.iter().enumerate() {
                    let (co, si) = (theta.cos(), theta.sin());
                    let view = &images.views[k];
                    let row = &view.geom[j * w..(j + 1) * w];
                    if let Some((x1, x2)) = bounds.range_cs(k, j * w + i, x, co, si) {
                        let m = march_row(&grid, row, x, co, si, x1, x2);
                        steps += u64::from(m.steps);
                        hits[slot] = m.hit;
                    }
                }
                let mut col = combine(images, &pair, j, x, [&hits[0], &hits[1]], rec, light, tol);
                // Beyond the row's stored geometry every march and wall scan misses.
                let reachable = x.abs() <= images.row_radius(j);
                if col.is_none() && rec.fallback && reachable {
                    let mut far = [None, None];
                    for (slot, &(k, theta, _)) in outer.iter().enumerate() {
                        let (co, si) = (theta.cos(), theta.sin());
                        let view = &images.views[k];
                        let row = &view.geom[j * w..(j + 1) * w];
                        // The row's stored geometry lies in the disc of its row radius.
                        let (x1, x2) = cylinder_range(x, co, si, images.row_radius(j).min(r));
                        let m = march_row(&grid, row, x, co, si, x1, x2);
                        fsteps += u64::from(m.steps);
                        far[slot] = m.hit;
                    }
                    let c = [&far[0], &far[1]];
                    col = combine(images, &outer, j, x, c, rec, light, tol)
                        .map(|col| col * fallback_coverage(images, &pair, &outer, j, x, c, rec));
                }
                if col.is_none() && rec.fill_holes && reachable {
                    let (c, n) = hole_fill(images, &pair, j, x, light);
                    col = c;
                    hsteps += n;
                }
                if let Some(c) = col {
                    *pixel = c.to_array();
                }
            }
            (steps, fsteps, hsteps)
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    Ok(BoundedRender {
        image,
        steps,
        fallback_steps,
        hole_steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parallax::ParallaxParams;
    use altrep_data_gen::scene_shape;

    /// The skip of [`render_bounded_with`] and [`render_with`] is exact: beyond a row's stored
    /// geometry ([`ParallaxImages::row_radius`]) no view's march over the whole cylinder chord
    /// hits and no wall scan finds a wall, at every pixel and for display angles all around.
    #[test]
    fn beyond_the_row_radius_every_march_and_wall_scan_misses() {
        for name in ["tree", "truck", "chair"] {
            let shape = scene_shape(name).unwrap();
            let params = ParallaxParams {
                views: 8,
                width: 48,
                height: 48,
                ..ParallaxParams::default()
            };
            let images = ParallaxImages::capture(&shape, &params).unwrap();
            let grid = images.pixel_grid();
            let r = images.march_radius();
            let (w, h) = (params.width, params.height);
            let mut skipped = 0usize;
            for a in 0..24 {
                let alpha = (a as f64 + 0.29) * std::f64::consts::TAU / 24.0;
                let pair = images.bracketing(alpha).unwrap();
                for j in 0..h {
                    for i in 0..w {
                        let x = grid.x_at(i as f64 + 0.5);
                        if x.abs() <= images.row_radius(j) {
                            continue;
                        }
                        skipped += 1;
                        for k in 0..params.views {
                            let theta = alpha - k as f64 * std::f64::consts::TAU / 8.0;
                            let (co, si) = (theta.cos(), theta.sin());
                            let row = &images.views[k].geom[j * w..(j + 1) * w];
                            let (x1, x2) = cylinder_range(x, co, si, r);
                            let m = march_row(&grid, row, x, co, si, x1, x2);
                            assert!(m.hit.is_none(), "{name} α {alpha} view {k} ({i}, {j})");
                        }
                        let (col, _) = hole_fill(&images, &pair, j, x, &Light::default());
                        assert!(col.is_none(), "{name} α {alpha} ({i}, {j}): a wall");
                    }
                }
            }
            assert!(skipped > 0, "{name}: no pixel beyond the row radius");
        }
    }
}
