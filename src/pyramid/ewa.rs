//! Elliptical weighted average (Greene & Heckbert 1986; Heckbert 1989) on a mip pyramid: the
//! quality reference among the lookups, as in pbrt-v4's `MIPMap::EWA`.
//!
//! The pixel's footprint is the ellipse spanned by the two derivative vectors
//! `e_x = k (u_x W, v_x H)`, `e_y = k (u_y W, v_y H)` (level-0 texels; `k` =
//! [`EWA_PIXEL_SCALE`] matches the Gaussian to the box pixel). The minor axis is lengthened
//! so that major/minor ≤ `ewa_max_anisotropy`; the level is `λ = log2(minor)` (clamped at 0),
//! and the two levels around `λ` are filtered and blended linearly. In a level with sizes
//! `w × h`, with `(s, t)` the lookup point in texel units (centres at integers) and
//! `(d₀, d₁)` the derivative vectors in that level's texels, the implicit ellipse
//! `A s² + B s t + C t² = F` has
//! `A = d₀ᵥ² + d₁ᵥ² + 1`, `B = −2(d₀ᵤ d₀ᵥ + d₁ᵤ d₁ᵥ)`, `C = d₀ᵤ² + d₁ᵤ² + 1`, `F = AC − B²/4`
//! (the `+1` adds a one-texel reconstruction radius); every texel inside (`r² = Q/F < 1`) gets
//! the Gaussian weight `e^{−α r²} − e^{−α}`, `α = 2`, and the sum is normalised. Each row of
//! texels is scanned only over the span where `r² < 1` (pbrt scans the bounding box).
//!
//! Cost: about `π (major + 1)(minor + 1) / 4^λ` texel reads per level, two levels: bounded by
//! `≈ 2π (max anisotropy + 2)` reads for a footprint of any size.

use super::filter::wrap_index;
use super::mip::Pyramid;

/// Gaussian fall-off `α` of the EWA weights (pbrt's value).
pub const EWA_ALPHA: f64 = 2.0;

/// Scale of the derivative vectors before the ellipse is formed: with it the truncated Gaussian
/// `e^{−2r²} − e^{−2}` (per-axis variance 0.13608 at scale 1) has the variance `1/12` of the
/// box pixel the supersampled truth integrates, `√(0.08333/0.13608) = 0.78255`. pbrt uses 1
/// (a filter 1.28× wider than the pixel).
pub const EWA_PIXEL_SCALE: f64 = 0.782_549_4;

/// EWA-filtered value at `(u, v)` with screen derivatives, into `out` (`channels` floats);
/// `max_anisotropy ≥ 1` bounds the ellipse eccentricity (see the module docs).
#[allow(clippy::too_many_arguments)]
pub fn ewa_into(
    pyr: &Pyramid,
    u: f64,
    v: f64,
    dudx: f64,
    dvdx: f64,
    dudy: f64,
    dvdy: f64,
    max_anisotropy: f64,
    out: &mut [f32],
) {
    let base = &pyr.levels()[0];
    let (w, h) = (base.width as f64, base.height as f64);
    // Derivative vectors in level-0 texels; e0 the longer.
    let k = EWA_PIXEL_SCALE;
    let (mut e0, mut e1) = ([k * dudx * w, k * dvdx * h], [k * dudy * w, k * dvdy * h]);
    let len = |e: [f64; 2]| (e[0] * e[0] + e[1] * e[1]).sqrt();
    if len(e0) < len(e1) {
        std::mem::swap(&mut e0, &mut e1);
    }
    let (major, mut minor) = (len(e0), len(e1));
    if !(major.is_finite() && minor.is_finite()) {
        out.iter_mut().for_each(|o| *o = 0.0);
        pyr.bilinear_into(0, u, v, out);
        return;
    }
    let max_aniso = max_anisotropy.max(1.0);
    if minor * max_aniso < major {
        // Lengthen the minor axis (perpendicular to the major if the minor vanished).
        let target = major / max_aniso;
        if minor > 0.0 {
            let s = target / minor;
            e1 = [e1[0] * s, e1[1] * s];
        } else {
            e1 = [-e0[1] / major * target, e0[0] / major * target];
        }
        minor = target;
    }
    if minor <= 0.0 {
        pyr.bilinear_into(0, u, v, out);
        return;
    }
    let nl = pyr.levels().len();
    let lod = minor.log2().clamp(0.0, (nl - 1) as f64);
    let l0 = lod.floor() as usize;
    let f = (lod - l0 as f64) as f32;
    level_ewa(pyr, l0, u, v, e0, e1, out);
    if f > 0.0 && l0 + 1 < nl {
        let mut b = vec![0.0f32; out.len()];
        level_ewa(pyr, l0 + 1, u, v, e0, e1, &mut b);
        out.iter_mut()
            .zip(b)
            .for_each(|(a, b)| *a = (1.0 - f) * *a + f * b);
    }
}

/// EWA within one level; `e0, e1` in level-0 texels.
fn level_ewa(
    pyr: &Pyramid,
    level: usize,
    u: f64,
    v: f64,
    e0: [f64; 2],
    e1: [f64; 2],
    out: &mut [f32],
) {
    let t = &pyr.levels()[level];
    let base = &pyr.levels()[0];
    let (sx, sy) = (
        t.width as f64 / base.width as f64,
        t.height as f64 / base.height as f64,
    );
    let (s, tt0) = (u * t.width as f64 - 0.5, v * t.height as f64 - 0.5);
    let (d0, d1) = ([e0[0] * sx, e0[1] * sy], [e1[0] * sx, e1[1] * sy]);
    // Ellipse coefficients bounding the filter region.
    let mut a = d0[1] * d0[1] + d1[1] * d1[1] + 1.0;
    let mut b = -2.0 * (d0[0] * d0[1] + d1[0] * d1[1]);
    let mut c = d0[0] * d0[0] + d1[0] * d1[0] + 1.0;
    let inv_f = 1.0 / (a * c - 0.25 * b * b);
    a *= inv_f;
    b *= inv_f;
    c *= inv_f;
    // The ellipse's bounding rows; per row, only the span inside the ellipse is read.
    let det = 4.0 * a * c - b * b;
    let inv_det = 1.0 / det;
    let vs = (det * a).max(0.0).sqrt();
    let (t0, t1) = (
        (tt0 - 2.0 * inv_det * vs).ceil() as i64,
        (tt0 + 2.0 * inv_det * vs).floor() as i64,
    );
    // An ellipse far larger than the level (its level clamped at the coarsest, or an axis that
    // stopped halving at one texel) averages the whole texture: read the coarsest level.
    let s_extent = 2.0 * inv_det * (det * c).max(0.0).sqrt();
    if !(s_extent.is_finite() && (t1 - t0) as f64 <= 4.0 * (t.height as f64 + 1.0))
        || s_extent > 4.0 * (t.width as f64 + 1.0)
    {
        let last = pyr.levels().len() - 1;
        pyr.bilinear_into(last, u, v, out);
        return;
    }
    let wrap = pyr.params().wrap;
    let floor_w = (-EWA_ALPHA).exp();
    let mut sum = vec![0.0f64; out.len()];
    let mut sum_w = 0.0;
    for it in t0..=t1 {
        let dt = it as f64 - tt0;
        let j = wrap_index(wrap[1], it, t.height);
        // A ds² + (B dt) ds + (C dt² − 1) < 0.
        let disc = (b * dt).powi(2) - 4.0 * a * (c * dt * dt - 1.0);
        if disc <= 0.0 {
            continue;
        }
        let root = disc.sqrt();
        let (s0, s1) = (
            (s + (-b * dt - root) / (2.0 * a)).ceil() as i64,
            (s + (-b * dt + root) / (2.0 * a)).floor() as i64,
        );
        for is in s0..=s1 {
            let ds = is as f64 - s;
            let r2 = a * ds * ds + b * ds * dt + c * dt * dt;
            if r2 < 1.0 {
                let wgt = (-EWA_ALPHA * r2).exp() - floor_w;
                let i = wrap_index(wrap[0], is, t.width);
                for (acc, x) in sum.iter_mut().zip(t.texel(i, j)) {
                    *acc += wgt * f64::from(*x);
                }
                sum_w += wgt;
            }
        }
    }
    if sum_w > 0.0 {
        out.iter_mut()
            .zip(sum)
            .for_each(|(o, s)| *o = (s / sum_w) as f32);
    } else {
        pyr.bilinear_into(level, u, v, out);
    }
}
