//! Helpers shared by the GPU tests: the device, and where failure artefacts go.

use std::path::{Path, PathBuf};

use altrep_display::Gpu;

/// The device, or `None` after printing "skipped: no GPU adapter" (a failure when `CI=true`).
pub fn gpu() -> Option<Gpu> {
    match Gpu::headless() {
        Ok(g) => {
            eprintln!("adapter: {} (f64: {})", g.describe(), g.has_f64);
            Some(g)
        }
        Err(e) => {
            if std::env::var("CI").is_ok_and(|v| v == "true") {
                panic!("CI=true and no GPU adapter: {e}");
            }
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    }
}

/// `target/tmp/display-failures/`: the actual, expected and difference PNGs of a failed check.
pub fn failures_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("display-failures")
}
