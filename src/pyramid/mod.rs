//! Pyramids for minification (docs/design.md §10; Williams 1983, Bornik & Ferko 2002): mipmaps with
//! the prefilters and colour handling current tools use, ripmaps, fipmaps chosen per view, an EWA
//! reference lookup, the supersampled ground truth they are measured against, and quad-tree
//! texture fusion from several views.
//!
//! ## Conventions (shared by every submodule)
//! * A [`Texture`] is row-major, `channels` floats per texel, row 0 at the top; `(u, v) ∈ [0, 1]²`
//!   spans it, texel `(i, j)` covers `[i/W, (i+1)/W] × [j/H, (j+1)/H]`, its centre at
//!   `((i + ½)/W, (j + ½)/H)`.
//! * Every coarser level is resampled **from level 0** by the definition in [`filter`] (level 0
//!   box-reconstructed, convolved with the kernel stretched to the output texel, sampled at its
//!   centre); the box filter is the exact area-weighted mean.
//! * Levels are halved with `max(1, ⌊n/2⌋)` per axis (sizes need not be powers of two).
//! * Colour is filtered in linear light and alpha premultiplied ([`levels`]); level 0 is stored
//!   exactly as given.
//! * Screen derivatives `(u_x, v_x, u_y, v_y)` are per pixel, in texture units.
//!
//! ## Entry points
//! * [`build`]: texture + [`PyramidParams`] → ([`PyramidData`], [`PyramidReport`]).
//! * [`truth::measure_sweep`]: error against the supersampled truth and time per lookup of mip,
//!   rip, fip and EWA over distances and tilts (the `altrep pyramid` table).
//! * [`fusion::fuse`]: quad-tree fusion of registered views with median rejection.

pub mod asset;
pub mod atlas;
pub mod ewa;
pub mod fast;
pub mod filter;
pub mod fip;
pub mod fusion;
pub mod levels;
pub mod mip;
pub mod rip;
pub mod speed;
pub mod truth;

pub use ewa::ewa_into;
pub use fip::{FipMap, FipTransform, Scheme, Shear, ShearAxis, decide};
pub use fusion::{FusionParams, FusionReport, FusionView, fuse};
pub use mip::{
    AlphaMode, ColourSpace, Filter, MipError, Pyramid, PyramidKind, PyramidParams, Texture,
    WrapMode,
};
pub use rip::RipMap;
pub use truth::{PlaneView, SweepParams, SweepReport, measure_sweep};

/// Errors of this module (one enum for the whole pyramid family).
pub type PyramidError = MipError;

/// The fitted pyramid, by kind.
#[derive(Clone, Debug)]
pub enum PyramidData {
    /// A mipmap.
    Mip(Pyramid),
    /// A ripmap.
    Rip(RipMap),
    /// A fipmap database (which holds its mipmap and ripmap too).
    Fip(FipMap),
}

impl PyramidData {
    /// Every stored level with a name an asset writer can use as a file stem: `mip{l}`,
    /// `rip_u{lu}_v{lv}`, `fip_{axis}{num}over{den}_u{lu}_v{lv}`.
    pub fn textures(&self) -> Vec<(String, &Texture)> {
        match self {
            Self::Mip(p) => mip_names(p),
            Self::Rip(r) => rip_names("rip", r),
            Self::Fip(f) => {
                let mut v = mip_names(f.mip());
                v.extend(rip_names("rip", f.rip()));
                for (i, s) in f.shears().iter().enumerate() {
                    v.extend(rip_names(&shear_prefix(s), f.sheared(i)));
                }
                v
            }
        }
    }

    /// Bytes of every stored level at `bytes_per_channel`.
    pub fn bytes(&self, bytes_per_channel: usize) -> usize {
        match self {
            Self::Mip(p) => p.bytes(bytes_per_channel),
            Self::Rip(r) => r.bytes(bytes_per_channel),
            Self::Fip(f) => f.bytes(bytes_per_channel),
        }
    }
}

/// File-stem prefix of the ripmap of shear `s`: `fip_{axis}{num}over{den}` (e.g. `fip_v-1over2`).
pub fn shear_prefix(s: &Shear) -> String {
    let axis = match s.axis {
        ShearAxis::U => "u",
        ShearAxis::V => "v",
    };
    format!("fip_{axis}{}over{}", s.num, s.den)
}

fn mip_names(p: &Pyramid) -> Vec<(String, &Texture)> {
    p.levels()
        .iter()
        .enumerate()
        .map(|(l, t)| (format!("mip{l}"), t))
        .collect()
}

fn rip_names<'a>(prefix: &str, r: &'a RipMap) -> Vec<(String, &'a Texture)> {
    let (nu, nv) = r.level_counts();
    (0..nv)
        .flat_map(|lv| (0..nu).map(move |lu| (lu, lv)))
        .map(|(lu, lv)| (format!("{prefix}_u{lu}_v{lv}"), r.level(lu, lv)))
        .collect()
}

/// Costs of a [`build`], and how well alpha coverage was kept.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PyramidReport {
    /// Kind built.
    pub kind: PyramidKind,
    /// Number of stored textures (levels, over all ripmaps).
    pub textures: usize,
    /// Bytes at 4 bytes per channel (f32).
    pub bytes_f32: usize,
    /// Bytes at 1 byte per channel (RGBA8-like).
    pub bytes_u8: usize,
    /// Build time, seconds.
    pub build_seconds: f64,
    /// When coverage is preserved: level 0's coverage, then each mip level's (mipmap diagonal).
    pub coverage: Vec<f64>,
    /// Largest `|coverage(level) − coverage(level 0)|` over mip levels of at least 4 × 4 texels.
    pub max_coverage_error: f64,
}

/// Builds the pyramid of `params.kind` for `texture`. Cost: see [`mip`], [`rip`], [`fip`].
pub fn build(
    texture: &Texture,
    params: &PyramidParams,
) -> Result<(PyramidData, PyramidReport), PyramidError> {
    let start = std::time::Instant::now();
    let data = match params.kind {
        PyramidKind::Mip => PyramidData::Mip(Pyramid::build(texture.clone(), *params)?),
        PyramidKind::Rip => PyramidData::Rip(RipMap::build(texture.clone(), *params)?),
        PyramidKind::Fip => PyramidData::Fip(FipMap::build(texture.clone(), *params)?),
    };
    let build_seconds = start.elapsed().as_secs_f64();
    let (coverage, max_coverage_error) = match (
        levels::alpha_channel(params, texture.channels),
        params.coverage_reference,
    ) {
        (Some(ai), Some(r)) => {
            let mips: Vec<&Texture> = match &data {
                PyramidData::Mip(p) => p.levels().iter().collect(),
                PyramidData::Fip(f) => f.mip().levels().iter().collect(),
                PyramidData::Rip(rm) => {
                    let (nu, nv) = rm.level_counts();
                    (0..nu.min(nv)).map(|l| rm.level(l, l)).collect()
                }
            };
            let cov: Vec<f64> = mips
                .iter()
                .map(|t| levels::alpha_coverage(t, ai, r, 1.0, params.wrap))
                .collect();
            let err = mips
                .iter()
                .zip(&cov)
                .filter(|(t, _)| t.width >= 4 && t.height >= 4)
                .map(|(_, c)| (c - cov[0]).abs())
                .fold(0.0, f64::max);
            (cov, err)
        }
        _ => (Vec::new(), 0.0),
    };
    let textures = data.textures().len();
    let report = PyramidReport {
        kind: params.kind,
        textures,
        bytes_f32: data.bytes(4),
        bytes_u8: data.bytes(1),
        build_seconds,
        coverage,
        max_coverage_error,
    };
    Ok((data, report))
}
