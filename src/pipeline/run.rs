//! Running a scene: lock, plan, cache, build, write, read back, measure, report.

use std::path::PathBuf;
use std::time::Instant;

use altrep_data_gen::Light;
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;

use super::manifest::{AssetSpec, Manifest};
use super::output::{io, prepare_output};
use super::source::load_source;
use crate::asset::{
    AssetReader, AssetWriter, Conventions, DESCRIPTION_FILE, FORMAT_MAJOR, write_atomic,
};
use crate::representation::registry::for_each_representation;
use crate::representation::{
    Lighting, Measurement, Needs, PipelineError, Plan, Representation, Source,
};

/// Name of the lock file in an output folder.
pub const LOCK_FILE: &str = ".altrep.lock";

/// How long a run waits for an output folder's lock before it reports the folder locked.
pub(super) const LOCK_PATIENCE: std::time::Duration = std::time::Duration::from_millis(500);

/// `--shard i/n`: this run handles the assets whose name hashes to `i` modulo `n`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0 ≤ index < count`.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `i/n`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("shard '{s}' must be i/n"))?;
        let index: usize = i.trim().parse().map_err(|_| format!("shard index '{i}'"))?;
        let count: usize = n.trim().parse().map_err(|_| format!("shard count '{n}'"))?;
        if count == 0 || index >= count {
            return Err(format!("shard {index}/{count}: need 0 ≤ i < n"));
        }
        Ok(Self { index, count })
    }

    /// Whether this shard handles asset `name` (BLAKE3 of the name, modulo the count: the same
    /// on every machine).
    pub fn owns(&self, name: &str) -> bool {
        let h = blake3::hash(name.as_bytes());
        let v = u64::from_le_bytes(h.as_bytes()[..8].try_into().unwrap_or([0; 8]));
        (v % self.count as u64) as usize == self.index
    }
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output folder.
    pub out: PathBuf,
    /// Rebuild even when the cache is valid.
    pub force: bool,
    /// Only the assets of this shard.
    pub shard: Option<Shard>,
    /// Ignore the needs when building (every view, level and channel), to measure what skipping
    /// saves; measuring still follows the needs (their directions, the planned sizes:
    /// [`Representation::measure_size`]), so the figures compare with a planned run's.
    pub everything: bool,
    /// Show progress bars.
    pub progress: bool,
    /// Time every stage of every build and each asset's load, ray set-up and mesh-to-files
    /// wall times ([`crate::profile`]); assets then run one at a time, so an asset's times hold no other
    /// asset's work (its representations still run concurrently: their rows overlap).
    pub profile: bool,
    /// Read back and measure every representation built (error figures and report pictures).
    /// Off (`--no-measure`), a run only writes the files, for libraries where the cost of the
    /// precompute matters and the error figures are not needed; a cached folder without
    /// figures is then reused, and a later run with measuring rebuilds it.
    pub measure: bool,
    /// Refuse the run before any work when the memory plan's estimate of its peak exceeds this
    /// many bytes ([`crate::pipeline::memory`]); `None`: no limit.
    pub max_memory: Option<u64>,
}

impl RunOptions {
    /// A quiet run into `out` that uses the cache and the needs and measures what it builds:
    /// no forced rebuild, every shard, no progress bars, no profile, and the memory limit of
    /// [`crate::pipeline::memory::default_max_memory`].
    pub fn new(out: impl Into<PathBuf>) -> Self {
        Self {
            out: out.into(),
            force: false,
            shard: None,
            everything: false,
            progress: false,
            profile: false,
            measure: true,
            max_memory: super::memory::default_max_memory(),
        }
    }
}

/// How one representation of one asset ended.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Built and written this run.
    Built,
    /// The asset folder's cache key matched and every file verified.
    Cached,
    /// The planner refused the representation: it cannot hold the object (the reason).
    Refused(String),
    /// Failed; the message says why.
    Failed(String),
}

/// The result for one representation of one asset.
#[derive(Clone, Debug, Serialize)]
pub struct AssetOutcome {
    /// Asset name.
    pub asset: String,
    /// Representation name.
    pub representation: String,
    /// How it ended.
    pub outcome: Outcome,
    /// What was built and skipped.
    pub plan: Plan,
    /// Wall seconds of this run for it (cache checks included).
    pub seconds: f64,
    /// Seconds the build took when it was built (from `asset.json` when cached).
    pub build_seconds: f64,
    /// Bytes of its data files.
    pub bytes: u64,
    /// Why a cached folder was not reused, if it existed.
    pub cache_note: Option<String>,
    /// Error figures against the ground truth.
    pub measurement: Option<Measurement>,
    /// Report pictures written (relative to the output folder).
    pub pictures: Vec<(String, String)>,
    /// A markdown section the representation writes from its build report
    /// ([`Representation::details`]), for the run's report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub details: Option<String>,
}

/// The result of a run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// Per asset and representation.
    pub outcomes: Vec<AssetOutcome>,
    /// Wall seconds of the whole run.
    pub wall_seconds: f64,
    /// Assets left to other shards.
    pub other_shards: Vec<String>,
    /// Per-stage times, with `--profile`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub profile: Option<crate::profile::StageTable>,
    /// Each asset's quality target (`needs.quality_db`, dB), by asset name.
    pub quality_targets: std::collections::BTreeMap<String, f64>,
    /// What each mesh's file holds that altrep does not read, or reads differently (glTF
    /// normal maps, emission, skins…; an OBJ's assumed up axis), by asset name.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub source_notes: std::collections::BTreeMap<String, Vec<String>>,
    /// The memory plan the run was checked against before any work (estimates).
    pub memory: super::memory::MemoryPlan,
}

impl RunSummary {
    /// `(measured mean PSNR, target)` when `o` measures below its asset's quality target.
    fn below(&self, o: &AssetOutcome) -> Option<(f64, f64)> {
        let target = *self.quality_targets.get(&o.asset)?;
        let db = o.measurement.as_ref()?.psnr_db;
        (db < target).then_some((db, target))
    }

    /// The measured representations whose mean PSNR against the ray-cast truth lies below their
    /// asset's quality target (`needs.quality_db`), with `(measured, target)` in dB. Unmeasured
    /// ones (`--no-measure`, cached without figures) are not judged.
    pub fn below_quality(&self) -> Vec<(&AssetOutcome, (f64, f64))> {
        self.outcomes
            .iter()
            .filter_map(|o| Some((o, self.below(o)?)))
            .collect()
    }

    /// `(measured mean PSNR, exact renderer's mean PSNR)` when `o`'s figures lie more than
    /// [`crate::representation::EXACT_GAP_DB`] below its own exact renderer's at the same views.
    fn below_exact_of(o: &AssetOutcome) -> Option<(f64, f64)> {
        let m = o.measurement.as_ref()?;
        let exact = m.exact_psnr_db?;
        (m.psnr_db < exact - crate::representation::EXACT_GAP_DB).then_some((m.psnr_db, exact))
    }

    /// The measured representations whose figures lie far below what their own exact renderer
    /// reaches at the same views ([`Measurement::exact_psnr_db`]), with `(measured, exact)` in
    /// dB: the renderer a display runs does not draw what the representation holds (a broken
    /// bound, damaged data). Flagged in the table; `altrep precompute` ends non-zero on them
    /// unless `--allow-below-quality`.
    pub fn below_exact(&self) -> Vec<(&AssetOutcome, (f64, f64))> {
        self.outcomes
            .iter()
            .filter_map(|o| Some((o, Self::below_exact_of(o)?)))
            .collect()
    }

    /// Whether every representation was built or cached.
    pub fn ok(&self) -> bool {
        self.outcomes
            .iter()
            .all(|o| !matches!(o.outcome, Outcome::Failed(_)))
    }

    /// The summary table (Markdown).
    pub fn table(&self) -> String {
        let mut s = String::from(
            "| asset | representation | outcome | skipped | seconds (build) | bytes | PSNR dB (worst) | IoU | coverage error | steps per pixel |\n|---|---|---|---|---|---|---|---|---|---|\n",
        );
        for o in &self.outcomes {
            let outcome = match (&o.outcome, self.below(o)) {
                (Outcome::Built, Some((_, target))) => {
                    format!("built, below the {target} dB quality target")
                }
                (Outcome::Cached, Some((_, target))) => {
                    format!("cached, below the {target} dB quality target")
                }
                (Outcome::Built | Outcome::Cached, None) => {
                    let word = if o.outcome == Outcome::Built {
                        "built"
                    } else {
                        "cached"
                    };
                    Self::below_exact_of(o).map_or(word.to_string(), |(_, exact)| {
                        format!("{word}, below its exact renderer's {exact:.2} dB")
                    })
                }
                (Outcome::Refused(r), _) => format!("skipped: {r}"),
                (Outcome::Failed(m), _) => format!("FAILED: {m}"),
            };
            let (psnr, iou, coverage, steps) = o.measurement.as_ref().map_or(
                (
                    "–".to_string(),
                    "–".to_string(),
                    "–".to_string(),
                    "–".to_string(),
                ),
                |m| {
                    (
                        format!("{:.2} ({:.2})", m.psnr_db, m.worst_psnr_db),
                        format!("{:.3}", m.iou),
                        m.coverage_error.map_or("–".into(), |e| format!("{e:.3}")),
                        m.mean_steps.map_or("–".into(), |s| {
                            if m.steps_split.is_empty() {
                                format!("{s:.2}")
                            } else {
                                let parts: Vec<String> = m
                                    .steps_split
                                    .iter()
                                    .map(|(_, v)| format!("{v:.2}"))
                                    .collect();
                                format!("{s:.2} ({})", parts.join(" + "))
                            }
                        }),
                    )
                },
            );
            s += &format!(
                "| {} | {} | {} | {} | {:.2} ({:.2}) | {} | {psnr} | {iou} | {coverage} | {steps} |\n",
                o.asset,
                o.representation,
                outcome,
                o.plan.skipped().count(),
                o.seconds,
                o.build_seconds,
                o.bytes
            );
        }
        let splits: std::collections::BTreeSet<String> = self
            .outcomes
            .iter()
            .filter_map(|o| o.measurement.as_ref())
            .filter(|m| !m.steps_split.is_empty())
            .map(|m| {
                let names: Vec<&str> = m.steps_split.iter().map(|(n, _)| n.as_str()).collect();
                names.join(" + ")
            })
            .collect();
        for split in splits {
            s += &format!("\nSteps per pixel count every march; in parentheses: {split}.\n");
        }
        s
    }
}

fn scene_light(manifest: &Manifest) -> Light {
    let l = manifest.scene.light;
    Light {
        direction: Vec3::from_array(l).normalize(),
        ambient: manifest.scene.ambient,
    }
}

/// The needs a run builds a representation for: the asset's, or everything for `--everything`
/// (every azimuth and screen size, and dynamic lighting where the representation `relights`: one
/// that stores shaded colour only keeps the asset's lighting, see
/// [`Representation::RELIGHTS`]).
pub(crate) fn effective_needs(spec: &AssetSpec, everything: bool, relights: bool) -> Needs {
    if everything {
        Needs {
            azimuth_deg: [0.0, 360.0],
            screen_px: [1.0, 16384.0],
            lighting: if relights {
                Lighting::Dynamic
            } else {
                spec.needs.lighting
            },
            ..spec.needs.clone()
        }
    } else {
        spec.needs.clone()
    }
}

/// Plans every representation of every asset (`--dry-run`): `(asset, representation, plan)`.
/// Loads each source once (a mesh is parsed; nothing is captured).
pub fn plan_scene(
    manifest: &Manifest,
    options: &RunOptions,
) -> Result<Vec<(String, String, Plan)>, PipelineError> {
    let light = scene_light(manifest);
    let mut out = Vec::new();
    for spec in &manifest.assets {
        if options.shard.is_some_and(|s| !s.owns(&spec.name)) {
            continue;
        }
        let (loaded, _) = load_source(spec, &light)?;
        let source = loaded.source(&spec.name, light);
        macro_rules! plan_each {
            ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {$(
                if let Some(p) = &spec.$key {
                    let needs = effective_needs(spec, options.everything, <$repr>::RELIGHTS);
                    out.push((
                        spec.name.clone(),
                        <$repr>::NAME.into(),
                        <$repr>::plan(p, &needs, &source)?.0,
                    ));
                }
            )*};
        }
        for_each_representation!(plan_each);
    }
    Ok(out)
}

/// Runs the scene: every asset of this shard, assets in parallel; the representations of an
/// asset are built and written concurrently, then each is read back and measured. Writes
/// `report.json`, `report.md` and the pictures into `options.out`. Errors that stop the whole
/// run: the output folder (unwritable, locked); a failing asset is reported in its outcome and
/// the others go on.
pub fn run_scene(manifest: &Manifest, options: &RunOptions) -> Result<RunSummary, PipelineError> {
    let t0 = Instant::now();
    let memory = super::memory::plan_memory(manifest, options)?;
    memory.check()?;
    let _lock = prepare_output(&options.out)?;
    let light = scene_light(manifest);
    let (mine, other_shards): (Vec<&AssetSpec>, Vec<&AssetSpec>) = manifest
        .assets
        .iter()
        .partition(|a| options.shard.is_none_or(|s| s.owns(&a.name)));
    // Before any work: every folder this run may replace is altrep's.
    for spec in &mine {
        for repr in wanted(spec) {
            crate::asset::check_owned(&options.out, &spec.name, repr)?;
        }
    }
    let jobs: u64 = mine.iter().map(|a| wanted(a).len() as u64).sum();
    let bar = if options.progress {
        indicatif::ProgressBar::new(jobs)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let pictures_dir = options.out.join("pictures");
    std::fs::create_dir_all(&pictures_dir).map_err(io(&pictures_dir))?;
    let profile = options.profile.then(crate::profile::Profile::new);
    let source_notes = std::sync::Mutex::new(std::collections::BTreeMap::new());
    let one = |spec: &&AssetSpec| {
        let t_asset = Instant::now();
        let loaded = load_source(spec, &light);
        let load_seconds = t_asset.elapsed().as_secs_f64();
        // The needs built for, by a representation that relights and by one that does not
        // (they differ under `--everything` only).
        let needs = effective_needs(spec, options.everything, true);
        let needs_shaded = effective_needs(spec, options.everything, false);
        let fail = |repr: &str, e: &PipelineError| AssetOutcome {
            asset: spec.name.clone(),
            representation: repr.into(),
            outcome: Outcome::Failed(e.to_string()),
            plan: Plan::default(),
            seconds: 0.0,
            build_seconds: 0.0,
            bytes: 0,
            cache_note: None,
            measurement: None,
            pictures: Vec::new(),
            details: None,
        };
        let (loaded, input_hash) = match loaded {
            Ok(l) => l,
            Err(e) => return wanted(spec).into_iter().map(|r| fail(r, &e)).collect(),
        };
        if !loaded.notes().is_empty()
            && let Ok(mut notes) = source_notes.lock()
        {
            notes.insert(spec.name.clone(), loaded.notes().to_vec());
        }
        let source = loaded.source(&spec.name, light);
        bar.set_message(spec.name.clone());
        let p = profile.as_ref();
        // First every representation is built and committed, concurrently (writing files
        // overlaps the others' computing); then each is read back and measured.
        let (source, hash) = (&source, input_hash.as_str());
        let (needs, needs_shaded) = (&needs, &needs_shaded);
        let mut builds: Vec<(&'static str, bool, BuildJob<'_>)> = Vec::new();
        // One job per representation the asset asks for, in manifest order.
        macro_rules! jobs {
            ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {$(
                if let Some(s) = &spec.$key {
                    builds.push((
                        <$repr>::NAME,
                        <$repr>::CASTS_RAYS,
                        Box::new(move || {
                            let needs = if <$repr>::RELIGHTS { needs } else { needs_shaded };
                            build_one::<$repr>(s, needs, &spec.needs, source, hash, options, p)
                        }),
                    ));
                }
            )*};
        }
        for_each_representation!(jobs);
        if let Some(p) = p {
            for (repr, _, _) in &builds {
                p.declare(&spec.name, repr);
            }
        }
        let (built, rays_seconds) = run_builds(builds, source.geometry);
        let files_seconds = t_asset.elapsed().as_secs_f64();
        let outcomes: Vec<AssetOutcome> = built
            .into_par_iter()
            .map(|(repr, b)| {
                let o = match b {
                    Ok(Built::Done(o)) => Ok(*o),
                    Ok(Built::Committed(finish)) => finish(),
                    Err(e) => Err(e),
                };
                bar.inc(1);
                o.unwrap_or_else(|e| fail(repr, &e))
            })
            .collect();
        if let Some(p) = p {
            p.asset(crate::profile::AssetTime {
                asset: spec.name.clone(),
                load_seconds,
                rays_seconds,
                files_seconds,
                total_seconds: t_asset.elapsed().as_secs_f64(),
            });
        }
        outcomes
    };
    // With --profile, assets run one at a time: an asset's stage times then hold no other
    // asset's work.
    let outcomes: Vec<AssetOutcome> = if profile.is_some() {
        mine.iter().flat_map(one).collect()
    } else {
        mine.par_iter().flat_map_iter(one).collect()
    };
    bar.finish_and_clear();
    let wall_seconds = t0.elapsed().as_secs_f64();
    let summary = RunSummary {
        outcomes,
        wall_seconds,
        other_shards: other_shards.iter().map(|a| a.name.clone()).collect(),
        profile: profile.map(|p| p.table(wall_seconds)),
        quality_targets: mine
            .iter()
            .map(|a| (a.name.clone(), a.needs.quality_db))
            .collect(),
        source_notes: source_notes.into_inner().unwrap_or_default(),
        memory,
    };
    write_report(&summary, options)?;
    Ok(summary)
}

/// The representations `spec` asks for, by name.
fn wanted(spec: &AssetSpec) -> Vec<&'static str> {
    let mut v = Vec::new();
    macro_rules! names {
        ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {$(
            if spec.$key.is_some() {
                v.push(<$repr>::NAME);
            }
        )*};
    }
    for_each_representation!(names);
    v
}

/// Names in an asset folder that its `asset.json` does not list (a rebuild replaces the folder,
/// and with it these).
fn stray_files(r: &AssetReader) -> Vec<String> {
    let listed: std::collections::HashSet<&str> = r
        .description()
        .files
        .iter()
        .map(|f| f.path.as_str())
        .chain([DESCRIPTION_FILE])
        .collect();
    let mut stray: Vec<String> = std::fs::read_dir(r.dir())
        .map(|d| {
            d.filter_map(Result::ok)
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !listed.contains(n.as_str()))
                .collect()
        })
        .unwrap_or_default();
    stray.sort();
    stray
}

/// The cache key of one representation of one asset.
fn cache_key<R: Representation>(
    spec: &R::Spec,
    decisions: &R::Decisions,
    needs: &Needs,
    input_hash: &str,
    light: &Light,
) -> String {
    let key = json!({
        "input": input_hash,
        "representation": R::NAME,
        "spec": spec,
        "decisions": decisions,
        "needs": R::relevant_needs(needs),
        "light": [light.direction.x, light.direction.y, light.direction.z, light.ambient],
        "tool": env!("CARGO_PKG_VERSION"),
        "format": FORMAT_MAJOR,
    });
    crate::asset::hash_hex(key.to_string().as_bytes())
}

/// A representation's build job (see [`build_one`]).
type BuildJob<'a> = Box<dyn FnOnce() -> Result<Built<'a>, PipelineError> + Send + 'a>;

/// A representation's name and what its build job returned.
type BuiltJob<'a> = (&'static str, Result<Built<'a>, PipelineError>);

/// Runs an asset's build jobs `(name, casts rays, job)` concurrently and returns their results
/// in the given order, with the seconds `geometry` took to prepare its ray queries (`None`
/// when no job casts rays, or without geometry: nothing is prepared then). The jobs that cast
/// no rays start at once, on other threads, while this thread prepares the ray queries (a
/// mesh's BVH: serial); the others start when it is done. Each job gives what it would give
/// run alone.
fn run_builds<'a>(
    builds: Vec<(&'static str, bool, BuildJob<'a>)>,
    geometry: Option<&(dyn altrep_data_gen::Shape + Sync)>,
) -> (Vec<BuiltJob<'a>>, Option<f64>) {
    let (rays, free): (Vec<_>, Vec<_>) = builds
        .into_iter()
        .enumerate()
        .partition(|(_, (_, casts, _))| *casts);
    let run = |jobs: Vec<(usize, (&'static str, bool, BuildJob<'a>))>| {
        jobs.into_par_iter()
            .map(|(i, (repr, _, job))| (i, (repr, job())))
            .collect::<Vec<_>>()
    };
    let ((mut done, rays_seconds), free_done) = rayon::join(
        || {
            let prepared = geometry.filter(|_| !rays.is_empty()).map(|g| {
                let t = Instant::now();
                g.prepare_rays();
                t.elapsed().as_secs_f64()
            });
            (run(rays), prepared)
        },
        || run(free),
    );
    done.extend(free_done);
    done.sort_by_key(|(i, _)| *i);
    (done.into_iter().map(|(_, b)| b).collect(), rays_seconds)
}

/// What [`build_one`] leaves: a finished outcome (refused, cached), or a representation built
/// and committed whose measuring and report remain (the closure).
enum Built<'a> {
    Done(Box<AssetOutcome>),
    Committed(Box<dyn FnOnce() -> Result<AssetOutcome, PipelineError> + Send + 'a>),
}

/// Plans representation `R` of `source` for `needs`, reuses its cached folder when valid, else
/// builds and commits it; the returned closure then reads the committed files back, measures
/// them at the conditions of the asset's own needs `measured` (their directions, and the size
/// the plan for them chooses: with `--everything` the larger data is measured as a planned run
/// would measure, so the two compare) and writes the report pictures.
#[allow(clippy::too_many_arguments)]
fn build_one<'a, R: Representation>(
    spec: &'a R::Spec,
    needs: &'a Needs,
    measured: &'a Needs,
    source: &'a Source<'a>,
    input_hash: &str,
    options: &'a RunOptions,
    profile: Option<&'a std::sync::Arc<crate::profile::Profile>>,
) -> Result<Built<'a>, PipelineError> {
    let t0 = Instant::now();
    let scope = profile.map(|p| p.scope(source.name, R::NAME));
    let (plan, decisions) = crate::profile::stage("plan", || R::plan(spec, needs, source))?;
    let dir = options.out.join(source.name).join(R::NAME);
    if let Some(reason) = &plan.refused {
        // Nothing of it is kept: a folder from an earlier run would be stale.
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(io(&dir))?;
        }
        return Ok(Built::Done(Box::new(AssetOutcome {
            asset: source.name.into(),
            representation: R::NAME.into(),
            outcome: Outcome::Refused(reason.clone()),
            plan,
            seconds: t0.elapsed().as_secs_f64(),
            build_seconds: 0.0,
            bytes: 0,
            cache_note: None,
            measurement: None,
            pictures: Vec::new(),
            details: None,
        })));
    }
    let mut key = cache_key::<R>(spec, &decisions, needs, input_hash, &source.light);
    let measure_size = if options.everything {
        // The size the plan for the asset's own needs chooses (its own if that plan refuses).
        let planned = R::plan(spec, measured, source)
            .ok()
            .filter(|(p, _)| p.refused.is_none());
        let size = planned.map_or(R::measure_size(&decisions), |(_, d)| R::measure_size(&d));
        // The figures kept with the files depend on these conditions too.
        let at = json!({ "key": key, "measured_at": R::relevant_needs(measured), "size": size });
        key = crate::asset::hash_hex(at.to_string().as_bytes());
        size
    } else {
        R::measure_size(&decisions)
    };
    let mut cache_note = None;
    if !options.force && dir.join(DESCRIPTION_FILE).exists() {
        let opened = AssetReader::open(&dir);
        // Read once: the files the folder holds that its asset.json does not list.
        let stray = match &opened {
            Ok(r) if r.description().cache_key == key => stray_files(r),
            _ => Vec::new(),
        };
        match opened {
            Ok(_) if !stray.is_empty() => {
                cache_note = Some(format!(
                    "cached folder holds files asset.json does not list: {}",
                    stray.join(", ")
                ));
            }
            Ok(r) if r.description().cache_key == key => {
                let rep = &r.description().report;
                let measurement =
                    serde_json::from_value::<Measurement>(rep["measurement"].clone()).ok();
                // Reused when it has its figures, or when none are wanted.
                if measurement.is_some() || !options.measure {
                    return Ok(Built::Done(Box::new(AssetOutcome {
                        asset: source.name.into(),
                        representation: R::NAME.into(),
                        outcome: Outcome::Cached,
                        plan,
                        seconds: t0.elapsed().as_secs_f64(),
                        build_seconds: rep["build_seconds"].as_f64().unwrap_or(0.0),
                        bytes: r.description().data_bytes(),
                        cache_note: None,
                        measurement,
                        // Empty for a folder built without measuring.
                        pictures: serde_json::from_value(rep["pictures"].clone())
                            .unwrap_or_default(),
                        details: R::details(&rep["build"]),
                    })));
                }
                cache_note = Some(
                    "cached folder has no measurement (built without measuring, or interrupted)"
                        .into(),
                );
            }
            Ok(_) => cache_note = Some("inputs, parameters or needs changed".into()),
            Err(e) => cache_note = Some(format!("cached folder invalid: {e}")),
        }
    }
    let tb = Instant::now();
    let (data, build_report) = R::build(spec, needs, &decisions, source)?;
    let build_seconds = tb.elapsed().as_secs_f64();
    let writing = crate::profile::timer("writing");
    let mut w = AssetWriter::new(&options.out, source.name, R::NAME)?;
    let metadata = R::write(&data, &mut w)?;
    drop(data);
    let report = json!({
        "build_seconds": build_seconds,
        "build": build_report,
        "plan": plan,
    });
    let mut desc = w.commit(
        R::NAME,
        source.name,
        &key,
        Conventions::new(1.0, 2.0).placed(source.placement.as_ref()),
        metadata,
        report,
    )?;
    writing.stop();
    drop(scope);
    let mut outcome = AssetOutcome {
        asset: source.name.into(),
        representation: R::NAME.into(),
        outcome: Outcome::Built,
        plan,
        seconds: t0.elapsed().as_secs_f64(),
        build_seconds,
        bytes: desc.data_bytes(),
        cache_note,
        measurement: None,
        pictures: Vec::new(),
        details: R::details(&desc.report["build"]),
    };
    if !options.measure {
        return Ok(Built::Done(Box::new(outcome)));
    }
    Ok(Built::Committed(Box::new(move || {
        let t1 = Instant::now();
        let _scope = profile.map(|p| p.scope(source.name, R::NAME));
        // Measure what a renderer would load: the files just written.
        let measuring = crate::profile::timer("measure");
        let loaded = R::read(&AssetReader::open(&dir)?)?;
        let (measurement, mut pictures) = R::measure(&loaded, measured, measure_size, source)?;
        measuring.stop();
        let _reporting = crate::profile::timer("report");
        pictures.extend(R::plots(&desc.report["build"], source.name)?);
        let mut written = Vec::new();
        for p in pictures {
            let rel = format!("pictures/{}", p.file);
            // Written beside and renamed into place, as every file of the run: a link or a
            // hard link at the picture's name is replaced, never written through.
            let image = magnify(&p.image.over([1.0, 1.0, 1.0]), 192);
            let codes = crate::asset::CodeImage {
                width: image.width,
                height: image.height,
                channels: 4,
                data: image.srgb8_codes(),
            };
            let png = crate::asset::encode_png(&codes).map_err(|reason| {
                crate::asset::AssetError::BadData {
                    role: rel.clone(),
                    reason,
                }
            })?;
            write_atomic(&options.out.join(&rel), &png)?;
            written.push((rel, p.caption));
        }
        desc.report["measurement"] = serde_json::to_value(&measurement).unwrap_or_default();
        desc.report["pictures"] = serde_json::to_value(&written).unwrap_or_default();
        let text = desc
            .sealed_json()
            .map_err(|e| PipelineError::Spec(e.to_string()))?;
        write_atomic(&dir.join(DESCRIPTION_FILE), &text)?;
        outcome.seconds += t1.elapsed().as_secs_f64();
        outcome.measurement = Some(measurement);
        outcome.pictures = written;
        Ok(outcome)
    })))
}

/// `image` with every pixel repeated so that it is at least `min_height` pixels high (nearest
/// neighbour: the pixels stay visible as they are).
fn magnify(image: &altrep_data_gen::RgbaImage, min_height: usize) -> altrep_data_gen::RgbaImage {
    let k = min_height.div_ceil(image.height.max(1)).max(1);
    let (w, h) = (image.width * k, image.height * k);
    let mut out = altrep_data_gen::RgbaImage::new(w, h);
    for (n, px) in out.pixels.iter_mut().enumerate() {
        *px = image.get((n % w) / k, (n / w) / k);
    }
    out
}

/// Writes `report.json` and `report.md` (atomically).
fn write_report(summary: &RunSummary, options: &RunOptions) -> Result<(), PipelineError> {
    let json =
        serde_json::to_vec_pretty(summary).map_err(|e| PipelineError::Spec(e.to_string()))?;
    write_atomic(&options.out.join("report.json"), &json)?;
    let mut md = format!(
        "# altrep precompute report\n\naltrep {}; wall time {:.2} s{}.\n\n{}\n",
        env!("CARGO_PKG_VERSION"),
        summary.wall_seconds,
        if options.everything {
            " (needs ignored when building: everything computed; measured as the plan for the needs measures, at their directions and the sizes it chooses, so the figures compare with a planned run's)"
        } else {
            ""
        },
        summary.table()
    );
    if !summary.source_notes.is_empty() {
        md += "\n## What the sources hold that altrep does not read\n\n";
        for (asset, notes) in &summary.source_notes {
            md += &format!("- {asset}: {}\n", notes.join("; "));
        }
    }
    md += "\n## Memory plan (estimated before the run)\n\n";
    md += "Peak memory and files (uncompressed, at most) per representation, from the parameters and the needs; the run's peak counts the assets that run at once. Files written: the bytes column of the table above.\n\n";
    for line in summary.memory.lines() {
        md += &format!("- {line}\n");
    }
    for o in &summary.outcomes {
        md += &format!("\n## {} — {}\n\n", o.asset, o.representation);
        if let Some(m) = &o.measurement {
            md += &format!("Measured: {}.\n\n", m.method);
        }
        if let Some(r) = &o.plan.refused {
            md += &format!("**Refused**: {r}.\n\n");
        }
        if let Some(n) = &o.cache_note {
            md += &format!("Rebuilt: {n}.\n\n");
        }
        for item in &o.plan.items {
            match &item.skipped {
                None => md += &format!("- built: {}\n", item.what),
                Some(r) => md += &format!("- **skipped**: {} — {r}\n", item.what),
            }
        }
        for (file, caption) in &o.pictures {
            md += &format!("\n![{caption}]({file})\n\n_{caption} (pixels magnified)_\n");
        }
        if let Some(d) = &o.details {
            md += &format!("\n{d}");
        }
    }
    if let Some(p) = &summary.profile {
        md += &format!("\n## Per-stage profile\n\n{}", p.markdown());
    }
    if !summary.other_shards.is_empty() {
        md += &format!(
            "\nLeft to other shards: {}.\n",
            summary.other_shards.join(", ")
        );
    }
    write_atomic(&options.out.join("report.md"), md.as_bytes())?;
    Ok(())
}
