//! Simplified meshes: a [`Mesh`] reduced by meshoptimizer's attribute-aware edge collapse
//! (`meshopt_simplifyWithAttributes`, through the `meshopt` crate), keeping its materials,
//! colours and placement.
//!
//! The mesh's corners are welded into indexed vertices first: two corners are one vertex when
//! their position (the normalised `f32` coordinates, bit for bit) and everything they carry
//! (material, texture coordinates of both sets, vertex colour, shading normal, tangent) are
//! equal. A position shared by corners that differ in anything else is an attribute seam, which
//! the simplifier keeps in place. Collapses are charged for the movement of the surface (the
//! quadric error) plus the change of the weighted attributes: texture coordinates of set 0,
//! vertex colour (RGBA) and shading normal.
//!
//! The output keeps a subset of the input's vertices (an edge collapse moves one vertex onto
//! another), so its bounds lie within the input's and its placement is the input's: it sits
//! exactly where the input did. Errors are in the normalised frame's units (the bounding
//! cylinder's, radius 1 by default).

use std::collections::HashMap;

use glam::{Vec2, Vec3, Vec3A, Vec4};
use meshopt::{SimplifyOptions, VertexDataAdapter};
use obvhs::triangle::Triangle;

use crate::error::DataGenError;
use crate::mesh::{Mesh, TriColor};
use crate::surface::SurfaceTri;

/// How to simplify a mesh ([`Mesh::simplified`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimplifyParams {
    /// Triangles to reach, at most (the simplifier stops at this count or at `max_error`,
    /// whichever comes first; it may also stop above it where every further collapse would
    /// cross a seam or a locked border).
    pub target_triangles: usize,
    /// Largest error allowed (normalised-frame units; infinite for none).
    pub max_error: f64,
    /// Keep the vertices of open borders in place (meshoptimizer's `LockBorder`): for pieces of
    /// a larger surface that must keep meeting their neighbours.
    pub lock_border: bool,
    /// Weight of the attributes (texture coordinates, colour, normal) against the surface's
    /// movement in the collapse cost; 0 simplifies by geometry alone.
    pub attribute_weight: f32,
}

impl Default for SimplifyParams {
    fn default() -> Self {
        Self {
            target_triangles: 0,
            max_error: f64::INFINITY,
            lock_border: false,
            attribute_weight: 1.0,
        }
    }
}

/// A simplified mesh and what the simplification did.
pub struct Simplified {
    /// The mesh: the input's materials, fallback colour and placement, fewer triangles.
    pub mesh: Mesh,
    /// meshoptimizer's error estimate: the largest distance (normalised-frame units) the
    /// surface moved, as its quadrics measure it.
    pub error: f64,
    /// Vertices after welding (the simplifier's input).
    pub welded_vertices: usize,
}

/// Attributes passed to the simplifier per vertex: `u, v`, colour `r, g, b, a`, normal
/// `x, y, z`.
const ATTRIBUTES: usize = 9;

/// What a corner carries besides its position, bit for bit, with a tag for its kind: the weld
/// key's second half.
type CornerKey = [u32; 17];

/// One welded vertex: its position and one corner's record (any corner of the vertex: they are
/// equal bit for bit).
struct Vertex {
    position: Vec3A,
    /// The triangle and corner it was first seen at.
    tri: u32,
    corner: u8,
}

fn bits2(v: Vec2) -> [u32; 2] {
    [v.x.to_bits(), v.y.to_bits()]
}

fn bits3(v: Vec3) -> [u32; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

fn bits4(v: Vec4) -> [u32; 4] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), v.w.to_bits()]
}

/// The key of corner `k` of a triangle coloured by `color`.
fn corner_key(color: Option<&TriColor>, k: usize) -> CornerKey {
    let mut key = [0u32; 17];
    match color {
        None | Some(TriColor::Procedural) => key[0] = 0,
        Some(TriColor::Flat(c)) => {
            key[0] = 1;
            key[1..4].copy_from_slice(&bits3(*c));
        }
        Some(TriColor::Vertex(c)) => {
            key[0] = 2;
            key[1..4].copy_from_slice(&bits3(c[k]));
        }
        Some(TriColor::Surface(s)) => {
            key[0] = 3 + s.material;
            key[1..3].copy_from_slice(&bits2(s.uv[0][k]));
            key[3..5].copy_from_slice(&bits2(s.uv[1][k]));
            key[5..9].copy_from_slice(&bits4(s.color[k]));
            if let Some(n) = &s.normal {
                key[9..12].copy_from_slice(&bits3(n[k]));
            }
            if let Some(t) = &s.tangent {
                key[12..16].copy_from_slice(&bits4(t[k]));
            }
            key[16] = u32::from(s.normal.is_some()) | (u32::from(s.tangent.is_some()) << 1);
        }
    }
    key
}

/// The simplifier's attributes of corner `k`.
fn corner_attributes(color: Option<&TriColor>, k: usize) -> [f32; ATTRIBUTES] {
    let mut a = [0.0; ATTRIBUTES];
    match color {
        None | Some(TriColor::Procedural) => {}
        Some(TriColor::Flat(c)) => a[2..5].copy_from_slice(&c.to_array()),
        Some(TriColor::Vertex(c)) => a[2..5].copy_from_slice(&c[k].to_array()),
        Some(TriColor::Surface(s)) => {
            a[0..2].copy_from_slice(&s.uv[0][k].to_array());
            a[2..6].copy_from_slice(&s.color[k].to_array());
            if let Some(n) = &s.normal {
                a[6..9].copy_from_slice(&n[k].to_array());
            }
        }
    }
    a
}

/// The colour record of a triangle whose corners come from `corners` (triangle and corner of
/// the input each): the kind of the first corner's triangle, with each corner's own values.
fn rebuild_color(colors: &[TriColor], corners: [(u32, u8); 3]) -> Option<TriColor> {
    let first = colors.get(corners[0].0 as usize)?;
    let at = |i: usize| (&colors[corners[i].0 as usize], corners[i].1 as usize);
    Some(match first {
        TriColor::Procedural => TriColor::Procedural,
        TriColor::Flat(c) => TriColor::Flat(*c),
        TriColor::Vertex(_) => TriColor::Vertex([0, 1, 2].map(|i| match at(i) {
            (TriColor::Vertex(c), k) => c[k],
            (TriColor::Flat(c), _) => *c,
            _ => Vec3::ONE,
        })),
        TriColor::Surface(s0) => {
            let corner = |i: usize| match at(i) {
                (TriColor::Surface(s), k) => Some((s, k)),
                _ => None,
            };
            let pick = |f: &dyn Fn(&SurfaceTri, usize) -> Vec4, fallback: Vec4| {
                [0, 1, 2].map(|i| corner(i).map_or(fallback, |(s, k)| f(s, k)))
            };
            let uv = [0, 1].map(|set| {
                pick(&|s, k| s.uv[set][k].extend(0.0).extend(0.0), Vec4::ZERO)
                    .map(|v| v.truncate().truncate())
            });
            let color = pick(&|s, k| s.color[k], Vec4::ONE);
            let normal = s0.normal.map(|_| {
                pick(
                    &|s, k| s.normal.map_or(Vec4::ZERO, |n| n[k].extend(0.0)),
                    Vec4::ZERO,
                )
                .map(|v| v.truncate())
            });
            let tangent = s0.tangent.as_ref().map(|_| {
                Box::new(pick(
                    &|s, k| s.tangent.as_ref().map_or(Vec4::ZERO, |t| t[k]),
                    Vec4::ZERO,
                ))
            });
            TriColor::Surface(SurfaceTri {
                material: s0.material,
                uv,
                color,
                normal,
                tangent,
            })
        }
    })
}

impl Mesh {
    /// The mesh simplified by meshoptimizer to about `params.target_triangles` triangles (or
    /// until the error would pass `params.max_error`), keeping its materials, colours and
    /// placement (module docs). Cost: one weld (a hash map over the corners) and one
    /// simplification, `O(n log n)` in the triangles; a 70 k-triangle mesh takes tens of
    /// milliseconds.
    ///
    /// Errors: [`DataGenError::InvalidParameter`] for a target of 0 triangles, a negative or NaN
    /// error bound or a negative or non-finite attribute weight; [`DataGenError::EmptyMesh`] when
    /// nothing is left.
    pub fn simplified(&self, params: &SimplifyParams) -> Result<Simplified, DataGenError> {
        let invalid = |name, value: String, reason| DataGenError::InvalidParameter {
            name,
            value,
            reason,
        };
        if params.target_triangles == 0 {
            return Err(invalid(
                "target_triangles",
                "0".into(),
                "a simplified mesh keeps at least one triangle",
            ));
        }
        if params.max_error.is_nan() || params.max_error < 0.0 {
            return Err(invalid(
                "max_error",
                params.max_error.to_string(),
                "must be ≥ 0 (infinite for no bound)",
            ));
        }
        if !(params.attribute_weight.is_finite() && params.attribute_weight >= 0.0) {
            return Err(invalid(
                "attribute_weight",
                params.attribute_weight.to_string(),
                "must be finite and ≥ 0",
            ));
        }
        let (triangles, colors) = self.input_parts();
        // Weld.
        let mut index: HashMap<([u32; 3], CornerKey), u32> =
            HashMap::with_capacity(triangles.len() * 2);
        let mut vertices: Vec<Vertex> = Vec::with_capacity(triangles.len());
        let mut indices: Vec<u32> = Vec::with_capacity(triangles.len() * 3);
        for (t, tri) in triangles.iter().enumerate() {
            let color = colors.get(t);
            for (k, p) in [tri.v0, tri.v1, tri.v2].into_iter().enumerate() {
                let key = (p.to_array().map(f32::to_bits), corner_key(color, k));
                let next = vertices.len() as u32;
                let v = *index.entry(key).or_insert_with(|| {
                    vertices.push(Vertex {
                        position: p,
                        tri: t as u32,
                        corner: k as u8,
                    });
                    next
                });
                indices.push(v);
            }
        }
        drop(index);
        let positions: Vec<[f32; 3]> = vertices.iter().map(|v| v.position.to_array()).collect();
        let attributes: Vec<f32> = vertices
            .iter()
            .flat_map(|v| corner_attributes(colors.get(v.tri as usize), v.corner as usize))
            .collect();
        let w = params.attribute_weight;
        let has_normals = colors
            .iter()
            .any(|c| matches!(c, TriColor::Surface(s) if s.normal.is_some()));
        let nw = if has_normals { 0.5 * w } else { 0.0 };
        let weights = [w, w, w, w, w, w, nw, nw, nw];
        let bytes: &[u8] = meshopt::typed_to_bytes(&positions);
        let adapter = VertexDataAdapter::new(bytes, 12, 0).map_err(|e| {
            invalid(
                "vertices",
                e.to_string(),
                "the simplifier could not read them",
            )
        })?;
        let mut options = SimplifyOptions::ErrorAbsolute;
        if params.lock_border {
            options |= SimplifyOptions::LockBorder;
        }
        let target_error = if params.max_error.is_finite() {
            params.max_error as f32
        } else {
            f32::MAX
        };
        let mut error = 0.0f32;
        // One entry per vertex: the binding hands meshoptimizer the slice's pointer, which it
        // reads for every vertex.
        let locks = vec![false; vertices.len()];
        let kept = meshopt::simplify_with_attributes_and_locks(
            &indices,
            &adapter,
            &attributes,
            &weights,
            ATTRIBUTES * std::mem::size_of::<f32>(),
            &locks,
            params.target_triangles.saturating_mul(3).min(indices.len()),
            target_error,
            options,
            Some(&mut error),
        );
        let mut out_tris = Vec::with_capacity(kept.len() / 3);
        let mut out_colors = Vec::with_capacity(if colors.is_empty() { 0 } else { kept.len() / 3 });
        for c in kept.chunks_exact(3) {
            let v = [0, 1, 2].map(|i| &vertices[c[i] as usize]);
            out_tris.push(Triangle {
                v0: v[0].position,
                v1: v[1].position,
                v2: v[2].position,
            });
            if !colors.is_empty() {
                let corners = v.map(|v| (v.tri, v.corner));
                out_colors.push(rebuild_color(colors, corners).unwrap_or(TriColor::Procedural));
            }
        }
        let mesh = self.with_parts(out_tris, out_colors)?;
        Ok(Simplified {
            mesh,
            error: f64::from(error),
            welded_vertices: vertices.len(),
        })
    }
}
