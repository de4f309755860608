//! Fit samples (the data, [`FitSamples`]) and trilinear node grids (the fitted function), with
//! the coordinate conventions of the module docs written once here.

use rayon::prelude::*;

use super::FitError;

/// Default position of fine-grid sample `i` of `n` along an axis: the cell centre
/// `(i + 0.5)/n` (the pixel-centre convention; the same on periodic and non-periodic axes).
pub fn sample_coordinate(i: usize, n: usize) -> f64 {
    (i as f64 + 0.5) / n as f64
}

/// Number of nodes along an axis of `cells` cells: `cells + 1`, or `cells` when periodic
/// (node `cells` is node 0).
pub fn node_count(cells: usize, periodic: bool) -> usize {
    if periodic { cells } else { cells + 1 }
}

/// Where a coordinate `u` falls on an axis of `cells` cells: the two nodes `(i0, i1)` and the
/// weight `t ∈ [0, 1]` of `i1` (`1 − t` is the weight of `i0`).
///
/// Node coordinate `u·cells`. Non-periodic: `u` is clamped to `[0, 1]` (a GPU's clamp-to-edge),
/// and `u = 1` gives `(cells − 1, cells, 1)`. Periodic: `u·cells` is taken modulo `cells`, and
/// `i1 = (i0 + 1) mod cells`. A NaN `u` gives `t = NaN` (and so a NaN value), never a panic;
/// so does `cells = 0` (an invalid axis), with nodes `(0, 0)`.
pub fn axis_weight(u: f64, cells: usize, periodic: bool) -> (usize, usize, f64) {
    if cells == 0 {
        return (0, 0, f64::NAN);
    }
    let a = cells as f64;
    if periodic {
        let mut s = (u * a).rem_euclid(a);
        if s >= a {
            // rem_euclid can round up to `a` for tiny negative inputs.
            s = 0.0;
        }
        let i0 = (s.floor() as usize).min(cells - 1);
        (i0, (i0 + 1) % cells, s - i0 as f64)
    } else {
        let s = u.clamp(0.0, 1.0) * a;
        let i0 = (s.floor() as usize).min(cells - 1);
        let t = if u.is_nan() { f64::NAN } else { s - i0 as f64 };
        (i0, i0 + 1, t)
    }
}

/// [`axis_weight`] of every sample position of `samples`, per axis, for a grid of `cells`
/// cells: the per-sample work of evaluating a grid at all samples is then one [`TrilinearGrid`]
/// blend. Cost: `Nx + Ny + Nz` calls.
pub(crate) fn sample_weights(
    samples: &FitSamples,
    cells: [usize; 3],
    periodic: [bool; 3],
) -> [Vec<(usize, usize, f64)>; 3] {
    [0, 1, 2].map(|a| {
        samples
            .coords(a)
            .iter()
            .map(|&u| axis_weight(u, cells[a], periodic[a]))
            .collect()
    })
}

/// Samples `d(i, j, k)` of a function on a fine `Nx × Ny × Nz` grid over `[0, 1]³`, each defined
/// or not: the data the trilinear fit approximates. (Not to be confused with data-gen's
/// `SampleGrid`, the pixels of a captured view.)
///
/// Storage: `values[i + Nx·(j + Ny·k)]` (x fastest). Positions: `coords[axis][i]`, by default
/// [`sample_coordinate`] (`(i + 0.5)/N`); [`FitSamples::with_coordinates`] accepts any positions
/// in `[0, 1]`. Every defined value is finite (checked at construction).
#[derive(Debug, Clone, PartialEq)]
pub struct FitSamples {
    dims: [usize; 3],
    coords: [Vec<f64>; 3],
    values: Vec<Option<f64>>,
}

impl FitSamples {
    /// Samples at the default cell-centre positions. Errors: a zero size, `values.len() ≠
    /// Nx·Ny·Nz`, a NaN or infinite defined value. Cost: one pass over the values.
    pub fn new(dims: [usize; 3], values: Vec<Option<f64>>) -> Result<Self, FitError> {
        for (axis, &n) in dims.iter().enumerate() {
            if n == 0 {
                return Err(FitError::ZeroSize {
                    what: "sample grid",
                    axis,
                });
            }
        }
        let coords = dims.map(|n| (0..n).map(|i| sample_coordinate(i, n)).collect());
        Self::with_coordinates(coords, values)
    }

    /// Samples at given per-axis positions (`coords[axis].len()` is that axis's size; every
    /// position finite and in `[0, 1]`). Errors as [`FitSamples::new`], plus
    /// [`FitError::CoordinateOutOfRange`].
    pub fn with_coordinates(
        coords: [Vec<f64>; 3],
        values: Vec<Option<f64>>,
    ) -> Result<Self, FitError> {
        let dims = [coords[0].len(), coords[1].len(), coords[2].len()];
        for (axis, c) in coords.iter().enumerate() {
            if c.is_empty() {
                return Err(FitError::ZeroSize {
                    what: "sample grid",
                    axis,
                });
            }
            if let Some(index) = c.iter().position(|u| !(0.0..=1.0).contains(u)) {
                return Err(FitError::CoordinateOutOfRange {
                    axis,
                    index,
                    value: c[index],
                });
            }
        }
        let expected = dims[0]
            .checked_mul(dims[1])
            .and_then(|v| v.checked_mul(dims[2]))
            .ok_or(FitError::InconsistentSize {
                what: "sample values (Nx·Ny·Nz overflows)",
                expected: usize::MAX,
                found: values.len(),
            })?;
        if values.len() != expected {
            return Err(FitError::InconsistentSize {
                what: "sample values (Nx·Ny·Nz)",
                expected,
                found: values.len(),
            });
        }
        if let Some(pos) = values
            .par_iter()
            .position_first(|v| v.is_some_and(|x| !x.is_finite()))
        {
            let (i, j, k) = (
                pos % dims[0],
                (pos / dims[0]) % dims[1],
                pos / (dims[0] * dims[1]),
            );
            return Err(FitError::NonFiniteSample {
                index: [i, j, k],
                value: values[pos].unwrap_or(f64::NAN),
            });
        }
        Ok(Self {
            dims,
            coords,
            values,
        })
    }

    /// Samples `f(x, y, z)` at the default positions, in parallel over z-slices (`None` =
    /// undefined). Errors as [`FitSamples::new`] (a non-finite value from `f` is an error, not
    /// a silent hole). Cost: `Nx·Ny·Nz` calls of `f`.
    pub fn from_fn(
        dims: [usize; 3],
        f: impl Fn([f64; 3]) -> Option<f64> + Sync,
    ) -> Result<Self, FitError> {
        if let Some(axis) = dims.iter().position(|&n| n == 0) {
            return Err(FitError::ZeroSize {
                what: "sample grid",
                axis,
            });
        }
        let [nx, ny, nz] = dims;
        let mut values = vec![None; nx * ny * nz];
        values
            .par_chunks_mut(nx * ny)
            .enumerate()
            .for_each(|(k, slice)| {
                let z = sample_coordinate(k, nz);
                for j in 0..ny {
                    let y = sample_coordinate(j, ny);
                    for i in 0..nx {
                        slice[i + nx * j] = f([sample_coordinate(i, nx), y, z]);
                    }
                }
            });
        Self::new(dims, values)
    }

    /// `[Nx, Ny, Nz]`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }
    /// Sample positions along `axis` (0 = x, 1 = y, 2 = z).
    pub fn coords(&self, axis: usize) -> &[f64] {
        &self.coords[axis]
    }
    /// All values, `values[i + Nx·(j + Ny·k)]`.
    pub fn values(&self) -> &[Option<f64>] {
        &self.values
    }
    /// Sample `(i, j, k)`; `None` when undefined or out of range.
    pub fn get(&self, i: usize, j: usize, k: usize) -> Option<f64> {
        let [nx, ny, nz] = self.dims;
        if i < nx && j < ny && k < nz {
            self.values[i + nx * (j + ny * k)]
        } else {
            None
        }
    }
    /// Position of sample `(i, j, k)` in `[0, 1]³` (indices must be in range).
    pub fn position(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [self.coords[0][i], self.coords[1][j], self.coords[2][k]]
    }
    /// Number of defined samples. Cost: one pass.
    pub fn defined_count(&self) -> usize {
        self.values.par_iter().filter(|v| v.is_some()).count()
    }
}

/// A trilinear function on `[0, 1]³`: node values on a coarse grid of `Ax × Ay × Az` cells.
///
/// Nodes per axis: [`node_count`] (`A + 1`, or `A` on a periodic axis). Storage:
/// `values[i + nx·(j + ny·k)]` with `nx, ny` the node counts. Node `(i, j, k)` sits at
/// `(i/Ax, j/Ay, k/Az)`. See the module docs for the GPU texture layout that reproduces
/// [`TrilinearGrid::eval`] with one hardware fetch.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrilinearGrid {
    cells: [usize; 3],
    periodic: [bool; 3],
    values: Vec<f64>,
}

impl TrilinearGrid {
    /// Errors: a zero cell count, `values.len()` not the node count, a non-finite value.
    pub fn new(cells: [usize; 3], periodic: [bool; 3], values: Vec<f64>) -> Result<Self, FitError> {
        if let Some(axis) = cells.iter().position(|&c| c == 0) {
            return Err(FitError::ZeroSize {
                what: "coarse grid",
                axis,
            });
        }
        let n: usize = (0..3).map(|a| node_count(cells[a], periodic[a])).product();
        if values.len() != n {
            return Err(FitError::InconsistentSize {
                what: "node values",
                expected: n,
                found: values.len(),
            });
        }
        if let Some(p) = values.iter().position(|v| !v.is_finite()) {
            return Err(FitError::InvalidParameter {
                name: "node value",
                value: format!("{} at {p}", values[p]),
                reason: "node values must be finite",
            });
        }
        Ok(Self {
            cells,
            periodic,
            values,
        })
    }
    /// `[Ax, Ay, Az]`.
    pub fn cells(&self) -> [usize; 3] {
        self.cells
    }
    /// Periodic flag per axis.
    pub fn periodic(&self) -> [bool; 3] {
        self.periodic
    }
    /// Node counts per axis (also the texture size in texels).
    pub fn nodes(&self) -> [usize; 3] {
        [0, 1, 2].map(|a| node_count(self.cells[a], self.periodic[a]))
    }
    /// Node values, `values[i + nx·(j + ny·k)]`.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Value of node `(i, j, k)` (indices wrap on periodic axes and clamp on the others).
    pub fn node(&self, i: usize, j: usize, k: usize) -> f64 {
        let [nx, ny, nz] = self.nodes();
        let fix = |v: usize, n: usize, p: bool| if p { v % n } else { v.min(n - 1) };
        let (i, j, k) = (
            fix(i, nx, self.periodic[0]),
            fix(j, ny, self.periodic[1]),
            fix(k, nz, self.periodic[2]),
        );
        self.values[i + nx * (j + ny * k)]
    }
    /// `(min, max)` of the node values.
    pub fn value_range(&self) -> (f64, f64) {
        self.values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }

    /// `g(x, y, z)`: trilinear interpolation of the node values at `p ∈ [0, 1]³` (periodic axes
    /// wrap, others clamp; see [`axis_weight`]). Equal to a GPU linear-filtered fetch of the
    /// texture laid out as in the module docs, up to the GPU's weight precision (see
    /// [`TrilinearGrid::eval_texture`]). Cost: 8 reads, 14 flops.
    pub fn eval(&self, p: [f64; 3]) -> f64 {
        let w = [0, 1, 2].map(|a| axis_weight(p[a], self.cells[a], self.periodic[a]));
        self.blend(w)
    }

    /// Blends the 8 nodes given per-axis `(i0, i1, t)` (from [`axis_weight`]).
    pub(crate) fn blend(&self, w: [(usize, usize, f64); 3]) -> f64 {
        let [nx, ny, _] = self.nodes();
        let [(x0, x1, tx), (y0, y1, ty), (z0, z1, tz)] = w;
        let at = |i: usize, j: usize, k: usize| self.values[i + nx * (j + ny * k)];
        let lerp = |a: f64, b: f64, t: f64| a + t * (b - a);
        let c00 = lerp(at(x0, y0, z0), at(x1, y0, z0), tx);
        let c10 = lerp(at(x0, y1, z0), at(x1, y1, z0), tx);
        let c01 = lerp(at(x0, y0, z1), at(x1, y0, z1), tx);
        let c11 = lerp(at(x0, y1, z1), at(x1, y1, z1), tx);
        lerp(lerp(c00, c10, ty), lerp(c01, c11, ty), tz)
    }

    /// Normalised texture coordinate `s` of the point `u` along `axis`, for the texture of
    /// [`TrilinearGrid::nodes`] texels: `s = (u·A + ½)/N` with `N = A + 1` (clamp-to-edge) or
    /// `N = A` (periodic, repeat). Texel centre `i` is at `s = (i + ½)/N`.
    pub fn texture_coordinate(&self, axis: usize, u: f64) -> f64 {
        let n = node_count(self.cells[axis], self.periodic[axis]) as f64;
        (u * self.cells[axis] as f64 + 0.5) / n
    }

    /// What a GPU's linear-filtered 3D texture fetch returns at normalised texture coordinates
    /// `s` (Vulkan/D3D rules): per axis `t = s·N − ½`, `i0 = ⌊t⌋`, `α = t − i0`, texels
    /// `i0, i0 + 1` wrapped (repeat, periodic axes) or clamped (clamp-to-edge). With
    /// `subtexel_bits = Some(b)`, `α` is rounded down to `b` fractional bits, as hardware does
    /// (`subTexelPrecisionBits`, commonly 8); `None` keeps it exact. Cost: as [`Self::eval`].
    pub fn eval_texture(&self, s: [f64; 3], subtexel_bits: Option<u32>) -> f64 {
        let w = [0, 1, 2].map(|a| {
            let n = node_count(self.cells[a], self.periodic[a]);
            let t = s[a] * n as f64 - 0.5;
            let f = t.floor();
            let mut alpha = t - f;
            if let Some(b) = subtexel_bits {
                let q = (1u64 << b.min(52)) as f64;
                alpha = (alpha * q).floor() / q;
            }
            let i0 = f as i64;
            let addr = |i: i64| -> usize {
                if self.periodic[a] {
                    i.rem_euclid(n as i64) as usize
                } else {
                    i.clamp(0, n as i64 - 1) as usize
                }
            };
            (addr(i0), addr(i0 + 1), alpha)
        });
        self.blend(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(cells: [usize; 3], periodic: [bool; 3]) -> TrilinearGrid {
        let n: usize = (0..3).map(|a| node_count(cells[a], periodic[a])).product();
        let values = (0..n)
            .map(|i| ((i * 7919) % 101) as f64 / 10.0 - 5.0)
            .collect();
        TrilinearGrid::new(cells, periodic, values).unwrap()
    }

    #[test]
    fn eval_interpolates_node_values() {
        let g = grid([3, 2, 4], [false, true, false]);
        let [nx, ny, nz] = g.nodes();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = [i as f64 / 3.0, j as f64 / 2.0, k as f64 / 4.0];
                    assert!((g.eval(p) - g.node(i, j, k)).abs() < 1e-12);
                }
            }
        }
        // Periodic y: u and u + 1 and u − 1 agree; non-periodic x clamps.
        assert!((g.eval([0.3, 0.2, 0.4]) - g.eval([0.3, 1.2, 0.4])).abs() < 1e-12);
        assert!((g.eval([0.3, 0.2, 0.4]) - g.eval([0.3, -0.8, 0.4])).abs() < 1e-12);
        assert_eq!(g.eval([-3.0, 0.2, 0.4]), g.eval([0.0, 0.2, 0.4]));
        assert!(g.eval([f64::NAN, 0.2, 0.4]).is_nan());
    }

    /// The GPU fetch at `texture_coordinate(u)` (brute force, texel rules) equals `eval(u)`.
    #[test]
    fn texture_fetch_matches_eval() {
        for periodic in [[false; 3], [true; 3], [true, false, true]] {
            for cells in [[1, 1, 1], [2, 3, 1], [15, 8, 16]] {
                let g = grid(cells, periodic);
                let mut s = 12345u64;
                for _ in 0..500 {
                    let mut u = [0.0; 3];
                    for v in &mut u {
                        s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                        *v = (s >> 11) as f64 / (1u64 << 53) as f64;
                    }
                    let st = [0, 1, 2].map(|a| g.texture_coordinate(a, u[a]));
                    let (a, b) = (g.eval(u), g.eval_texture(st, None));
                    assert!(
                        (a - b).abs() < 1e-9,
                        "{cells:?} {periodic:?} {u:?}: {a} vs {b}"
                    );
                    // 8-bit sub-texel weights: error at most the node spread times 2⁻⁸ per axis.
                    let c = g.eval_texture(st, Some(8));
                    assert!((a - c).abs() <= 3.0 * 10.0 / 256.0);
                }
            }
        }
    }

    #[test]
    fn axis_weight_edges() {
        assert_eq!(axis_weight(1.0, 4, false), (3, 4, 1.0));
        assert_eq!(axis_weight(0.0, 4, false), (0, 1, 0.0));
        assert_eq!(axis_weight(1.0, 4, true), (0, 1, 0.0));
        let (i0, i1, t) = axis_weight(-1e-20, 4, true);
        assert!(i0 < 4 && i1 < 4 && (0.0..=1.0).contains(&t));
        assert_eq!(axis_weight(0.5, 1, true), (0, 0, 0.5));
    }
}
