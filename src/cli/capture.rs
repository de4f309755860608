//! `altrep capture` — N orthographic views of a mesh (OBJ or glTF) (or a procedural shape) with colour,
//! 16-bit depth and normals, and the ray-casting throughput.

use std::path::PathBuf;
use std::time::Instant;

use altrep_data_gen::{
    BoundingCylinder, Light, Mesh, MeshLoadOptions, Shape, ViewParams, capture_view, scene_shape,
};
use serde_json::json;

use super::CliResult;

/// Arguments of `altrep capture`.
/// How a `--mesh` file is read (`docs/real-assets.md`).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct MeshReadArgs {
    /// The mesh's up axis: x, -x, y, -y, z or -z (glTF is y-up by its specification; OBJ has
    /// no convention).
    #[arg(long, default_value = "y")]
    pub up: altrep_data_gen::UpAxis,
    /// glTF only: load the subtree of the node of this name, in the scene's world coordinates
    /// (default: the whole default scene).
    #[arg(long)]
    pub node: Option<String>,
}

#[derive(clap::Args, Debug)]
pub struct CaptureArgs {
    /// Mesh to capture (.obj, .gltf or .glb).
    #[arg(long, conflicts_with = "shape", required_unless_present = "shape")]
    pub mesh: Option<PathBuf>,
    /// How the mesh file is read.
    #[command(flatten)]
    pub read: crate::cli::capture::MeshReadArgs,
    /// Procedural shape to capture instead (sphere, box, torus, capsule, pear, truck, chair, tree, building).
    #[arg(long)]
    pub shape: Option<String>,
    /// Number of views, at angles 2πk/N.
    #[arg(long, default_value_t = 8, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub views: u32,
    /// Width and height of each view in pixels.
    #[arg(long, default_value_t = 64, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub size: u32,
    /// Output folder, replaced whole: it must be absent, empty, or a capture folder this command
    /// wrote (holding only what its capture.json lists).
    #[arg(long, default_value = "altrep-out/capture")]
    pub out: PathBuf,
}

/// Loads the shape named by `--mesh` or `--shape` (shared by the subcommands that take them).
pub fn load_shape(
    mesh: Option<&PathBuf>,
    shape: Option<&str>,
    read: &MeshReadArgs,
) -> Result<Box<dyn Shape>, Box<dyn std::error::Error + Send + Sync>> {
    match (mesh, shape) {
        (Some(path), _) => {
            let options = MeshLoadOptions {
                up: read.up,
                node: read.node.clone(),
                ..MeshLoadOptions::default()
            };
            let mesh = Mesh::load(path, &options)?;
            for note in mesh.notes() {
                eprintln!("altrep: {}: {note}", path.display());
            }
            Ok(Box::new(mesh))
        }
        (None, Some(name)) => Ok(Box::new(scene_shape(name)?)),
        (None, None) => Err("give --mesh FILE or --shape NAME".into()),
    }
}

/// Runs `altrep capture`.
pub fn run(args: CaptureArgs) -> CliResult {
    // The output folder is replaced whole: it must be one this command wrote, checked before
    // any work and again just before the swap.
    check_capture_folder(&args.out)?;
    let t_load = Instant::now();
    let shape = load_shape(args.mesh.as_ref(), args.shape.as_deref(), &args.read)?;
    let load_ms = t_load.elapsed().as_secs_f64() * 1e3;
    // The rate counts tracing only: a mesh's BVH, built on its first ray query, is built here.
    let t_setup = Instant::now();
    shape.prepare_rays();
    let setup_ms = t_setup.elapsed().as_secs_f64() * 1e3;
    // Everything is written into a staging folder beside `--out`, then swapped in whole: a rerun
    // never leaves files of an earlier run (e.g. more views) beside the new ones, and an
    // interrupted run leaves the earlier output intact.
    let parent = match args.out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent)
        .map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
    let name = args
        .out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| format!("--out {} has no folder name", args.out.display()))?;
    let staging = parent.join(format!(".{name}.staging{}", std::process::id()));
    if staging.exists() {
        std::fs::remove_dir_all(&staging)
            .map_err(|e| format!("cannot clear {}: {e}", staging.display()))?;
    }
    std::fs::create_dir_all(&staging)
        .map_err(|e| format!("cannot create {}: {e}", staging.display()))?;
    let result = capture_into(&args, shape.as_ref(), &staging, [load_ms, setup_ms]);
    match result {
        Ok(summary) => {
            if let Err(e) = check_capture_folder(&args.out) {
                let _ = std::fs::remove_dir_all(&staging);
                return Err(e.into());
            }
            crate::asset::replace_dir(&staging, &args.out)?;
            println!("{summary}");
            Ok(())
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            Err(e)
        }
    }
}

/// Captures the views into `dir`; returns the summary line. `[load_ms, setup_ms]`: the shape's
/// load and its ray set-up (a mesh's BVH build), both before the timed captures.
fn capture_into(
    args: &CaptureArgs,
    shape: &dyn Shape,
    dir: &std::path::Path,
    [load_ms, setup_ms]: [f64; 2],
) -> Result<String, Box<dyn std::error::Error + Send + Sync>> {
    let cylinder = BoundingCylinder::default();
    let size = args.size as usize;
    let n = args.views as usize;
    let mut capture_s = 0.0;
    let mut files = Vec::new();
    let mut seen = false;
    for k in 0..n {
        let angle = std::f64::consts::TAU * k as f64 / n as f64;
        let t0 = Instant::now();
        let view = capture_view(
            shape,
            &ViewParams {
                angle,
                width: size,
                height: size,
                cylinder,
            },
        )?;
        capture_s += t0.elapsed().as_secs_f64();
        seen |= view.coverage() > 0.0;
        // capture.json names the files relative to its own folder: the folder is written
        // under a staging name and renamed, so a full path would name the staging folder.
        let [colour, albedo, normal, depth] =
            ["color", "albedo", "normal", "depth16"].map(|kind| format!("view{k:03}.{kind}.png"));
        view.shade(&Light::default())
            .write_png(&dir.join(&colour))?;
        view.write_albedo_png(&dir.join(&albedo))?;
        view.write_normal_png(&dir.join(&normal))?;
        view.write_depth_png16(&dir.join(&depth))?;
        files.push(json!({
            "view": k, "angle_rad": angle, "coverage": view.coverage(),
            "color": colour, "albedo": albedo, "normal": normal, "depth16": depth,
        }));
    }
    if !seen {
        return Err(format!(
            "the object is not visible in any of the {n} views (every ray missed it): nothing to capture"
        )
        .into());
    }
    let rays = (n * size * size) as f64;
    let rps = rays / capture_s;
    let desc = json!({
        "shape": shape.name(),
        "views": n, "size": size,
        "conventions": "view k looks along -d(2πk/N); files relative to this file's folder; depth16: 0 = undefined, 1..65535 maps depth/R in [-1,1]; normal: rgb=(n+1)/2, object frame",
        "load_ms": load_ms, "ray_setup_ms": setup_ms, "rays": rays, "rays_per_second": rps,
        "files": files,
    });
    let json_path = dir.join("capture.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&desc)?)?;
    Ok(format!(
        "captured {} views of {} at {size}×{size} into {}: {rays:.0} rays in {:.1} ms, {rps:.3e} rays/s (load {load_ms:.0} ms, ray set-up {setup_ms:.0} ms)",
        n,
        shape.name(),
        args.out.display(),
        capture_s * 1e3
    ))
}

/// The files a capture folder's `capture.json` lists (itself included), if it is one of this
/// command's.
fn capture_listing(out: &std::path::Path) -> Option<std::collections::BTreeSet<String>> {
    let bytes = std::fs::read(out.join("capture.json")).ok()?;
    let d: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
    if !d["conventions"].is_string() {
        return None;
    }
    let files = d["files"].as_array()?;
    Some(
        files
            .iter()
            .flat_map(|f| ["color", "albedo", "normal", "depth16"].map(|k| &f[k]))
            .filter_map(|v| v.as_str().map(String::from))
            .chain(["capture.json".to_string()])
            .collect(),
    )
}

/// Whether `out` may be replaced by a capture ([`super::check_replaceable`]).
fn check_capture_folder(out: &std::path::Path) -> Result<(), String> {
    super::check_replaceable(out, "altrep capture", "capture.json", capture_listing)
}
