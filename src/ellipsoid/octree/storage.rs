//! What an octree stores: the node array ([`OctreeNode`], with its [`PackedEllipsoid`]), the
//! [`Octree`] that owns it, what a lookup returns ([`NodeSample`]), and building an octree from
//! stored nodes (as a loader decodes them).

use std::num::NonZeroU32;

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};

use crate::ellipsoid::error::EllipsoidError;
use crate::ellipsoid::filter::FilterRule;
use crate::ellipsoid::primitive::Ellipsoid;

/// An ellipsoid stored compactly: unit quaternion `(x, y, z, w)` of its basis and its lengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedEllipsoid {
    /// Unit quaternion `(x, y, z, w)` rotating the frame axes onto the ellipsoid's axes.
    pub rotation: [f32; 4],
    /// Semi-axis lengths along the rotated x, y, z axes.
    pub lengths: [f32; 3],
}

impl PackedEllipsoid {
    /// Packs `e` (rounding to `f32`).
    pub fn pack(e: &Ellipsoid) -> Self {
        let rot = Rotation3::from_matrix_unchecked(*e.basis());
        let q = UnitQuaternion::from_rotation_matrix(&rot);
        let c = q.coords;
        let l = e.lengths();
        Self {
            rotation: [c.x as f32, c.y as f32, c.z as f32, c.w as f32],
            lengths: [l.x as f32, l.y as f32, l.z as f32],
        }
    }

    /// Back to an [`Ellipsoid`] (quaternion renormalised in `f64`).
    pub fn unpack(&self) -> Result<Ellipsoid, EllipsoidError> {
        let [x, y, z, w] = self.rotation.map(f64::from);
        let q = Quaternion::new(w, x, y, z);
        if q.norm() == 0.0 || !q.norm().is_finite() {
            return Err(EllipsoidError::NonFiniteMatrix {
                what: "packed rotation",
            });
        }
        let r = UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner();
        Ellipsoid::new(r, Vector3::from(self.lengths.map(f64::from)))
    }
}

/// A stored octree node (52 bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeNode {
    /// Mean coverage over the node's cube, `[0, 1]`.
    pub density: f32,
    /// Density-weighted mean linear RGB (zero where empty).
    pub color: [f32; 3],
    /// Filtered micro-primitive; `None` where the density is zero.
    pub ellipsoid: Option<PackedEllipsoid>,
    /// Index of the first of 8 consecutive children (octant order `x + 2y + 4z`), `None` for a leaf.
    pub first_child: Option<NonZeroU32>,
}

/// What a lookup found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeSample {
    /// Level of the node that answered (≥ the level asked for when the region was pruned).
    pub level: u32,
    /// Mean coverage.
    pub density: f32,
    /// Density-weighted mean colour.
    pub color: [f32; 3],
    /// Micro-primitive (`None` where empty).
    pub ellipsoid: Option<Ellipsoid>,
}

/// The multiscale octree. See the module docs for levels and contents.
#[derive(Debug, Clone)]
pub struct Octree {
    pub(super) nodes: Vec<OctreeNode>,
    pub(super) depth: u32,
    pub(super) dims: [usize; 3],
    pub(super) rule: FilterRule,
}

impl Octree {
    /// An octree from stored nodes (as a loader decodes them). Errors
    /// ([`EllipsoidError::BadParameter`]): no node, a depth above 24, dimensions beyond
    /// `2^depth`, a child block out of range or not after its parent (which would loop), a
    /// non-finite or out-of-range density or colour. Cost: one pass over the nodes.
    pub fn from_nodes(
        nodes: Vec<OctreeNode>,
        depth: u32,
        dims: [usize; 3],
        rule: FilterRule,
    ) -> Result<Self, EllipsoidError> {
        let bad = |name: &'static str, value: String, reason: &'static str| {
            EllipsoidError::BadParameter {
                name,
                reason: format!("{value}: {reason}"),
            }
        };
        if nodes.is_empty() {
            return Err(bad("nodes", "0".into(), "an octree needs a root"));
        }
        if depth > 24 {
            return Err(bad("depth", depth.to_string(), "must be at most 24"));
        }
        if dims.iter().any(|&d| d == 0 || d as u64 > 1u64 << depth) {
            return Err(bad("dims", format!("{dims:?}"), "must be in 1..=2^depth"));
        }
        for (i, n) in nodes.iter().enumerate() {
            if let Some(first) = n.first_child {
                let f = first.get() as usize;
                if f <= i || f.checked_add(8).is_none_or(|end| end > nodes.len()) {
                    return Err(bad(
                        "first_child",
                        format!("{f} at node {i}"),
                        "must name 8 nodes after the parent",
                    ));
                }
            }
            if !(n.density.is_finite() && (0.0..=1.0).contains(&n.density))
                || n.color.iter().any(|c| !c.is_finite())
            {
                return Err(bad(
                    "node",
                    i.to_string(),
                    "density must be in [0, 1] and colour finite",
                ));
            }
        }
        Ok(Self {
            nodes,
            depth,
            dims,
            rule,
        })
    }

    /// The stored nodes, breadth-first; index 0 is the root.
    pub fn nodes(&self) -> &[OctreeNode] {
        &self.nodes
    }

    /// Levels below the root.
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Input dimensions.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The filter rule the coarser levels were built with.
    pub fn rule(&self) -> FilterRule {
        self.rule
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_round_trip() {
        let e = Ellipsoid::spheroid(Vector3::new(1.0, 2.0, -0.5), 0.1, 1.3).unwrap();
        let back = PackedEllipsoid::pack(&e).unpack().unwrap();
        let (q1, q2) = (e.quadratic_form(), back.quadratic_form());
        assert!((q1 - q2).amax() < 1e-5 * q1.amax());
    }
}
