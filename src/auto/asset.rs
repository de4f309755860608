//! The automatic level-of-detail chain (docs/design.md §10c) in the pipeline: `[asset.auto]`.
//!
//! Files: the members the chain draws, each written by its own representation under a prefix
//! in this one folder: `mesh-level{k}.glb` and `mesh-texture{i}.png|.jpg` (simplified meshes,
//! as [`crate::mesh_lod`] writes them), `impostor{S}-…` (images with parallax of `S²` views,
//! as [`crate::parallax`] writes them), `frames{S}-…` (frames over the sphere built for screen
//! size `S`, as [`crate::sphere`] writes them). `metadata.chain` lists the bands (`from_px`, `to_px`,
//! `member`, triangles, steps per pixel, draw cost); `metadata.members` each member's prefix,
//! representation and the metadata its writer returned; `metadata.target_db` the target.

use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

use altrep_data_gen::{ExternalImages, Mesh, RgbaImage, Supersample};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::{
    AutoBand, Candidate, Chain, CostModel, Family, Member, band_tops, cheapest_chain, pareto_fronts,
};
use crate::asset::{AssetReader, AssetWriter};
use crate::mesh_lod::asset::{MeshLodDecisions, MeshLodRepr, MeshLodSpec, simplify_levels};
use crate::mesh_lod::{
    Band, Level, LevelInfo, MeshLod, band_edges, draw, lowered_reach, preview_sizes, reach,
    score_levels,
};
use crate::parallax::asset::{Parallax, ParallaxData, ParallaxDecisions, ParallaxSpec};
use crate::parallax::{RenderParams, WarpMethod, render};
use crate::representation::{
    Estimate, InputSize, Measurement, Needs, Picture, PipelineError, Plan, Representation, Source,
    Window, elevation_note, measure_views, secs,
};
use crate::sphere::asset::{SphereDecisions, SphereRepr, SphereSpec};
use crate::sphere::{MethodStats, SphereImages, azimuth_elevation, measure_one_step};

/// Manifest parameters of the automatic chain (`[asset.auto]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutoSpec {
    /// Quality target (PSNR dB against the truth) every band must meet at both its edges
    /// (default: the asset's `quality_db`).
    pub target_db: Option<f64>,
    /// Families of candidates: `mesh_lod` (simplified meshes, mesh assets only), `parallax`
    /// (impostors: images with parallax) and `sphere` (frames over the sphere, with the engines'
    /// octahedral impostor of the same frames as the baseline chain) (default all three).
    pub families: Vec<String>,
    /// Largest screen size (pixels, 8–2048; default 512) at which candidates are previewed and
    /// verified: above it the chain draws the source.
    pub max_px: f64,
    /// The simplified levels' parameters (`[asset.auto.mesh_lod]`; its `max_px` is this one's).
    pub mesh_lod: MeshLodSpec,
    /// The impostors' parameters (`[asset.auto.parallax]`): one candidate per preview size up
    /// to its `size` (default 256 here), with its views, depth and bounds.
    pub parallax: ParallaxSpec,
    /// The frames' parameters (`[asset.auto.sphere]`): one candidate per preview size up to
    /// its `size` (default 64), with its grid and surface model.
    pub sphere: SphereSpec,
    /// The combination of costs the chain minimises ([`CostModel`]).
    pub cost: CostModel,
}

impl Default for AutoSpec {
    fn default() -> Self {
        Self {
            target_db: None,
            families: FAMILIES.iter().map(|f| f.to_string()).collect(),
            max_px: 512.0,
            mesh_lod: MeshLodSpec::default(),
            parallax: ParallaxSpec {
                size: 256,
                ..ParallaxSpec::default()
            },
            sphere: SphereSpec::default(),
            cost: CostModel::default(),
        }
    }
}

/// What the planner decided: the target, the preview sizes and each candidate family's plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AutoDecisions {
    /// The quality target (dB).
    pub target_db: f64,
    /// Screen sizes (pixels) at which candidates are previewed: the bands' tops.
    pub sizes: Vec<usize>,
    /// The simplified levels' plan, when that family applies.
    pub mesh: Option<MeshLodDecisions>,
    /// `(view size, plan)` of each impostor candidate.
    pub impostors: Vec<(usize, ParallaxDecisions)>,
    /// `(screen size built for, plan)` of each candidate of frames over the sphere.
    #[serde(default)]
    pub frames: Vec<(usize, SphereDecisions)>,
}

/// The chain as built or loaded: its bands and the members they draw.
pub struct AutoChain {
    /// The bands, smallest sizes first; [`Member::Mesh`] indexes `mesh.levels`.
    pub chain: Vec<AutoBand>,
    /// The simplified levels the chain draws (their own chain: the bands that draw them).
    pub mesh: Option<MeshLod>,
    /// `(view size, data)` of each impostor the chain draws.
    pub impostors: Vec<(usize, ParallaxData)>,
    /// `(screen size built for, data)` of each set of frames over the sphere the chain draws.
    pub frames: Vec<(usize, SphereImages)>,
    /// Where the chain draws the source at every size: the candidate kept, undrawn, that came
    /// closest to the target (the finest level, else the largest impostor, else the largest
    /// frames), which the measurement reports below the target. `None` otherwise.
    pub undrawn: Option<Member>,
    /// The quality target (dB) the chain was verified for.
    pub target_db: f64,
}

/// Prefix of the simplified levels' files in the folder.
const MESH_PREFIX: &str = "mesh-";

/// The candidate families `families` may name.
const FAMILIES: [&str; 3] = ["mesh_lod", "parallax", "sphere"];

/// The automatic chain for the pipeline.
pub struct AutoRepr;

/// The needs with the chain's target as their quality.
fn with_target(needs: &Needs, target_db: f64) -> Needs {
    Needs {
        quality_db: target_db,
        ..needs.clone()
    }
}

/// The needs an impostor of `size²` views is planned for: the sizes up to its own.
fn impostor_needs(needs: &Needs, size: usize) -> Needs {
    let s = size as f64;
    Needs {
        screen_px: [needs.screen_px[0].min(s), s],
        ..needs.clone()
    }
}

fn impostor_spec(spec: &AutoSpec, size: usize) -> ParallaxSpec {
    ParallaxSpec {
        size,
        ..spec.parallax.clone()
    }
}

/// The bounding sphere's radius in units of the bounding cylinder's (whose window `2R` a screen
/// size spans): frames over the sphere frame that sphere, `radius` times wider.
fn sphere_radius(source: &Source) -> Result<f64, PipelineError> {
    Ok(altrep_data_gen::OrthoFrame::bounding_sphere(source.shape()?).1)
}

/// Pixels (or frame texels) across the bounding sphere when the cylinder's window spans `p`.
fn sphere_px(p: usize, radius: f64) -> usize {
    ((p as f64 * radius).ceil() as usize).clamp(4, 1024)
}

fn frames_spec(spec: &AutoSpec, size: usize) -> SphereSpec {
    SphereSpec {
        size,
        ..spec.sphere.clone()
    }
}

/// One candidate per preview size up to `cap` (the manifest's `auto.{key}.size`): each planned
/// by `plan_one`, added to `plan` as built (described by `describe`) or skipped with its reason
/// where refused or above the cap, named by `what`.
fn plan_per_size<D>(
    plan: &mut Plan,
    sizes: &[usize],
    (key, cap): (&str, usize),
    what: impl Fn(usize) -> String,
    mut plan_one: impl FnMut(usize) -> Result<(Plan, D), PipelineError>,
    describe: impl Fn(usize, &D) -> String,
) -> Result<Vec<(usize, D)>, PipelineError> {
    let mut out = Vec::new();
    for &s in sizes {
        if s > cap {
            plan.skip(what(s), format!("above auto.{key}.size = {cap}"));
            continue;
        }
        let (p, d) = plan_one(s)?;
        match p.refused {
            Some(reason) => plan.skip(what(s), reason),
            None => {
                plan.build(describe(s, &d));
                out.push((s, d));
            }
        }
    }
    Ok(out)
}

/// The candidates' data a measurement draws from.
struct Members<'a> {
    levels: &'a [&'a Mesh],
    impostors: &'a [(usize, &'a ParallaxData)],
    frames: &'a [(usize, &'a SphereImages)],
}

impl Members<'_> {
    fn impostor_of(&self, s: usize) -> Result<&ParallaxData, PipelineError> {
        of_size(self.impostors, s)
            .ok_or_else(|| PipelineError::Spec(format!("no impostor of {s}² views")))
    }

    fn frames_of(&self, s: usize) -> Result<&SphereImages, PipelineError> {
        of_size(self.frames, s).ok_or_else(|| PipelineError::Spec(format!("no frames of {s}²")))
    }
}

/// The data of size `s` in a list of `(size, data)`.
fn of_size<'a, T>(list: &[(usize, &'a T)], s: usize) -> Option<&'a T> {
    list.iter().find(|(k, _)| *k == s).map(|(_, d)| *d)
}

/// The frames of `data` and the engines' octahedral impostor of the same frames drawn at the
/// scale of screen size `size` ([`crate::sphere::asset::measured`] over the bounding sphere's
/// [`sphere_px`]: 8 needed directions, 3 × 3; the two-step baseline is not drawn): the frames'
/// measurement, the engine's worst PSNR (dB) and the engine's figures.
fn frames_measured(
    data: &SphereImages,
    size: usize,
    needs: &Needs,
    source: &Source,
) -> Result<(Measurement, f64, MethodStats), PipelineError> {
    let px = sphere_px(size, sphere_radius(source)?);
    let ((ours, engine), _, _) =
        crate::sphere::asset::measured(data, needs, px, source, false, measure_one_step)?;
    let m = crate::sphere::asset::exact_warp_measurement(&ours, String::new(), size);
    Ok((m, engine.psnr_min, engine))
}

/// The engine's steps per pixel (its depth reads; [`super`] docs): one per enclosing frame of
/// the one-step offset, whose `4·(1 + 3)` texel reads per frame the measurement counts.
fn engine_steps(engine: &MethodStats) -> f64 {
    engine.reads_mean / 16.0
}

/// A member's figures at `size` pixels over the 4 measured directions (3 × 3 rays per pixel),
/// as every representation is measured (frames over the sphere and the engine's impostor: 8,
/// [`frames_measured`]; the engine's worst PSNR alone); the source is the truth (worst PSNR
/// infinite).
fn measured_at(
    member: Member,
    size: usize,
    members: &Members,
    needs: &Needs,
    source: &Source,
) -> Result<Measurement, PipelineError> {
    match member {
        Member::Source => Ok(Measurement {
            worst_psnr_db: f64::INFINITY,
            ..Measurement::default()
        }),
        Member::Mesh { level } => {
            let scores = score_levels(
                source,
                &[members.levels[level]],
                needs,
                size,
                &measure_views(needs, 4),
                Supersample::of(3),
            )?
            .remove(0);
            Ok(crate::representation::fold(
                String::new(),
                &scores,
                Some(1.0),
            ))
        }
        Member::Impostor { size: s } => {
            Ok(Parallax::measure(members.impostor_of(s)?, needs, size, source)?.0)
        }
        Member::Frames { size: s } => {
            Ok(frames_measured(members.frames_of(s)?, size, needs, source)?.0)
        }
        Member::Engine { size: s } => {
            let (_, engine, _) = frames_measured(members.frames_of(s)?, size, needs, source)?;
            Ok(Measurement {
                worst_psnr_db: engine,
                ..Measurement::default()
            })
        }
    }
}

/// A chain verified at both edges of every band, with what it measured.
struct VerifiedChain {
    chain: Chain,
    /// `(band, size, worst PSNR dB)` per measured edge.
    edges: Vec<(usize, usize, f64)>,
    repairs: usize,
}

/// The cheapest chain of `family`, verified: every band's member measured at both its edges
/// by `measure` (which the caller caches, shared by the families), a member that misses the target at a
/// size has its reach lowered below that size and the chain is chosen again. Ends: every
/// repair lowers a reach.
#[allow(clippy::too_many_arguments)]
fn verified(
    candidates: &mut [Candidate],
    family: Family,
    tops: &[f64],
    model: &CostModel,
    texture_bytes: u64,
    measure: &mut dyn FnMut(Member, usize) -> Result<f64, PipelineError>,
    needs: &Needs,
) -> Result<Option<VerifiedChain>, PipelineError> {
    let mut repairs = 0;
    loop {
        let Some(chain) = cheapest_chain(
            candidates,
            family,
            tops,
            needs.screen_px[0],
            model,
            texture_bytes,
        ) else {
            return Ok(None);
        };
        let mut measured = Vec::new();
        let mut changed = false;
        for (b, band) in chain.bands.iter().enumerate() {
            if band.member == Member::Source {
                continue;
            }
            for size in band_edges(band.from_px, band.to_px, needs) {
                let worst = measure(band.member, size)?;
                measured.push((b, size, worst));
                if worst >= needs.quality_db {
                    continue;
                }
                let c = candidates
                    .iter_mut()
                    .find(|c| c.member == band.member)
                    .expect("a chain's member is a candidate");
                if (size as f64) < band.to_px.min(needs.screen_px[1]).round() {
                    // The bottom edge: drawn only above it from now on.
                    let f = c.floor_px.map_or(size as f64, |f| f.max(size as f64));
                    if c.floor_px != Some(f) {
                        c.floor_px = Some(f);
                        changed = true;
                    }
                    continue;
                }
                let lowered = lowered_reach(c.reach, tops.iter().copied(), size);
                if lowered != c.reach {
                    c.reach = lowered;
                    changed = true;
                }
            }
        }
        if !changed {
            return Ok(Some(VerifiedChain {
                chain,
                edges: measured,
                repairs,
            }));
        }
        repairs += 1;
    }
}

impl Representation for AutoRepr {
    const NAME: &'static str = "auto";
    const CASTS_RAYS: bool = true;
    type Spec = AutoSpec;
    type Data = AutoChain;
    type Decisions = AutoDecisions;

    fn validate(spec: &AutoSpec) -> Result<(), String> {
        if let Some(t) = spec.target_db
            && !(t.is_finite() && t > 0.0)
        {
            return Err(format!(
                "auto.target_db = {t} must be a positive number of dB"
            ));
        }
        if spec.families.is_empty() {
            return Err(format!(
                "auto.families must list at least one of {}",
                FAMILIES.join(", ")
            ));
        }
        for f in &spec.families {
            if !FAMILIES.contains(&f.as_str()) {
                return Err(format!(
                    "auto.families: unknown family '{f}' ({})",
                    FAMILIES.join(", ")
                ));
            }
        }
        if !(8.0..=2048.0).contains(&spec.max_px) {
            return Err(format!(
                "auto.max_px = {} must lie in 8..=2048",
                spec.max_px
            ));
        }
        MeshLodRepr::validate(&spec.mesh_lod).map_err(|e| format!("auto.{e}"))?;
        Parallax::validate(&spec.parallax).map_err(|e| format!("auto.{e}"))?;
        SphereRepr::validate(&spec.sphere).map_err(|e| format!("auto.{e}"))?;
        spec.cost.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px": needs.screen_px, "azimuth_deg": needs.azimuth_deg,
                "elevation_deg": needs.elevation_deg, "quality_db": needs.quality_db,
                "lighting": needs.lighting })
    }

    fn estimate(spec: &AutoSpec, needs: &Needs, input: &InputSize) -> Estimate {
        // Every candidate is built and held at once: the levels' estimate and each impostor's.
        let mut e = Estimate::default();
        let mut add = |x: Estimate| {
            e.peak_bytes += x.peak_bytes;
            e.output_bytes += x.output_bytes;
        };
        if spec.families.iter().any(|f| f == "mesh_lod") && input.mesh.is_some() {
            add(MeshLodRepr::estimate(&spec.mesh_lod, needs, input));
        }
        if spec.families.iter().any(|f| f == "parallax") {
            for s in preview_sizes(needs, spec.max_px) {
                if s <= spec.parallax.size {
                    add(Parallax::estimate(
                        &impostor_spec(spec, s),
                        &impostor_needs(needs, s),
                        input,
                    ));
                }
            }
        }
        if spec.families.iter().any(|f| f == "sphere") {
            for s in preview_sizes(needs, spec.max_px) {
                if s <= spec.sphere.size {
                    // The bounding sphere is at most √3 times the cylinder's radius.
                    let f = sphere_px(s, 3f64.sqrt());
                    add(SphereRepr::estimate(
                        &frames_spec(spec, f),
                        &impostor_needs(needs, f),
                        input,
                    ));
                }
            }
        }
        e
    }

    fn plan(
        spec: &AutoSpec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, AutoDecisions), PipelineError> {
        let target_db = spec.target_db.unwrap_or(needs.quality_db);
        let needs = with_target(needs, target_db);
        let mut plan = Plan::default();
        let sizes = preview_sizes(&needs, spec.max_px);
        if source.shape()?.as_mesh().is_none() {
            plan.refuse(
                "the chain needs a mesh (`mesh = ...`): its bands end at the source mesh, drawn where no stand-in meets the target".into(),
            );
            return Ok((
                plan,
                AutoDecisions {
                    target_db,
                    sizes,
                    mesh: None,
                    impostors: Vec::new(),
                    frames: Vec::new(),
                },
            ));
        }
        let asks = |family: &str| spec.families.iter().any(|f| f == family);
        let mut mesh = None;
        if asks("mesh_lod") {
            let lod_spec = MeshLodSpec {
                max_px: spec.max_px,
                ..spec.mesh_lod.clone()
            };
            let (p, d) = MeshLodRepr::plan(&lod_spec, &needs, source)?;
            match p.refused {
                Some(reason) => plan.skip("simplified meshes".into(), reason),
                None => {
                    for item in p.items {
                        match item.skipped {
                            None => plan.build(format!("mesh_lod: {}", item.what)),
                            Some(r) => plan.skip(format!("mesh_lod: {}", item.what), r),
                        }
                    }
                    mesh = Some(d);
                }
            }
        }
        let mut impostors = Vec::new();
        if asks("parallax") {
            impostors = plan_per_size(
                &mut plan,
                &sizes,
                ("parallax", spec.parallax.size),
                |s| format!("impostor of {s}² views"),
                |s| Parallax::plan(&impostor_spec(spec, s), &impostor_needs(&needs, s), source),
                |s, d| {
                    format!(
                        "impostor candidate: {} of {} views of {s}²",
                        d.views.len(),
                        spec.parallax.views
                    )
                },
            )?;
        }
        let mut frames = Vec::new();
        if asks("sphere") {
            let radius = sphere_radius(source)?;
            frames = plan_per_size(
                &mut plan,
                &sizes,
                ("sphere", spec.sphere.size),
                |s| format!("frames over the sphere for {s} px"),
                // Frame texels as fine as the pixels across the bounding sphere at this size.
                |s| {
                    let f = sphere_px(s, radius);
                    SphereRepr::plan(&frames_spec(spec, f), &impostor_needs(&needs, f), source)
                },
                |_, d| {
                    format!(
                        "frames candidate: {g}×{g} frames of {}² over the {}, and the engines' octahedral impostor of the same frames (the baseline chain)",
                        d.size,
                        match d.coverage {
                            crate::sphere::Coverage::Hemisphere => "upper hemisphere",
                            crate::sphere::Coverage::Sphere => "sphere",
                        },
                        g = d.grid
                    )
                },
            )?;
        }
        if mesh.is_none() && impostors.is_empty() && frames.is_empty() {
            plan.refuse(format!(
                "no candidate family applies (families {:?}): nothing but the source to draw",
                spec.families
            ));
        }
        plan.build(format!(
            "the chain chosen over bands ending at {sizes:?} px for {target_db} dB: at each band the candidate of least cost (draw steps at its top, {} steps per triangle, {} per byte) that met the target there, then verified at both edges of every band (4 directions, 3×3) and chosen again where a member misses",
            spec.cost.triangle_steps, spec.cost.byte_steps
        ));
        Ok((
            plan,
            AutoDecisions {
                target_db,
                sizes,
                mesh,
                impostors,
                frames,
            },
        ))
    }

    fn build(
        spec: &AutoSpec,
        needs: &Needs,
        decisions: &AutoDecisions,
        source: &Source,
    ) -> Result<(AutoChain, serde_json::Value), PipelineError> {
        let needs = &with_target(needs, decisions.target_db);
        let sizes = &decisions.sizes;
        let tops = band_tops(sizes, needs.screen_px);
        let mut candidates = Vec::new();
        let source_mesh = source
            .shape()?
            .as_mesh()
            .ok_or_else(|| PipelineError::WrongSource {
                asset: source.name.into(),
                needed: "a mesh (the chain ends at the source mesh: `mesh = ...`)",
            })?;
        // The levels' files as written: under the members' prefix, which their image URIs
        // carry; the source sized the same way, sharing the same textures (what drawing it
        // needs resident).
        let mut images = ExternalImages::default();
        images.uri_prefix = MESH_PREFIX.into();
        let source_bytes = source_mesh.to_glb_beside(&mut images)?.bytes.len() as u64;
        // The object's share of the picture: what a mesh shades.
        let coverage = {
            let window = Window::for_needs(needs, 64);
            let view = measure_views(needs, 1)[0];
            let truth = window.truth(source, view, Supersample::of(2))?;
            let n = truth.pixels.len().max(1) as f64;
            truth.pixels.iter().map(|p| f64::from(p[3])).sum::<f64>() / n
        };
        candidates.push(Candidate {
            member: Member::Source,
            triangles: source_mesh.triangle_count(),
            bytes: source_bytes,
            shares_textures: true,
            steps_per_pixel: 1.0,
            pixel_share: coverage,
            reach: None,
            floor_px: None,
        });
        // Simplified levels: built, previewed (3 directions, 2 × 2), their files sized.
        let t0 = Instant::now();
        let mut levels: Vec<(f64, altrep_data_gen::Simplified)> = Vec::new();
        let mut lod_report = serde_json::Value::Null;
        if let Some(d) = &decisions.mesh {
            let (kept, dropped) = simplify_levels(source_mesh, &spec.mesh_lod, &d.targets)?;
            let meshes: Vec<&Mesh> = kept.iter().map(|(_, s)| &s.mesh).collect();
            let preview = reach(source, &meshes, needs, sizes)?;
            for (l, (_, s)) in kept.iter().enumerate() {
                let file = s.mesh.to_glb_beside(&mut images)?;
                candidates.push(Candidate {
                    member: Member::Mesh { level: l },
                    triangles: s.mesh.triangle_count(),
                    bytes: file.bytes.len() as u64,
                    shares_textures: true,
                    steps_per_pixel: 1.0,
                    pixel_share: coverage,
                    reach: preview.reach[l],
                    floor_px: None,
                });
            }
            // The source reads the same textures (the user holds them).
            lod_report = json!({ "dropped": dropped, "preview_worst_db": preview.worst_db });
            levels = kept;
        }
        let mesh_s = secs(t0);
        let texture_bytes: u64 = images.files.iter().map(|f| f.bytes.len() as u64).sum();
        // Impostors: built, measured at their own size (4 directions, 3 × 3), files sized.
        let t1 = Instant::now();
        let mut impostors: Vec<(usize, ParallaxData)> = Vec::new();
        let mut measured: HashMap<(Member, usize), f64> = HashMap::new();
        let mut pruned = Vec::new();
        let mut last_steps: Option<f64> = None;
        for (s, d) in &decisions.impostors {
            // The cost model first: an impostor shades at least one step per pixel of its
            // quad, and at least half the steps per pixel of the next smaller impostor (its
            // march lengthens with the views' size: measured ratios of consecutive sizes 0.90
            // to 1.99 on the shipped meshes and the rock). Where a previewed level meets the
            // target at this size for no more than that (bytes weighed in), the impostor
            // cannot be cheaper here: it is not built.
            let p = *s as f64;
            let least = p * p * last_steps.map_or(1.0, |k: f64| (0.5 * k).max(1.0));
            if let Some(c) = candidates.iter().find(|c| {
                matches!(c.member, Member::Mesh { .. })
                    && c.reaches(p)
                    && spec.cost.draw_steps(c, p)
                        + spec.cost.byte_steps * (c.bytes + texture_bytes) as f64
                        <= least
            }) {
                pruned.push(json!({ "size": s, "reason": format!(
                    "{} meets the target at {s} px for {:.0} steps, no more than an impostor's least ({least:.0})",
                    c.member, spec.cost.draw_steps(c, p)) }));
                continue;
            }
            let (data, _) = Parallax::build(
                &impostor_spec(spec, *s),
                &impostor_needs(needs, *s),
                d,
                source,
            )?;
            let (m, _) = Parallax::measure(&data, needs, *s, source)?;
            let mut w = AssetWriter::sizing();
            Parallax::write(&data, &mut w)?;
            let member = Member::Impostor { size: *s };
            measured.insert((member, *s), m.worst_psnr_db);
            last_steps = m.mean_steps;
            candidates.push(Candidate {
                member,
                triangles: 0,
                bytes: w.sized()?,
                shares_textures: false,
                steps_per_pixel: m.mean_steps.unwrap_or(1.0),
                pixel_share: 1.0,
                reach: (m.worst_psnr_db >= needs.quality_db).then_some(*s as f64),
                floor_px: None,
            });
            impostors.push((*s, data));
        }
        let impostor_s = secs(t1);
        // Frames over the sphere: built, measured at their own size (8 directions, 3 × 3) with
        // the engines' octahedral impostor of the same frames, files sized. Not pruned: the
        // engine-only chain is the baseline, and it is given every size.
        let t_frames = Instant::now();
        let mut frames: Vec<(usize, SphereImages)> = Vec::new();
        // Their quad spans the bounding sphere's window: radius² times the cylinder's pixels.
        let quad_share = sphere_radius(source)?.powi(2);
        for (s, d) in &decisions.frames {
            let f = d.size;
            let (data, _) =
                SphereRepr::build(&frames_spec(spec, f), &impostor_needs(needs, f), d, source)?;
            let (ours, engine, m) = frames_measured(&data, *s, needs, source)?;
            let mut w = AssetWriter::sizing();
            SphereRepr::write(&data, &mut w)?;
            let files = w.sized_files()?;
            let all: u64 = files.iter().map(|(_, b)| b).sum();
            // An engine ships the albedo, normal and depth atlases, not the cone bounds.
            let bounds: u64 = files
                .iter()
                .filter(|(role, _)| role == "bounds")
                .map(|(_, b)| b)
                .sum();
            let p = *s as f64;
            let (fm, em) = (Member::Frames { size: *s }, Member::Engine { size: *s });
            measured.insert((fm, *s), ours.worst_psnr_db);
            measured.insert((em, *s), engine);
            candidates.push(Candidate {
                member: fm,
                triangles: 0,
                bytes: all,
                shares_textures: false,
                steps_per_pixel: ours.mean_steps.unwrap_or(1.0),
                pixel_share: quad_share,
                reach: (ours.worst_psnr_db >= needs.quality_db).then_some(p),
                floor_px: None,
            });
            candidates.push(Candidate {
                member: em,
                triangles: 0,
                bytes: all - bounds,
                shares_textures: false,
                steps_per_pixel: engine_steps(&m),
                pixel_share: quad_share,
                reach: (engine >= needs.quality_db).then_some(p),
                floor_px: None,
            });
            frames.push((*s, data));
        }
        let frames_s = secs(t_frames);
        let previewed = candidates.clone();
        // The chains: automatic, then the single-family ones for comparison, each verified.
        let t2 = Instant::now();
        let meshes: Vec<&Mesh> = levels.iter().map(|(_, s)| &s.mesh).collect();
        let impostor_refs: Vec<(usize, &ParallaxData)> =
            impostors.iter().map(|(s, d)| (*s, d)).collect();
        let frame_refs: Vec<(usize, &SphereImages)> = frames.iter().map(|(s, d)| (*s, d)).collect();
        let members = Members {
            levels: &meshes,
            impostors: &impostor_refs,
            frames: &frame_refs,
        };
        let mut measure = |member: Member, size: usize| -> Result<f64, PipelineError> {
            if let Some(&w) = measured.get(&(member, size)) {
                return Ok(w);
            }
            match member {
                // One measurement draws both the frames and the engine's blend of them.
                Member::Frames { size: s } | Member::Engine { size: s } => {
                    let (ours, engine, _) =
                        frames_measured(members.frames_of(s)?, size, needs, source)?;
                    measured.insert((Member::Frames { size: s }, size), ours.worst_psnr_db);
                    measured.insert((Member::Engine { size: s }, size), engine);
                }
                _ => {
                    let w = measured_at(member, size, &members, needs, source)?.worst_psnr_db;
                    measured.insert((member, size), w);
                }
            }
            Ok(measured[&(member, size)])
        };
        let mut chains = Vec::new();
        for family in [
            Family::All,
            Family::Meshes,
            Family::Impostors,
            Family::Frames,
            Family::Engine,
        ] {
            if family != Family::All
                && !candidates
                    .iter()
                    .any(|c| c.member != Member::Source && family.admits(c.member))
            {
                // A family not asked for (or refused by the plan): no chain to compare.
                chains.push((family, None));
                continue;
            }
            let mut c = candidates.clone();
            let v = verified(
                &mut c,
                family,
                &tops,
                &spec.cost,
                texture_bytes,
                &mut measure,
                needs,
            )?;
            if family == Family::All {
                candidates = c;
            }
            chains.push((family, v));
        }
        let verify_s = secs(t2);
        let fronts = pareto_fronts(&candidates, &tops, &spec.cost, texture_bytes);
        let Some(auto) = chains[0].1.as_ref() else {
            return Err(PipelineError::Spec(
                "no chain: the source is always a candidate".into(),
            ));
        };
        let chain_report = |v: &Option<VerifiedChain>| {
            v.as_ref().map(|v| {
                json!({ "bands": v.chain.bands, "bytes": v.chain.bytes, "cost": v.chain.cost,
                        "edges_worst_db": v.edges, "repairs": v.repairs,
                        "triangles_max": v.chain.bands.iter().map(|b| b.triangles).max() })
            })
        };
        let mut report = json!({
            "target_db": decisions.target_db,
            "tops_px": tops,
            "coverage": coverage,
            "texture_bytes": texture_bytes,
            "candidates": previewed,
            "auto": chain_report(&chains[0].1),
            "meshes_only": chain_report(&chains[1].1),
            "impostors_only": chain_report(&chains[2].1),
            "frames_only": chain_report(&chains[3].1),
            "engine_only": chain_report(&chains[4].1),
            "pareto": fronts,
            "mesh_lod": lod_report,
            "impostors_pruned": pruned,
            "mesh_s": mesh_s,
            "impostor_s": impostor_s,
            "frames_s": frames_s,
            "verify_s": verify_s,
        });
        // Keep what the automatic chain draws, renumbered. A chain that draws the source at
        // every size (no stand-in met the target over any band, or none was cheaper) keeps the
        // candidate that came closest, undrawn, so that the measurement says by how much it
        // misses: the finest level, else the largest impostor.
        let mut bands = auto.chain.bands.clone();
        let mut undrawn = None;
        if bands.iter().all(|b| b.member == Member::Source) {
            undrawn = if levels.is_empty() {
                impostors
                    .iter()
                    .map(|(s, _)| Member::Impostor { size: *s })
                    .next_back()
                    .or_else(|| {
                        frames
                            .iter()
                            .map(|(s, _)| Member::Frames { size: *s })
                            .next_back()
                    })
            } else {
                Some(Member::Mesh { level: 0 })
            };
        }
        let keeps = |m: Member| undrawn == Some(m) || bands.iter().any(|b| b.member == m);
        let used_levels: Vec<usize> = (0..levels.len())
            .filter(|l| keeps(Member::Mesh { level: *l }))
            .collect();
        let renumber = |m: Member| match m {
            Member::Mesh { level } => Member::Mesh {
                level: used_levels.iter().position(|u| *u == level).unwrap_or(0),
            },
            other => other,
        };
        let impostors: Vec<(usize, ParallaxData)> = impostors
            .into_iter()
            .filter(|(s, _)| keeps(Member::Impostor { size: *s }))
            .collect();
        let frames: Vec<(usize, SphereImages)> = frames
            .into_iter()
            .filter(|(s, _)| keeps(Member::Frames { size: *s }))
            .collect();
        let undrawn = undrawn.map(renumber);
        for b in &mut bands {
            b.member = renumber(b.member);
        }
        let lod_levels: Vec<Level> = levels
            .into_iter()
            .enumerate()
            .filter(|(l, _)| used_levels.contains(l))
            .enumerate()
            .map(|(i, (_, (ratio, s)))| Level {
                info: LevelInfo {
                    ratio,
                    triangles: s.mesh.triangle_count(),
                    error: s.error,
                    // The largest size the chain draws it at (verified there).
                    max_px: bands
                        .iter()
                        .filter(|b| b.member == Member::Mesh { level: i })
                        .map(|b| b.to_px)
                        .reduce(f64::max),
                    texture_px: None,
                },
                mesh: s.mesh,
            })
            .collect();
        let mut mesh = (!lod_levels.is_empty()).then(|| MeshLod {
            chain: mesh_bands(&bands),
            levels: lod_levels,
        });
        // Each drawn level's textures reduced to the sizes it is drawn at, verified again.
        let t3 = Instant::now();
        if let Some(lod) = &mut mesh {
            crate::mesh_lod::reduce_textures(&mut lod.levels, &lod.chain, needs, source)?;
        }
        let textures_s = secs(t3);
        let chain = AutoChain {
            chain: bands,
            mesh,
            impostors,
            frames,
            undrawn,
            target_db: decisions.target_db,
        };
        // What the files weigh once the textures are reduced (the chains' `bytes` are those
        // of the candidates as chosen, with the source's textures): the levels sized again,
        // the impostors and frames as they were sized when built (the same files).
        let mut sizing = AssetWriter::sizing();
        if let Some(lod) = &chain.mesh {
            sizing.member(MESH_PREFIX, |w| MeshLodRepr::write(lod, w))?;
        }
        let kept = chain
            .impostors
            .iter()
            .map(|(s, _)| Member::Impostor { size: *s })
            .chain(
                chain
                    .frames
                    .iter()
                    .map(|(s, _)| Member::Frames { size: *s }),
            );
        let image_bytes: u64 = kept
            .filter_map(|m| candidates.iter().find(|c| c.member == m))
            .map(|c| c.bytes)
            .sum();
        report["files_bytes"] = json!(sizing.sized()? + image_bytes);
        report["textures_s"] = json!(textures_s);
        report["texture_px"] = json!(chain.mesh.as_ref().map(|m| {
            m.levels
                .iter()
                .map(|l| l.info.texture_px)
                .collect::<Vec<_>>()
        }));
        Ok((chain, report))
    }

    fn write(data: &AutoChain, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let mut members = Vec::new();
        if let Some(lod) = &data.mesh {
            let m = w.member(MESH_PREFIX, |w| MeshLodRepr::write(lod, w))?;
            members.push(
                json!({ "prefix": MESH_PREFIX, "representation": MeshLodRepr::NAME, "metadata": m }),
            );
        }
        for (s, d) in &data.impostors {
            let prefix = format!("impostor{s}-");
            let m = w.member(&prefix, |w| Parallax::write(d, w))?;
            members.push(json!({ "prefix": prefix, "representation": Parallax::NAME,
                                 "size": s, "metadata": m }));
        }
        for (s, d) in &data.frames {
            let prefix = format!("frames{s}-");
            let m = w.member(&prefix, |w| SphereRepr::write(d, w))?;
            members.push(
                json!({ "prefix": prefix, "representation": SphereRepr::NAME,
                                 "size": s, "metadata": m }),
            );
        }
        Ok(
            json!({ "chain": data.chain, "members": members, "undrawn": data.undrawn,
                   "target_db": data.target_db }),
        )
    }

    fn read(r: &AssetReader) -> Result<AutoChain, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let chain: Vec<AutoBand> = serde_json::from_value(m["chain"].clone())
            .map_err(|e| r.content(format!("metadata.chain: {e}")))?;
        let target_db = m["target_db"]
            .as_f64()
            .ok_or_else(|| r.content("metadata.target_db is not a number".into()))?;
        let members = m["members"]
            .as_array()
            .ok_or_else(|| r.content("metadata.members is not a list".into()))?;
        let (mut mesh, mut impostors, mut frames) = (None, Vec::new(), Vec::new());
        for (i, member) in members.iter().enumerate() {
            let prefix = member["prefix"]
                .as_str()
                .ok_or_else(|| r.content(format!("metadata.members[{i}].prefix")))?;
            let repr = member["representation"].as_str().unwrap_or_default();
            let inner = r.member(prefix, repr, member["metadata"].clone())?;
            if repr == MeshLodRepr::NAME && mesh.is_none() {
                mesh = Some(MeshLodRepr::read(&inner)?);
            } else if repr == Parallax::NAME {
                let size = member["size"]
                    .as_u64()
                    .ok_or_else(|| r.content(format!("metadata.members[{i}].size")))?
                    as usize;
                let data = Parallax::read(&inner)?;
                if data.images.params.width != size {
                    return Err(r
                        .content(format!(
                            "metadata.members[{i}]: views of {}², the member says {size}²",
                            data.images.params.width
                        ))
                        .into());
                }
                impostors.push((size, data));
            } else if repr == SphereRepr::NAME {
                let size = member["size"]
                    .as_u64()
                    .ok_or_else(|| r.content(format!("metadata.members[{i}].size")))?
                    as usize;
                frames.push((size, SphereRepr::read(&inner)?));
            } else {
                return Err(r
                    .content(format!(
                        "metadata.members[{i}]: representation '{repr}' (mesh_lod once, parallax, sphere)"
                    ))
                    .into());
            }
        }
        let undrawn: Option<Member> = serde_json::from_value(m["undrawn"].clone())
            .map_err(|e| r.content(format!("metadata.undrawn: {e}")))?;
        // Every band's member must be held, and the undrawn one.
        let levels = mesh.as_ref().map_or(0, |m: &MeshLod| m.levels.len());
        let holds = |member: Member| match member {
            Member::Source => true,
            Member::Mesh { level } => level < levels,
            Member::Impostor { size } => impostors.iter().any(|(s, _)| *s == size),
            Member::Frames { size } => frames.iter().any(|(s, _)| *s == size),
            // The baseline is measured, never drawn by a written chain.
            Member::Engine { .. } => false,
        };
        if let Some(u) = undrawn.filter(|u| !holds(*u) || *u == Member::Source) {
            return Err(r
                .content(format!(
                    "metadata.undrawn names {u}, which the folder does not hold"
                ))
                .into());
        }
        for (b, band) in chain.iter().enumerate() {
            let held = holds(band.member);
            let ordered =
                band.from_px.is_finite() && band.to_px.is_finite() && band.from_px <= band.to_px;
            if !held || !ordered {
                return Err(r
                    .content(format!(
                        "metadata.chain[{b}] draws {} over [{}, {}] px, which the folder does not hold",
                        band.member, band.from_px, band.to_px
                    ))
                    .into());
            }
        }
        Ok(AutoChain {
            chain,
            mesh,
            impostors,
            frames,
            undrawn,
            target_db,
        })
    }

    fn details(build: &serde_json::Value) -> Option<String> {
        let member = |m: &serde_json::Value| -> String {
            serde_json::from_value::<Member>(m.clone()).map_or("?".into(), |m| m.to_string())
        };
        let mut md = format!(
            "Chains over the same candidates, verified at both edges of every band (target {} dB): \
             the automatic one, then each family with the source alone: simplified meshes, images \
             with parallax, frames over the sphere, and the engines' octahedral impostor of the \
             same frames (the baseline). Cost: shader steps (docs/design.md §10c).\n\n\
             | chain | bands: sizes (px) → member, triangles, worst dB at the edges | bytes | cost | repairs |\n\
             |---|---|---|---|---|\n",
            build.get("target_db")?.as_f64()?
        );
        for (key, name) in CHAINS {
            let c = &build[key];
            let Some(bands) = c["bands"].as_array() else {
                md += &format!("| {name} | not built: no candidate of the family | – | – | – |\n");
                continue;
            };
            let edges = c["edges_worst_db"].as_array().cloned().unwrap_or_default();
            let text: Vec<String> = bands
                .iter()
                .enumerate()
                .map(|(b, band)| {
                    let worst: Vec<String> = edges
                        .iter()
                        .filter(|e| e[0].as_u64() == Some(b as u64))
                        .map(|e| format!("{:.2}", e[2].as_f64().unwrap_or(f64::NAN)))
                        .collect();
                    format!(
                        "{}–{} → {}, {} tris{}",
                        band["from_px"],
                        band["to_px"],
                        member(&band["member"]),
                        band["triangles"],
                        if worst.is_empty() {
                            String::new()
                        } else {
                            format!(" ({})", worst.join(", "))
                        }
                    )
                })
                .collect();
            md += &format!(
                "| {name} | {} | {} | {:.0} | {} |\n",
                text.join("; "),
                c["bytes"],
                c["cost"].as_f64().unwrap_or(f64::NAN),
                c["repairs"]
            );
        }
        md += &error_against_size(build);
        md += "\nCandidates (as previewed; reach: the largest size where every preview view met the target):\n\n\
               | candidate | triangles | bytes | steps per pixel | reach (px) |\n|---|---|---|---|---|\n";
        for c in build["candidates"].as_array()? {
            md += &format!(
                "| {} | {} | {} | {:.2} | {} |\n",
                member(&c["member"]),
                c["triangles"],
                c["bytes"],
                c["steps_per_pixel"].as_f64().unwrap_or(f64::NAN),
                c["reach"].as_f64().map_or("–".into(), |r| format!("{r}"))
            );
        }
        if let Some(pruned) = build["impostors_pruned"]
            .as_array()
            .filter(|p| !p.is_empty())
        {
            let sizes: Vec<String> = pruned.iter().map(|p| format!("{}²", p["size"])).collect();
            md += &format!(
                "\nImpostors not built (a level meets the target there for less than an impostor's least cost): {}.\n",
                sizes.join(", ")
            );
        }
        md += "\nPareto front of each band's top (draw steps, bytes) among the candidates meeting the target there:\n\n";
        for entry in build["pareto"].as_array()? {
            let front: Vec<String> = entry[1]
                .as_array()?
                .iter()
                .filter(|p| p["on_front"].as_bool() == Some(true))
                .map(|p| {
                    format!(
                        "{} ({:.0} steps, {} B)",
                        member(&p["member"]),
                        p["draw_steps"].as_f64().unwrap_or(f64::NAN),
                        p["bytes"]
                    )
                })
                .collect();
            md += &format!("- {} px: {}\n", entry[0], front.join(", "));
        }
        Some(md)
    }

    /// The error against screen size of every chain built, as a plot
    /// (`ASSET-auto-error-against-size.png`): the table of [`Self::details`] drawn.
    fn plots(build: &serde_json::Value, asset: &str) -> Result<Vec<Picture>, PipelineError> {
        let lines = size_lines(build);
        if lines.iter().all(|l| l.points.is_empty()) {
            return Ok(Vec::new());
        }
        let target = build["target_db"].as_f64().unwrap_or(f64::NAN);
        let title = format!("{asset}: error against screen size");
        let rgb = crate::report::plot::error_against_size(&title, &lines, target)?;
        let (w, h) = crate::report::plot::SIZE_PLOT;
        let mut image = RgbaImage::new(w as usize, h as usize);
        for (px, c) in image.pixels.iter_mut().zip(rgb.chunks_exact(3)) {
            let l = |k: usize| altrep_data_gen::srgb_to_linear(f32::from(c[k]) / 255.0);
            *px = [l(0), l(1), l(2), 1.0];
        }
        Ok(vec![Picture {
            file: format!("{asset}-auto-error-against-size.png"),
            caption: format!(
                "{asset}: worst PSNR over the measured directions at each size every chain was verified at (target {target} dB, dashed; sizes where a chain draws the source are not points)"
            ),
            image,
        }])
    }

    fn measure_size(d: &AutoDecisions) -> usize {
        d.sizes.last().copied().unwrap_or(0)
    }

    fn measure(
        data: &AutoChain,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let needs = &with_target(needs, data.target_db);
        let meshes: Vec<&Mesh> = data
            .mesh
            .as_ref()
            .map(|m| m.levels.iter().map(|l| &l.mesh).collect())
            .unwrap_or_default();
        let impostors: Vec<(usize, &ParallaxData)> =
            data.impostors.iter().map(|(s, d)| (*s, d)).collect();
        let frames: Vec<(usize, &SphereImages)> =
            data.frames.iter().map(|(s, d)| (*s, d)).collect();
        let members = Members {
            levels: &meshes,
            impostors: &impostors,
            frames: &frames,
        };
        let mut parts = Vec::new();
        let mut what = Vec::new();
        let mut measured_sizes = Vec::new();
        for (b, band) in data.chain.iter().enumerate() {
            if band.member == Member::Source {
                continue;
            }
            for size in band_edges(band.from_px, band.to_px, needs) {
                let m = measured_at(band.member, size, &members, needs, source)?;
                what.push(format!("band {b} at {size} px"));
                parts.push((m, band.steps_per_pixel));
                measured_sizes.push(size);
            }
        }
        if parts.is_empty() {
            // The source at every size: the candidate that came closest, at the needs' ends.
            let Some(u) = data.undrawn else {
                return Err(PipelineError::Spec(
                    "the chain draws the source everywhere and keeps no candidate to measure"
                        .into(),
                ));
            };
            let min = crate::mesh_lod::MIN_MEASURED_PX;
            let top = match u {
                Member::Impostor { size: s } | Member::Frames { size: s } => size.min(s),
                _ => size,
            };
            let mut sizes = vec![
                needs.screen_px[0].max(min).round() as usize,
                top.max(min as usize),
            ];
            sizes.dedup();
            for s in sizes {
                let m = measured_at(u, s, &members, needs, source)?;
                what.push(format!(
                    "{u} (the chain draws the source at every size; kept undrawn) at {s} px"
                ));
                parts.push((m, 0.0));
                measured_sizes.push(s);
            }
        }
        let biggest = measured_sizes.iter().copied().max().unwrap_or(size);
        let window = Window::for_needs(needs, biggest);
        let n = parts.len() as f64;
        let mut m = Measurement {
            method: format!(
                "each band's member at both its edges ({}), 4 needed directions each (frames over the sphere: 8, over the bounding sphere's window), vs truth 3×3 supersampled{}",
                what.join(", "),
                elevation_note(needs, window)
            ),
            psnr_db: parts.iter().map(|(m, _)| m.psnr_db).sum::<f64>() / n,
            worst_psnr_db: parts
                .iter()
                .map(|(m, _)| m.worst_psnr_db)
                .fold(f64::INFINITY, f64::min),
            iou: parts.iter().map(|(m, _)| m.iou).sum::<f64>() / n,
            coverage_error: Some(
                parts
                    .iter()
                    .map(|(m, _)| m.coverage_error.unwrap_or(0.0))
                    .sum::<f64>()
                    / n,
            ),
            mean_steps: Some(parts.iter().map(|(_, s)| s).sum::<f64>() / n),
            ..Measurement::default()
        };
        m.size = biggest;
        // The picture: truth | each member of the chain, smallest sizes first, at the largest
        // measured size.
        let view = measure_views(needs, 4)[0];
        let k = Supersample::of(3);
        let mut images = vec![window.truth(source, view, k)?];
        let mut drawn = Vec::new();
        let undrawn = data.undrawn.map(|u| AutoBand {
            from_px: needs.screen_px[0],
            to_px: needs.screen_px[1],
            member: u,
            triangles: 0,
            steps_per_pixel: 0.0,
            draw_steps: 0.0,
        });
        for band in data.chain.iter().chain(&undrawn) {
            let image = match band.member {
                Member::Source => continue,
                Member::Mesh { level } => draw(source, meshes[level], window, view, k)?,
                Member::Impostor { size } => {
                    let d = members.impostor_of(size)?;
                    let screen = RenderParams {
                        width: biggest,
                        height: biggest * d.images.params.height / d.images.params.width,
                        supersample: Supersample::ONE,
                        light: source.light,
                        mip: biggest != size,
                    };
                    window.place(&render(
                        &d.images,
                        view.azimuth,
                        WarpMethod::Inverse,
                        &screen,
                    )?)
                }
                // Over the bounding sphere's window, at the same scale.
                Member::Frames { size } => {
                    let params = crate::sphere::asset::render_params(
                        sphere_px(biggest, sphere_radius(source)?),
                        source,
                    );
                    let dir = azimuth_elevation(view.azimuth, view.elevation);
                    crate::sphere::render(members.frames_of(size)?, dir, &params)
                        .map_err(crate::sphere::asset::sphere_err)?
                        .image
                }
                Member::Engine { .. } => continue,
            };
            images.push(image);
            drawn.push(if data.chain.iter().any(|b| b.member == band.member) {
                format!("{} for {}–{} px", band.member, band.from_px, band.to_px)
            } else {
                format!("{} (undrawn: the chain draws the source)", band.member)
            });
        }
        let refs: Vec<&RgbaImage> = images.iter().collect();
        let picture = Picture {
            file: format!("{}-auto.png", source.name),
            caption: format!(
                "{}: ground truth | {} (drawn at {biggest} px), azimuth {:.0}°",
                source.name,
                drawn.join(" | "),
                view.azimuth.to_degrees()
            ),
            image: RgbaImage::side_by_side(&refs),
        };
        Ok((m, vec![picture]))
    }
}

/// The chains the build report compares, by key, with their names in the report.
const CHAINS: [(&str, &str); 5] = [
    ("auto", "automatic"),
    ("meshes_only", "meshes only"),
    ("impostors_only", "images with parallax only"),
    ("frames_only", "frames over the sphere only"),
    ("engine_only", "engine octahedral impostor only"),
];

/// A chain's verified edges in the build report: `(band, size in px, worst dB)`.
fn edges(chain: &serde_json::Value) -> Vec<(u64, u64, f64)> {
    chain["edges_worst_db"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|e| Some((e[0].as_u64()?, e[1].as_u64()?, e[2].as_f64()?)))
                .collect()
        })
        .unwrap_or_default()
}

/// A chain's worst PSNR (dB) at each size it was verified at, the lower of the two members
/// meeting at a switch: size (px) → dB.
fn worst_by_size(chain: &serde_json::Value) -> BTreeMap<u64, f64> {
    let mut worst: BTreeMap<u64, f64> = BTreeMap::new();
    for (_, size, db) in edges(chain) {
        let w = worst.entry(size).or_insert(f64::INFINITY);
        *w = w.min(db);
    }
    worst
}

/// Each chain built, as a line of [`crate::report::plot::error_against_size`]: the worst PSNR
/// at each size it was verified at (the lower of the two members meeting at a switch), as
/// [`error_against_size`]'s table. Sizes where a chain draws the source are not points; a chain
/// that draws it at every size is named so in the legend.
fn size_lines(build: &serde_json::Value) -> Vec<crate::report::plot::SizeLine> {
    CHAINS
        .iter()
        .filter(|(key, _)| build[*key]["bands"].is_array())
        .map(|(key, name)| {
            let worst = worst_by_size(&build[*key]);
            crate::report::plot::SizeLine {
                // A chain verified nowhere draws the source at every size: its legend says so.
                name: if worst.is_empty() {
                    format!("{name} (the source throughout)")
                } else {
                    (*name).to_string()
                },
                points: worst.into_iter().map(|(s, db)| (s as f64, db)).collect(),
            }
        })
        .collect()
}

/// The report's table of error against screen size: for each chain of a build report, the
/// worst PSNR (dB) its verification measured at each band edge (the lower of the two members
/// meeting at a switch), `source` where the band draws the truth itself, `–` where the chain
/// was not built. Columns: every size any chain was measured at, ascending.
fn error_against_size(build: &serde_json::Value) -> String {
    let mut sizes: Vec<u64> = CHAINS
        .iter()
        .flat_map(|(k, _)| edges(&build[*k]).into_iter().map(|e| e.1))
        .collect();
    sizes.sort_unstable();
    sizes.dedup();
    if sizes.is_empty() {
        return String::new();
    }
    let mut md = format!(
        "\nError against screen size: the worst PSNR (dB) over the measured directions at each size a chain was verified at (`source`: the band draws the source itself; blank: inside a band, measured at its edges).\n\n| chain | {} |\n|---|{}\n",
        sizes
            .iter()
            .map(|s| format!("{s} px"))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(sizes.len())
    );
    for (key, name) in CHAINS {
        let c = &build[key];
        let Some(bands) = c["bands"].as_array() else {
            continue;
        };
        let worst = worst_by_size(c);
        let cells: Vec<String> = sizes
            .iter()
            .map(|&s| {
                if let Some(w) = worst.get(&s).filter(|w| w.is_finite()) {
                    return format!("{w:.2}");
                }
                let p = s as f64;
                let source = bands.iter().any(|b| {
                    b["member"]["kind"] == "source"
                        && b["from_px"].as_f64().is_some_and(|f| f <= p)
                        && b["to_px"].as_f64().is_some_and(|t| p <= t)
                });
                if source { "source".into() } else { "".into() }
            })
            .collect();
        md += &format!("| {name} | {} |\n", cells.join(" | "));
    }
    md
}

/// The bands of `bands` that draw a mesh level, as the simplified meshes' own chain.
fn mesh_bands(bands: &[AutoBand]) -> Vec<Band> {
    bands
        .iter()
        .filter_map(|b| match b.member {
            Member::Mesh { level } => Some(Band {
                from_px: b.from_px,
                to_px: b.to_px,
                level: Some(level),
            }),
            _ => None,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::size_lines;
    use serde_json::json;

    /// The plot's lines are the table's figures: one per chain built, the worst of the edges
    /// meeting at each size, none for a family not asked for, and a chain drawing the source
    /// at every size named so.
    #[test]
    fn size_lines_take_the_worst_edge_at_each_size() {
        let build = json!({
            "auto": {
                "bands": [{}, {}],
                "edges_worst_db": [[0, 8, 21.5], [0, 32, 24.0], [1, 32, 22.75], [1, 128, 25.0]],
            },
            "meshes_only": null,
            "impostors_only": { "bands": [{}], "edges_worst_db": [] },
        });
        let lines = size_lines(&build);
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].name, "automatic");
        assert_eq!(lines[0].points, [(8.0, 21.5), (32.0, 22.75), (128.0, 25.0)]);
        assert_eq!(
            lines[1].name,
            "images with parallax only (the source throughout)"
        );
        assert!(lines[1].points.is_empty());
    }
}
