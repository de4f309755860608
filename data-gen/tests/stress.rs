//! Property tests of the ray casting numerics: random and adversarial primitives and rays give a
//! finite hit with a unit normal on the surface, or a miss; degenerate primitives are typed
//! errors; nothing panics.

use altrep_data_gen::{Albedo, Csg, DataGenError, Part, Primitive, Ray, Shape};
use glam::{DVec3, Vec3};
use proptest::prelude::*;

fn vec3(range: std::ops::Range<f64>) -> impl Strategy<Value = DVec3> {
    (range.clone(), range.clone(), range).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn primitive() -> impl Strategy<Value = Primitive> {
    prop_oneof![
        (vec3(-1.0..1.0), 1e-4..1.0f64)
            .prop_map(|(center, radius)| Primitive::Sphere { center, radius }),
        (vec3(-1.0..1.0), vec3(1e-4..1.0), -7.0..7.0f64)
            .prop_map(|(center, half, yaw)| Primitive::Box { center, half, yaw }),
        (vec3(-1.0..1.0), vec3(-1.0..1.0), 1e-3..0.5f64)
            .prop_map(|(a, b, radius)| Primitive::Capsule { a, b, radius }),
        (vec3(-1.0..1.0), vec3(-1.0..1.0), 1e-3..0.5f64)
            .prop_map(|(a, b, radius)| Primitive::Cylinder { a, b, radius }),
        (vec3(-1.0..1.0), vec3(-1.0..1.0), 0.05..0.6f64, 0.01..0.3f64).prop_map(
            |(center, axis, major, minor)| Primitive::Torus {
                center,
                axis,
                major,
                minor
            }
        ),
    ]
}

/// A point strictly inside `p`: the centre of a sphere or box, the middle of a capsule's or
/// cylinder's axis, a point of a torus's core circle.
fn inside(p: &Primitive) -> DVec3 {
    match p {
        Primitive::Sphere { center, .. } | Primitive::Box { center, .. } => *center,
        Primitive::Capsule { a, b, .. } | Primitive::Cylinder { a, b, .. } => 0.5 * (*a + *b),
        Primitive::Torus {
            center,
            axis,
            major,
            ..
        } => *center + *major * axis.normalize().any_orthonormal_vector(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    /// A ray from outside (distance 10) toward a random point: a miss, or a hit whose point lies
    /// on the surface (|sdf| small), with a finite unit normal facing the ray. A ray toward a
    /// point inside the primitive ([`inside`]) must hit, before reaching that point.
    #[test]
    fn hits_lie_on_the_surface(p in primitive(), from in vec3(-1.0..1.0), to in vec3(-1.0..1.0)) {
        let Ok(shape) = Csg::new("p", vec![Part { primitive: p.clone(), albedo: Albedo::Solid(Vec3::ONE) }]) else {
            // Degenerate draws (coincident ends) are typed errors; nothing else to check.
            return Ok(());
        };
        let target = inside(&p);
        prop_assert!(shape.sdf(target).unwrap() < 0.0, "{target} is not inside {p:?}");
        for (to, must_hit) in [(to, false), (target, true)] {
            let dir = (to - from).normalize_or(DVec3::X);
            let ray = Ray::new(to - 10.0 * dir, dir);
            let hit = shape.intersect(&ray, 0.0, 100.0);
            prop_assert!(hit.is_some() || !must_hit, "the ray toward {to}, inside {p:?}, missed");
            if let Some(hit) = hit {
                prop_assert!(hit.t.is_finite() && hit.t > 0.0);
                prop_assert!(!must_hit || hit.t < 10.0, "hit at t = {} past the inner point", hit.t);
                prop_assert!((hit.normal.length() - 1.0).abs() < 1e-6, "normal {:?}", hit.normal);
                prop_assert!(hit.normal.dot(dir) <= 1e-12);
                let sdf = shape.sdf(ray.at(hit.t)).unwrap();
                prop_assert!(sdf.abs() < 1e-6, "sdf at hit {sdf} for {p:?}");
            }
        }
    }

    /// Degenerate and non-finite primitives are rejected with a typed error.
    #[test]
    fn degenerate_primitives_are_typed_errors(c in vec3(-1.0..1.0), r in -1.0..0.0f64, pick in 0usize..5) {
        let p = match pick {
            0 => Primitive::Sphere { center: c, radius: r },
            1 => Primitive::Box { center: c, half: DVec3::new(0.5, r, 0.5), yaw: 0.0 },
            2 => Primitive::Cylinder { a: c, b: c, radius: 0.3 },
            3 => Primitive::Torus { center: c, axis: DVec3::ZERO, major: 0.5, minor: 0.1 },
            _ => Primitive::Capsule { a: c, b: DVec3::new(f64::NAN, 0.0, 0.0), radius: 0.2 },
        };
        let e = Csg::new("bad", vec![Part { primitive: p, albedo: Albedo::Solid(Vec3::ONE) }]);
        prop_assert!(matches!(e, Err(DataGenError::InvalidParameter { .. })), "{:?}", e.map(|c| c.parts().len()));
    }
}
