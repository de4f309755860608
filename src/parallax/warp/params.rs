//! The parameters of a render: its screen, and how the two warped views become a pixel.

use altrep_data_gen::Supersample;
use altrep_data_gen::{Light, PixelGrid};

use super::ParallaxImages;
use crate::parallax::{ParallaxError, invalid};

/// Which warping algorithm renders the views.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarpMethod {
    /// Per pixel, march the ray through the height field (the shader's algorithm), bounded by the
    /// cylinder.
    Inverse,
    /// Per row, draw the front-facing pieces back to front (painter's order).
    Direct,
}

/// Screen of a render: the impostor quad `[−R, R] × [0, H]` sampled by `width × height` pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderParams {
    /// Screen columns.
    pub width: usize,
    /// Screen rows; each screen row reads the nearest view row (rows warp independently).
    pub height: usize,
    /// Rays per pixel edge ([`Supersample`]), taken across the pixel only: rows warp
    /// independently, so the `k` rows of a pixel's `k × k` rays would read the same view row.
    pub supersample: Supersample,
    /// The light shading albedo and normals.
    pub light: Light,
    /// Warp a mip level when the screen is coarser than the views: level
    /// `round(log2(max(Lx/width, Ly/height)))` of [`ParallaxImages::level`] (nearest level, as
    /// `GL_LINEAR_MIPMAP_NEAREST`). With `false`, level 0 is point-sampled. Measured at 128² → 32²
    /// against a 4×4-supersampled truth: +0.6 dB on fine detail (tree), −1 to −3 dB on coarse
    /// detail (truck, building, pear), where box-filtered depth mixes front and back surfaces;
    /// the coarse level also needs about 4× fewer march steps.
    pub mip: bool,
}

impl RenderParams {
    /// A screen of the views' own size, one ray per pixel (texel = pixel).
    pub fn native(images: &ParallaxImages) -> Self {
        Self {
            width: images.params.width,
            height: images.params.height,
            supersample: Supersample::ONE,
            light: Light::default(),
            mip: true,
        }
    }

    /// The mip level this screen reads from views of `width × height` texels.
    pub fn mip_level(&self, width: usize, height: usize) -> usize {
        if !self.mip {
            return 0;
        }
        let ratio = (width as f64 / self.width as f64).max(height as f64 / self.height as f64);
        ratio.log2().round().max(0.0) as usize
    }

    pub(super) fn validate(&self) -> Result<(), ParallaxError> {
        if self.width == 0 || self.height == 0 {
            return Err(invalid(
                "render size",
                format!("{}×{} ×{}", self.width, self.height, self.supersample),
                "width and height must be at least 1",
            ));
        }
        Ok(())
    }

    /// Screen abscissae of the rays of one row, ascending.
    pub(crate) fn sample_xs(&self, r: f64) -> Vec<f64> {
        let grid = PixelGrid {
            width: self.width,
            height: self.height,
            cylinder: altrep_data_gen::BoundingCylinder {
                radius: r,
                height: 1.0,
            },
        };
        let k = self.supersample.get() as f64;
        (0..self.width * self.supersample.get())
            .map(|s| {
                grid.x_at(
                    (s / self.supersample.get()) as f64
                        + ((s % self.supersample.get()) as f64 + 0.5) / k,
                )
            })
            .collect()
    }

    /// View rows read by screen row `js` and their weights (summing to at most 1): the nearest
    /// row with weight 1, or with [`RowFilter::Linear`] the two rows around each of `supersample`
    /// sub-rows spread evenly down the pixel (linear interpolation between row centres; rows
    /// outside the view count as transparent). At `supersample = 1` and the views' own size both
    /// read the one row. Cost: at most `supersample + 1` rows.
    pub fn row_weights(
        &self,
        js: usize,
        view_height: usize,
        filter: RowFilter,
    ) -> Vec<(usize, f32)> {
        match filter {
            RowFilter::Nearest => vec![(self.view_row(js, view_height), 1.0)],
            RowFilter::Linear => {
                let k = self.supersample.get() as f64;
                let scale = view_height as f64 / self.height as f64;
                let mut out: Vec<(usize, f32)> = Vec::with_capacity(self.supersample.get() + 1);
                let mut add = |j: i64, w: f64| {
                    if j < 0 || j >= view_height as i64 || w <= 0.0 {
                        return;
                    }
                    let j = j as usize;
                    match out.iter_mut().find(|(r, _)| *r == j) {
                        Some(e) => e.1 += w as f32,
                        None => out.push((j, w as f32)),
                    }
                };
                for q in 0..self.supersample.get() {
                    let v = (js as f64 + (q as f64 + 0.5) / k) * scale - 0.5;
                    let j0 = v.floor();
                    let f = v - j0;
                    add(j0 as i64, (1.0 - f) / k);
                    add(j0 as i64 + 1, f / k);
                }
                out
            }
        }
    }

    /// View row read by screen row `j`.
    pub(crate) fn view_row(&self, j: usize, view_height: usize) -> usize {
        let v = (j as f64 + 0.5) * view_height as f64 / self.height as f64;
        (v.floor() as usize).min(view_height - 1)
    }
}

/// How a screen row reads the view rows (rows warp independently; this is the vertical
/// reconstruction filter).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RowFilter {
    /// Every ray of a pixel reads the nearest view row (the original path).
    Nearest,
    /// Linear interpolation between view rows at `supersample` sub-rows per pixel (see
    /// [`RenderParams::row_weights`]): the shaded, premultiplied results of warping each row are
    /// blended, as a GPU's bilinear fetch blends texels. At native size with 3 sub-rows the
    /// weights of rows `j − 1, j, j + 1` are `1/9, 7/9, 1/9`. Costs one more row warp per pixel
    /// at native size (two with 3 sub-rows); at native size with one ray per pixel it reads
    /// the one row, as `Nearest`. The default.
    #[default]
    Linear,
}

/// How the two warped views are turned into a pixel ([`render_with`](super::render_with)). The default
/// ([`Reconstruction::DEFAULT`], docs/design.md §7.6) filters linearly between view rows, falls
/// back to the next views out where both bracketing views miss, fills holes hidden in both views
/// and softens silhouette brims;
/// [`Reconstruction::ORIGINAL`] is the original path (nearest row, hard coverage, two views).
/// The surface model at silhouettes is a property of the images instead ([`Brim`](crate::parallax::Brim),
/// [`ParallaxImages::with_brim`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Reconstruction {
    /// Vertical filter (default [`RowFilter::Linear`]).
    pub rows: RowFilter,
    /// Where both bracketing views hit at depths `z_e` further apart than the continuity
    /// threshold, keep the nearer crossing instead of blending: both are true surface points,
    /// and the farther one was reached through a gap of its view (a hidden occluder). Default
    /// `false` (always blend by angular proportion; measured ±0.05 dB).
    pub depth_test: bool,
    /// Where both bracketing views miss, march the next views out (`k1 − 1` under `θ1 + Δθ`,
    /// `k2 + 1` under `θ2 − Δθ`, from the cylinder: their stored bounds do not cover these
    /// angles) and combine them the same way: fills points hidden in both bracketing views.
    /// Costs two more marches on every ray that misses (the background included). Default
    /// `true`.
    pub fallback: bool,
    /// Anti-aliased silhouettes: a crossing on an unjoined half piece (a brim), at the fraction
    /// `u ∈ [0, 1)` of the way from the texel centre to the cell boundary, gets coverage
    /// `1 − u/2`, the chance that the point is covered when the outline lies uniformly between
    /// this texel's centre (covered) and the next one (not covered), **where only one view hits
    /// or both hit brims**; where both hit and either is inside its surface, they agree that the
    /// point is covered: full coverage (softening every brim hit measured 0.1–1.8 dB worse, and
    /// softening only single-view hits left N = 16 up to 0.9 dB below N = 8). Colours are
    /// premultiplied. Default `true`.
    pub soft_edges: bool,
    /// Where every view read misses, fill the holes: the nearest point of the ray hidden in
    /// both bracketing views (below the surface of a defined texel in each, where neither can
    /// say it is empty) is taken as surface, opaque, coloured by the surface seen beside it:
    /// in each bracketing view, marched from the cylinder, the first front-facing **wall** (the
    /// step between two defined, unjoined texels, which the surface model otherwise leaves open)
    /// whose crossing the other view also hides; the nearer of the two, coloured by the texel
    /// on the far (lower) side of the step. A ray every point of which one view or the other
    /// sees empty stays empty (a true gap, as through the teapot's handle). Measured at N = 8,
    /// 64²: tree +4.8 dB, beetle +1.0, teapot −0.5. Costs two more marches from the cylinder
    /// (not counted in the step tables) per ray missed by all views read. Default `true`.
    pub fill_holes: bool,
    /// Where one view hits on a brim and the other misses the whole ray, and the point projects
    /// in the missing view just past a texel of its outline (an undefined texel beside a
    /// defined one, `±1`, whose depth is within [`CARVE_DEPTH_TEXELS`](super::CARVE_DEPTH_TEXELS) texel pitches of the
    /// point's): the brim sticks out past that view's outline, so the hit is dropped (a miss;
    /// fallback views and hole filling still apply). A miss beside no such texel (a thin part
    /// that the other view's texels step over) keeps the hit. Measured at 64², 15 shapes, mean
    /// PSNR N = 8 / 16: 31.38 / 31.98 → 31.61 / 32.43 dB; N = 16 is no longer below N = 8 on
    /// the torus and capsule, where brims stuck out (the fandisk stays 0.33 dB below). Costs
    /// three texel reads per ray that one view misses. Default `true`.
    pub carve_brims: bool,
    /// Where a ray missed by both bracketing views is hit by only one fallback view, and that
    /// hit is a brim which, projected into a bracketing view, lies just past that view's outline
    /// (the evidence of `carve_brims`, asked of the bracketing views: an empty texel beside a
    /// defined one at the point's depth), the hit counts at half coverage
    /// ([`DOUBTFUL_FALLBACK_COVERAGE`](super::DOUBTFUL_FALLBACK_COVERAGE)): the nearer views say the point lies just outside the
    /// surface, the farther view says inside, and half is the coverage that minimises the
    /// expected squared error when either is as likely. A thin part that both bracketing views
    /// step over has no outline texel there and keeps its full hit. Measured at 64², 15 shapes,
    /// mean PSNR N = 8 / 16: 31.61 / 32.43 → 31.72 / 32.59 dB; the fandisk's N = 16 goes from
    /// 0.33 dB below N = 8 to 0.09. Costs up to six texel reads per ray hit by one fallback
    /// view only. Default `true`.
    pub soft_fallback: bool,
}

impl Reconstruction {
    /// The default reconstruction (docs/design.md §7.6): linear row filter, fallback views
    /// (doubtful hits at half coverage), soft edges, hole filling, brim carving, no depth test.
    pub const DEFAULT: Reconstruction = Reconstruction {
        rows: RowFilter::Linear,
        depth_test: false,
        fallback: true,
        soft_edges: true,
        fill_holes: true,
        carve_brims: true,
        soft_fallback: true,
    };

    /// The original path: nearest view row, the two bracketing views only, hard coverage.
    /// With [`Brim::Flat`](crate::parallax::Brim::Flat) images it reproduces the original renders exactly.
    pub const ORIGINAL: Reconstruction = Reconstruction {
        rows: RowFilter::Nearest,
        depth_test: false,
        fallback: false,
        soft_edges: false,
        fill_holes: false,
        carve_brims: false,
        soft_fallback: false,
    };
}

impl Default for Reconstruction {
    /// [`Reconstruction::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}
