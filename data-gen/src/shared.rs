//! The project's evaluation meshes, `../shared/data/meshes` beside the checkout (or the folder
//! named by `$ALTREP_MESHES`), for its tests and benchmarks. Not part of the library's API: the
//! folder is found from where this crate was compiled.

use std::path::PathBuf;

use crate::mesh::{Mesh, MeshLoadOptions};

/// The folder of the evaluation meshes: `$ALTREP_MESHES`, else `../shared/data/meshes` beside
/// the checkout.
fn mesh_dir() -> PathBuf {
    std::env::var_os("ALTREP_MESHES").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/meshes"),
        PathBuf::from,
    )
}

/// The OBJ files of the evaluation meshes, sorted by path; empty, after a loud message on
/// stderr naming `what` was skipped, when the folder is absent or holds no OBJ file.
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
        eprintln!(
            "\n*** skipped {what}: ../shared absent ({} has no meshes) ***\n",
            dir.display()
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
/// `None`, after a loud message on stderr naming `what` was skipped, when its file is absent.
/// Panics if it fails to load: for tests and benchmarks only.
#[doc(hidden)]
pub fn shared_mesh(name: &str, what: &str) -> Option<Mesh> {
    let path = mesh_dir().join(format!("{name}.obj"));
    if !path.exists() {
        eprintln!("\n*** skipped {what}: {} not found ***\n", path.display());
        return None;
    }
    Some(Mesh::load_obj(&path, &MeshLoadOptions::default()).expect("an evaluation mesh loads"))
}
