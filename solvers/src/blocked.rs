//! A CSR matrix with a lane-blocked copy for fast products: [`BlockedCsr`].
//!
//! # Layout
//!
//! Rows are taken in blocks of [`BLOCK_ROWS`] consecutive rows `i .. i + BLOCK_ROWS`. Row `i + k`
//! stores column `c` at the *relative offset* `o = c − (i + k)`. A block whose rows' offsets fit
//! one sorted list (their union, the block's *pattern*) is stored lane-interleaved:
//! `values[t·BLOCK_ROWS + k]` is row `i + k`'s entry at offset `pattern[t]`, or an explicit `0`
//! where that row has no entry there. The product of such a block reads, for each `t`, the
//! contiguous `x[i + pattern[t] .. i + pattern[t] + BLOCK_ROWS]` and the contiguous values, with
//! no column index per entry: the eight row sums run side by side as SIMD lanes. Blocks whose
//! pattern would read outside `x`, or hold more than twice their stored entries (irregular rows),
//! and the last partial block, stay plain CSR rows.
//!
//! On a matrix with a grid stencil's sparsity (the trilinear fit's normal equations: 27-point
//! stencil, rows in grid order) nearly every block is lane-blocked and consecutive blocks share a
//! pattern, so the patterns cost almost nothing and the explicit zeros are few (the fit's default
//! system: 45 860 entries become 59 688 slots, 95.8 % of the rows lane-blocked).
//!
//! # Results
//!
//! Each row's sum is the same serial sum, in stored (column) order and starting from `+0`, as the
//! CSR product's ([`crate::operator::csr_apply_raw`]): a padded slot adds `0·x[c] = ±0` to a sum
//! that is never `−0` (a sum started at `+0` can only reach `+0` when it cancels), which leaves it
//! unchanged bit for bit. So for finite `x` the product is **bitwise identical** to the CSR
//! product, and solves through a [`BlockedCsr`] give the same iterates, iteration counts and
//! residuals as through its CSR matrix. (An infinite or NaN `x[c]` turns a padded slot into NaN
//! where the CSR product would not read `x[c]`; the solvers stop on non-finite iterates anyway.)

use crate::error::{SolverError, check_finite};
use crate::operator::{LinearOperator, PAR_MIN_NNZ, csr_apply_transpose_raw, csr_rows};
use crate::parallel::go_parallel;
use rayon::prelude::*;
use sprs::CsMat;

/// Rows per block: eight `f64` sums are four SSE2 (two AVX) registers, enough independent
/// chains of additions to hide an addition's latency; eight beat four on the fit's default
/// system.
pub const BLOCK_ROWS: usize = 8;

/// Blocks per parallel task (`BLOCKS_PER_TASK · BLOCK_ROWS` = 512 rows, as the CSR product).
const BLOCKS_PER_TASK: usize = 64;

/// A lane-blocked block: its pattern (a range of `BlockedCsr::offsets`) and values.
#[derive(Debug, Clone, Copy)]
struct Lanes {
    /// First offset of the pattern in `offsets`.
    pattern: usize,
    /// Pattern length (slots per lane).
    len: usize,
    /// First value in `values` (`len · BLOCK_ROWS` values).
    values: usize,
}

/// A CSR matrix (kept for the transpose product, the preconditioners and [`LinearOperator::to_csr`])
/// with a lane-blocked copy of its rows used by [`LinearOperator::apply`]: see the module docs.
/// Memory: the CSR matrix plus the lane slots (about `1.3·nnz` values on a stencil matrix).
#[derive(Debug, Clone)]
pub struct BlockedCsr {
    csr: CsMat<f64>,
    /// One entry per full block of rows; `None` = plain CSR rows.
    blocks: Vec<Option<Lanes>>,
    /// Patterns: sorted relative offsets `c − row`.
    offsets: Vec<isize>,
    /// Lane-interleaved values.
    values: Vec<f64>,
}

impl BlockedCsr {
    /// Builds the blocked copy of a CSR matrix (a CSC matrix is converted to CSR first). Errors
    /// on a non-finite stored value. Cost: O(slots), a merge of each block's rows with its
    /// pattern, plus a sort of the pattern of each block that the previous block's pattern does
    /// not hold (on the fit's default system, 33 of 288 blocks); about 0.2 ms on that system.
    pub fn new(a: CsMat<f64>) -> Result<Self, SolverError> {
        check_finite("matrix", a.data())?;
        let csr = if a.is_csr() { a } else { a.to_csr() };
        let (nrows, ncols) = (csr.rows(), csr.cols());
        let indptr = csr.proper_indptr();
        let (indices, data) = (csr.indices(), csr.data());
        let nblocks = nrows / BLOCK_ROWS;
        let mut blocks = Vec::with_capacity(nblocks);
        let mut offsets: Vec<isize> = Vec::new();
        // A stencil matrix pads its entries by about a third (the fit's: 1.30), so this
        // capacity holds it without a reallocation.
        let mut values: Vec<f64> = Vec::with_capacity(csr.nnz() + csr.nnz() / 2);
        let mut scratch: Vec<isize> = Vec::new();
        // The current pattern: (start, len) in `offsets`.
        let mut current: Option<(usize, usize)> = None;
        // Appends rows `first .. first + BLOCK_ROWS` laid out on `pattern` (lane-interleaved,
        // zeros where a row lacks an offset) to `values`, walking the pattern and every row's
        // entries together (a merge: no lookups, `values` written in order). False, with
        // `values` unchanged, when a row has an offset outside the pattern or unsorted columns
        // (its entries are then not all consumed).
        let fill = |pattern: &[isize], first: usize, values: &mut Vec<f64>| -> bool {
            let v0 = values.len();
            let mut cur: [usize; BLOCK_ROWS] = std::array::from_fn(|k| indptr[first + k]);
            let end: [usize; BLOCK_ROWS] = std::array::from_fn(|k| indptr[first + k + 1]);
            for &o in pattern {
                let mut lane = [0.0f64; BLOCK_ROWS];
                for k in 0..BLOCK_ROWS {
                    let e = cur[k];
                    let want = (first + k) as isize + o;
                    if e < end[k] && indices[e] as isize == want {
                        lane[k] = data[e];
                        cur[k] = e + 1;
                    }
                }
                values.extend_from_slice(&lane);
            }
            if cur != end {
                values.truncate(v0);
                return false;
            }
            true
        };
        for b in 0..nblocks {
            let first = b * BLOCK_ROWS;
            let block_nnz = indptr[first + BLOCK_ROWS] - indptr[first];
            // x[first + o .. first + o + BLOCK_ROWS] must lie inside x for every slot; an empty
            // block, or one padded beyond twice its entries, stays plain.
            let fits = |pattern: &[isize]| {
                let (Some(&lo), Some(&hi)) = (pattern.first(), pattern.last()) else {
                    return false;
                };
                first as isize + lo >= 0
                    && first as isize + hi + BLOCK_ROWS as isize <= ncols as isize
                    && pattern.len() * BLOCK_ROWS <= 2 * block_nnz
            };
            let v0 = values.len();
            // First try the current pattern (on a stencil matrix, nearly every block).
            if let Some((start, len)) = current
                && fits(&offsets[start..start + len])
                && fill(&offsets[start..start + len], first, &mut values)
            {
                blocks.push(Some(Lanes {
                    pattern: start,
                    len,
                    values: v0,
                }));
                continue;
            }
            // A new pattern: the union of the rows' offsets.
            scratch.clear();
            for i in first..first + BLOCK_ROWS {
                scratch.extend(
                    indices[indptr[i]..indptr[i + 1]]
                        .iter()
                        .map(|&c| c as isize - i as isize),
                );
            }
            scratch.sort_unstable();
            scratch.dedup();
            // Unsorted columns in a row cannot follow a sorted pattern: `fill` refuses them.
            if !fits(&scratch) || !fill(&scratch, first, &mut values) {
                blocks.push(None);
                continue;
            }
            let start = offsets.len();
            offsets.extend_from_slice(&scratch);
            current = Some((start, scratch.len()));
            blocks.push(Some(Lanes {
                pattern: start,
                len: scratch.len(),
                values: v0,
            }));
        }
        Ok(Self {
            csr,
            blocks,
            offsets,
            values,
        })
    }

    /// The CSR matrix the operator was built from.
    pub fn csr(&self) -> &CsMat<f64> {
        &self.csr
    }

    /// The CSR matrix, giving up the blocked copy.
    pub fn into_csr(self) -> CsMat<f64> {
        self.csr
    }

    /// Share of the rows that the blocked product handles (the rest are plain CSR rows), in
    /// `[0, 1]` (`1` for an empty matrix).
    pub fn blocked_share(&self) -> f64 {
        let n = self.csr.rows();
        if n == 0 {
            return 1.0;
        }
        (self.blocks.iter().filter(|b| b.is_some()).count() * BLOCK_ROWS) as f64 / n as f64
    }

    /// Lane slots the product multiplies (stored entries of the blocked rows plus their explicit
    /// zeros, plus the stored entries of the plain rows): the product costs `2·slots` flops.
    pub fn slots(&self) -> usize {
        let indptr = self.csr.proper_indptr();
        let plain: usize = self
            .blocks
            .iter()
            .enumerate()
            .filter(|(_, b)| b.is_none())
            .map(|(b, _)| indptr[(b + 1) * BLOCK_ROWS] - indptr[b * BLOCK_ROWS])
            .sum();
        let tail = indptr[self.csr.rows()] - indptr[self.blocks.len() * BLOCK_ROWS];
        self.values.len() + plain + tail
    }

    /// `y[r] ← (A·x)[first_row + r]` for whole blocks from block `first_block` (and the rows
    /// after the last full block when `y` reaches them). Compiled twice: with AVX where the CPU
    /// has it (four lanes per instruction instead of SSE2's two: 1.5× faster on the fit's
    /// system), and for the baseline. Both multiply, then add, lane by lane (no fused
    /// multiply-add), so they give the same bits.
    fn rows(&self, x: &[f64], first_block: usize, y: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX (detected just above).
            unsafe { self.rows_avx(x, first_block, y) };
            return;
        }
        self.rows_portable(x, first_block, y);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn rows_avx(&self, x: &[f64], first_block: usize, y: &mut [f64]) {
        self.rows_portable(x, first_block, y);
    }

    #[inline(always)]
    fn rows_portable(&self, x: &[f64], first_block: usize, y: &mut [f64]) {
        let indptr = self.csr.proper_indptr();
        let (indices, data) = (self.csr.indices(), self.csr.data());
        // Plain rows: the CSR product's own kernel (each row the same serial sum).
        let plain = |first: usize, y: &mut [f64]| csr_rows(&indptr, indices, data, x, first, y);
        let mut chunks = y.chunks_exact_mut(BLOCK_ROWS);
        for (b, yb) in (first_block..).zip(&mut chunks) {
            let first = b * BLOCK_ROWS;
            match self.blocks[b] {
                Some(l) => {
                    let pattern = &self.offsets[l.pattern..l.pattern + l.len];
                    let values = &self.values[l.values..l.values + l.len * BLOCK_ROWS];
                    let mut acc = [0.0f64; BLOCK_ROWS];
                    for (&o, v) in pattern.iter().zip(values.chunks_exact(BLOCK_ROWS)) {
                        // In range by construction (`new` checked every pattern against x).
                        let base = (first as isize + o) as usize;
                        let xs = &x[base..base + BLOCK_ROWS];
                        for k in 0..BLOCK_ROWS {
                            acc[k] += v[k] * xs[k];
                        }
                    }
                    yb.copy_from_slice(&acc);
                }
                None => plain(first, yb),
            }
        }
        plain(self.blocks.len() * BLOCK_ROWS, chunks.into_remainder());
    }
}

impl LinearOperator for BlockedCsr {
    fn nrows(&self) -> usize {
        self.csr.rows()
    }
    fn ncols(&self) -> usize {
        self.csr.cols()
    }
    /// The blocked product (module docs), in parallel over groups of blocks from
    /// [`PAR_MIN_NNZ`] stored entries. Cost: `2·slots()` flops.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        assert_eq!(x.len(), self.csr.cols(), "x (columns of A)");
        assert_eq!(y.len(), self.csr.rows(), "y (rows of A)");
        if !go_parallel(self.csr.nnz(), PAR_MIN_NNZ) {
            self.rows(x, 0, y);
        } else {
            let rows_per_task = BLOCKS_PER_TASK * BLOCK_ROWS;
            y.par_chunks_mut(rows_per_task)
                .enumerate()
                .for_each(|(c, yc)| self.rows(x, c * BLOCKS_PER_TASK, yc));
        }
    }
    fn apply_transpose(&self, x: &[f64], y: &mut [f64]) {
        let indptr = self.csr.proper_indptr();
        csr_apply_transpose_raw(&indptr, self.csr.indices(), self.csr.data(), x, y);
    }
    fn to_csr(&self) -> Option<CsMat<f64>> {
        Some(self.csr.clone())
    }
    fn column_norms(&self) -> Option<Vec<f64>> {
        LinearOperator::column_norms(&self.csr)
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        LinearOperator::diagonal(&self.csr)
    }
    fn check_finite(&self) -> Result<(), SolverError> {
        // Checked once in `new`; the matrix is not mutable afterwards.
        Ok(())
    }
}
