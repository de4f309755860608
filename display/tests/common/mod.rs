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
#[allow(dead_code)] // each test binary uses what it needs of this module
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
