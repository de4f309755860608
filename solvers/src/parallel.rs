//! Whether the kernels (CSR products, dot products, vector updates) split their work over rayon
//! threads.
//!
//! The **result** of every kernel does not depend on this choice: each reduction has a fixed
//! shape that depends only on the sizes involved (rows of a product are single serial sums;
//! long dot products and transpose products are cut into fixed chunks or blocks whose partial
//! results are added in order), and the serial path evaluates exactly the same chunks one after
//! the other. So serial and parallel solves give bit-for-bit identical iterates, and the choice
//! is purely one of speed.
//!
//! By default ([`Parallelism::Auto`]) a kernel runs in parallel when its work is at least a
//! threshold ([`crate::operator::PAR_MIN_NNZ`] for products,
//! [`crate::vecops::PAR_MIN_LEN`] for vector kernels) and rayon has more than one thread: below
//! that, splitting costs more than it gives. [`with_parallelism`] overrides the choice for the
//! kernels called on the current thread (for tests and benchmarks).

use std::cell::Cell;

/// How the kernels called on the current thread split their work.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Parallelism {
    /// Parallel above the measured thresholds, with more than one rayon thread (the default).
    #[default]
    Auto,
    /// Always serial.
    Serial,
    /// Always through the parallel code path (even for tiny work; for tests).
    Parallel,
}

thread_local! {
    static MODE: Cell<Parallelism> = const { Cell::new(Parallelism::Auto) };
}

/// The mode in force on the current thread.
pub fn parallelism() -> Parallelism {
    MODE.with(Cell::get)
}

/// Runs `f` with the kernels called on the current thread in `mode`, then restores the previous
/// mode (also when `f` panics). Results are identical in every mode (module docs).
pub fn with_parallelism<R>(mode: Parallelism, f: impl FnOnce() -> R) -> R {
    struct Restore(Parallelism);
    impl Drop for Restore {
        fn drop(&mut self) {
            MODE.with(|m| m.set(self.0));
        }
    }
    let _restore = Restore(MODE.with(|m| m.replace(mode)));
    f()
}

/// Whether a kernel with `work` units (non-zeros, entries) should split, given its threshold.
#[inline]
pub(crate) fn go_parallel(work: usize, threshold: usize) -> bool {
    match parallelism() {
        Parallelism::Auto => work >= threshold && rayon::current_num_threads() > 1,
        Parallelism::Serial => false,
        Parallelism::Parallel => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_is_scoped_and_restored() {
        assert_eq!(parallelism(), Parallelism::Auto);
        let inner = with_parallelism(Parallelism::Serial, || {
            assert!(!go_parallel(usize::MAX, 1));
            with_parallelism(Parallelism::Parallel, || go_parallel(0, usize::MAX))
        });
        assert!(inner);
        assert_eq!(parallelism(), Parallelism::Auto);
        let r = std::panic::catch_unwind(|| {
            with_parallelism(Parallelism::Serial, || panic!("inside"));
        });
        assert!(r.is_err());
        assert_eq!(parallelism(), Parallelism::Auto);
    }
}
