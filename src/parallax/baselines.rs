//! Two baselines at their own memory cost: blending many views without parallax (the report's
//! alternative, 64 views), and a one-step parallax offset (what common engine impostors do).
//!
//! Both fetch shaded, premultiplied texels with linear filtering along the row (a GPU's bilinear
//! fetch; undefined texels are transparent) and blend the two bracketing views by angular
//! proportion, premultiplied, as engines do.

use altrep_data_gen::{PixelGrid, RgbaImage};
use glam::Vec4;
use rayon::prelude::*;

use super::images::{ParallaxImages, View};
use super::warp::{RenderParams, RowFilter};
use super::{ParallaxError, invalid};

/// Shaded premultiplied texel `(i, j)`; transparent when undefined or outside the view.
fn texel(view: &View, i: i64, j: usize, light: &altrep_data_gen::Light) -> Vec4 {
    if i < 0 || i >= view.width as i64 {
        return Vec4::ZERO;
    }
    let k = j * view.width + i as usize;
    if !view.geom[k].defined {
        return Vec4::ZERO;
    }
    let c = light.shade(view.albedo[k], view.normal[k].normalize_or_zero());
    Vec4::new(c.x, c.y, c.z, 1.0)
}

/// Linear filtering along row `j` at view abscissa `x`.
fn fetch(view: &View, grid: &PixelGrid, x: f64, j: usize, light: &altrep_data_gen::Light) -> Vec4 {
    let u = grid.u_of(x) - 0.5;
    let i0 = u.floor();
    let f = (u - i0) as f32;
    let i0 = i0 as i64;
    texel(view, i0, j, light) * (1.0 - f) + texel(view, i0 + 1, j, light) * f
}

fn render_with(
    images: &ParallaxImages,
    alpha: f64,
    screen: &RenderParams,
    rows: RowFilter,
    offset: impl Fn(&View, usize, f64, f64) -> f64 + Sync,
) -> Result<RgbaImage, ParallaxError> {
    if screen.width == 0 || screen.height == 0 {
        return Err(invalid(
            "render size",
            format!("{}×{}", screen.width, screen.height),
            "must be positive",
        ));
    }
    let [(k1, t1, w1), (k2, t2, w2)] = images.bracketing(alpha)?;
    let grid = images.pixel_grid();
    let xs = screen.sample_xs(images.params.cylinder.radius);
    let inv = 1.0 / screen.supersample.get() as f32;
    let mut img = RgbaImage::new(screen.width, screen.height);
    img.pixels
        .par_chunks_mut(screen.width)
        .enumerate()
        .for_each(|(js, px)| {
            let weights = screen.row_weights(js, images.params.height, rows);
            for (s, &x) in xs.iter().enumerate() {
                let mut acc = Vec4::ZERO;
                for &(j, wr) in &weights {
                    for (k, theta, w) in [(k1, t1, w1), (k2, t2, w2)] {
                        let v = &images.views[k];
                        let xt = offset(v, j, x, theta);
                        acc += fetch(v, &grid, xt, j, &screen.light) * (w as f32 * wr);
                    }
                }
                let p = &mut px[s / screen.supersample.get()];
                for c in 0..4 {
                    p[c] += acc[c] * inv;
                }
            }
        });
    Ok(img)
}

/// Cross-fades the two bracketing views as billboards (no parallax): the texel at the fragment's
/// own abscissa. Meant for many views (the report: 64, 2 MB at 64 × 64 with normals). Cost: two
/// filtered fetches per ray. Errors: a zero screen size.
pub fn render_blend_baseline(
    images: &ParallaxImages,
    alpha: f64,
    screen: &RenderParams,
) -> Result<RgbaImage, ParallaxError> {
    render_with(images, alpha, screen, RowFilter::Nearest, |_, _, x, _| x)
}

/// [`render_blend_baseline`] with a vertical filter ([`RowFilter::Linear`]: bilinear fetches, the
/// same vertical reconstruction as the warp's option), so that the comparison with a filtered warp
/// is fair. Errors: a zero screen size.
pub fn render_blend_baseline_with(
    images: &ParallaxImages,
    alpha: f64,
    screen: &RenderParams,
    rows: RowFilter,
) -> Result<RgbaImage, ParallaxError> {
    render_with(images, alpha, screen, rows, |_, _, x, _| x)
}

/// One-step parallax offset per view: fetch the depth `z` of the nearest texel at the fragment's
/// abscissa `X` (0, the axis plane, where undefined), assume the surface is there, and read the
/// colour at `x_t = (X − z·sin θ)/cos θ` (from `x_e = x_t cos θ + z_t sin θ`); then cross-fade.
/// Same memory as the parallax views. Cost: three fetches per ray and view. Errors: a zero
/// screen size.
pub fn render_offset_baseline(
    images: &ParallaxImages,
    alpha: f64,
    screen: &RenderParams,
) -> Result<RgbaImage, ParallaxError> {
    let grid = images.pixel_grid();
    render_with(
        images,
        alpha,
        screen,
        RowFilter::Nearest,
        |v, j, x, theta| {
            let i = (grid.u_of(x).floor() as i64).clamp(0, v.width as i64 - 1) as usize;
            let z = v.depth(i, j).unwrap_or(0.0);
            let (si, co) = theta.sin_cos();
            (x - z * si) / co.max(1e-6)
        },
    )
}
