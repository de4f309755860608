//! Real textured assets (glTF 2.0) against the ray-cast truth, on a folder of assets given by
//! `ALTREP_EVAL_ASSETS` (none are shipped: see docs/real-assets.md). Ignored by default; run
//!
//! ```text
//! ALTREP_EVAL_ASSETS=/path/to/assets cargo test --release --test integration real_assets:: -- --ignored --nocapture
//! ```
//!
//! It prints, per asset, the capture at a view's own direction against the truth (`k × k`
//! supersampled) over the pixels both cover fully, where only the texture's sampling differs.

use std::path::{Path, PathBuf};

use altrep::metrics::{CompareOptions, compare};
use altrep_data_gen::{
    BoundingCylinder, Light, Mesh, MeshLoadOptions, RgbaImage, Shape, Supersample, TruthParams,
    ViewParams, capture_view, render_truth, render_truth_at_points,
};

fn gltf_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            gltf_files(&p, out);
        } else if p
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"))
        {
            out.push(p);
        }
    }
}

fn interior(capture: &RgbaImage, truth: &RgbaImage) -> f64 {
    let mask: Vec<bool> = truth
        .pixels
        .iter()
        .zip(&capture.pixels)
        .map(|(t, c)| t[3] == 1.0 && c[3] == 1.0)
        .collect();
    compare(
        capture,
        truth,
        &CompareOptions {
            mask: Some(&mask),
            threshold: 0.0,
        },
    )
    .map_or(f64::NAN, |e| e.psnr_db)
}

/// The same comparison as [`interior_psnr`] with the texture read at one point per ray in both
/// pictures (how captures and the truth read textures before footprints).
fn interior_psnr_point(mesh: &Mesh, angle: f64, size: usize, k: usize) -> f64 {
    let at_points = |k: usize| render_truth_at_points(mesh, &view(angle, size, k)).unwrap();
    interior(&at_points(1), &at_points(k))
}

/// The truth's parameters of the view at `angle`, `size × 2·size` pixels, `k × k` rays each.
fn view(angle: f64, size: usize, k: usize) -> TruthParams {
    TruthParams {
        angle,
        width: size,
        height: 2 * size,
        supersample: Supersample::of(k),
        light: Light::default(),
        cylinder: BoundingCylinder::default(),
    }
}

/// The capture of view `angle` at `size²` against the truth with `k × k` rays per pixel, over
/// the pixels the truth covers fully and the capture defines: PSNR in dB.
fn interior_psnr(mesh: &Mesh, angle: f64, size: usize, k: usize) -> f64 {
    let light = Light::default();
    let cylinder = BoundingCylinder::default();
    let grid = capture_view(
        mesh,
        &ViewParams {
            angle,
            width: size,
            height: 2 * size,
            cylinder,
        },
    )
    .unwrap();
    let capture = grid.shade(&light);
    let truth = render_truth(mesh, &view(angle, size, k)).unwrap();
    interior(&capture, &truth)
}

#[test]
#[ignore = "needs ALTREP_EVAL_ASSETS (real assets are not shipped)"]
fn captures_of_real_assets_against_the_truth() {
    let Some(dir) = std::env::var_os("ALTREP_EVAL_ASSETS") else {
        eprintln!("SKIPPED: set ALTREP_EVAL_ASSETS to a folder of glTF assets");
        return;
    };
    let mut files = Vec::new();
    gltf_files(Path::new(&dir), &mut files);
    eprintln!(
        "| asset | triangles | materials | load + BVH, s | own direction, footprint: 64² / 256², dB | point-sampled: 64² / 256², dB |"
    );
    eprintln!("|---|---|---|---|---|---|");
    for f in files {
        let t = std::time::Instant::now();
        let mesh = match Mesh::load(&f, &MeshLoadOptions::default()) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("| {} | load failed: {e} | | |", f.display());
                continue;
            }
        };
        mesh.prepare_rays();
        let load = t.elapsed().as_secs_f64();
        let p64 = interior_psnr(&mesh, 0.4, 64, 4);
        let p256 = interior_psnr(&mesh, 0.4, 256, 4);
        let q64 = interior_psnr_point(&mesh, 0.4, 64, 4);
        let q256 = interior_psnr_point(&mesh, 0.4, 256, 4);
        eprintln!(
            "| {} | {} | {} | {load:.3} | {p64:.2} / {p256:.2} | {q64:.2} / {q256:.2} |",
            f.strip_prefix(&dir).unwrap_or(&f).display(),
            mesh.triangle_count(),
            mesh.materials().len(),
        );
    }
}

/// Load and BVH time of a generated textured glTF of about 10⁶ triangles (a UV sphere of
/// 500 × 1000 quads with a 2048² texture, one `.glb`), and of 8 views of 512² captured from it;
/// the same single-sided (back faces culled in the tracers), and without its texture.
#[test]
#[ignore = "timing: run in release with --nocapture"]
fn a_million_textured_triangles_load_and_capture() {
    use altrep_data_gen::gltf_write::{Rgba8, TestGltf, TestPrimitive};
    let (n, m) = (500u32, 1000u32);
    let mut prim = TestPrimitive::empty(0);
    for a in 0..=n {
        for b in 0..=m {
            let (th, ph) = (
                std::f32::consts::PI * a as f32 / n as f32,
                std::f32::consts::TAU * b as f32 / m as f32,
            );
            prim.positions
                .push([th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()]);
            prim.uvs.push([b as f32 / m as f32, a as f32 / n as f32]);
        }
    }
    // Counter-clockwise seen from outside (glTF's front faces): the single-sided case culls the
    // inside.
    for a in 0..n {
        for b in 0..m {
            let k = a * (m + 1) + b;
            prim.indices
                .extend([k, k + m + 2, k + m + 1, k, k + 1, k + m + 2]);
        }
    }
    let mut doc = TestGltf::textured_box(2);
    let size = 2048u32;
    doc.materials[0].texture = Some(Rgba8 {
        width: size,
        height: size,
        data: (0..size * size)
            .flat_map(|k| [(k % 251) as u8, (k / size % 241) as u8, 90, 255])
            .collect(),
    });
    doc.materials[0].nearest = false;
    doc.meshes = vec![vec![prim]];
    let plain = {
        let mut d = doc.clone();
        d.materials[0].texture = None;
        d
    };
    let single = {
        let mut d = doc.clone();
        d.materials[0].double_sided = false;
        d
    };
    for (what, doc) in [
        ("textured", doc),
        ("textured, single-sided", single),
        ("untextured", plain),
    ] {
        let glb = doc.to_glb().unwrap();
        let t = std::time::Instant::now();
        let mesh =
            Mesh::from_gltf_bytes(&glb, Path::new("sphere.glb"), &MeshLoadOptions::default())
                .unwrap();
        let load = t.elapsed().as_secs_f64();
        mesh.prepare_rays();
        let bvh = t.elapsed().as_secs_f64() - load;
        let t = std::time::Instant::now();
        for v in 0..8 {
            capture_view(
                &mesh,
                &ViewParams {
                    angle: v as f64 * std::f64::consts::TAU / 8.0,
                    width: 512,
                    height: 1024,
                    cylinder: BoundingCylinder::default(),
                },
            )
            .unwrap();
        }
        let capture = t.elapsed().as_secs_f64();
        let tree = mesh.bvh_build_time().map_or(f64::NAN, |d| d.as_secs_f64());
        eprintln!(
            "{what}, {} triangles: load {load:.3} s, BVH {bvh:.3} s (the tree alone {tree:.3} s), 8 views of 512 × 1024: {capture:.3} s",
            mesh.triangle_count()
        );
    }
}
