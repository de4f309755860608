//! Random rotations and directions for reproducible test cases, drawn from data-gen's seeded
//! [`SplitMix64`] (the project's one generator).

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

pub use altrep_data_gen::SplitMix64;

/// Random rotations and unit vectors from a seeded generator.
pub trait RandomGeometry {
    /// A rotation drawn uniformly from SO(3) (Shoemake's uniform unit quaternion), as a matrix
    /// whose columns are the rotated x, y, z axes (orthonormal, determinant +1).
    fn rotation(&mut self) -> Matrix3<f64>;
    /// A unit vector drawn uniformly on the sphere.
    fn unit_vector(&mut self) -> Vector3<f64>;
}

impl RandomGeometry for SplitMix64 {
    fn rotation(&mut self) -> Matrix3<f64> {
        let u1 = self.next_f64();
        let u2 = self.next_f64() * std::f64::consts::TAU;
        let u3 = self.next_f64() * std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = nalgebra::Quaternion::new(b * u3.cos(), a * u2.sin(), a * u2.cos(), b * u3.sin());
        UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner()
    }

    fn unit_vector(&mut self) -> Vector3<f64> {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
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
