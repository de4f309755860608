//! The pyramid side-by-side shader against its CPU twins (`Pyramid::sample_grad`,
//! `RipMap::sample_grad`, `FipMap::decide` + `FipMap::sample_into`) and against the supersampled
//! truth of `altrep::pyramid::truth`, on mip and rip assets written by the pipeline and read back
//! through the library's loader (the fipmap, which the pipeline does not write yet, is built with
//! `FipMap::build`).
//!
//! Without a GPU adapter every test prints "skipped: no GPU adapter" and passes, except with
//! `CI=true`, where a missing adapter fails. No reference image is stored: the expected images
//! come from the CPU samplers at test time. On failure the actual, expected and difference PNGs
//! go to `target/tmp/display-failures/`.

use std::path::Path;

use altrep::asset::{AssetWriter, Conventions};
use altrep::pipeline::{Needs, Representation, Source};
use altrep::pyramid::asset::{PyramidAsset, PyramidRepr};
use altrep::pyramid::truth::{PlaneView, footprints, supersampled_truth, test_texture};
use altrep::pyramid::{FipMap, PyramidData, PyramidParams, Scheme, Texture, WrapMode};
use altrep_data_gen::{Light, RgbaImage};
use altrep_display::DisplayError;
use altrep_display::check::{pixel_errors, quantile, write_artefacts};
use altrep_display::load;
use altrep_display::pyramid::{PyramidDisplay, Sampler, value_psnr, values_to_image};
use approx::assert_abs_diff_eq;

use crate::common::{assert_floor, failures_dir, gpu};

/// Texels per side of the test texture (checkerboard, diagonal wave and noise; periodic).
const TEX: usize = 128;
/// Image side (pixels).
const PIXELS: usize = 48;
/// Truth samples per pixel (cap).
const TRUTH_SAMPLES: usize = 2048;

/// Views: face on, oblique, grazing; along a texture axis and skewed (30°, where the fipmap
/// shears), two distances.
fn views() -> Vec<PlaneView> {
    let mut v = Vec::new();
    for (d, tilt, az) in [
        (1.0, 0.0, 0.0),
        (2.0, 45.0, 30.0),
        (1.0, 70.0, 0.0),
        (1.0, 82.0, 30.0),
        (2.0, 85.0, 30.0),
        (1.0, 85.0, 60.0),
        (0.5, 88.0, 25.0),
        (1.0, 87.0, 0.0),
    ] {
        v.push(PlaneView {
            texels_per_pixel: d,
            tilt_deg: tilt,
            azimuth_deg: az,
        });
    }
    v
}

fn params() -> PyramidParams {
    PyramidParams {
        wrap: [WrapMode::Repeat; 2],
        ..PyramidParams::default()
    }
}

/// Plans, builds and writes the pyramid asset the planner chooses for views up to `grazing`
/// degrees (a mipmap at 0°, a ripmap at 79°: from 80° on a periodic texture the planner writes a
/// fipmap) with every level kept, and loads it back through the
/// library's loader.
fn asset(tex: &Texture, grazing: f64, dir: &Path) -> PyramidAsset {
    let name = format!("grain-{grazing}");
    let src = Source {
        name: &name,
        geometry: None,
        texture: Some(tex),
        tile: None,
        light: Light::default(),
        placement: None,
    };
    let needs = Needs {
        grazing_deg: grazing,
        screen_px: [1.0, TEX as f64],
        ..Needs::default()
    };
    let (_, dec) = PyramidRepr::plan(&params(), &needs, &src).unwrap();
    let (data, _) = PyramidRepr::build(&params(), &needs, &dec, &src).unwrap();
    let mut w = AssetWriter::new(dir, &name, PyramidRepr::NAME).unwrap();
    let meta = PyramidRepr::write(&data, &mut w).unwrap();
    w.commit(
        PyramidRepr::NAME,
        &name,
        "test",
        Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .unwrap();
    load::<PyramidRepr>(&dir.join(&name).join(PyramidRepr::NAME)).unwrap()
}

struct Setup {
    tex: Texture,
    mip: PyramidAsset,
    rip: PyramidAsset,
    fip: FipMap,
    _dir: tempfile::TempDir,
}

fn setup() -> Setup {
    let dir = tempfile::tempdir().unwrap();
    let tex = test_texture(TEX, 3);
    let mip = asset(&tex, 0.0, dir.path());
    let rip = asset(&tex, 79.0, dir.path());
    assert!(matches!(mip.data, PyramidData::Mip(_)));
    assert!(matches!(rip.data, PyramidData::Rip(_)));
    assert_eq!(mip.first, [0, 0], "every level kept");
    assert_eq!(rip.first, [0, 0], "every level kept");
    let fip = FipMap::build(tex.clone(), params()).unwrap();
    Setup {
        tex,
        mip,
        rip,
        fip,
        _dir: dir,
    }
}

/// The CPU twin of one panel: values (`PIXELS² × channels`), per-pixel schemes and bilinear
/// lookup counts.
fn cpu_panel(
    s: &Setup,
    sampler: Sampler,
    view: &PlaneView,
) -> (Vec<f64>, Vec<Option<Scheme>>, Vec<u32>) {
    let ch = s.tex.channels;
    let fps = footprints(view, &s.tex, PIXELS);
    let mut vals = vec![0.0f64; PIXELS * PIXELS * ch];
    let mut schemes = vec![None; PIXELS * PIXELS];
    let mut lookups = vec![0u32; PIXELS * PIXELS];
    let mut buf = vec![0.0f32; ch];
    for (k, fp) in fps.iter().enumerate() {
        let Some(fp) = fp else { continue };
        let [u, v] = fp.uv;
        let [ux, vx, uy, vy] = fp.derivs;
        let (scheme, mip, rip) = match sampler {
            Sampler::Mip => {
                let PyramidData::Mip(p) = &s.mip.data else {
                    unreachable!()
                };
                (Scheme::Mip, p, s.fip.rip())
            }
            Sampler::Rip => {
                let PyramidData::Rip(r) = &s.rip.data else {
                    unreachable!()
                };
                (Scheme::Rip, s.fip.mip(), r)
            }
            Sampler::Fip => (s.fip.decide(fp.dir), s.fip.mip(), s.fip.rip()),
        };
        // Lookups and bilinear count, through the public API of each structure.
        let count_rip = |r: &altrep::pyramid::RipMap, lod: (f64, f64)| {
            let (nu, nv) = r.level_counts();
            let frac = |l: f64, n: usize| {
                let l = l.clamp(0.0, (n - 1) as f64);
                (l - l.floor()) as f32
            };
            let (fu, fv) = (frac(lod.0, nu), frac(lod.1, nv));
            let mut n = 0;
            for wu in [1.0 - fu, fu] {
                for wv in [1.0 - fv, fv] {
                    n += u32::from(wu * wv > 0.0);
                }
            }
            n
        };
        let count_mip = |p: &altrep::pyramid::Pyramid, lod: f64| {
            let l = lod.clamp(0.0, (p.levels().len() - 1) as f64);
            1 + u32::from((l - l.floor()) as f32 > 0.0)
        };
        lookups[k] = match scheme {
            Scheme::Mip => {
                buf.copy_from_slice(&mip.sample_grad(u, v, ux, vx, uy, vy));
                count_mip(mip, mip.lod(ux, vx, uy, vy))
            }
            Scheme::Rip => {
                buf.copy_from_slice(&rip.sample_grad(u, v, ux, vx, uy, vy));
                count_rip(rip, rip.lod(ux, vx, uy, vy))
            }
            Scheme::Fip(i) => {
                s.fip
                    .sample_into(scheme, u, v, ux, vx, uy, vy, None, &mut buf);
                // The sheared ripmap's levels from the sheared derivatives (fip.rs).
                let sh = s.fip.shears()[i];
                let q = sh.period() as f64;
                let c = sh.value();
                let map = |du: f64, dv: f64| match sh.axis {
                    altrep::pyramid::ShearAxis::V => (du / q, dv + c * du),
                    altrep::pyramid::ShearAxis::U => (du + c * dv, dv / q),
                };
                let (sux, svx) = map(ux, vx);
                let (suy, svy) = map(uy, vy);
                let r = s.fip.sheared(i);
                count_rip(r, r.lod(sux, svx, suy, svy))
            }
        };
        schemes[k] = Some(scheme);
        for (o, x) in vals[k * ch..(k + 1) * ch].iter_mut().zip(&buf) {
            *o = f64::from(*x);
        }
    }
    (vals, schemes, lookups)
}

fn truth(s: &Setup, view: &PlaneView) -> RgbaImage {
    let t = supersampled_truth(view, &s.tex, PIXELS, TRUTH_SAMPLES, 1);
    values_to_image(&t, s.tex.channels, PIXELS).unwrap()
}

fn name(sampler: Sampler, v: &PlaneView) -> String {
    format!(
        "pyramid-{}-d{}-t{}-a{}",
        sampler.name(),
        v.texels_per_pixel,
        v.tilt_deg,
        v.azimuth_deg
    )
}

/// PSNR ≥ `min_db` and 99th percentile of the per-pixel largest channel error ≤ `max_p99`;
/// artefacts when either fails.
fn check_image(
    name: &str,
    actual: &RgbaImage,
    expected: &RgbaImage,
    min_db: f64,
    max_p99: f32,
) -> f64 {
    let db = value_psnr(actual, expected, 1).unwrap();
    let p99 = quantile(&pixel_errors(actual, expected).unwrap(), 0.99);
    if db < min_db || p99 > max_p99 {
        let dir = write_artefacts(&failures_dir(), name, actual, expected).unwrap();
        panic!(
            "{name}: PSNR {db:.2} dB (need ≥ {min_db}), p99 error {p99:.5} (need ≤ {max_p99}); artefacts in {}",
            dir.display()
        );
    }
    db
}

#[test]
fn gpu_pyramid_lookups_match_the_cpu_samplers() {
    let Some(gpu) = gpu() else { return };
    let s = setup();
    let disp = PyramidDisplay::new(gpu, &[&s.mip, &s.rip], Some(&s.fip)).unwrap();
    assert_eq!(disp.samplers(), Sampler::ALL.to_vec());
    for sampler in Sampler::ALL {
        let mut worst = f64::INFINITY;
        let mut ms = Vec::new();
        for v in views() {
            let frame = disp.render(gpu, sampler, &v, PIXELS).unwrap();
            ms.push(frame.millis);
            let (vals, _, _) = cpu_panel(&s, sampler, &v);
            let cpu = values_to_image(&vals, 1, PIXELS).unwrap();
            let db = check_image(&name(sampler, &v), &frame.image, &cpu, 40.0, 0.01);
            worst = worst.min(db);
        }
        ms.sort_by(f64::total_cmp);
        eprintln!(
            "{}: worst GPU-vs-CPU PSNR over {} views {worst:.1} dB; median {:.2} ms per {PIXELS}² frame (draw + read-back)",
            sampler.name(),
            views().len(),
            ms[ms.len() / 2]
        );
    }
}

/// Measured PSNR (dB) of the GPU panel against the supersampled truth of the textured plane, per
/// sampler and view ([`crate::common::MEASURED_ON`]); the floors are these less
/// [`crate::common::FLOOR_MARGIN_DB`].
const MEASURED_VS_TRUTH: [(&str, f64); 24] = [
    ("mip D0 1 tilt 0 az 0", 47.29),
    ("rip D0 1 tilt 0 az 0", 47.29),
    ("fip D0 1 tilt 0 az 0", 47.29),
    ("mip D0 2 tilt 45 az 30", 30.82),
    ("rip D0 2 tilt 45 az 30", 32.94),
    ("fip D0 2 tilt 45 az 30", 32.94),
    ("mip D0 1 tilt 70 az 0", 27.23),
    ("rip D0 1 tilt 70 az 0", 29.95),
    ("fip D0 1 tilt 70 az 0", 29.95),
    ("mip D0 1 tilt 82 az 30", 24.94),
    ("rip D0 1 tilt 82 az 30", 28.51),
    ("fip D0 1 tilt 82 az 30", 29.47),
    ("mip D0 2 tilt 85 az 30", 19.37),
    ("rip D0 2 tilt 85 az 30", 20.30),
    ("fip D0 2 tilt 85 az 30", 29.80),
    ("mip D0 1 tilt 85 az 60", 22.48),
    ("rip D0 1 tilt 85 az 60", 25.36),
    ("fip D0 1 tilt 85 az 60", 28.52),
    ("mip D0 0.5 tilt 88 az 25", 21.44),
    ("rip D0 0.5 tilt 88 az 25", 24.45),
    ("fip D0 0.5 tilt 88 az 25", 25.65),
    ("mip D0 1 tilt 87 az 0", 24.19),
    ("rip D0 1 tilt 87 az 0", 37.19),
    ("fip D0 1 tilt 87 az 0", 37.19),
];

/// Each panel against the supersampled truth: within half a decibel of the CPU sampler's PSNR
/// (the same loaded pyramids) and, since a defect the two share would pass that, above an
/// absolute floor per sampler and view.
#[test]
fn gpu_pyramid_psnr_against_supersampled_truth_within_half_db_of_cpu_and_above_its_floor() {
    let Some(gpu) = gpu() else { return };
    let s = setup();
    let disp = PyramidDisplay::new(gpu, &[&s.mip, &s.rip], Some(&s.fip)).unwrap();
    for v in views() {
        let t = truth(&s, &v);
        let mut line = format!(
            "D0 {} tilt {:>4} az {:>3}:",
            v.texels_per_pixel, v.tilt_deg, v.azimuth_deg
        );
        for sampler in Sampler::ALL {
            let frame = disp.render(gpu, sampler, &v, PIXELS).unwrap();
            let (vals, _, _) = cpu_panel(&s, sampler, &v);
            let cpu = values_to_image(&vals, 1, PIXELS).unwrap();
            let (db_cpu, db_gpu) = (
                value_psnr(&cpu, &t, 1).unwrap(),
                value_psnr(&frame.image, &t, 1).unwrap(),
            );
            line += &format!(" {} CPU {db_cpu:.2} GPU {db_gpu:.2} dB;", sampler.name());
            assert_abs_diff_eq!(db_gpu, db_cpu, epsilon = 0.5);
            let name = format!(
                "{} D0 {} tilt {} az {}",
                sampler.name(),
                v.texels_per_pixel,
                v.tilt_deg,
                v.azimuth_deg
            );
            assert_floor(&MEASURED_VS_TRUTH, &name, db_gpu);
        }
        eprintln!("{line}");
    }
}

/// The per-fragment scheme (mip, rip or which shear) of the fipmap's decision equals the CPU's
/// `FipMap::decide` exactly, and every scheme occurs over the views; the per-fragment count of
/// bilinear lookups equals the CPU's but where the fractional level is within `f32` rounding of 0
/// (measured: see the printout; allowed 0.5 % of fragments).
#[test]
fn gpu_fip_decisions_and_lookup_counts_match_cpu_per_fragment() {
    let Some(gpu) = gpu() else { return };
    let s = setup();
    let disp = PyramidDisplay::new(gpu, &[&s.mip, &s.rip], Some(&s.fip)).unwrap();
    let (mut seen_mip, mut seen_rip, mut seen_fip) = (false, false, false);
    let (mut bad_counts, mut total) = (0usize, 0usize);
    for sampler in Sampler::ALL {
        let mut sum_gpu = 0u64;
        for v in views() {
            let frame = disp.render(gpu, sampler, &v, PIXELS).unwrap();
            let (_, schemes, lookups) = cpu_panel(&s, sampler, &v);
            for (f, (g, c)) in frame.scheme.iter().zip(&schemes).enumerate() {
                assert_eq!(
                    g,
                    c,
                    "{}: fragment ({}, {}) scheme",
                    name(sampler, &v),
                    f % PIXELS,
                    f / PIXELS
                );
                match c {
                    Some(Scheme::Mip) => seen_mip = true,
                    Some(Scheme::Rip) => seen_rip = true,
                    Some(Scheme::Fip(_)) => seen_fip = true,
                    None => {}
                }
            }
            for (g, c) in frame.lookups.iter().zip(&lookups) {
                total += 1;
                sum_gpu += u64::from(*g);
                bad_counts += usize::from(g != c);
            }
        }
        eprintln!(
            "{}: mean bilinear lookups per fragment {:.3}",
            sampler.name(),
            sum_gpu as f64 / (views().len() * PIXELS * PIXELS) as f64
        );
    }
    assert!(
        seen_mip && seen_rip && seen_fip,
        "every scheme is exercised"
    );
    let share = bad_counts as f64 / total as f64;
    eprintln!(
        "lookup counts: {bad_counts} of {total} fragments differ ({:.4} %)",
        100.0 * share
    );
    assert!(
        share <= 0.005,
        "{bad_counts} of {total} lookup counts differ"
    );
}

#[test]
fn bad_pyramid_inputs_are_typed_errors() {
    // Loading needs no GPU.
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        load::<PyramidRepr>(&dir.path().join("nothing-here")),
        Err(DisplayError::Asset { .. })
    ));
    assert!(values_to_image(&[0.0; 5], 1, 2).is_err());
    let Some(gpu) = gpu() else { return };
    let s = setup();
    assert!(matches!(
        PyramidDisplay::new(gpu, &[], None),
        Err(DisplayError::InvalidParameter { .. })
    ));
    assert!(matches!(
        PyramidDisplay::new(gpu, &[&s.mip, &s.mip], None),
        Err(DisplayError::InvalidParameter { .. })
    ));
    let other = FipMap::build(test_texture(64, 1), params()).unwrap();
    assert!(matches!(
        PyramidDisplay::new(gpu, &[&s.mip], Some(&other)),
        Err(DisplayError::InvalidParameter { .. })
    ));
    let disp = PyramidDisplay::new(gpu, &[&s.mip], None).unwrap();
    let ok = views()[0];
    let bad = [
        (Sampler::Rip, ok, PIXELS),
        (Sampler::Mip, ok, 0),
        (
            Sampler::Mip,
            PlaneView {
                tilt_deg: 90.0,
                ..ok
            },
            PIXELS,
        ),
        (
            Sampler::Mip,
            PlaneView {
                texels_per_pixel: f64::NAN,
                ..ok
            },
            PIXELS,
        ),
    ];
    for (sampler, v, px) in bad {
        let e = disp.render(gpu, sampler, &v, px).unwrap_err();
        assert!(
            matches!(e, DisplayError::InvalidParameter { .. }),
            "{sampler:?} {v:?} {px}: {e}"
        );
    }
}
