//! Capture against analytic geometry: depths, normals and definedness of views and cylindrical
//! textures of spheres and boxes, and bad input.

use std::f64::consts::TAU;

use altrep_data_gen::{
    Albedo, BoundingCylinder, Csg, CylinderParams, DataGenError, Light, Part, Primitive, Shape,
    Supersample, TruthParams, ViewParams, capture_cylinder, capture_view, direction, render_truth,
    screen_right,
};
use glam::{DVec3, Vec3};

fn one(primitive: Primitive) -> Csg {
    Csg::new(
        "test",
        vec![Part {
            primitive,
            albedo: Albedo::Solid(Vec3::splat(0.5)),
        }],
    )
    .unwrap()
}

/// Tolerance on depth, in units of the pixel pitch: the analytic intersections are exact to
/// rounding, so a millionth of a pixel is ample.
const DEPTH_TOL_PIXELS: f64 = 1e-6;
/// Tolerance on normals (radians, about): the same.
const NORMAL_TOL: f64 = 1e-6;

#[test]
fn sphere_view_depth_and_normal_are_analytic() {
    let c = DVec3::new(0.2, 1.0, -0.15);
    let rho = 0.6;
    let shape = one(Primitive::Sphere {
        center: c,
        radius: rho,
    });
    for &alpha in &[0.0, 0.7, 2.0, -1.3] {
        let view = capture_view(
            &shape,
            &ViewParams {
                angle: alpha,
                width: 48,
                height: 40,
                cylinder: BoundingCylinder::default(),
            },
        )
        .unwrap();
        let grid = view.pixel_grid();
        let (d, right) = (direction(alpha), screen_right(alpha));
        let mut defined = 0;
        for j in 0..view.height {
            for i in 0..view.width {
                let (x, y) = grid.center(i, j);
                // Distance of the pixel's line (direction d) from the centre.
                let q = x * right + DVec3::Y * y - c;
                let perp2 = (q - d * q.dot(d)).length_squared();
                let s = view.get(i, j);
                if perp2 >= rho * rho {
                    assert!(s.is_none(), "pixel ({i},{j}) at α={alpha} should miss");
                    continue;
                }
                let s = s.unwrap_or_else(|| panic!("pixel ({i},{j}) at α={alpha} should hit"));
                defined += 1;
                let depth = c.dot(d) + (rho * rho - perp2).sqrt();
                let err = (f64::from(s.depth) - depth).abs() / grid.pitch_x();
                assert!(
                    err < DEPTH_TOL_PIXELS + 1e-7 / grid.pitch_x(),
                    "depth error {err} px at ({i},{j})"
                );
                let p = x * right + DVec3::Y * y + depth * d;
                let n = ((p - c) / rho).as_vec3();
                assert!(
                    (s.normal - n).length() < NORMAL_TOL as f32 + 1e-6,
                    "normal {:?} vs {n:?}",
                    s.normal
                );
            }
        }
        assert!(defined > 200, "sphere covers too few pixels: {defined}");
    }
}

#[test]
fn box_view_depth_and_normal_are_analytic() {
    // A box turned by yaw shows one face to the view at α = −yaw (its local +x axis is d(−yaw)).
    let (c, h, yaw) = (DVec3::new(0.1, 0.9, 0.05), DVec3::new(0.3, 0.5, 0.4), 0.35);
    let shape = one(Primitive::Box {
        center: c,
        half: h,
        yaw,
    });
    let alpha = -yaw;
    let view = capture_view(
        &shape,
        &ViewParams {
            angle: alpha,
            width: 64,
            height: 64,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let grid = view.pixel_grid();
    let (d, right) = (direction(alpha), screen_right(alpha));
    let (mut hits, mut misses) = (0, 0);
    for j in 0..view.height {
        for i in 0..view.width {
            let (x, y) = grid.center(i, j);
            // Screen coordinates of the face: lateral offset along `right`, height along y.
            let lateral = x - c.dot(right);
            let inside = lateral.abs() < h.z && (y - c.y).abs() < h.y;
            match (inside, view.get(i, j)) {
                (true, Some(s)) => {
                    hits += 1;
                    let depth = c.dot(d) + h.x;
                    let err = (f64::from(s.depth) - depth).abs() / grid.pitch_x();
                    assert!(
                        err < DEPTH_TOL_PIXELS + 1e-7 / grid.pitch_x(),
                        "depth error {err} px"
                    );
                    assert!(
                        (s.normal - d.as_vec3()).length() < 1e-6,
                        "normal {:?}",
                        s.normal
                    );
                }
                (false, None) => misses += 1,
                (inside, s) => panic!("pixel ({i},{j}): inside={inside} but sample {s:?}"),
            }
        }
    }
    assert!(hits > 500 && misses > 500, "hits {hits} misses {misses}");
}

#[test]
fn cylinder_capture_of_a_sphere_on_the_axis() {
    let shape = one(Primitive::Sphere {
        center: DVec3::new(0.0, 1.0, 0.0),
        radius: 1.0,
    });
    let cap = capture_cylinder(&shape, &CylinderParams::default()).unwrap();
    let grid = cap.pixel_grid();
    for j in 0..cap.height {
        let y = grid.y_at(j as f64 + 0.5);
        let expected = (1.0 - (y - 1.0).powi(2)).sqrt();
        for i in 0..cap.width {
            let s = cap
                .get(i, j)
                .expect("every ray crosses the axis inside the sphere");
            assert!(
                (f64::from(s.depth) - expected).abs() < 1e-6,
                "row {j}: r={} expected {expected}",
                s.depth
            );
        }
    }
    // At the equator rows the radius is 1 (to the half-row offset).
    let mid = cap.get(0, cap.height / 2).unwrap().depth;
    assert!((mid - 1.0).abs() < 1e-3, "equator radius {mid}");
}

#[test]
fn cylinder_capture_of_a_sphere_off_the_axis_has_negative_radii_where_geometry_says() {
    let c = DVec3::new(0.5, 1.0, 0.1);
    let rho = 0.3;
    let shape = one(Primitive::Sphere {
        center: c,
        radius: rho,
    });
    let params = CylinderParams {
        columns: 180,
        rows: 32,
        cylinder: BoundingCylinder::default(),
    };
    let cap = capture_cylinder(&shape, &params).unwrap();
    let grid = cap.pixel_grid();
    let (mut pos, mut neg, mut undef) = (0, 0, 0);
    for j in 0..cap.height {
        let y = grid.y_at(j as f64 + 0.5);
        let rho_y2 = rho * rho - (y - c.y).powi(2);
        for i in 0..cap.width {
            let d = direction(TAU * i as f64 / cap.width as f64);
            let ch = DVec3::new(c.x, 0.0, c.z);
            let perp2 = (ch - d * ch.dot(d)).length_squared();
            let s = cap.get(i, j);
            if rho_y2 <= 0.0 || perp2 >= rho_y2 {
                assert!(s.is_none(), "column {i} row {j} should be undefined");
                undef += 1;
                continue;
            }
            // The ray comes from +d: the first hit is the root with the larger coordinate.
            let r = ch.dot(d) + (rho_y2 - perp2).sqrt();
            let s = s.unwrap_or_else(|| panic!("column {i} row {j} should hit"));
            assert!(
                (f64::from(s.depth) - r).abs() < 1e-6,
                "column {i} row {j}: {} vs {r}",
                s.depth
            );
            if r < 0.0 {
                neg += 1;
            } else {
                pos += 1;
            }
        }
    }
    assert!(
        pos > 50 && neg > 50 && undef > 1000,
        "pos {pos} neg {neg} undef {undef}"
    );
}

#[test]
fn truth_alpha_is_coverage_and_colour_is_shaded() {
    let shape = one(Primitive::Sphere {
        center: DVec3::new(0.0, 1.0, 0.0),
        radius: 0.5,
    });
    let light = Light::default();
    let img = render_truth(
        &shape,
        &TruthParams {
            angle: 0.3,
            width: 32,
            height: 32,
            supersample: Supersample::of(4),
            light,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    // Coverage: the disk of radius 0.5 over a 2×2 square → π/16 of the image.
    let alpha: f32 = img.pixels.iter().map(|p| p[3]).sum::<f32>() / (32.0 * 32.0);
    let expected = std::f32::consts::PI * 0.25 / 4.0;
    assert!(
        (alpha - expected).abs() < 0.01,
        "coverage {alpha} vs {expected}"
    );
    // Premultiplied: colour never exceeds alpha × max albedo.
    assert!(img.pixels.iter().all(|p| p[0] <= p[3] * 0.5 + 1e-6));
}

#[test]
fn zero_sizes_and_bad_parameters_are_typed_errors() {
    let shape = one(Primitive::Sphere {
        center: DVec3::new(0.0, 1.0, 0.0),
        radius: 0.5,
    });
    let cyl = BoundingCylinder::default();
    let e = capture_view(
        &shape,
        &ViewParams {
            angle: 0.0,
            width: 0,
            height: 8,
            cylinder: cyl,
        },
    );
    assert!(
        matches!(
            e,
            Err(DataGenError::ZeroSize {
                what: "capture width"
            })
        ),
        "{e:?}"
    );
    let e = capture_view(
        &shape,
        &ViewParams {
            angle: f64::NAN,
            width: 8,
            height: 8,
            cylinder: cyl,
        },
    );
    assert!(matches!(e, Err(DataGenError::NonFinite { .. })), "{e:?}");
    let e = capture_cylinder(
        &shape,
        &CylinderParams {
            columns: 8,
            rows: 0,
            cylinder: cyl,
        },
    );
    assert!(matches!(e, Err(DataGenError::ZeroSize { .. })), "{e:?}");
    let bad = BoundingCylinder {
        radius: -1.0,
        height: 2.0,
    };
    let e = capture_cylinder(
        &shape,
        &CylinderParams {
            columns: 8,
            rows: 8,
            cylinder: bad,
        },
    );
    assert!(
        matches!(e, Err(DataGenError::InvalidParameter { .. })),
        "{e:?}"
    );
    // A zero supersampling factor cannot be made: the type refuses it.
    assert_eq!(Supersample::new(0), None);
    assert!(matches!(
        altrep_data_gen::scene_shape("nope"),
        Err(DataGenError::UnknownShape { .. })
    ));
}

#[test]
fn scene_shapes_fit_the_cylinder_and_are_seen() {
    for name in altrep_data_gen::SCENE_SHAPES {
        let shape = altrep_data_gen::scene_shape(name).unwrap();
        let (lo, hi) = shape.bounds();
        assert!(lo.y >= 0.0 && hi.y <= 2.0, "{name}: y range {lo:?} {hi:?}");
        let view = capture_view(
            &shape,
            &ViewParams {
                angle: 0.5,
                width: 32,
                height: 32,
                cylinder: BoundingCylinder::default(),
            },
        )
        .unwrap();
        let cov = view.coverage();
        assert!(cov > 0.05 && cov < 0.9, "{name}: coverage {cov}");
        // Every defined sample lies inside the cylinder.
        assert!(
            view.samples.iter().flatten().all(|s| s.depth.abs() <= 1.0),
            "{name}"
        );
    }
}

#[test]
fn torus_is_hit_where_its_sdf_vanishes() {
    let shape = one(Primitive::Torus {
        center: DVec3::new(0.0, 1.0, 0.0),
        axis: DVec3::Z,
        major: 0.6,
        minor: 0.2,
    });
    let view = capture_view(
        &shape,
        &ViewParams {
            angle: 0.4,
            width: 40,
            height: 40,
            cylinder: BoundingCylinder::default(),
        },
    )
    .unwrap();
    let grid = view.pixel_grid();
    let (d, right) = (direction(0.4), screen_right(0.4));
    let mut n = 0;
    for j in 0..40 {
        for i in 0..40 {
            if let Some(s) = view.get(i, j) {
                let (x, y) = grid.center(i, j);
                let p = x * right + DVec3::Y * y + f64::from(s.depth) * d;
                let sdf = shape.sdf(p).unwrap();
                assert!(sdf.abs() < 1e-6, "sdf {sdf} at ({i},{j})");
                n += 1;
            }
        }
    }
    assert!(n > 100);
}
