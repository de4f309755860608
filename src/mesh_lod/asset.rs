//! Simplified meshes (docs/design.md §10b) in the pipeline: `[asset.mesh_lod]`.
//!
//! Files: `level{k}.glb` for each level `k` the chain draws (finest first; the finest level
//! alone, undrawn, when no level meets the target anywhere), a glTF 2.0 binary file of the level
//! with the source's materials, in the object frame under a root node whose matrix is the
//! placement's inverse; and `texture{i}.png` or `.jpg`, the levels' textures (the source's own
//! files where it had them, or PNGs reduced to the sizes the chain draws), written once beside
//! the levels, which reference them by file name. `metadata.levels` lists each level's ratio,
//! triangles, the simplifier's error, the largest previewed size it met the target at and the
//! side of its reduced textures; `metadata.chain`
//! the bands (`from_px`, `to_px`, `level`; `null` draws the source mesh); `metadata.to_object`
//! the row-major 3 × 4 map from the files' world coordinates back to the object frame (the exact
//! inverse of the `f32` root matrix).

use std::time::Instant;

use altrep_data_gen::{
    ExternalImages, Light, Mesh, MeshLoadOptions, Placement, Simplified, SimplifyParams, UpAxis,
};
use glam::{DAffine3, DMat4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::{Band, Level, LevelInfo, MeshLod, draw, preview_sizes, reach};
use crate::asset::{AssetReader, AssetWriter, Channel, Encoding, FileFormat};
use crate::representation::{
    Estimate, InputSize, Measurement, Needs, Picture, PipelineError, Plan, Representation, Source,
    Window, elevation_note, fold, linear_bytes, measure_views, secs,
};

/// Manifest parameters of simplified meshes (`[asset.mesh_lod]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeshLodSpec {
    /// Triangle ratio of each level against the source, strictly decreasing, each in `(0, 1)`
    /// (default `[0.5, 0.25, 0.1, 0.04, 0.015, 0.005]`).
    pub ratios: Vec<f64>,
    /// Fewest triangles a level keeps (default 12): a ratio below it is raised to it.
    pub min_triangles: usize,
    /// Keep the vertices of open borders in place (default false).
    pub lock_border: bool,
    /// Weight of texture coordinates, vertex colours and normals against the surface's movement
    /// in the simplifier's collapse cost (default 1; 0 simplifies by geometry alone).
    pub attribute_weight: f32,
    /// Largest screen size (pixels, 8–2048; default 512) at which levels are previewed and
    /// verified: above it the chain draws the source mesh (a preview costs rays in proportion
    /// to its pixels).
    pub max_px: f64,
}

impl Default for MeshLodSpec {
    fn default() -> Self {
        Self {
            ratios: vec![0.5, 0.25, 0.1, 0.04, 0.015, 0.005],
            min_triangles: 12,
            lock_border: false,
            attribute_weight: 1.0,
            max_px: 512.0,
        }
    }
}

/// What the planner decided: the triangle target of each level built, and the preview sizes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshLodDecisions {
    /// `(ratio, triangle target)` per level, finest first.
    pub targets: Vec<(f64, usize)>,
    /// Screen sizes (pixels) at which the levels are previewed ([`preview_sizes`]).
    pub sizes: Vec<usize>,
}

/// Simplified meshes for the pipeline.
pub struct MeshLodRepr;

/// The source as a mesh. Errors: a procedural shape or a texture.
fn source_mesh<'a>(source: &Source<'a>) -> Result<&'a Mesh, PipelineError> {
    source
        .shape()?
        .as_mesh()
        .ok_or_else(|| PipelineError::WrongSource {
            asset: source.name.into(),
            needed: "a mesh (simplified meshes are made from triangles: `mesh = ...`)",
        })
}

/// A row-major 3 × 4 matrix of an affine map (the last row of the 4 × 4 is `0 0 0 1`).
fn rows(m: DAffine3) -> [[f64; 4]; 3] {
    let t = DMat4::from(m).transpose().to_cols_array_2d();
    [t[0], t[1], t[2]]
}

/// The levels of `targets` (`(ratio, triangle target)`, finest first, as
/// [`MeshLodDecisions::targets`]) simplified from `mesh` with `spec`'s options, in parallel.
/// A level the simplifier could not take below the one before it (it stops where every further
/// collapse would cross a seam or tear a part) adds nothing: it is dropped, and the second list
/// says why (one JSON record per level). Cost: one simplification per target.
#[allow(clippy::type_complexity)] // the kept levels and the dropped ones' reasons
pub fn simplify_levels(
    mesh: &Mesh,
    spec: &MeshLodSpec,
    targets: &[(f64, usize)],
) -> Result<(Vec<(f64, Simplified)>, Vec<serde_json::Value>), PipelineError> {
    let simplified: Vec<_> = targets
        .par_iter()
        .map(|&(ratio, target)| {
            mesh.simplified(&SimplifyParams {
                target_triangles: target,
                max_error: f64::INFINITY,
                lock_border: spec.lock_border,
                attribute_weight: spec.attribute_weight,
            })
            .map(|s| (ratio, s))
        })
        .collect::<Result<_, _>>()?;
    let mut dropped = Vec::new();
    let mut kept: Vec<(f64, Simplified)> = Vec::new();
    for (ratio, s) in simplified {
        let floor = kept
            .last()
            .map_or(mesh.triangle_count(), |(_, k)| k.mesh.triangle_count());
        if s.mesh.triangle_count() >= floor {
            dropped.push(json!({ "ratio": ratio, "triangles": s.mesh.triangle_count(),
                "reason": format!("the simplifier stopped at {} triangles, no fewer than the level before ({floor})", s.mesh.triangle_count()) }));
        } else {
            kept.push((ratio, s));
        }
    }
    Ok((kept, dropped))
}

impl Representation for MeshLodRepr {
    const NAME: &'static str = "mesh_lod";
    const CASTS_RAYS: bool = true;
    type Spec = MeshLodSpec;
    type Data = MeshLod;
    type Decisions = MeshLodDecisions;

    fn validate(spec: &MeshLodSpec) -> Result<(), String> {
        if spec.ratios.is_empty() {
            return Err("mesh_lod.ratios must list at least one ratio".into());
        }
        if let Some(r) = spec
            .ratios
            .iter()
            .find(|r| !(r.is_finite() && **r > 0.0 && **r < 1.0))
        {
            return Err(format!("mesh_lod.ratios: {r} must lie in (0, 1)"));
        }
        if spec.ratios.windows(2).any(|w| w[1] >= w[0]) {
            return Err(format!(
                "mesh_lod.ratios = {:?} must decrease strictly (finest level first)",
                spec.ratios
            ));
        }
        if spec.min_triangles == 0 {
            return Err("mesh_lod.min_triangles must be at least 1".into());
        }
        if !(spec.attribute_weight.is_finite() && spec.attribute_weight >= 0.0) {
            return Err(format!(
                "mesh_lod.attribute_weight = {} must be finite and ≥ 0",
                spec.attribute_weight
            ));
        }
        if !(8.0..=2048.0).contains(&spec.max_px) {
            return Err(format!(
                "mesh_lod.max_px = {} must lie in 8..=2048",
                spec.max_px
            ));
        }
        Ok(())
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px": needs.screen_px, "azimuth_deg": needs.azimuth_deg,
                "elevation_deg": needs.elevation_deg, "quality_db": needs.quality_db })
    }

    fn estimate(spec: &MeshLodSpec, _needs: &Needs, input: &InputSize) -> Estimate {
        // The levels hold Σ ratios of the source's triangles, each with its BVH; the read-back
        // copy as many again; the source's own memory is counted by the plan. Each file holds
        // its level's share of the geometry and the whole of the textures: at most about the
        // source file's size (a sixteenth of its memory estimate) per level.
        let mesh = input.mesh.unwrap_or(0) as f64;
        let share: f64 = spec.ratios.iter().sum();
        Estimate {
            peak_bytes: linear_bytes(4e6, 2.0 * share, mesh),
            output_bytes: linear_bytes(0.0, spec.ratios.len() as f64 / 16.0, mesh),
        }
    }

    fn plan(
        spec: &MeshLodSpec,
        needs: &Needs,
        source: &Source,
    ) -> Result<(Plan, MeshLodDecisions), PipelineError> {
        let mut plan = Plan::default();
        let mesh = match source_mesh(source) {
            Ok(m) => m,
            Err(PipelineError::WrongSource { needed, .. }) => {
                plan.refuse(format!("this representation needs {needed}"));
                return Ok((
                    plan,
                    MeshLodDecisions {
                        targets: Vec::new(),
                        sizes: Vec::new(),
                    },
                ));
            }
            Err(e) => return Err(e),
        };
        let n = mesh.triangle_count();
        let mut targets = Vec::new();
        let mut last = n;
        for &ratio in &spec.ratios {
            let target = ((ratio * n as f64).ceil() as usize).max(spec.min_triangles);
            if target >= last {
                plan.skip(
                    format!("level at ratio {ratio} ({target} triangles)"),
                    format!(
                        "no fewer triangles than the {} before it (the source has {n}; min_triangles = {})",
                        if targets.is_empty() { "source" } else { "level" },
                        spec.min_triangles
                    ),
                );
                continue;
            }
            plan.build(format!(
                "level {} at ratio {ratio}: at most {target} of {n} triangles",
                targets.len()
            ));
            targets.push((ratio, target));
            last = target;
        }
        if targets.is_empty() {
            plan.refuse(format!(
                "the mesh has {n} triangles: no ratio leaves fewer than that and at least min_triangles = {}",
                spec.min_triangles
            ));
        } else if let Some(&(_, coarsest)) = targets.last() {
            // One simplification, the coarsest (the cheapest of them), tells whether the mesh
            // simplifies at all: where every vertex lies on a seam or an open border, none does.
            let s = mesh.simplified(&SimplifyParams {
                target_triangles: coarsest,
                max_error: f64::INFINITY,
                lock_border: spec.lock_border,
                attribute_weight: spec.attribute_weight,
            })?;
            if s.mesh.triangle_count() >= n {
                plan.refuse(format!(
                    "the simplifier cannot take the mesh below its {n} triangles (every collapse would cross \
                     a texture seam, a material border or an open border): images or volumes are its stand-ins"
                ));
            }
        }
        let sizes = preview_sizes(needs, spec.max_px);
        plan.build(format!(
            "switch sizes chosen by previewing every level against the truth at {sizes:?} px (3 directions, 2×2 rays per pixel) for {} dB, then verified at both edges of every band (4 other directions, 3×3) and repaired where a level misses",
            needs.quality_db
        ));
        Ok((plan, MeshLodDecisions { targets, sizes }))
    }

    fn build(
        spec: &MeshLodSpec,
        needs: &Needs,
        decisions: &MeshLodDecisions,
        source: &Source,
    ) -> Result<(MeshLod, serde_json::Value), PipelineError> {
        let mesh = source_mesh(source)?;
        let t0 = Instant::now();
        let simplifying = crate::profile::timer("simplify");
        let (simplified, dropped) = simplify_levels(mesh, spec, &decisions.targets)?;
        simplifying.stop();
        let simplify_s = secs(t0);
        let t1 = Instant::now();
        let previewing = crate::profile::timer("preview levels");
        let meshes: Vec<&Mesh> = simplified.iter().map(|(_, s)| &s.mesh).collect();
        let preview = reach(source, &meshes, needs, &decisions.sizes)?;
        previewing.stop();
        let preview_s = secs(t1);
        let t2 = Instant::now();
        let verifying = crate::profile::timer("verify chain");
        let super::Verified {
            mut chain,
            reach: verified,
            repairs,
        } = super::verified_chain(&meshes, &preview.reach, &decisions.sizes, needs, source)?;
        verifying.stop();
        let verify_s = secs(t2);
        let levels: Vec<Level> = simplified
            .into_iter()
            .zip(&verified)
            .map(|((ratio, s), max_px)| Level {
                info: LevelInfo {
                    ratio,
                    triangles: s.mesh.triangle_count(),
                    error: s.error,
                    max_px: *max_px,
                    texture_px: None,
                },
                mesh: s.mesh,
            })
            .collect();
        let infos: Vec<LevelInfo> = levels.iter().map(|l| l.info.clone()).collect();
        // Only the levels the chain draws are kept (and renumbered, finest first): the others
        // are measured in the report and skipped.
        let mut used: Vec<usize> = (0..levels.len())
            .filter(|l| chain.iter().any(|b| b.level == Some(*l)))
            .collect();
        // A chain that draws no level keeps the finest, undrawn, so that the report measures
        // by how much the simplification misses the target (and a user can look at it).
        if used.is_empty() && !levels.is_empty() {
            used.push(0);
        }
        for band in &mut chain {
            band.level = band.level.and_then(|l| used.iter().position(|u| *u == l));
        }
        let mut levels: Vec<Level> = levels
            .into_iter()
            .enumerate()
            .filter(|(l, _)| used.contains(l))
            .map(|(_, level)| level)
            .collect();
        let t3 = Instant::now();
        let reducing = crate::profile::timer("reduce textures");
        let reduced = super::reduce_textures(&mut levels, &chain, needs, source)?;
        reducing.stop();
        let textures_s = secs(t3);
        let report = json!({
            "source_triangles": mesh.triangle_count(),
            "levels": infos,
            "kept": used,
            "dropped": dropped,
            "chain": chain,
            "previewed_px": preview.reach,
            "preview_worst_db": preview.worst_db,
            "repairs": repairs,
            "simplify_s": simplify_s,
            "preview_s": preview_s,
            "verify_s": verify_s,
            "texture_px": levels.iter().map(|l| l.info.texture_px).collect::<Vec<_>>(),
            "texture_sizes_tried": reduced,
            "textures_s": textures_s,
        });
        Ok((MeshLod { levels, chain }, report))
    }

    fn write(lod: &MeshLod, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        // The levels share their textures: each is written once, beside the files.
        let mut images = ExternalImages::default();
        images.uri_prefix = w.prefix().to_string();
        for (k, level) in lod.levels.iter().enumerate() {
            let file = level.mesh.to_glb_beside(&mut images)?;
            w.glb(
                &format!("level{k}"),
                &format!("level{k}.glb"),
                level.info.triangles,
                file.bytes,
                vec![Channel {
                    name: "glTF 2.0 mesh, object frame under a root node holding to_source".into(),
                    encoding: Encoding::Float,
                }],
            )?;
        }
        let mut textures = Vec::new();
        for image in images.files {
            let channels = ["r", "g", "b", "a"]
                .map(|c| Channel {
                    name: format!("texture.{c} (as the .glb's materials read it)"),
                    encoding: Encoding::Linear {
                        scale: 1.0 / if image.sixteen_bit { 65535.0 } else { 255.0 },
                        offset: 0.0,
                    },
                })
                .to_vec();
            let role = image
                .name
                .rsplit_once('.')
                .map_or(image.name.as_str(), |(stem, _)| stem)
                .to_string();
            let format = match (image.mime, image.sixteen_bit) {
                ("image/jpeg", _) => FileFormat::Jpeg8,
                (_, true) => FileFormat::Png16,
                _ => FileFormat::Png8,
            };
            w.encoded_image(
                &role,
                &image.name,
                format,
                image.size,
                image.bytes,
                channels,
            )?;
            textures.push(image.name);
        }
        let placement = lod.levels.first().map(|l| l.mesh.placement().of_written());
        let infos: Vec<&LevelInfo> = lod.levels.iter().map(|l| &l.info).collect();
        Ok(json!({
            "levels": infos,
            "chain": lod.chain,
            "textures": textures,
            "to_object": placement.map(|p| rows(p.to_normalised)),
            "up": placement.map(|p| p.up.name()),
            "units": placement.map(|p| p.units),
            "light": lod.levels.first().map(|l| {
                let light = l.mesh.light();
                let d = light.direction;
                [d.x, d.y, d.z, light.ambient]
            }),
        }))
    }

    fn read(r: &AssetReader) -> Result<MeshLod, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let infos: Vec<LevelInfo> = serde_json::from_value(m["levels"].clone())
            .map_err(|e| r.content(format!("metadata.levels: {e}")))?;
        let chain: Vec<Band> = serde_json::from_value(m["chain"].clone())
            .map_err(|e| r.content(format!("metadata.chain: {e}")))?;
        if let Some(b) = chain
            .iter()
            .find(|b| b.level.is_some_and(|l| l >= infos.len()))
        {
            return Err(r
                .content(format!(
                    "metadata.chain names level {:?} of {}",
                    b.level,
                    infos.len()
                ))
                .into());
        }
        let mut levels = Vec::with_capacity(infos.len());
        if !infos.is_empty() {
            let to_object: [[f64; 4]; 3] = serde_json::from_value(m["to_object"].clone())
                .map_err(|e| r.content(format!("metadata.to_object: {e}")))?;
            let mut cols = [0.0; 16];
            for (i, row) in to_object.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    cols[4 * j + i] = *v;
                }
            }
            cols[15] = 1.0;
            let to_normalised = DAffine3::from_mat4(DMat4::from_cols_array(&cols));
            if !to_normalised.is_finite() || to_normalised.matrix3.determinant() <= 0.0 {
                return Err(r
                    .content("metadata.to_object is not a proper affine map".into())
                    .into());
            }
            let up: UpAxis = m["up"]
                .as_str()
                .unwrap_or("+y")
                .parse()
                .map_err(|e: String| r.content(format!("metadata.up: {e}")))?;
            let units = if m["units"].as_str() == Some("metre") {
                "metre"
            } else {
                "file unit"
            };
            let frame = Placement {
                to_normalised,
                up,
                units,
            };
            // The light emissive and unlit surfaces are seen under (absent: the default).
            let light = match &m["light"] {
                serde_json::Value::Null => Light::default(),
                v => {
                    let [x, y, z, ambient]: [f32; 4] = serde_json::from_value(v.clone())
                        .map_err(|e| r.content(format!("metadata.light: {e}")))?;
                    let direction = glam::Vec3::new(x, y, z);
                    if !direction.is_normalized() || !(0.0..=1.0).contains(&ambient) {
                        return Err(r
                            .content(format!(
                                "metadata.light {v} is not a unit direction and an ambient in [0, 1]"
                            ))
                            .into());
                    }
                    Light { direction, ambient }
                }
            };
            for (k, info) in infos.into_iter().enumerate() {
                let role = format!("level{k}");
                let (bytes, triangles) = r.glb(&role)?;
                let file = r
                    .description()
                    .file(&role)
                    .map_or(format!("{role}.glb"), |e| e.path.clone());
                let path = r.dir().join(file);
                let mesh = Mesh::from_gltf_bytes(
                    bytes,
                    &path,
                    &MeshLoadOptions {
                        frame: Some(frame),
                        light,
                        ..MeshLoadOptions::default()
                    },
                )?;
                if mesh.triangle_count() != triangles || triangles != info.triangles {
                    return Err(r
                        .content(format!(
                            "{role}.glb holds {} triangles, asset.json says {triangles} (levels: {})",
                            mesh.triangle_count(),
                            info.triangles
                        ))
                        .into());
                }
                levels.push(Level { mesh, info });
            }
        }
        Ok(MeshLod { levels, chain })
    }

    fn measure_size(d: &MeshLodDecisions) -> usize {
        d.sizes.last().copied().unwrap_or(0)
    }

    fn measure(
        lod: &MeshLod,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        let meshes: Vec<&Mesh> = lod.levels.iter().map(|l| &l.mesh).collect();
        let measured = super::verify(&meshes, &lod.chain, needs, source)?;
        let (scores, what): (Vec<_>, String) = if measured.is_empty() {
            // No level reached the target anywhere: the finest, at the needs' two ends, so the
            // report shows by how much.
            let Some(finest) = lod.levels.first() else {
                return Err(PipelineError::Spec(
                    "the chain holds no simplified level to measure".into(),
                ));
            };
            let mut scores = Vec::new();
            let mut sizes = vec![
                needs.screen_px[0].max(super::MIN_MEASURED_PX).round() as usize,
                size.max(super::MIN_MEASURED_PX as usize),
            ];
            sizes.dedup();
            for s in &sizes {
                scores.extend(
                    super::score_levels(
                        source,
                        &[&finest.mesh],
                        needs,
                        *s,
                        &measure_views(needs, 4),
                        altrep_data_gen::Supersample::of(3),
                    )?
                    .remove(0),
                );
            }
            (
                scores,
                format!(
                    "the finest level ({} triangles; no level met the target at any previewed size) at {sizes:?} px",
                    finest.info.triangles
                ),
            )
        } else {
            let edges: Vec<String> = measured
                .iter()
                .map(|(b, s, _)| format!("band {b} at {s} px"))
                .collect();
            (
                measured.iter().flat_map(|(_, _, s)| s.clone()).collect(),
                format!(
                    "the chain's levels at both edges of each band ({})",
                    edges.join(", ")
                ),
            )
        };
        let biggest = measured
            .iter()
            .map(|(_, s, _)| *s)
            .max()
            .unwrap_or(size.max(super::MIN_MEASURED_PX as usize));
        let window = Window::for_needs(needs, biggest);
        let method = format!(
            "ray casting of {what}, at 4 needed directions each, vs truth 3×3 supersampled{}",
            elevation_note(needs, window)
        );
        let mut m = fold(method, &scores, None);
        m.size = biggest;
        // The picture: truth | each level of the chain, coarsest first, at the largest size.
        let view = measure_views(needs, 4)[0];
        let k = altrep_data_gen::Supersample::of(3);
        let mut images = vec![window.truth(source, view, k)?];
        let mut drawn = Vec::new();
        for band in &lod.chain {
            if let Some(l) = band.level {
                images.push(draw(source, &lod.levels[l].mesh, window, view, k)?);
                drawn.push(format!(
                    "level {l} ({} triangles) for {}–{} px",
                    lod.levels[l].info.triangles, band.from_px, band.to_px
                ));
            }
        }
        let refs: Vec<_> = images.iter().collect();
        let picture = Picture {
            file: format!("{}-mesh_lod.png", source.name),
            caption: format!(
                "{}: ground truth | {} (ray cast at {biggest} px), azimuth {:.0}°",
                source.name,
                if drawn.is_empty() {
                    "no level in the chain".to_string()
                } else {
                    drawn.join(" | ")
                },
                view.azimuth.to_degrees()
            ),
            image: altrep_data_gen::RgbaImage::side_by_side(&refs),
        };
        Ok((m, vec![picture]))
    }
}
