//! The operator abstraction the solvers work on, and rayon-parallel CSR products.
//!
//! A solver only needs `y = A·x` (and `y = Aᵀ·x` for BiCG and the least-squares methods), so it
//! takes any [`LinearOperator`]. `sprs` matrices implement it with a parallel product (`sprs`'s
//! own product is serial). An operator that is not an assembled matrix (a matrix-free product)
//! implements the four required methods; it then gets no Jacobi/SSOR preconditioner from a
//! [`PreconditionerKind`](crate::PreconditionerKind) unless it also exposes
//! [`LinearOperator::to_csr`], but it can be given any [`Preconditioner`](crate::Preconditioner)
//! directly.

use crate::error::{SolverError, check_finite, check_len};
use crate::parallel::go_parallel;
use rayon::prelude::*;
use sprs::{CsMat, CsMatI, CsMatViewI, SpIndex};

/// A real linear operator `A : R^ncols → R^nrows`.
///
/// Preconditions of `apply`/`apply_transpose`: `x` and `y` have the lengths stated; the
/// solvers check every length once before they start, so implementations may panic (a
/// programming error, never a data error) when they do not hold.
pub trait LinearOperator: Sync {
    /// Number of rows (length of `A·x`).
    fn nrows(&self) -> usize;
    /// Number of columns (length of `x`).
    fn ncols(&self) -> usize;
    /// `y ← A·x`, with `x.len() == ncols()`, `y.len() == nrows()` (`y` is overwritten).
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// `y ← Aᵀ·x`, with `x.len() == nrows()`, `y.len() == ncols()` (`y` is overwritten).
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]);
    /// The operator as a CSR matrix with `usize` indices, when it has one; used to build
    /// Jacobi/SSOR preconditioners and column scalings. Default: `None` (matrix-free).
    /// Cost: a copy of the matrix (O(nnz)), once per solve.
    fn to_csr(&self) -> Option<CsMat<f64>> {
        None
    }
    /// Euclidean norm of every column (length `ncols`), for the column scaling of LSQR/LSMR
    /// and `‖A‖_F`. Default: through [`LinearOperator::to_csr`]. Cost: O(nnz).
    fn column_norms(&self) -> Option<Vec<f64>> {
        self.to_csr().map(|a| column_norms(&a))
    }
    /// The diagonal (length `min(nrows, ncols)`, zeros where not stored), when the operator
    /// has entries; used to build the Jacobi preconditioner. Default: through
    /// [`LinearOperator::to_csr`]. Cost: O(nnz).
    fn diagonal(&self) -> Option<Vec<f64>> {
        self.to_csr().map(|a| crate::precond::diagonal(&a))
    }
    /// Checks that every stored value is finite. Default: `Ok(())` (nothing to check).
    fn check_finite(&self) -> Result<(), SolverError> {
        Ok(())
    }
}

/// A product with at least this many stored entries runs in parallel (under
/// [`crate::Parallelism::Auto`]); below it, serially. On the fit's default normal matrix (2304
/// rows, 45 344 non-zeros) a rayon split and join costs more than the product itself: we
/// measured 77 µs per PCG iteration split against about 30 µs for a serial loop. The split pays
/// once each thread gets a few hundred µs of work, hence 2^18 entries (about 0.1–0.2 ms serially
/// on the project's machine). `cargo bench -p altrep-benches --bench solvers` (group `csr_product_split`: serial
/// and split products on 27-point stencils of 97 k to 1.2 M entries) chose it: on 2 cores the
/// split lost at 97 k entries (230 vs 154 µs), tied at 262 k (496 vs 487 µs) and won at 551 k
/// (0.63 vs 1.30 ms), measured under a load average of 4–7 (bench/RESULTS.md).
pub const PAR_MIN_NNZ: usize = 262_144;
/// Rows per parallel task in a CSR product.
const ROW_CHUNK: usize = 512;
/// The transpose product of a matrix with `nnz` entries scatters `nnz / TRANSPOSE_BLOCK_NNZ`
/// row blocks (at most 64, at most `nnz / ncols`) into buffers of their own; fewer than two
/// blocks: one scatter. This shape depends on the sizes only, never on the threads.
const TRANSPOSE_BLOCK_NNZ: usize = 65_536;

/// `y[k] ← Σ_j A[first + k, j]·x[j]` for the rows `first .. first + y.len()`: each row is one
/// serial sum in stored order, starting from 0 (so the result does not depend on how rows are
/// grouped). Four rows are summed side by side (their entries interleaved) to keep the
/// floating-point units busy while one row's chain of additions waits; each row's own order of
/// additions is unchanged.
#[inline]
pub(crate) fn csr_rows<I: SpIndex, Iptr: SpIndex>(
    indptr: &[Iptr],
    indices: &[I],
    data: &[f64],
    x: &[f64],
    first: usize,
    y: &mut [f64],
) {
    let one = |i: usize| -> f64 {
        let (s, e) = (indptr[i].index(), indptr[i + 1].index());
        let mut acc = 0.0;
        for (c, v) in indices[s..e].iter().zip(&data[s..e]) {
            acc += v * x[c.index()];
        }
        acc
    };
    let mut quads = y.chunks_exact_mut(4);
    let mut i = first;
    for yq in &mut quads {
        let p = [
            indptr[i].index(),
            indptr[i + 1].index(),
            indptr[i + 2].index(),
            indptr[i + 3].index(),
            indptr[i + 4].index(),
        ];
        let common = (p[1] - p[0])
            .min(p[2] - p[1])
            .min(p[3] - p[2])
            .min(p[4] - p[3]);
        let (c0, c1, c2, c3) = (
            &indices[p[0]..p[0] + common],
            &indices[p[1]..p[1] + common],
            &indices[p[2]..p[2] + common],
            &indices[p[3]..p[3] + common],
        );
        let (d0, d1, d2, d3) = (
            &data[p[0]..p[0] + common],
            &data[p[1]..p[1] + common],
            &data[p[2]..p[2] + common],
            &data[p[3]..p[3] + common],
        );
        let mut acc = [0.0f64; 4];
        for t in 0..common {
            acc[0] += d0[t] * x[c0[t].index()];
            acc[1] += d1[t] * x[c1[t].index()];
            acc[2] += d2[t] * x[c2[t].index()];
            acc[3] += d3[t] * x[c3[t].index()];
        }
        for (k, a) in acc.iter_mut().enumerate() {
            let (s, e) = (p[k] + common, p[k + 1]);
            for (c, v) in indices[s..e].iter().zip(&data[s..e]) {
                *a += v * x[c.index()];
            }
        }
        yq.copy_from_slice(&acc);
        i += 4;
    }
    for (k, yi) in quads.into_remainder().iter_mut().enumerate() {
        *yi = one(i + k);
    }
}

/// `y ← A·x` for a CSR matrix given by its raw arrays (`indptr` of length `nrows + 1`, starting
/// at 0), parallel over blocks of rows from [`PAR_MIN_NNZ`] entries. Deterministic: each `y[i]`
/// is one serial row sum, the same on every path. Cost: `2·nnz` flops.
pub fn csr_apply_raw<I: SpIndex, Iptr: SpIndex>(
    indptr: &[Iptr],
    indices: &[I],
    data: &[f64],
    x: &[f64],
    y: &mut [f64],
) {
    if !go_parallel(data.len(), PAR_MIN_NNZ) {
        csr_rows(indptr, indices, data, x, 0, y);
    } else {
        y.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(c, yc)| {
            csr_rows(indptr, indices, data, x, c * ROW_CHUNK, yc);
        });
    }
}

/// `y ← Aᵀ·x` for a CSR matrix given by its raw arrays (a scatter). Large matrices are cut into
/// a fixed number of row blocks (a function of the sizes only); each block scatters into its own
/// buffer of length `ncols`, and buffers are added in block order, so the result is the same
/// whatever the thread count and whether the blocks run in parallel (from [`PAR_MIN_NNZ`]
/// entries) or one after the other. Cost: `2·nnz` flops plus `blocks·ncols` additions.
pub fn csr_apply_transpose_raw<I: SpIndex, Iptr: SpIndex>(
    indptr: &[Iptr],
    indices: &[I],
    data: &[f64],
    x: &[f64],
    y: &mut [f64],
) {
    let nrows = indptr.len().saturating_sub(1);
    let ncols = y.len();
    let scatter = |rows: std::ops::Range<usize>, out: &mut [f64]| {
        for i in rows {
            let xi = x[i];
            if xi == 0.0 {
                continue;
            }
            let (s, e) = (indptr[i].index(), indptr[i + 1].index());
            for (c, v) in indices[s..e].iter().zip(&data[s..e]) {
                out[c.index()] += v * xi;
            }
        }
    };
    y.iter_mut().for_each(|v| *v = 0.0);
    let nnz = data.len();
    // Blocks: enough to feed the threads, few enough that the buffers stay small next to A.
    let blocks = (nnz / TRANSPOSE_BLOCK_NNZ).min(64).min(nnz / ncols.max(1));
    if blocks < 2 {
        scatter(0..nrows, y);
        return;
    }
    let per = nrows.div_ceil(blocks);
    let block = |b: usize| {
        let mut out = vec![0.0; ncols];
        scatter(b * per..((b + 1) * per).min(nrows), &mut out);
        out
    };
    let partial: Vec<Vec<f64>> = if go_parallel(nnz, PAR_MIN_NNZ) {
        (0..blocks).into_par_iter().map(block).collect()
    } else {
        (0..blocks).map(block).collect()
    };
    for p in &partial {
        y.iter_mut().zip(p).for_each(|(yi, pi)| *yi += pi);
    }
}

/// `y ← A·x` for any `sprs` matrix (CSR: parallel rows; CSC: parallel scatter), with the
/// lengths checked. Cost: `2·nnz` flops.
pub fn par_mul_vec<I: SpIndex, Iptr: SpIndex>(
    a: CsMatViewI<'_, f64, I, Iptr>,
    x: &[f64],
    y: &mut [f64],
) -> Result<(), SolverError> {
    check_len("x (columns of A)", a.cols(), x.len())?;
    check_len("y (rows of A)", a.rows(), y.len())?;
    mat_apply(&a, x, y, false);
    Ok(())
}

/// `y ← Aᵀ·x` for any `sprs` matrix, with the lengths checked. Cost: `2·nnz` flops.
pub fn par_mul_vec_transpose<I: SpIndex, Iptr: SpIndex>(
    a: CsMatViewI<'_, f64, I, Iptr>,
    x: &[f64],
    y: &mut [f64],
) -> Result<(), SolverError> {
    check_len("x (rows of A)", a.rows(), x.len())?;
    check_len("y (columns of A)", a.cols(), y.len())?;
    mat_apply(&a, x, y, true);
    Ok(())
}

fn mat_apply<I: SpIndex, Iptr: SpIndex>(
    a: &CsMatViewI<'_, f64, I, Iptr>,
    x: &[f64],
    y: &mut [f64],
    transpose: bool,
) {
    let indptr = a.proper_indptr();
    // A CSC matrix is the CSR storage of its transpose.
    if a.is_csr() != transpose {
        csr_apply_raw(&indptr, a.indices(), a.data(), x, y);
    } else {
        csr_apply_transpose_raw(&indptr, a.indices(), a.data(), x, y);
    }
}

fn to_csr_usize<I: SpIndex, Iptr: SpIndex>(a: &CsMatViewI<'_, f64, I, Iptr>) -> CsMat<f64> {
    let csr = if a.is_csr() { a.to_owned() } else { a.to_csr() };
    let indptr: Vec<usize> = csr.proper_indptr().iter().map(|p| p.index()).collect();
    let indices: Vec<usize> = csr.indices().iter().map(|c| c.index()).collect();
    // The structure was valid in `a`, so it is valid with wider indices.
    CsMat::new(
        (csr.rows(), csr.cols()),
        indptr,
        indices,
        csr.data().to_vec(),
    )
}

impl<I: SpIndex, Iptr: SpIndex> LinearOperator for CsMatViewI<'_, f64, I, Iptr> {
    fn nrows(&self) -> usize {
        self.rows()
    }
    fn ncols(&self) -> usize {
        self.cols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        mat_apply(self, x, y, false);
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        mat_apply(self, x, y, true);
    }
    fn to_csr(&self) -> Option<CsMat<f64>> {
        Some(to_csr_usize(self))
    }
    fn column_norms(&self) -> Option<Vec<f64>> {
        Some(column_norms_generic(self))
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(diagonal_generic(self))
    }
    fn check_finite(&self) -> Result<(), SolverError> {
        check_finite("matrix", self.data())
    }
}

impl<I: SpIndex, Iptr: SpIndex> LinearOperator for CsMatI<f64, I, Iptr> {
    fn nrows(&self) -> usize {
        self.rows()
    }
    fn ncols(&self) -> usize {
        self.cols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        mat_apply(&self.view(), x, y, false);
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        mat_apply(&self.view(), x, y, true);
    }
    fn to_csr(&self) -> Option<CsMat<f64>> {
        Some(to_csr_usize(&self.view()))
    }
    fn column_norms(&self) -> Option<Vec<f64>> {
        Some(column_norms_generic(&self.view()))
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(diagonal_generic(&self.view()))
    }
    fn check_finite(&self) -> Result<(), SolverError> {
        check_finite("matrix", self.data())
    }
}

/// `B = A·D⁻¹`: `A` with its columns divided by `scale` (right preconditioning of LSQR/LSMR
/// by column norms). A solution `y` of `min ‖B·y − b‖` gives `x = D⁻¹·y`.
pub struct ColumnScaled<'a, Op: LinearOperator + ?Sized> {
    /// The operator being scaled.
    pub inner: &'a Op,
    /// `1/dⱼ` for each column `j` (length `ncols`).
    pub inv_scale: Vec<f64>,
}

impl<Op: LinearOperator + ?Sized> LinearOperator for ColumnScaled<'_, Op> {
    fn nrows(&self) -> usize {
        self.inner.nrows()
    }
    fn ncols(&self) -> usize {
        self.inner.ncols()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let xs: Vec<f64> = x.iter().zip(&self.inv_scale).map(|(a, s)| a * s).collect();
        self.inner.apply(&xs, y);
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        self.inner.apply_transpose(x, y);
        y.iter_mut().zip(&self.inv_scale).for_each(|(a, s)| *a *= s);
    }
}

/// Euclidean norm of every column of a matrix (length `ncols`). Cost: O(nnz).
pub fn column_norms(a: &CsMat<f64>) -> Vec<f64> {
    column_norms_generic(&a.view())
}

/// The diagonal of a matrix in either storage, without a copy (the sum of the stored entries
/// `(i, i)` of each outer lane, as [`crate::precond::diagonal`] computes it). Cost: O(nnz).
fn diagonal_generic<I: SpIndex, Iptr: SpIndex>(a: &CsMatViewI<'_, f64, I, Iptr>) -> Vec<f64> {
    let n = a.rows().min(a.cols());
    let mut d = vec![0.0; n];
    for (i, lane) in a.outer_iterator().enumerate().take(n) {
        for (j, v) in lane.iter() {
            if j == i {
                d[i] += v;
            }
        }
    }
    d
}

fn column_norms_generic<I: SpIndex, Iptr: SpIndex>(a: &CsMatViewI<'_, f64, I, Iptr>) -> Vec<f64> {
    let mut sq = vec![0.0; a.cols()];
    if a.is_csr() {
        for (c, v) in a.indices().iter().zip(a.data()) {
            sq[c.index()] += v * v;
        }
    } else {
        for (j, col) in a.outer_iterator().enumerate() {
            sq[j] = col.data().iter().map(|v| v * v).sum();
        }
    }
    sq.iter().map(|s| s.sqrt()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sprs::TriMat;

    fn random_csr(rows: usize, cols: usize, per_row: usize, seed: u64) -> CsMat<f64> {
        let mut t = TriMat::new((rows, cols));
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as usize
        };
        for i in 0..rows {
            for _ in 0..per_row {
                let j = next() % cols;
                let v = (next() % 1000) as f64 / 100.0 - 5.0;
                t.add_triplet(i, j, v);
            }
        }
        t.to_csr()
    }

    #[test]
    fn parallel_products_match_sprs_serial() {
        // Big enough to take the parallel paths (nnz > PAR_MIN_NNZ, several transpose blocks).
        let a = random_csr(40_000, 300, 8, 7);
        let x: Vec<f64> = (0..300).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut y = vec![0.0; 40_000];
        par_mul_vec(a.view(), &x, &mut y).unwrap();
        let expect: Vec<f64> = a
            .outer_iterator()
            .map(|row| row.iter().map(|(j, v)| v * x[j]).sum())
            .collect();
        for (u, v) in y.iter().zip(&expect) {
            assert!((u - v).abs() <= 1e-12 * (1.0 + v.abs()));
        }
        let u: Vec<f64> = (0..40_000).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut z = vec![0.0; 300];
        par_mul_vec_transpose(a.view(), &u, &mut z).unwrap();
        let at = a.transpose_view().to_csr();
        let mut z2 = vec![0.0; 300];
        csr_apply_raw(&at.proper_indptr(), at.indices(), at.data(), &u, &mut z2);
        for (p, q) in z.iter().zip(&z2) {
            assert!((p - q).abs() <= 1e-9 * (1.0 + q.abs()), "{p} vs {q}");
        }
        // CSC storage gives the same products.
        let csc = a.to_csc();
        let mut y2 = vec![0.0; 40_000];
        LinearOperator::apply(&csc, &x, &mut y2);
        for (u, v) in y.iter().zip(&y2) {
            assert!((u - v).abs() <= 1e-12 * (1.0 + v.abs()));
        }
    }

    #[test]
    fn length_mismatch_is_an_error() {
        let a = random_csr(5, 4, 2, 1);
        let mut y = vec![0.0; 5];
        assert!(matches!(
            par_mul_vec(a.view(), &[1.0; 3], &mut y),
            Err(SolverError::DimensionMismatch { .. })
        ));
    }
}
