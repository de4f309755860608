//! `altrep precompute SCENE.toml --out DIR` — the offline step: plan, build, write, measure.

use std::path::{Path, PathBuf};

use crate::pipeline::{Manifest, RunOptions, Shard, plan_scene, run_scene};

use super::CliResult;

/// Arguments of `altrep precompute`.
#[derive(clap::Args, Debug)]
pub struct PrecomputeArgs {
    /// The scene manifest (TOML).
    pub manifest: PathBuf,
    /// Output folder: one folder per asset and representation, `report.md`, `report.json`.
    #[arg(long, default_value = "altrep-out/scene")]
    pub out: PathBuf,
    /// Print what would be built and skipped, and why; compute nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Rebuild even what the cache holds.
    #[arg(long)]
    pub force: bool,
    /// Only the assets of shard `i` of `n` (`i/n`, e.g. `0/4`); assets are split by a hash of
    /// their name, the same on every machine.
    #[arg(long, value_parser = Shard::parse)]
    pub shard: Option<Shard>,
    /// Ignore the scene's needs when building and compute everything (to measure what skipping
    /// saves); the figures are measured as a planned run measures them (the needs' directions,
    /// the planned sizes), so the two runs' tables compare.
    #[arg(long)]
    pub everything: bool,
    /// Also write the run summary as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Time every stage (capture, bounds, octree, pyramids, writing, …) of every build and each
    /// asset's load, ray set-up (BVH build) and mesh-to-files time, and print the tables (also
    /// in report.md and report.json); assets then run one at a time.
    #[arg(long)]
    pub profile: bool,
    /// Only write the files: no read-back, error figures or report pictures (a library run
    /// where only the precompute matters; a later run without this flag rebuilds and measures).
    #[arg(long)]
    pub no_measure: bool,
    /// End with success even when a representation measures below its asset's quality target
    /// (`needs.quality_db`) or far below its own exact renderer at the same views; without it
    /// such a run ends non-zero (the report flags them either way).
    #[arg(long)]
    pub allow_below_quality: bool,
    /// Refuse the run before any work when its estimated peak memory exceeds SIZE (for example
    /// `2GiB`, `512M`; binary units). Default: three quarters of the memory the system reports
    /// available. `--dry-run` prints the estimates.
    #[arg(long, value_name = "SIZE", value_parser = crate::pipeline::memory::parse_size)]
    pub max_memory: Option<u64>,
}

/// Fails unless a file can be written at `path`, checked before any work: an existing file is
/// opened for appending (nothing is written), elsewhere a probe file is created and removed. A
/// folder at `path` fails.
pub fn check_writable(path: &Path) -> Result<(), String> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !parent.is_dir() {
        return Err(format!(
            "cannot write {}: folder {} does not exist",
            path.display(),
            parent.display()
        ));
    }
    if path.is_dir() {
        return Err(format!("cannot write {}: it is a folder", path.display()));
    }
    if path.exists() {
        std::fs::File::options()
            .append(true)
            .open(path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        return Ok(());
    }
    let probe = parent.join(format!(".altrep-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// The run an interrupt (SIGINT, SIGTERM) reports on: the output folder and when the run began.
static INTERRUPTED_RUN: std::sync::Mutex<Option<(PathBuf, std::time::SystemTime)>> =
    std::sync::Mutex::new(None);

/// The representations a run into `out` that began at `since` finished: asset folders holding an
/// `asset.json` written since (folders are renamed into place complete, so every one listed is
/// whole). Sorted `ASSET/REPR` names.
pub fn finished_since(out: &Path, since: std::time::SystemTime) -> Vec<String> {
    let mut done = Vec::new();
    let Ok(assets) = std::fs::read_dir(out) else {
        return done;
    };
    for asset in assets.filter_map(Result::ok) {
        let name = asset.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || !asset.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        let Ok(reprs) = std::fs::read_dir(asset.path()) else {
            continue;
        };
        for repr in reprs.filter_map(Result::ok) {
            let description = repr.path().join(crate::asset::DESCRIPTION_FILE);
            let fresh = std::fs::symlink_metadata(&description)
                .and_then(|m| m.modified())
                .is_ok_and(|t| t >= since);
            if fresh {
                done.push(format!("{name}/{}", repr.file_name().to_string_lossy()));
            }
        }
    }
    done.sort();
    done
}

/// Installs (once per process) the interrupt handler of a precompute into `out`: on SIGINT or
/// SIGTERM it prints the representations finished so far and how to resume, then exits with
/// status 130. What was being written stays in `OUT/.staging/`, never in an asset folder, and the
/// next run clears it.
fn report_interrupts(out: &Path) {
    let since = std::time::SystemTime::now();
    if let Ok(mut run) = INTERRUPTED_RUN.lock() {
        *run = Some((out.to_path_buf(), since));
    }
    let _ = ctrlc::set_handler(|| {
        // From here no asset folder lands, so the list below is exactly what is finished.
        crate::asset::stop_commits();
        let run = INTERRUPTED_RUN.lock().ok().and_then(|r| r.clone());
        if let Some((out, since)) = run {
            let done = finished_since(&out, since);
            eprintln!(
                "\ninterrupted: {} representation(s) finished and written in this run{}{}",
                done.len(),
                if done.is_empty() { "" } else { ": " },
                done.join(", ")
            );
            eprintln!(
                "to resume, run the same command again: what is finished (from this run or \
                 earlier ones) is verified and reused from the cache, the rest is built; the \
                 unfinished write in {} is cleared",
                out.join(".staging").display()
            );
        }
        std::process::exit(130);
    });
}

/// Runs `altrep precompute`.
pub fn run(args: PrecomputeArgs) -> CliResult {
    let manifest = Manifest::load(&args.manifest)?;
    run_manifest(&manifest, &args)
}

/// Runs a parsed manifest with the command's options (shared with `altrep demo`).
pub fn run_manifest(manifest: &Manifest, args: &PrecomputeArgs) -> CliResult {
    if let Some(j) = &args.json {
        check_writable(j)?;
    }
    let options = RunOptions {
        out: args.out.clone(),
        force: args.force,
        shard: args.shard,
        everything: args.everything,
        progress: true,
        profile: args.profile,
        measure: !args.no_measure,
        max_memory: args
            .max_memory
            .or_else(crate::pipeline::memory::default_max_memory),
    };
    if args.dry_run {
        for (asset, repr, plan) in plan_scene(manifest, &options)? {
            println!("{asset} / {repr}:");
            if let Some(r) = &plan.refused {
                println!("  REFUSED — {r}");
            }
            for item in &plan.items {
                match &item.skipped {
                    None => println!("  build  {}", item.what),
                    Some(r) => println!("  skip   {} — {r}", item.what),
                }
            }
        }
        let memory = crate::pipeline::plan_memory(manifest, &options)?;
        println!("memory plan (estimates):");
        for line in memory.lines() {
            println!("  {line}");
        }
        memory.check()?;
        return Ok(());
    }
    report_interrupts(&args.out);
    let summary = run_scene(manifest, &options)?;
    print!("{}", summary.table());
    if let Some(p) = &summary.profile {
        print!("\nPer-stage profile\n\n{}", p.markdown());
    }
    let built = summary
        .outcomes
        .iter()
        .filter(|o| o.outcome == crate::pipeline::Outcome::Built)
        .count();
    let cached = summary
        .outcomes
        .iter()
        .filter(|o| o.outcome == crate::pipeline::Outcome::Cached)
        .count();
    let bytes: u64 = summary.outcomes.iter().map(|o| o.bytes).sum();
    let skipped: usize = summary
        .outcomes
        .iter()
        .map(|o| o.plan.skipped().count())
        .sum();
    if built == 0 && cached > 0 && summary.ok() {
        println!("nothing to do: all {cached} representations are cached");
    }
    println!(
        "{built} built, {cached} cached, {skipped} parts skipped by the planner, {bytes} bytes, {:.2} s; report: {}",
        summary.wall_seconds,
        args.out.join("report.md").display()
    );
    if let Some(j) = &args.json {
        super::write_json(j, &summary)?;
    }
    if !summary.ok() {
        return Err("some representations failed (see the table above)".into());
    }
    let below = summary.below_quality();
    let below_exact = summary.below_exact();
    if !below.is_empty() || !below_exact.is_empty() {
        let list: Vec<String> = below
            .iter()
            .map(|(o, (db, target))| {
                format!("{}/{} {db:.2} dB < {target} dB", o.asset, o.representation)
            })
            .collect();
        let exact: Vec<String> = below_exact
            .iter()
            .map(|(o, (db, exact))| {
                format!(
                    "{}/{} {db:.2} dB, its exact renderer {exact:.2} dB",
                    o.asset, o.representation
                )
            })
            .collect();
        let mut parts = Vec::new();
        if !below.is_empty() {
            parts.push(format!(
                "{} representation(s) below their asset's quality target (needs.quality_db): {}",
                below.len(),
                list.join(", ")
            ));
        }
        if !below_exact.is_empty() {
            parts.push(format!(
                "{} representation(s) measured far below their own exact renderer at the same views (the renderer a display runs does not draw what was stored): {}",
                below_exact.len(),
                exact.join(", ")
            ));
        }
        let message = parts.join("; ");
        if !args.allow_below_quality {
            return Err(
                format!("{message}; rerun with --allow-below-quality to accept them").into(),
            );
        }
        println!("{message} (accepted: --allow-below-quality)");
    }
    Ok(())
}
