//! # The automatic level-of-detail chain (docs/design.md §10c)
//!
//! For each screen-size band of an asset's needs, the chain names the representation to draw:
//! a simplified mesh level ([`crate::mesh_lod`]), an impostor (images with parallax,
//! [`crate::parallax`], at a view size), frames over the sphere ([`crate::sphere`], at a frame
//! size), or the source mesh itself. The engines' octahedral impostor blending the same frames
//! is measured beside them as the baseline chain ([`Family::Engine`]), never drawn by the
//! automatic chain. The candidates are built
//! small and previewed against the ray-cast truth at the needed screen sizes; the chain takes at
//! each size the candidate that meets the quality target there at the least **cost**
//! ([`CostModel`]); then every band is measured at both its edges and the chain is chosen again
//! wherever a member misses the target (its reach lowered), until all meet it.
//!
//! ## Conventions
//!
//! * Screen sizes are pixels across the bounding cylinder's window (`2R`), as every
//!   representation's `size`. The **bands** of the choice end at the preview sizes
//!   ([`crate::mesh_lod::preview_sizes`]): the first starts at the needs' smallest size, each
//!   ends at a preview size, and above the largest preview size (the `max_px` cap) only the
//!   source is drawn.
//! * A candidate **reaches** size `p` when it met the target at the largest preview size at or
//!   above `p` it was measured at: errors grow with the screen size, so a member drawn over a
//!   band is chosen by its error at the band's top. The source reaches every size (it is the
//!   truth).
//! * **Cost** of drawing a member at `p` pixels ([`CostModel::draw_steps`]):
//!   `triangles · triangle_steps + steps_per_pixel · pixel_share · p²` shader steps, where an
//!   impostor's `steps_per_pixel` is its march's measured mean over its quad (`pixel_share` 1;
//!   for the frames over the sphere, the exact warp's march steps over every enclosing frame,
//!   on a quad over the bounding sphere: `pixel_share` its radius², in cylinder radii),
//!   the engine's octahedral impostor takes one depth read per enclosing frame (its one-step
//!   offset; the colour reads, which every impostor makes, are not steps), and a mesh shades
//!   each covered pixel once (`steps_per_pixel` 1, `pixel_share` the object's measured
//!   coverage). A chain's cost is the sum over the bands of the draw cost at each
//!   band's top, plus `byte_steps` per byte of the distinct members' files (the textures the
//!   source and its levels share counted once; the source's own geometry counted where it is
//!   drawn, though the chain's files do not hold it).

pub mod asset;

use serde::{Deserialize, Serialize};

/// A member of a chain: what a band draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Member {
    /// The source mesh itself: drawn where no stand-in meets the target (it is the truth).
    Source,
    /// A simplified mesh level (index among the chain's mesh levels, finest first).
    Mesh {
        /// The level.
        level: usize,
    },
    /// Images with parallax whose views are `size × size` texels.
    Impostor {
        /// The views' side (texels).
        size: usize,
    },
    /// Images with parallax from any direction ([`crate::sphere`]): frames over the sphere
    /// drawn by the exact warp, built for screen size `size`: as many texels across as the
    /// bounding sphere spans pixels there.
    Frames {
        /// The screen size (pixels across the cylinder's window) the frames were built for.
        size: usize,
    },
    /// The engines' octahedral impostor ([`crate::sphere::render_engine_baseline`]) blending
    /// the frames built for screen size `size`: the baseline the other chains are compared
    /// with. It is a member of the engine-only chain only; altrep does not draw it in the
    /// automatic chain (its display draws the exact warp).
    Engine {
        /// The screen size (pixels) its frames were built for.
        size: usize,
    },
}

impl std::fmt::Display for Member {
    /// `source`, `level k`, `impostor S²`, `frames S²`, `engine S²`: as the report names
    /// members.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Member::Source => write!(f, "source"),
            Member::Mesh { level } => write!(f, "level {level}"),
            Member::Impostor { size } => write!(f, "impostor {size}²"),
            Member::Frames { size } => write!(f, "frames {size}²"),
            Member::Engine { size } => write!(f, "engine {size}²"),
        }
    }
}

/// The families a chain may be drawn from; the source belongs to all.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Family {
    /// Simplified meshes and the source (a meshoptimizer-only chain).
    Meshes,
    /// Images with parallax and the source (an impostor-only chain).
    Impostors,
    /// Frames over the sphere and the source.
    Frames,
    /// The engines' octahedral impostor and the source (the baseline chain).
    Engine,
    /// Every candidate but the engine baseline (the automatic chain).
    All,
}

impl Family {
    /// Whether `member` belongs to the family.
    pub fn admits(self, member: Member) -> bool {
        matches!(
            (self, member),
            (_, Member::Source)
                | (
                    Family::All,
                    Member::Mesh { .. } | Member::Impostor { .. } | Member::Frames { .. }
                )
                | (Family::Meshes, Member::Mesh { .. })
                | (Family::Impostors, Member::Impostor { .. })
                | (Family::Frames, Member::Frames { .. })
                | (Family::Engine, Member::Engine { .. })
        )
    }
}

/// A candidate member with what it costs and how far it reaches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// What it is.
    pub member: Member,
    /// Triangles drawn (0 for an impostor's quad, counted as its two triangles' worth of
    /// nothing: its cost is its pixels).
    pub triangles: usize,
    /// Bytes of its own files (a level's `.glb`, an impostor's PNGs; for the source, its
    /// geometry as a `.glb`: what drawing it needs resident). Textures that the source and its
    /// levels share are counted apart.
    pub bytes: u64,
    /// Whether it reads the textures the source and its levels share.
    pub shares_textures: bool,
    /// Mean shader steps per pixel it runs on.
    pub steps_per_pixel: f64,
    /// Share of the picture's `p²` pixels its shader runs on: the object's coverage for a
    /// mesh, 1 for an impostor's quad over the cylinder's window, the bounding sphere's radius
    /// squared (in the cylinder's radii) for the frames over the sphere, whose quad spans that
    /// sphere.
    pub pixel_share: f64,
    /// Largest screen size (pixels) at which it met the target; `None` where it met it at no
    /// size it was measured at. Ignored for the source.
    pub reach: Option<f64>,
    /// The largest size at which it missed the target at the bottom edge of a band (an
    /// impostor drawn much smaller than its views can): it is drawn only on bands whose
    /// bottom edge lies above. `None`: no such miss. Ignored for the source.
    #[serde(default)]
    pub floor_px: Option<f64>,
}

impl Candidate {
    /// Whether it may be drawn up to `p` pixels.
    pub fn reaches(&self, p: f64) -> bool {
        self.member == Member::Source || self.reach.is_some_and(|r| r >= p)
    }

    /// Whether it may be drawn on the band `(bottom, top]` (its bottom edge measured at
    /// `bottom` raised to [`MIN_MEASURED_PX`]).
    pub fn admits_band(&self, bottom: f64, top: f64) -> bool {
        self.reaches(top)
            && (self.member == Member::Source
                || self
                    .floor_px
                    .is_none_or(|f| bottom.max(MIN_MEASURED_PX) > f))
    }
}

use crate::mesh_lod::MIN_MEASURED_PX;

/// The documented combination of costs a chain minimises (overridable in the manifest).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CostModel {
    /// Shader steps one drawn triangle is worth (default 16: a GPU sets up a triangle in about
    /// the time it shades 10–30 pixels).
    pub triangle_steps: f64,
    /// Shader steps one byte of the chain's files is worth (default 0.01: 100 bytes resident
    /// weigh as much as one pixel step per frame at each band's top size).
    pub byte_steps: f64,
}

impl Default for CostModel {
    fn default() -> Self {
        Self {
            triangle_steps: 16.0,
            byte_steps: 0.01,
        }
    }
}

impl CostModel {
    /// Checks the weights; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        for (key, v) in [
            ("triangle_steps", self.triangle_steps),
            ("byte_steps", self.byte_steps),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("auto.cost.{key} = {v} must be finite and ≥ 0"));
            }
        }
        Ok(())
    }

    /// Shader steps (triangles weighed by `triangle_steps`) of drawing `c` at `p` pixels.
    pub fn draw_steps(&self, c: &Candidate, p: f64) -> f64 {
        c.triangles as f64 * self.triangle_steps + c.steps_per_pixel * c.pixel_share * p * p
    }
}

/// A band of a chain: `member` drawn for screen sizes from `from_px` to `to_px`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AutoBand {
    /// Smallest size (pixels).
    pub from_px: f64,
    /// Largest size (pixels): the switch to the next member.
    pub to_px: f64,
    /// What is drawn.
    pub member: Member,
    /// Triangles drawn.
    pub triangles: usize,
    /// Shader steps per pixel of the picture at any size (`steps_per_pixel · pixel_share`).
    pub steps_per_pixel: f64,
    /// Draw cost at `to_px` ([`CostModel::draw_steps`]).
    pub draw_steps: f64,
}

/// A chain and what it costs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chain {
    /// The bands, smallest sizes first.
    pub bands: Vec<AutoBand>,
    /// Bytes of the distinct members' files, shared textures counted once.
    pub bytes: u64,
    /// The objective: Σ over the preview bands of the draw cost at their tops, plus
    /// `byte_steps · bytes`.
    pub cost: f64,
}

/// The bands' tops for `sizes` (the preview sizes, ascending) and the needs' range `[s0, s1]`:
/// each preview size, then `s1` when above them all (a band only the source reaches).
pub fn band_tops(sizes: &[usize], screen_px: [f64; 2]) -> Vec<f64> {
    let mut tops: Vec<f64> = sizes.iter().map(|&s| s as f64).collect();
    if tops.last().is_none_or(|&t| t < screen_px[1]) {
        tops.push(screen_px[1]);
    }
    tops
}

/// The cheapest chain of `candidates` in `family` over the bands ending at `tops` (ascending),
/// from `s0`: a dynamic program over (band, member, whether the shared textures are paid for).
/// Returns `None` when some band has no admitted candidate reaching it (never with the source
/// among the candidates). `texture_bytes`: the files the source and its levels share. Cost:
/// `O(bands · candidates²)`.
pub fn cheapest_chain(
    candidates: &[Candidate],
    family: Family,
    tops: &[f64],
    s0: f64,
    model: &CostModel,
    texture_bytes: u64,
) -> Option<Chain> {
    let n = candidates.len();
    if tops.is_empty() || n == 0 {
        return None;
    }
    let bottom = |i: usize| if i == 0 { s0 } else { tops[i - 1] };
    let ok = |c: &Candidate, i: usize| family.admits(c.member) && c.admits_band(bottom(i), tops[i]);
    // best[m][t]: least cost of the bands so far ending with member m, textures paid (t = 1) or
    // not; back[i][m][t]: the previous state.
    const NONE: f64 = f64::INFINITY;
    let mut best = vec![[NONE; 2]; n];
    let mut back: Vec<Vec<[(usize, usize); 2]>> = Vec::with_capacity(tops.len());
    let bytes_of = |c: &Candidate, paid: bool| -> (f64, bool) {
        let tex = c.shares_textures && !paid;
        let b = c.bytes + if tex { texture_bytes } else { 0 };
        (b as f64 * model.byte_steps, paid || c.shares_textures)
    };
    for (i, &top) in tops.iter().enumerate() {
        let mut next = vec![[NONE; 2]; n];
        let mut from = vec![[(usize::MAX, 0); 2]; n];
        for (m, c) in candidates.iter().enumerate() {
            if !ok(c, i) {
                continue;
            }
            let draw = model.draw_steps(c, top);
            if i == 0 {
                let (b, paid) = bytes_of(c, false);
                let t = paid as usize;
                if draw + b < next[m][t] {
                    next[m][t] = draw + b;
                }
                continue;
            }
            for (p, prev) in best.iter().enumerate() {
                for (pt, &cost) in prev.iter().enumerate() {
                    if !cost.is_finite() {
                        continue;
                    }
                    let (b, paid) = if p == m {
                        (0.0, pt == 1)
                    } else {
                        bytes_of(c, pt == 1)
                    };
                    let t = paid as usize;
                    let total = cost + draw + b;
                    if total < next[m][t] {
                        next[m][t] = total;
                        from[m][t] = (p, pt);
                    }
                }
            }
        }
        best = next;
        back.push(from);
    }
    // The cheapest final state, then back to the first band.
    let (mut m, mut t, cost) = (0..n)
        .flat_map(|m| (0..2).map(move |t| (m, t)))
        .map(|(m, t)| (m, t, best[m][t]))
        .filter(|(_, _, c)| c.is_finite())
        .min_by(|a, b| a.2.total_cmp(&b.2))?;
    let mut members = vec![0; tops.len()];
    for i in (0..tops.len()).rev() {
        members[i] = m;
        if i > 0 {
            (m, t) = back[i][m][t];
        }
    }
    let _ = t;
    let mut bands: Vec<AutoBand> = Vec::new();
    let mut from_px = s0.min(tops[0]);
    for (i, &m) in members.iter().enumerate() {
        let c = &candidates[m];
        match bands.last_mut() {
            Some(last) if last.member == c.member => {
                last.to_px = tops[i];
                last.draw_steps = model.draw_steps(c, tops[i]);
            }
            _ => bands.push(AutoBand {
                from_px,
                to_px: tops[i],
                member: c.member,
                triangles: c.triangles,
                steps_per_pixel: c.steps_per_pixel * c.pixel_share,
                draw_steps: model.draw_steps(c, tops[i]),
            }),
        }
        from_px = tops[i];
    }
    let bytes = chain_bytes(candidates, &bands, texture_bytes);
    Some(Chain { bands, bytes, cost })
}

/// Bytes of the files of `bands`: the distinct members' own (found in `candidates`), and the
/// shared textures once where a written member reads them. The source is the user's, not
/// written: its bytes count in the objective (drawing it needs its geometry and textures
/// resident), not here.
pub fn chain_bytes(candidates: &[Candidate], bands: &[AutoBand], texture_bytes: u64) -> u64 {
    let mut seen: Vec<Member> = Vec::new();
    let mut bytes = 0;
    let mut textures = false;
    for b in bands {
        if seen.contains(&b.member) || b.member == Member::Source {
            continue;
        }
        seen.push(b.member);
        if let Some(c) = candidates.iter().find(|c| c.member == b.member) {
            bytes += c.bytes;
            textures |= c.shares_textures;
        }
    }
    bytes + if textures { texture_bytes } else { 0 }
}

/// One point of a band's Pareto front: a candidate that meets the target at the band's top,
/// with its draw cost and bytes there.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrontPoint {
    /// The candidate.
    pub member: Member,
    /// Draw cost at the band's top ([`CostModel::draw_steps`]).
    pub draw_steps: f64,
    /// Its own bytes (the shared textures added for mesh levels).
    pub bytes: u64,
    /// Whether no other candidate is both cheaper to draw and smaller (the front).
    pub on_front: bool,
}

/// For each band top, the candidates meeting the target there with their draw cost and bytes,
/// those on the Pareto front of (draw steps, bytes) flagged: what each choice was taken from.
pub fn pareto_fronts(
    candidates: &[Candidate],
    tops: &[f64],
    model: &CostModel,
    texture_bytes: u64,
) -> Vec<(f64, Vec<FrontPoint>)> {
    tops.iter()
        .map(|&top| {
            let mut points: Vec<FrontPoint> = candidates
                .iter()
                .filter(|c| c.reaches(top) && c.floor_px.is_none_or(|f| top > f))
                .map(|c| FrontPoint {
                    member: c.member,
                    draw_steps: model.draw_steps(c, top),
                    bytes: c.bytes + if c.shares_textures { texture_bytes } else { 0 },
                    on_front: false,
                })
                .collect();
            for i in 0..points.len() {
                let (d, b) = (points[i].draw_steps, points[i].bytes);
                points[i].on_front = !points.iter().any(|q| {
                    q.draw_steps <= d && q.bytes <= b && (q.draw_steps < d || q.bytes < b)
                });
            }
            (top, points)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(level: usize, triangles: usize, bytes: u64, reach: Option<f64>) -> Candidate {
        Candidate {
            member: Member::Mesh { level },
            triangles,
            bytes,
            shares_textures: true,
            steps_per_pixel: 1.0,
            pixel_share: 0.5,
            reach,
            floor_px: None,
        }
    }

    fn impostor(size: usize, steps: f64, bytes: u64, reach: Option<f64>) -> Candidate {
        Candidate {
            member: Member::Impostor { size },
            triangles: 0,
            bytes,
            shares_textures: false,
            steps_per_pixel: steps,
            pixel_share: 1.0,
            reach,
            floor_px: None,
        }
    }

    fn source(triangles: usize) -> Candidate {
        Candidate {
            member: Member::Source,
            triangles,
            bytes: 0,
            shares_textures: true,
            steps_per_pixel: 1.0,
            pixel_share: 0.5,
            reach: None,
            floor_px: None,
        }
    }

    fn members(c: &Chain) -> Vec<(f64, f64, Member)> {
        c.bands
            .iter()
            .map(|b| (b.from_px, b.to_px, b.member))
            .collect()
    }

    #[test]
    fn each_band_draws_the_cheapest_member_that_reaches_it() {
        let tops = band_tops(&[8, 16, 32, 64], [4.0, 64.0]);
        assert_eq!(tops, vec![8.0, 16.0, 32.0, 64.0]);
        let model = CostModel {
            triangle_steps: 16.0,
            byte_steps: 0.0,
        };
        // A 100-triangle level reaching 32 px: 1,600 + 0.5·p² steps; an impostor of 4 steps
        // per pixel reaching 16: 4·p². At 8 and 16 px the impostor is cheaper (256, 1,024 vs
        // 1,632, 1,728), at 32 the level is the only stand-in; above, the source.
        let c = vec![
            source(10_000),
            mesh(0, 100, 3_000, Some(32.0)),
            impostor(16, 4.0, 2_000, Some(16.0)),
        ];
        let auto = cheapest_chain(&c, Family::All, &tops, 4.0, &model, 0).unwrap();
        assert_eq!(
            members(&auto),
            vec![
                (4.0, 16.0, Member::Impostor { size: 16 }),
                (16.0, 32.0, Member::Mesh { level: 0 }),
                (32.0, 64.0, Member::Source),
            ]
        );
        let expected = 256.0 + 1024.0 + (1600.0 + 512.0) + (160_000.0 + 2048.0);
        approx::assert_relative_eq!(auto.cost, expected, max_relative = 1e-12);
        assert_eq!(auto.bytes, 5_000);
        // The single-family chains cost at least as much.
        for family in [Family::Meshes, Family::Impostors] {
            let one = cheapest_chain(&c, family, &tops, 4.0, &model, 0).unwrap();
            assert!(
                one.cost >= auto.cost,
                "{family:?}: {} < {}",
                one.cost,
                auto.cost
            );
            assert!(one.bands.iter().all(|b| family.admits(b.member)));
        }
    }

    #[test]
    fn a_member_that_missed_at_a_band_bottom_is_drawn_only_above_it() {
        let tops = band_tops(&[8, 16, 32], [4.0, 32.0]);
        let model = CostModel {
            triangle_steps: 16.0,
            byte_steps: 0.0,
        };
        let mut imp = impostor(32, 1.0, 0, Some(32.0));
        let c = |imp: &Candidate| vec![source(10_000), mesh(0, 100, 0, Some(32.0)), imp.clone()];
        let all = cheapest_chain(&c(&imp), Family::All, &tops, 4.0, &model, 0).unwrap();
        assert_eq!(
            members(&all),
            vec![(4.0, 32.0, Member::Impostor { size: 32 })]
        );
        // Missed at 8 px (a bottom edge): not drawn on the bands measured there, (4, 8] and
        // (8, 16], only on those starting above.
        imp.floor_px = Some(8.0);
        let above = cheapest_chain(&c(&imp), Family::All, &tops, 4.0, &model, 0).unwrap();
        assert_eq!(
            members(&above),
            vec![
                (4.0, 16.0, Member::Mesh { level: 0 }),
                (16.0, 32.0, Member::Impostor { size: 32 }),
            ]
        );
    }

    #[test]
    fn bytes_and_shared_textures_are_paid_once() {
        let tops = band_tops(&[8, 16], [8.0, 16.0]);
        // Two levels of equal draw cost: switching from one to the other pays the second's
        // bytes; staying pays once. The textures (10,000 bytes) count once for both.
        let model = CostModel {
            triangle_steps: 0.0,
            byte_steps: 1.0,
        };
        let c = vec![
            mesh(0, 10, 500, Some(16.0)),
            mesh(1, 10, 100, Some(16.0)),
            impostor(16, 0.0, 20_000, Some(16.0)),
        ];
        let chain = cheapest_chain(&c, Family::All, &tops, 8.0, &model, 10_000).unwrap();
        assert_eq!(
            members(&chain),
            vec![(8.0, 16.0, Member::Mesh { level: 1 })]
        );
        assert_eq!(chain.bytes, 10_100);
        let draw: f64 = tops.iter().map(|&p| 0.5 * p * p).sum();
        approx::assert_relative_eq!(chain.cost, draw + 10_100.0, max_relative = 1e-12);
        // Without the source nothing reaches a band above every reach.
        let tops = band_tops(&[8, 16], [8.0, 32.0]);
        assert!(cheapest_chain(&c, Family::All, &tops, 8.0, &model, 0).is_none());
    }

    #[test]
    fn the_front_keeps_what_no_other_candidate_beats_on_both_costs() {
        let model = CostModel::default();
        let c = vec![
            mesh(0, 1000, 40_000, Some(64.0)),
            mesh(1, 100, 4_000, Some(64.0)),
            impostor(64, 6.0, 30_000, Some(64.0)),
            impostor(32, 6.0, 8_000, Some(32.0)),
        ];
        let fronts = pareto_fronts(&c, &[64.0], &model, 0);
        let on: Vec<Member> = fronts[0]
            .1
            .iter()
            .filter(|p| p.on_front)
            .map(|p| p.member)
            .collect();
        // Level 1 (1,600 + 2,048 steps, 4 kB) beats level 0 and the 64² impostor on both.
        assert_eq!(on, vec![Member::Mesh { level: 1 }]);
        assert_eq!(
            fronts[0].1.len(),
            3,
            "the 32² impostor does not reach 64 px"
        );
    }

    /// The objective of `chain` recomputed from its bands: draw cost at every band top, bytes
    /// of each member where it starts a run (a member taken again pays again), the textures
    /// once.
    fn objective(c: &[Candidate], chain: &Chain, tops: &[f64], model: &CostModel, tex: u64) -> f64 {
        let mut cost = 0.0;
        let mut paid = false;
        let mut last: Option<Member> = None;
        for &top in tops {
            let band = chain.bands.iter().find(|b| top <= b.to_px).unwrap();
            let cand = c.iter().find(|x| x.member == band.member).unwrap();
            cost += model.draw_steps(cand, top);
            if last != Some(band.member) {
                cost += cand.bytes as f64 * model.byte_steps;
                if cand.shares_textures && !paid {
                    cost += tex as f64 * model.byte_steps;
                    paid = true;
                }
            }
            last = Some(band.member);
        }
        cost
    }

    proptest::proptest! {
        /// Random candidates and weights: the chain covers the needs from end to end, every
        /// band's member is admitted there, its cost is the objective of its bands, no chain
        /// of one member beats it, and each single family costs at least as much.
        #[test]
        fn the_chain_is_admissible_and_no_single_member_beats_it(
            cands in proptest::collection::vec(
                (0usize..4, 0usize..5000, 0u64..100_000, 0.0f64..50.0, proptest::option::of(0usize..7), proptest::option::of(0usize..7)),
                0..8),
            triangle_steps in 0.0f64..64.0,
            byte_steps in 0.0f64..1.0,
            tex in 0u64..50_000,
            s0 in 1.0f64..12.0,
        ) {
            let sizes = [8usize, 16, 32, 64, 128];
            let tops = band_tops(&sizes, [s0, 200.0]);
            let model = CostModel { triangle_steps, byte_steps };
            let mut c = vec![source(10_000)];
            for (i, &(kind, tris, bytes, steps, reach, floor)) in cands.iter().enumerate() {
                let member = match kind {
                    0 => Member::Mesh { level: i },
                    1 => Member::Impostor { size: 1000 + i },
                    2 => Member::Frames { size: 1000 + i },
                    _ => Member::Engine { size: 1000 + i },
                };
                c.push(Candidate {
                    member,
                    triangles: if kind == 0 { tris } else { 0 },
                    bytes,
                    shares_textures: kind == 0,
                    steps_per_pixel: if kind == 0 { 1.0 } else { steps },
                    pixel_share: if kind == 0 { 0.5 } else { 1.0 },
                    reach: reach.map(|r| tops[r.min(tops.len() - 1)]),
                    floor_px: floor.map(|f| tops[f.min(tops.len() - 1)]),
                });
            }
            let auto = cheapest_chain(&c, Family::All, &tops, s0, &model, tex).unwrap();
            approx::assert_abs_diff_eq!(auto.bands[0].from_px, s0.min(tops[0]));
            approx::assert_abs_diff_eq!(auto.bands.last().unwrap().to_px, 200.0);
            for w in auto.bands.windows(2) {
                proptest::prop_assert!(w[0].to_px == w[1].from_px && w[0].member != w[1].member);
            }
            for (i, &top) in tops.iter().enumerate() {
                let bottom = if i == 0 { s0 } else { tops[i - 1] };
                let band = auto.bands.iter().find(|b| top <= b.to_px).unwrap();
                let cand = c.iter().find(|x| x.member == band.member).unwrap();
                proptest::prop_assert!(cand.admits_band(bottom, top));
            }
            let recomputed = objective(&c, &auto, &tops, &model, tex);
            approx::assert_relative_eq!(auto.cost, recomputed, max_relative = 1e-9, epsilon = 1e-6);
            // Any single admissible member over every band costs at least as much.
            for one in c.iter().filter(|x| Family::All.admits(x.member)) {
                if (0..tops.len()).all(|i| one.admits_band(if i == 0 { s0 } else { tops[i - 1] }, tops[i])) {
                    let single = Chain { bands: vec![AutoBand {
                        from_px: s0.min(tops[0]), to_px: 200.0, member: one.member, triangles: one.triangles,
                        steps_per_pixel: 0.0, draw_steps: 0.0 }], bytes: 0, cost: 0.0 };
                    let cost = objective(&c, &single, &tops, &model, tex);
                    proptest::prop_assert!(auto.cost <= cost * (1.0 + 1e-12) + 1e-9, "{} > {}", auto.cost, cost);
                }
            }
            let engine_drawn = auto.bands.iter().any(|b| matches!(b.member, Member::Engine { .. }));
            proptest::prop_assert!(!engine_drawn, "the automatic chain draws the baseline");
            for family in [Family::Meshes, Family::Impostors, Family::Frames] {
                let one = cheapest_chain(&c, family, &tops, s0, &model, tex).unwrap();
                proptest::prop_assert!(auto.cost <= one.cost * (1.0 + 1e-12) + 1e-9);
            }
            let engine = cheapest_chain(&c, Family::Engine, &tops, s0, &model, tex).unwrap();
            let engine_only = engine.bands.iter().all(|b| matches!(b.member, Member::Engine { .. } | Member::Source));
            proptest::prop_assert!(engine_only, "the baseline chain draws another family");
        }
    }
}
