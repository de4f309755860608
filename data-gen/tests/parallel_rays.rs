//! Orthographic captures and ground truths traced as grids of parallel rays
//! (`Shape::parallel_tracer`: a mesh bins its triangles over grids with at least 3/4 as many
//! rays as it has triangles) against the same images traced ray by ray through the BVH
//! (`Shape::intersect`), on a generated mesh and on the shipped meshes of
//! `../shared/data/meshes` (at these sizes the Stanford bunny walks everywhere and the rocker arm
//! is binned for its 17 k-ray truths only). Without that folder the torus is still checked and
//! the meshes' part is skipped with a visible message, a failure under `CI=true`
//! (`altrep_data_gen::skip`).

use altrep_data_gen::{
    BoundingCylinder, Light, Mesh, MeshLoadOptions, OrthoFrame, ParallelRays, Ray, RayByRay,
    RgbaImage, SCENE_SHAPES, Sample, Shape, Supersample, TruthParams, ViewParams, capture_frame,
    capture_view, intersect_parallel, render_silhouette, render_truth, render_truth_frame,
    scene_shape, shared_meshes,
};
use glam::DVec3;

/// A torus of `n × 2n` quads, tilted so that no edge lies in an axis plane.
fn torus(n: usize) -> Mesh {
    let p = |a: usize, b: usize| {
        let (u, v) = (
            std::f64::consts::TAU * a as f64 / n as f64,
            std::f64::consts::TAU * b as f64 / (2 * n) as f64,
        );
        let (r, q) = (1.0 + 0.4 * u.cos(), 0.4 * u.sin());
        let (x, y, z) = (r * v.cos(), q, r * v.sin());
        [x, 0.8 * y + 0.6 * z, -0.6 * y + 0.8 * z]
    };
    let mut tris = Vec::new();
    for a in 0..n {
        for b in 0..2 * n {
            tris.push([p(a, b), p(a + 1, b), p(a + 1, b + 1)]);
            tris.push([p(a, b), p(a + 1, b + 1), p(a, b + 1)]);
        }
    }
    Mesh::from_raw_triangles("torus", tris, &MeshLoadOptions::default()).unwrap()
}

/// Pixels where two captures differ (ties: two triangles met at the same `f32` distance); panics
/// where one tracer hits and the other does not, or where their depths differ (the grid tracer
/// finds the walk's nearest distance bitwise, and the walk's padded boxes keep every hit).
fn sample_differences(grid: &[Option<Sample>], walk: &[Option<Sample>]) -> usize {
    let mut differ = 0;
    for (k, (g, w)) in grid.iter().zip(walk).enumerate() {
        match (g, w) {
            (Some(g), Some(w)) => {
                assert_eq!(
                    g.depth.to_bits(),
                    w.depth.to_bits(),
                    "pixel {k}: depth {} on the grid, {} walked",
                    g.depth,
                    w.depth
                );
                differ += usize::from(g != w);
            }
            (None, None) => {}
            (g, w) => panic!(
                "pixel {k}: a hit on the grid: {}, walked: {}",
                g.is_some(),
                w.is_some()
            ),
        }
    }
    differ
}

/// Pixels where two images differ.
fn pixel_differences(a: &RgbaImage, b: &RgbaImage) -> usize {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(a, b)| a != b)
        .count()
}

#[test]
fn grid_captures_and_truths_are_those_of_the_ray_by_ray_walk() {
    let mut meshes = vec![torus(12)];
    meshes.extend(shared_meshes("the shipped meshes"));
    let cylinder = BoundingCylinder::default();
    for mesh in &meshes {
        let walk = RayByRay(mesh);
        let (mut differ, mut pixels) = (0, 0);
        for angle in [0.0, 0.9, std::f64::consts::FRAC_PI_2, 4.0] {
            let view = ViewParams {
                angle,
                width: 128,
                height: 96,
                cylinder,
            };
            let (g, w) = (
                capture_view(mesh, &view).unwrap(),
                capture_view(&walk, &view).unwrap(),
            );
            differ += sample_differences(&g.samples, &w.samples);
            pixels += g.samples.len();
            let truth = TruthParams {
                angle,
                width: 48,
                height: 40,
                supersample: Supersample::of(3),
                light: Light::default(),
                cylinder,
            };
            let (g, w) = (
                render_truth(mesh, &truth).unwrap(),
                render_truth(&walk, &truth).unwrap(),
            );
            differ += pixel_differences(&g, &w);
            pixels += g.pixels.len();
        }
        let (centre, radius) = OrthoFrame::bounding_sphere(mesh);
        for dir in [DVec3::new(0.3, 0.9, -0.2), DVec3::NEG_Y] {
            let frame = OrthoFrame::new(centre, radius, dir).unwrap();
            let (g, w) = (
                capture_frame(mesh, &frame, 100, 100).unwrap(),
                capture_frame(&walk, &frame, 100, 100).unwrap(),
            );
            differ += sample_differences(&g.samples, &w.samples);
            pixels += g.samples.len();
            let light = Light::default();
            let (g, w) = (
                render_truth_frame(mesh, &frame, 50, 50, Supersample::of(2), &light).unwrap(),
                render_truth_frame(&walk, &frame, 50, 50, Supersample::of(2), &light).unwrap(),
            );
            differ += pixel_differences(&g, &w);
            pixels += g.pixels.len();
        }
        eprintln!(
            "{}: {differ} of {pixels} pixels differ from the walk",
            mesh.name()
        );
        // Ties between triangles (rays through a shared edge) are rare.
        assert!(
            differ * 100 <= pixels,
            "{}: {differ} of {pixels} pixels differ",
            mesh.name()
        );
    }
}

/// The silhouette alone (`render_silhouette`: occlusion rays, no shading, a mesh's walk stops at
/// the first triangle) is bitwise the truth's alpha: on meshes traced binned and walked, the
/// same meshes ray by ray, and the procedural scene shapes; at the coverage check's size and at
/// sizes that bin the torus.
#[test]
fn silhouettes_are_the_truths_alpha_bitwise() {
    let mut meshes = vec![torus(12), torus(40)];
    meshes.extend(shared_meshes("the shipped meshes"));
    let procedural: Vec<_> = SCENE_SHAPES
        .iter()
        .map(|n| scene_shape(n).unwrap())
        .collect();
    let walks: Vec<_> = meshes.iter().map(|m| RayByRay(m)).collect();
    let shapes = meshes
        .iter()
        .map(|m| m as &dyn Shape)
        .chain(walks.iter().map(|w| w as &dyn Shape))
        .chain(procedural.iter().map(|c| c as &dyn Shape));
    let (mut pixels, mut covered) = (0, 0);
    for shape in shapes {
        for (angle, size, k) in [
            (0.37, 48, 2),
            (std::f64::consts::FRAC_PI_2, 64, 3),
            (2.5, 33, 1),
        ] {
            let params = TruthParams {
                angle,
                width: size,
                height: size + 7,
                supersample: Supersample::of(k),
                light: Light::default(),
                cylinder: BoundingCylinder::default(),
            };
            let truth = render_truth(shape, &params).unwrap();
            let alpha = render_silhouette(shape, &params).unwrap();
            assert_eq!(alpha.len(), truth.pixels.len());
            for (i, (a, p)) in alpha.iter().zip(&truth.pixels).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    p[3].to_bits(),
                    "{} at {angle}: pixel {i}: silhouette {a}, truth alpha {}",
                    shape.name(),
                    p[3]
                );
            }
            pixels += alpha.len();
            covered += alpha.iter().filter(|&&a| a > 0.0).count();
        }
    }
    // Not a vacuous comparison: a good share of the pixels are covered.
    assert!(
        covered * 10 >= pixels,
        "{covered} of {pixels} pixels covered"
    );
}

/// The public grid entry point on a hand-made grid (uneven columns, ascending rows, a tilted
/// direction): the same hit distances as the walk, and a grid whose rays leave their declared
/// positions still gets every hit.
#[test]
fn intersect_parallel_on_a_hand_made_grid() {
    let mesh = torus(10);
    let walk = RayByRay(&mesh);
    let dir = DVec3::new(-0.6, -0.3, -0.74).normalize();
    let right = DVec3::Y.cross(-dir).normalize();
    let up = (-dir).cross(right);
    let columns: Vec<f64> = (0..70)
        .map(|i| -1.2 + 2.4 * (i as f64 / 69.0).powf(1.3))
        .collect();
    let rows: Vec<f64> = (0..50).map(|j| -0.2 + 2.4 * j as f64 / 49.0).collect();
    for shift in [0.0, 0.05] {
        let ray = |c: usize, r: usize| {
            let x = columns[c] + if c.is_multiple_of(7) { shift } else { 0.0 };
            Ray::new(x * right + rows[r] * up - 3.0 * dir, dir)
        };
        let rays = ParallelRays {
            dir,
            across: [right, up],
            columns: &columns,
            rows: &rows,
            t_min: 0.0,
            t_max: 8.0,
            ray: &ray,
        };
        let (g, w) = (
            intersect_parallel(&mesh, &rays),
            intersect_parallel(&walk, &rays),
        );
        assert_eq!(g.len(), columns.len() * rows.len());
        let hits = g.iter().filter(|h| h.is_some()).count();
        assert!(hits > 500, "{hits} hits: the grid misses the torus");
        for (k, (a, b)) in g.iter().zip(&w).enumerate() {
            match (a, b) {
                (Some(a), Some(b)) => {
                    assert!(a.t <= b.t, "ray {k}: {} on the grid, {} walked", a.t, b.t)
                }
                (None, Some(_)) => panic!("ray {k}: the grid misses a hit of the walk"),
                _ => {}
            }
        }
    }
}
