//! The stored representation: `N` quantised views with their height fields.

use std::f64::consts::TAU;
use std::time::{Duration, Instant};

use altrep_data_gen::{
    BoundingCylinder, PixelGrid, Projection, SampleGrid, Shape, ViewParams, capture_view,
    linear_to_srgb, srgb_to_linear,
};
use glam::Vec3;
use rayon::prelude::*;

use super::{ParallaxError, finite, invalid};
use crate::mip::{Pyramid, PyramidParams, Texture};

/// Parameters of an image-with-parallax representation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParallaxParams {
    /// Number of views `N` (≥ 3, so that `Δθ = 2π/N < π`); default 8.
    pub views: usize,
    /// Columns `Lx` of each view; default 64.
    pub width: usize,
    /// Rows `Ly` of each view; default 64.
    pub height: usize,
    /// The bounding cylinder the views span.
    pub cylinder: BoundingCylinder,
    /// Bits of the stored depth (8 or 16). Default 8: colour RGBA8 + normal-and-depth RGBA8, the
    /// report's 8 bytes per texel.
    pub depth_bits: u32,
    /// Continuity threshold, in texel widths `δx`: neighbouring texels whose depths differ by more
    /// than `continuity_texels·δx` are not joined by a surface. Default 3 (see the module docs).
    pub continuity_texels: f64,
}

impl Default for ParallaxParams {
    fn default() -> Self {
        Self {
            views: 8,
            width: 64,
            height: 64,
            cylinder: BoundingCylinder::default(),
            depth_bits: 8,
            continuity_texels: 3.0,
        }
    }
}

impl ParallaxParams {
    /// The numbers of views accepted everywhere (library, manifest, command line): at least 3 so
    /// that `Δθ = 2π/N < π`, at most 1024.
    pub const VIEW_COUNTS: std::ops::RangeInclusive<usize> = 3..=1024;

    /// Checks every field; errors name the offending one.
    pub fn validate(&self) -> Result<(), ParallaxError> {
        if !Self::VIEW_COUNTS.contains(&self.views) {
            return Err(invalid(
                "views",
                self.views,
                "must be in 3..=1024 (Δθ = 2π/N < π)",
            ));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(invalid(
                "view size",
                format!("{}×{}", self.width, self.height),
                "must be in 1..=16384",
            ));
        }
        if self.depth_bits != 8 && self.depth_bits != 16 {
            return Err(invalid("depth_bits", self.depth_bits, "must be 8 or 16"));
        }
        if self.continuity_texels.is_nan() || self.continuity_texels <= 0.0 {
            return Err(invalid(
                "continuity_texels",
                self.continuity_texels,
                "must be positive (infinity allowed)",
            ));
        }
        self.cylinder.validate()?;
        Ok(())
    }

    /// `Δθ = 2π/N`: the largest |θ| under which a view is seen.
    pub fn delta_theta(&self) -> f64 {
        TAU / self.views as f64
    }

    /// Angle of view `k`, `2πk/N`.
    pub fn view_angle(&self, k: usize) -> f64 {
        TAU * k as f64 / self.views as f64
    }

    /// Stored bytes per texel: colour RGBA8 (4) + normal RGB8 (3) + depth (1 or 2).
    pub fn bytes_per_texel(&self) -> usize {
        7 + self.depth_bits as usize / 8
    }
}

/// How the surface ends on a side of a texel that is not joined to its neighbour (a silhouette or
/// a depth jump): the half piece from the texel centre to the cell boundary. A representation
/// option ([`ParallaxImages::with_brim`]); it adds no stored data (it is derived from the stored
/// depth and normal) and changes the march, the direct warp and the bounds together, since all of
/// them read the same pieces. The default is [`Brim::DEFAULT`] (tangent, max slope 4, measured
/// 1.1 dB better than flat on the teapot at N = 8); [`Brim::Flat`] is the original
/// model.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Brim {
    /// Flat at the texel's depth (`z_l = z_r = z`): the original model. Under a turn `θ` the
    /// outer corner of a silhouette brim moves by `z·sin θ` while the true outline barely moves,
    /// so brims stick out up to half a texel on the side the view turns toward.
    Flat,
    /// Along the tangent of the stored normal, never rising toward the camera: the end depth is
    /// `z − (δx/2)·min(max_slope, max(0, ∓n_x/n_z))` (view-frame normal, `−` for the left end and
    /// `+` for the right one, so that the end drops away from the camera toward the outside). A tangent segment leaves a smooth outline
    /// only to second order, so silhouettes stay put when the view turns; a brim steeper than
    /// `1/tan θ` is seen from behind and skipped. At θ = 0 the piece still starts at the texel
    /// centre, so a view seen head-on still reproduces its capture.
    Tangent {
        /// Largest `|dz/dx|` of a brim (≥ 0; 0 is [`Brim::Flat`]).
        max_slope: f64,
    },
}

impl Brim {
    /// The default surface model: tangent brims with max slope 4 (a brim drops at most two
    /// texel pitches over its half texel).
    pub const DEFAULT: Brim = Brim::Tangent { max_slope: 4.0 };
}

impl Default for Brim {
    /// [`Brim::DEFAULT`].
    fn default() -> Self {
        Brim::DEFAULT
    }
}

/// Geometry of one texel of a view's height field (world units).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TexelGeom {
    /// Depth at the texel centre (`z_t`, toward the camera).
    pub z: f64,
    /// Depth at the left cell boundary `x_i − δx/2`: the mean with the left neighbour when joined,
    /// else `z`.
    pub zl: f64,
    /// Depth at the right cell boundary `x_i + δx/2`.
    pub zr: f64,
    /// Whether the ray hit something here.
    pub defined: bool,
    /// Joined to the left neighbour.
    pub link_l: bool,
    /// Joined to the right neighbour.
    pub link_r: bool,
}

/// One stored view: quantised albedo, normal and depth per texel, row-major, row 0 at the top.
#[derive(Clone, Debug)]
pub struct View {
    /// Capture angle `α_k` (radians).
    pub angle: f64,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    pub(crate) geom: Vec<TexelGeom>,
    /// Linear albedo decoded from sRGB8 (meaningless where undefined).
    pub(crate) albedo: Vec<Vec3>,
    /// Normal decoded from RGB8 (not renormalised; meaningless where undefined).
    pub(crate) normal: Vec<Vec3>,
}

impl View {
    fn index(&self, i: usize, j: usize) -> Option<usize> {
        (i < self.width && j < self.height).then_some(j * self.width + i)
    }

    /// Whether texel `(i, j)` is defined (`false` outside the view).
    pub fn defined(&self, i: usize, j: usize) -> bool {
        self.index(i, j).is_some_and(|k| self.geom[k].defined)
    }

    /// Stored depth of texel `(i, j)` in world units (toward the camera), `None` if undefined or
    /// outside the view.
    pub fn depth(&self, i: usize, j: usize) -> Option<f64> {
        let g = &self.geom[self.index(i, j)?];
        g.defined.then_some(g.z)
    }

    /// Stored (decoded) albedo and normal of texel `(i, j)`, `None` if undefined or outside the
    /// view.
    pub fn attributes(&self, i: usize, j: usize) -> Option<(Vec3, Vec3)> {
        let k = self.index(i, j)?;
        self.geom[k]
            .defined
            .then(|| (self.albedo[k], self.normal[k]))
    }

    /// Share of defined texels.
    pub fn coverage(&self) -> f64 {
        self.geom.iter().filter(|g| g.defined).count() as f64 / self.geom.len().max(1) as f64
    }

    /// The view as stored, shaded by `light`: premultiplied linear RGBA, alpha 1 where defined.
    pub fn shade(&self, light: &altrep_data_gen::Light) -> altrep_data_gen::RgbaImage {
        let pixels = (0..self.geom.len())
            .map(|k| {
                if self.geom[k].defined {
                    let c = light.shade(self.albedo[k], self.normal[k].normalize_or_zero());
                    [c.x, c.y, c.z, 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect();
        altrep_data_gen::RgbaImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}

/// `N` views with parallax of one object (docs/design.md §7): the representation a display draws.
#[derive(Clone, Debug)]
pub struct ParallaxImages {
    /// The parameters the views were built with.
    pub params: ParallaxParams,
    /// The views, view `k` at `2πk/N`.
    pub views: Vec<View>,
    /// Wall time of the capture (zero when built from given grids).
    pub capture_time: Duration,
    /// See [`Self::march_radius`].
    march_radius: f64,
    /// See [`Self::row_radius`].
    row_radius: Vec<f64>,
    /// See [`Self::pyramids`].
    pyramids: Vec<Pyramid>,
    /// See [`Self::brim`].
    brim: Brim,
}

/// Joins neighbouring defined texels of every row whose depths differ by at most `threshold`
/// (world units) and sets the depths at the cell boundaries.
fn link_rows(geom: &mut [TexelGeom], width: usize, threshold: f64) {
    for row in geom.chunks_mut(width) {
        for i in 0..width {
            let linked = i + 1 < width
                && row[i].defined
                && row[i + 1].defined
                && (row[i].z - row[i + 1].z).abs() <= threshold;
            row[i].link_r = linked;
            if i + 1 < width {
                row[i + 1].link_l = linked;
            }
        }
        for i in 0..width {
            let z = row[i].z;
            row[i].zl = if row[i].link_l {
                0.5 * (row[i - 1].z + z)
            } else {
                z
            };
            row[i].zr = if row[i].link_r {
                0.5 * (z + row[i + 1].z)
            } else {
                z
            };
        }
    }
}

/// Sets the depths of the unjoined ends of every texel of `view` by `brim` (the joined ends keep
/// the mean with their neighbour); `pitch` is `δx`.
fn apply_brim(view: &mut View, pitch: f64, brim: Brim) {
    let max_slope = match brim {
        Brim::Flat => 0.0,
        Brim::Tangent { max_slope } => max_slope,
    };
    let (sa, ca) = view.angle.sin_cos();
    for (g, n) in view.geom.iter_mut().zip(&view.normal) {
        if !g.defined {
            continue;
        }
        // View-frame normal: n·right(α) and n·d(α), right = (sin α, 0, −cos α), d = (cos α, 0, sin α).
        let nx = f64::from(n.x) * sa - f64::from(n.z) * ca;
        let nz = f64::from(n.x) * ca + f64::from(n.z) * sa;
        // Height-field slope dz/dx = −n_x/n_z. Going right the surface drops by −slope per unit,
        // going left by +slope; a normal facing away or edge-on drops both ends the most.
        let (down_l, down_r) = if nz > 1e-6 && nx.is_finite() {
            (-nx / nz, nx / nz)
        } else {
            (max_slope, max_slope)
        };
        let drop = |s: f64| 0.5 * pitch * s.clamp(0.0, max_slope);
        if !g.link_l {
            g.zl = g.z - drop(down_l);
        }
        if !g.link_r {
            g.zr = g.z - drop(down_r);
        }
    }
}

/// The `bits`-bit unorm code of `x ∈ [0, 1]` (clamped), rounded to nearest.
pub(crate) fn unorm_code(x: f64, bits: u32) -> u32 {
    let levels = ((1u64 << bits) - 1) as f64;
    (x.clamp(0.0, 1.0) * levels).round() as u32
}

/// The 8-bit code of one normal component `c ∈ [−1, 1]`: `round((c + 1)/2 · 255)`, as the
/// views store it.
pub fn normal_code(c: f32) -> u8 {
    unorm_code((f64::from(c) + 1.0) * 0.5, 8) as u8
}

/// The value `code / (2^bits − 1)` of a unorm code.
pub(crate) fn code_value(code: u32, bits: u32) -> f64 {
    f64::from(code) / ((1u64 << bits) - 1) as f64
}

/// The integer codes of one stored view, as files hold them (row-major, row 0 at the top):
/// albedo in sRGB8, normal `(n + 1)/2` in 8 bits per component, depth `(z/R + 1)/2` in
/// `depth_bits` bits, and whether the texel is defined (codes of undefined texels are 0).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ViewCodes {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Whether each texel is defined.
    pub defined: Vec<bool>,
    /// sRGB8 albedo.
    pub albedo: Vec<[u8; 3]>,
    /// Normal codes.
    pub normal: Vec<[u8; 3]>,
    /// Depth codes.
    pub depth: Vec<u16>,
}

impl ViewCodes {
    /// A view with no defined texel.
    pub fn empty(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            defined: vec![false; n],
            albedo: vec![[0; 3]; n],
            normal: vec![[0; 3]; n],
            depth: vec![0; n],
        }
    }
}

impl ParallaxImages {
    /// Captures the `N` views of `shape` with data-gen's ray caster (`N·Lx·Ly` rays, views in
    /// parallel) and quantises them. Errors: invalid parameters, capture errors.
    pub fn capture(shape: &dyn Shape, params: &ParallaxParams) -> Result<Self, ParallaxError> {
        params.validate()?;
        let t0 = Instant::now();
        let grids = (0..params.views)
            .into_par_iter()
            .map(|k| {
                capture_view(
                    shape,
                    &ViewParams {
                        angle: params.view_angle(k),
                        width: params.width,
                        height: params.height,
                        cylinder: params.cylinder,
                    },
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut images = Self::from_grids(&grids, params)?;
        images.capture_time = t0.elapsed();
        Ok(images)
    }

    /// Builds the representation from captured grids (view `k` must be an orthographic capture
    /// at `2πk/N` of `width × height` over `params.cylinder`). Quantises albedo to sRGB8, normals
    /// to 8 bits per component and depth to `depth_bits`, then joins neighbours by the continuity
    /// threshold. Cost: linear in the texels.
    ///
    /// Errors: invalid parameters, wrong number of grids, a grid of another size, angle, cylinder
    /// or projection, a sample count that does not match the size, a non-finite albedo or normal,
    /// a non-finite depth or a depth outside `[−1, 1]`.
    pub fn from_grids(
        grids: &[SampleGrid],
        params: &ParallaxParams,
    ) -> Result<Self, ParallaxError> {
        params.validate()?;
        if grids.len() != params.views {
            return Err(invalid(
                "number of grids",
                grids.len(),
                "must equal params.views",
            ));
        }
        let mut views = Vec::with_capacity(params.views);
        for (k, g) in grids.iter().enumerate() {
            let bad = |reason: String| ParallaxError::InconsistentView { view: k, reason };
            if (g.width, g.height) != (params.width, params.height) {
                return Err(bad(format!(
                    "size {}×{}, expected {}×{}",
                    g.width, g.height, params.width, params.height
                )));
            }
            if g.cylinder != params.cylinder {
                return Err(bad("captured over another bounding cylinder".into()));
            }
            match g.projection {
                Projection::Orthographic { angle }
                    if (angle - params.view_angle(k)).abs() <= 1e-9 => {}
                other => {
                    return Err(bad(format!(
                        "projection {other:?}, expected orthographic at {}",
                        params.view_angle(k)
                    )));
                }
            }
            let n = g.width * g.height;
            if g.samples.len() != n {
                return Err(bad(format!("{} samples for {n} texels", g.samples.len())));
            }
            let mut codes = ViewCodes::empty(g.width, g.height);
            for (idx, s) in g.samples.iter().enumerate() {
                let Some(s) = s else { continue };
                let d = f64::from(s.depth);
                if !d.is_finite() || d.abs() > 1.0 + 1e-6 {
                    return Err(bad(format!("texel {idx} has depth {d} outside [-1, 1]")));
                }
                if !(s.albedo.is_finite() && s.normal.is_finite()) {
                    return Err(bad(format!(
                        "texel {idx} has a non-finite albedo or normal"
                    )));
                }
                let q = |c: f32| unorm_code(f64::from(linear_to_srgb(c.clamp(0.0, 1.0))), 8) as u8;
                let qn = normal_code;
                codes.defined[idx] = true;
                codes.depth[idx] = unorm_code((d + 1.0) * 0.5, params.depth_bits) as u16;
                codes.albedo[idx] = [q(s.albedo.x), q(s.albedo.y), q(s.albedo.z)];
                codes.normal[idx] = [qn(s.normal.x), qn(s.normal.y), qn(s.normal.z)];
            }
            views.push(codes);
        }
        Self::from_codes(params, &views)
    }

    /// Builds the representation from the integer codes of its views, as files store them (see
    /// [`ViewCodes`]); [`Self::from_grids`] quantises and then calls this, so a representation
    /// written as codes and read back is identical. Cost: linear in the texels, plus the mip
    /// pyramids. Errors: invalid parameters, a wrong number or size of views, a depth code above
    /// `2^depth_bits − 1`.
    pub fn from_codes(params: &ParallaxParams, codes: &[ViewCodes]) -> Result<Self, ParallaxError> {
        params.validate()?;
        if codes.len() != params.views {
            return Err(invalid(
                "number of views",
                codes.len(),
                "must equal params.views",
            ));
        }
        let grid = PixelGrid {
            width: params.width,
            height: params.height,
            cylinder: params.cylinder,
        };
        let r = params.cylinder.radius;
        let threshold = params.continuity_texels * grid.pitch_x();
        let levels = (1u32 << params.depth_bits) - 1;
        let mut views = Vec::with_capacity(params.views);
        for (k, c) in codes.iter().enumerate() {
            let n = params.width * params.height;
            if (c.width, c.height) != (params.width, params.height)
                || [
                    c.defined.len(),
                    c.albedo.len(),
                    c.normal.len(),
                    c.depth.len(),
                ]
                .iter()
                .any(|&l| l != n)
            {
                return Err(ParallaxError::InconsistentView {
                    view: k,
                    reason: format!(
                        "codes of size {}×{}, expected {}×{}",
                        c.width, c.height, params.width, params.height
                    ),
                });
            }
            if let Some(idx) = c.depth.iter().position(|&d| u32::from(d) > levels) {
                return Err(ParallaxError::InconsistentView {
                    view: k,
                    reason: format!("texel {idx}: depth code above {levels}"),
                });
            }
            let mut geom = vec![TexelGeom::default(); n];
            let mut albedo = vec![Vec3::ZERO; n];
            let mut normal = vec![Vec3::ZERO; n];
            for idx in (0..n).filter(|&i| c.defined[i]) {
                let a = c.albedo[idx].map(|q| srgb_to_linear(code_value(q.into(), 8) as f32));
                let nm = c.normal[idx].map(|q| (code_value(q.into(), 8) * 2.0 - 1.0) as f32);
                geom[idx].defined = true;
                geom[idx].z = (code_value(c.depth[idx].into(), params.depth_bits) * 2.0 - 1.0) * r;
                albedo[idx] = Vec3::from_array(a);
                normal[idx] = Vec3::from_array(nm);
            }
            link_rows(&mut geom, params.width, threshold);
            views.push(View {
                angle: params.view_angle(k),
                width: params.width,
                height: params.height,
                geom,
                albedo,
                normal,
            });
        }
        Self::assemble(*params, views, Brim::DEFAULT)
    }

    /// The integer codes of every view, as a file stores them (the inverse of
    /// [`Self::from_codes`] for a representation built by [`Self::from_grids`] or
    /// [`Self::from_codes`]). Cost: linear in the texels.
    pub fn codes(&self) -> Vec<ViewCodes> {
        let r = self.params.cylinder.radius;
        let bits = self.params.depth_bits;
        self.views
            .iter()
            .map(|v| {
                let mut c = ViewCodes::empty(v.width, v.height);
                for (idx, g) in v.geom.iter().enumerate().filter(|(_, g)| g.defined) {
                    c.defined[idx] = true;
                    c.depth[idx] = unorm_code((g.z / r + 1.0) * 0.5, bits) as u16;
                    c.albedo[idx] = v.albedo[idx]
                        .to_array()
                        .map(|x| unorm_code(f64::from(linear_to_srgb(x.clamp(0.0, 1.0))), 8) as u8);
                    c.normal[idx] = v.normal[idx].to_array().map(normal_code);
                }
                c
            })
            .collect()
    }

    /// Finishes a representation from its views (rows already joined): the brims, the march
    /// radius and one mip pyramid per view.
    fn assemble(
        params: ParallaxParams,
        mut views: Vec<View>,
        brim: Brim,
    ) -> Result<Self, ParallaxError> {
        let pitch = 2.0 * params.cylinder.radius / params.width as f64;
        for v in &mut views {
            apply_brim(v, pitch, brim);
        }
        let r = params.cylinder.radius;
        let pyramids = views
            .iter()
            .map(|v| {
                let mut data = Vec::with_capacity(v.geom.len() * 8);
                for (k, g) in v.geom.iter().enumerate() {
                    if g.defined {
                        let (a, n) = (v.albedo[k], v.normal[k]);
                        data.extend([a.x, a.y, a.z, 1.0, n.x, n.y, n.z, (g.z / r) as f32]);
                    } else {
                        data.extend([0.0; 8]);
                    }
                }
                let tex = Texture::new(v.width, v.height, 8, data)?;
                Ok(Pyramid::build(tex, PyramidParams::default())?)
            })
            .collect::<Result<Vec<_>, ParallaxError>>()?;
        let mut images = Self {
            params,
            views,
            capture_time: Duration::ZERO,
            march_radius: r,
            row_radius: Vec::new(),
            pyramids,
            brim,
        };
        images.march_radius = images.compute_march_radius();
        images.row_radius = images.compute_row_radii();
        Ok(images)
    }

    /// One mip pyramid per view ([`crate::mip`], box filter, clamped edges), 8 channels per
    /// texel, all premultiplied by coverage: albedo (3, linear), coverage, normal (3), depth / R.
    /// Level 0 holds the stored views exactly.
    pub fn pyramids(&self) -> &[Pyramid] {
        &self.pyramids
    }

    /// Number of mip levels (down to 1 × 1).
    pub fn mip_levels(&self) -> usize {
        self.pyramids.first().map_or(1, |p| p.levels().len())
    }

    /// The representation at mip level `level`: views of the level's size whose texels are
    /// defined where the filtered coverage is at least ½, with albedo, normal and depth divided
    /// by the coverage (un-premultiplied) and neighbours joined by the same continuity threshold
    /// in texels of that level. A display warps this when the impostor covers fewer pixels than
    /// the views have texels (fewer, filtered texels: less aliasing and fewer steps). Level 0 is
    /// a copy. Cost: linear in the level's texels, plus its own pyramid.
    ///
    /// Errors: `level` beyond the last level.
    pub fn level(&self, level: usize) -> Result<ParallaxImages, ParallaxError> {
        if level >= self.mip_levels() {
            return Err(invalid(
                "mip level",
                level,
                "must be below the number of levels",
            ));
        }
        if level == 0 {
            return Ok(self.clone());
        }
        let r = self.params.cylinder.radius;
        let first = &self.pyramids[0].levels()[level];
        let params = ParallaxParams {
            width: first.width,
            height: first.height,
            ..self.params
        };
        let grid = PixelGrid {
            width: params.width,
            height: params.height,
            cylinder: params.cylinder,
        };
        let threshold = params.continuity_texels * grid.pitch_x();
        let views = self
            .pyramids
            .iter()
            .zip(&self.views)
            .map(|(p, v)| {
                let t = &p.levels()[level];
                let n = t.width * t.height;
                let mut geom = vec![TexelGeom::default(); n];
                let mut albedo = vec![Vec3::ZERO; n];
                let mut normal = vec![Vec3::ZERO; n];
                for k in 0..n {
                    let c = &t.data[k * 8..k * 8 + 8];
                    if c[3] >= 0.5 {
                        let inv = 1.0 / c[3];
                        geom[k].defined = true;
                        geom[k].z = f64::from(c[7] * inv) * r;
                        albedo[k] = Vec3::new(c[0], c[1], c[2]) * inv;
                        normal[k] = Vec3::new(c[4], c[5], c[6]) * inv;
                    }
                }
                link_rows(&mut geom, t.width, threshold);
                View {
                    angle: v.angle,
                    width: t.width,
                    height: t.height,
                    geom,
                    albedo,
                    normal,
                }
            })
            .collect();
        Self::assemble(params, views, self.brim)
    }

    /// The same stored views with another surface model at unjoined texel ends (see [`Brim`]);
    /// the stored data, their codes and the mip pyramids are unchanged, the march radius is
    /// recomputed. Bounds must be built for the result ([`super::build_bounds`]) since they bound
    /// the crossings of its surface. Cost: linear in the texels.
    ///
    /// Errors: a negative or non-finite `max_slope`.
    pub fn with_brim(&self, brim: Brim) -> Result<ParallaxImages, ParallaxError> {
        if let Brim::Tangent { max_slope } = brim
            && !(max_slope.is_finite() && max_slope >= 0.0)
        {
            return Err(invalid(
                "brim max_slope",
                max_slope,
                "must be finite and non-negative",
            ));
        }
        let mut out = self.clone();
        let pitch = out.pixel_grid().pitch_x();
        let threshold = out.params.continuity_texels * pitch;
        for v in &mut out.views {
            link_rows(&mut v.geom, v.width, threshold);
            apply_brim(v, pitch, brim);
        }
        out.brim = brim;
        out.march_radius = out.compute_march_radius();
        out.row_radius = out.compute_row_radii();
        Ok(out)
    }

    /// The surface model at unjoined texel ends ([`Brim::DEFAULT`] unless set by
    /// [`Self::with_brim`]).
    pub fn brim(&self) -> Brim {
        self.brim
    }

    /// Bytes of the stored views with their mip pyramids: every level at the bytes per texel of
    /// level 0 (about 4/3 of [`Self::bytes`]).
    pub fn bytes_with_mips(&self) -> usize {
        let texels: usize = self
            .pyramids
            .iter()
            .flat_map(|p| p.levels().iter().map(|l| l.width * l.height))
            .sum();
        texels * self.params.bytes_per_texel()
    }

    /// Radius `R' ≥ R` of the cylinder the march starts from: the largest distance to the axis of
    /// any point of the stored height fields. Half-texel flat ends at the silhouette and depth
    /// quantisation can poke slightly out of the capture cylinder; using `R'` keeps the
    /// "no precomputation" bounds exact.
    pub fn march_radius(&self) -> f64 {
        self.march_radius
    }

    fn compute_march_radius(&self) -> f64 {
        let r2 = self
            .row_squared_radii()
            .into_iter()
            .fold(self.params.cylinder.radius.powi(2), f64::max);
        r2.sqrt() * (1.0 + 1e-12)
    }

    /// Per view row, the largest squared distance to the axis of any piece end point of any
    /// view (0 where no texel of the row is defined).
    fn row_squared_radii(&self) -> Vec<f64> {
        let grid = self.pixel_grid();
        let w = self.params.width;
        (0..self.params.height)
            .map(|j| {
                let mut r2 = 0.0f64;
                for v in &self.views {
                    let row = v.geom.get(j * w..(j + 1) * w).unwrap_or(&[]);
                    for (i, g) in row.iter().enumerate() {
                        if !g.defined {
                            continue;
                        }
                        let (xl, xc, xr) = (
                            grid.x_at(i as f64),
                            grid.x_at(i as f64 + 0.5),
                            grid.x_at(i as f64 + 1.0),
                        );
                        for (x, z) in [(xl, g.zl), (xc, g.z), (xr, g.zr)] {
                            r2 = r2.max(x * x + z * z);
                        }
                    }
                }
                r2
            })
            .collect()
    }

    /// Radius of the stored geometry on view row `j`: the largest distance to the axis of any
    /// piece end point on row `j` of any view (pieces are segments, so they lie in that disc),
    /// `0` where no view defines a texel on the row, `∞` for a row outside the views. A ray of
    /// that row whose offset `|x|` exceeds it meets no piece and no wall of any view: marches
    /// and wall scans there can be skipped without changing the picture. Cost: none (computed
    /// with the views).
    pub fn row_radius(&self, j: usize) -> f64 {
        self.row_radius.get(j).copied().unwrap_or(f64::INFINITY)
    }

    fn compute_row_radii(&self) -> Vec<f64> {
        self.row_squared_radii()
            .into_iter()
            .map(|r2| r2.sqrt() * (1.0 + 1e-12))
            .collect()
    }

    /// The texel grid of every view (pitch, centres).
    pub fn pixel_grid(&self) -> PixelGrid {
        PixelGrid {
            width: self.params.width,
            height: self.params.height,
            cylinder: self.params.cylinder,
        }
    }

    /// The two views used at display angle `alpha`: `[(k1, θ1, w1), (k2, θ2, w2)]` with
    /// `θ1 = α − α_k1 ∈ [0, Δθ)`, `θ2 = θ1 − Δθ`, and blending weights `w1 = 1 − θ1/Δθ`,
    /// `w2 = θ1/Δθ` (the report's angular proportion). Errors: a non-finite angle.
    pub fn bracketing(&self, alpha: f64) -> Result<[(usize, f64, f64); 2], ParallaxError> {
        finite("display angle", alpha)?;
        Ok(self.bracket(alpha))
    }

    /// The next views out of [`Self::bracketing`], which [`super::Reconstruction::fallback`]
    /// reads where both bracketing views miss: `[(k1 − 1, θ1 + Δθ, w), (k2 + 1, θ2 − Δθ, w')]`
    /// (indices modulo N), weighted by angular proportion between them. Errors: a non-finite
    /// angle.
    pub fn fallback_views(&self, alpha: f64) -> Result<[(usize, f64, f64); 2], ParallaxError> {
        Ok(self.outer(&self.bracketing(alpha)?))
    }

    /// [`Self::fallback_views`] of a bracketing pair.
    pub(crate) fn outer(&self, pair: &[(usize, f64, f64); 2]) -> [(usize, f64, f64); 2] {
        let nv = self.params.views;
        let dt = self.params.delta_theta();
        let (t1, t2) = (pair[0].1, pair[1].1);
        let (d0, d1) = (t1 + dt, dt - t2);
        [
            ((pair[0].0 + nv - 1) % nv, t1 + dt, d1 / (d0 + d1)),
            ((pair[1].0 + 1) % nv, t2 - dt, d0 / (d0 + d1)),
        ]
    }

    /// [`Self::bracketing`] for a finite angle.
    pub(crate) fn bracket(&self, alpha: f64) -> [(usize, f64, f64); 2] {
        let n = self.params.views;
        let dt = self.params.delta_theta();
        let a = alpha.rem_euclid(TAU);
        let k1 = ((a / dt).floor() as usize).min(n - 1);
        let theta1 = (a - self.params.view_angle(k1)).clamp(0.0, dt);
        let beta = theta1 / dt;
        [(k1, theta1, 1.0 - beta), ((k1 + 1) % n, theta1 - dt, beta)]
    }

    /// Bytes of the stored views (level 0, as the report counts): `N·Lx·Ly·(7 + depth_bits/8)`.
    pub fn bytes(&self) -> usize {
        self.params.views * self.params.width * self.params.height * self.params.bytes_per_texel()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use altrep_data_gen::scene_shape;

    #[test]
    fn bracketing_covers_the_circle() {
        let p = ParallaxParams {
            views: 8,
            width: 8,
            height: 4,
            ..Default::default()
        };
        let img = ParallaxImages::capture(&scene_shape("sphere").unwrap(), &p).unwrap();
        for m in 0..97 {
            let a = TAU * m as f64 / 97.0 - 3.0;
            let [(k1, t1, w1), (k2, t2, w2)] = img.bracketing(a).unwrap();
            assert_eq!(k2, (k1 + 1) % 8);
            assert!((0.0..=p.delta_theta()).contains(&t1) && t2 <= 0.0);
            assert!((w1 + w2 - 1.0).abs() < 1e-12);
            let back = p.view_angle(k1) + t1;
            assert!(((back - a).rem_euclid(TAU)).min((a - back).rem_euclid(TAU)) < 1e-9);
        }
    }

    #[test]
    fn rejects_bad_input() {
        let p = ParallaxParams {
            views: 2,
            ..Default::default()
        };
        assert!(matches!(
            p.validate(),
            Err(ParallaxError::InvalidParameter { .. })
        ));
        let p = ParallaxParams {
            depth_bits: 12,
            ..Default::default()
        };
        assert!(p.validate().is_err());
        let p = ParallaxParams {
            continuity_texels: f64::NAN,
            ..Default::default()
        };
        assert!(p.validate().is_err());
        let ok = ParallaxParams {
            views: 4,
            width: 4,
            height: 4,
            ..Default::default()
        };
        assert!(matches!(
            ParallaxImages::from_grids(&[], &ok),
            Err(ParallaxError::InvalidParameter { .. })
        ));
    }
}
