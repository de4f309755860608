//! The engines' octahedral impostor, built from the same frames (the baseline to beat).
//!
//! Per ray and enclosing frame `k` (weight `w_k`): the ray meets the frame's plane `Z = 0` at
//! `q_k`; the depth `D` is read there (bilinear, undefined texels read as `Z = 0`, the plane's
//! depth, as engines clear their depth channel); the colour, normal and coverage `α_k` are read
//! bilinearly at the **one-step offset** `q_k + D·t_k`. The frames are blended with barycentric
//! weights: `α = Σ w_k α_k`, colour `Σ w_k α_k c_k / α`, and alpha-tested at ½. Four bilinear
//! fetches of two textures per frame; no march.

use glam::{DVec2, Vec3};

use super::frames::Frame;
use super::warp::{
    RaySample, RenderOutput, SphereRenderParams, display_frame, draw, enclosing_maps,
};
use super::{SphereError, SphereImages};

/// Bilinear depth (undefined texels read as 0) and coverage at frame position `P`.
fn depth_and_coverage(frame: &Frame, p: DVec2) -> (f64, f64) {
    let t = frame.texel_coords(p) - 0.5;
    let (i0, j0) = (t.x.floor() as i64, t.y.floor() as i64);
    let (fx, fy) = (t.x - i0 as f64, t.y - j0 as f64);
    let (mut d, mut a) = (0.0, 0.0);
    for (di, dj, w) in [
        (0, 0, (1.0 - fx) * (1.0 - fy)),
        (1, 0, fx * (1.0 - fy)),
        (0, 1, (1.0 - fx) * fy),
        (1, 1, fx * fy),
    ] {
        if let Some(k) = frame.cell(i0 + di, j0 + dj) {
            d += w * frame.depth[k];
            a += w;
        }
    }
    (d, a)
}

/// Draws the object along `dir` as an engine octahedral impostor does (module docs of
/// `baseline`). Cost: per ray, 2 bilinear lookups in each of the (up to) three frames.
/// [`RenderOutput::steps`] counts texel lookups (8 per frame); it finds no depth
/// ([`RenderOutput::depth`] is `None` everywhere).
///
/// Errors: invalid parameters, or a direction the view set does not cover.
pub fn render_engine_baseline(
    images: &SphereImages,
    dir: glam::DVec3,
    params: &SphereRenderParams,
) -> Result<RenderOutput, SphereError> {
    params.validate()?;
    let display = display_frame(images, dir)?;
    let maps = enclosing_maps(images, &display)?;
    let lookups = 8 * maps.len() as u32;
    Ok(draw(params, |x, y, _| {
        let (mut alpha, mut col) = (0.0f64, Vec3::ZERO);
        for &(k, wt, ref map) in &maps {
            let frame = &images.frames[k];
            let line = map.line(x, y);
            let (depth, _) = depth_and_coverage(frame, line.q);
            let p = line.q + depth * line.t;
            let (_, cov) = depth_and_coverage(frame, p);
            if cov <= 0.0 {
                continue;
            }
            if let Some((albedo, normal)) = frame.attributes_at(p) {
                let c = params.light.shade(albedo, normal);
                alpha += wt * cov;
                col += c * (wt * cov) as f32;
            }
        }
        RaySample {
            colour: (alpha >= 0.5).then(|| col / alpha as f32),
            steps: lookups,
            ..RaySample::default()
        }
    }))
}
