//! `altrep demo` — the main job: captures the bundled procedural scene, runs every
//! representation's demo section, and writes images, `report.json` and `report.md` into the
//! output folder.
//!
//! Each representation contributes a [`DemoSection`] through a function
//! `fn(&DemoContext) -> Result<DemoSection, Box<dyn Error + Send + Sync>>` listed in
//! [`sections`]; a section writes its own files under `ctx.out`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use altrep_data_gen::{
    BoundingCylinder, Light, RgbaImage, Shape, Supersample, TruthParams, ViewParams, capture_view,
    render_truth, scene_shape,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use super::CliResult;

/// Arguments of `altrep demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Output folder (created if missing).
    #[arg(long, default_value = "altrep-out")]
    pub out: PathBuf,
    /// Smaller sizes everywhere, for a quick look (used by the end-to-end test).
    #[arg(long)]
    pub quick: bool,
}

/// What a demo section sees.
pub struct DemoContext<'a> {
    /// The section's own folder (created, empty), which lands at `OUT/<its name>/`: a section
    /// writes only here, and links its images in its Markdown as `<its name>/FILE`.
    pub dir: &'a Path,
    /// Quick mode: smaller sizes.
    pub quick: bool,
    /// The light every image is shaded with.
    pub light: Light,
}

/// What a demo section returns for the report.
pub struct DemoSection {
    /// Section title (also its key in `report.json`).
    pub name: String,
    /// Machine-readable results.
    pub json: serde_json::Value,
    /// Markdown for `report.md` (tables, image links relative to the output folder).
    pub markdown: String,
}

/// Signature of a demo section.
pub type SectionFn =
    fn(&DemoContext) -> Result<DemoSection, Box<dyn std::error::Error + Send + Sync>>;

/// The sections of the demo, in order.
pub fn sections() -> Vec<(&'static str, SectionFn)> {
    vec![
        ("captures", captures_section),
        ("cylinder", super::cylinder::demo_section),
        ("parallax", super::parallax::demo_section),
        ("ellipsoid", super::ellipsoid_bench::demo_section),
        ("pyramids", super::pyramid::demo_section),
    ]
}

/// The bundled scene manifest (`scenes/demo.toml`).
pub const DEMO_SCENE: &str = include_str!("../../scenes/demo.toml");
/// The bundled scene's flat cut-out (`scenes/cutout.obj`).
pub const DEMO_CUTOUT: &str = include_str!("../../scenes/cutout.obj");
/// The bundled scene's shrub of alpha-masked leaf cards (`scenes/shrub.glb`): data-gen's
/// `TestGltf::leaf_shrub(300, 7)`, byte for byte (a unit test checks it).
pub const DEMO_SHRUB: &[u8] = include_bytes!("../../scenes/shrub.glb");
/// The bundled scene's textured rock (`scenes/rock.glb`): data-gen's
/// `TestGltf::textured_rock(4, 11)`, byte for byte (a unit test checks it).
pub const DEMO_ROCK: &[u8] = include_bytes!("../../scenes/rock.glb");

/// Runs `altrep demo`: `precompute` of the bundled scene into `OUT/scene`, then the measured
/// sections into `OUT/report.md`.
pub fn run(args: DemoArgs) -> CliResult {
    // What the demo writes besides the scene (which `precompute` guards itself): checked before
    // any work, staged, and renamed into place (crate::asset::OutputClaim).
    let list = sections();
    let entries = ["report.json", "report.md", "scene-inputs"]
        .into_iter()
        .chain(list.iter().map(|(name, _)| *name))
        .map(String::from)
        .collect();
    let mut claim = crate::asset::OutputClaim::new(&args.out, "demo", entries);
    claim.check()?;
    let staging = claim.begin()?;
    // The scene's own meshes (a flat cut-out, a shrub, a rock) are written beside a copy of the
    // manifest, so the demo runs from any folder.
    let staged_inputs = staging.join("scene-inputs");
    std::fs::create_dir(&staged_inputs)
        .map_err(|e| format!("cannot create {}: {e}", staged_inputs.display()))?;
    std::fs::write(staged_inputs.join("cutout.obj"), DEMO_CUTOUT)
        .and_then(|()| std::fs::write(staged_inputs.join("shrub.glb"), DEMO_SHRUB))
        .and_then(|()| std::fs::write(staged_inputs.join("rock.glb"), DEMO_ROCK))
        .map_err(|e| format!("cannot write {}: {e}", staged_inputs.display()))?;
    let inputs = claim.place("scene-inputs")?;
    let manifest = crate::pipeline::Manifest::parse(DEMO_SCENE, &inputs.join("demo.toml"))?;
    let scene_out = args.out.join("scene");
    super::precompute::run_manifest(
        &manifest,
        &super::precompute::PrecomputeArgs {
            manifest: PathBuf::from("scenes/demo.toml"),
            out: scene_out,
            dry_run: false,
            force: false,
            shard: None,
            everything: false,
            json: None,
            profile: false,
            no_measure: false,
            // The bundled scene holds three stand-ins below the default 20 dB target (a flat
            // sign, the truck's cylinder, the shrub's octree): the demo shows them flagged.
            allow_below_quality: true,
            max_memory: None,
        },
    )?;
    let bar = ProgressBar::new(list.len() as u64).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]")
            .expect("static progress template"),
    );
    let mut report = serde_json::Map::new();
    let mut md = String::from("# altrep demo report\n\n");
    md += &format!(
        "Generated by `altrep demo{}` (altrep {}).\n\nThe bundled scene (`scenes/demo.toml`) was precomputed into \
         [`scene/`](scene/report.md): assets, what the planner skipped and why, bytes and errors.\n\n",
        if args.quick { " --quick" } else { "" },
        env!("CARGO_PKG_VERSION")
    );
    for (name, section) in list {
        bar.set_message(name);
        let t0 = Instant::now();
        let dir = staging.join(name);
        std::fs::create_dir(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let ctx = DemoContext {
            dir: &dir,
            quick: args.quick,
            light: Light::default(),
        };
        let s = section(&ctx).map_err(|e| format!("demo section '{name}' failed: {e}"))?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        report.insert(s.name.clone(), json!({ "wall_ms": ms, "results": s.json }));
        md += &format!(
            "## {}\n\n{}\n\n_Section wall time: {:.0} ms._\n\n",
            s.name,
            s.markdown.trim_end(),
            ms
        );
        bar.inc(1);
    }
    bar.finish_with_message("done");
    let write = |name: &str, bytes: &[u8]| {
        let path = staging.join(name);
        std::fs::write(&path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
    };
    write(
        "report.json",
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    write("report.md", md.as_bytes())?;
    claim.commit()?;
    println!(
        "wrote {} and {}",
        args.out.join("report.json").display(),
        args.out.join("report.md").display()
    );
    Ok(())
}

/// The demo's scene: the procedural shapes every section works on.
pub const DEMO_SHAPES: &[&str] = &["truck", "pear", "tree", "chair", "building"];

/// Captures and ground truth of the bundled scene: a few views per shape with albedo, normals and
/// depth, and ground-truth renders beside them.
fn captures_section(
    ctx: &DemoContext,
) -> Result<DemoSection, Box<dyn std::error::Error + Send + Sync>> {
    let dir = ctx.dir;
    let (size, truth_size, k) = if ctx.quick {
        (32, 64, Supersample::of(2))
    } else {
        (64, 128, Supersample::of(4))
    };
    let cylinder = BoundingCylinder::default();
    let mut rows = Vec::new();
    let mut md = String::from(
        "Orthographic captures (albedo, normal, 16-bit depth) and the supersampled ground truth.\n\n\
         | shape | view angles | capture size | coverage | rays/s (capture) | truth size | truth ms |\n|---|---|---|---|---|---|---|\n",
    );
    for name in DEMO_SHAPES {
        let shape = scene_shape(name)?;
        let angles = [0.0, std::f64::consts::FRAC_PI_2, 2.5];
        let t0 = Instant::now();
        let mut coverage = 0.0;
        for (v, &angle) in angles.iter().enumerate() {
            let view = capture_view(
                &shape,
                &ViewParams {
                    angle,
                    width: size,
                    height: size,
                    cylinder,
                },
            )?;
            coverage += view.coverage() / angles.len() as f64;
            view.write_albedo_png(&dir.join(format!("{name}_view{v}_albedo.png")))?;
            view.write_normal_png(&dir.join(format!("{name}_view{v}_normal.png")))?;
            view.write_depth_png16(&dir.join(format!("{name}_view{v}_depth16.png")))?;
        }
        let rays = (angles.len() * size * size) as f64;
        let rps = rays / t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let truth = truth_image(&shape, 0.6, truth_size, k, ctx.light, cylinder)?;
        let truth_ms = t1.elapsed().as_secs_f64() * 1e3;
        truth.write_png(&dir.join(format!("{name}_truth.png")))?;
        md += &format!(
            "| {name} | {} | {size}² | {:.1} % | {rps:.3e} | {truth_size}² ×{k}² | {truth_ms:.0} |\n",
            angles.len(),
            coverage * 100.0
        );
        md += "";
        rows.push(json!({ "shape": name, "coverage": coverage, "rays_per_second": rps, "truth_ms": truth_ms }));
    }
    md += "\n";
    for name in DEMO_SHAPES {
        md += &format!("![{name}](captures/{name}_truth.png) ");
    }
    md += "\n";
    Ok(DemoSection {
        name: "captures".into(),
        json: json!(rows),
        markdown: md,
    })
}

/// A square ground-truth render of `shape` at `angle` (premultiplied linear RGBA).
pub fn truth_image(
    shape: &dyn Shape,
    angle: f64,
    size: usize,
    supersample: Supersample,
    light: Light,
    cylinder: BoundingCylinder,
) -> Result<RgbaImage, altrep_data_gen::DataGenError> {
    render_truth(
        shape,
        &TruthParams {
            angle,
            width: size,
            height: size,
            supersample,
            light,
            cylinder,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bundled shrub is what data-gen writes, so it can be rebuilt from the code (and a
    /// change to the generator shows up here).
    #[test]
    fn the_bundled_shrub_is_data_gens_leaf_shrub() {
        let written = altrep_data_gen::gltf_write::TestGltf::leaf_shrub(300, 7)
            .to_glb()
            .unwrap();
        assert!(
            written == DEMO_SHRUB,
            "scenes/shrub.glb differs from TestGltf::leaf_shrub(300, 7): rewrite it"
        );
    }

    /// The bundled rock is what data-gen writes.
    #[test]
    fn the_bundled_rock_is_data_gens_textured_rock() {
        let written = altrep_data_gen::gltf_write::TestGltf::textured_rock(4, 11)
            .to_glb()
            .unwrap();
        assert!(
            written == DEMO_ROCK,
            "scenes/rock.glb differs from TestGltf::textured_rock(4, 11): rewrite it"
        );
    }
}
