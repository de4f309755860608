//! The project's evaluation meshes, `../shared/data/meshes` beside the checkout (or the folder
//! named by `$ALTREP_MESHES`), for its tests and benchmarks, and the one way those tests skip
//! ([`skip`]). Not part of the library's API: the folder is found from where this crate was
//! compiled.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::mesh::{Mesh, MeshLoadOptions};

/// The folder of the evaluation meshes: `$ALTREP_MESHES`, else `../shared/data/meshes` beside
/// the checkout.
fn mesh_dir() -> PathBuf {
    std::env::var_os("ALTREP_MESHES").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/meshes"),
        PathBuf::from,
    )
}

/// Whether this run is continuous integration (`CI=true`), where nothing may be skipped.
#[doc(hidden)]
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Skips the check `what` because of `reason`, loudly: under `CI=true` this panics (a skipped
/// check is a failure there); otherwise it writes a numbered `SKIPPED` line straight to the
/// process's stderr, which the test harness does not capture, so the line shows in the output
/// of a passing test. For tests and benchmarks only.
#[doc(hidden)]
pub fn skip(what: &str, reason: &str) {
    if under_ci() {
        panic!("CI=true: {what} cannot be skipped: {reason}");
    }
    static SKIPS: AtomicUsize = AtomicUsize::new(0);
    let n = SKIPS.fetch_add(1, Ordering::Relaxed) + 1;
    let test = std::thread::current()
        .name()
        .map_or(String::new(), |t| format!(" (test {t})"));
    // Straight to the file descriptor: `eprintln!` would be captured and hidden.
    let _ = writeln!(
        std::io::stderr().lock(),
        "*** SKIPPED [{n} in this test binary] {what}{test}: {reason} ***"
    );
}

/// The OBJ files of the evaluation meshes, sorted by path; empty, after [`skip`] naming `what`,
/// when the folder is absent or holds no OBJ file (a panic under `CI=true`).
#[doc(hidden)]
pub fn shared_mesh_paths(what: &str) -> Vec<PathBuf> {
    let dir = mesh_dir();
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "obj"))
                .collect()
        })
        .unwrap_or_default();
    paths.sort();
    if paths.is_empty() {
        skip(
            what,
            &format!(
                "the evaluation meshes are absent ({} has no OBJ file; they come with ../shared)",
                dir.display()
            ),
        );
    }
    paths
}

/// The evaluation meshes loaded with the default options ([`shared_mesh_paths`]). Panics if one
/// fails to load: for tests and benchmarks only.
#[doc(hidden)]
pub fn shared_meshes(what: &str) -> Vec<Mesh> {
    shared_mesh_paths(what)
        .iter()
        .map(|p| Mesh::load_obj(p, &MeshLoadOptions::default()).expect("an evaluation mesh loads"))
        .collect()
}

/// The evaluation mesh `name` (its file stem, e.g. `"teapot"`) loaded with the default options;
/// `None`, after [`skip`] naming `what`, when its file is absent (a panic under `CI=true`).
/// Panics if it fails to load: for tests and benchmarks only.
#[doc(hidden)]
pub fn shared_mesh(name: &str, what: &str) -> Option<Mesh> {
    let path = mesh_dir().join(format!("{name}.obj"));
    if !path.exists() {
        skip(
            what,
            &format!(
                "{} not found (the evaluation meshes come with ../shared)",
                path.display()
            ),
        );
        return None;
    }
    Some(Mesh::load_obj(&path, &MeshLoadOptions::default()).expect("an evaluation mesh loads"))
}
