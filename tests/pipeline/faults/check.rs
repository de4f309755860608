//! Running a case (in this process or as the command, interrupted or not) and checking what it
//! did against what it expects.

use super::*;

/// What a case ran and expects; `extra`: paths outside altrep's layout it may create (a
/// `--json` file); `gone`: paths the run must remove (stray files in altrep's folders).
pub(super) struct Plan {
    /// Taken when the case runs.
    pub(super) run: Option<Run>,
    pub(super) expect: Expect,
    pub(super) extra: Vec<PathBuf>,
    pub(super) gone: Vec<PathBuf>,
}

impl Plan {
    pub(super) fn lib(expect: Expect) -> Self {
        Self::with(
            Run::Lib {
                force: false,
                measure: true,
            },
            expect,
        )
    }
    pub(super) fn forced(expect: Expect) -> Self {
        Self::with(
            Run::Lib {
                force: true,
                measure: true,
            },
            expect,
        )
    }
    pub(super) fn bin(args: &[&std::ffi::OsStr], expect: Expect) -> Self {
        Self::with(Run::Bin(args.iter().map(|a| a.into()).collect()), expect)
    }
    pub(super) fn custom(f: impl FnOnce(&mut Trap) -> Observed + 'static) -> Self {
        Self::with(Run::Custom(Box::new(f)), Expect::Ok)
    }
    pub(super) fn with(run: Run, expect: Expect) -> Self {
        Self {
            run: Some(run),
            expect,
            extra: Vec::new(),
            gone: Vec::new(),
        }
    }
    pub(super) fn gone(mut self, p: PathBuf) -> Self {
        self.gone.push(p);
        self
    }
    pub(super) fn extra(mut self, p: PathBuf) -> Self {
        self.extra.push(p);
        self
    }
}

/// What a run did: its summary line or error message, the path its typed error names (runs in
/// this process), and a panic.
pub(super) struct Observed {
    pub(super) result: Result<String, String>,
    pub(super) typed: Option<PathBuf>,
    pub(super) panicked: Option<String>,
}

impl Observed {
    pub(super) fn ok(s: impl Into<String>) -> Self {
        Self {
            result: Ok(s.into()),
            typed: None,
            panicked: None,
        }
    }
    pub(super) fn err(s: impl Into<String>) -> Self {
        Self {
            result: Err(s.into()),
            typed: None,
            panicked: None,
        }
    }
}

/// The path a typed error names.
pub(super) fn error_path(e: &PipelineError) -> Option<PathBuf> {
    match e {
        PipelineError::Io { path, .. }
        | PipelineError::Locked { path }
        | PipelineError::Manifest { path, .. }
        | PipelineError::TextureFile { path, .. } => Some(path.clone()),
        PipelineError::Asset(
            AssetError::Io { path, .. }
            | AssetError::NotOurs { path, .. }
            | AssetError::Malformed { path, .. }
            | AssetError::NewerVersion { path, .. }
            | AssetError::MissingFile { path }
            | AssetError::Altered { path, .. }
            | AssetError::Decode { path, .. }
            | AssetError::Content { path, .. },
        ) => Some(path.clone()),
        PipelineError::DataGen(altrep_data_gen::DataGenError::Io { path, .. }) => {
            Some(path.clone())
        }
        _ => None,
    }
}

pub(super) fn summary_observed(s: &RunSummary) -> Observed {
    let failed: Vec<String> = s
        .outcomes
        .iter()
        .filter_map(|o| match &o.outcome {
            Outcome::Failed(m) => Some(format!("{}/{} failed: {m}", o.asset, o.representation)),
            _ => None,
        })
        .collect();
    if failed.is_empty() {
        let n = |x: Outcome| s.outcomes.iter().filter(|o| o.outcome == x).count();
        Observed::ok(format!(
            "{} built, {} cached",
            n(Outcome::Built),
            n(Outcome::Cached)
        ))
    } else {
        Observed::err(failed.join("; "))
    }
}

pub(super) fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "a panic".into())
}

/// `run_scene` into `out`, a panic caught.
pub(super) fn lib_run(manifest: &Manifest, out: &Path, force: bool, measure: bool) -> Observed {
    let o = RunOptions {
        force,
        measure,
        ..options(out)
    };
    match catch_unwind(AssertUnwindSafe(|| run_scene(manifest, &o))) {
        Err(p) => Observed {
            result: Err("panicked".into()),
            typed: None,
            panicked: Some(panic_text(p.as_ref())),
        },
        Ok(Ok(s)) => summary_observed(&s),
        Ok(Err(e)) => Observed {
            result: Err(e.to_string()),
            typed: error_path(&e),
            panicked: None,
        },
    }
}

/// What a finished command did: a panic is an exit code of 101 or 134, a signal, or
/// "panicked" on stderr.
pub(super) fn bin_observed(o: &std::process::Output) -> Observed {
    let err = String::from_utf8_lossy(&o.stderr).trim().to_string();
    let panicked = (err.contains("panicked")
        || matches!(o.status.code(), Some(101 | 134))
        || o.status.signal().is_some())
    .then(|| format!("{}: {err}", o.status));
    let result = if o.status.success() {
        let stdout = String::from_utf8_lossy(&o.stdout);
        Ok(stdout.lines().last().unwrap_or("").to_string())
    } else {
        Err(err)
    };
    Observed {
        result,
        typed: None,
        panicked,
    }
}

/// `altrep precompute MANIFEST --out OUT ARGS…`.
pub(super) fn precompute(t: &Trap, args: &[&std::ffi::OsStr]) -> Command {
    let mut c = Command::new(BIN);
    c.arg("precompute")
        .arg(&t.manifest)
        .arg("--out")
        .arg(&t.out)
        .args(args);
    c
}

/// Whether the files under `lands` are those of a clean run of [`TINY`].
pub(super) fn equals_clean(lands: &Path) -> Result<(), String> {
    for (key, want) in &clean().assets {
        let got = fingerprint(&lands.join(key)).map_err(|e| format!("{key}: {e}"))?;
        if &got != want {
            return Err(format!("{key} differs from a clean run's"));
        }
    }
    Ok(())
}

/// Every asset folder present under `lands` opens (no half-written asset).
pub(super) fn complete(t: &Trap) -> Result<(), String> {
    for (a, reprs) in layout(&t.scene) {
        for r in reprs {
            let d = t.lands.join(&a).join(r);
            if d.exists() {
                AssetReader::open(&d).map_err(|e| format!("half-written {a}/{r}: {e}"))?;
            }
        }
    }
    Ok(())
}

/// When an interrupt lands.
#[derive(Clone, Copy, Debug)]
pub(super) enum When {
    /// As soon as the lock file exists.
    Lock,
    /// As soon as a file is being written in `.staging`.
    Staged,
    /// As soon as an asset folder is committed.
    Committed,
    /// As soon as a report picture exists.
    Picture,
    /// After this share of a clean run's wall time.
    After(f64),
}

impl When {
    pub(super) fn reached(self, t: &Trap, t0: Instant) -> bool {
        let has = |d: &Path| std::fs::read_dir(d).is_ok_and(|mut e| e.next().is_some());
        match self {
            Self::Lock => t.lands.join(LOCK_FILE).exists(),
            Self::Staged => std::fs::read_dir(t.lands.join(STAGING_DIR))
                .is_ok_and(|d| d.flatten().any(|e| has(&e.path()))),
            Self::Committed => layout(&t.scene).iter().any(|(a, reprs)| {
                reprs
                    .iter()
                    .any(|r| t.lands.join(a).join(r).join(DESCRIPTION_FILE).exists())
            }),
            Self::Picture => has(&t.lands.join("pictures")),
            Self::After(share) => t0.elapsed().as_secs_f64() >= share * clean().seconds,
        }
    }
}

/// Interrupts that landed while the run was going on.
pub(super) static LANDED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Starts the command, sends `signal` when `when` is reached (unless it finished first), and
/// checks what the interrupt left: no panic, every asset folder present complete. Returns
/// whether the signal landed mid-run.
pub(super) fn interrupt(
    t: &Trap,
    signal: &str,
    when: When,
    args: &[&std::ffi::OsStr],
) -> Result<bool, String> {
    let mut child = precompute(t, args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !when.reached(t, t0)
        && child.try_wait().unwrap().is_none()
        && t0.elapsed() < Duration::from_secs(30)
    {
        std::thread::sleep(Duration::from_micros(500));
    }
    let running = child.try_wait().unwrap().is_none();
    if running {
        Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
    }
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("panicked") || matches!(o.status.code(), Some(101 | 134)) {
        return Err(format!("the run panicked: {err}"));
    }
    // SIGINT and SIGTERM are caught: the run says what it finished and exits with 130.
    let landed = o.status.signal().is_some()
        || (o.status.code() == Some(130) && err.contains("interrupted: "));
    if landed {
        LANDED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    if !landed && !o.status.success() {
        return Err(format!("the run failed before the {signal}: {err}"));
    }
    complete(t)?;
    Ok(landed)
}

/// The command run to the end; its error otherwise.
pub(super) fn finish(t: &Trap) -> Result<(), String> {
    let o = bin_observed(&precompute(t, &[]).output().unwrap());
    if let Some(p) = o.panicked {
        return Err(format!("the rerun panicked: {p}"));
    }
    o.result
        .map(|_| ())
        .map_err(|e| format!("the rerun failed: {e}"))
}

/// A case that interrupts a run with `signal` at `when`, then reruns to the end: the rerun's
/// files are a clean run's.
pub(super) fn interrupted(signal: &'static str, when: When) -> Plan {
    Plan::custom(move |t| {
        let r = interrupt(t, signal, when, &[]).and_then(|landed| {
            finish(t)?;
            equals_clean(&t.lands)?;
            Ok(format!(
                "SIG{signal} at {when:?}: {}; the rerun equals a clean run",
                if landed {
                    "killed mid-run, no half asset"
                } else {
                    "the run had finished"
                }
            ))
        });
        match r {
            Ok(s) => Observed::ok(s),
            Err(e) => Observed::err(e),
        }
    })
}

/// `p` relative to the case's root, for the printed table.
pub(super) fn rel(t: &Trap, p: &Path) -> String {
    p.strip_prefix(&t.base)
        .map_or_else(|_| p.display().to_string(), |r| r.display().to_string())
}

impl Expect {
    pub(super) fn describe(&self, t: &Trap) -> String {
        match self {
            Self::Ok => "succeeds".into(),
            Self::Refused(p) => format!("refused, naming {}", rel(t, p)),
            Self::Stops(p) => format!("stops before any work, naming {}", rel(t, p)),
            Self::Fails(p) => format!("fails, naming {}", rel(t, p)),
            Self::DiskFull => "fails: no space left on device".into(),
            Self::Either => "errs or succeeds (fault not simulated here)".into(),
        }
    }
}

/// The harm the run did and where it missed its expectation (empty: none).
pub(super) fn check(
    t: &Trap,
    plan: &Plan,
    in_process: bool,
    obs: &Observed,
    before: &Snap,
    after: &Snap,
) -> Vec<String> {
    let mut problems = Vec::new();
    if let Some(p) = &obs.panicked {
        problems.push(format!("panicked: {p}"));
    }
    let named = |p: &Path| match &obs.result {
        Err(m) => m.contains(&p.display().to_string()),
        Ok(_) => false,
    };
    // Nothing changed but the lock file a run creates before it refuses, and altrep's own
    // staging folder, cleared before the checks.
    let staging = t.lands.join(STAGING_DIR);
    let own_staging =
        t.owned.get(&staging) == Some(&Entry::Dir) && before.get(&staging) == Some(&Entry::Dir);
    let untouched = |problems: &mut Vec<String>| {
        let kept = |s: &Snap| -> Snap {
            s.iter()
                .filter(|(p, _)| !(own_staging && p.starts_with(&staging)))
                .filter(|(p, _)| {
                    **p != t.lands.join(LOCK_FILE) || before.contains_key(&t.lands.join(LOCK_FILE))
                })
                .map(|(p, e)| (p.clone(), e.clone()))
                .collect()
        };
        if kept(after) != kept(before) {
            problems.push("refused, yet the file system changed".into());
        }
    };
    match &plan.expect {
        Expect::Ok => {
            if let Err(e) = &obs.result {
                problems.push(format!("expected success: {e}"));
            } else {
                for (a, reprs) in layout(&t.scene) {
                    for r in reprs {
                        if let Err(e) = AssetReader::open(&t.lands.join(&a).join(r)) {
                            problems.push(format!("{a}/{r} does not open: {e}"));
                        }
                    }
                }
            }
        }
        Expect::Refused(p) => {
            if !named(p) || !matches!(&obs.result, Err(m) if m.contains("altrep writes only")) {
                problems.push(format!("expected a refusal naming {}", p.display()));
            }
            if in_process && obs.typed.as_deref() != Some(p.as_path()) {
                problems.push(format!("the typed error names {:?}", obs.typed));
            }
            untouched(&mut problems);
        }
        Expect::Stops(p) => {
            if !named(p) {
                problems.push(format!("expected an error naming {}", p.display()));
            }
            if in_process && obs.typed.is_none() {
                problems.push("the error is not a typed one with its path".into());
            }
            untouched(&mut problems);
        }
        Expect::Fails(p) => {
            if !named(p) {
                problems.push(format!("expected an error naming {}", p.display()));
            }
        }
        Expect::DiskFull => {
            if !named(&t.lands)
                || !matches!(&obs.result, Err(m) if m.contains("No space left on device"))
            {
                problems.push("expected a full-disk error naming its path".into());
            }
        }
        Expect::Either => {}
    }
    // The user's entries: everything but what altrep wrote (an earlier run's entries as it left
    // them, anything inside an asset folder it wrote, and in a folder it ran in, its staging
    // folder and the files it writes at the top and in `pictures`).
    let w = &t.lands;
    let assets = layout(&t.scene);
    let pictures: Vec<String> = assets
        .iter()
        .flat_map(|(a, rs)| rs.iter().map(move |r| format!("{a}-{r}.png")))
        .collect();
    let ran_here = matches!(before.get(&w.join(LOCK_FILE)), Some(Entry::File(_)));
    let altreps = |p: &Path| -> bool {
        let Ok(r) = p.strip_prefix(w) else {
            return false;
        };
        if plan.gone.iter().any(|g| p.starts_with(g))
            || (t.owned.contains_key(p) && t.owned.get(p) == before.get(p))
        {
            return true;
        }
        let c: Vec<String> = r
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        if c.len() >= 3 {
            let folder = w.join(&c[0]).join(&c[1]);
            if t.owned.contains_key(&folder.join(DESCRIPTION_FILE))
                && before.get(&folder) == Some(&Entry::Dir)
            {
                return true;
            }
        }
        ran_here
            && match c.as_slice() {
                [s, _, ..] if s == STAGING_DIR => true,
                [f] => f == "report.md" || f == "report.json",
                [d, f] => d == "pictures" && pictures.contains(f),
                _ => false,
            }
    };
    for (p, e) in before {
        let now = after.get(p);
        if now != Some(e) && !altreps(p) {
            let how = if now.is_none() { "removed" } else { "changed" };
            problems.push(format!("{} {how}", rel(t, p)));
        }
    }
    // New entries: only altrep's layout under where the files land.
    let in_layout = |p: &Path| -> bool {
        let Ok(r) = p.strip_prefix(w) else {
            return false;
        };
        let c: Vec<String> = r
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        match c.as_slice() {
            [] => true,
            [f] if [
                LOCK_FILE,
                "report.md",
                "report.json",
                "pictures",
                STAGING_DIR,
            ]
            .contains(&f.as_str()) =>
            {
                true
            }
            [d, f] if d == "pictures" => pictures.contains(f),
            [s, ..] if s == STAGING_DIR => true,
            [a, rest @ ..] => assets.iter().any(|(name, reprs)| {
                name == a && rest.first().is_none_or(|r| reprs.contains(&r.as_str()))
            }),
        }
    };
    for p in after.keys().filter(|p| !before.contains_key(*p)) {
        if !in_layout(p) && !plan.extra.contains(p) {
            problems.push(format!("{} created", rel(t, p)));
        }
    }
    for p in &t.protect {
        if before.get(p) != after.get(p) {
            problems.push(format!("the user's {} lost or changed", rel(t, p)));
        }
    }
    for p in &plan.gone {
        if after.contains_key(p) {
            problems.push(format!("{} should be gone", rel(t, p)));
        }
    }
    // No half-written asset: every asset folder the run touched opens.
    for (a, reprs) in &assets {
        for r in reprs {
            let d = w.join(a).join(r);
            let changed = !under(before, &d).eq(under(after, &d));
            if changed
                && after.get(&d) == Some(&Entry::Dir)
                && let Err(e) = AssetReader::open(&d)
            {
                problems.push(format!("half-written {a}/{r}: {e}"));
            }
        }
    }
    problems
}

pub(super) type Setup = fn(&mut Trap) -> Plan;

/// Runs each case in its own root, prints one line per case, and returns the cases that did
/// harm or missed their expectation.
pub(super) fn run_cases(cases: &[(&str, Setup)]) -> Vec<String> {
    let mut failures = Vec::new();
    let t_all = Instant::now();
    for (name, setup) in cases {
        let t0 = Instant::now();
        let mut t = Trap::new();
        let mut plan = setup(&mut t);
        if !t.manifest.exists() {
            std::fs::write(&t.manifest, &t.scene).unwrap();
        }
        t.protect.push(t.manifest.clone());
        if t.lands == t.out {
            t.lands = std::fs::canonicalize(&t.out).unwrap_or(t.out.clone());
            if t.lands != t.out {
                t.owned = snap(&t.lands);
            }
        }
        let expect = plan.expect.describe(&t);
        let before = snap(&t.base);
        let run = plan.run.take().expect("each plan runs once");
        let in_process = matches!(run, Run::Lib { .. });
        let obs = match run {
            Run::Lib { force, measure } => lib_run(&t.parsed(), &t.out, force, measure),
            Run::Bin(args) => {
                let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
                bin_observed(&precompute(&t, &args).output().unwrap())
            }
            Run::BinArgs(args) => bin_observed(&Command::new(BIN).args(args).output().unwrap()),
            Run::Custom(f) => match catch_unwind(AssertUnwindSafe(|| f(&mut t))) {
                Ok(o) => o,
                Err(p) => Observed {
                    result: Err("the case panicked".into()),
                    typed: None,
                    panicked: Some(panic_text(p.as_ref())),
                },
            },
        };
        let after = snap(&t.base);
        let problems = check(&t, &plan, in_process, &obs, &before, &after);
        let root = t.base.display().to_string();
        let observed = match &obs.result {
            Ok(s) => format!("ok ({})", s.replace(&root, "ROOT")),
            Err(m) => {
                let m = m.replace(&root, "ROOT");
                format!("error: {}", m.chars().take(240).collect::<String>())
            }
        };
        eprintln!(
            "{} {name} → expected: {expect}; observed: {observed} [{:.2} s]",
            if problems.is_empty() { "ok  " } else { "FAIL" },
            t0.elapsed().as_secs_f64()
        );
        for p in &problems {
            eprintln!("       {p}");
        }
        if !problems.is_empty() {
            failures.push(format!("{name}: {}", problems.join("; ")));
        }
    }
    eprintln!(
        "{} cases in {:.1} s",
        cases.len(),
        t_all.elapsed().as_secs_f64()
    );
    failures
}

/// The `k`-th seeded share of a run's wall time in `[0.05, 0.95)` (SplitMix64): the random,
/// repeatable points where interrupts land.
pub(super) fn share(k: u64) -> f64 {
    let mut z = 20261204u64.wrapping_add(k.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    0.05 + 0.9 * (z >> 11) as f64 / (1u64 << 53) as f64
}

/// `bytes` written where altrep wrote `rel` (an edit of the user's in altrep's output).
pub(super) fn overwrite(t: &Trap, rel: &str, bytes: &[u8]) {
    std::fs::write(t.at(rel), bytes).unwrap();
}

pub(super) fn remove(t: &Trap, rel: &str) {
    let p = t.at(rel);
    if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_dir()) {
        std::fs::remove_dir_all(&p).unwrap();
    } else {
        std::fs::remove_file(&p).unwrap();
    }
}

/// A hard link at `outside/name` to `rel`, protected: the user's copy of an output.
pub(super) fn hard_copy(t: &mut Trap, rel: &str, name: &str) {
    let p = t.outside.join(name);
    std::fs::hard_link(t.at(rel), &p).unwrap();
    t.protect.push(p);
}
