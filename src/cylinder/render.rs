//! CPU renderers of a cylindrical texture at a camera angle: the reference triangle mesh, direct
//! warping and inverse warping, all drawing into the same supersampled image as the ground truth.
//!
//! Image: `W × H` pixels over the cylinder's silhouette `[−R, R] × [0, H]` (data-gen's
//! [`PixelGrid`] convention), each pixel the average of `k × k` sub-samples at the same stratified
//! positions as [`altrep_data_gen::render_truth`]; premultiplied linear RGBA, alpha = coverage.
//! Every sub-sample row is drawn independently (rayon over rows); a sub-sample's colour is
//! `Light::shade(albedo, normal)` of the interpolated texel.

use altrep_data_gen::Supersample;
use altrep_data_gen::{Light, PixelGrid, RgbaImage};
use glam::Vec3;
use rayon::prelude::*;

use super::CylinderError;
use super::frame::{column_angle, depth, row_coordinate, screen_x};
use super::texture::{CylindricalTexture, Texel};
use super::warp::{DrawOrder, Fragment, RadiusModel, SliceView};

/// Camera and image of a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderRenderParams {
    /// Camera angle `α` (radians): the view looks along `−d(α)`.
    pub angle: f64,
    /// Image width in pixels (spans `[−R, R]`).
    pub width: usize,
    /// Image height in pixels (spans `[0, H]`).
    pub height: usize,
    /// Sub-samples per pixel edge ([`Supersample`]: `k × k` per pixel).
    pub supersample: Supersample,
    /// The light every sub-sample is shaded with.
    pub light: Light,
}

impl Default for CylinderRenderParams {
    /// 64 × 64 pixels, 3 × 3 sub-samples, angle 0, the default light.
    fn default() -> Self {
        Self {
            angle: 0.0,
            width: 64,
            height: 64,
            supersample: Supersample::of(3),
            light: Light::default(),
        }
    }
}

impl CylinderRenderParams {
    /// Errors on a zero size or a non-finite angle.
    pub fn validate(&self) -> Result<(), CylinderError> {
        for (n, what) in [
            (self.width, "image width"),
            (self.height, "image height"),
            (self.supersample.get(), "supersampling factor"),
        ] {
            if n == 0 {
                return Err(CylinderError::ZeroSize { what });
            }
        }
        if !self.angle.is_finite() {
            return Err(CylinderError::InvalidParameter {
                name: "camera angle",
                value: self.angle.to_string(),
                reason: "must be finite",
            });
        }
        Ok(())
    }
}

/// A rendered image with what each sub-sample saw and what it cost.
#[derive(Clone, Debug)]
pub struct CylinderRender {
    /// The image, premultiplied linear RGBA, alpha = coverage of the sub-samples.
    pub image: RgbaImage,
    /// Sub-samples per row (`W·k`).
    pub sub_width: usize,
    /// Sub-sample rows (`H·k`).
    pub sub_height: usize,
    /// Per sub-sample (row-major, row 0 at the top) the visible point, `None` where empty.
    pub fragments: Vec<Option<Fragment>>,
    /// Per sub-sample the column its fetched offset named, after refinement (fitted renderers
    /// only; empty for the exact ones), for offset errors.
    pub named: Vec<Option<f64>>,
    /// Total sector tests of inverse warping or of hybrid refinement (0 for other renderers).
    pub steps: u64,
    /// Total sub-sample writes (direct warping's overdraw; the mesh's depth-test passes).
    pub writes: u64,
}

impl CylinderRender {
    /// Mean sector tests per sub-sample (over all sub-samples of the image).
    pub fn mean_steps(&self) -> f64 {
        self.steps as f64 / self.fragments.len().max(1) as f64
    }
}

/// The exact renderers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ExactMethod {
    /// The reference: the triangle mesh of the samples, rasterised with a depth test and
    /// back-face culling; triangles with an undefined sample or radii of both signs are skipped.
    /// The first and last rows are extended half a row up and down by vertical "skirt"
    /// triangles, as the warpers clamp to edge.
    Mesh,
    /// Direct warping of each slice (per half, sector by sector) in the given order.
    Direct(DrawOrder, RadiusModel),
    /// Inverse warping per sub-sample: march the sectors front to back from the first one the
    /// ray can reach; steps are counted.
    Inverse(RadiusModel),
}

impl ExactMethod {
    /// A short name for tables: `mesh`, `direct-btf`, `direct-ftb`, `direct-simple`, `inverse`,
    /// `inverse-simple`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Mesh => "mesh",
            Self::Direct(DrawOrder::BackToFront, RadiusModel::General) => "direct-btf",
            Self::Direct(DrawOrder::FrontToBack, RadiusModel::General) => "direct-ftb",
            Self::Direct(DrawOrder::BackToFront, RadiusModel::Simple) => "direct-simple",
            Self::Direct(DrawOrder::FrontToBack, RadiusModel::Simple) => "direct-ftb-simple",
            Self::Inverse(RadiusModel::General) => "inverse",
            Self::Inverse(RadiusModel::Simple) => "inverse-simple",
        }
    }
}

/// Renders `texture` with an exact method. Cost: mesh `O(k·H·L)` triangle-scanline tests plus
/// the covered sub-samples; direct `O(k·H·(L + k·W))`; inverse `O(k²·W·H)` times the mean steps
/// (up to `L/2 + 1` per sub-sample).
pub fn render_exact(
    texture: &CylindricalTexture,
    method: ExactMethod,
    params: &CylinderRenderParams,
) -> Result<CylinderRender, CylinderError> {
    match method {
        ExactMethod::Mesh => render_mesh(texture, params),
        ExactMethod::Direct(order, model) => render_rows(texture, params, false, |row, out, _| {
            let slice = texture.slice_at_height(row.y);
            let view = SliceView::new(&slice, params.angle, model);
            (0, view.direct(row.xs, out, order))
        }),
        ExactMethod::Inverse(model) => render_rows(texture, params, false, |row, out, _| {
            let slice = texture.slice_at_height(row.y);
            let view = SliceView::new(&slice, params.angle, model);
            let mut steps = 0u64;
            for (x, o) in row.xs.iter().zip(out.iter_mut()) {
                let (f, n) = view.inverse(*x);
                *o = f;
                steps += u64::from(n);
            }
            (steps, row.xs.len() as u64)
        }),
    }
}

/// One row of sub-samples handed to a row renderer.
pub(crate) struct SubRow<'a> {
    /// Height of the row (world units).
    pub y: f64,
    /// Abscissae of the sub-samples, units of `R`, increasing.
    pub xs: &'a [f64],
}

/// Runs `per_row` on every sub-sample row in parallel, then shades and averages. `per_row`
/// fills the row's fragments (and named columns when `track_named`, else it gets an empty
/// slice) and returns `(steps, writes)`.
pub(crate) fn render_rows(
    texture: &CylindricalTexture,
    params: &CylinderRenderParams,
    track_named: bool,
    per_row: impl Fn(&SubRow, &mut [Option<Fragment>], &mut [Option<f64>]) -> (u64, u64) + Sync,
) -> Result<CylinderRender, CylinderError> {
    params.validate()?;
    let k = params.supersample.get();
    let sub = PixelGrid {
        width: params.width * k,
        height: params.height * k,
        cylinder: texture.cylinder(),
    };
    let radius = sub.cylinder.radius;
    let xs: Vec<f64> = (0..sub.width)
        .map(|i| sub.x_at(i as f64 + 0.5) / radius)
        .collect();
    let mut fragments = vec![None; sub.width * sub.height];
    let mut named = vec![None; if track_named { fragments.len() } else { 0 }];
    let mut named_rows: Vec<&mut [Option<f64>]> = if track_named {
        named.chunks_mut(sub.width).collect()
    } else {
        (0..sub.height).map(|_| Default::default()).collect()
    };
    let (steps, writes) = fragments
        .par_chunks_mut(sub.width)
        .zip(named_rows.par_iter_mut())
        .enumerate()
        .map(|(j, (out, named))| {
            let row = SubRow {
                y: sub.y_at(j as f64 + 0.5),
                xs: &xs,
            };
            per_row(&row, out, named)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let image = shade_and_average(&fragments, sub.width, params);
    Ok(CylinderRender {
        image,
        sub_width: sub.width,
        sub_height: sub.height,
        fragments,
        named,
        steps,
        writes,
    })
}

/// Shades each fragment and averages `k × k` blocks into premultiplied RGBA.
fn shade_and_average(
    frags: &[Option<Fragment>],
    sub_width: usize,
    p: &CylinderRenderParams,
) -> RgbaImage {
    let k = p.supersample.get();
    let inv = 1.0 / (k * k) as f32;
    let mut pixels = vec![[0.0f32; 4]; p.width * p.height];
    pixels
        .par_chunks_mut(p.width)
        .enumerate()
        .for_each(|(j, row)| {
            for (i, px) in row.iter_mut().enumerate() {
                let mut acc = [0.0f32; 4];
                for b in 0..k {
                    for a in 0..k {
                        if let Some(f) = &frags[(j * k + b) * sub_width + i * k + a] {
                            let c = p.light.shade(f.albedo, f.normal.normalize_or_zero());
                            acc[0] += c.x;
                            acc[1] += c.y;
                            acc[2] += c.z;
                            acc[3] += 1.0;
                        }
                    }
                }
                *px = acc.map(|v| v * inv);
            }
        });
    RgbaImage {
        width: p.width,
        height: p.height,
        pixels,
    }
}

/// A projected vertex of the reference mesh.
#[derive(Clone, Copy)]
struct Vertex {
    /// Screen abscissa (units of `R`).
    x: f64,
    /// Height (world units).
    y: f64,
    /// Depth toward the camera.
    z: f64,
    texel: Texel,
}

/// The reference: a scanline rasteriser of the sample mesh (see [`ExactMethod::Mesh`]).
fn render_mesh(
    texture: &CylindricalTexture,
    params: &CylinderRenderParams,
) -> Result<CylinderRender, CylinderError> {
    let (l, rows) = (texture.columns(), texture.rows());
    let cyl = texture.cylinder();
    let dy = cyl.height / rows as f64;
    // Vertex rows: a top skirt at y = H, the texture rows, a bottom skirt at y = 0.
    let vertex_rows = rows + 2;
    let row_height = |k: usize| match k {
        0 => cyl.height,
        k if k == rows + 1 => 0.0,
        k => cyl.height - (k as f64 - 0.5) * dy,
    };
    let vertices: Vec<Option<Vertex>> = (0..vertex_rows * l)
        .into_par_iter()
        .map(|n| {
            let (k, c) = (n / l, n % l);
            let j = k.saturating_sub(1).min(rows - 1);
            texture.get(c, j).map(|t| {
                let (r, beta) = (f64::from(t.radius), column_angle(c as f64, l));
                Vertex {
                    x: screen_x(r, beta, params.angle),
                    y: row_height(k),
                    z: depth(r, beta, params.angle),
                    texel: *t,
                }
            })
        })
        .collect();
    render_rows(texture, params, false, |row, out, _| {
        // The strip (between vertex rows s and s + 1) that holds this height.
        let v = row_coordinate(row.y, &cyl, rows);
        let s = ((v.floor() + 1.0).max(0.0) as usize).min(rows);
        let mut writes = 0;
        for c in 0..l {
            let c1 = (c + 1) % l;
            let at = |k: usize, c: usize| vertices[k * l + c].as_ref();
            // Columns as numbers for interpolation: c and c + 1 (unwrapped).
            let (u0, u1) = (c as f64, c as f64 + 1.0);
            let quads = [
                [(at(s, c), u0), (at(s, c1), u1), (at(s + 1, c), u0)],
                [(at(s, c1), u1), (at(s + 1, c1), u1), (at(s + 1, c), u0)],
            ];
            for tri in quads {
                let [(Some(a), ua), (Some(b), ub), (Some(d), ud)] = tri else {
                    continue;
                };
                if !(a.texel.same_side(&b.texel) && a.texel.same_side(&d.texel)) {
                    continue;
                }
                writes += raster_triangle([(a, ua), (b, ub), (d, ud)], row, out, l as f64);
            }
        }
        (0, writes)
    })
}

/// Edge function: twice the signed area of `(a, b, p)` in the screen plane.
#[inline]
fn edge_fn(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> f64 {
    (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
}

/// Draws the intersection of one triangle with the sub-sample row (depth test, back-face
/// culling); returns the number of writes.
fn raster_triangle(
    tri: [(&Vertex, f64); 3],
    row: &SubRow,
    out: &mut [Option<Fragment>],
    columns: f64,
) -> u64 {
    let p = tri.map(|(v, _)| (v.x, v.y));
    let area = edge_fn(p[0], p[1], p[2]);
    // Front-facing: σ·area > 0, σ = −1 for inner (negative-radius) triangles; this is the
    // warpers' σ·(x_a − x_b) > 0 for the triangle's horizontal edges.
    let sigma = if tri[0].0.texel.is_negative() {
        -1.0
    } else {
        1.0
    };
    if sigma * area <= 1e-18 {
        return 0;
    }
    let y = row.y;
    let (ymin, ymax) = p
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(q.1), hi.max(q.1))
        });
    if y < ymin || y > ymax {
        return 0;
    }
    // Span of the triangle on this row: intersections of the line with its edges.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for e in 0..3 {
        let (a, b) = (p[e], p[(e + 1) % 3]);
        if (a.1 - y) * (b.1 - y) > 0.0 {
            continue;
        }
        if a.1 == b.1 {
            lo = lo.min(a.0.min(b.0));
            hi = hi.max(a.0.max(b.0));
        } else {
            let x = a.0 + (y - a.1) / (b.1 - a.1) * (b.0 - a.0);
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    let i0 = row.xs.partition_point(|&x| x < lo);
    let i1 = row.xs.partition_point(|&x| x <= hi);
    let mut writes = 0;
    for (x, o) in row.xs[i0..i1].iter().zip(&mut out[i0..i1]) {
        let q = (*x, y);
        let w = [
            edge_fn(p[1], p[2], q),
            edge_fn(p[2], p[0], q),
            edge_fn(p[0], p[1], q),
        ]
        .map(|e| (e / area).max(0.0));
        let sum = w[0] + w[1] + w[2];
        let w = w.map(|e| e / sum);
        let z = w[0] * tri[0].0.z + w[1] * tri[1].0.z + w[2] * tri[2].0.z;
        if o.is_some_and(|f| f.depth >= z) {
            continue;
        }
        let wf = w.map(|e| e as f32);
        let mix = |f: fn(&Texel) -> Vec3| {
            f(&tri[0].0.texel) * wf[0] + f(&tri[1].0.texel) * wf[1] + f(&tri[2].0.texel) * wf[2]
        };
        let u = w[0] * tri[0].1 + w[1] * tri[1].1 + w[2] * tri[2].1;
        *o = Some(Fragment {
            column: u.rem_euclid(columns),
            depth: z,
            albedo: mix(|t| t.albedo),
            normal: mix(|t| t.normal),
        });
        writes += 1;
    }
    writes
}
