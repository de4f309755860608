//! Helpers shared by the GPU tests: one device per test binary, loud skips, and where failure
//! artefacts go.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use altrep_display::Gpu;

/// The test binary's device, shared by its tests so that each pipeline is built once per
/// binary; `None` after a loud skip line when no usable adapter exists (a failure under
/// `CI=true`).
pub fn gpu() -> Option<&'static Gpu> {
    static GPU: OnceLock<Result<Gpu, String>> = OnceLock::new();
    let gpu = GPU.get_or_init(|| {
        let g = Gpu::headless().map_err(|e| e.to_string())?;
        eprintln!("adapter: {} (f64: {})", g.describe(), g.has_f64);
        Ok(g)
    });
    match gpu {
        Ok(g) => Some(g),
        Err(e) => {
            altrep_data_gen::skip("a GPU test", &format!("no usable GPU adapter: {e}"));
            None
        }
    }
}

/// The device when it has `SHADER_F64` (the exact `f64` twins); `None` after a loud skip line
/// otherwise (GL adapters have no `f64`; a failure under `CI=true`).
#[allow(dead_code)] // the pyramid's tests have no f64 twin
pub fn gpu_f64() -> Option<&'static Gpu> {
    let gpu = gpu()?;
    if gpu.has_f64 {
        Some(gpu)
    } else {
        altrep_data_gen::skip(
            "an f64 GPU test",
            &format!("the adapter {} has no SHADER_F64", gpu.describe()),
        );
        None
    }
}

/// `target/tmp/display-failures/`: the actual, expected and difference PNGs of a failed check.
pub fn failures_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("display-failures")
}

/// When and where the PSNRs behind the absolute floors were measured.
pub const MEASURED_ON: &str =
    "2026-12-04 on lavapipe (Mesa 22.3.6, LLVM 15; the CPU renderer gives the same to 0.01 dB)";

/// How far below its measured PSNR against the truth a GPU image may fall. The truth is ray-cast
/// from the shape, so it passes through none of the writer, the loader, the lighting or the
/// framing that the GPU and CPU renderers share; a defect in one of those costs whole decibels,
/// while drivers' `f32` rounding moved no figure by more than 0.01 dB.
pub const FLOOR_MARGIN_DB: f64 = 0.3;

/// Asserts the absolute floor of case `name`: its PSNR `db` against the ray-cast truth is at
/// least `measured − FLOOR_MARGIN_DB`, with `measured` looked up by name in `table` (a case
/// missing from the table fails: every case has its floor).
pub fn assert_floor(table: &[(&str, f64)], name: &str, db: f64) {
    let measured = table
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("{name}: no measured PSNR in the table of floors"))
        .1;
    let floor = measured - FLOOR_MARGIN_DB;
    assert!(
        db >= floor,
        "{name}: {db:.2} dB against the ray-cast truth, below its floor {floor:.2} dB (measured \
         {measured:.2} dB {MEASURED_ON})"
    );
}

/// View directions (toward the camera) of the volume twins' checks: oblique horizontal, from
/// above at 40°, from below at 25°, straight down, and exactly along the x axis.
pub fn volume_directions() -> Vec<glam::DVec3> {
    let polar = |az: f64, el: f64| {
        let (a, e) = (az.to_radians(), el.to_radians());
        glam::DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
    };
    vec![
        polar(33.0, 0.0),
        polar(120.0, 40.0),
        polar(250.0, -25.0),
        glam::DVec3::Y,
        glam::DVec3::X,
    ]
}

/// Writes `data` of representation `R` with the pipeline's writer into `dir/name/R::NAME` and
/// loads it back through the display's loader, as a user's folder would be.
pub fn written_and_loaded<R: altrep::pipeline::Representation>(
    dir: &Path,
    name: &str,
    data: &R::Data,
) -> R::Data {
    let mut w = altrep::asset::AssetWriter::new(dir, name, R::NAME).unwrap();
    let meta = R::write(data, &mut w).unwrap();
    w.commit(
        R::NAME,
        name,
        "test",
        altrep::asset::Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .unwrap();
    altrep_display::load::<R>(&dir.join(name).join(R::NAME)).unwrap()
}

/// PSNR (dB) of the GPU image `actual` against the CPU twin's `expected`, after asserting it is
/// at least `min_db` and that the 99th percentile of the per-pixel largest channel error is at
/// most `max_p99`; on failure the images and their difference go to [`failures_dir`] under
/// `name`.
pub fn check_against_cpu(
    name: &str,
    actual: &altrep_display::RgbaImage,
    expected: &altrep_display::RgbaImage,
    min_db: f64,
    max_p99: f32,
) -> f64 {
    use altrep_display::check::{pixel_errors, quantile, write_artefacts};
    let db = altrep::metrics::psnr(actual, expected).unwrap();
    let p99 = quantile(&pixel_errors(actual, expected).unwrap(), 0.99);
    if db < min_db || p99 > max_p99 {
        let out = write_artefacts(&failures_dir(), name, actual, expected).unwrap();
        panic!(
            "{name}: PSNR {db:.2} dB (need ≥ {min_db}), p99 error {p99:.4} (need ≤ {max_p99}); artefacts in {}",
            out.display()
        );
    }
    db
}
