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
