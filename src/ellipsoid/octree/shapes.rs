//! Analytic procedural volumes for the octree: signed-distance shapes ([`AnalyticShape`]) and
//! their union sampled as voxels ([`AnalyticVolume`]).

use nalgebra::Vector3;

use super::voxels::{Voxel, VoxelSource};

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
    pub fn sdf(&self, p: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let safe = |v: Vector3<f64>| {
            let n = v.norm();
            if n > 0.0 { v / n } else { Vector3::y() }
        };
        match *self {
            AnalyticShape::Sphere { center, radius } => {
                let d = p - Vector3::from(center);
                (d.norm() - radius, safe(d))
            }
            AnalyticShape::Torus {
                center,
                major,
                minor,
            } => {
                let d = p - Vector3::from(center);
                let radial = Vector3::new(d.x, 0.0, d.z);
                let ring = safe(radial) * major;
                let q = d - ring;
                (q.norm() - minor, safe(q))
            }
            AnalyticShape::Capsule { a, b, radius } => {
                let (a, b) = (Vector3::from(a), Vector3::from(b));
                let ab = b - a;
                let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                let d = p - (a + ab * t);
                (d.norm() - radius, safe(d))
            }
            AnalyticShape::Slab { min, max } => {
                let c = (Vector3::from(min) + Vector3::from(max)) * 0.5;
                let h = (Vector3::from(max) - Vector3::from(min)) * 0.5;
                let d = p - c;
                let q = d.abs() - h;
                let outside = q.map(|x| x.max(0.0));
                if outside.norm() > 0.0 {
                    let n = outside.component_mul(&d.map(|x| x.signum()));
                    (outside.norm(), safe(n))
                } else {
                    let k = q.imax();
                    let mut n = Vector3::zeros();
                    n[k] = d[k].signum();
                    (q.max(), n)
                }
            }
        }
    }
}

/// A procedural volume: a union of [`AnalyticShape`]s in the unit cube, sampled at voxel centres.
/// Coverage `clamp(0.5 − sd/h, 0, 1)` (a one-voxel ramp, `h` the voxel size), normal = gradient of
/// the nearest shape where `|sd| < h` (the surface shell), `None` deeper inside; each shape has a
/// colour. Cost per voxel: one distance per shape.
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

    /// A lawn texel like the seed's: a ground slab and 16 tilted grass blades (capsules), seeded.
    pub fn lawn(n: usize, seed: u64) -> Self {
        let mut rng = crate::ellipsoid::rng::SplitMix64::new(seed);
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

impl VoxelSource for AnalyticVolume {
    fn dims(&self) -> [usize; 3] {
        [self.n; 3]
    }

    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let h = 1.0 / self.n as f64;
        let p = Vector3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * h;
        let mut best: Option<(f64, Vector3<f64>, [f32; 3])> = None;
        for (shape, color) in &self.shapes {
            let (d, g) = shape.sdf(&p);
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
            normal: (d.abs() < h).then(|| [g.x as f32, g.y as f32, g.z as f32]),
        }
    }
}
