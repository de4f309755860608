//! The [`Shape`] trait and the procedural constructive solids ([`Csg`]: a union of analytic
//! primitives, each with an albedo).
//!
//! Primitives intersect rays analytically (sphere, box, capsule, capped cylinder) or by sphere
//! tracing their signed distance with a bisection refinement (torus), to about 1e-9 world units.
//! Rays are assumed to start outside every primitive (data-gen's rays start outside the bounding
//! cylinder); a primitive reports the first surface crossing with `t > t_min`.

use std::ops::Range;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::albedo::Albedo;
use crate::error::DataGenError;
use crate::geometry::{Footprint, Hit, ParallelRays, RadialRays, Ray};

/// Anything data-gen can sample: ray intersection, inside test, bounds.
///
/// Implemented by [`Csg`] (procedural) and [`crate::Mesh`]. All methods are thread-safe and
/// called from rayon loops.
pub trait Shape: Send + Sync {
    /// A short name for reports.
    fn name(&self) -> &str;
    /// First hit of `ray` with `t ∈ (t_min, t_max)`, or `None`.
    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit>;
    /// [`Shape::intersect`] for a ray that stands for the cell `footprint` of a grid: a
    /// textured surface is read over the cell ([`crate::Mesh`]); shapes without textures
    /// ignore it (the default).
    fn intersect_over(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        footprint: Option<Footprint>,
    ) -> Option<Hit> {
        let _ = footprint;
        self.intersect(ray, t_min, t_max)
    }
    /// Whether `ray` meets the shape with `t ∈ (t_min, t_max)`: exactly
    /// `self.intersect(ray, t_min, t_max).is_some()`, which is what the default computes. A
    /// shape overrides it where it can stop at any hit and skip shading ([`crate::Mesh`]: the
    /// BVH walk stops at the first triangle it meets).
    fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.intersect(ray, t_min, t_max).is_some()
    }
    /// Whether `p` is inside the solid.
    fn contains(&self, p: DVec3) -> bool;
    /// Axis-aligned bounds `(min, max)` of the solid.
    fn bounds(&self) -> (DVec3, DVec3);
    /// Whether the shape encloses a volume, so that [`Shape::contains`] means something:
    /// voxelisation then fills its inside ([`crate::Fill::Auto`] takes [`crate::Fill::Solid`]),
    /// and otherwise covers its surface ([`crate::Fill::Shell`]). True by default (procedural
    /// solids); a [`crate::Mesh`] answers from its edges and materials.
    fn encloses_volume(&self) -> bool {
        true
    }
    /// Whether some of the surface lets rays through its back faces ([`crate::Mesh`]: a
    /// single-sided glTF material), so that what a ray meets depends on its sense: the shell
    /// voxelisation then casts its rays both ways. False by default.
    fn single_sided(&self) -> bool {
        false
    }
    /// Linear RGB albedo of the surface nearest to `p` (used by voxelisation).
    fn albedo_at(&self, p: DVec3) -> Vec3;
    /// Signed distance to the surface (negative inside), when the shape has one. Used for voxel
    /// normals; shapes without it get normals from the density gradient.
    fn sdf(&self, _p: DVec3) -> Option<f64> {
        None
    }
    /// Inside tests of the row of points `(xs[i], y, z)`, written to `inside[i]` (pairs beyond
    /// the shorter slice are left alone). The answers are exactly those of [`Shape::contains`]
    /// point by point, which is what the default does; a shape overrides it where one row of
    /// points can share work ([`crate::Mesh`] tests only the triangles near the row's parity
    /// ray). Used by voxelisation.
    fn contains_row(&self, y: f64, z: f64, xs: &[f64], inside: &mut [bool]) {
        for (x, o) in xs.iter().zip(inside.iter_mut()) {
            *o = self.contains(DVec3::new(*x, y, z));
        }
    }
    /// A tracer of the grid of parallel rays `rays`: whatever work the rays can share (a mesh
    /// bins its triangles over the grid) is done here, once, and
    /// [`ParallelTracer::trace_rows`] then traces bands of rows, from any thread. Each hit is
    /// the one [`Shape::intersect`] finds for that ray, up to the exceptions stated by the
    /// implementation ([`crate::Mesh`]: where two triangles meet a ray at the same `f32`
    /// distance).
    ///
    /// The default traces each ray with [`Shape::intersect`]. Cost: up to `O(rays.len())`.
    fn parallel_tracer<'a>(&'a self, rays: &'a ParallelRays<'a>) -> Box<dyn ParallelTracer + 'a> {
        Box::new(OneByOne { shape: self, rays })
    }
    /// A tracer of the radial rays `rays` of a cylindrical capture, as
    /// [`Shape::parallel_tracer`] is for parallel rays: shared work here, then bands of rows
    /// from any thread, each hit the one [`Shape::intersect`] finds for [`RadialRays::ray`] in
    /// `(0, 4R)`, up to the same exceptions ([`crate::Mesh`] bins its triangles by height and
    /// angle).
    ///
    /// The default traces each ray with [`Shape::intersect`]. Cost: up to `O(rays.len())`.
    fn radial_tracer<'a>(&'a self, rays: &'a RadialRays<'a>) -> Box<dyn ParallelTracer + 'a> {
        Box::new(RadialOneByOne { shape: self, rays })
    }
    /// The shape as a triangle mesh, where it is one ([`crate::Mesh`]; `None` by default):
    /// for what only meshes have (simplification, export).
    fn as_mesh(&self) -> Option<&crate::Mesh> {
        None
    }
    /// Builds now what ray queries need and a shape builds on first use ([`crate::Mesh`]: its
    /// BVH), so that a caller can choose the thread and the moment; queries give the same
    /// answers either way. The default does nothing.
    fn prepare_rays(&self) {}
}

/// A shape traced one ray at a time: every method delegates to the inner shape except
/// [`Shape::parallel_tracer`] and [`Shape::radial_tracer`], which keep the defaults (one
/// [`Shape::intersect`] per ray). For comparing a shape's grid tracers with its own per-ray
/// casts (tests, benchmarks).
pub struct RayByRay<'a>(pub &'a dyn Shape);

impl Shape for RayByRay<'_> {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        self.0.intersect(ray, t_min, t_max)
    }
    fn intersect_over(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        footprint: Option<Footprint>,
    ) -> Option<Hit> {
        self.0.intersect_over(ray, t_min, t_max, footprint)
    }
    fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.0.occluded(ray, t_min, t_max)
    }
    fn contains(&self, p: DVec3) -> bool {
        self.0.contains(p)
    }
    fn bounds(&self) -> (DVec3, DVec3) {
        self.0.bounds()
    }
    fn encloses_volume(&self) -> bool {
        self.0.encloses_volume()
    }
    fn single_sided(&self) -> bool {
        self.0.single_sided()
    }
    fn albedo_at(&self, p: DVec3) -> Vec3 {
        self.0.albedo_at(p)
    }
    fn sdf(&self, p: DVec3) -> Option<f64> {
        self.0.sdf(p)
    }
    fn contains_row(&self, y: f64, z: f64, xs: &[f64], inside: &mut [bool]) {
        self.0.contains_row(y, z, xs, inside);
    }
    fn prepare_rays(&self) {
        self.0.prepare_rays();
    }
}

/// Traces bands of rows of a grid of rays: a [`ParallelRays`] grid (made by
/// [`Shape::parallel_tracer`]) or a [`RadialRays`] grid (made by [`Shape::radial_tracer`]).
pub trait ParallelTracer: Sync {
    /// The number of rows of a band: callers that split the grid into bands of this many rows
    /// (starting at row 0) let the tracer share its work within each band.
    fn band_rows(&self) -> usize;
    /// Traces rows `rows` of the grid into `out[(r − rows.start) · columns + c]`. `out` must hold
    /// `rows.len() × columns` entries; rows past the grid are not traced.
    fn trace_rows(&self, rows: Range<usize>, out: &mut [Option<Hit>]);
    /// Whether each ray of rows `rows` meets the shape, laid out as [`Self::trace_rows`] lays
    /// out its hits: exactly `trace_rows`' hits' `is_some()`, which is what the default
    /// computes. Tracers override it to skip shading and stop at any hit.
    fn occluded_rows(&self, rows: Range<usize>, out: &mut [bool]) {
        let mut hits = vec![None; out.len()];
        self.trace_rows(rows, &mut hits);
        for (o, h) in out.iter_mut().zip(&hits) {
            *o = h.is_some();
        }
    }
}

/// The first hits of every ray of `rays`, `out[r · columns + c]`, traced in bands of rows in
/// parallel by `shape`'s [`Shape::parallel_tracer`]. Cost: that of the tracer.
pub fn intersect_parallel(shape: &dyn Shape, rays: &ParallelRays) -> Vec<Option<Hit>> {
    let mut out = vec![None; rays.len()];
    trace_in_groups(
        shape,
        rays,
        1,
        rays.columns.len(),
        &mut out,
        |_, hits, out| {
            out.copy_from_slice(hits);
        },
    );
    out
}

/// Traces `rays` in bands of rows, in parallel, and hands the hits to `consume` group by group:
/// the grid's rows come in groups of `rows_per_group` (the sub-sample rows of one pixel row),
/// each owning `out_per_group` consecutive entries of `out`. `consume(first_group, hits, out)`
/// gets the hits of whole consecutive groups (`rows × columns`, row-major) and their part of
/// `out`. Chunks hold whole bands of the tracer, so no band is binned twice.
pub(crate) fn trace_in_groups<T: Send>(
    shape: &dyn Shape,
    rays: &ParallelRays,
    rows_per_group: usize,
    out_per_group: usize,
    out: &mut [T],
    consume: impl Fn(usize, &[Option<Hit>], &mut [T]) + Sync,
) {
    let tracer = shape.parallel_tracer(rays);
    let (w, h) = (rays.columns.len(), rays.rows.len());
    trace_grid_in_groups(&*tracer, w, h, rows_per_group, out_per_group, out, consume);
}

/// [`trace_in_groups`] with any tracer of a grid of `w × h` rays.
pub(crate) fn trace_grid_in_groups<T: Send>(
    tracer: &dyn ParallelTracer,
    w: usize,
    h: usize,
    rows_per_group: usize,
    out_per_group: usize,
    out: &mut [T],
    consume: impl Fn(usize, &[Option<Hit>], &mut [T]) + Sync,
) {
    let band = tracer.band_rows();
    let trace = |rows, hits: &mut [Option<Hit>]| tracer.trace_rows(rows, hits);
    let groups = Groups {
        w,
        h,
        rows_per_group,
        out_per_group,
    };
    groups.run(band, trace, out, consume);
}

/// A grid of `w × h` rays whose rows come in groups of `rows_per_group`, each owning
/// `out_per_group` consecutive entries of an output ([`trace_grid_in_groups`]).
pub(crate) struct Groups {
    pub(crate) w: usize,
    pub(crate) h: usize,
    pub(crate) rows_per_group: usize,
    pub(crate) out_per_group: usize,
}

impl Groups {
    /// Runs `trace(rows, per_ray)` over chunks of whole groups and whole bands of `band` rows,
    /// in parallel, and hands each chunk's per-ray results to `consume` as
    /// [`trace_grid_in_groups`] does.
    pub(crate) fn run<H: Clone + Default + Send, T: Send>(
        &self,
        band: usize,
        trace: impl Fn(Range<usize>, &mut [H]) + Sync,
        out: &mut [T],
        consume: impl Fn(usize, &[H], &mut [T]) + Sync,
    ) {
        let Self {
            w,
            h,
            rows_per_group,
            out_per_group,
        } = *self;
        if w == 0 || rows_per_group == 0 || out_per_group == 0 {
            return;
        }
        let band = band.max(1);
        // Groups per chunk: the least number whose rows are a whole number of bands.
        let groups = band / gcd(band, rows_per_group);
        let groups_total = h / rows_per_group;
        let len = (groups_total * out_per_group).min(out.len());
        let out = &mut out[..len];
        out.par_chunks_mut(groups * out_per_group)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * groups;
                let rows =
                    first * rows_per_group..(first + out.len() / out_per_group) * rows_per_group;
                let mut per_ray = vec![H::default(); rows.len() * w];
                trace(rows, &mut per_ray);
                consume(first, &per_ray, out);
            });
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The default [`ParallelTracer`]: each ray on its own, with [`Shape::intersect`].
pub(crate) struct OneByOne<'a, S: ?Sized> {
    pub(crate) shape: &'a S,
    pub(crate) rays: &'a ParallelRays<'a>,
}

impl<S: Shape + ?Sized> OneByOne<'_, S> {
    /// `out[(r − rows.start) · columns + c] = f(ray (c, r))` for the rows of the grid in `rows`.
    fn each_ray<T>(&self, rows: Range<usize>, out: &mut [T], f: impl Fn(&Ray) -> T) {
        let w = self.rays.columns.len();
        if w == 0 {
            return;
        }
        let rows = rows.start..rows.end.min(self.rays.rows.len());
        for (r, out) in rows.zip(out.chunks_mut(w)) {
            for (c, o) in out.iter_mut().enumerate() {
                *o = f(&(self.rays.ray)(c, r));
            }
        }
    }
}

impl<S: Shape + ?Sized> ParallelTracer for OneByOne<'_, S> {
    fn band_rows(&self) -> usize {
        1
    }

    fn trace_rows(&self, rows: Range<usize>, out: &mut [Option<Hit>]) {
        let (t_min, t_max) = (self.rays.t_min, self.rays.t_max);
        let cell = self.rays.footprint();
        self.each_ray(rows, out, |ray| {
            self.shape.intersect_over(ray, t_min, t_max, cell)
        });
    }

    fn occluded_rows(&self, rows: Range<usize>, out: &mut [bool]) {
        let (t_min, t_max) = (self.rays.t_min, self.rays.t_max);
        self.each_ray(rows, out, |ray| self.shape.occluded(ray, t_min, t_max));
    }
}

/// The default radial tracer: each ray on its own, with [`Shape::intersect`].
pub(crate) struct RadialOneByOne<'a, S: ?Sized> {
    pub(crate) shape: &'a S,
    pub(crate) rays: &'a RadialRays<'a>,
}

impl<S: Shape + ?Sized> ParallelTracer for RadialOneByOne<'_, S> {
    fn band_rows(&self) -> usize {
        1
    }

    fn trace_rows(&self, rows: Range<usize>, out: &mut [Option<Hit>]) {
        let w = self.rays.columns;
        if w == 0 {
            return;
        }
        let outward: Vec<DVec3> = (0..w).map(|c| self.rays.outward(c)).collect();
        let cell = self.rays.footprint();
        let rows = rows.start..rows.end.min(self.rays.rows.len());
        for (r, out) in rows.zip(out.chunks_mut(w)) {
            for (d, o) in outward.iter().zip(out.iter_mut()) {
                let ray = self.rays.ray_along(*d, r);
                *o = self
                    .shape
                    .intersect_over(&ray, 0.0, self.rays.t_max(), cell);
            }
        }
    }
}

/// An analytic solid. Coordinates in world units.
#[derive(Clone, Debug, PartialEq)]
pub enum Primitive {
    /// Ball of `radius` about `center`.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
    /// Box of half extents `half` about `center`, rotated by `yaw` radians about `+y`.
    Box {
        /// Centre.
        center: DVec3,
        /// Half extents along the box's own axes.
        half: DVec3,
        /// Rotation about `+y` (radians).
        yaw: f64,
    },
    /// Segment `a–b` swept by a ball of `radius`.
    Capsule {
        /// First end.
        a: DVec3,
        /// Second end.
        b: DVec3,
        /// Radius.
        radius: f64,
    },
    /// Cylinder of `radius` about segment `a–b`, with flat caps.
    Cylinder {
        /// Centre of the first cap.
        a: DVec3,
        /// Centre of the second cap.
        b: DVec3,
        /// Radius.
        radius: f64,
    },
    /// Torus about `center` with unit `axis`, ring radius `major`, tube radius `minor`.
    Torus {
        /// Centre.
        center: DVec3,
        /// Unit axis of revolution.
        axis: DVec3,
        /// Distance from the centre to the tube's centre line.
        major: f64,
        /// Tube radius.
        minor: f64,
    },
}

/// Rotates `v` about `+y` by `angle` radians (right-handed: a quarter turn takes `+z` to `+x`).
#[inline]
fn rot_y(v: DVec3, angle: f64) -> DVec3 {
    // Standard right-handed rotation about +y: x' = x cos + z sin, z' = −x sin + z cos.
    let (s, c) = angle.sin_cos();
    DVec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z)
}

/// Entry and exit parameters of a ray with an axis-aligned box (local frame), with the entry
/// face's normal.
fn slab(o: DVec3, d: DVec3, half: DVec3) -> Option<(f64, f64, DVec3, DVec3)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    let mut n0 = DVec3::ZERO;
    let mut n1 = DVec3::ZERO;
    for k in 0..3 {
        let (ok, dk, hk) = (o[k], d[k], half[k]);
        if dk.abs() < 1e-300 {
            if ok.abs() > hk {
                return None;
            }
            continue;
        }
        let inv = 1.0 / dk;
        let (mut ta, mut tb) = ((-hk - ok) * inv, (hk - ok) * inv);
        let mut na = DVec3::ZERO;
        na[k] = -1.0;
        let mut nb = -na;
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
            std::mem::swap(&mut na, &mut nb);
        }
        if ta > t0 {
            t0 = ta;
            n0 = na;
        }
        if tb < t1 {
            t1 = tb;
            n1 = nb;
        }
    }
    (t0 <= t1).then_some((t0, t1, n0, n1))
}

/// First root `t > t_min` of the unit-direction ray with a sphere.
fn sphere_hit(ray: &Ray, center: DVec3, radius: f64, t_min: f64) -> Option<f64> {
    let oc = ray.origin - center;
    let b = oc.dot(ray.dir);
    let c = oc.length_squared() - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    [-b - s, -b + s].into_iter().find(|&t| t > t_min)
}

/// First hit `t > t_min` of a ray with the lateral surface of the infinite cylinder about
/// segment `a–b`, restricted to the segment's extent. Returns `(t, normal)`.
fn tube_hit(ray: &Ray, a: DVec3, b: DVec3, radius: f64, t_min: f64) -> Option<(f64, DVec3)> {
    let axis = (b - a).normalize();
    let len = (b - a).length();
    let oa = ray.origin - a;
    let d_perp = ray.dir - axis * ray.dir.dot(axis);
    let o_perp = oa - axis * oa.dot(axis);
    let qa = d_perp.length_squared();
    if qa < 1e-300 {
        return None;
    }
    let qb = o_perp.dot(d_perp);
    let qc = o_perp.length_squared() - radius * radius;
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    for t in [(-qb - s) / qa, (-qb + s) / qa] {
        if t <= t_min {
            continue;
        }
        let h = (ray.at(t) - a).dot(axis);
        if (0.0..=len).contains(&h) {
            let p = ray.at(t) - a - axis * h;
            return Some((t, p / radius));
        }
    }
    None
}

/// Hit of a ray with the disk of `radius` about `c` with unit normal `n`.
fn disk_hit(ray: &Ray, c: DVec3, n: DVec3, radius: f64, t_min: f64) -> Option<(f64, DVec3)> {
    let dn = ray.dir.dot(n);
    if dn.abs() < 1e-300 {
        return None;
    }
    let t = (c - ray.origin).dot(n) / dn;
    (t > t_min && (ray.at(t) - c).length_squared() <= radius * radius).then_some((t, n))
}

fn closest(a: Option<(f64, DVec3)>, b: Option<(f64, DVec3)>) -> Option<(f64, DVec3)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if x.0 <= y.0 { x } else { y }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// Distance from `p` to segment `a–b`.
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ba = b - a;
    let h = ((p - a).dot(ba) / ba.length_squared()).clamp(0.0, 1.0);
    (p - a - ba * h).length()
}

impl Primitive {
    /// Checks that every coordinate is finite, radii and half extents are positive, segments
    /// have distinct ends and a torus axis is non-zero. Degenerate primitives are rejected here
    /// so that intersection and distance never see them.
    pub fn validate(&self) -> Result<(), DataGenError> {
        let bad = |reason: &'static str| {
            Err(DataGenError::InvalidParameter {
                name: "primitive",
                value: format!("{self:?}"),
                reason,
            })
        };
        let finite3 = |v: DVec3| v.is_finite();
        match *self {
            Primitive::Sphere { center, radius } => {
                if !finite3(center) || !radius.is_finite() || radius <= 0.0 {
                    return bad("a sphere needs a finite centre and a positive radius");
                }
            }
            Primitive::Box { center, half, yaw } => {
                if !finite3(center)
                    || !finite3(half)
                    || !yaw.is_finite()
                    || half.min_element() <= 0.0
                {
                    return bad("a box needs finite values and positive half extents");
                }
            }
            Primitive::Capsule { a, b, radius } | Primitive::Cylinder { a, b, radius } => {
                if !finite3(a) || !finite3(b) || !radius.is_finite() || radius <= 0.0 {
                    return bad("a capsule or cylinder needs finite ends and a positive radius");
                }
                if (b - a).length() <= 1e-12 * (1.0 + a.length()) {
                    return bad("a capsule or cylinder needs two distinct ends");
                }
            }
            Primitive::Torus {
                center,
                axis,
                major,
                minor,
            } => {
                if !finite3(center) || !finite3(axis) || axis.length() < 1e-12 {
                    return bad("a torus needs a finite centre and a non-zero axis");
                }
                if !(major.is_finite() && minor.is_finite() && major > 0.0 && minor > 0.0) {
                    return bad("a torus needs positive radii");
                }
            }
        }
        Ok(())
    }

    /// Signed distance from `p` (negative inside). Exact for every primitive.
    pub fn sdf(&self, p: DVec3) -> f64 {
        match *self {
            Primitive::Sphere { center, radius } => (p - center).length() - radius,
            Primitive::Box { center, half, yaw } => {
                let q = rot_y(p - center, -yaw).abs() - half;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
            Primitive::Capsule { a, b, radius } => segment_distance(p, a, b) - radius,
            Primitive::Cylinder { a, b, radius } => {
                let axis = (b - a).normalize();
                let len = (b - a).length();
                let h = (p - a).dot(axis);
                let r = (p - a - axis * h).length();
                let dx = r - radius;
                let dy = (h - 0.5 * len).abs() - 0.5 * len;
                DVec3::new(dx.max(0.0), dy.max(0.0), 0.0).length() + dx.max(dy).min(0.0)
            }
            Primitive::Torus {
                center,
                axis,
                major,
                minor,
            } => {
                let q = p - center;
                let h = q.dot(axis);
                let r = (q - axis * h).length();
                ((r - major).powi(2) + h * h).sqrt() - minor
            }
        }
    }

    /// Axis-aligned bounds `(min, max)`.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match *self {
            Primitive::Sphere { center, radius } => (center - radius, center + radius),
            Primitive::Box { center, half, yaw } => {
                let (s, c) = yaw.sin_cos();
                let ex = DVec3::new(
                    c.abs() * half.x + s.abs() * half.z,
                    half.y,
                    s.abs() * half.x + c.abs() * half.z,
                );
                (center - ex, center + ex)
            }
            Primitive::Capsule { a, b, radius } => (a.min(b) - radius, a.max(b) + radius),
            Primitive::Cylinder { a, b, radius } => {
                // A cap disk with unit normal u reaches radius·√(1 − u_k²) along axis k.
                let u = (b - a).normalize();
                let ext = radius * (DVec3::ONE - u * u).max(DVec3::ZERO).sqrt();
                (a.min(b) - ext, a.max(b) + ext)
            }
            Primitive::Torus {
                center,
                major,
                minor,
                ..
            } => (center - (major + minor), center + (major + minor)),
        }
    }

    /// First crossing of the surface along `ray` (unit direction) with `t ∈ (t_min, t_max)`, as
    /// `(t, outward unit normal)`.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<(f64, DVec3)> {
        let hit = match *self {
            Primitive::Sphere { center, radius } => {
                sphere_hit(ray, center, radius, t_min).map(|t| (t, (ray.at(t) - center) / radius))
            }
            Primitive::Box { center, half, yaw } => {
                let o = rot_y(ray.origin - center, -yaw);
                let d = rot_y(ray.dir, -yaw);
                let (t0, t1, n0, n1) = slab(o, d, half)?;
                if t0 > t_min {
                    Some((t0, rot_y(n0, yaw)))
                } else if t1 > t_min {
                    Some((t1, rot_y(n1, yaw)))
                } else {
                    None
                }
            }
            Primitive::Capsule { a, b, radius } => {
                let cap = |c: DVec3| {
                    sphere_hit(ray, c, radius, t_min).map(|t| (t, (ray.at(t) - c) / radius))
                };
                closest(closest(cap(a), cap(b)), tube_hit(ray, a, b, radius, t_min))
            }
            Primitive::Cylinder { a, b, radius } => {
                let axis = (b - a).normalize();
                let caps = closest(
                    disk_hit(ray, a, -axis, radius, t_min),
                    disk_hit(ray, b, axis, radius, t_min),
                );
                closest(caps, tube_hit(ray, a, b, radius, t_min))
            }
            Primitive::Torus {
                center,
                major,
                minor,
                ..
            } => self.sphere_trace(ray, center, major + minor, t_min, t_max),
        }?;
        (hit.0 < t_max).then_some(hit)
    }

    /// Sphere tracing of the exact SDF inside the bounding ball, then bisection to 1e-12.
    fn sphere_trace(
        &self,
        ray: &Ray,
        center: DVec3,
        bound: f64,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, DVec3)> {
        let oc = ray.origin - center;
        let b = oc.dot(ray.dir);
        let disc = b * b - (oc.length_squared() - bound * bound);
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let mut t = (-b - s).max(t_min);
        let t_end = (-b + s).min(t_max);
        let mut prev = t;
        for _ in 0..4096 {
            if t > t_end {
                return None;
            }
            let d = self.sdf(ray.at(t));
            if d < 1e-10 {
                // The crossing lies in [prev, t]: bisect on the sign of the SDF.
                let (mut lo, mut hi) = (prev, t);
                if d > 0.0 {
                    lo = t;
                    hi = t;
                }
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if self.sdf(ray.at(mid)) > 0.0 {
                        lo = mid
                    } else {
                        hi = mid
                    }
                }
                let th = hi;
                return Some((th, self.numeric_normal(ray.at(th))));
            }
            prev = t;
            t += d.max(1e-7);
        }
        None
    }

    /// Outward unit normal from the SDF gradient (central differences).
    pub fn numeric_normal(&self, p: DVec3) -> DVec3 {
        let e = 1e-6;
        let g = DVec3::new(
            self.sdf(p + DVec3::X * e) - self.sdf(p - DVec3::X * e),
            self.sdf(p + DVec3::Y * e) - self.sdf(p - DVec3::Y * e),
            self.sdf(p + DVec3::Z * e) - self.sdf(p - DVec3::Z * e),
        );
        g.normalize_or(DVec3::Y)
    }
}

/// One primitive of a [`Csg`] with its colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The solid.
    pub primitive: Primitive,
    /// Its surface colour.
    pub albedo: Albedo,
}

/// A union of primitives: the procedural shapes of altrep's scenes.
///
/// The first hit of a union is the nearest first hit of its parts (rays start outside), so
/// intersection is exact. Cost: one primitive test per part per ray.
#[derive(Clone, Debug)]
pub struct Csg {
    name: String,
    parts: Vec<Part>,
    bounds: (DVec3, DVec3),
}

impl Csg {
    /// A union of `parts` named `name`. An empty union is allowed (it is hit by nothing).
    /// A torus axis is normalised here.
    ///
    /// Errors: [`DataGenError::InvalidParameter`] naming the first degenerate primitive (see
    /// [`Primitive::validate`]).
    pub fn new(name: impl Into<String>, mut parts: Vec<Part>) -> Result<Self, DataGenError> {
        for part in &mut parts {
            part.primitive.validate()?;
            if let Primitive::Torus { axis, .. } = &mut part.primitive {
                *axis = axis.normalize();
            }
        }
        let bounds = parts.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| {
                let (a, b) = p.primitive.bounds();
                (lo.min(a), hi.max(b))
            },
        );
        Ok(Self {
            name: name.into(),
            parts,
            bounds,
        })
    }

    /// The parts of the union.
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }

    fn nearest_part(&self, p: DVec3) -> Option<(&Part, f64)> {
        self.parts
            .iter()
            .map(|part| (part, part.primitive.sdf(p)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

impl Shape for Csg {
    fn name(&self) -> &str {
        &self.name
    }

    fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        let mut best: Option<(f64, DVec3, &Part)> = None;
        for part in &self.parts {
            let limit = best.map_or(t_max, |b| b.0);
            if let Some((t, n)) = part.primitive.intersect(ray, t_min, limit) {
                best = Some((t, n, part));
            }
        }
        best.map(|(t, n, part)| {
            let normal = if n.dot(ray.dir) > 0.0 { -n } else { n };
            Hit {
                t,
                normal,
                geometric: normal,
                albedo: part.albedo.at(ray.at(t)),
            }
        })
    }

    fn contains(&self, p: DVec3) -> bool {
        self.parts.iter().any(|part| part.primitive.sdf(p) < 0.0)
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    fn albedo_at(&self, p: DVec3) -> Vec3 {
        self.nearest_part(p)
            .map_or(Vec3::ZERO, |(part, _)| part.albedo.at(p))
    }

    fn sdf(&self, p: DVec3) -> Option<f64> {
        self.nearest_part(p).map(|(_, d)| d)
    }
}
