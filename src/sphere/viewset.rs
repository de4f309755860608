//! Octahedral and hemi-octahedral grids of frame directions (conventions in the module docs).

use glam::{DVec2, DVec3};

use super::{SphereError, check};

/// Which directions a [`ViewSet`] covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Coverage {
    /// The upper hemisphere `y ≥ 0` (hemi-octahedral map): objects seen from the side and above.
    Hemisphere,
    /// The whole sphere (octahedral map).
    Sphere,
}

/// A `G × G` octahedral grid of frame directions (module docs: the maps, the grid, the
/// enclosing triangle).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ViewSet {
    /// What the grid covers.
    pub coverage: Coverage,
    /// Frames per side `G` (at least 2); `G²` frames in all.
    pub grid: usize,
}

/// The unit direction toward the camera at azimuth `a` and elevation `e` (radians):
/// `(cos e cos a, sin e, cos e sin a)`, the manifest's convention (`y` up, azimuth from `x`
/// toward `z`).
pub fn azimuth_elevation(a: f64, e: f64) -> DVec3 {
    DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
}

fn sign(x: f64) -> f64 {
    if x < 0.0 { -1.0 } else { 1.0 }
}

impl ViewSet {
    /// A hemi-octahedral grid of `grid × grid` frames. Errors: `grid < 2` or above 64.
    pub fn hemisphere(grid: usize) -> Result<Self, SphereError> {
        Self::new(Coverage::Hemisphere, grid)
    }

    /// A grid of `grid × grid` frames covering `coverage`. Errors: `grid < 2` or above 64.
    pub fn new(coverage: Coverage, grid: usize) -> Result<Self, SphereError> {
        check(
            (2..=64).contains(&grid),
            "view-set grid",
            grid,
            "must be 2 to 64 frames per side",
        )?;
        Ok(Self { coverage, grid })
    }

    /// Number of frames `G²`.
    pub fn len(&self) -> usize {
        self.grid * self.grid
    }

    /// Whether the set has no frame (never: `G ≥ 2`).
    pub fn is_empty(&self) -> bool {
        self.grid == 0
    }

    /// Octahedral coordinates of the unit direction `d` (module docs). For the hemisphere, `d`
    /// must have `y ≥ 0` (a direction below is mirrored to its upper twin).
    pub fn encode(&self, d: DVec3) -> DVec2 {
        let s = d.x.abs() + d.y.abs() + d.z.abs();
        let (a, b) = (d.x / s, d.z / s);
        match self.coverage {
            Coverage::Hemisphere => DVec2::new(a + b, a - b),
            Coverage::Sphere if d.y >= 0.0 => DVec2::new(a, b),
            Coverage::Sphere => DVec2::new((1.0 - b.abs()) * sign(a), (1.0 - a.abs()) * sign(b)),
        }
    }

    /// The unit direction of octahedral coordinates `e ∈ [−1, 1]²` (inverse of
    /// [`Self::encode`]).
    pub fn decode(&self, e: DVec2) -> DVec3 {
        let e = e.clamp(DVec2::splat(-1.0), DVec2::splat(1.0));
        let (a, b) = match self.coverage {
            Coverage::Hemisphere => ((e.x + e.y) * 0.5, (e.x - e.y) * 0.5),
            Coverage::Sphere => (e.x, e.y),
        };
        let y = 1.0 - a.abs() - b.abs();
        let (a, b) = if y < 0.0 {
            ((1.0 - b.abs()) * sign(a), (1.0 - a.abs()) * sign(b))
        } else {
            (a, b)
        };
        DVec3::new(a, y, b).normalize()
    }

    /// Octahedral coordinates of grid point `(i, j)`.
    fn grid_point(&self, i: usize, j: usize) -> DVec2 {
        let s = 2.0 / (self.grid - 1) as f64;
        DVec2::new(-1.0 + s * i as f64, -1.0 + s * j as f64)
    }

    /// The direction of frame `k` (`k = j·G + i`).
    pub fn direction(&self, k: usize) -> DVec3 {
        self.decode(self.grid_point(k % self.grid, k / self.grid))
    }

    /// All frame directions, in frame order.
    pub fn directions(&self) -> Vec<DVec3> {
        (0..self.len()).map(|k| self.direction(k)).collect()
    }

    /// The three enclosing frames of the unit direction `d` and their barycentric weights (sum
    /// 1, each in `[0, 1]`). Errors: `d` not finite or zero, or below the horizon (`y < −10⁻⁹`)
    /// for a hemisphere.
    pub fn enclosing(&self, d: DVec3) -> Result<[(usize, f64); 3], SphereError> {
        check(
            d.is_finite() && d.length() > 1e-12,
            "display direction",
            format!("{d:?}"),
            "must be finite and not zero",
        )?;
        let d = d.normalize();
        check(
            self.coverage == Coverage::Sphere || d.y >= -1e-9,
            "display direction",
            format!("{d:?}"),
            "a hemisphere view set covers directions with y ≥ 0 only",
        )?;
        let g = (self.encode(d) + 1.0) * 0.5 * (self.grid - 1) as f64;
        let last = (self.grid - 2) as f64;
        let (i, j) = (g.x.floor().clamp(0.0, last), g.y.floor().clamp(0.0, last));
        let (f0, f1) = ((g.x - i).clamp(0.0, 1.0), (g.y - j).clamp(0.0, 1.0));
        let (i, j) = (i as usize, j as usize);
        let k = |a: usize, b: usize| b * self.grid + a;
        Ok(if f0 + f1 <= 1.0 {
            [
                (k(i, j), 1.0 - f0 - f1),
                (k(i + 1, j), f0),
                (k(i, j + 1), f1),
            ]
        } else {
            [
                (k(i + 1, j + 1), f0 + f1 - 1.0),
                (k(i, j + 1), 1.0 - f0),
                (k(i + 1, j), 1.0 - f1),
            ]
        })
    }

    /// The triangles (corners in octahedral coordinates) that have frame `k` as a corner.
    fn triangles_of(&self, k: usize) -> Vec<[DVec2; 3]> {
        let (fi, fj) = (k % self.grid, k / self.grid);
        let mut out = Vec::new();
        for j in fj.saturating_sub(1)..=fj.min(self.grid - 2) {
            for i in fi.saturating_sub(1)..=fi.min(self.grid - 2) {
                let tris = [
                    [(i, j), (i + 1, j), (i, j + 1)],
                    [(i + 1, j + 1), (i, j + 1), (i + 1, j)],
                ];
                for t in tris {
                    if t.contains(&(fi, fj)) {
                        out.push(t.map(|(a, b)| self.grid_point(a, b)));
                    }
                }
            }
        }
        out
    }

    /// Half-angle `β_k` (radians) of the cone of directions that use frame `k`: the largest
    /// angle between its direction and a direction of one of its triangles. The maximum of the
    /// angle over a triangle lies on its border (the distance to a point on the sphere has no
    /// other local maximum than the antipode, which no triangle holds); the border is sampled
    /// at 512 points per edge and the largest angular gap between neighbouring samples is
    /// added, so the value is an upper bound. Cost: ~1.5 k decodes per triangle.
    pub fn cone_angle(&self, k: usize) -> f64 {
        const SAMPLES: usize = 512;
        let dk = self.direction(k);
        let mut worst = 0.0f64;
        let mut gap = 0.0f64;
        for tri in self.triangles_of(k) {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let mut prev = self.decode(a);
                for s in 0..=SAMPLES {
                    let d = self.decode(a.lerp(b, s as f64 / SAMPLES as f64));
                    worst = worst.max(d.angle_between(dk));
                    gap = gap.max(d.angle_between(prev));
                    prev = d;
                }
            }
        }
        worst + gap
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn encode_and_decode_are_inverse() {
        for coverage in [Coverage::Hemisphere, Coverage::Sphere] {
            let set = ViewSet::new(coverage, 5).unwrap();
            for k in 0..200 {
                let t = k as f64 * 0.731;
                let y = (k as f64 / 200.0)
                    * if coverage == Coverage::Sphere {
                        2.0
                    } else {
                        1.0
                    }
                    - if coverage == Coverage::Sphere {
                        1.0
                    } else {
                        0.0
                    };
                let r = (1.0 - y * y).max(0.0).sqrt();
                let d = DVec3::new(r * t.cos(), y, r * t.sin());
                let back = set.decode(set.encode(d));
                assert_abs_diff_eq!(back.distance(d), 0.0, epsilon = 1e-12);
            }
        }
    }

    #[test]
    fn enclosing_weights_reproduce_the_direction_on_the_map_and_hit_frames_exactly() {
        let set = ViewSet::hemisphere(4).unwrap();
        for k in 0..set.len() {
            let w = set.enclosing(set.direction(k)).unwrap();
            let own: f64 = w.iter().filter(|(f, _)| *f == k).map(|(_, w)| w).sum();
            assert_abs_diff_eq!(own, 1.0, epsilon = 1e-9);
        }
        let d = DVec3::new(0.3, 0.6, -0.2).normalize();
        let w = set.enclosing(d).unwrap();
        let e: DVec2 = w
            .iter()
            .map(|&(f, wt)| set.grid_point(f % 4, f / 4) * wt)
            .sum();
        assert_abs_diff_eq!(e.distance(set.encode(d)), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(w.iter().map(|x| x.1).sum::<f64>(), 1.0, epsilon = 1e-12);
        assert!(set.enclosing(DVec3::new(0.0, -1.0, 0.0)).is_err());
        assert!(set.enclosing(DVec3::ZERO).is_err());
        assert!(ViewSet::hemisphere(1).is_err());
    }

    #[test]
    fn cone_angles_cover_every_direction_that_uses_a_frame() {
        let set = ViewSet::hemisphere(4).unwrap();
        let cones: Vec<f64> = (0..set.len()).map(|k| set.cone_angle(k)).collect();
        for d in crate::sphere::fibonacci_directions(2000, Coverage::Hemisphere) {
            for (k, w) in set.enclosing(d).unwrap() {
                if w > 0.0 {
                    assert!(d.angle_between(set.direction(k)) <= cones[k], "frame {k}");
                }
            }
        }
        // The march needs every direction of a cone in front of the frame (d·d_k > 0).
        assert!(
            cones.iter().all(|c| *c < std::f64::consts::FRAC_PI_2),
            "{cones:?}"
        );
    }
}
