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
/// million entries) far above. `cargo bench -p altrep-benches --bench solvers`, group `vecops_split`.
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
    finish4(acc, rx.iter().zip(ry).map(|(a, b)| a * b))
}

/// The end of [`dot_serial`]'s sum: its four accumulators (over groups of four), then the
/// remainder's terms added one by one. Fused kernels end with it, so they sum exactly as
/// `dot_serial` would.
#[inline(always)]
fn finish4(acc: [f64; 4], rest: impl Iterator<Item = f64>) -> f64 {
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for t in rest {
        s += t;
    }
    s
}

/// CG's update in one pass: `x ← x + a·p`, `r ← r − a·q`, and returns `‖r‖₂`. Bit for bit the
/// same as [`axpy`]`(a, p, x)`, [`axpy`]`(−a, q, r)`, [`norm2`]`(r)`; short vectors (below
/// `2·PAR_CHUNK`) make one pass instead of three, long ones call those kernels. Cost: `6n` flops.
pub fn cg_update(a: f64, p: &[f64], q: &[f64], x: &mut [f64], r: &mut [f64]) -> f64 {
    let n = r.len();
    debug_assert!(p.len() == n && q.len() == n && x.len() == n);
    if n >= 2 * PAR_CHUNK {
        axpy(a, p, x);
        axpy(-a, q, r);
        return norm2(r);
    }
    let na = -a;
    let mut acc = [0.0f64; 4];
    let mut xs = x.chunks_exact_mut(4);
    let mut rs = r.chunks_exact_mut(4);
    let (ps, qs) = (p.chunks_exact(4), q.chunks_exact(4));
    let (pr, qr) = (ps.remainder(), qs.remainder());
    for ((xc, rc), (pc, qc)) in (&mut xs).zip(&mut rs).zip(ps.zip(qs)) {
        for k in 0..4 {
            xc[k] += a * pc[k];
            rc[k] += na * qc[k];
            acc[k] += rc[k] * rc[k];
        }
    }
    let (xr, rr) = (xs.into_remainder(), rs.into_remainder());
    let rest =
        xr.iter_mut()
            .zip(rr.iter_mut())
            .zip(pr.iter().zip(qr))
            .map(|((xi, ri), (pi, qi))| {
                *xi += a * pi;
                *ri += na * qi;
                *ri * *ri
            });
    finish4(acc, rest).sqrt()
}

/// `z ← d ⊙ r` (elementwise) and returns `rᵀz`: the Jacobi preconditioner and the dot product
/// that follows it, in one pass for short vectors. Bit for bit the same as the two separate
/// kernels. Cost: `3n` flops.
pub fn scale_dot(d: &[f64], r: &[f64], z: &mut [f64]) -> f64 {
    let n = z.len();
    debug_assert!(d.len() == n && r.len() == n);
    if n >= 2 * PAR_CHUNK {
        scale_into(d, r, z);
        return dot(r, z);
    }
    let mut acc = [0.0f64; 4];
    let mut zs = z.chunks_exact_mut(4);
    let (ds, rs) = (d.chunks_exact(4), r.chunks_exact(4));
    let (dr, rr) = (ds.remainder(), rs.remainder());
    for (zc, (dc, rc)) in (&mut zs).zip(ds.zip(rs)) {
        for k in 0..4 {
            zc[k] = rc[k] * dc[k];
            acc[k] += rc[k] * zc[k];
        }
    }
    let rest = zs
        .into_remainder()
        .iter_mut()
        .zip(dr.iter().zip(rr))
        .map(|(zi, (di, ri))| {
            *zi = ri * di;
            ri * *zi
        });
    finish4(acc, rest)
}

/// `z ← d ⊙ r` (elementwise, `r[i]·d[i]`): the Jacobi preconditioner's step. Cost: `n` flops.
pub fn scale_into(d: &[f64], r: &[f64], z: &mut [f64]) {
    z.iter_mut()
        .zip(r.iter().zip(d))
        .for_each(|(zi, (ri, di))| *zi = ri * di);
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
    fn fused_kernels_are_bitwise_the_separate_ones() {
        for n in [0, 1, 3, 4, 7, 2304, 2 * PAR_CHUNK - 1, 2 * PAR_CHUNK + 3] {
            let p: Vec<f64> = (0..n).map(|i| (i as f64 * 0.731).sin()).collect();
            let q: Vec<f64> = (0..n).map(|i| (i as f64 * 0.237).cos() * 1e3).collect();
            let d: Vec<f64> = (0..n).map(|i| 1.0 / (1.0 + i as f64 * 0.01)).collect();
            let x0: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).sin() * 1e-3).collect();
            let r0: Vec<f64> = (0..n).map(|i| (i as f64 * 0.05).cos()).collect();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let (mut x1, mut r1) = (x0.clone(), r0.clone());
            axpy(0.37, &p, &mut x1);
            axpy(-0.37, &q, &mut r1);
            let n1 = norm2(&r1);
            let (mut x2, mut r2) = (x0.clone(), r0.clone());
            let n2 = cg_update(0.37, &p, &q, &mut x2, &mut r2);
            assert_eq!(
                (bits(&x1), bits(&r1), n1.to_bits()),
                (bits(&x2), bits(&r2), n2.to_bits())
            );
            let z1: Vec<f64> = r1.iter().zip(&d).map(|(r, d)| r * d).collect();
            let s1 = dot(&r1, &z1);
            let mut z2 = vec![0.0; n];
            let s2 = scale_dot(&d, &r1, &mut z2);
            assert_eq!(
                (bits(&z1), s1.to_bits()),
                (bits(&z2), s2.to_bits()),
                "n = {n}"
            );
        }
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
