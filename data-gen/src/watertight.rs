//! The ray–triangle test of every mesh tracer: Woop, Benthin and Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013, in `f32` with the paper's `f64` fallback for edge functions
//! that round to exactly zero.
//!
//! The ray's frame is sheared so that the ray runs along `+z` through the origin; each triangle
//! vertex is translated by the ray's origin and sheared, and the three 2D edge functions decide
//! the hit. Two triangles sharing an edge compute that edge's function from the same two sheared
//! vertices with the same operations, so its values are exact negatives of each other: a ray
//! through the edge (or a vertex) is inside at least one of them. No ray slips through a closed
//! mesh; Möller–Trumbore's separate barycentric divisions do not promise that.
//!
//! Back faces are hits (altrep's normals face the ray). The distance is `T / det` in `f32`, kept
//! when it lies in `[t_min, t_max]` (as `obvhs`'s test keeps it), else `f32::INFINITY`.

use glam::Vec3A;
use obvhs::ray::Ray as BvhRay;
use obvhs::triangle::Triangle;

/// A ray direction prepared for the test: the dominant axis `kz`, the other two in an order that
/// keeps the winding, and the shear.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Shear {
    k: [usize; 3],
    s: [f32; 3],
}

impl Shear {
    /// The shear of direction `dir` (non-zero and finite for a meaningful test; any input gives
    /// a value, and a zero direction misses every triangle).
    #[inline]
    pub(crate) fn new(dir: Vec3A) -> Self {
        let a = dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z { 0 } else { 2 }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = dir[kz];
        Self {
            k: [kx, ky, kz],
            s: [dir[kx] / dz, dir[ky] / dz, 1.0 / dz],
        }
    }

    /// The distance at which the ray from `origin` (along the direction this shear was made
    /// from) meets `tri`, if it lies in `[t_min, t_max]`; `f32::INFINITY` otherwise.
    #[inline]
    pub(crate) fn intersect(&self, tri: &Triangle, origin: Vec3A, t_min: f32, t_max: f32) -> f32 {
        let [kx, ky, kz] = self.k;
        let [sx, sy, sz] = self.s;
        let (a, b, c) = (tri.v0 - origin, tri.v1 - origin, tri.v2 - origin);
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // The paper's fallback: the products exact in f64, one rounding to f32.
            let d = |p: f32, q: f32, r: f32, s: f32| {
                (f64::from(p) * f64::from(q) - f64::from(r) * f64::from(s)) as f32
            };
            u = d(cx, by, cy, bx);
            v = d(ax, cy, ay, cx);
            w = d(bx, ay, by, ax);
        }
        // Mixed signs: outside (NaN compares false both ways and is caught by `det` below).
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return f32::INFINITY;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return f32::INFINITY;
        }
        let t = (u * (sz * a[kz]) + v * (sz * b[kz]) + w * (sz * c[kz])) / det;
        if t >= t_min && t <= t_max {
            t
        } else {
            f32::INFINITY
        }
    }

    /// [`Shear::intersect`] on an `obvhs` ray (its origin and window; the direction must be the
    /// one this shear was made from).
    #[inline]
    pub(crate) fn intersect_ray(&self, tri: &Triangle, ray: &BvhRay) -> f32 {
        self.intersect(tri, ray.origin, ray.tmin, ray.tmax)
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use proptest::prelude::*;

    use super::*;
    use crate::rng::SplitMix64;

    fn tri(p: [[f32; 3]; 3]) -> Triangle {
        Triangle {
            v0: Vec3A::from(p[0]),
            v1: Vec3A::from(p[1]),
            v2: Vec3A::from(p[2]),
        }
    }

    #[test]
    fn a_ray_through_the_middle_meets_the_triangle_at_its_distance_from_either_side() {
        let t = tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        for dir in [Vec3A::Z, Vec3A::NEG_Z] {
            let origin = Vec3A::new(0.25, 0.25, 0.0) - dir * 2.0;
            let d = Shear::new(dir).intersect(&t, origin, 0.0, 10.0);
            assert_eq!(d, 2.0);
        }
        // Outside, and outside the window.
        let s = Shear::new(Vec3A::NEG_Z);
        assert!(
            s.intersect(&t, Vec3A::new(0.8, 0.8, 1.0), 0.0, 10.0)
                .is_infinite()
        );
        assert!(
            s.intersect(&t, Vec3A::new(0.2, 0.2, 1.0), 0.0, 0.5)
                .is_infinite()
        );
        // A ray in the triangle's plane, a zero direction: no hit, no NaN.
        assert!(
            Shear::new(Vec3A::X)
                .intersect(&t, Vec3A::new(-1.0, 0.2, 0.0), 0.0, 10.0)
                .is_infinite()
        );
        assert!(
            Shear::new(Vec3A::ZERO)
                .intersect(&t, Vec3A::new(0.2, 0.2, 1.0), 0.0, 10.0)
                .is_infinite()
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(20261205), ..ProptestConfig::default() })]
        /// A fan of random triangles around a shared vertex, closed into a cone: rays aimed at
        /// the shared vertex and at points of the shared edges (in `f32`, from random origins)
        /// meet at least one triangle of the fan.
        #[test]
        fn rays_through_shared_edges_and_vertices_never_slip_through(seed in any::<u64>(), n in 4usize..12) {
            let mut rng = SplitMix64::new(seed);
            let centre = Vec3A::new(rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32);
            // A ring of points around the centre (every sector below half a turn, so the fan
            // covers a neighbourhood of the centre as seen from above): the fan's rim.
            let rim: Vec<Vec3A> = (0..n)
                .map(|k| {
                    let a = std::f64::consts::TAU * (k as f64 + rng.range(-0.2, 0.2)) / n as f64;
                    centre + Vec3A::new(a.cos() as f32, a.sin() as f32, rng.range(-0.3, 0.3) as f32)
                })
                .collect();
            let fan: Vec<Triangle> = (0..n)
                .map(|k| Triangle { v0: centre, v1: rim[k], v2: rim[(k + 1) % n] })
                .collect();
            for corner in &rim {
                // The shared vertex, and a point along each shared edge.
                let s = rng.range(0.0, 1.0) as f32;
                for target in [centre, centre + (*corner - centre) * s] {
                    let from = DVec3::new(rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), rng.range(2.0, 4.0));
                    let origin = target + Vec3A::from(from.as_vec3());
                    let dir = (target - origin).normalize();
                    let shear = Shear::new(dir);
                    let hits = fan.iter().filter(|t| shear.intersect(t, origin, 0.0, 100.0).is_finite()).count();
                    prop_assert!(hits > 0, "ray to {target:?} from {origin:?} slipped through");
                }
            }
        }
    }
}
