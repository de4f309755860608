//! Analytic shapes with an exact signed distance **and gradient** ([`AnalyticShape`]), and
//! procedural voxel volumes made of them ([`AnalyticVolume`]): the octree's test volumes (a
//! sphere inside a torus, a lawn texel of grass blades on a ground slab).
//!
//! Coordinates: the unit cube `[0, 1]³` (not the bounding cylinder of the crate conventions);
//! `y` is up. Unlike [`crate::Primitive`] (ray-cast solids, normals by ray hit or numeric
//! gradient), these shapes give the analytic gradient of their distance, which the volumes use
//! as the surface normal.

use glam::DVec3;

use crate::rng::SplitMix64;
use crate::volume::Voxel;

/// An analytic signed-distance shape for procedural test volumes (unit-cube coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnalyticShape {
    /// Sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// Torus about the y axis.
    Torus {
        /// Centre.
        center: [f64; 3],
        /// Distance from the centre to the tube's axis.
        major: f64,
        /// Tube radius.
        minor: f64,
    },
    /// Capsule: the points within `radius` of the segment `a`–`b`.
    Capsule {
        /// One end of the axis.
        a: [f64; 3],
        /// Other end of the axis.
        b: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// Axis-aligned box.
    Slab {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
    },
}

impl AnalyticShape {
    /// Signed distance (negative inside) and its gradient (outward unit normal) at `p`.
    /// Cost: a few flops.
    pub fn sdf(&self, p: DVec3) -> (f64, DVec3) {
        let safe = |v: DVec3| {
            let n = v.length();
            if n > 0.0 { v / n } else { DVec3::Y }
        };
        match *self {
            AnalyticShape::Sphere { center, radius } => {
                let d = p - DVec3::from(center);
                (d.length() - radius, safe(d))
            }
            AnalyticShape::Torus {
                center,
                major,
                minor,
            } => {
                let d = p - DVec3::from(center);
                let radial = DVec3::new(d.x, 0.0, d.z);
                let ring = safe(radial) * major;
                let q = d - ring;
                (q.length() - minor, safe(q))
            }
            AnalyticShape::Capsule { a, b, radius } => {
                let (a, b) = (DVec3::from(a), DVec3::from(b));
                let ab = b - a;
                let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                let d = p - (a + ab * t);
                (d.length() - radius, safe(d))
            }
            AnalyticShape::Slab { min, max } => {
                let c = (DVec3::from(min) + DVec3::from(max)) * 0.5;
                let h = (DVec3::from(max) - DVec3::from(min)) * 0.5;
                let d = p - c;
                let q = d.abs() - h;
                let outside = q.map(|x| x.max(0.0));
                if outside.length() > 0.0 {
                    let n = outside * d.map(f64::signum);
                    (outside.length(), safe(n))
                } else {
                    // The axis of the largest q (the first on ties).
                    let mut k = 0;
                    for i in 1..3 {
                        if q[i] > q[k] {
                            k = i;
                        }
                    }
                    let mut n = DVec3::ZERO;
                    n[k] = d[k].signum();
                    (q[k], n)
                }
            }
        }
    }
}

/// A procedural volume: a union of [`AnalyticShape`]s in the unit cube, sampled at voxel centres
/// ([`AnalyticVolume::sample`]). Coverage `clamp(0.5 − sd/h, 0, 1)` (a one-voxel ramp, `h` the
/// voxel size), normal = gradient of the nearest shape where `|sd| < h` (the surface shell), `None`
/// deeper inside; each shape has a colour. Cost per voxel: one distance per shape.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticVolume {
    /// Name used in reports.
    pub name: String,
    /// Voxels per side (the volume is `n³`).
    pub n: usize,
    /// Shapes and their linear RGB colours.
    pub shapes: Vec<(AnalyticShape, [f32; 3])>,
}

impl AnalyticVolume {
    /// A sphere and a torus around it (smooth closed surfaces).
    pub fn sphere_torus(n: usize) -> Self {
        Self {
            name: "sphere-torus".into(),
            n,
            shapes: vec![
                (
                    AnalyticShape::Sphere {
                        center: [0.5, 0.5, 0.5],
                        radius: 0.25,
                    },
                    [0.8, 0.3, 0.2],
                ),
                (
                    AnalyticShape::Torus {
                        center: [0.5, 0.5, 0.5],
                        major: 0.36,
                        minor: 0.07,
                    },
                    [0.2, 0.6, 0.3],
                ),
            ],
        }
    }

    /// A lawn texel like Neyret 1995's: a ground slab and 16 tilted grass blades (capsules),
    /// seeded.
    pub fn lawn(n: usize, seed: u64) -> Self {
        let mut rng = SplitMix64::new(seed);
        let mut shapes = vec![(
            AnalyticShape::Slab {
                min: [0.0, 0.0, 0.0],
                max: [1.0, 0.08, 1.0],
            },
            [0.35, 0.25, 0.15],
        )];
        for i in 0..16 {
            let (gx, gz) = ((i % 4) as f64, (i / 4) as f64);
            let base = [
                0.125 + 0.25 * gx + rng.range(-0.06, 0.06),
                0.08,
                0.125 + 0.25 * gz + rng.range(-0.06, 0.06),
            ];
            let tilt = rng.range(0.0, 0.35);
            let az = rng.range(0.0, std::f64::consts::TAU);
            let h = rng.range(0.6, 0.85);
            let tip = [
                (base[0] + h * tilt.sin() * az.cos()).clamp(0.03, 0.97),
                base[1] + h * tilt.cos(),
                (base[2] + h * tilt.sin() * az.sin()).clamp(0.03, 0.97),
            ];
            shapes.push((
                AnalyticShape::Capsule {
                    a: base,
                    b: tip,
                    radius: 0.018,
                },
                [0.2, 0.55 + 0.02 * i as f32, 0.15],
            ));
        }
        Self {
            name: "lawn".into(),
            n,
            shapes,
        }
    }
}

impl AnalyticVolume {
    /// Voxel `(x, y, z)` of the `n³` grid (centre `((x, y, z) + ½)/n`), [`Voxel::EMPTY`] where
    /// the coverage is zero (or the volume has no shape). Cost: one distance per shape.
    pub fn sample(&self, x: usize, y: usize, z: usize) -> Voxel {
        let h = 1.0 / self.n as f64;
        let p = DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * h;
        let mut best: Option<(f64, DVec3, [f32; 3])> = None;
        for (shape, color) in &self.shapes {
            let (d, g) = shape.sdf(p);
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, g, *color));
            }
        }
        let Some((d, g, color)) = best else {
            return Voxel::EMPTY;
        };
        let density = (0.5 - d / h).clamp(0.0, 1.0) as f32;
        if density == 0.0 {
            return Voxel::EMPTY;
        }
        Voxel {
            density,
            color,
            normal: (d.abs() < h).then_some([g.x as f32, g.y as f32, g.z as f32]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_gradients_match_closed_forms() {
        let sphere = AnalyticShape::Sphere {
            center: [0.5; 3],
            radius: 0.25,
        };
        let (d, g) = sphere.sdf(DVec3::new(0.5, 0.5, 0.95));
        assert!((d - 0.2).abs() < 1e-12 && (g - DVec3::Z).length() < 1e-12);
        let slab = AnalyticShape::Slab {
            min: [0.0; 3],
            max: [1.0, 0.1, 1.0],
        };
        let (d, g) = slab.sdf(DVec3::new(0.5, 0.04, 0.5));
        assert!((d + 0.04).abs() < 1e-12 && (g + DVec3::Y).length() < 1e-12);
        let (d, g) = slab.sdf(DVec3::new(0.5, 0.3, 0.5));
        assert!((d - 0.2).abs() < 1e-12 && (g - DVec3::Y).length() < 1e-12);
        let torus = AnalyticShape::Torus {
            center: [0.5; 3],
            major: 0.3,
            minor: 0.05,
        };
        let (d, g) = torus.sdf(DVec3::new(0.9, 0.5, 0.5));
        assert!((d - 0.05).abs() < 1e-12 && (g - DVec3::X).length() < 1e-12);
    }

    #[test]
    fn volumes_cover_their_shapes_and_nothing_else() {
        let v = AnalyticVolume::sphere_torus(32);
        let centre = v.sample(16, 16, 16);
        assert_eq!(centre.density, 1.0);
        assert_eq!(centre.normal, None);
        assert_eq!(v.sample(0, 0, 0), Voxel::EMPTY);
        let lawn = AnalyticVolume::lawn(32, 1);
        assert_eq!(lawn.shapes.len(), 17);
        assert_eq!(lawn.sample(3, 0, 3).density, 1.0);
    }
}
