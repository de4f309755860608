//! The representation: per texel albedo, normal and signed radius (or undefined), and the slices
//! (rows, interpolated vertically) that every renderer draws.

use altrep_data_gen::{
    BoundingCylinder, CylinderParams, Light, Projection, RgbaImage, SampleGrid, Shape,
    capture_cylinder,
};
use glam::Vec3;

use super::CylinderError;
use super::frame::row_coordinate;

/// One defined texel of a cylindrical texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texel {
    /// Linear RGB albedo.
    pub albedo: Vec3,
    /// Surface normal, object frame (unit in captured texels; interpolated texels are not
    /// renormalised, shading does it).
    pub normal: Vec3,
    /// Signed radius `r` in units of `R`, in `[−1, 1]`: the point is `r·R·d(α_c)` at the row's
    /// height (positive: on the side of the column's camera; negative: beyond the axis).
    pub radius: f32,
}

impl Texel {
    /// Linear interpolation `(1 − t)·self + t·other` of every channel.
    #[inline]
    pub fn lerp(&self, other: &Texel, t: f32) -> Texel {
        Texel {
            albedo: self.albedo.lerp(other.albedo, t),
            normal: self.normal.lerp(other.normal, t),
            radius: self.radius + (other.radius - self.radius) * t,
        }
    }

    /// Whether the radius is negative (the sample lies beyond the axis). Zero counts as positive.
    #[inline]
    pub fn is_negative(&self) -> bool {
        self.radius < 0.0
    }

    /// Whether two texels can be joined by an edge or a triangle: radii of one sign.
    #[inline]
    pub fn same_side(&self, other: &Texel) -> bool {
        self.is_negative() == other.is_negative()
    }
}

/// A cylindrical texture (docs/design.md §6): `L` columns (angles `α_c = 2πc/L`) × `Ly` rows
/// (heights `y_j = H − (j + ½)H/Ly`), each texel an optional [`Texel`] (`None` where the capture
/// ray missed). Row-major, row 0 at the top: `texels[j·L + c]`.
///
/// Storage as the source counts it: two RGBA8 textures (albedo + coverage alpha; normal + radius),
/// 8 bytes per texel — 128 KiB at the default 256 × 64. [`CylindricalTexture::quantized_rgba8`]
/// gives the texture as those bytes would restore it, so the cost of 8-bit storage is measured.
#[derive(Clone, Debug, PartialEq)]
pub struct CylindricalTexture {
    columns: usize,
    rows: usize,
    cylinder: BoundingCylinder,
    texels: Vec<Option<Texel>>,
}

/// The capture grid of `prefilter × prefilter` samples per texel of `params`. Errors: a bad
/// column count or prefilter factor.
fn fine_params(params: &CylinderParams, prefilter: usize) -> Result<CylinderParams, CylinderError> {
    check_columns(params.columns)?;
    check_prefilter(prefilter)?;
    Ok(CylinderParams {
        columns: params.columns * prefilter,
        rows: params.rows * prefilter,
        cylinder: params.cylinder,
    })
}

impl CylindricalTexture {
    /// Builds the texture from a cylindrical capture of data-gen ([`capture_cylinder`]).
    ///
    /// Errors: a grid that is not [`Projection::Cylindrical`], fewer than 4 or an odd number of
    /// columns (the inner edge of a sector comes from the opposite columns `c + L/2`), no row, a
    /// sample count that does not match, a non-finite sample. Cost: one pass over the samples.
    pub fn from_samples(grid: &SampleGrid) -> Result<Self, CylinderError> {
        if grid.projection != Projection::Cylindrical {
            return Err(CylinderError::NotCylindrical {
                projection: grid.projection,
            });
        }
        check_columns(grid.width)?;
        if grid.height == 0 {
            return Err(CylinderError::ZeroSize {
                what: "texture rows",
            });
        }
        grid.cylinder.validate()?;
        if grid.samples.len() != grid.width * grid.height {
            return Err(CylinderError::InvalidParameter {
                name: "sample grid",
                value: format!("{} samples", grid.samples.len()),
                reason: "must hold width × height samples",
            });
        }
        let mut texels = Vec::with_capacity(grid.samples.len());
        for (index, s) in grid.samples.iter().enumerate() {
            let texel = match s {
                None => None,
                Some(s) => {
                    let finite = s.albedo.is_finite()
                        && s.normal.is_finite()
                        && s.depth.is_finite()
                        && s.depth.abs() <= 1.0 + 1e-4;
                    if !finite {
                        return Err(CylinderError::BadSample {
                            column: index % grid.width,
                            row: index / grid.width,
                        });
                    }
                    Some(Texel {
                        albedo: s.albedo,
                        normal: s.normal,
                        radius: s.depth.clamp(-1.0, 1.0),
                    })
                }
            };
            texels.push(texel);
        }
        Ok(Self {
            columns: grid.width,
            rows: grid.height,
            cylinder: grid.cylinder,
            texels,
        })
    }

    /// Captures `shape` with data-gen and builds the texture, with the albedo prefiltered over
    /// `prefilter × prefilter` rays per texel (see [`Self::from_oversampled`]; `1` point-samples).
    /// Cost: `columns × rows × prefilter²` rays.
    ///
    /// Errors: as [`Self::from_samples`], and an even or zero `prefilter`.
    pub fn capture(
        shape: &dyn Shape,
        params: &CylinderParams,
        prefilter: usize,
    ) -> Result<Self, CylinderError> {
        Self::from_oversampled(
            &capture_cylinder(shape, &fine_params(params, prefilter)?)?,
            prefilter,
        )
    }

    /// [`Self::capture`] with lighting baked in sample by sample before the prefilter: each fine
    /// sample's albedo is shaded by `light` at its own normal, and the texel holds the box
    /// average of the shaded colours with the light's direction as its normal (as
    /// [`Self::baked`] leaves it). Shading after averaging would mix albedo across normals: a
    /// texel straddling an edge, or an unlit or emitting surface (whose albedo is folded by its
    /// normal, docs/real-assets.md), would take the centre's shading for all. Cost: as
    /// [`Self::capture`].
    ///
    /// Errors: as [`Self::capture`].
    pub fn capture_baked(
        shape: &dyn Shape,
        params: &CylinderParams,
        prefilter: usize,
        light: &Light,
    ) -> Result<Self, CylinderError> {
        let fine = capture_cylinder(shape, &fine_params(params, prefilter)?)?;
        Self::from_samples(&fine)?
            .baked(light)
            .downsampled(prefilter)
    }

    /// Builds an `L × Ly` texture from a cylindrical capture of `(s·L) × (s·Ly)` samples, `s` odd
    /// (the source "acquires the texture at a larger size, then downsamples it").
    ///
    /// The geometry (radius, normal, definition) of texel `(c, j)` is the centre sample
    /// `(s·c, s·j + (s − 1)/2)`, which lies exactly on column `c`'s ray at row `j`'s height, so the
    /// warps stay exact. Its albedo is the box average over the `s × s` samples centred there
    /// (columns `s·c − (s−1)/2 … s·c + (s−1)/2`, wrapping) that are defined with a radius of the
    /// centre's sign: a prefilter over one texel, without which a colour edge that falls on a
    /// column is shifted by up to half a texel. Cost: one pass over the fine samples.
    pub fn from_oversampled(grid: &SampleGrid, prefilter: usize) -> Result<Self, CylinderError> {
        check_prefilter(prefilter)?;
        Self::from_samples(grid)?.downsampled(prefilter)
    }

    /// The texture of `prefilter × prefilter` fine texels per texel ([`Self::from_oversampled`]).
    fn downsampled(self, prefilter: usize) -> Result<Self, CylinderError> {
        let fine = self;
        let s = prefilter;
        if !fine.columns.is_multiple_of(2 * s) || !fine.rows.is_multiple_of(s) {
            return Err(CylinderError::InvalidParameter {
                name: "oversampled grid",
                value: format!("{} × {} for factor {s}", fine.columns, fine.rows),
                reason: "the size must be the factor times an even column count and a row count",
            });
        }
        let (columns, rows) = (fine.columns / s, fine.rows / s);
        let half = (s - 1) / 2;
        let texels = (0..columns * rows)
            .map(|n| {
                let (c, j) = (n % columns, n / columns);
                let centre = *fine.get(s * c, s * j + half)?;
                let mut sum = Vec3::ZERO;
                let mut count = 0.0f32;
                for dj in 0..s {
                    for dc in 0..s {
                        let fc = (s * c + fine.columns + dc - half) % fine.columns;
                        if let Some(t) = fine.get(fc, s * j + dj)
                            && t.same_side(&centre)
                        {
                            sum += t.albedo;
                            count += 1.0;
                        }
                    }
                }
                Some(Texel {
                    albedo: sum / count,
                    ..centre
                })
            })
            .collect();
        Ok(Self {
            columns,
            rows,
            cylinder: fine.cylinder,
            texels,
        })
    }

    /// Columns `L` (angles).
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// Rows `Ly` (heights).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The bounding cylinder the texture was captured in.
    pub fn cylinder(&self) -> BoundingCylinder {
        self.cylinder
    }

    /// Texel at column `c`, row `j` (`None` if undefined or `j ≥ Ly`; columns wrap modulo `L`).
    #[inline]
    pub fn get(&self, c: usize, j: usize) -> Option<&Texel> {
        self.texels
            .get(j * self.columns + c % self.columns)?
            .as_ref()
    }

    /// All texels, row-major.
    pub fn texels(&self) -> &[Option<Texel>] {
        &self.texels
    }

    /// Share of defined texels.
    pub fn coverage(&self) -> f64 {
        self.texels.iter().filter(|t| t.is_some()).count() as f64 / self.texels.len() as f64
    }

    /// Share of defined texels whose radius is negative.
    pub fn negative_share(&self) -> f64 {
        let defined = self.texels.iter().flatten().count().max(1);
        self.texels
            .iter()
            .flatten()
            .filter(|t| t.is_negative())
            .count() as f64
            / defined as f64
    }

    /// Bytes as stored for a shader: two RGBA8 textures, 8 bytes per texel.
    pub fn storage_bytes(&self) -> usize {
        8 * self.columns * self.rows
    }

    /// The texture as its 8-bit storage restores it: albedo in sRGB8, normal `(n + 1)/2` in 8 bits
    /// per component, radius `(r + 1)/2` in 8 bits (step `2/255 ≈ 0.008 R`), definition in the
    /// alpha channel. Cost: one pass.
    pub fn quantized_rgba8(&self) -> Self {
        use altrep_data_gen::{linear_to_srgb, srgb_to_linear};
        let q = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() / 255.0;
        let q_srgb = |c: f32| srgb_to_linear(q(linear_to_srgb(c.clamp(0.0, 1.0))));
        let q_signed = |c: f32| q(c * 0.5 + 0.5) * 2.0 - 1.0;
        let texels = self
            .texels
            .iter()
            .map(|t| {
                t.map(|t| Texel {
                    albedo: Vec3::new(q_srgb(t.albedo.x), q_srgb(t.albedo.y), q_srgb(t.albedo.z)),
                    normal: Vec3::new(
                        q_signed(t.normal.x),
                        q_signed(t.normal.y),
                        q_signed(t.normal.z),
                    ),
                    radius: q_signed(t.radius),
                })
            })
            .collect();
        Self {
            texels,
            ..self.clone()
        }
    }

    /// The 8-bit codes of the texture's storage (see [`Self::quantized_rgba8`]), row-major:
    /// `albedo[n] = [sRGB r, g, b, defined ? 255 : 0]`, `geometry[n] = [(n + 1)/2 ×3, (r + 1)/2]`
    /// (codes of undefined texels are 0). [`Self::from_codes`] restores
    /// `self.quantized_rgba8()` exactly. Cost: one pass.
    pub fn codes(&self) -> (Vec<[u8; 4]>, Vec<[u8; 4]>) {
        use altrep_data_gen::linear_to_srgb;
        let q = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        let q_signed = |c: f32| q(c * 0.5 + 0.5);
        self.texels
            .iter()
            .map(|t| match t {
                None => ([0; 4], [0; 4]),
                Some(t) => (
                    [
                        q(linear_to_srgb(t.albedo.x.clamp(0.0, 1.0))),
                        q(linear_to_srgb(t.albedo.y.clamp(0.0, 1.0))),
                        q(linear_to_srgb(t.albedo.z.clamp(0.0, 1.0))),
                        255,
                    ],
                    [
                        q_signed(t.normal.x),
                        q_signed(t.normal.y),
                        q_signed(t.normal.z),
                        q_signed(t.radius),
                    ],
                ),
            })
            .unzip()
    }

    /// A texture from the codes of [`Self::codes`] (alpha 0 = undefined), decoded exactly as
    /// [`Self::quantized_rgba8`] decodes. Errors: fewer than 4 or an odd number of columns, no
    /// row, code arrays of another length.
    pub fn from_codes(
        columns: usize,
        rows: usize,
        cylinder: BoundingCylinder,
        albedo: &[[u8; 4]],
        geometry: &[[u8; 4]],
    ) -> Result<Self, CylinderError> {
        use altrep_data_gen::srgb_to_linear;
        check_columns(columns)?;
        if rows == 0 {
            return Err(CylinderError::ZeroSize {
                what: "texture rows",
            });
        }
        cylinder.validate()?;
        if albedo.len() != columns * rows || geometry.len() != columns * rows {
            return Err(CylinderError::InvalidParameter {
                name: "texture codes",
                value: format!("{} and {} texels", albedo.len(), geometry.len()),
                reason: "must hold columns × rows texels",
            });
        }
        let v = |c: u8| f32::from(c) / 255.0;
        let signed = |c: u8| v(c) * 2.0 - 1.0;
        let texels = albedo
            .iter()
            .zip(geometry)
            .map(|(a, g)| {
                (a[3] != 0).then(|| Texel {
                    albedo: Vec3::new(
                        srgb_to_linear(v(a[0])),
                        srgb_to_linear(v(a[1])),
                        srgb_to_linear(v(a[2])),
                    ),
                    normal: Vec3::new(signed(g[0]), signed(g[1]), signed(g[2])),
                    radius: signed(g[3]),
                })
            })
            .collect();
        Ok(Self {
            columns,
            rows,
            cylinder,
            texels,
        })
    }

    /// The texture with lighting baked in: every albedo replaced by its colour shaded by
    /// `light`, every normal by the light's direction (so shading with `light` again is the
    /// identity). Cost: one pass.
    pub fn baked(&self, light: &Light) -> Self {
        let texels = self
            .texels
            .iter()
            .map(|t| {
                t.map(|t| Texel {
                    albedo: light.shade(t.albedo, t.normal),
                    normal: light.direction,
                    ..t
                })
            })
            .collect();
        Self {
            texels,
            ..self.clone()
        }
    }

    /// The texture shaded by `light` as an `L × Ly` image (alpha 0 where undefined), for reports.
    pub fn shade(&self, light: &Light) -> RgbaImage {
        self.image(|t| {
            let c = light.shade(t.albedo, t.normal.normalize_or_zero());
            [c.x, c.y, c.z, 1.0]
        })
    }

    /// The signed radius as an `L × Ly` image for reports: red for positive, blue for negative,
    /// brightness `|r|`; alpha 0 where undefined.
    pub fn radius_image(&self) -> RgbaImage {
        self.image(|t| {
            let r = t.radius.abs();
            if t.is_negative() {
                [0.1 * r, 0.3 * r, r, 1.0]
            } else {
                [r, 0.3 * r, 0.1 * r, 1.0]
            }
        })
    }

    fn image(&self, f: impl Fn(&Texel) -> [f32; 4]) -> RgbaImage {
        RgbaImage {
            width: self.columns,
            height: self.rows,
            pixels: self
                .texels
                .iter()
                .map(|t| t.as_ref().map_or([0.0; 4], &f))
                .collect(),
        }
    }

    /// The slice at height `y` (world units): rows `j = ⌊v⌋` and `j + 1` interpolated linearly
    /// with weight `t = v − j`, where `v` is the [`row_coordinate`] clamped to `[0, Ly − 1]`
    /// (clamp to edge: the first and last rows extend half a row up and down). A column of the
    /// slice is defined where both rows are defined with radii of one sign (the vertical edge of
    /// the reference mesh); at `t = 0` only row `j` is read. Cost: `O(L)`.
    pub fn slice_at_height(&self, y: f64) -> Slice {
        self.slice(row_coordinate(y, &self.cylinder, self.rows))
    }

    /// The slice at continuous row coordinate `v` (see [`Self::slice_at_height`]).
    pub fn slice(&self, v: f64) -> Slice {
        let last = self.rows - 1;
        let v = if v.is_nan() {
            0.0
        } else {
            v.clamp(0.0, last as f64)
        };
        let j = (v.floor() as usize).min(last);
        let t = (v - j as f64) as f32;
        let row = |j: usize| &self.texels[j * self.columns..(j + 1) * self.columns];
        let texels = if t <= 0.0 || j == last {
            row(j).to_vec()
        } else {
            row(j)
                .iter()
                .zip(row(j + 1))
                .map(|(a, b)| match (a, b) {
                    (Some(a), Some(b)) if a.same_side(b) => Some(a.lerp(b, t)),
                    _ => None,
                })
                .collect()
        };
        Slice { row: v, texels }
    }
}

/// Channels per texel in the row pyramid: per sign, coverage and coverage-weighted radius,
/// albedo and normal.
const PYRAMID_CHANNELS: usize = 16;

/// Vertical minification (docs/design.md §6.7, §10): the rows of a texture as a mip pyramid built
/// by [`crate::mip`] (exact area-weighted box, clamp at the top and bottom). Columns are kept: they
/// are the capture angles, which the warps need.
///
/// How the pyramid is built with the foundation's 2D pyramid: the texture becomes a `1 × Ly`
/// image whose texel is a whole row (`16·L` channels); halving a width of 1 keeps it 1, so the
/// levels halve the rows only. A texel carries, separately for positive and negative radii,
/// its coverage `w` (1 where defined with that sign) and `w·r`, `w·albedo`, `w·normal`. A coarse
/// texel is defined when the sign with the larger coverage covers at least half its footprint;
/// its values are that sign's coverage-weighted means, so radii of both signs are never
/// averaged into a point near the axis.
#[derive(Clone, Debug)]
pub struct RowPyramid {
    levels: Vec<CylindricalTexture>,
}

impl RowPyramid {
    /// Builds the pyramid of `texture` (level 0 is the texture itself). Cost: about
    /// `2·16·L·Ly` multiply-adds per level.
    pub fn build(texture: &CylindricalTexture) -> Result<Self, CylinderError> {
        let (l, rows) = (texture.columns, texture.rows);
        let mut data = vec![0.0f32; rows * l * PYRAMID_CHANNELS];
        for (t, out) in texture.texels.iter().zip(data.chunks_mut(PYRAMID_CHANNELS)) {
            if let Some(t) = t {
                let o = if t.is_negative() { 8 } else { 0 };
                out[o] = 1.0;
                out[o + 1] = t.radius;
                out[o + 2..o + 5].copy_from_slice(&t.albedo.to_array());
                out[o + 5..o + 8].copy_from_slice(&t.normal.to_array());
            }
        }
        let base = crate::mip::Texture::new(1, rows, l * PYRAMID_CHANNELS, data)?;
        let pyramid = crate::mip::Pyramid::build(
            base,
            crate::mip::PyramidParams {
                wrap: [crate::mip::WrapMode::Clamp; 2],
                ..Default::default()
            },
        )?;
        let levels = pyramid
            .levels()
            .iter()
            .map(|level| {
                let texels = level
                    .data
                    .chunks(PYRAMID_CHANNELS)
                    .map(|c| {
                        let o = if c[8] > c[0] { 8 } else { 0 };
                        let w = c[o];
                        (w >= 0.5).then(|| Texel {
                            radius: c[o + 1] / w,
                            albedo: Vec3::from_slice(&c[o + 2..o + 5]) / w,
                            normal: Vec3::from_slice(&c[o + 5..o + 8]) / w,
                        })
                    })
                    .collect();
                CylindricalTexture {
                    columns: l,
                    rows: level.height,
                    cylinder: texture.cylinder,
                    texels,
                }
            })
            .collect();
        Ok(Self { levels })
    }

    /// The levels, finest first (`Ly`, `Ly/2`, … rows, down to 1).
    pub fn levels(&self) -> &[CylindricalTexture] {
        &self.levels
    }

    /// The level for an image that samples `screen_rows` rows over the cylinder's height:
    /// `round(log2(Ly / screen_rows))` (Heckbert's `D` of [`crate::mip`] for the rows, nearest
    /// level), clamped to the pyramid.
    pub fn level_for(&self, screen_rows: usize) -> usize {
        let d = self.levels[0].rows as f64 / screen_rows.max(1) as f64;
        (d.log2().round().max(0.0) as usize).min(self.levels.len() - 1)
    }

    /// Bytes of all levels as stored (8 per texel).
    pub fn storage_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(CylindricalTexture::storage_bytes)
            .sum()
    }
}

fn check_prefilter(prefilter: usize) -> Result<(), CylinderError> {
    if prefilter.is_multiple_of(2) {
        return Err(CylinderError::InvalidParameter {
            name: "prefilter",
            value: prefilter.to_string(),
            reason: "must be odd (1 point-samples)",
        });
    }
    Ok(())
}

fn check_columns(columns: usize) -> Result<(), CylinderError> {
    if columns < 4 || !columns.is_multiple_of(2) {
        return Err(CylinderError::Columns { columns });
    }
    Ok(())
}

/// One horizontal slice of the texture: `L` optional texels at one (continuous) row coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    /// Continuous row coordinate `v` the slice was taken at (row `j`'s centre is `v = j`).
    pub row: f64,
    /// `L` texels, column `c` at angle `2πc/L`.
    pub texels: Vec<Option<Texel>>,
}

impl Slice {
    /// Columns `L`.
    #[inline]
    pub fn columns(&self) -> usize {
        self.texels.len()
    }

    /// Texel of column `c` (wrapping modulo `L`).
    #[inline]
    pub fn get(&self, c: usize) -> Option<&Texel> {
        self.texels[c % self.texels.len()].as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use altrep_data_gen::{Sample, SampleGrid};

    #[test]
    fn row_pyramid_halves_rows_and_keeps_signs_apart() {
        let g = grid(
            4,
            vec![
                Some(0.2),
                Some(0.4),
                None,
                Some(-0.5),
                Some(0.6),
                None,
                None,
                Some(0.5),
            ],
        );
        let t = CylindricalTexture::from_samples(&g).unwrap();
        let p = RowPyramid::build(&t).unwrap();
        assert_eq!(p.levels().len(), 2);
        let top = &p.levels()[1];
        assert_eq!((top.columns(), top.rows()), (4, 1));
        assert!((top.get(0, 0).unwrap().radius - 0.4).abs() < 1e-6);
        // Half covered: kept.
        assert!((top.get(1, 0).unwrap().radius - 0.4).abs() < 1e-6);
        assert!(top.get(2, 0).is_none());
        // One negative, one positive: a tie, the positive wins; never their mean 0.
        assert!((top.get(3, 0).unwrap().radius - 0.5).abs() < 1e-6);
        assert_eq!(p.level_for(2), 0);
        assert_eq!(p.level_for(1), 1);
        assert_eq!(p.storage_bytes(), 64 + 32);
    }

    fn grid(width: usize, samples: Vec<Option<f32>>) -> SampleGrid {
        let height = samples.len() / width;
        SampleGrid {
            width,
            height,
            cylinder: BoundingCylinder::default(),
            projection: Projection::Cylindrical,
            samples: samples
                .into_iter()
                .map(|r| {
                    r.map(|depth| Sample {
                        albedo: Vec3::ONE,
                        normal: Vec3::X,
                        depth,
                    })
                })
                .collect(),
        }
    }

    #[test]
    fn rejects_bad_input() {
        let mut g = grid(4, vec![Some(0.5); 8]);
        g.width = 3;
        assert!(matches!(
            CylindricalTexture::from_samples(&g),
            Err(CylinderError::Columns { columns: 3 })
        ));
        let g = grid(4, vec![Some(f32::NAN); 8]);
        assert!(matches!(
            CylindricalTexture::from_samples(&g),
            Err(CylinderError::BadSample { column: 0, row: 0 })
        ));
        let mut g = grid(4, vec![Some(0.5); 8]);
        g.projection = Projection::Orthographic { angle: 0.0 };
        assert!(CylindricalTexture::from_samples(&g).is_err());
    }

    #[test]
    fn slices_interpolate_only_within_one_sign() {
        let g = grid(
            4,
            vec![
                Some(0.2),
                Some(0.4),
                None,
                Some(-0.5),
                Some(0.6),
                None,
                Some(0.3),
                Some(0.5),
            ],
        );
        let t = CylindricalTexture::from_samples(&g).unwrap();
        let s = t.slice(0.5);
        assert!((s.get(0).unwrap().radius - 0.4).abs() < 1e-6);
        assert!(s.get(1).is_none() && s.get(2).is_none());
        assert!(s.get(3).is_none(), "radii of both signs are not joined");
        // Exactly on a row, that row alone; clamped above and below.
        assert_eq!(t.slice(0.0).get(1).unwrap().radius, 0.4);
        assert_eq!(t.slice(-3.0).get(3).unwrap().radius, -0.5);
        assert_eq!(t.slice(7.0).get(2).unwrap().radius, 0.3);
    }

    #[test]
    fn rgba8_storage_is_close() {
        let g = grid(4, vec![Some(0.123), None, Some(-0.77), Some(1.0)]);
        let t = CylindricalTexture::from_samples(&g).unwrap();
        let q = t.quantized_rgba8();
        for (a, b) in t.texels().iter().zip(q.texels()) {
            assert_eq!(a.is_some(), b.is_some());
            if let (Some(a), Some(b)) = (a, b) {
                assert!((a.radius - b.radius).abs() <= 1.0 / 255.0 + 1e-6);
            }
        }
        assert_eq!(t.storage_bytes(), 32);
    }
}
