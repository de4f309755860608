//! The cylindrical impostor shader against its CPU twins (`MarchBounds::render`,
//! `OffsetTexture::render` plain and hybrid, one sub-sample per pixel) and against the ray-cast
//! ground truth, on assets written by the pipeline and read back through the library's loader.
//! The offsets are fitted by the library (`OffsetTexture::fit`), never by the display.
//!
//! Without a GPU adapter every test prints "skipped: no GPU adapter" and passes, except with
//! `CI=true`, where a missing adapter fails. No reference image is stored: the expected images
//! are computed by the CPU renderers at test time. On failure the actual, expected and
//! difference PNGs go to `target/tmp/display-failures/`.

use std::f64::consts::TAU;
use std::path::Path;

use altrep::asset::{AssetWriter, Conventions};
use altrep::cylinder::asset::{Cylinder, CylinderData, CylinderSpec};
use altrep::cylinder::frame::row_coordinate;
use altrep::cylinder::{
    CylinderRenderParams, OffsetMode, OffsetParams, OffsetTexture, RadiusModel, SliceView,
};
use altrep::metrics::psnr;
use altrep::pipeline::{Needs, Representation, Source};
use altrep_data_gen::{
    BoundingCylinder, Light, PixelGrid, RgbaImage, Supersample, TruthParams, render_truth,
    scene_shape,
};
use altrep_display::Precision;
use altrep_display::check::{pixel_errors, quantile, write_artefacts};
use altrep_display::cylinder::{CylinderDisplay, CylinderDraw, CylinderMode};
use altrep_display::load;
use altrep_display::{DisplayError, Gpu};
use approx::assert_abs_diff_eq;

use crate::common::{assert_floor, failures_dir, gpu, gpu_f64};

/// Shapes of the step-count and image checks (star-shaped, flat faces, thin branches).
const SHAPES: [&str; 3] = ["pear", "truck", "tree"];
/// Camera angles (radians): off the columns, one on a column, one past a turn.
const ANGLES: [f64; 4] = [0.3, 1.1, std::f64::consts::FRAC_PI_2, 4.4];
/// Screen size of the checks (the texture is 128 × 32).
const SIZE: usize = 32;
/// Modes checked.
const MODES: [CylinderMode; 4] = [
    CylinderMode::Bounded,
    CylinderMode::Fitted,
    CylinderMode::Hybrid { steps: 2 },
    CylinderMode::Hybrid { steps: 4 },
];

/// Builds the cylinder asset of `shape` with the pipeline, writes it with the pipeline's writer,
/// loads it back through the library's loader, and fits the offsets of the loaded texture with
/// the library (15 × 8 × 16 cells, mask, 32 × rows × 32 samples).
fn asset(shape: &str, dir: &Path) -> (CylinderData, OffsetTexture) {
    let s = scene_shape(shape).unwrap();
    let src = Source {
        name: shape,
        geometry: Some(&s),
        texture: None,
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let spec = CylinderSpec {
        columns: 128,
        rows: 32,
        ..CylinderSpec::default()
    };
    let needs = Needs::default();
    let (_, decisions) = Cylinder::plan(&spec, &needs, &src).unwrap();
    let (data, _) = Cylinder::build(&spec, &needs, &decisions, &src).unwrap();
    let mut w = AssetWriter::new(dir, shape, Cylinder::NAME).unwrap();
    let meta = Cylinder::write(&data, &mut w).unwrap();
    w.commit(
        Cylinder::NAME,
        shape,
        "test",
        Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .unwrap();
    let loaded = load::<Cylinder>(&dir.join(shape).join(Cylinder::NAME)).unwrap();
    let offsets = OffsetTexture::fit(
        &loaded.texture,
        &OffsetParams {
            samples: [32, 0, 32],
            ..OffsetParams::default()
        },
    )
    .unwrap();
    (loaded, offsets)
}

fn draw(mode: CylinderMode, alpha: f64) -> CylinderDraw {
    CylinderDraw {
        alpha,
        width: SIZE,
        height: SIZE,
        mode,
        tolerance_px: 1.0,
        light: Light::default(),
    }
}

fn params(alpha: f64) -> CylinderRenderParams {
    CylinderRenderParams {
        angle: alpha,
        width: SIZE,
        height: SIZE,
        supersample: Supersample::ONE,
        light: Light::default(),
    }
}

/// The CPU renderer of `mode`: image and total sector tests.
fn cpu_render(
    data: &CylinderData,
    off: &OffsetTexture,
    mode: CylinderMode,
    alpha: f64,
) -> (RgbaImage, u64) {
    let p = params(alpha);
    let r = match mode {
        CylinderMode::Bounded => data.bounds.render(&data.texture, &p).unwrap(),
        CylinderMode::Fitted => off
            .render(&data.texture, OffsetMode::Plain, 1.0, &p)
            .unwrap(),
        CylinderMode::Hybrid { steps } => off
            .render(
                &data.texture,
                OffsetMode::Hybrid {
                    steps: steps as usize,
                },
                1.0,
                &p,
            )
            .unwrap(),
    };
    (r.image, r.steps)
}

/// Per fragment, the CPU's sector tests (public API: the slice at the pixel's row, then
/// `MarchBounds::march` or `OffsetTexture::sample`), as the renderers count them.
fn cpu_steps(data: &CylinderData, off: &OffsetTexture, mode: CylinderMode, alpha: f64) -> Vec<u32> {
    let tex = &data.texture;
    let grid = PixelGrid {
        width: SIZE,
        height: SIZE,
        cylinder: tex.cylinder(),
    };
    let mut out = vec![0u32; SIZE * SIZE];
    for j in 0..SIZE {
        let v = row_coordinate(grid.y_at(j as f64 + 0.5), &grid.cylinder, tex.rows());
        let slice = tex.slice(v);
        let view = SliceView::new(&slice, alpha, RadiusModel::General);
        for i in 0..SIZE {
            let x = grid.x_at(i as f64 + 0.5) / grid.cylinder.radius;
            out[j * SIZE + i] = match mode {
                CylinderMode::Bounded => data.bounds.march(&view, x, v).1,
                CylinderMode::Fitted => {
                    off.sample(&view, x, v, OffsetMode::Plain, 2.0 / SIZE as f64)
                        .2
                }
                CylinderMode::Hybrid { steps } => {
                    off.sample(
                        &view,
                        x,
                        v,
                        OffsetMode::Hybrid {
                            steps: steps as usize,
                        },
                        2.0 / SIZE as f64,
                    )
                    .2
                }
            };
        }
    }
    out
}

/// Compares the GPU image with the expected one: PSNR ≥ `min_db` and the 99th percentile of
/// the per-pixel largest channel error ≤ `max_p99`; writes artefacts when either fails.
fn check_image(
    name: &str,
    actual: &RgbaImage,
    expected: &RgbaImage,
    min_db: f64,
    max_p99: f32,
) -> (f64, f32) {
    let db = psnr(actual, expected).unwrap();
    let p99 = quantile(&pixel_errors(actual, expected).unwrap(), 0.99);
    if db < min_db || p99 > max_p99 {
        let dir = write_artefacts(&failures_dir(), name, actual, expected).unwrap();
        panic!(
            "{name}: PSNR {db:.2} dB (need ≥ {min_db}), p99 error {p99:.4} (need ≤ {max_p99}); artefacts in {}",
            dir.display()
        );
    }
    (db, p99)
}

#[test]
fn gpu_image_matches_cpu_renderer_for_every_mode_f32() {
    let Some(gpu) = gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut worst = f64::INFINITY;
    for shape in SHAPES {
        let (data, off) = asset(shape, dir.path());
        let disp = CylinderDisplay::new(gpu, &data, Some(&off), Precision::F32).unwrap();
        for mode in MODES {
            for alpha in ANGLES {
                let frame = disp.render(gpu, &draw(mode, alpha)).unwrap();
                let (cpu, _) = cpu_render(&data, &off, mode, alpha);
                let name = format!("cyl-{shape}-{}-{alpha:.2}", mode.name());
                let (db, _) = check_image(&name, &frame.image, &cpu, 40.0, 0.02);
                worst = worst.min(db);
                // Depth is written exactly where a colour is.
                for (p, &z) in frame.image.pixels.iter().zip(&frame.depth) {
                    assert_eq!(p[3] > 0.0, z < 1.0, "{name}: depth written where drawn");
                    assert!((0.0..=1.0).contains(&z));
                }
            }
        }
    }
    eprintln!("worst GPU(f32)-vs-CPU PSNR over shapes, modes and angles: {worst:.1} dB");
}

/// Counts fragments whose GPU step count differs from the CPU's, over shapes, modes, angles.
fn step_mismatches(gpu: &Gpu, precision: Precision) -> (usize, usize, Vec<String>) {
    let dir = tempfile::tempdir().unwrap();
    let (mut bad, mut total, mut notes) = (0, 0, Vec::new());
    for shape in SHAPES {
        let (data, off) = asset(shape, dir.path());
        let disp = CylinderDisplay::new(gpu, &data, Some(&off), precision).unwrap();
        for mode in MODES {
            let (mut steps_gpu, mut steps_cpu) = (0u64, 0u64);
            for alpha in ANGLES {
                let frame = disp.render(gpu, &draw(mode, alpha)).unwrap();
                let cpu = cpu_steps(&data, &off, mode, alpha);
                let (_, total_render) = cpu_render(&data, &off, mode, alpha);
                let sum: u64 = cpu.iter().map(|&s| u64::from(s)).sum();
                assert_eq!(
                    sum, total_render,
                    "per-fragment CPU steps add up to the render's"
                );
                for (f, (g, &c)) in frame.steps.iter().zip(&cpu).enumerate() {
                    total += 1;
                    steps_gpu += u64::from(g[0]);
                    steps_cpu += u64::from(c);
                    assert_eq!(g[1], 0, "one march per fragment");
                    if g[0] != c {
                        bad += 1;
                        if notes.len() < 12 {
                            notes.push(format!(
                                "{shape} {} α={alpha:.2} fragment ({}, {}): GPU {} CPU {c}",
                                mode.name(),
                                f % SIZE,
                                f / SIZE,
                                g[0]
                            ));
                        }
                    }
                }
            }
            eprintln!(
                "{precision:?} {shape} {:<10} sector tests per fragment: GPU {:.3} CPU {:.3}",
                mode.name(),
                steps_gpu as f64 / (ANGLES.len() * SIZE * SIZE) as f64,
                steps_cpu as f64 / (ANGLES.len() * SIZE * SIZE) as f64
            );
        }
    }
    (bad, total, notes)
}

#[test]
fn gpu_step_counts_equal_cpu_per_fragment_in_f64() {
    let Some(gpu) = gpu_f64() else { return };
    let (bad, total, notes) = step_mismatches(gpu, Precision::F64);
    eprintln!("f64: {bad} of {total} fragments differ");
    assert_eq!(bad, 0, "step counts differ:\n{}", notes.join("\n"));
}

/// In `f32` an edge end within rounding of a pixel's abscissa can cover it on one side and not
/// on the other, and a fetched offset within rounding of a column boundary names the neighbour:
/// the count then differs in a rare fragment. The tolerance is stated in the README with the
/// measured figure; the `f64` test above demands exact equality.
#[test]
fn gpu_step_counts_match_cpu_per_fragment_in_f32_but_for_rounding() {
    let Some(gpu) = gpu() else { return };
    let (bad, total, notes) = step_mismatches(gpu, Precision::F32);
    let share = bad as f64 / total as f64;
    eprintln!(
        "f32: {bad} of {total} fragments differ ({:.4} %)\n{}",
        100.0 * share,
        notes.join("\n")
    );
    assert!(
        share <= 0.001,
        "f32 step mismatches above 0.1 %: {bad} of {total}\n{}",
        notes.join("\n")
    );
}

/// Measured PSNR (dB) of the GPU image (f32) against the ray-cast truth, per case
/// ([`crate::common::MEASURED_ON`]); the floors are these less [`crate::common::FLOOR_MARGIN_DB`].
const MEASURED_VS_TRUTH: [(&str, f64); 24] = [
    ("pear bounded α=0.30", 25.97),
    ("pear hybrid-m4 α=0.30", 25.97),
    ("pear bounded α=1.10", 25.64),
    ("pear hybrid-m4 α=1.10", 25.40),
    ("pear bounded α=1.57", 25.45),
    ("pear hybrid-m4 α=1.57", 25.46),
    ("pear bounded α=4.40", 25.30),
    ("pear hybrid-m4 α=4.40", 25.25),
    ("truck bounded α=0.30", 19.35),
    ("truck hybrid-m4 α=0.30", 17.43),
    ("truck bounded α=1.10", 18.77),
    ("truck hybrid-m4 α=1.10", 17.18),
    ("truck bounded α=1.57", 27.03),
    ("truck hybrid-m4 α=1.57", 20.08),
    ("truck bounded α=4.40", 20.18),
    ("truck hybrid-m4 α=4.40", 18.35),
    ("tree bounded α=0.30", 22.75),
    ("tree hybrid-m4 α=0.30", 17.72),
    ("tree bounded α=1.10", 22.52),
    ("tree hybrid-m4 α=1.10", 17.14),
    ("tree bounded α=1.57", 23.45),
    ("tree hybrid-m4 α=1.57", 16.34),
    ("tree bounded α=4.40", 22.56),
    ("tree hybrid-m4 α=4.40", 17.92),
];

/// The GPU image against the ray-cast truth: within half a decibel of the CPU renderer's PSNR
/// (the same loaded asset) and, since a defect the two renderers share would pass that, above an
/// absolute floor per case.
#[test]
fn gpu_psnr_against_ray_cast_truth_within_half_db_of_cpu_and_above_its_floor() {
    let Some(gpu) = gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let light = Light::default();
    for shape in SHAPES {
        let (data, off) = asset(shape, dir.path());
        let disp = CylinderDisplay::new(gpu, &data, Some(&off), Precision::F32).unwrap();
        let s = scene_shape(shape).unwrap();
        for alpha in ANGLES {
            let truth = render_truth(
                &s,
                &TruthParams {
                    angle: alpha,
                    width: SIZE,
                    height: SIZE,
                    supersample: Supersample::of(4),
                    light,
                    cylinder: BoundingCylinder::default(),
                },
            )
            .unwrap();
            for mode in [CylinderMode::Bounded, CylinderMode::Hybrid { steps: 4 }] {
                let (cpu, _) = cpu_render(&data, &off, mode, alpha);
                let frame = disp.render(gpu, &draw(mode, alpha)).unwrap();
                let (db_cpu, db_gpu) = (
                    psnr(&cpu, &truth).unwrap(),
                    psnr(&frame.image, &truth).unwrap(),
                );
                let name = format!("{shape} {} α={alpha:.2}", mode.name());
                eprintln!("{name}: PSNR vs truth CPU {db_cpu:.2} dB, GPU {db_gpu:.2} dB");
                assert_abs_diff_eq!(db_gpu, db_cpu, epsilon = 0.5);
                assert_floor(&MEASURED_VS_TRUTH, &name, db_gpu);
            }
        }
    }
}

#[test]
fn bad_draw_parameters_are_typed_errors() {
    let Some(gpu) = gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (data, off) = asset("pear", dir.path());
    let bare = CylinderDisplay::new(gpu, &data, None, Precision::F32).unwrap();
    assert!(!bare.has_offsets());
    let full = CylinderDisplay::new(gpu, &data, Some(&off), Precision::F32).unwrap();
    let cases = [
        (&bare, draw(CylinderMode::Fitted, 0.3)),
        (&full, draw(CylinderMode::Hybrid { steps: 0 }, 0.3)),
        (
            &full,
            CylinderDraw {
                width: 0,
                ..draw(CylinderMode::Bounded, 0.3)
            },
        ),
        (&full, draw(CylinderMode::Bounded, f64::NAN)),
        (
            &full,
            CylinderDraw {
                tolerance_px: f64::NAN,
                ..draw(CylinderMode::Fitted, 0.3)
            },
        ),
    ];
    for (disp, d) in cases {
        let e = disp.render(gpu, &d).unwrap_err();
        assert!(
            matches!(e, DisplayError::InvalidParameter { .. }),
            "{d:?}: {e}"
        );
    }
    // Offsets fitted on a texture of another size are refused.
    let (other, _) = {
        let s = scene_shape("pear").unwrap();
        let src = Source {
            name: "pear",
            geometry: Some(&s),
            texture: None,
            tile: None,
            light: Light::default(),
            placement: None,
        };
        let spec = CylinderSpec {
            columns: 64,
            rows: 16,
            ..CylinderSpec::default()
        };
        let (_, dec) = Cylinder::plan(&spec, &Needs::default(), &src).unwrap();
        Cylinder::build(&spec, &Needs::default(), &dec, &src).unwrap()
    };
    assert!(matches!(
        CylinderDisplay::new(gpu, &other, Some(&off), Precision::F32),
        Err(DisplayError::InvalidParameter { .. })
    ));
    assert!(matches!(
        load::<Cylinder>(&dir.path().join("nothing-here")),
        Err(DisplayError::Asset { .. })
    ));
    // The full turn: α and α + 2π draw the same frame.
    let a = full.render(gpu, &draw(CylinderMode::Bounded, 0.7)).unwrap();
    let b = full
        .render(gpu, &draw(CylinderMode::Bounded, 0.7 + TAU))
        .unwrap();
    assert!(psnr(&a.image, &b.image).unwrap() > 40.0);
}
