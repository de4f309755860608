//! Ellipsoid micro-primitives, eigen-solver, filtering and octree (docs/design.md §8): closed forms
//! against quadrature, adversarial eigen suite, filter invariants, property tests.

use std::f64::consts::PI;

use altrep_data_gen::Supersample;

use altrep::ellipsoid::eigen::{
    adversarial_suite, adversarial_suite_f32, orthogonality_error, reconstruction_error,
    sym_eigen3, sym_eigen3_nalgebra,
};
use altrep::ellipsoid::filter::{FilterCase, fit_sin2_exponent, rotate, rotation_about};
use altrep::ellipsoid::octree::{
    AnalyticVolume, Octree, OctreeParams, Voxel, VoxelGrid, VoxelSource,
};
use altrep::ellipsoid::rng::{RandomGeometry, SplitMix64};
use altrep::ellipsoid::{
    Ellipsoid, EllipsoidError, FilterRule, Phong, SphereQuadrature, filter, filter_errors,
};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

fn quad(tolerance: f64) -> SphereQuadrature {
    SphereQuadrature {
        base: 12,
        max_depth: 9,
        tolerance,
    }
}

fn triaxial(seed: u64, lengths: [f64; 3]) -> Ellipsoid {
    let r = SplitMix64::new(seed).rotation();
    Ellipsoid::new(r, Vector3::from(lengths)).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Normal distribution and projected area.

#[test]
fn normal_distribution_integrates_to_surface_area() {
    // Sphere: 4πr².
    let s = Ellipsoid::sphere(1.7).unwrap();
    let r = quad(1e-10).integrate_scalar(|n| s.normal_density(n));
    assert!((r.value[0] / (4.0 * PI * 1.7 * 1.7) - 1.0).abs() < 1e-12);

    // Spheroids with closed-form areas, and thin ones (the quadrature must resolve the peaks).
    let oblate = |a: f64, c: f64| {
        let e = (1.0 - c * c / (a * a)).sqrt();
        2.0 * PI * a * a * (1.0 + (1.0 - e * e) / e * e.atanh())
    };
    let prolate = |a: f64, c: f64| {
        let e = (1.0 - a * a / (c * c)).sqrt();
        2.0 * PI * a * a * (1.0 + c / (a * e) * e.asin())
    };
    let cases = [
        (
            Ellipsoid::spheroid(Vector3::new(1.0, 2.0, 3.0), 0.4, 1.0).unwrap(),
            oblate(1.0, 0.4),
        ),
        (
            Ellipsoid::spheroid(Vector3::new(-1.0, 0.2, 0.1), 0.02, 1.0).unwrap(),
            oblate(1.0, 0.02),
        ),
        (
            Ellipsoid::spheroid(Vector3::new(0.3, 1.0, 0.0), 2.0, 0.5).unwrap(),
            prolate(0.5, 2.0),
        ),
        (
            Ellipsoid::spheroid(Vector3::new(0.0, 1.0, 0.5), 1.0, 0.03).unwrap(),
            prolate(0.03, 1.0),
        ),
    ];
    for (e, area) in &cases {
        assert!(
            (e.surface_area() / area - 1.0).abs() < 1e-13,
            "Carlson vs closed form"
        );
        let r = quad(1e-8 * area).integrate_scalar(|n| e.normal_density(n));
        let rel = (r.value[0] / area - 1.0).abs();
        assert!(
            rel < 1e-6,
            "lengths {:?}: ∫f = {} vs {area} (rel {rel:e})",
            e.lengths(),
            r.value[0]
        );
    }

    // Triaxial, rotated: against the Carlson area.
    let e = triaxial(5, [1.3, 0.4, 0.07]);
    let area = e.surface_area();
    let r = quad(1e-8 * area).integrate_scalar(|n| e.normal_density(n));
    assert!((r.value[0] / area - 1.0).abs() < 1e-6);
}

#[test]
fn projected_area_matches_analytic_values() {
    // Along each principal axis: π l_j l_k.
    let e = triaxial(2, [2.0, 0.5, 0.1]);
    let l = e.lengths();
    for i in 0..3 {
        let axis = e.basis().column(i).into_owned();
        let expected = PI * l[(i + 1) % 3] * l[(i + 2) % 3];
        assert!((e.projected_area(&axis) / expected - 1.0).abs() < 1e-14);
    }
    // Any direction: the apparent ellipse's area π/√det K (independent construction from Q).
    let mut rng = SplitMix64::new(9);
    for _ in 0..100 {
        let v = rng.unit_vector();
        let (_, _, k) = e.apparent_ellipse(&v);
        let ellipse_area = PI / k.determinant().sqrt();
        assert!((e.projected_area(&v) / ellipse_area - 1.0).abs() < 1e-10);
    }
    // Mean over all directions is S/4 (Cauchy), and ∫ f_Q(n) max(0, n·ω) dn = A(ω).
    let r = quad(1e-10).integrate_scalar(|w| e.projected_area(w));
    assert!((r.value[0] / (4.0 * PI) / e.mean_projected_area() - 1.0).abs() < 1e-8);
    let omega = Vector3::new(0.3, -0.8, 0.52).normalize();
    let r = quad(1e-9).integrate_scalar(|n| e.normal_density(n) * n.dot(&omega).max(0.0));
    assert!((r.value[0] / e.projected_area(&omega) - 1.0).abs() < 1e-6);
}

#[test]
fn normalisation_is_the_unit_sphere_mean() {
    let e = triaxial(4, [5.0, 0.2, 1.0]).normalized().unwrap();
    let mean: f64 = (0..3)
        .map(|i| e.projected_area(&e.basis().column(i).into_owned()))
        .sum::<f64>()
        / 3.0;
    assert!((mean - PI).abs() < 1e-13);
    let s = Ellipsoid::sphere(3.0).unwrap().normalized().unwrap();
    assert!((s.lengths() - Vector3::repeat(1.0)).amax() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Reflectance: two independent methods.

/// Lambert sphere: `∫ max(0, n·l) max(0, n·v) dn = (2/3)(sin α + (π − α) cos α)`, α = angle(l, v).
fn lambert_sphere(alpha: f64, kd: f64) -> f64 {
    kd / PI * (2.0 / 3.0) * (alpha.sin() + (PI - alpha) * alpha.cos()) / PI
}

#[test]
fn reflectance_methods_agree_with_each_other_and_with_closed_form() {
    let q = SphereQuadrature {
        base: 12,
        max_depth: 8,
        tolerance: 1e-7,
    };
    let lambert = Phong {
        diffuse: 0.8,
        specular: 0.0,
        exponent: 0.0,
    };
    let sphere = Ellipsoid::sphere(1.0).unwrap();
    for alpha in [0.0f64, 0.7, 1.6, 2.5] {
        let l = Vector3::new(alpha.sin(), 0.0, alpha.cos());
        let v = Vector3::z();
        let exact = lambert_sphere(alpha, 0.8);
        let a = sphere
            .reflectance_normal_integral(&l, &v, &lambert, &q)
            .unwrap();
        let b = sphere
            .reflectance_apparent_ellipse(&l, &v, &lambert, 200)
            .unwrap();
        // The quadrature's depth cap bounds its error at the two kinks (n·l = 0, n·v = 0).
        assert!(
            (a - exact).abs() < 2e-5 * exact.max(0.05),
            "normal integral {a} vs {exact}"
        );
        assert!(
            (b - exact).abs() < 2e-4 * exact.max(0.05),
            "ellipse {b} vs {exact}"
        );
    }
    // Anisotropic ellipsoids with a Phong lobe: stated tolerance 1e-3 relative (the ellipse
    // sampler's midpoint rule is O(h²) at the terminator and the specular lobe's kink).
    let phong = Phong {
        diffuse: 0.6,
        specular: 0.4,
        exponent: 20.0,
    };
    let shapes = [
        triaxial(1, [1.0, 0.5, 0.2]),
        Ellipsoid::spheroid(Vector3::new(0.2, 1.0, 0.1), 0.05, 1.0).unwrap(),
        Ellipsoid::spheroid(Vector3::new(1.0, 0.1, 0.3), 1.0, 0.1).unwrap(),
    ];
    let mut rng = SplitMix64::new(21);
    for e in &shapes {
        for _ in 0..3 {
            let l = rng.unit_vector();
            let mut v = rng.unit_vector();
            if v.dot(&l) < -0.5 {
                v = -v;
            }
            let a = e.reflectance_normal_integral(&l, &v, &phong, &q).unwrap();
            let b = e.reflectance_apparent_ellipse(&l, &v, &phong, 200).unwrap();
            let tol = 1e-3 * a.abs().max(1e-2);
            assert!((a - b).abs() < tol, "lengths {:?}: {a} vs {b}", e.lengths());
        }
    }
}

#[test]
fn reflectance_rejects_bad_input() {
    let e = Ellipsoid::sphere(1.0).unwrap();
    let p = Phong {
        diffuse: f64::NAN,
        specular: 0.0,
        exponent: 1.0,
    };
    let z = Vector3::z();
    assert!(matches!(
        e.reflectance_apparent_ellipse(&z, &z, &p, 10),
        Err(EllipsoidError::BadParameter { .. })
    ));
    let ok = Phong {
        diffuse: 1.0,
        specular: 0.0,
        exponent: 1.0,
    };
    assert_eq!(
        e.reflectance_apparent_ellipse(&Vector3::zeros(), &z, &ok, 10),
        Err(EllipsoidError::BadDirection)
    );
}

// ---------------------------------------------------------------------------------------------
// Eigen-solver.

#[test]
fn eigen_adversarial_suite_f64_within_1e12() {
    let suite = adversarial_suite(1);
    assert!(suite.len() > 1000);
    for case in &suite {
        let e = sym_eigen3(&case.matrix).unwrap();
        let r = reconstruction_error(&case.matrix, &e);
        let o = orthogonality_error(&e);
        assert!(r <= 1e-12, "{}: reconstruction {r:e}", case.name);
        assert!(o <= 1e-12, "{}: orthogonality {o:e}", case.name);
        assert!(
            e.values[0] <= e.values[1] && e.values[1] <= e.values[2],
            "{}",
            case.name
        );
        // Eigenvalues agree with nalgebra's to 1e-13 of the largest entry.
        let reference = sym_eigen3_nalgebra(&case.matrix).unwrap();
        let scale = case.matrix.amax().max(f64::MIN_POSITIVE);
        assert!(
            (e.values - reference.values).amax() <= 1e-13 * scale,
            "{}: {:?} vs {:?}",
            case.name,
            e.values,
            reference.values
        );
    }
}

#[test]
fn eigen_adversarial_suite_f32_within_1e5() {
    for (name, m) in adversarial_suite_f32(2) {
        let e = sym_eigen3(&m).unwrap();
        assert!(reconstruction_error(&m, &e) <= 1e-5, "{name}");
        assert!(orthogonality_error(&e) <= 1e-5, "{name}");
    }
}

#[test]
fn eigen_exact_on_diagonal_and_multiples_of_identity() {
    let d = Matrix3::from_diagonal(&Vector3::new(1e-200, -4.0, 1e200));
    let e = sym_eigen3(&d).unwrap();
    assert_eq!(e.values, Vector3::new(-4.0, 1e-200, 1e200));
    assert_eq!(reconstruction_error(&d, &e), 0.0);
    let i = Matrix3::identity() * 2.5;
    let e = sym_eigen3(&i).unwrap();
    assert_eq!(e.values, Vector3::repeat(2.5));
    assert_eq!(e.vectors, Matrix3::identity());
}

#[test]
fn eigen_sign_and_order_convention() {
    let mut rng = SplitMix64::new(77);
    for _ in 0..100 {
        let r = rng.rotation();
        let a = r * Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 0.5)) * r.transpose();
        let e = sym_eigen3(&a).unwrap();
        assert!((e.values - Vector3::new(-1.0, 0.5, 3.0)).amax() < 1e-14);
        for i in 0..3 {
            let c = e.vectors.column(i);
            assert!(c[c.iamax()] > 0.0);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Filtering.

#[test]
fn filtering_identical_ellipsoids_returns_that_ellipsoid() {
    let mut rng = SplitMix64::new(3);
    for seed in 0..20 {
        let e = triaxial(
            seed,
            [
                rng.range(0.01, 3.0),
                rng.range(0.01, 3.0),
                rng.range(0.01, 3.0),
            ],
        );
        let k = 1 + (seed as usize % 7);
        let weights: Vec<f64> = (0..k).map(|_| rng.range(0.0, 2.0) + 1e-3).collect();
        for rule in FilterRule::ALL {
            let f = filter(&vec![e; k], &weights, rule).unwrap();
            let (q, qf) = (e.quadratic_form(), f.quadratic_form());
            assert!(
                (q - qf).amax() <= 1e-12 * q.amax(),
                "{rule:?} {:?} vs {:?}",
                e.lengths(),
                f.lengths()
            );
        }
    }
}

#[test]
fn filter_errors_vanish_for_identical_and_grow_with_angle() {
    let q = quad(1e-7);
    let case = FilterCase::rotated_pair(0.0).unwrap();
    for rule in FilterRule::ALL {
        let f = filter(&case.ellipsoids, &case.weights, rule).unwrap();
        let err = filter_errors(&case.ellipsoids, &case.weights, &f, &q).unwrap();
        assert!(
            err.l1_error < 1e-9 && err.area_error < 1e-9,
            "{rule:?} {err:?}"
        );
    }
    // Neyret 1995's worst case is worse than 30°, for both rules.
    for rule in FilterRule::ALL {
        let mut last = 0.0;
        for case in [
            FilterCase::rotated_pair(10f64.to_radians()).unwrap(),
            FilterCase::rotated_pair(30f64.to_radians()).unwrap(),
            FilterCase::orthogonal_pair().unwrap(),
        ] {
            let f = filter(&case.ellipsoids, &case.weights, rule).unwrap();
            let err = filter_errors(&case.ellipsoids, &case.weights, &f, &q).unwrap();
            assert!(err.l1_error > last, "{rule:?} {}", case.name);
            last = err.l1_error;
        }
    }
}

#[test]
fn seed_sin2_law_holds_for_both_rules() {
    let q = SphereQuadrature {
        base: 10,
        max_depth: 8,
        tolerance: 1e-7,
    };
    for rule in FilterRule::ALL {
        let fit = fit_sin2_exponent(rule, &[0.02, 0.05, 0.1], &q).unwrap();
        assert!(
            (fit.exponent - 1.0).abs() < 0.03,
            "{rule:?}: k = {}",
            fit.exponent
        );
    }
}

#[test]
fn sggx_turns_cylinder_pieces_into_a_cylinder_and_wins_every_case() {
    // Neyret 1995 says flat pieces tangent to a large cylinder filter into a cylinder-like
    // ellipsoid (long along the cylinder's axis y). Measured: true for the SGGX rule only.
    let case = FilterCase::cylinder_pieces(32).unwrap();
    let f = filter(&case.ellipsoids, &case.weights, FilterRule::Sggx).unwrap();
    let l = f.lengths();
    let long = l.imax();
    let axis = f.basis().column(long);
    assert!(axis.y.abs() > 1.0 - 1e-9, "long axis {axis:?}");
    assert!(
        l[long] > 5.0 * l[(long + 1) % 3] && l[long] > 5.0 * l[(long + 2) % 3],
        "{l:?}"
    );
    let f95 = filter(&case.ellipsoids, &case.weights, FilterRule::Seed1995).unwrap();
    assert!(
        f95.lengths().max() < 2.0 * f95.lengths().min(),
        "{:?}",
        f95.lengths()
    );

    let q = SphereQuadrature {
        base: 8,
        max_depth: 7,
        tolerance: 1e-4,
    };
    for case in FilterCase::standard(1).unwrap() {
        let mut errs = Vec::new();
        for rule in FilterRule::ALL {
            let f = filter(&case.ellipsoids, &case.weights, rule).unwrap();
            errs.push(filter_errors(&case.ellipsoids, &case.weights, &f, &q).unwrap());
        }
        assert!(errs[1].l1_error < errs[0].l1_error, "{}", case.name);
        assert!(errs[1].area_error < errs[0].area_error, "{}", case.name);
    }
}

#[test]
fn typed_errors_for_bad_ellipsoids_and_weights() {
    let v = |a, b, c| Vector3::new(a, b, c);
    assert!(matches!(
        Ellipsoid::axis_aligned(v(1.0, 0.0, 1.0)),
        Err(EllipsoidError::NonPositiveLength { axis: 1, .. })
    ));
    assert!(matches!(
        Ellipsoid::axis_aligned(v(1.0, 1.0, -2.0)),
        Err(EllipsoidError::NonPositiveLength { axis: 2, .. })
    ));
    assert!(matches!(
        Ellipsoid::axis_aligned(v(f64::NAN, 1.0, 1.0)),
        Err(EllipsoidError::NonFiniteLength { axis: 0, .. })
    ));
    assert!(matches!(
        Ellipsoid::axis_aligned(v(1.0, f64::INFINITY, 1.0)),
        Err(EllipsoidError::NonFiniteLength { axis: 1, .. })
    ));
    assert!(matches!(
        Ellipsoid::axis_aligned(v(1.0, 1.0, 1e-9)),
        Err(EllipsoidError::TooAnisotropic { .. })
    ));
    assert!(matches!(
        Ellipsoid::axis_aligned(v(1e60, 1e60, 1e60)),
        Err(EllipsoidError::LengthOutOfRange { .. })
    ));
    assert!(matches!(
        Ellipsoid::new(
            Matrix3::new(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            v(1.0, 1.0, 1.0)
        ),
        Err(EllipsoidError::NotOrthonormal { .. })
    ));
    let mut nan_q = Matrix3::identity();
    nan_q[(0, 2)] = f64::NAN;
    assert!(matches!(
        Ellipsoid::from_quadratic_form(&nan_q),
        Err(EllipsoidError::MatrixNotFinite { row: 0, col: 2, .. })
    ));
    assert!(matches!(
        Ellipsoid::from_quadratic_form(&Matrix3::from_diagonal(&v(1.0, -1.0, 1.0))),
        Err(EllipsoidError::NotPositiveDefinite { .. })
    ));
    let e = Ellipsoid::sphere(1.0).unwrap();
    assert_eq!(
        filter(&[e], &[0.0], FilterRule::Seed1995),
        Err(EllipsoidError::ZeroTotalWeight)
    );
    assert!(matches!(
        filter(&[e], &[f64::INFINITY], FilterRule::Sggx),
        Err(EllipsoidError::BadWeight { .. })
    ));
    assert_eq!(
        Ellipsoid::spheroid(Vector3::zeros(), 1.0, 1.0),
        Err(EllipsoidError::BadDirection)
    );
}

// ---------------------------------------------------------------------------------------------
// Property tests.

fn arb_ellipsoid() -> impl Strategy<Value = Ellipsoid> {
    (any::<u64>(), -3.0f64..3.0, -2.9f64..0.0, -2.9f64..0.0).prop_map(|(seed, s, a, b)| {
        let big = 10f64.powf(s);
        let r = SplitMix64::new(seed).rotation();
        Ellipsoid::new(
            r,
            Vector3::new(big, big * 10f64.powf(a), big * 10f64.powf(b)),
        )
        .unwrap()
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(20261204), ..ProptestConfig::default() })]

    #[test]
    fn filter_never_panics_or_returns_nan(
        es in prop::collection::vec(arb_ellipsoid(), 1..12),
        ws in prop::collection::vec(0.0f64..10.0, 12),
        rule in prop_oneof![Just(FilterRule::Seed1995), Just(FilterRule::Sggx)],
    ) {
        let w = &ws[..es.len()];
        match filter(&es, w, rule) {
            Ok(f) => {
                prop_assert!(f.lengths().iter().all(|l| l.is_finite() && *l > 0.0));
                prop_assert!(f.basis().iter().all(|x| x.is_finite()));
            }
            Err(e) => prop_assert_eq!(e, EllipsoidError::ZeroTotalWeight),
        }
    }

    #[test]
    fn filter_rejects_bad_weights(
        es in prop::collection::vec(arb_ellipsoid(), 1..6),
        bad in prop_oneof![Just(f64::NAN), Just(-1.0), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
        at in 0usize..6,
    ) {
        let mut w = vec![1.0; es.len()];
        let i = at % es.len();
        w[i] = bad;
        let typed = matches!(filter(&es, &w, FilterRule::Sggx), Err(EllipsoidError::BadWeight { index, .. }) if index == i);
        prop_assert!(typed);
        let zeros = vec![0.0; es.len()];
        prop_assert_eq!(filter(&es, &zeros, FilterRule::Seed1995), Err(EllipsoidError::ZeroTotalWeight));
    }

    #[test]
    fn bad_lengths_are_typed_errors(
        good in 0.1f64..10.0,
        bad in prop_oneof![Just(0.0), Just(-0.0), -1e10f64..-1e-300, Just(f64::NAN), Just(f64::INFINITY)],
        axis in 0usize..3,
    ) {
        let mut l = Vector3::repeat(good);
        l[axis] = bad;
        let r = Ellipsoid::axis_aligned(l);
        let typed = matches!(r,
            Err(EllipsoidError::NonPositiveLength { axis: a, .. }) | Err(EllipsoidError::NonFiniteLength { axis: a, .. }) if a == axis);
        prop_assert!(typed);
    }

    #[test]
    fn eigen_never_panics_and_reconstructs(
        entries in prop::array::uniform6(-1.0f64..1.0),
        exps in prop::array::uniform6(-40i32..40),
        scale in -150i32..150,
    ) {
        let v: Vec<f64> = entries.iter().zip(exps).map(|(x, e)| x * 10f64.powi(e / 4)).collect();
        let m = Matrix3::new(v[0], v[1], v[2], v[1], v[3], v[4], v[2], v[4], v[5]) * 10f64.powi(scale);
        let e = sym_eigen3(&m).unwrap();
        prop_assert!(e.values.iter().all(|x| x.is_finite()));
        prop_assert!(reconstruction_error(&m, &e) <= 1e-12);
        prop_assert!(orthogonality_error(&e) <= 1e-12);
        let e32 = sym_eigen3(&m.map(|x| (x * 10f64.powi(-scale)) as f32)).unwrap();
        prop_assert!(e32.values.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn eigen_rejects_non_finite(
        pos in 0usize..6,
        bad in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
    ) {
        let idx = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)][pos];
        let mut m = Matrix3::identity();
        m[idx] = bad;
        let err = sym_eigen3(&m).unwrap_err();
        let typed = matches!(err, EllipsoidError::MatrixNotFinite { row, col, .. } if (row, col) == idx);
        prop_assert!(typed);
    }
}

// ---------------------------------------------------------------------------------------------
// Octree.

fn small_sphere(n: usize) -> AnalyticVolume {
    let mut v = AnalyticVolume::sphere_torus(n);
    v.shapes.truncate(1);
    v
}

#[test]
fn octree_root_is_the_filter_of_all_voxels() {
    let vol = AnalyticVolume::sphere_torus(24); // not a power of two: padded to 32
    let grid = VoxelGrid::from_source(&vol).unwrap();
    for rule in FilterRule::ALL {
        let params = OctreeParams {
            rule,
            tolerance: 0.0,
            ..Default::default()
        };
        let (tree, report) = Octree::build(&grid, &params).unwrap();
        assert_eq!(report.depth, 5);
        // Density: mean over the padded cube; colour: density-weighted mean.
        let mut rho = 0.0;
        let mut col = [0.0f64; 3];
        let mut ellipsoids = Vec::new();
        let mut weights = Vec::new();
        for z in 0..24 {
            for y in 0..24 {
                for x in 0..24 {
                    let v = grid.voxel(x, y, z);
                    if v.density > 0.0 {
                        let d = f64::from(v.density);
                        rho += d;
                        for (c, vc) in col.iter_mut().zip(v.color) {
                            *c += d * f64::from(vc);
                        }
                        let leaf = tree
                            .lookup([x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5], 0)
                            .unwrap();
                        ellipsoids.push(leaf.ellipsoid.unwrap());
                        weights.push(d);
                    }
                }
            }
        }
        let root = tree.nodes()[0];
        assert!((f64::from(root.density) - rho / 32f64.powi(3)).abs() < 1e-6);
        for (rc, c) in root.color.iter().zip(col) {
            assert!((f64::from(*rc) - c / rho).abs() < 1e-5);
        }
        let expected = filter(&ellipsoids, &weights, rule).unwrap();
        let got = tree.lookup([1.0, 1.0, 1.0], tree.depth()).unwrap();
        assert_eq!(got.level, 5);
        let (q1, q2) = (
            expected.quadratic_form(),
            got.ellipsoid.unwrap().quadratic_form(),
        );
        assert!((q1 - q2).amax() < 1e-4 * q1.amax(), "{rule:?}");
    }
}

#[test]
fn octree_leaves_follow_the_surface_and_uniform_regions_prune() {
    let vol = small_sphere(32);
    let (tree, report) = Octree::build(&vol, &OctreeParams::default()).unwrap();
    assert!(report.compression > 0.5, "{report:?}");
    assert_eq!(report.nodes, tree.nodes().len());
    assert_eq!(report.nodes_per_level.iter().sum::<usize>(), report.nodes);
    // A surface voxel: flat ellipsoid whose short axis is the normal.
    let p = [16.0 + 7.9 * 0.6, 16.0 + 7.9 * 0.8, 16.5];
    let leaf = tree.lookup(p, 0).unwrap();
    assert_eq!(leaf.level, 0);
    let e = leaf.ellipsoid.unwrap();
    let short = e.basis().column(e.lengths().imin()).into_owned();
    let normal = Vector3::new(p[0] - 16.0, p[1] - 16.0, 0.0).normalize();
    assert!(short.dot(&normal).abs() > 0.95, "{short:?} vs {normal:?}");
    // Deep inside and far outside: pruned leaves above level 0.
    let inside = tree.lookup([16.0, 16.0, 16.0], 0).unwrap();
    assert!(inside.level > 0 && inside.density == 1.0);
    let outside = tree.lookup([0.5, 0.5, 0.5], 0).unwrap();
    assert!(outside.level > 0 && outside.density == 0.0 && outside.ellipsoid.is_none());
    // Empty and full volumes: one node.
    for v in [0.0f32, 1.0] {
        let n = 16 * 16 * 16;
        let grid = VoxelGrid::new([16; 3], vec![v; n], vec![[0.5; 3]; n], vec![None; n]).unwrap();
        let (t, r) = Octree::build(&grid, &OctreeParams::default()).unwrap();
        assert_eq!((t.nodes().len(), r.nodes), (1, 1));
    }
}

#[test]
fn octree_level_lookup_by_footprint() {
    let (tree, _) = Octree::build(&small_sphere(32), &OctreeParams::default()).unwrap();
    assert_eq!(tree.depth(), 5);
    assert_eq!(tree.level_for_footprint(0.3), 0);
    assert_eq!(tree.level_for_footprint(f64::NAN), 0);
    assert_eq!(tree.level_for_footprint(1.0), 0);
    assert_eq!(tree.level_for_footprint(2.0), 1);
    assert_eq!(tree.level_for_footprint(5.0), 2);
    assert_eq!(tree.level_for_footprint(1e9), 5);
    let s = tree
        .lookup_footprint([16.0 + 7.9, 16.0, 16.0], 4.0)
        .unwrap();
    assert_eq!(s.level, 2);
    assert!(tree.lookup([-1.0, 0.0, 0.0], 0).is_none());
    assert!(tree.lookup([f64::NAN, 0.0, 0.0], 0).is_none());
    assert!(tree.lookup([32.0, 0.0, 0.0], 0).is_none());
}

#[test]
fn octree_rejects_bad_volumes() {
    let n = 8 * 8 * 8;
    assert!(matches!(
        VoxelGrid::new([8; 3], vec![0.0; n - 1], vec![[0.0; 3]; n], vec![None; n]),
        Err(EllipsoidError::BadVolume(_))
    ));
    let mut density = vec![0.0f32; n];
    density[3 + 8 * (2 + 8)] = f32::NAN;
    let grid = VoxelGrid::new([8; 3], density, vec![[0.0; 3]; n], vec![None; n]).unwrap();
    match Octree::build(&grid, &OctreeParams::default()) {
        Err(EllipsoidError::BadVolume(msg)) => assert!(msg.contains("(3, 2, 1)"), "{msg}"),
        other => panic!("{other:?}"),
    }
    let mut normal = vec![None; n];
    normal[0] = Some([0.0f32; 3]);
    let grid = VoxelGrid::new([8; 3], vec![0.5; n], vec![[0.0; 3]; n], normal).unwrap();
    assert!(matches!(
        Octree::build(&grid, &OctreeParams::default()),
        Err(EllipsoidError::BadVolume(_))
    ));
    let params = OctreeParams {
        leaf_flatness: 0.0,
        ..Default::default()
    };
    assert!(matches!(
        Octree::build(&small_sphere(8), &params),
        Err(EllipsoidError::BadParameter { .. })
    ));
    assert_eq!(Voxel::EMPTY.density, 0.0);
}

#[test]
fn rotating_a_pair_rotates_the_filter() {
    // Filtering commutes with rotations (both rules are equivariant).
    let case = FilterCase::rotated_pair(0.6).unwrap();
    let rot = rotation_about(&Vector3::new(1.0, 2.0, -1.0), 1.1);
    for rule in FilterRule::ALL {
        let f = filter(&case.ellipsoids, &case.weights, rule).unwrap();
        let rotated: Vec<Ellipsoid> = case
            .ellipsoids
            .iter()
            .map(|e| rotate(e, &rot).unwrap())
            .collect();
        let g = filter(&rotated, &case.weights, rule).unwrap();
        let expected = rot * f.quadratic_form() * rot.transpose();
        assert!((g.quadratic_form() - expected).amax() < 1e-12 * expected.amax());
    }
}

#[test]
fn octree_from_data_gen_volume_and_periodic_interiors() {
    use altrep_data_gen::{VoxelParams, scene_shape, voxelize};
    let shape = scene_shape("sphere").unwrap();
    let vp = VoxelParams {
        dims: [24; 3],
        min: glam::DVec3::new(-1.0, 0.0, -1.0),
        max: glam::DVec3::new(1.0, 2.0, 1.0),
        periodic: [false; 3],
        supersample: Supersample::ONE,
        fill: altrep_data_gen::Fill::Solid,
    };
    let vol = voxelize(&shape, &vp).unwrap();
    let (tree, report) = Octree::build(&vol, &OctreeParams::default()).unwrap();
    assert!(report.compression > 0.3, "{report:?}");
    let mean: f64 = vol.density.iter().map(|&d| f64::from(d)).sum::<f64>() / 32f64.powi(3);
    assert!((f64::from(tree.nodes()[0].density) - mean).abs() < 1e-6);
    // The centre is inside the solid: isotropic micro-primitive (the sphere's colour is striped
    // by azimuth, so the interior does not prune here).
    let centre = tree.lookup([12.0, 12.0, 12.0], 0).unwrap();
    assert!(centre.density == 1.0);
    let l = centre.ellipsoid.unwrap().lengths().into_owned();
    assert!(l.max() / l.min() < 1.0 + 1e-5, "{l:?}");

    // A full volume whose every voxel carries a normal: interior everywhere only when periodic.
    struct Full(bool);
    impl VoxelSource for Full {
        fn dims(&self) -> [usize; 3] {
            [4; 3]
        }
        fn voxel(&self, _: usize, _: usize, _: usize) -> Voxel {
            Voxel {
                density: 1.0,
                color: [0.3; 3],
                normal: Some([0.0, 1.0, 0.0]),
            }
        }
        fn periodic(&self) -> [bool; 3] {
            [self.0; 3]
        }
    }
    let (t, _) = Octree::build(&Full(true), &OctreeParams::default()).unwrap();
    assert_eq!(t.nodes().len(), 1);
    let (t, _) = Octree::build(&Full(false), &OctreeParams::default()).unwrap();
    assert!(t.nodes().len() > 1);
}

#[test]
fn ellipsoid_bench_cli_writes_the_json_keys() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_altrep"))
        .args([
            "ellipsoid-bench",
            "--sections",
            "eigen,octree",
            "--batches",
            "1",
            "--sizes",
            "16",
            "--volumes",
            "lawn,sphere",
            "--json",
        ])
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let eigen = v["eigen"].as_array().unwrap();
    assert_eq!(eigen.len(), 4);
    for row in eigen {
        for key in [
            "method",
            "ns_per_op",
            "worst_reconstruction",
            "worst_orthogonality",
        ] {
            assert!(!row[key].is_null(), "eigen.{key}");
        }
    }
    assert!(v["filter"].as_array().unwrap().is_empty());
    assert!(v["sin2_exponent"].is_object());
    let octree = v["octree"].as_array().unwrap();
    assert_eq!(octree.len(), 2);
    for key in ["volume", "nodes", "compression", "build_seconds", "bytes"] {
        assert!(!octree[0][key].is_null(), "octree.{key}");
    }
    // Bad input: an unknown volume is an error message, not a panic.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_altrep"))
        .args([
            "ellipsoid-bench",
            "--sections",
            "octree",
            "--sizes",
            "8",
            "--volumes",
            "nope",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope"));
}
