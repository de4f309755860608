//! The mesh's triangles binned by their y–z extent, for the inside test of a row of points
//! ([`crate::Mesh`]'s `Shape::contains_row`).

use obvhs::triangle::Triangle;

/// The triangles of a mesh binned on a uniform grid of the y–z plane by their y–z extent widened
/// by [`YzGrid::MARGIN`] (compressed rows: the triangles of cell `c` are
/// `tris[start[c]..start[c + 1]]`), with each triangle's `[x_max, y_min, y_max, z_min, z_max]`.
pub(crate) struct YzGrid {
    pub(crate) lo: [f32; 2],
    pub(crate) inv_cell: [f32; 2],
    pub(crate) cells: [usize; 2],
    pub(crate) start: Vec<u32>,
    pub(crate) tris: Vec<u32>,
    pub(crate) boxes: Vec<[f32; 5]>,
    pub(crate) x_max: f32,
}

impl YzGrid {
    /// Widening of each triangle's y–z extent when binning (world units; the object is
    /// normalised to radius 1): more than a parity ray drifts in y or z across the mesh
    /// (`2.7e-4` per unit of x) plus [`YzGrid::SLOP`].
    pub(crate) const MARGIN: f32 = 2e-3;
    /// Allowance for `f32` rounding in the triangle test (a ray the test accepts passes within
    /// ~1e-6 of the triangle).
    pub(crate) const SLOP: f32 = 1e-4;

    pub(crate) fn new(triangles: &[Triangle]) -> Self {
        let boxes: Vec<[f32; 5]> = triangles
            .iter()
            .map(|t| {
                let b = t.aabb();
                [b.max.x, b.min.y, b.max.y, b.min.z, b.max.z]
            })
            .collect();
        let m = Self::MARGIN;
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        let mut x_max = f32::NEG_INFINITY;
        for b in &boxes {
            lo = [lo[0].min(b[1] - m), lo[1].min(b[3] - m)];
            hi = [hi[0].max(b[2] + m), hi[1].max(b[4] + m)];
            x_max = x_max.max(b[0]);
        }
        let side = ((triangles.len() as f64).sqrt() as usize).clamp(8, 512);
        let cells = [side, side];
        let inv_cell = [0, 1].map(|k| side as f32 / (hi[k] - lo[k]).max(f32::MIN_POSITIVE));
        let index = |v: f32, k: usize| -> usize {
            (((v - lo[k]) * inv_cell[k]).floor().max(0.0) as usize).min(cells[k] - 1)
        };
        let range = |b: &[f32; 5]| {
            (
                index(b[1] - m, 0)..=index(b[2] + m, 0),
                index(b[3] - m, 1)..=index(b[4] + m, 1),
            )
        };
        let mut count = vec![0u32; side * side + 1];
        for b in &boxes {
            let (ry, rz) = range(b);
            for iz in rz {
                for iy in ry.clone() {
                    count[iy + side * iz + 1] += 1;
                }
            }
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        let start = count.clone();
        let mut tris = vec![0u32; *count.last().unwrap_or(&0) as usize];
        for (t, b) in boxes.iter().enumerate() {
            let (ry, rz) = range(b);
            for iz in rz {
                for iy in ry.clone() {
                    let c = iy + side * iz;
                    tris[count[c] as usize] = t as u32;
                    count[c] += 1;
                }
            }
        }
        Self {
            lo,
            inv_cell,
            cells,
            start,
            tris,
            boxes,
            x_max,
        }
    }

    /// The cell holding `(y, z)` (the last cell for points at or past the upper edge), `None`
    /// below the grid's lower edges, where no widened extent reaches.
    pub(crate) fn cell(&self, y: f32, z: f32) -> Option<usize> {
        let fy = (y - self.lo[0]) * self.inv_cell[0];
        let fz = (z - self.lo[1]) * self.inv_cell[1];
        if !(fy >= 0.0 && fz >= 0.0) {
            return None;
        }
        let iy = (fy as usize).min(self.cells[0] - 1);
        let iz = (fz as usize).min(self.cells[1] - 1);
        Some(iy + self.cells[0] * iz)
    }
}
