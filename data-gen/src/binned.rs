//! Grids of parallel rays traced through a [`Mesh`] by binning its triangles over the grid: the
//! tracer of [`crate::Shape::parallel_tracer`] for meshes.
//!
//! ## Method
//!
//! The rays of an orthographic view share their direction, so a triangle can only meet the rays
//! whose grid positions lie inside its projection on the screen. Each triangle is projected once
//! (in `f64`, from its `f32` vertices) and goes to the grid cells (rays) within its **footprint**:
//! its projected bounding box and its three edge lines, all moved out by a margin `m`. On each
//! cell of its footprint it runs the BVH walk's own `f32` triangle test (the watertight test of
//! `watertight`) against the cell's ray, and a depth buffer over the cells keeps the first
//! strictly nearer distance: triangles go in triangle order, so each ray meets its candidates in
//! the order the walk keeps them along its path.
//!
//! ## Exactness
//!
//! The result of a ray is exactly the nearest hit of that test over **all** the triangles (the
//! first in triangle order among equal distances), as long as every triangle the test accepts is
//! among the ray's candidates. The test works on coordinates of size `s` (the largest coordinate
//! of the mesh and of the rays' origins) with a few `f32` roundings, so it accepts rays within
//! about `10⁻⁶·s` of a triangle; the footprint holds every position within `m = 2·10⁻⁵·s` of
//! the triangle. A ray is binned by its declared grid position; one whose direction differs
//! from the grid's, or whose origin lies farther from its position than `m` minus the test's
//! allowance, walks the BVH instead (so a wrong grid costs time, not correctness).
//!
//! Against the BVH walk ([`crate::Shape::intersect`], whose boxes are padded so that they keep
//! every hit the triangle test accepts): the distance is bitwise the same, and so is the
//! triangle: where two triangles meet the ray at the same `f32` distance (a ray through a shared
//! edge), the walk too keeps the first in triangle order. The tests count ties (none on every
//! mesh they trace).
//!
//! ## Cost
//!
//! Rows are cut into bands ([`ParallelTracer::band_rows`]); building the tracer projects every
//! triangle once for its rows and sorts the triangles into bands. Tracing a band builds its rays
//! (checking each against its grid position), projects the band's triangles again and runs the
//! triangle test on each cell of their footprints (with bounding boxes alone, 1.4 tests per ray
//! on the teapot and 2.5 on the Stanford bunny at 512², misses included; the edge lines remove
//! some), where a BVH walk tests boxes and triangles along the whole ray. No list of (cell,
//! triangle) pairs is built: sorting one by cell made the bunny's views 10–15 % slower.
//! Measured: about 110 ns per triangle and 55 ns per ray on one core with that sort, against
//! 250–700 ns per ray for the walk ([`crate::Mesh`]'s tracer chooses between them).

use std::ops::Range;

use glam::{DVec3, Vec3A};
use obvhs::triangle::Triangle;
use rayon::prelude::*;

use crate::geometry::{Footprint as RayCell, Hit, ParallelRays, Ray};
use crate::mesh::Mesh;
use crate::shape::ParallelTracer;
use crate::watertight::Shear;

/// The binning tracer of a [`Mesh`] for one grid of parallel rays.
pub(crate) struct MeshTracer<'a> {
    mesh: &'a Mesh,
    /// The mesh's triangles in the BVH's leaf order (the order of ray queries).
    triangles: &'a [Triangle],
    rays: &'a ParallelRays<'a>,
    cols: Axis<'a>,
    /// The footprint margin `m` (world units).
    margin: f64,
    /// The largest coordinate of the mesh.
    mesh_scale: f64,
    /// Each triangle's rows (half-open; empty when it misses the grid's rows).
    row_spans: Vec<[u32; 2]>,
    /// The triangles of each band of rows.
    bands: Bands,
}

impl<'a> MeshTracer<'a> {
    /// `None` when the grid cannot be binned: no ray, positions not strictly monotonic, a
    /// non-finite direction or scale. Cost: one projection and one row search per triangle.
    pub(crate) fn new(mesh: &'a Mesh, rays: &'a ParallelRays<'a>) -> Option<Self> {
        let (w, h) = (rays.columns.len(), rays.rows.len());
        let (cols, rows) = (Axis::new(rays.columns)?, Axis::new(rays.rows)?);
        if w == 0 || h == 0 || !rays.dir.is_finite() {
            return None;
        }
        let mesh_scale = inf(mesh.bounds.0).max(inf(mesh.bounds.1));
        let corner_scale = [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)]
            .into_iter()
            .map(|(c, r)| inf((rays.ray)(c, r).origin))
            .fold(0.0, f64::max);
        let margin = 2e-5 * (mesh_scale + corner_scale);
        if !margin.is_finite() {
            return None;
        }
        let across = rays.across;
        let triangles = mesh.traced().triangles.as_slice();
        let row_spans: Vec<[u32; 2]> = triangles
            .par_iter()
            .map(|t| {
                let p = project(t, across);
                let r = rows.range(
                    p[0][1].min(p[1][1]).min(p[2][1]) - margin,
                    p[0][1].max(p[1][1]).max(p[2][1]) + margin,
                );
                [r.start as u32, r.end as u32]
            })
            .collect();
        let bands = Bands::new(&row_spans, h);
        Some(Self {
            mesh,
            triangles,
            rays,
            cols,
            margin,
            mesh_scale,
            row_spans,
            bands,
        })
    }
}

impl BandTracer for MeshTracer<'_> {
    fn mesh(&self) -> &Mesh {
        self.mesh
    }

    fn bands(&self) -> &Bands {
        &self.bands
    }

    fn size(&self) -> (usize, usize) {
        (self.rays.columns.len(), self.rays.rows.len())
    }

    fn footprint(&self) -> Option<RayCell> {
        self.rays.footprint()
    }

    fn trace_band<T>(
        &self,
        b: usize,
        rows: Range<usize>,
        out: &mut [T],
        emit: impl Fn(&Ray, Option<(usize, f32)>) -> T,
    ) {
        let (rays, w) = (self.rays, self.rays.columns.len());
        let (r0, r1) = (rows.start, rows.end);
        let [a0, a1] = rays.across;
        let cells = (r1 - r0) * w;
        // Every binned ray has direction `rays.dir`: its `f32` ray differs from this one only
        // in its origin (same bits as `Mesh::to_bvh_ray` gives it).
        let template = Mesh::to_bvh_ray(&Ray::new(DVec3::ZERO, rays.dir), rays.t_min, rays.t_max);
        // The band's rays, their `f32` origins and whether each lies on its grid position.
        let mut band_rays = Vec::with_capacity(cells);
        let mut origins = Vec::with_capacity(cells);
        let mut on_grid = Vec::with_capacity(cells);
        for r in r0..r1 {
            for c in 0..w {
                let ray = (rays.ray)(c, r);
                let off = (ray.origin.dot(a0) - rays.columns[c]).abs()
                    + (ray.origin.dot(a1) - rays.rows[r]).abs();
                // Half the margin's rate is left for the triangle test's allowance; the
                // comparison is false for NaN.
                on_grid.push(
                    ray.dir == rays.dir
                        && off + 1e-5 * (self.mesh_scale + inf(ray.origin)) <= self.margin,
                );
                origins.push(Vec3A::from(ray.origin.as_vec3()));
                band_rays.push(ray);
            }
        }
        // A depth buffer over the band's cells: each triangle, in triangle order, is tested
        // on the cells of its footprint and kept where strictly nearer (so the first in
        // triangle order wins among equal distances, as in the walk along one ray).
        let mut best_d = vec![template.tmax; cells];
        let mut best_t = vec![u32::MAX; cells];
        let mut bray = template;
        let traced = self.mesh.traced();
        let shear = Shear::new(template.direction);
        for &t in self.bands.of(b) {
            let span = self.row_spans[t as usize];
            let (s0, s1) = ((span[0] as usize).max(r0), (span[1] as usize).min(r1));
            if s0 >= s1 {
                continue;
            }
            let tri = &self.triangles[t as usize];
            let f = Footprint::new(project(tri, rays.across), self.margin, &self.cols);
            if f.columns.is_empty() {
                continue;
            }
            let mut test = |k: usize| {
                bray.origin = origins[k];
                let d = shear.intersect_ray(tri, &bray);
                if d < best_d[k] && self.mesh.traced_stops(traced, t as usize, &bray, d) {
                    best_d[k] = d;
                    best_t[k] = t;
                }
            };
            for r in s0..s1 {
                let y = rays.rows[r];
                let row = (r - r0) * w;
                if f.columns.len() <= SMALL {
                    // A small footprint: its few columns are tested one by one.
                    for c in f.columns.clone() {
                        if f.covers(rays.columns[c], y) {
                            test(row + c);
                        }
                    }
                } else {
                    for c in f.row_columns(y, &self.cols) {
                        test(row + c);
                    }
                }
            }
        }
        for (k, o) in out.iter_mut().enumerate().take(cells) {
            let ray = &band_rays[k];
            *o = if !on_grid[k] {
                emit(ray, self.mesh.first_hit(ray, rays.t_min, rays.t_max))
            } else if best_t[k] == u32::MAX {
                emit(ray, None)
            } else {
                emit(ray, Some((best_t[k] as usize, best_d[k])))
            };
        }
    }
}

/// A mesh tracer that works one band of rows at a time ([`MeshTracer`] for parallel rays,
/// [`crate::radial::RadialTracer`] for radial ones): it traces any rows band by band, and is
/// the [`ParallelTracer`] that shades its hits with [`Mesh::hit_over`].
pub(crate) trait BandTracer: Sync {
    /// The mesh traced.
    fn mesh(&self) -> &Mesh;
    /// The mesh's triangles sorted into bands of rows.
    fn bands(&self) -> &Bands;
    /// The grid's columns and rows.
    fn size(&self) -> (usize, usize);
    /// Traces rows `rows` (all within band `b`) into `out`, passing each ray and its nearest
    /// `(triangle, distance)` to `emit`.
    fn trace_band<T>(
        &self,
        b: usize,
        rows: Range<usize>,
        out: &mut [T],
        emit: impl Fn(&Ray, Option<(usize, f32)>) -> T,
    );
    /// The cell each ray of the grid stands for.
    fn footprint(&self) -> Option<RayCell>;
    /// Traces rows `rows` (any range) band by band.
    fn trace<T>(
        &self,
        rows: Range<usize>,
        out: &mut [T],
        emit: impl Fn(&Ray, Option<(usize, f32)>) -> T,
    ) {
        let (w, h) = self.size();
        self.bands().split(w, h, rows, out, |b, rows, out| {
            self.trace_band(b, rows, out, &emit);
        });
    }
}

impl<B: BandTracer> ParallelTracer for B {
    fn band_rows(&self) -> usize {
        self.bands().band
    }

    fn trace_rows(&self, rows: Range<usize>, out: &mut [Option<Hit>]) {
        let cell = self.footprint();
        self.trace(rows, out, |ray, hit| {
            hit.map(|(t, d)| self.mesh().hit_over(ray, t, d, cell))
        });
    }

    fn occluded_rows(&self, rows: Range<usize>, out: &mut [bool]) {
        self.trace(rows, out, |_, hit| hit.is_some());
    }
}

/// The triangles of each band of rows, in triangle order: band `b` holds rows
/// `b·band..(b + 1)·band` and the triangles `in_band[start[b]..start[b + 1]]` whose row span
/// meets them.
pub(crate) struct Bands {
    /// Rows per band: `h / (8·threads)`, between 1 and 16.
    pub(crate) band: usize,
    start: Vec<u32>,
    in_band: Vec<u32>,
}

impl Bands {
    /// Sorts the triangles, whose half-open row spans are `row_spans`, into the bands of `h`
    /// rows. Cost: two passes over the spans.
    pub(crate) fn new(row_spans: &[[u32; 2]], h: usize) -> Self {
        let band = (h / (8 * rayon::current_num_threads())).clamp(1, 16);
        let bands = h.div_ceil(band);
        let band_range = |r: &[u32; 2]| r[0] as usize / band..(r[1] as usize).div_ceil(band);
        let mut start = vec![0u32; bands + 1];
        for r in row_spans {
            for b in band_range(r) {
                start[b + 1] += 1;
            }
        }
        for b in 1..=bands {
            start[b] += start[b - 1];
        }
        let mut fill = start.clone();
        let mut in_band = vec![0u32; start[bands] as usize];
        for (t, r) in row_spans.iter().enumerate() {
            for b in band_range(r) {
                in_band[fill[b] as usize] = t as u32;
                fill[b] += 1;
            }
        }
        Self {
            band,
            start,
            in_band,
        }
    }

    /// The triangles of band `b`, in triangle order.
    pub(crate) fn of(&self, b: usize) -> &[u32] {
        &self.in_band[self.start[b] as usize..self.start[b + 1] as usize]
    }

    /// Cuts rows `rows` (any range, clipped to the grid's `h` rows of `w` rays) and their part
    /// of `out` (`w` entries per row) at band boundaries, and hands each piece to
    /// `trace_band(b, rows, out)`; stops where `out` is too short.
    pub(crate) fn split<T>(
        &self,
        w: usize,
        h: usize,
        rows: Range<usize>,
        out: &mut [T],
        mut trace_band: impl FnMut(usize, Range<usize>, &mut [T]),
    ) {
        let rows = rows.start..rows.end.min(h);
        let mut r = rows.start;
        while r < rows.end {
            let b = r / self.band;
            let end = ((b + 1) * self.band).min(rows.end);
            let (lo, hi) = ((r - rows.start) * w, (end - rows.start) * w);
            let Some(out) = out.get_mut(lo..hi) else {
                return;
            };
            trace_band(b, r..end, out);
            r = end;
        }
    }
}

/// The largest absolute coordinate of `v`.
pub(crate) fn inf(v: DVec3) -> f64 {
    v.abs().max_element()
}

/// The screen coordinates `(p·across[0], p·across[1])` of a triangle's vertices, in `f64`.
fn project(t: &Triangle, across: [DVec3; 2]) -> [[f64; 2]; 3] {
    let v64 = |a: Vec3A| DVec3::new(a.x.into(), a.y.into(), a.z.into());
    [t.v0, t.v1, t.v2].map(|v| [v64(v).dot(across[0]), v64(v).dot(across[1])])
}

/// The grid positions of one axis of a [`ParallelRays`], strictly monotonic either way.
#[derive(Clone, Copy)]
pub(crate) struct Axis<'a> {
    coords: &'a [f64],
    ascending: bool,
    /// `(x₀, 1/step)` when the positions are within a quarter step of `x₀ + i·step`: the index
    /// of a position is then guessed in O(1) and corrected by exact comparisons.
    uniform: Option<(f64, f64)>,
}

impl<'a> Axis<'a> {
    /// `None` unless the coordinates are strictly monotonic (NaN fails both orders).
    pub(crate) fn new(coords: &'a [f64]) -> Option<Self> {
        let ascending = coords.windows(2).all(|p| p[0] < p[1]);
        if !ascending && !coords.windows(2).all(|p| p[0] > p[1]) {
            return None;
        }
        let n = coords.len();
        let uniform = (n >= 2)
            .then(|| (coords[0], (coords[n - 1] - coords[0]) / (n - 1) as f64))
            .filter(|&(x0, step)| {
                coords
                    .iter()
                    .enumerate()
                    .all(|(i, &x)| (x - (x0 + i as f64 * step)).abs() <= 0.25 * step.abs())
            })
            .map(|(x0, step)| (x0, 1.0 / step));
        Some(Self {
            coords,
            ascending,
            uniform,
        })
    }

    /// Indices of the positions in `[lo, hi]` (exact: the guess of a uniform axis is only a
    /// starting point).
    #[inline]
    pub(crate) fn range(&self, lo: f64, hi: f64) -> Range<usize> {
        let x = self.coords;
        let n = x.len();
        let inside = |i: usize| lo <= x[i] && x[i] <= hi;
        if let Some((x0, inv_step)) = self.uniform {
            let (a, b) = ((lo - x0) * inv_step, (hi - x0) * inv_step);
            let (a, b) = (a.min(b), a.max(b));
            // False for NaN bounds too.
            let ordered = a <= b;
            if !ordered || b < -1.0 || a > n as f64 {
                return 0..0;
            }
            // Position `i` lies within a quarter step of `x₀ + i·step`, so the indices inside
            // are within `[a − ¼, b + ¼]`: from `⌊a⌋` to `⌊b⌋ + 1`. Start from that superset
            // (`a + 1 ≥ 0` truncates to its floor) and shrink it to the exact range.
            let (a, b) = (a.min(n as f64), b.min(n as f64));
            let mut s = ((a + 1.0) as usize).saturating_sub(1);
            let mut e = ((b + 1.0) as usize + 1).min(n);
            while s < e && !inside(s) {
                s += 1;
            }
            while e > s && !inside(e - 1) {
                e -= 1;
            }
            return s..e;
        }
        if self.ascending {
            x.partition_point(|&v| v < lo)..x.partition_point(|&v| v <= hi)
        } else {
            x.partition_point(|&v| v > hi)..x.partition_point(|&v| v >= lo)
        }
    }
}

/// Footprints at most this many columns wide are cut by evaluating their edge lines column by
/// column, wider ones by solving the lines for `x` on each row.
const SMALL: usize = 4;

/// A triangle's footprint on a grid of parallel rays: the grid columns within its projected
/// bounding box widened by the margin `m` (its rows are kept apart) and, unless the projection
/// is degenerate, the points within its three edge lines moved out by `m` (a superset of the
/// points within `m` of the triangle).
struct Footprint {
    columns: Range<usize>,
    /// The box's screen abscissae, widened by `m`.
    x_range: (f64, f64),
    /// Edge lines `a·x + b·y + c ≥ 0` inside, already moved out by at least `m`; `0·x + 0·y + 1`
    /// for a projection too thin to orient reliably (then the box alone decides).
    edges: [[f64; 3]; 3],
}

impl Footprint {
    #[inline]
    fn new(p: [[f64; 2]; 3], m: f64, cols: &Axis) -> Self {
        let x_range = (
            p[0][0].min(p[1][0]).min(p[2][0]) - m,
            p[0][0].max(p[1][0]).max(p[2][0]) + m,
        );
        let columns = cols.range(x_range.0, x_range.1);
        let e = [0, 1, 2].map(|i| {
            let (a, b) = (p[i], p[(i + 1) % 3]);
            [b[0] - a[0], b[1] - a[1]]
        });
        let area = e[0][0] * e[1][1] - e[0][1] * e[1][0];
        let longest = e
            .iter()
            .map(|v| v[0] * v[0] + v[1] * v[1])
            .fold(0.0, f64::max);
        // Rounding of the projected coordinates moves `area` by about 1e-16·longest: far
        // below this threshold, so the orientation below is the exact one.
        let edges = if area.abs() > 1e-9 * longest {
            let s = area.signum();
            [0, 1, 2].map(|i| {
                let (nx, ny) = (-s * e[i][1], s * e[i][0]);
                // `|nx| + |ny| ≥ |n|`: the line moves out by at least `m`.
                [
                    nx,
                    ny,
                    -(nx * p[i][0] + ny * p[i][1]) + m * (nx.abs() + ny.abs()),
                ]
            })
        } else {
            [[0.0, 0.0, 1.0]; 3]
        };
        Self {
            columns,
            x_range,
            edges,
        }
    }

    /// Whether the point `(x, y)` (already inside the box) lies within the three moved edge
    /// lines. Branch-free: all three lines are evaluated.
    #[inline]
    fn covers(&self, x: f64, y: f64) -> bool {
        let [e0, e1, e2] = &self.edges;
        (e0[0] * x + e0[1] * y + e0[2] >= 0.0)
            & (e1[0] * x + e1[1] * y + e1[2] >= 0.0)
            & (e2[0] * x + e2[1] * y + e2[2] >= 0.0)
    }

    /// The columns of the footprint on the row at height `y` (a row already inside the box):
    /// the box's columns cut by the three moved edge lines, each solved for `x`. Each bound
    /// is moved out by `10⁻⁹` of its terms, far more than the rounding of the division, so the
    /// columns are a superset of the positions where every `a·x + b·y + c ≥ 0`.
    /// Footprints at most [`SMALL`] columns wide are tested column by column with
    /// [`Self::covers`] instead (no division).
    fn row_columns(&self, y: f64, cols: &Axis) -> Range<usize> {
        let (mut lo, mut hi) = self.x_range;
        for &[a, b, c] in &self.edges {
            let v = -(b * y + c);
            let slack = 1e-9 * ((b * y).abs() + c.abs());
            if a > 0.0 {
                let bound = (v - slack) / a;
                if bound > lo {
                    lo = bound;
                }
            } else if a < 0.0 {
                let bound = (v - slack) / a;
                if bound < hi {
                    hi = bound;
                }
            } else if v > slack {
                return 0..0;
            }
        }
        let ordered = lo <= hi;
        if !ordered {
            return 0..0;
        }
        let r = cols.range(lo, hi);
        r.start.max(self.columns.start)..r.end.min(self.columns.end)
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use proptest::prelude::*;

    use super::*;
    use crate::frame::OrthoFrame;
    use crate::geometry::{BoundingCylinder, PixelGrid, ViewGrid, direction, screen_right};
    use crate::shape::Shape;
    use crate::test_meshes::{check_traced, masked_soup, mesh, soup, sphere, squash_flat};

    /// Checks the binned grid ray by ray ([`check_ray`]). Returns the number of ties: rays where
    /// the walk reports another triangle at the same distance.
    fn check_grid(mesh: &Mesh, rays: &ParallelRays) -> usize {
        let tracer = MeshTracer::new(mesh, rays).expect("the grid was not binned");
        check_traced(mesh, &tracer, rays.ray, (rays.t_min, rays.t_max))
    }

    /// The `k × k` sub-sample grid of a `w × h` frame along `dir`, as
    /// [`crate::render_truth_frame`] lays out its rays.
    fn check_frame(mesh: &Mesh, dir: DVec3, w: usize, h: usize) -> usize {
        let (centre, radius) = OrthoFrame::bounding_sphere(mesh);
        let frame = OrthoFrame::new(centre, radius, dir).unwrap();
        let k = 2;
        let (columns, rows) = frame.grid(w, h, k);
        let ray = |c: usize, r: usize| frame.grid_ray(c, r, w, h, k);
        check_grid(mesh, &frame.parallel_rays(&columns, &rows, &ray))
    }

    fn check_view(mesh: &Mesh, angle: f64, w: usize, h: usize) -> usize {
        let grid = PixelGrid {
            width: w,
            height: h,
            cylinder: BoundingCylinder::default(),
        };
        let view = ViewGrid::new(&grid, angle, 1);
        let ray = |i: usize, j: usize| view.ray(i, j);
        check_grid(mesh, &view.parallel_rays(&ray))
    }

    /// An axis-aligned box: faces seen edge-on from the axis views, quads split along diagonals
    /// that axis-aligned rays can meet exactly.
    fn cube() -> Vec<[[f64; 3]; 3]> {
        let v = |i: usize| [(i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2 & 1) as f64];
        let quads = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ];
        quads
            .iter()
            .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]])
            .collect()
    }

    #[test]
    fn binned_parallel_rays_find_the_hits_of_the_bvh_walk() {
        let diagonal = DVec3::new(1.0, 1.0, 1.0);
        for (name, m) in [
            ("sphere", mesh(sphere(24, 0.0))),
            ("cube", mesh(cube())),
            ("soup", mesh(soup(7, 400))),
            ("alpha-masked soup", masked_soup(7, 400)),
        ] {
            let (mut ties, mut rays) = (0, 0);
            let mut add = |t: usize, n: usize| (ties, rays) = (ties + t, rays + n);
            for (angle, w, h) in [
                (0.0, 64, 64),
                (PI / 2.0, 37, 23),
                (0.3, 50, 71),
                (2.1, 1, 9),
            ] {
                add(check_view(&m, angle, w, h), w * h);
            }
            for (dir, w, h) in [
                (diagonal, 48, 40),
                (DVec3::Y, 33, 33),
                (DVec3::new(0.2, -0.9, 0.1), 20, 31),
            ] {
                add(check_frame(&m, dir, w, h), w * h);
            }
            eprintln!("{name}: {rays} rays, {ties} ties with the BVH walk");
            // Ties are exceptional: rays along a shared edge.
            assert!(ties * 100 <= rays, "{name}: {ties} ties in {rays} rays");
        }
    }

    /// The shipped meshes (`../shared/data/meshes`), when present: every binned ray is exactly
    /// the nearest hit over all triangles, on views and frames of each mesh.
    #[test]
    fn shipped_meshes_are_traced_exactly() {
        for m in crate::shared_meshes("the shipped meshes") {
            let (mut ties, mut rays) = (0, 0);
            for (angle, n) in [(0.0, 24), (PI / 2.0, 19), (2.0, 21)] {
                (ties, rays) = (ties + check_view(&m, angle, n, n), rays + n * n);
            }
            ties += check_frame(&m, DVec3::new(0.3, 0.8, -0.5), 14, 14);
            rays += 4 * 14 * 14;
            eprintln!("{}: {rays} rays, {ties} ties with the BVH walk", m.name());
            assert!(
                ties * 100 <= rays,
                "{}: {ties} ties in {rays} rays",
                m.name()
            );
        }
    }

    #[test]
    fn rays_off_their_declared_grid_still_get_the_bvh_walks_hits() {
        let m = mesh(sphere(16, 0.0));
        let (w, h) = (24, 24);
        let grid = PixelGrid {
            width: w,
            height: h,
            cylinder: BoundingCylinder::default(),
        };
        let view = ViewGrid::new(&grid, 0.4, 1);
        let (d, right) = (direction(0.4), screen_right(0.4));
        // Every third ray is shifted by a quarter pixel, every fifth tilted.
        let ray = |i: usize, j: usize| {
            let (x, y) = (view.columns[i], view.rows[j]);
            let shift = if (i + j).is_multiple_of(3) { 0.02 } else { 0.0 };
            let tilt = if (i + j).is_multiple_of(5) {
                DVec3::new(0.0, 0.01, 0.0)
            } else {
                DVec3::ZERO
            };
            Ray::new(
                (x + shift) * right + DVec3::Y * y + 2.0 * d,
                (tilt - d).normalize(),
            )
        };
        let rays = view.parallel_rays(&ray);
        check_grid(&m, &rays);
        let mut shuffled = view.rows.clone();
        shuffled.swap(0, 1);
        let bad = ParallelRays {
            rows: &shuffled,
            ..rays
        };
        assert!(
            MeshTracer::new(&m, &bad).is_none(),
            "non-monotonic rows were binned"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        /// The index range of a position interval is exactly the positions inside it, on
        /// uniform grids (with rounding-sized jitter) either way and on uneven ones.
        #[test]
        fn axis_ranges_are_exact(
            n in 1usize..40,
            x0 in -3.0f64..3.0,
            step in 0.01f64..1.0,
            descending in any::<bool>(),
            uneven in any::<bool>(),
            lo in -40.0f64..40.0,
            len in 0.0f64..20.0,
        ) {
            let step = if descending { -step } else { step };
            let coords: Vec<f64> = (0..n)
                .map(|i| {
                    let i = i as f64;
                    x0 + step * if uneven { i + 0.3 * i * i / n as f64 } else { i } + 1e-15 * i
                })
                .collect();
            let axis = Axis::new(&coords).unwrap();
            prop_assert!(uneven || n < 2 || axis.uniform.is_some());
            let hi = lo + len;
            let expect: Vec<usize> = (0..n).filter(|&i| lo <= coords[i] && coords[i] <= hi).collect();
            let got: Vec<usize> = axis.range(lo, hi).collect();
            prop_assert_eq!(got, expect);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]
        /// Adversarial geometry: random triangle soups with slivers, nearly collinear and
        /// nearly edge-on triangles, seen along any direction on grids of any shape.
        #[test]
        fn binned_rays_match_the_bvh_walk_on_random_soups(
            seed in any::<u64>(),
            n in 1usize..60,
            flat in 0.0f64..1.0,
            dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0,
            w in 1usize..24, h in 1usize..24,
        ) {
            let mut tris = soup(seed, n);
            // Squash a share of the soup into the plane y = 0.5 (edge-on from horizontal views).
            squash_flat(&mut tris, (flat * n as f64) as usize);
            let m = mesh(tris);
            let dir = DVec3::new(dx, dy, dz);
            prop_assume!(dir.length() > 1e-3);
            check_frame(&m, dir, w, h);
            check_view(&m, dx * PI, w, h);
        }
    }
}
