//! A tiny seeded random generator for reproducible test cases (rotations, jitter).
//!
//! The library needs random numbers only to build its own test and benchmark cases; a full `rand`
//! dependency would be heavier than these 30 lines. SplitMix64 (Steele, Lea & Flood 2014) passes
//! BigCrush and is the usual seeder of xoshiro generators; it is not cryptographic.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// SplitMix64: a 64-bit seeded generator. Same seed, same sequence, on every platform.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)` with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform number in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }

    /// A rotation drawn uniformly from SO(3) (Shoemake's uniform unit quaternion), as a matrix
    /// whose columns are the rotated x, y, z axes (orthonormal, determinant +1).
    pub fn rotation(&mut self) -> Matrix3<f64> {
        let u1 = self.next_f64();
        let u2 = self.next_f64() * std::f64::consts::TAU;
        let u3 = self.next_f64() * std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = nalgebra::Quaternion::new(b * u3.cos(), a * u2.sin(), a * u2.cos(), b * u3.sin());
        UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner()
    }

    /// A unit vector drawn uniformly on the sphere.
    pub fn unit_vector(&mut self) -> Vector3<f64> {
        let z = self.uniform(-1.0, 1.0);
        let phi = self.uniform(0.0, std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vector3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_sequence_and_uniform_range() {
        let mut a = SplitMix64::new(7);
        let mut b = SplitMix64::new(7);
        for _ in 0..100 {
            let x = a.next_f64();
            assert_eq!(x, b.next_f64());
            assert!((0.0..1.0).contains(&x));
        }
    }

    #[test]
    fn rotations_are_orthonormal_and_proper() {
        let mut r = SplitMix64::new(1);
        for _ in 0..100 {
            let m = r.rotation();
            assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-14);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
        }
    }
}
