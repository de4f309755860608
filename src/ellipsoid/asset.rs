//! The ellipsoid octree (docs/design.md §8) in the pipeline.
//!
//! One file, `octree.bin`: the nodes breadth-first, root first, 52-byte little-endian records
//! `density f32, colour f32×3 (linear RGB), has_ellipsoid u32 (0/1), rotation quaternion f32×4
//! (x, y, z, w), semi-axis lengths f32×3, first_child u32 (0 = leaf; else the index of the first
//! of 8 consecutive children in octant order x + 2y + 4z)`. The cube of side `2^depth` voxels
//! spans the object box `[−R, R] × [0, H] × [−R, R]` (voxel `(i, j, k)` at
//! `x = −R + (i + ½)·2R/n`, …).

use std::num::NonZeroU32;
use std::time::Instant;

use altrep_data_gen::{Fill, Supersample, VoxelParams, voxelize};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::asset::{AssetReader, AssetWriter, Channel, Encoding};
use crate::ellipsoid::octree::{OctreeNode, OctreeRenderParams, OctreeView, PackedEllipsoid};
use crate::ellipsoid::{FilterRule, Octree, OctreeParams as BuildParams};
use crate::representation::{
    Estimate, InputSize, Measurement, Needs, Picture, PipelineError, Plan, Representation, Source,
    Window, elevation_note, fold, linear_bytes, measure_views, secs,
};

/// Bytes per stored node.
pub const NODE_BYTES: usize = 52;

/// Manifest parameters of the ellipsoid octree (`[asset.octree]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OctreeSpec {
    /// Voxels per side of the leaf level (power of two, 4–512; default 64). The planner lowers it
    /// to the closest footprint (the largest screen size).
    pub resolution: usize,
    /// Filter rule of coarser levels: `sggx` (default) or `seed1995`.
    pub rule: String,
    /// Inside tests per voxel edge when voxelising ([`Supersample`]: `k³` per voxel; 1–4,
    /// default 2).
    pub supersample: Supersample,
    /// How a mesh is voxelised ([`Fill`]): `solid` (its inside, by ray parity), `shell` (the
    /// share of rays its surface stops in each voxel: open meshes, alpha-masked leaves) or
    /// `auto` (default: solid when the mesh is closed and no material cuts rays, shell
    /// otherwise).
    pub fill: Fill,
}

impl Default for OctreeSpec {
    fn default() -> Self {
        Self {
            resolution: 64,
            rule: "sggx".into(),
            supersample: Supersample::of(2),
            fill: Fill::Auto,
        }
    }
}

fn rule_of(name: &str) -> Option<FilterRule> {
    FilterRule::ALL.into_iter().find(|r| r.name() == name)
}

impl OctreeSpec {
    /// Checks ranges; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !self.resolution.is_power_of_two() || !(4..=512).contains(&self.resolution) {
            return Err(format!(
                "octree.resolution = {} must be a power of two in 4..=512",
                self.resolution
            ));
        }
        if rule_of(&self.rule).is_none() {
            return Err(format!(
                "octree.rule = '{}' must be sggx or seed1995",
                self.rule
            ));
        }
        if !(1..=4).contains(&self.supersample.get()) {
            return Err(format!(
                "octree.supersample = {} must be in 1..=4",
                self.supersample.get()
            ));
        }
        Ok(())
    }
}

/// What the planner decided for the octree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OctreeDecisions {
    /// Leaf resolution actually built.
    pub resolution: usize,
}

/// The ellipsoid octree for the pipeline.
pub struct OctreeRepr;

/// The leaf resolution the closest footprint needs: the largest screen size rounded up to a
/// power of two, at least 4.
fn closest_resolution(needs: &Needs) -> usize {
    (needs.screen_px[1].ceil() as usize)
        .next_power_of_two()
        .max(4)
}

impl Representation for OctreeRepr {
    const NAME: &'static str = "octree";
    const CASTS_RAYS: bool = false;
    type Spec = OctreeSpec;
    type Data = Octree;
    type Decisions = OctreeDecisions;

    fn validate(spec: &Self::Spec) -> Result<(), String> {
        spec.validate()
    }

    fn relevant_needs(needs: &Needs) -> serde_json::Value {
        json!({ "screen_px_max": needs.screen_px[1], "azimuth_deg": needs.azimuth_deg,
                "elevation_deg": needs.elevation_deg })
    }

    fn estimate(spec: &OctreeSpec, needs: &Needs, _input: &InputSize) -> Estimate {
        // ~60 B per leaf voxel at 128³ (the voxelised volume, the tree, the read-back copy), and
        // a few MB of fixed cost that dominate below 32³.
        let n = closest_resolution(needs).min(spec.resolution) as f64;
        let ss = spec.supersample.get() as f64 / 2.0;
        Estimate {
            peak_bytes: linear_bytes(3e6, 58.0 * ss.max(1.0), n * n * n),
            // At most one node per voxel of every level, NODE_BYTES each.
            output_bytes: linear_bytes(0.0, NODE_BYTES as f64 * 8.0 / 7.0, n * n * n),
        }
    }

    fn plan(
        spec: &OctreeSpec,
        needs: &Needs,
        _source: &Source,
    ) -> Result<(Plan, OctreeDecisions), PipelineError> {
        let mut plan = Plan::default();
        let closest = closest_resolution(needs);
        let resolution = if closest < spec.resolution {
            let mut l = spec.resolution;
            let mut level = 0;
            while l > closest {
                plan.skip(
                    format!("octree level {level} ({l}³ leaves)"),
                    format!(
                        "finer than the closest footprint: the largest screen size is {} px",
                        needs.screen_px[1]
                    ),
                );
                l /= 2;
                level += 1;
            }
            closest
        } else {
            spec.resolution
        };
        plan.build(format!(
            "octree of {resolution}³ leaves, rule {}",
            spec.rule
        ));
        Ok((plan, OctreeDecisions { resolution }))
    }

    fn build(
        spec: &OctreeSpec,
        _needs: &Needs,
        decisions: &OctreeDecisions,
        source: &Source,
    ) -> Result<(Octree, serde_json::Value), PipelineError> {
        let n = decisions.resolution;
        let t0 = Instant::now();
        let voxelising = crate::profile::timer("voxelise");
        let volume = voxelize(
            source.shape()?,
            &VoxelParams {
                dims: [n; 3],
                min: DVec3::new(-1.0, 0.0, -1.0),
                max: DVec3::new(1.0, 2.0, 1.0),
                periodic: [false; 3],
                supersample: spec.supersample,
                fill: spec.fill,
            },
        )?;
        voxelising.stop();
        let voxelize_s = secs(t0);
        if volume.density.iter().all(|&d| d <= 0.0) {
            return Err(PipelineError::Invisible {
                asset: source.name.into(),
                what: format!("the {n}³ voxelisation"),
            });
        }
        let rule = rule_of(&spec.rule).ok_or_else(|| PipelineError::Spec(spec.rule.clone()))?;
        let octree = crate::profile::timer("octree");
        let (tree, report) = Octree::build(
            &volume,
            &BuildParams {
                rule,
                ..BuildParams::default()
            },
        )?;
        octree.stop();
        Ok((
            tree,
            json!({ "voxelize_s": voxelize_s, "fill": volume.fill.name(), "build_s": report.build_seconds,
                    "nodes": report.nodes, "leaves": report.leaves, "compression": report.compression }),
        ))
    }

    fn write(tree: &Octree, w: &mut AssetWriter) -> Result<serde_json::Value, PipelineError> {
        let mut bytes = Vec::with_capacity(tree.nodes().len() * NODE_BYTES);
        for node in tree.nodes() {
            let mut put = |v: f32| bytes.extend_from_slice(&v.to_le_bytes());
            put(node.density);
            node.color.iter().for_each(|&c| put(c));
            let e = node.ellipsoid.unwrap_or(PackedEllipsoid {
                rotation: [0.0; 4],
                lengths: [0.0; 3],
            });
            bytes.extend_from_slice(&u32::from(node.ellipsoid.is_some()).to_le_bytes());
            for v in e.rotation.iter().chain(&e.lengths) {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            let child = node.first_child.map_or(0, NonZeroU32::get);
            bytes.extend_from_slice(&child.to_le_bytes());
        }
        let f = |name: &str, encoding: Encoding| Channel {
            name: name.into(),
            encoding,
        };
        let fields = vec![
            f("density: f32", Encoding::Float),
            f("colour: f32x3, linear RGB", Encoding::Float),
            f("has_ellipsoid: u32", Encoding::Integer),
            f("rotation: f32x4 quaternion (x, y, z, w)", Encoding::Float),
            f("lengths: f32x3 semi-axes in voxels", Encoding::Float),
            f("first_child: u32 (0 = leaf)", Encoding::Integer),
        ];
        w.bin("nodes", "octree.bin", NODE_BYTES, bytes, fields)?;
        Ok(
            json!({ "depth": tree.depth(), "dims": tree.dims(), "rule": tree.rule().name(),
                   "box_min": [-1.0, 0.0, -1.0], "box_max": [1.0, 2.0, 1.0] }),
        )
    }

    fn read(r: &AssetReader) -> Result<Octree, PipelineError> {
        r.expect_representation(Self::NAME)?;
        let m = &r.description().metadata;
        let depth = m["depth"]
            .as_u64()
            .ok_or_else(|| r.content("metadata.depth missing".into()))? as u32;
        let dims: [usize; 3] = serde_json::from_value(m["dims"].clone())
            .map_err(|e| r.content(format!("metadata.dims: {e}")))?;
        let rule = m["rule"]
            .as_str()
            .and_then(rule_of)
            .ok_or_else(|| r.content("metadata.rule".into()))?;
        let (bytes, rec) = r.bin("nodes")?;
        if rec != NODE_BYTES {
            return Err(r
                .content(format!(
                    "node records of {rec} bytes, expected {NODE_BYTES}"
                ))
                .into());
        }
        let nodes = bytes
            .chunks_exact(NODE_BYTES)
            .map(|c| {
                let f = |i: usize| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                };
                let u = |i: usize| {
                    u32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                };
                OctreeNode {
                    density: f(0),
                    color: [f(1), f(2), f(3)],
                    ellipsoid: (u(4) != 0).then(|| PackedEllipsoid {
                        rotation: [f(5), f(6), f(7), f(8)],
                        lengths: [f(9), f(10), f(11)],
                    }),
                    first_child: NonZeroU32::new(u(12)),
                }
            })
            .collect();
        Ok(Octree::from_nodes(nodes, depth, dims, rule)?)
    }

    fn measure_size(d: &OctreeDecisions) -> usize {
        d.resolution
    }

    fn measure(
        tree: &Octree,
        needs: &Needs,
        size: usize,
        source: &Source,
    ) -> Result<(Measurement, Vec<Picture>), PipelineError> {
        // The cube [0, 2^depth]³ is the voxelised box (−1, 0, −1)–(1, 2, 1) scaled by 2^depth / 2:
        // the window's centre (0, 1, 0) is the cube's centre, and directions carry over.
        let side = 1usize << tree.depth();
        // A tree finer than the measured size (a run that ignored the needs) is drawn at the
        // level whose voxels are the size's pixels, as a display chooses by footprint.
        let size = size.clamp(1, side);
        let base = (side / size).ilog2();
        let window = Window::for_needs(needs, size);
        let d = source.light.direction;
        let params = OctreeRenderParams {
            light: nalgebra::Vector3::new(f64::from(d.x), f64::from(d.y), f64::from(d.z)),
            ambient: f64::from(source.light.ambient),
            ..OctreeRenderParams::default()
        };
        let view_of = |v: crate::representation::ViewDir| {
            let f = window.frame(v);
            let half = 0.5 * side as f64;
            OctreeView {
                dir: f.dir.to_array(),
                right: f.right.to_array(),
                up: f.up.to_array(),
                centre: [half; 3],
                half_width: half * f.radius,
                width: window.side(),
                height: window.side(),
            }
        };
        let mut scores = Vec::new();
        let mut images = Vec::new();
        let views = measure_views(needs, 4);
        // Samples marched (tree descents) per pixel whose ray crosses the cube.
        let (mut samples, mut crossing) = (0u64, 0usize);
        for (i, &v) in views.iter().enumerate() {
            let reference = window.truth(source, v, Supersample::of(3))?;
            let (img, counts) = tree.render_view_counted(base, &params, &view_of(v))?;
            samples += counts.iter().map(|&c| u64::from(c)).sum::<u64>();
            crossing += counts.iter().filter(|&&c| c > 0).count();
            scores.push(window.score(&img, &reference)?);
            if i == 0 {
                images.push(reference);
                images.push(img);
                // Coarser levels, drawn at the same resolution, for the picture.
                for level in base + 1..=tree.depth().min(base + 2) {
                    images.push(tree.render_view(level, &params, &view_of(v))?);
                }
            }
        }
        let refs: Vec<_> = images.iter().collect();
        let first = views[0];
        let picture = Picture {
            file: format!("{}-octree.png", source.name),
            caption: format!(
                "{}: ground truth | octree levels {base}–{} (volume rendering of the micro-primitives), azimuth {:.0}°, elevation {:.0}°",
                source.name,
                base as usize + images.len() - 2,
                first.azimuth.to_degrees(),
                first.elevation.to_degrees()
            ),
            image: altrep_data_gen::RgbaImage::side_by_side(&refs),
        };
        let method = format!(
            "volume rendering of octree level {base} of {side}³ leaves ({size}³ voxels, 2 samples per voxel length; steps: samples per pixel whose ray crosses the cube) at {} needed directions, vs truth 3×3 supersampled{}",
            scores.len(),
            elevation_note(needs, window)
        );
        let steps = (crossing > 0).then(|| samples as f64 / crossing as f64);
        let mut m = fold(method, &scores, steps);
        m.size = size;
        Ok((m, vec![picture]))
    }
}
