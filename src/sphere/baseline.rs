//! The engines' octahedral impostor, built from the same frames (the baseline to beat), as the
//! engines ship it.
//!
//! Per ray and enclosing frame `k` (weight `w_k`): the ray meets the frame's plane `Z = 0` at
//! `q_k`; the depth `D` is read there; the colour, normal and coverage `α_k` are read bilinearly at
//! the **offset** `q_k + D·t_k`. The frames are blended with barycentric weights:
//! `α = Σ w_k α_k`, colour `Σ w_k α_k c_k / α`, and alpha-tested at ½.
//!
//! The depth is read as engine bakers prepare it: their atlases are **dilated** (each empty texel
//! padded with its nearest defined neighbour's value), so a bilinear read near an outline blends
//! defined depths only — here, the bilinear weights are renormalised over the defined texels of the
//! four, and where none of them is defined the nearest defined texel's depth is read (the padded
//! value; nearest by breadth-first distance over the texel grid). Reading undefined texels as the
//! plane's depth, without renormalising, pulls every offset near an outline toward the plane. Colour
//! and normal are likewise renormalised over defined texels; the coverage is not (it is what the
//! alpha test reads).
//!
//! [`EngineSteps::One`] is the usual one-step offset; [`EngineSteps::Two`] reads the depth again
//! at the first offset and offsets from `q_k` by it (one fixed-point iteration more), the variant
//! some engines use for steep relief. Per frame: one depth read per step, then colour, normal and
//! coverage at the offset: `4·(steps + 3)` texel reads.

use glam::{DVec2, Vec3};

use super::frames::{Frame, nearest_defined};
use super::warp::{
    RaySample, RenderOutput, SphereRenderParams, display_frame, draw, enclosing_maps,
};
use super::{SphereError, SphereImages};

/// How many depth reads the engine baseline's offset takes (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum EngineSteps {
    /// One depth read: the offset engines ship by default.
    One,
    /// Two depth reads: the offset refined once.
    Two,
}

impl EngineSteps {
    fn count(self) -> u32 {
        match self {
            Self::One => 1,
            Self::Two => 2,
        }
    }
}

/// A frame's depth with every undefined texel padded by its nearest defined texel's
/// ([`nearest_defined`]). Empty when the frame has no defined texel. Cost: `F²`.
fn dilated_depth(frame: &Frame) -> Vec<f64> {
    nearest_defined(&frame.defined, frame.size)
        .map(|near| near.iter().map(|&n| frame.depth[n]).collect())
        .unwrap_or_default()
}

/// Depth at frame position `p`: bilinear over the defined texels of the four, renormalised; the
/// padded depth of the nearest texel (clamped to the frame) where none is defined.
fn depth_at(frame: &Frame, padded: &[f64], p: DVec2) -> f64 {
    let (d, w) = frame.bilinear(p, |k| frame.depth[k]);
    if w > 0.0 {
        return d / w;
    }
    let t = frame.texel_coords(p);
    let f = frame.size as i64;
    let (i, j) = (
        (t.x.floor() as i64).clamp(0, f - 1),
        (t.y.floor() as i64).clamp(0, f - 1),
    );
    padded[(j * f + i) as usize]
}

/// Draws the object along `dir` as an engine octahedral impostor does, with the one-step
/// offset ([`render_engine`] with [`EngineSteps::One`]).
///
/// Errors: invalid parameters, or a direction the view set does not cover.
pub fn render_engine_baseline(
    images: &SphereImages,
    dir: glam::DVec3,
    params: &SphereRenderParams,
) -> Result<RenderOutput, SphereError> {
    render_engine(images, dir, params, EngineSteps::One)
}

/// Draws the object along `dir` as an engine octahedral impostor does (module docs), with
/// `steps` depth reads per frame. [`RenderOutput::steps`] counts texel reads, `4·(steps + 3)`
/// per enclosing frame; it finds no depth ([`RenderOutput::depth`] is `None` everywhere). Cost:
/// the padding of the (up to) three frames (`F²` each), then per ray those reads.
///
/// Errors: invalid parameters, or a direction the view set does not cover.
pub fn render_engine(
    images: &SphereImages,
    dir: glam::DVec3,
    params: &SphereRenderParams,
    steps: EngineSteps,
) -> Result<RenderOutput, SphereError> {
    params.validate()?;
    let display = display_frame(images, dir)?;
    let maps = enclosing_maps(images, &display)?;
    let padded: Vec<Vec<f64>> = maps
        .iter()
        .map(|&(k, _, _)| dilated_depth(&images.frames[k]))
        .collect();
    let lookups = 4 * (steps.count() + 3) * maps.len() as u32;
    Ok(draw(params, |x, y, _| {
        let (mut alpha, mut col) = (0.0f64, Vec3::ZERO);
        for (&(k, wt, ref map), padded) in maps.iter().zip(&padded) {
            if padded.is_empty() {
                continue;
            }
            let frame = &images.frames[k];
            let line = map.line(x, y);
            let mut p = line.q;
            for _ in 0..steps.count() {
                p = line.q + depth_at(frame, padded, p) * line.t;
            }
            let (cov, _) = frame.bilinear(p, |_| 1.0);
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
            other_reads: 0,
            ..RaySample::default()
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_takes_the_nearest_defined_depth() {
        // A 4 × 4 frame with two defined texels, at (0, 0) and (3, 3).
        let mut frame = Frame::empty_for_tests(4);
        for (k, d) in [(0usize, 0.25), (15, -0.5)] {
            frame.defined[k] = true;
            frame.depth[k] = d;
        }
        let padded = dilated_depth(&frame);
        // Texels nearer (0, 0) than (3, 3) take 0.25, nearer (3, 3) take −0.5.
        for j in 0..4 {
            for i in 0..4 {
                let (a, b) = (i + j, 6 - i - j);
                if a != b {
                    let want = if a < b { 0.25 } else { -0.5 };
                    assert_eq!(padded[j * 4 + i], want, "({i}, {j})");
                }
            }
        }
        assert!(dilated_depth(&Frame::empty_for_tests(3)).is_empty());
    }
}
