//! # Simplified meshes as a representation (docs/design.md §10b)
//!
//! A level-of-detail chain of a mesh: levels simplified by meshoptimizer's attribute-aware edge
//! collapse ([`altrep_data_gen::Mesh::simplified`]) at decreasing triangle ratios, each written as
//! a `.glb` with the source's materials, and the **switch sizes** that say which level to draw at
//! which on-screen size. The switch sizes are chosen by measurement, not predicted from the
//! simplifier's error: a level is previewed against the ray-cast truth at the needed screen
//! sizes (powers of two across the needs' range) and kept up to the largest size at which every
//! preview view meets the quality target. The chain draws, at each size, the coarsest level that
//! met the target there; above the finest level's reach it names the source mesh.
//!
//! ## Conventions
//!
//! * Levels are numbered from the finest (0). Each is stored in the object frame under a root
//!   node holding the placement's inverse (see `altrep_data_gen`'s `gltf_export`), so an engine
//!   loading a level finds it where the source asset was.
//! * A **band** `[from_px, to_px]` of the chain is the range of on-screen sizes (pixels across
//!   the bounding cylinder's window, `2R`, as every representation's `size`) over which its level
//!   is drawn; consecutive bands meet at the switch sizes. The first band starts at the needs'
//!   smallest size, the last ends at their largest.
//! * A level is drawn by ray casting it exactly as the truth is cast (same supersampling, same
//!   texture filtering over each pixel's footprint): the measured error is the simplification's
//!   alone, as a rasteriser with the same materials would show it.

pub mod asset;

use altrep_data_gen::{Mesh, RgbaImage, Supersample};
use serde::{Deserialize, Serialize};

use crate::representation::{Needs, PipelineError, Score, Source, ViewDir, Window, measure_views};

/// One simplified level.
pub struct Level {
    /// The mesh (object frame, the source's materials).
    pub mesh: Mesh,
    /// What it was built from and what it measured.
    pub info: LevelInfo,
}

/// What is known of a level besides its mesh (stored in `asset.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevelInfo {
    /// The triangle ratio asked for (of the source's triangles).
    pub ratio: f64,
    /// Triangles kept.
    pub triangles: usize,
    /// The simplifier's error estimate (object-frame units, the bounding cylinder's radius 1).
    pub error: f64,
    /// The largest previewed screen size (pixels) up to which every preview view met the
    /// quality target, lowered where the verification of the chain found the level missing it
    /// at a band edge; `None` when it failed at the smallest.
    pub max_px: Option<f64>,
    /// The largest side (texels) of the textures the level keeps, where they were reduced for
    /// the sizes it is drawn at ([`reduce_textures`]); `None`: the source's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture_px: Option<usize>,
}

/// A band of the chain: the level drawn for on-screen sizes from `from_px` to `to_px`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// Smallest size (pixels) of the band.
    pub from_px: f64,
    /// Largest size (pixels): the switch to the next finer level (or the source) above it.
    pub to_px: f64,
    /// The level drawn (index from the finest), or `None` for the source mesh itself.
    pub level: Option<usize>,
}

/// A level-of-detail chain: levels (finest first) and bands (smallest sizes first).
pub struct MeshLod {
    /// The levels, finest first.
    pub levels: Vec<Level>,
    /// The bands, from the smallest sizes up.
    pub chain: Vec<Band>,
}

/// Smallest screen size (pixels) at which a level is previewed or verified: below it a picture
/// holds too few pixels for a PSNR to mean anything (every representation is measured there or
/// above).
pub const MIN_MEASURED_PX: f64 = 8.0;

/// The screen sizes (pixels) at which levels are previewed for `needs`: the powers of two
/// strictly inside the needs' range, with its two ends, the smallest raised to
/// [`MIN_MEASURED_PX`] and the largest lowered to `max_px` (the chain draws the source mesh
/// above it); ascending, whole pixels.
pub fn preview_sizes(needs: &Needs, max_px: f64) -> Vec<usize> {
    let [s0, s1] = needs.screen_px;
    let lo = s0
        .max(MIN_MEASURED_PX)
        .min(s1.max(MIN_MEASURED_PX))
        .min(max_px);
    let hi = s1.min(max_px).max(lo);
    let mut sizes = vec![lo.round() as usize];
    let mut p = (lo.round() as usize).next_power_of_two();
    while (p as f64) < hi {
        if p as f64 > lo {
            sizes.push(p);
        }
        p *= 2;
    }
    sizes.push(hi.round() as usize);
    sizes.dedup();
    sizes
}

/// A picture of `shape` along `view` in `window`, `k × k` rays per pixel: the truth's renderer
/// (an empty picture where nothing is visible, which a level may be).
pub fn draw(
    source: &Source,
    shape: &Mesh,
    window: Window,
    view: ViewDir,
    k: Supersample,
) -> Result<RgbaImage, PipelineError> {
    let level = Source {
        name: source.name,
        geometry: Some(shape),
        texture: None,
        tile: None,
        light: source.light,
        placement: source.placement,
    };
    match window.truth(&level, view, k) {
        Err(PipelineError::Invisible { .. }) => Ok(RgbaImage::new(window.side(), window.side())),
        other => other,
    }
}

/// Scores of `levels` against the truth at `size` pixels along `views`, with `k × k` rays per
/// pixel for both: `scores[l][v]`. Cost: `(1 + levels) · views` ray-cast pictures of
/// `size²` (more off the horizontal).
pub fn score_levels(
    source: &Source,
    levels: &[&Mesh],
    needs: &Needs,
    size: usize,
    views: &[ViewDir],
    k: Supersample,
) -> Result<Vec<Vec<Score>>, PipelineError> {
    let window = Window::for_needs(needs, size);
    let mut scores = vec![Vec::with_capacity(views.len()); levels.len()];
    for &view in views {
        let truth = window.truth(source, view, k)?;
        for (l, mesh) in levels.iter().enumerate() {
            let img = draw(source, mesh, window, view, k)?;
            scores[l].push(window.score(&img, &truth)?);
        }
    }
    Ok(scores)
}

/// Views at which levels are previewed while the chain is chosen (3 of the needed directions,
/// 2 × 2 rays per pixel), and verified after (4, 3 × 3): the verification's are the ones every
/// representation is measured at.
pub fn preview_views(needs: &Needs) -> Vec<ViewDir> {
    measure_views(needs, 3)
}

/// What the preview found: for each level (finest first), its reach and the worst PSNR of
/// every size it was drawn at.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Preview {
    /// The largest size of the preview sizes up to which every preview view met the target.
    pub reach: Vec<Option<f64>>,
    /// `(size, worst PSNR dB over the preview views)` per level, for every size it was drawn
    /// at: the level's error against screen size, up to its first failure.
    pub worst_db: Vec<Vec<(usize, f64)>>,
}

/// For each level (finest first), the largest size of `sizes` (ascending) up to which every
/// preview view meets `needs.quality_db`, searching upward from the smallest and stopping at
/// the first failure (errors grow with the size: a level that fails at one size is not tried
/// larger). Cost: at most `levels · sizes · 3` pictures of the levels and `sizes · 3` of the
/// truth, each `size²` at 2 × 2 rays per pixel; coarse levels stop early.
pub fn reach(
    source: &Source,
    levels: &[&Mesh],
    needs: &Needs,
    sizes: &[usize],
) -> Result<Preview, PipelineError> {
    let views = preview_views(needs);
    let mut preview = Preview {
        reach: vec![None; levels.len()],
        worst_db: vec![Vec::new(); levels.len()],
    };
    let mut alive: Vec<usize> = (0..levels.len()).collect();
    for &size in sizes {
        if alive.is_empty() {
            break;
        }
        let meshes: Vec<&Mesh> = alive.iter().map(|&l| levels[l]).collect();
        let scores = score_levels(source, &meshes, needs, size, &views, Supersample::of(2))?;
        let mut still = Vec::new();
        for (i, &l) in alive.iter().enumerate() {
            let worst = scores[i]
                .iter()
                .map(|s| s.psnr_db)
                .fold(f64::INFINITY, f64::min);
            preview.worst_db[l].push((size, worst));
            if worst >= needs.quality_db {
                preview.reach[l] = Some(size as f64);
                still.push(l);
            }
        }
        alive = still;
    }
    Ok(preview)
}

/// The chain for levels of `reach` (finest first): at each size the coarsest level that
/// reached it, the source mesh above every level's reach; bands from the needs' smallest size
/// to their largest, meeting at the switch sizes.
pub fn choose_chain(reach: &[Option<f64>], needs: &Needs) -> Vec<Band> {
    let [s0, s1] = needs.screen_px;
    let mut bands: Vec<Band> = Vec::new();
    let mut from = s0;
    // Coarsest first: each level that reaches beyond the bands so far takes the sizes from
    // there to its reach.
    for l in (0..reach.len()).rev() {
        let Some(r) = reach[l] else { continue };
        let to = r.min(s1);
        if to > from || (bands.is_empty() && to >= from) {
            bands.push(Band {
                from_px: from,
                to_px: to,
                level: Some(l),
            });
            from = to;
        }
        if from >= s1 {
            break;
        }
    }
    if from < s1 || bands.is_empty() {
        bands.push(Band {
            from_px: from,
            to_px: s1,
            level: None,
        });
    }
    bands
}

/// The sizes (pixels) at which a band from `from_px` to `to_px` is measured: both its edges
/// within the needs' sizes, raised to [`MIN_MEASURED_PX`], once each; none when the band lies
/// outside the needs (a chain built for wider needs is measured where these needs look).
pub fn band_edges(from_px: f64, to_px: f64, needs: &Needs) -> Vec<usize> {
    let [s0, s1] = needs.screen_px;
    let (from, to) = (from_px.max(s0), to_px.min(s1));
    if from > to {
        return Vec::new();
    }
    let mut sizes = vec![
        from.max(MIN_MEASURED_PX).round() as usize,
        to.max(MIN_MEASURED_PX).round() as usize,
    ];
    sizes.dedup();
    sizes
}

/// The reach of a member that missed the target at `missed_at` pixels: the largest of `sizes`
/// (ascending) below that size when it lies below the present `reach`, else none.
pub fn lowered_reach(
    reach: Option<f64>,
    sizes: impl DoubleEndedIterator<Item = f64>,
    missed_at: usize,
) -> Option<f64> {
    let below = sizes.rev().find(|&s| s < missed_at as f64);
    match (reach, below) {
        (Some(r), Some(b)) if b < r => Some(b),
        _ => None,
    }
}

/// Scores of the bands of `chain` at both edges of each, within the needs' sizes (raised to
/// [`MIN_MEASURED_PX`]), at the 4 needed directions every representation is measured at,
/// 3 × 3 rays per pixel: the verification of the switch sizes. Bands that draw the source are
/// not measured (the source is the truth). `levels[l]` draws level `l`. Returns
/// `(band, size, scores)` per measured edge.
pub fn verify(
    levels: &[&Mesh],
    chain: &[Band],
    needs: &Needs,
    source: &Source,
) -> Result<Vec<(usize, usize, Vec<Score>)>, PipelineError> {
    let views = measure_views(needs, 4);
    let mut out = Vec::new();
    for (b, band) in chain.iter().enumerate() {
        let Some(l) = band.level else { continue };
        for size in band_edges(band.from_px, band.to_px, needs) {
            let scores = score_levels(
                source,
                &[levels[l]],
                needs,
                size,
                &views,
                Supersample::of(3),
            )?;
            out.push((b, size, scores.into_iter().next().unwrap_or_default()));
        }
    }
    Ok(out)
}

/// Textures reduced to the sizes the chain draws: every level it draws gets the smallest
/// textures (a power of two on a side, from the next power of two at or above the largest size
/// any level is drawn at, doubling) with which every band still meets the target at both edges,
/// measured as [`verify`] does; one size for all the levels, so they share one set of images.
/// Where no size below the source's passes, or the reduced files would not weigh less, the
/// levels keep the source's. The levels' `info.texture_px` say what they kept. Returns the sizes tried. Cost:
/// one verification of the chain per size tried.
pub fn reduce_textures(
    levels: &mut [Level],
    chain: &[Band],
    needs: &Needs,
    source: &Source,
) -> Result<Vec<usize>, PipelineError> {
    let drawn: Vec<usize> = (0..levels.len())
        .filter(|l| chain.iter().any(|b| b.level == Some(*l)))
        .collect();
    let top = chain
        .iter()
        .filter(|b| b.level.is_some())
        .map(|b| b.to_px.min(needs.screen_px[1]))
        .reduce(f64::max);
    let full = drawn
        .iter()
        .filter_map(|&l| levels[l].mesh.largest_texture_side())
        .max();
    let (Some(top), Some(full)) = (top, full) else {
        return Ok(Vec::new());
    };
    let mut tried = Vec::new();
    let mut side = (top.max(1.0).ceil() as usize).next_power_of_two();
    while side < full {
        tried.push(side);
        let mut reduced = Vec::with_capacity(levels.len());
        for level in levels.iter() {
            reduced.push(level.mesh.with_textures_at_most(side)?);
        }
        let meshes: Vec<&Mesh> = reduced.iter().map(|(m, _)| m).collect();
        let ok = verify(&meshes, chain, needs, source)?
            .iter()
            .all(|(_, _, scores)| scores.iter().all(|s| s.psnr_db >= needs.quality_db));
        if ok {
            // Kept only where the files shrink: a small source image stored compactly (a
            // JPEG, a PNG of few colours) can weigh less than its reduction.
            let now: Vec<&Mesh> = levels.iter().map(|l| &l.mesh).collect();
            if files_bytes(&meshes)? < files_bytes(&now)? {
                for (level, (mesh, kept)) in levels.iter_mut().zip(reduced) {
                    level.mesh = mesh;
                    level.info.texture_px = kept;
                }
            }
            break;
        }
        side *= 2;
    }
    Ok(tried)
}

/// Bytes of `levels` written as `.glb` files sharing their textures beside them (what the
/// files of a chain weigh). Cost: one export of each level, one encoding of each texture.
pub fn files_bytes(levels: &[&Mesh]) -> Result<u64, PipelineError> {
    let mut images = altrep_data_gen::ExternalImages::default();
    let mut bytes = 0;
    for mesh in levels {
        bytes += mesh.to_glb_beside(&mut images)?.bytes.len() as u64;
    }
    Ok(bytes
        + images
            .files
            .iter()
            .map(|f| f.bytes.len() as u64)
            .sum::<u64>())
}

/// A chain that passed its verification ([`verified_chain`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Verified {
    /// The bands.
    pub chain: Vec<Band>,
    /// Each level's reach after the repairs (finest first).
    pub reach: Vec<Option<f64>>,
    /// How many rounds of repair it took.
    pub repairs: usize,
}

/// The chain for the previewed `reach` of `levels`, verified ([`verify`]) and repaired until
/// every band meets the target at both edges: a level that misses it at a size has its reach
/// lowered to the previewed size below (of `sizes`, ascending), and the chain is chosen again,
/// so a finer level (or the source) takes that size. Ends: each repair lowers a reach. Cost: one
/// verification per round.
pub fn verified_chain(
    levels: &[&Mesh],
    reach: &[Option<f64>],
    sizes: &[usize],
    needs: &Needs,
    source: &Source,
) -> Result<Verified, PipelineError> {
    let mut reach = reach.to_vec();
    let mut repairs = 0;
    loop {
        let chain = choose_chain(&reach, needs);
        let mut changed = false;
        for (b, size, scores) in verify(levels, &chain, needs, source)? {
            let worst = scores
                .iter()
                .map(|s| s.psnr_db)
                .fold(f64::INFINITY, f64::min);
            let Some(l) = chain[b].level else { continue };
            if worst >= needs.quality_db {
                continue;
            }
            let lowered = lowered_reach(reach[l], sizes.iter().map(|&s| s as f64), size);
            if lowered != reach[l] {
                reach[l] = lowered;
                changed = true;
            }
        }
        if !changed {
            return Ok(Verified {
                chain,
                reach,
                repairs,
            });
        }
        repairs += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn needs(s0: f64, s1: f64) -> Needs {
        Needs {
            screen_px: [s0, s1],
            ..Needs::default()
        }
    }

    #[test]
    fn preview_sizes_span_the_needed_range_in_powers_of_two() {
        let big = 512.0;
        let sizes = |s0, s1, cap| preview_sizes(&needs(s0, s1), cap);
        assert_eq!(sizes(1.0, 256.0, big), vec![8, 16, 32, 64, 128, 256]);
        assert_eq!(sizes(20.0, 100.0, big), vec![20, 32, 64, 100]);
        assert_eq!(sizes(1.0, 4.0, big), vec![8]);
        assert_eq!(sizes(64.0, 64.0, big), vec![64]);
        // Needs beyond the cap are previewed up to it (the source is drawn above).
        assert_eq!(sizes(1.0, 16384.0, 64.0), vec![8, 16, 32, 64]);
        assert_eq!(sizes(100.0, 200.0, 64.0), vec![64]);
    }

    #[test]
    fn the_chain_draws_the_coarsest_level_that_reaches_each_size() {
        let n = needs(1.0, 256.0);
        // Finest first: level 0 reaches 128, level 1 reaches 32, level 2 nothing, level 3 16.
        let chain = choose_chain(&[Some(128.0), Some(32.0), None, Some(16.0)], &n);
        let got: Vec<(f64, f64, Option<usize>)> = chain
            .iter()
            .map(|b| (b.from_px, b.to_px, b.level))
            .collect();
        assert_eq!(
            got,
            vec![
                (1.0, 16.0, Some(3)),
                (16.0, 32.0, Some(1)),
                (32.0, 128.0, Some(0)),
                (128.0, 256.0, None)
            ]
        );
        // Every level reaching every size: the coarsest alone.
        let all = choose_chain(&[Some(256.0), Some(256.0)], &n);
        assert_eq!(all.len(), 1);
        assert_eq!(all[0].level, Some(1));
        // No level reaching anything: the source everywhere.
        let none = choose_chain(&[None, None], &n);
        assert_eq!(none.len(), 1);
        assert_eq!(none[0].level, None);
    }
}
