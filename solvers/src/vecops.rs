//! Dense vector kernels used by the solvers: dot, norm, axpy-like updates.
//!
//! Short vectors (the normal equations of a fit have a few thousand unknowns) run serially: a
//! rayon split costs more than the work. Long vectors (LSQR's sample-space vectors, millions of
//! entries) are cut into fixed chunks of [`PAR_CHUNK`] entries; partial sums are added in chunk
//! order, so results are bit-for-bit reproducible whatever the thread count, and the same
//! whether the chunks run in parallel or one after the other (see [`crate::parallel`]).

use rayon::prelude::*;

use crate::parallel::go_parallel;

/// Chunk length of long vectors: a dot product of at least `2·PAR_CHUNK` entries is the ordered
/// sum of the dot products of its chunks (the reduction's shape, independent of threads).
pub const PAR_CHUNK: usize = 1 << 15;

/// Vectors at least this long are processed in parallel (under [`crate::Parallelism::Auto`]):
/// below it the rayon split (a few µs) costs more than the work it shares. The fit's normal
/// equations (a few thousand unknowns) stay far below it; LSQR's sample-space vectors (about a
/// million entries) far above. `cargo bench --bench solvers`, group `vecops_split`.
pub const PAR_MIN_LEN: usize = 2 * PAR_CHUNK;

/// `xᵀy`. Cost: `2n` flops.
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    debug_assert_eq!(x.len(), y.len());
    if x.len() < 2 * PAR_CHUNK {
        return dot_serial(x, y);
    }
    let partial: Vec<f64> = if go_parallel(x.len(), PAR_MIN_LEN) {
        x.par_chunks(PAR_CHUNK)
            .zip(y.par_chunks(PAR_CHUNK))
            .map(|(a, b)| dot_serial(a, b))
            .collect()
    } else {
        x.chunks(PAR_CHUNK)
            .zip(y.chunks(PAR_CHUNK))
            .map(|(a, b)| dot_serial(a, b))
            .collect()
    };
    partial.iter().sum()
}

fn dot_serial(x: &[f64], y: &[f64]) -> f64 {
    // Four accumulators: lets the compiler vectorise without reassociating a single sum.
    let mut acc = [0.0f64; 4];
    let cx = x.chunks_exact(4);
    let cy = y.chunks_exact(4);
    let (rx, ry) = (cx.remainder(), cy.remainder());
    for (a, b) in cx.zip(cy) {
        for k in 0..4 {
            acc[k] += a[k] * b[k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (a, b) in rx.iter().zip(ry) {
        s += a * b;
    }
    s
}

/// Euclidean norm `‖x‖₂`, computed as `sqrt(xᵀx)`. Cost: `2n` flops.
pub fn norm2(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

/// Applies `f(&mut y[i], x[i])` for every `i`, in parallel for long vectors.
pub fn zip_apply(y: &mut [f64], x: &[f64], f: impl Fn(&mut f64, f64) + Sync) {
    debug_assert_eq!(x.len(), y.len());
    if !go_parallel(y.len(), PAR_MIN_LEN) {
        y.iter_mut().zip(x).for_each(|(yi, &xi)| f(yi, xi));
    } else {
        y.par_chunks_mut(PAR_CHUNK)
            .zip(x.par_chunks(PAR_CHUNK))
            .for_each(|(yc, xc)| yc.iter_mut().zip(xc).for_each(|(yi, &xi)| f(yi, xi)));
    }
}

/// `y ← y + a·x`.
pub fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    zip_apply(y, x, |yi, xi| *yi += a * xi);
}

/// `y ← x + b·y` (the search-direction update of CG-type methods).
pub fn xpby(x: &[f64], b: f64, y: &mut [f64]) {
    zip_apply(y, x, |yi, xi| *yi = xi + b * *yi);
}

/// `y ← a·y`.
pub fn scale(a: f64, y: &mut [f64]) {
    if !go_parallel(y.len(), PAR_MIN_LEN) {
        y.iter_mut().for_each(|v| *v *= a);
    } else {
        y.par_chunks_mut(PAR_CHUNK)
            .for_each(|c| c.iter_mut().for_each(|v| *v *= a));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_long_matches_serial_sum() {
        let n = 5 * PAR_CHUNK + 17;
        let x: Vec<f64> = (0..n).map(|i| (i % 7) as f64 - 3.0).collect();
        let y: Vec<f64> = (0..n).map(|i| (i % 5) as f64 * 0.5).collect();
        let expect: f64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
        assert!((dot(&x, &y) - expect).abs() <= 1e-9 * expect.abs().max(1.0));
        let mut z = y.clone();
        axpy(2.0, &x, &mut z);
        assert_eq!(z[n - 1], y[n - 1] + 2.0 * x[n - 1]);
        xpby(&x, 0.5, &mut z);
        assert_eq!(z[3], x[3] + 0.5 * (y[3] + 2.0 * x[3]));
        scale(2.0, &mut z);
        assert_eq!(z[3], 2.0 * (x[3] + 0.5 * (y[3] + 2.0 * x[3])));
    }

    #[test]
    fn serial_and_parallel_kernels_are_bitwise_identical() {
        use crate::parallel::{Parallelism, with_parallelism};
        for n in [7, 2 * PAR_CHUNK - 1, 2 * PAR_CHUNK, 3 * PAR_CHUNK + 5] {
            let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.731).sin()).collect();
            let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.237).cos() * 1e3).collect();
            let run = |mode| {
                with_parallelism(mode, || {
                    let mut z = y.clone();
                    axpy(0.3, &x, &mut z);
                    xpby(&x, -1.7, &mut z);
                    scale(1.1, &mut z);
                    (
                        dot(&x, &z).to_bits(),
                        z.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    )
                })
            };
            assert_eq!(
                run(Parallelism::Serial),
                run(Parallelism::Parallel),
                "n = {n}"
            );
            assert_eq!(run(Parallelism::Serial), run(Parallelism::Auto), "n = {n}");
        }
    }
}
