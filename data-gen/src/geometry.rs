//! Rays, hits, the bounding cylinder and the view conventions (see the crate docs).

use glam::{DVec3, Vec3};

use crate::error::{DataGenError, finite};

/// Horizontal unit direction at angle `alpha` (radians): `d(α) = (cos α, 0, sin α)`.
#[inline]
pub fn direction(alpha: f64) -> DVec3 {
    DVec3::new(alpha.cos(), 0.0, alpha.sin())
}

/// Screen "right" vector of the view at angle `alpha`: `(sin α, 0, −cos α)`, so that
/// `right × y = d(α)` and the screen abscissa of `r·d(β)` is `r·sin(α − β)`.
#[inline]
pub fn screen_right(alpha: f64) -> DVec3 {
    DVec3::new(alpha.sin(), 0.0, -alpha.cos())
}

/// A ray `origin + t·dir`, `t` in world units (`dir` need not be unit, but every ray data-gen
/// makes has a unit direction).
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point.
    pub origin: DVec3,
    /// Direction.
    pub dir: DVec3,
}

impl Ray {
    /// A ray from `origin` along `dir`.
    pub fn new(origin: DVec3, dir: DVec3) -> Self {
        Self { origin, dir }
    }
    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.dir
    }
}

/// The first intersection of a ray with a shape.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Unit shading normal, facing the incoming ray (`normal · dir ≤ 0`): the surface's own, or
    /// a mesh's interpolated vertex normal turned by its normal map.
    pub normal: DVec3,
    /// Unit geometric normal of the surface hit (a mesh's triangle), facing the incoming ray:
    /// what sampling density and grazing depend on.
    pub geometric: DVec3,
    /// Linear RGB albedo at the hit.
    pub albedo: Vec3,
}

/// The cylinder every object is normalised into: radius `R` about the `y` axis, `y ∈ [0, H]`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BoundingCylinder {
    /// Radius `R` (world units).
    pub radius: f64,
    /// Height `H` (world units).
    pub height: f64,
}

impl Default for BoundingCylinder {
    /// `R = 1`, `H = 2`: the cylinder the procedural shapes are built for.
    fn default() -> Self {
        Self {
            radius: 1.0,
            height: 2.0,
        }
    }
}

impl BoundingCylinder {
    /// Checks that both dimensions are finite and positive.
    pub fn validate(&self) -> Result<(), DataGenError> {
        finite(self.radius, "cylinder radius", 0)?;
        finite(self.height, "cylinder height", 1)?;
        if self.radius <= 0.0 || self.height <= 0.0 {
            return Err(DataGenError::InvalidParameter {
                name: "bounding cylinder",
                value: format!("R={}, H={}", self.radius, self.height),
                reason: "radius and height must be positive",
            });
        }
        Ok(())
    }
}

/// A pixel grid over the cylinder's silhouette `[−R, R] × [0, H]` (see the crate docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelGrid {
    /// Columns.
    pub width: usize,
    /// Rows (row 0 at the top).
    pub height: usize,
    /// The cylinder the grid spans.
    pub cylinder: BoundingCylinder,
}

impl PixelGrid {
    /// Horizontal pixel pitch `δx = 2R / W` (world units).
    #[inline]
    pub fn pitch_x(&self) -> f64 {
        2.0 * self.cylinder.radius / self.width as f64
    }
    /// Vertical pixel pitch `δy = H / Hpx` (world units).
    #[inline]
    pub fn pitch_y(&self) -> f64 {
        self.cylinder.height / self.height as f64
    }
    /// Screen abscissa of the continuous column coordinate `u` (pixel centres at `i + ½`).
    #[inline]
    pub fn x_at(&self, u: f64) -> f64 {
        -self.cylinder.radius + u * self.pitch_x()
    }
    /// Height of the continuous row coordinate `v` (row centres at `j + ½`, row 0 at the top).
    #[inline]
    pub fn y_at(&self, v: f64) -> f64 {
        self.cylinder.height - v * self.pitch_y()
    }
    /// Centre of pixel `(i, j)` as (screen x, height y).
    #[inline]
    pub fn center(&self, i: usize, j: usize) -> (f64, f64) {
        (self.x_at(i as f64 + 0.5), self.y_at(j as f64 + 0.5))
    }
    /// Continuous column coordinate of screen abscissa `x` (inverse of [`Self::x_at`]).
    #[inline]
    pub fn u_of(&self, x: f64) -> f64 {
        (x + self.cylinder.radius) / self.pitch_x()
    }
}

/// Rays that share one direction and start on a grid across it: the rays of an orthographic
/// view, traced together by [`crate::Shape::parallel_tracer`].
///
/// Ray `(c, r)` (column `c < columns.len()`, row `r < rows.len()`) is `ray(c, r)`; the caller
/// builds it with its own formula, so a grid of rays gives bitwise the rays the caller would
/// trace one at a time. Every ray must have direction `dir`, and its origin `o` must satisfy
/// `o·across[0] ≈ columns[c]` and `o·across[1] ≈ rows[r]` (to within rounding); `columns` and
/// `rows` are each strictly monotonic (either way). A shape that bins its geometry over the
/// grid checks both per ray and traces a ray that breaks them on its own, so a wrong grid costs
/// speed, never correctness.
pub struct ParallelRays<'a> {
    /// Direction of every ray.
    pub dir: DVec3,
    /// Two unit vectors orthogonal to `dir` and to each other: the screen axes of the grid.
    pub across: [DVec3; 2],
    /// `o·across[0]` of each column's rays (world units).
    pub columns: &'a [f64],
    /// `o·across[1]` of each row's rays (world units).
    pub rows: &'a [f64],
    /// The hit window `(t_min, t_max)` of every ray.
    pub t_min: f64,
    /// See `t_min`.
    pub t_max: f64,
    /// The ray of column `c`, row `r`.
    pub ray: &'a (dyn Fn(usize, usize) -> Ray + Sync),
}

/// The cell of a grid of rays that one ray stands for: what a textured surface is averaged over
/// where the ray meets it (`docs/real-assets.md`). A capture's ray stands for its pixel; each of
/// the truth's `k × k` rays for a `1/k` part of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Footprint {
    /// Parallel rays: the cell's two edge vectors (world units), orthogonal to the rays.
    Parallel([DVec3; 2]),
    /// Horizontal rays toward the `y` axis: `angle` radians around the axis by `height` world
    /// units (the cell's width grows with the distance from the axis).
    Radial {
        /// Angular width (radians).
        angle: f64,
        /// Height (world units).
        height: f64,
    },
}

impl Footprint {
    /// The cell's two edge vectors at point `p` of a ray along `dir`.
    pub fn at(&self, p: DVec3, dir: DVec3) -> [DVec3; 2] {
        match *self {
            Footprint::Parallel(axes) => axes,
            Footprint::Radial { angle, height } => {
                let r = p.x.hypot(p.z);
                let tangent = DVec3::new(-dir.z, 0.0, dir.x).normalize_or_zero();
                [tangent * (r * angle), DVec3::Y * height]
            }
        }
    }
}

/// The mean spacing of sorted positions `v`, `None` for fewer than two or a non-finite spacing.
fn spacing(v: &[f64]) -> Option<f64> {
    let (first, last) = (v.first()?, v.last()?);
    let s = ((last - first) / (v.len() as f64 - 1.0)).abs();
    (v.len() >= 2 && s.is_finite() && s > 0.0).then_some(s)
}

impl<'a> ParallelRays<'a> {
    /// Number of rays, `columns × rows`.
    pub fn len(&self) -> usize {
        self.columns.len() * self.rows.len()
    }

    /// The cell each ray stands for: the grid's mean spacing along each screen axis (one axis's
    /// for the other when the grid is one ray across). `None` for a single ray.
    pub fn footprint(&self) -> Option<Footprint> {
        let (c, r) = (spacing(self.columns), spacing(self.rows));
        let (c, r) = (c.or(r)?, r.or(c)?);
        Some(Footprint::Parallel([
            self.across[0] * c,
            self.across[1] * r,
        ]))
    }

    /// Whether the grid has no ray.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The rays of a cylindrical capture (docs/design.md §3.3): horizontal rays through the `y` axis,
/// traced together by [`crate::Shape::radial_tracer`].
///
/// Column `c < columns` looks along `−d(α_c)`, `α_c = 2πc/L` ([`direction`]); row `r` lies at
/// height `rows[r]`. Ray `(c, r)` starts at `(0, rows[r], 0) + 2R·d(α_c)`, outside the bounding
/// cylinder of radius `R`, crosses the axis at `t = 2R` and ends at `t = 4R`: the hit window is
/// `(0, 4R)`. [`Self::ray`] is the one formula of this ray, for a shape that traces the grid
/// and for one that casts ray by ray. `rows` need not be sorted; a shape that bins its geometry
/// over the rows traces unsorted rows one by one.
#[derive(Clone, Copy, Debug)]
pub struct RadialRays<'a> {
    /// Height of each row's rays (world units).
    pub rows: &'a [f64],
    /// Number of columns `L` (angles around the axis).
    pub columns: usize,
    /// Radius `R` of the bounding cylinder (world units).
    pub radius: f64,
}

impl RadialRays<'_> {
    /// Number of rays, `columns × rows`.
    pub fn len(&self) -> usize {
        self.columns * self.rows.len()
    }

    /// Whether the grid has no ray.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The outward direction `d(α_c)` of column `c`, `α_c = 2πc/L`: ray `(c, r)` travels along
    /// its opposite.
    #[inline]
    pub fn outward(&self, c: usize) -> DVec3 {
        direction(std::f64::consts::TAU * c as f64 / self.columns as f64)
    }

    /// The ray of row `r` whose outward direction is `outward` (= [`Self::outward`] of its
    /// column): from `(0, rows[r], 0) + 2R·outward` along `−outward`.
    #[inline]
    pub fn ray_along(&self, outward: DVec3, r: usize) -> Ray {
        Ray::new(
            DVec3::Y * self.rows[r] + 2.0 * self.radius * outward,
            -outward,
        )
    }

    /// The ray of column `c`, row `r`.
    #[inline]
    pub fn ray(&self, c: usize, r: usize) -> Ray {
        self.ray_along(self.outward(c), r)
    }

    /// The cell each ray stands for: `2π/L` around the axis by the rows' mean spacing (the
    /// angular width at radius `R` for a single row).
    pub fn footprint(&self) -> Option<Footprint> {
        if self.columns == 0 {
            return None;
        }
        let angle = std::f64::consts::TAU / self.columns as f64;
        let height = spacing(self.rows).unwrap_or(angle * self.radius);
        (angle.is_finite() && height.is_finite()).then_some(Footprint::Radial { angle, height })
    }

    /// The end of every ray's hit window, `4R` (the start is 0).
    #[inline]
    pub fn t_max(&self) -> f64 {
        4.0 * self.radius
    }
}

/// Fractional pixel coordinate of sub-sample `a` of pixel `i` in a `k × k` stratification:
/// `i + (a + ½)/k` (`i + ½` at the centre for `k = 1`).
#[inline]
pub(crate) fn sub_sample(i: usize, a: usize, k: usize) -> f64 {
    i as f64 + (a as f64 + 0.5) / k as f64
}

/// The `k × k` sub-sample rays of every pixel of an orthographic view at angle `alpha` (crate
/// docs), as one grid of `width·k × height·k` parallel rays: their screen positions, and the
/// ray through each, along `−d(α)` from `2R` in front of its screen point. The one formula of
/// captures (`k = 1`) and ground truths.
pub(crate) struct ViewGrid {
    radius: f64,
    d: DVec3,
    right: DVec3,
    /// Screen abscissa of each column of rays, `x_at(sub_sample(i, a, k))`.
    pub(crate) columns: Vec<f64>,
    /// Height of each row of rays, `y_at(sub_sample(j, b, k))`.
    pub(crate) rows: Vec<f64>,
}

impl ViewGrid {
    /// The sub-sample grid of `grid` viewed at angle `alpha`, `k` rays across each pixel.
    pub(crate) fn new(grid: &PixelGrid, alpha: f64, k: usize) -> Self {
        Self {
            radius: grid.cylinder.radius,
            d: direction(alpha),
            right: screen_right(alpha),
            columns: (0..grid.width * k)
                .map(|c| grid.x_at(sub_sample(c / k, c % k, k)))
                .collect(),
            rows: (0..grid.height * k)
                .map(|r| grid.y_at(sub_sample(r / k, r % k, k)))
                .collect(),
        }
    }

    /// The ray of column `c`, row `r`.
    #[inline]
    pub(crate) fn ray(&self, c: usize, r: usize) -> Ray {
        let start = self.columns[c] * self.right + DVec3::Y * self.rows[r];
        Ray::new(start + 2.0 * self.radius * self.d, -self.d)
    }

    /// The view direction `d(α)` (rays travel along `−d`).
    pub(crate) fn d(&self) -> DVec3 {
        self.d
    }

    /// The grid as [`ParallelRays`] with rays `ray` (the caller's closure over [`Self::ray`]):
    /// screen axes `[right(α), +y]`, hit window `(0, 4R)`.
    pub(crate) fn parallel_rays<'a>(
        &'a self,
        ray: &'a (dyn Fn(usize, usize) -> Ray + Sync),
    ) -> ParallelRays<'a> {
        ParallelRays {
            dir: -self.d,
            across: [self.right, DVec3::Y],
            columns: &self.columns,
            rows: &self.rows,
            t_min: 0.0,
            t_max: 4.0 * self.radius,
            ray,
        }
    }
}
