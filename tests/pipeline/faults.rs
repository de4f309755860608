//! Output safety under scripted faults: what a user keeps around, beside and behind `--out`
//! (folders and files at the names altrep writes, symbolic and hard links at every level,
//! read-only paths, a full disk, interrupts, concurrent runs, edits between runs) is never
//! changed, and nothing outside `--out` appears or goes.
//!
//! Read-only paths and a full disk need root (the immutable attribute, bind and tmpfs mounts;
//! as another user a folder's mode stands in for read-only). Where a fault cannot be made, the
//! case says so on stderr ("NOT SIMULATED") and checks only that the run does no harm.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::os::unix::fs::symlink;
use std::os::unix::process::ExitStatusExt;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::process::Stdio;
use std::sync::OnceLock;

use super::*;
use altrep::asset::STAGING_DIR;
use altrep::pipeline::{LOCK_FILE, RunSummary};

/// Two assets, one representation each, small enough for a run in a fraction of a second.
const TINY: &str = "[[asset]]
name = \"pear\"
shape = \"pear\"
[asset.needs]
screen_px = [4, 16]
quality_db = 10
[asset.parallax]
views = 4
size = 16
[[asset]]
name = \"chair\"
shape = \"chair\"
[asset.needs]
screen_px = [4, 16]
quality_db = 10
[asset.octree]
resolution = 8
";

/// [`TINY`] with two more parallax views: a run replaces the pear's files and picture.
fn changed() -> String {
    TINY.replace("views = 4", "views = 6")
}

/// A closed box, as an OBJ mesh.
const BOX_OBJ: &str = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

/// A scene of one mesh asset, `mesh` relative to the manifest.
fn mesh_scene(mesh: &str) -> String {
    format!(
        "[[asset]]\nname = \"box\"\nmesh = \"{mesh}\"\n[asset.needs]\nscreen_px = [4, 16]\nquality_db = 10\n[asset.octree]\nresolution = 8\n[[asset]]\nname = \"chair\"\nshape = \"chair\"\n[asset.needs]\nscreen_px = [4, 16]\nquality_db = 10\n[asset.octree]\nresolution = 8\n"
    )
}

/// One entry of a snapshot, links not followed.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Entry {
    Dir,
    File(Vec<u8>),
    Link(PathBuf),
}

type Snap = BTreeMap<PathBuf, Entry>;

/// Every entry under `root` (not `root` itself): folders, files with their bytes, links with
/// their targets.
fn snap(root: &Path) -> Snap {
    let mut out = Snap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(dir) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in dir.flatten() {
            let p = e.path();
            let Ok(m) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            let entry = if m.file_type().is_symlink() {
                Entry::Link(std::fs::read_link(&p).unwrap_or_default())
            } else if m.is_dir() {
                stack.push(p.clone());
                Entry::Dir
            } else {
                Entry::File(
                    std::fs::read(&p).unwrap_or_else(|e| format!("unreadable: {e}").into_bytes()),
                )
            };
            out.insert(p, entry);
        }
    }
    out
}

/// The entries of `s` at or below `dir`.
fn under<'a>(s: &'a Snap, dir: &'a Path) -> impl Iterator<Item = (&'a PathBuf, &'a Entry)> {
    s.iter().filter(move |(p, _)| p.starts_with(dir))
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status").is_ok_and(|s| {
        s.lines()
            .find(|l| l.starts_with("Uid:"))
            .and_then(|l| l.split_whitespace().nth(2))
            == Some("0")
    })
}

/// Runs a system command quietly; whether it succeeded.
fn sh(cmd: &str, args: &[&std::ffi::OsStr]) -> bool {
    Command::new(cmd)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// The representations each asset of `scene` asks for: `(asset, [representation])`.
fn layout(scene: &str) -> Vec<(String, Vec<&'static str>)> {
    let m = Manifest::parse(scene, Path::new("scene.toml")).unwrap();
    m.assets
        .iter()
        .map(|a| {
            let mut r = Vec::new();
            for (name, wanted) in [
                ("parallax", a.parallax.is_some()),
                ("cylinder", a.cylinder.is_some()),
                ("octree", a.octree.is_some()),
                ("pyramid", a.pyramid.is_some()),
                ("sphere", a.sphere.is_some()),
            ] {
                if wanted {
                    r.push(name);
                }
            }
            (a.name.clone(), r)
        })
        .collect()
}

/// What every case compares with: a clean run of [`TINY`].
struct Clean {
    /// `asset/representation` → the files and cache key its `asset.json` lists.
    assets: BTreeMap<String, String>,
    /// Wall seconds of a clean run of the command.
    seconds: f64,
    /// 4 KiB pages the files of a clean run take.
    pages: u64,
    /// Entries (inodes) a clean run creates in its output folder.
    entries: u64,
}

/// What an asset folder holds, as its `asset.json` says: compared with [`Clean::assets`].
fn fingerprint(dir: &Path) -> Result<String, String> {
    let r = AssetReader::open(dir).map_err(|e| e.to_string())?;
    let d = r.description();
    Ok(format!("{:?} {}", d.files, d.cache_key))
}

fn clean() -> &'static Clean {
    static CLEAN: OnceLock<Clean> = OnceLock::new();
    CLEAN.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let m = Manifest::parse(TINY, &dir.path().join("scene.toml")).unwrap();
        let s = run_scene(&m, &options(&dir.path().join("lib"))).unwrap();
        assert!(s.ok(), "{}", s.table());
        let mut assets = BTreeMap::new();
        for (a, reprs) in layout(TINY) {
            for r in reprs {
                let key = format!("{a}/{r}");
                let f = fingerprint(&dir.path().join("lib").join(&key)).unwrap();
                assets.insert(key, f);
            }
        }
        let (mut pages, mut entries) = (0, 0);
        for (_, e) in snap(&dir.path().join("lib")) {
            entries += 1;
            if let Entry::File(b) = e {
                pages += (b.len() as u64).div_ceil(4096);
            }
        }
        // The command writes the same files as the library.
        std::fs::write(dir.path().join("scene.toml"), TINY).unwrap();
        let t0 = Instant::now();
        let o = Command::new(BIN)
            .arg("precompute")
            .arg(dir.path().join("scene.toml"))
            .arg("--out")
            .arg(dir.path().join("bin"))
            .output()
            .unwrap();
        let seconds = t0.elapsed().as_secs_f64();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for (key, f) in &assets {
            assert_eq!(&fingerprint(&dir.path().join("bin").join(key)).unwrap(), f);
        }
        Clean {
            assets,
            seconds,
            pages,
            entries,
        }
    })
}

/// A temporary root holding `out` (the `--out` of the run), `outside` beside it (with a file
/// of the user's) and the manifest; what a case made read-only or mounted is undone on drop.
struct Trap {
    /// Removed on drop, after the attributes and mounts are undone.
    _root: tempfile::TempDir,
    /// The root's path, links resolved (the paths errors name and snapshots hold).
    base: PathBuf,
    /// The `--out` of the run.
    out: PathBuf,
    /// A folder beside `out`.
    outside: PathBuf,
    /// Where the run's files land: `out`, or where a link at `out` leads.
    lands: PathBuf,
    /// The manifest and where it is written.
    scene: String,
    manifest: PathBuf,
    /// Entries altrep wrote in an earlier run (under `lands`).
    owned: Snap,
    /// The user's files the case names: byte for byte the same after the run.
    protect: Vec<PathBuf>,
    /// Paths given attributes (`chattr`), mounts, folders made read-only by mode: undone on drop.
    attrs: bool,
    mounts: Vec<PathBuf>,
    modes: Vec<PathBuf>,
}

impl Trap {
    fn new() -> Self {
        let root = tempfile::tempdir().unwrap();
        let base = std::fs::canonicalize(root.path()).unwrap();
        let (out, outside) = (base.join("out"), base.join("outside"));
        std::fs::create_dir_all(&outside).unwrap();
        let keep = outside.join("keep.txt");
        std::fs::write(&keep, "the user's").unwrap();
        let manifest = base.join("scene.toml");
        Self {
            base,
            lands: out.clone(),
            out,
            outside,
            scene: TINY.into(),
            manifest,
            owned: Snap::new(),
            protect: vec![keep],
            attrs: false,
            mounts: Vec::new(),
            modes: Vec::new(),
            _root: root,
        }
    }

    /// `rel` under the root.
    fn at(&self, rel: &str) -> PathBuf {
        self.base.join(rel)
    }

    fn parsed(&self) -> Manifest {
        Manifest::parse(&self.scene, &self.manifest).unwrap()
    }

    /// An earlier complete run of the case's scene into `out`: its entries are altrep's.
    fn prior(&mut self) {
        let s = run_scene(&self.parsed(), &options(&self.out)).unwrap();
        assert!(s.ok(), "{}", s.table());
        self.owned = snap(&self.lands);
    }

    /// A file of the user's at `rel` (parents created), protected.
    fn user(&mut self, rel: &str, bytes: &[u8]) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, bytes).unwrap();
        self.protect.push(p.clone());
        p
    }

    fn dir(&self, rel: &str) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(&p).unwrap();
        p
    }

    /// A symbolic link at `rel` to `target` (parents of the link created).
    fn link(&self, target: impl AsRef<Path>, rel: &str) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        symlink(target, &p).unwrap();
        p
    }

    /// Makes `p` read-only for root too: the immutable attribute, else a read-only bind mount;
    /// for another user, its mode. Whether writes to it now fail whatever the user.
    fn read_only(&mut self, p: &Path) -> bool {
        if !is_root() {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(p).unwrap().permissions().mode();
            std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode & !0o222)).unwrap();
            self.modes.push(p.to_path_buf());
            // A file whose mode forbids writing is still replaced by a rename.
            return p.is_dir();
        }
        if sh("chattr", &["+i".as_ref(), p.as_os_str()]) {
            self.attrs = true;
            return true;
        }
        self.read_only_mount(p)
    }

    /// Makes `p` read-only with a read-only bind mount; whether it could.
    fn read_only_mount(&mut self, p: &Path) -> bool {
        if sh("mount", &["--bind".as_ref(), p.as_os_str(), p.as_os_str()]) {
            self.mounts.push(p.to_path_buf());
            if sh(
                "mount",
                &["-o".as_ref(), "remount,bind,ro".as_ref(), p.as_os_str()],
            ) {
                return true;
            }
        }
        eprintln!(
            "!!! NOT SIMULATED: {} cannot be made read-only here (no chattr +i, no bind mount): \
             the case only checks that the run does no harm",
            p.display()
        );
        false
    }

    /// Makes folder `p` append-only (entries can be added, none removed or renamed).
    fn append_only(&mut self, p: &Path) -> bool {
        let ok = is_root() && sh("chattr", &["+a".as_ref(), p.as_os_str()]);
        if ok {
            self.attrs = true;
        } else {
            eprintln!(
                "!!! NOT SIMULATED: {} cannot be made append-only here (chattr +a needs root \
                 and a file system that has it): the case only checks that the run does no harm",
                p.display()
            );
        }
        ok
    }

    /// Mounts a tmpfs with `opts` at `p` (created); whether it could.
    fn tmpfs(&mut self, p: &Path, opts: &str) -> bool {
        std::fs::create_dir_all(p).unwrap();
        let ok = sh(
            "mount",
            &[
                "-t".as_ref(),
                "tmpfs".as_ref(),
                "-o".as_ref(),
                opts.as_ref(),
                "tmpfs".as_ref(),
                p.as_os_str(),
            ],
        );
        if ok {
            self.mounts.push(p.to_path_buf());
        } else {
            eprintln!(
                "!!! NOT SIMULATED: cannot mount a tmpfs at {} (needs root with CAP_SYS_ADMIN): \
                 the full-disk case only checks that the run does no harm",
                p.display()
            );
        }
        ok
    }

    /// Fills a tmpfs at `out` of `free + 1` pages with a file of the user's, leaving `free`
    /// pages; whether the tmpfs is there.
    fn full_disk(&mut self, free: u64) -> bool {
        let out = self.out.clone();
        if !self.tmpfs(&out, &format!("size={}k", 4 * (free + 1))) {
            return false;
        }
        self.user("out/filler.bin", &[7; 4096]);
        true
    }
}

impl Drop for Trap {
    fn drop(&mut self) {
        if self.attrs {
            sh(
                "chattr",
                &[
                    "-R".as_ref(),
                    "-i".as_ref(),
                    "-a".as_ref(),
                    self.base.as_os_str(),
                ],
            );
        }
        for m in self.mounts.iter().rev() {
            if !sh("umount", &[m.as_os_str()]) {
                sh("umount", &["-l".as_ref(), m.as_os_str()]);
            }
        }
        for p in &self.modes {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755));
        }
    }
}

/// How a case runs altrep.
enum Run {
    /// `run_scene` in this process.
    Lib { force: bool, measure: bool },
    /// `altrep precompute MANIFEST --out OUT` and these arguments.
    Bin(Vec<OsString>),
    /// The command with exactly these arguments.
    BinArgs(Vec<OsString>),
    /// Anything else (interrupts, concurrent runs): what it observed.
    Custom(Box<dyn FnOnce(&mut Trap) -> Observed>),
}

/// What a case expects of the run.
enum Expect {
    /// Every representation built or cached; every asset folder opens.
    Ok,
    /// Refused before any work, as not altrep's, naming the path; nothing changed.
    Refused(PathBuf),
    /// An error naming the path before any work; nothing changed but the lock file.
    Stops(PathBuf),
    /// An error naming the path (or a path under it), after some work.
    Fails(PathBuf),
    /// An error of a full disk (`os error 28`) naming a path under where the files land.
    DiskFull,
    /// The fault could not be simulated here: the run errs or succeeds, without harm.
    Either,
}

/// What a case ran and expects; `extra`: paths outside altrep's layout it may create (a
/// `--json` file); `gone`: paths the run must remove (stray files in altrep's folders).
struct Plan {
    /// Taken when the case runs.
    run: Option<Run>,
    expect: Expect,
    extra: Vec<PathBuf>,
    gone: Vec<PathBuf>,
}

impl Plan {
    fn lib(expect: Expect) -> Self {
        Self::with(
            Run::Lib {
                force: false,
                measure: true,
            },
            expect,
        )
    }
    fn forced(expect: Expect) -> Self {
        Self::with(
            Run::Lib {
                force: true,
                measure: true,
            },
            expect,
        )
    }
    fn bin(args: &[&std::ffi::OsStr], expect: Expect) -> Self {
        Self::with(Run::Bin(args.iter().map(|a| a.into()).collect()), expect)
    }
    fn custom(f: impl FnOnce(&mut Trap) -> Observed + 'static) -> Self {
        Self::with(Run::Custom(Box::new(f)), Expect::Ok)
    }
    fn with(run: Run, expect: Expect) -> Self {
        Self {
            run: Some(run),
            expect,
            extra: Vec::new(),
            gone: Vec::new(),
        }
    }
    fn gone(mut self, p: PathBuf) -> Self {
        self.gone.push(p);
        self
    }
    fn extra(mut self, p: PathBuf) -> Self {
        self.extra.push(p);
        self
    }
}

/// What a run did: its summary line or error message, the path its typed error names (runs in
/// this process), and a panic.
struct Observed {
    result: Result<String, String>,
    typed: Option<PathBuf>,
    panicked: Option<String>,
}

impl Observed {
    fn ok(s: impl Into<String>) -> Self {
        Self {
            result: Ok(s.into()),
            typed: None,
            panicked: None,
        }
    }
    fn err(s: impl Into<String>) -> Self {
        Self {
            result: Err(s.into()),
            typed: None,
            panicked: None,
        }
    }
}

/// The path a typed error names.
fn error_path(e: &PipelineError) -> Option<PathBuf> {
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

fn summary_observed(s: &RunSummary) -> Observed {
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

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "a panic".into())
}

/// `run_scene` into `out`, a panic caught.
fn lib_run(manifest: &Manifest, out: &Path, force: bool, measure: bool) -> Observed {
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
fn bin_observed(o: &std::process::Output) -> Observed {
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
fn precompute(t: &Trap, args: &[&std::ffi::OsStr]) -> Command {
    let mut c = Command::new(BIN);
    c.arg("precompute")
        .arg(&t.manifest)
        .arg("--out")
        .arg(&t.out)
        .args(args);
    c
}

/// Whether the files under `lands` are those of a clean run of [`TINY`].
fn equals_clean(lands: &Path) -> Result<(), String> {
    for (key, want) in &clean().assets {
        let got = fingerprint(&lands.join(key)).map_err(|e| format!("{key}: {e}"))?;
        if &got != want {
            return Err(format!("{key} differs from a clean run's"));
        }
    }
    Ok(())
}

/// Every asset folder present under `lands` opens (no half-written asset).
fn complete(t: &Trap) -> Result<(), String> {
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
enum When {
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
    fn reached(self, t: &Trap, t0: Instant) -> bool {
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
static LANDED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Starts the command, sends `signal` when `when` is reached (unless it finished first), and
/// checks what the interrupt left: no panic, every asset folder present complete. Returns
/// whether the signal landed mid-run.
fn interrupt(
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
fn finish(t: &Trap) -> Result<(), String> {
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
fn interrupted(signal: &'static str, when: When) -> Plan {
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
fn rel(t: &Trap, p: &Path) -> String {
    p.strip_prefix(&t.base)
        .map_or_else(|_| p.display().to_string(), |r| r.display().to_string())
}

impl Expect {
    fn describe(&self, t: &Trap) -> String {
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
fn check(
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

type Setup = fn(&mut Trap) -> Plan;

/// Runs each case in its own root, prints one line per case, and returns the cases that did
/// harm or missed their expectation.
fn run_cases(cases: &[(&str, Setup)]) -> Vec<String> {
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
fn share(k: u64) -> f64 {
    let mut z = 20261204u64.wrapping_add(k.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    0.05 + 0.9 * (z >> 11) as f64 / (1u64 << 53) as f64
}

/// `bytes` written where altrep wrote `rel` (an edit of the user's in altrep's output).
fn overwrite(t: &Trap, rel: &str, bytes: &[u8]) {
    std::fs::write(t.at(rel), bytes).unwrap();
}

fn remove(t: &Trap, rel: &str) {
    let p = t.at(rel);
    if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_dir()) {
        std::fs::remove_dir_all(&p).unwrap();
    } else {
        std::fs::remove_file(&p).unwrap();
    }
}

/// A hard link at `outside/name` to `rel`, protected: the user's copy of an output.
fn hard_copy(t: &mut Trap, rel: &str, name: &str) {
    let p = t.outside.join(name);
    std::fs::hard_link(t.at(rel), &p).unwrap();
    t.protect.push(p);
}

/// Faults set up around `--out` of runs in this process: the user's files and folders at the
/// names altrep writes, in a folder it never ran in and in one it did; symbolic links at every
/// level; hard links to its outputs; edits, stray files and leftovers between runs; read-only
/// folders and files (immutable attribute or read-only bind mount, as root); a full disk (a
/// small tmpfs, filled at several points, or out of inodes); missing or linked inputs; a held
/// lock and two runs at once. Each case checks that nothing panics, the run ends as expected
/// (success, or a typed error naming the offending path), every file of the user's is byte for
/// byte the same, nothing outside the folder the files land in appears, changes or goes, and
/// every asset folder the run touched is complete.
#[cfg(unix)]
#[test]
fn faults_around_the_output_folder_do_no_harm() {
    let cases: &[(&str, Setup)] = &[
        // The user's things where altrep writes, in a folder it never ran in.
        ("user report.json in a new --out", |t| {
            Plan::lib(Expect::Refused(t.user("out/report.json", b"{\"mine\": 1}")))
        }),
        ("user pictures folder in a new --out", |t| {
            t.user("out/pictures/holiday.png", b"not a png");
            Plan::lib(Expect::Refused(t.at("out/pictures")))
        }),
        ("user .staging folder in a new --out", |t| {
            t.user("out/.staging/draft.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/.staging")))
        }),
        ("user file named like the lock file", |t| {
            t.user("out/.altrep.lock", b"mine, not a lock");
            Plan::lib(Expect::Ok)
        }),
        ("user folder at an asset's name, with notes", |t| {
            t.user("out/pear/notes.txt", b"mine");
            Plan::lib(Expect::Ok)
        }),
        ("user folder at an asset/representation name", |t| {
            t.user("out/pear/parallax/notes.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/pear/parallax")))
        }),
        ("empty asset.json", |t| {
            Plan::lib(Expect::Refused(t.user("out/pear/parallax/asset.json", b"")))
        }),
        ("garbage asset.json", |t| {
            let p = t.user(
                "out/chair/octree/asset.json",
                &[0xff, 0x00, 0x9c, 0x7b, 0x0a],
            );
            Plan::lib(Expect::Refused(p))
        }),
        ("valid JSON asset.json that is not altrep's", |t| {
            let p = t.user(
                "out/pear/parallax/asset.json",
                b"{\"name\": \"pear\", \"v\": 3}",
            );
            Plan::lib(Expect::Refused(p))
        }),
        ("another tool's asset.json (an image catalogue)", |t| {
            let p = t.user(
                "out/chair/octree/asset.json",
                br#"{"info": {"author": "xcode", "version": 1}, "images": [{"filename": "chair.png", "idiom": "universal"}]}"#,
            );
            t.user("out/chair/octree/chair.png", b"not a png");
            Plan::lib(Expect::Refused(p))
        }),
        ("a newer altrep's asset folder", |t| {
            t.prior();
            let p = t.at("out/pear/parallax/asset.json");
            let mut v: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            v["format_version"] = serde_json::json!([2, 0]);
            v["a_field_of_format_2"] = true.into();
            std::fs::write(&p, v.to_string()).unwrap();
            t.protect.push(p.clone());
            Plan::lib(Expect::Refused(p))
        }),
        ("asset.json a folder", |t| {
            t.user("out/chair/octree/asset.json/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/chair/octree/asset.json")))
        }),
        ("a file where an asset folder goes", |t| {
            Plan::lib(Expect::Refused(t.user("out/chair", b"mine")))
        }),
        ("a file where a representation folder goes", |t| {
            Plan::lib(Expect::Refused(t.user("out/chair/octree", b"mine")))
        }),
        ("report.md a folder, in a folder altrep ran in", |t| {
            t.prior();
            remove(t, "out/report.md");
            t.user("out/report.md/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/report.md")))
        }),
        ("pictures a file, in a folder altrep ran in", |t| {
            t.prior();
            remove(t, "out/pictures");
            Plan::lib(Expect::Refused(t.user("out/pictures", b"mine")))
        }),
        (".staging a file, in a folder altrep ran in", |t| {
            t.prior();
            let _ = std::fs::remove_dir_all(t.at("out/.staging"));
            Plan::lib(Expect::Refused(t.user("out/.staging", b"mine")))
        }),
        ("the lock file a folder", |t| {
            t.user("out/.altrep.lock/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/.altrep.lock")))
        }),
        // The user's things beside altrep's.
        ("user files beside altrep's, in a folder it ran in", |t| {
            t.prior();
            t.user("out/notes.txt", b"mine");
            t.user("out/pear/notes.txt", b"mine");
            t.user("out/pictures/mine.png", b"mine");
            Plan::forced(Expect::Ok)
        }),
        ("a user folder of other things in --out", |t| {
            t.user("out/mine/photo.png", b"mine");
            t.user("out/mine/deep/x.txt", b"mine");
            Plan::lib(Expect::Ok)
        }),
        ("an asset no longer in the scene", |t| {
            t.prior();
            t.protect.push(t.at("out/pear/parallax/asset.json"));
            t.protect.push(t.at("out/pear/parallax/view0-albedo.png"));
            t.scene = TINY
                .split("[[asset]]")
                .nth(2)
                .map(|c| format!("[[asset]]{c}"))
                .unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("an asset folder the user renamed", |t| {
            t.prior();
            std::fs::rename(t.at("out/pear/parallax"), t.at("out/pear/parallax-mine")).unwrap();
            t.protect.push(t.at("out/pear/parallax-mine/asset.json"));
            Plan::lib(Expect::Ok)
        }),
        // Symbolic links at every level.
        ("asset folder a link to a folder outside", |t| {
            t.user("outside/elsewhere/parallax/notes.txt", b"mine");
            let p = t.link(t.at("outside/elsewhere"), "out/pear");
            Plan::lib(Expect::Refused(p))
        }),
        (
            "representation folder a link to altrep's asset outside",
            |t| {
                let elsewhere = t.at("outside/elsewhere");
                assert!(run_scene(&t.parsed(), &options(&elsewhere)).unwrap().ok());
                let p = t.link(elsewhere.join("pear/parallax"), "out/pear/parallax");
                Plan::lib(Expect::Refused(p))
            },
        ),
        ("asset.json a link to a file outside", |t| {
            let p = t.link(t.at("outside/keep.txt"), "out/chair/octree/asset.json");
            Plan::lib(Expect::Refused(p))
        }),
        ("asset folder a dangling link", |t| {
            Plan::lib(Expect::Refused(t.link(t.at("outside/nowhere"), "out/pear")))
        }),
        ("asset folders linked in a loop", |t| {
            t.link(t.at("out/pear"), "out/pear2");
            Plan::lib(Expect::Refused(t.link(t.at("out/pear2"), "out/pear")))
        }),
        ("representation folder a link to itself", |t| {
            Plan::lib(Expect::Refused(t.link("octree", "out/chair/octree")))
        }),
        ("pictures a link to a folder outside", |t| {
            t.user("outside/photos/holiday.png", b"mine");
            Plan::lib(Expect::Refused(
                t.link(t.at("outside/photos"), "out/pictures"),
            ))
        }),
        (
            "report.md a link to a file outside, in a folder altrep ran in",
            |t| {
                t.prior();
                remove(t, "out/report.md");
                Plan::lib(Expect::Refused(
                    t.link(t.at("outside/keep.txt"), "out/report.md"),
                ))
            },
        ),
        ("report.json a dangling link", |t| {
            let p = t.link(t.at("outside/summary.json"), "out/report.json");
            Plan::lib(Expect::Refused(p))
        }),
        (
            ".staging a link to a folder outside, in a folder altrep ran in",
            |t| {
                t.prior();
                let _ = std::fs::remove_dir_all(t.at("out/.staging"));
                t.user("outside/drafts/a.txt", b"mine");
                Plan::lib(Expect::Refused(
                    t.link(t.at("outside/drafts"), "out/.staging"),
                ))
            },
        ),
        ("the lock file a link to a file outside", |t| {
            Plan::lib(Expect::Refused(
                t.link(t.at("outside/keep.txt"), "out/.altrep.lock"),
            ))
        }),
        ("a picture a link to a file outside", |t| {
            t.prior();
            remove(t, "out/pictures/pear-parallax.png");
            t.user("outside/holiday.png", b"the user's photo");
            t.link(
                t.at("outside/holiday.png"),
                "out/pictures/pear-parallax.png",
            );
            Plan::forced(Expect::Ok)
        }),
        ("a picture a dangling link out of --out", |t| {
            t.prior();
            remove(t, "out/pictures/chair-octree.png");
            t.link(t.at("outside/new.png"), "out/pictures/chair-octree.png");
            Plan::forced(Expect::Ok)
        }),
        ("a folder of the user's at a picture's name", |t| {
            t.prior();
            remove(t, "out/pictures/pear-parallax.png");
            t.user("out/pictures/pear-parallax.png/mine.txt", b"mine");
            Plan::forced(Expect::Fails(t.at("out/pictures/pear-parallax.png")))
        }),
        ("a picture edited by the user, then a forced rerun", |t| {
            t.prior();
            overwrite(t, "out/pictures/chair-octree.png", b"painted over");
            Plan::forced(Expect::Ok)
        }),
        (
            "altrep's temporary file name a link to a file outside",
            |t| {
                t.prior();
                let name = format!("out/.report.md.tmp{}", std::process::id());
                let p = t.link(t.at("outside/keep.txt"), &name);
                Plan::lib(Expect::Ok).gone(p)
            },
        ),
        ("a data file replaced by a link to a file outside", |t| {
            t.prior();
            remove(t, "out/pear/parallax/view2-depth.png");
            t.link(
                t.at("outside/keep.txt"),
                "out/pear/parallax/view2-depth.png",
            );
            Plan::lib(Expect::Ok)
        }),
        ("a link to a folder outside inside an asset folder", |t| {
            t.prior();
            t.user("outside/photos/a.png", b"mine");
            let p = t.link(t.at("outside/photos"), "out/chair/octree/photos");
            Plan::lib(Expect::Ok).gone(p)
        }),
        // Hard links: the user's copies of altrep's outputs.
        ("a picture hard-linked outside, then a changed scene", |t| {
            t.prior();
            hard_copy(t, "out/pictures/pear-parallax.png", "kept.png");
            t.scene = changed();
            Plan::lib(Expect::Ok)
        }),
        ("report.md hard-linked outside, then a rerun", |t| {
            t.prior();
            hard_copy(t, "out/report.md", "report-kept.md");
            Plan::lib(Expect::Ok)
        }),
        (
            "a data file hard-linked outside, then a changed scene",
            |t| {
                t.prior();
                hard_copy(t, "out/pear/parallax/view0-albedo.png", "kept.png");
                t.scene = changed();
                Plan::lib(Expect::Ok)
            },
        ),
        (
            "asset.json hard-linked outside, then a changed scene",
            |t| {
                t.prior();
                hard_copy(t, "out/pear/parallax/asset.json", "kept.json");
                t.scene = changed();
                Plan::lib(Expect::Ok)
            },
        ),
        ("the lock file hard-linked to a file outside", |t| {
            std::fs::create_dir_all(&t.out).unwrap();
            std::fs::hard_link(t.at("outside/keep.txt"), t.at("out/.altrep.lock")).unwrap();
            Plan::lib(Expect::Ok)
        }),
        (
            "a stray hard link to a user's file in an asset folder",
            |t| {
                t.prior();
                let p = t.at("out/chair/octree/keep.txt");
                std::fs::hard_link(t.at("outside/keep.txt"), &p).unwrap();
                Plan::lib(Expect::Ok).gone(p)
            },
        ),
        // Edits and leftovers between runs: altrep's own folders are rebuilt.
        ("a stray file in an asset folder", |t| {
            t.prior();
            overwrite(t, "out/chair/octree/notes.txt", b"x");
            Plan::lib(Expect::Ok).gone(t.at("out/chair/octree/notes.txt"))
        }),
        ("a stray folder in an asset folder", |t| {
            t.prior();
            t.dir("out/pear/parallax/extra");
            overwrite(t, "out/pear/parallax/extra/deep.txt", b"x");
            Plan::lib(Expect::Ok).gone(t.at("out/pear/parallax/extra"))
        }),
        ("a data file altered by one byte", |t| {
            t.prior();
            let p = t.at("out/chair/octree/octree.bin");
            let mut b = std::fs::read(&p).unwrap();
            b[20] ^= 0x10;
            std::fs::write(&p, b).unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("a data file deleted", |t| {
            t.prior();
            remove(t, "out/pear/parallax/view1-depth.png");
            Plan::lib(Expect::Ok)
        }),
        ("asset.json edited", |t| {
            t.prior();
            let p = t.at("out/pear/parallax/asset.json");
            let mut v: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            v["metadata"]["edited_by_hand"] = true.into();
            std::fs::write(&p, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("asset.json cut short", |t| {
            t.prior();
            let p = t.at("out/chair/octree/asset.json");
            let b = std::fs::read(&p).unwrap();
            std::fs::write(&p, &b[..b.len() / 2]).unwrap();
            Plan::lib(Expect::Refused(p))
        }),
        ("a leftover staging folder of a killed run", |t| {
            t.prior();
            t.dir("out/.staging/pear.parallax.99999.0");
            overwrite(
                t,
                "out/.staging/pear.parallax.99999.0/view0-albedo.png",
                b"half",
            );
            Plan::lib(Expect::Ok).gone(t.at("out/.staging/pear.parallax.99999.0"))
        }),
        ("temporary files left by a run killed while it wrote", |t| {
            t.prior();
            overwrite(t, "out/.report.md.tmp99999", b"half a rep");
            overwrite(t, "out/pictures/.pear-parallax.png.tmp99999", b"half a png");
            t.user("out/.notes.tmp5", b"mine");
            Plan::lib(Expect::Ok)
                .gone(t.at("out/.report.md.tmp99999"))
                .gone(t.at("out/pictures/.pear-parallax.png.tmp99999"))
        }),
        // Read-only folders and files.
        ("--out a read-only empty folder", |t| {
            let out = t.dir("out");
            if t.read_only(&out) {
                Plan::lib(Expect::Stops(out.join(LOCK_FILE)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out a read-only bind mount after a run", |t| {
            t.prior();
            let out = t.out.clone();
            if t.read_only_mount(&out) {
                Plan::lib(Expect::Stops(out.join(LOCK_FILE)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out immutable after a run", |t| {
            t.prior();
            let out = t.out.clone();
            if t.read_only(&out) {
                Plan::lib(Expect::Stops(out.join(STAGING_DIR)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("pictures read-only, a forced rerun", |t| {
            t.prior();
            let p = t.at("out/pictures");
            if t.read_only(&p) {
                Plan::forced(Expect::Fails(p))
            } else {
                Plan::forced(Expect::Either)
            }
        }),
        (
            "an asset's folder a read-only bind mount, a forced rerun",
            |t| {
                t.prior();
                let p = t.at("out/chair");
                if t.read_only_mount(&p) {
                    Plan::forced(Expect::Fails(p.join("octree")))
                } else {
                    Plan::forced(Expect::Either)
                }
            },
        ),
        ("report.md read-only", |t| {
            t.prior();
            let p = t.at("out/report.md");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(p))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("an asset folder read-only, a forced rerun", |t| {
            t.prior();
            let p = t.at("out/pear/parallax");
            if t.read_only(&p) {
                Plan::forced(Expect::Fails(p))
            } else {
                Plan::forced(Expect::Either)
            }
        }),
        ("a read-only stray file in an asset folder", |t| {
            t.prior();
            overwrite(t, "out/pear/parallax/notes.txt", b"x");
            let p = t.at("out/pear/parallax/notes.txt");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(t.at("out/.staging")))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        (".staging read-only with a leftover, after a run", |t| {
            t.prior();
            t.dir("out/.staging/pear.parallax.99999.0");
            overwrite(
                t,
                "out/.staging/pear.parallax.99999.0/view0-albedo.png",
                b"half",
            );
            let p = t.at("out/.staging");
            if t.read_only(&p) {
                Plan::lib(Expect::Stops(p))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("a user's empty folder at an asset's name, read-only", |t| {
            let p = t.dir("out/pear");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(p.join("parallax")))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out append-only", |t| {
            let out = t.dir("out");
            let tmp = out.join(format!(".report.json.tmp{}", std::process::id()));
            if t.append_only(&out) {
                Plan::lib(Expect::Fails(out.join("report.json"))).extra(tmp)
            } else {
                Plan::lib(Expect::Either).extra(tmp)
            }
        }),
        ("manifest and mesh in a read-only folder", |t| {
            t.manifest = t.at("input/scene.toml");
            t.scene = mesh_scene("box.obj");
            t.user("input/box.obj", BOX_OBJ.as_bytes());
            let scene = t.scene.clone();
            t.user("input/scene.toml", scene.as_bytes());
            let input = t.at("input");
            t.read_only(&input);
            Plan::lib(Expect::Ok)
        }),
        // Inputs.
        ("the mesh a link to a file outside", |t| {
            t.user("outside/box.obj", BOX_OBJ.as_bytes());
            t.link(t.at("outside/box.obj"), "box.obj");
            t.scene = mesh_scene("box.obj");
            Plan::lib(Expect::Ok)
        }),
        ("the mesh missing", |t| {
            t.scene = mesh_scene("missing.obj");
            Plan::lib(Expect::Fails(t.at("missing.obj")))
        }),
        ("the mesh a folder", |t| {
            t.dir("box.obj");
            t.scene = mesh_scene("box.obj");
            Plan::lib(Expect::Fails(t.at("box.obj")))
        }),
        // A full disk: a tmpfs as --out, filled by a file of the user's.
        ("full disk: no page free", |t| {
            let ok = t.full_disk(0);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: a quarter of a run's pages free", |t| {
            let ok = t.full_disk(clean().pages / 4);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: half of a run's pages free", |t| {
            let ok = t.full_disk(clean().pages / 2);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: one page short of a run", |t| {
            let ok = t.full_disk(clean().pages - 1);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("no inode left", |t| {
            let out = t.out.clone();
            let n = clean().entries / 2;
            let ok = t.tmpfs(&out, &format!("size=4m,nr_inodes={n}"));
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk under a forced rerun of a changed scene", |t| {
            let out = t.out.clone();
            let ok = t.tmpfs(&out, &format!("size={}k", 4 * (clean().pages + 8)));
            t.prior();
            if ok {
                // The rest of the disk: a file of the user's.
                use std::io::Write;
                let filler = t.at("out/filler.bin");
                let mut f = std::fs::File::create(&filler).unwrap();
                while f.write_all(&[7; 4096]).is_ok() {}
                drop(f);
                t.protect.push(filler);
            }
            t.scene = changed();
            Plan::forced(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("--out deep inside a full disk", |t| {
            let disk = t.at("disk");
            let ok = t.tmpfs(&disk, "size=8k");
            if ok {
                t.user("disk/filler.bin", &[7; 4096]);
            }
            t.out = t.at("disk/a/b/out");
            t.lands = t.out.clone();
            let plan = Plan::lib(if ok { Expect::DiskFull } else { Expect::Either });
            plan.extra(t.at("disk/a")).extra(t.at("disk/a/b"))
        }),
        ("full disk, then room: the rerun completes", |t| {
            let ok = t.full_disk(clean().pages / 3);
            Plan::custom(move |t| {
                let m = t.parsed();
                let first = lib_run(&m, &t.out, false, true);
                if !ok {
                    return first;
                }
                if first.panicked.is_some() || first.result.is_ok() {
                    return first;
                }
                let size = format!("remount,size={}k", 4 * (clean().pages + 64));
                assert!(sh(
                    "mount",
                    &["-o".as_ref(), size.as_ref(), t.out.as_os_str()]
                ));
                let second = lib_run(&m, &t.out, false, true);
                match (second.result, equals_clean(&t.lands)) {
                    (Ok(s), Ok(())) => Observed::ok(format!(
                        "the full disk: {}; with room: {s}, equal to a clean run",
                        first
                            .result
                            .unwrap_err()
                            .chars()
                            .take(100)
                            .collect::<String>()
                    )),
                    (Err(e), _) | (_, Err(e)) => Observed::err(e),
                }
            })
        }),
        // Concurrent runs.
        (
            "a run while another holds the lock, beside its staging",
            |t| {
                t.user(
                    "out/.staging/pear.parallax.1.0/view0-albedo.png",
                    b"being written",
                );
                let lock = t.user("out/.altrep.lock", b"");
                Plan::with(
                    Run::Custom(Box::new(move |t| {
                        let held = std::fs::File::options().write(true).open(&lock).unwrap();
                        held.try_lock().unwrap();
                        lib_run(&t.parsed(), &t.out, false, true)
                    })),
                    Expect::Stops(t.at("out/.altrep.lock")),
                )
            },
        ),
        ("two runs at once in one folder", |_| {
            Plan::custom(|t| {
                let m = t.parsed();
                let (a, b) = std::thread::scope(|s| {
                    let a = s.spawn(|| lib_run(&m, &t.out, false, true));
                    let b = s.spawn(|| lib_run(&m, &t.out, false, true));
                    (a.join().unwrap(), b.join().unwrap())
                });
                let locked = |o: &Observed| matches!(&o.result, Err(e) if e.contains("lock held"));
                for o in [&a, &b] {
                    if o.panicked.is_some() || (o.result.is_err() && !locked(o)) {
                        return Observed::err(format!("{:?}", o.result));
                    }
                }
                if locked(&a) && locked(&b) {
                    return Observed::err("both runs were refused");
                }
                match equals_clean(&t.lands) {
                    Ok(()) => Observed::ok(format!(
                        "{:?} and {:?}; the files are a clean run's",
                        a.result, b.result
                    )),
                    Err(e) => Observed::err(e),
                }
            })
        }),
    ];
    let failures = run_cases(cases);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Faults that need the command: `--out` itself a link (to a folder, to a file, dangling, in a
/// loop) or a file, its parent a link, missing parents; a missing manifest; `--json` a folder, a
/// read-only file or in a missing folder; interrupts (SIGINT, SIGTERM, SIGKILL) when the lock
/// exists, while files are staged, once an asset is committed, once a picture is written and
/// at seeded points of a run, each followed by a rerun that must equal a clean run; a run
/// stopped while it holds the lock; two commands at once. Each case checks what
/// [`faults_around_the_output_folder_do_no_harm`] checks, and that the command does not panic.
#[cfg(unix)]
#[test]
fn faults_of_the_command_do_no_harm() {
    let cases: &[(&str, Setup)] = &[
        ("--out a link to an empty folder outside", |t| {
            t.dir("outside/target");
            t.link(t.at("outside/target"), "out");
            Plan::bin(&[], Expect::Ok)
        }),
        (
            "--out a link to a folder outside holding the user's report.md",
            |t| {
                t.user("outside/target/report.md", b"my notes");
                t.link(t.at("outside/target"), "out");
                Plan::bin(&[], Expect::Refused(t.at("out/report.md")))
            },
        ),
        ("--out a dangling link", |t| {
            t.link(t.at("outside/nowhere"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out a link to a file outside", |t| {
            t.link(t.at("outside/keep.txt"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out a link in a loop", |t| {
            t.link(t.at("out"), "out2");
            t.link(t.at("out2"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out's parent a link to a folder outside", |t| {
            t.dir("outside/real");
            t.link(t.at("outside/real"), "via");
            t.out = t.at("via/out");
            t.lands = t.at("outside/real/out");
            Plan::bin(&[], Expect::Ok)
        }),
        ("--out a file", |t| {
            let out = t.user("out", b"mine");
            Plan::bin(&[], Expect::Stops(out))
        }),
        ("--out inside a file", |t| {
            t.user("afile", b"mine");
            t.out = t.at("afile/out");
            t.lands = t.out.clone();
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out with missing parents", |t| {
            t.out = t.at("a/b/out");
            t.lands = t.out.clone();
            Plan::bin(&[], Expect::Ok)
                .extra(t.at("a"))
                .extra(t.at("a/b"))
        }),
        ("a missing manifest", |t| {
            let missing = t.at("none.toml");
            let args = [
                "precompute".as_ref(),
                missing.as_os_str(),
                "--out".as_ref(),
                t.out.as_os_str(),
            ];
            Plan::with(
                Run::BinArgs(args.iter().map(|a| a.into()).collect()),
                Expect::Stops(missing.clone()),
            )
        }),
        ("--json an existing folder", |t| {
            let p = t.dir("outside/summary");
            Plan::bin(
                &["--json".as_ref(), p.as_os_str()],
                Expect::Stops(p.clone()),
            )
        }),
        ("--json a read-only file", |t| {
            let p = t.user("outside/summary.json", b"{\"earlier\": true}");
            if t.read_only(&p) {
                Plan::bin(
                    &["--json".as_ref(), p.as_os_str()],
                    Expect::Stops(p.clone()),
                )
            } else {
                Plan::bin(&["--json".as_ref(), p.as_os_str()], Expect::Either)
            }
        }),
        ("--json in a missing folder", |t| {
            let p = t.at("outside/none/summary.json");
            Plan::bin(
                &["--json".as_ref(), p.as_os_str()],
                Expect::Stops(p.clone()),
            )
        }),
        ("--json a new file beside --out", |t| {
            let p = t.at("outside/summary.json");
            Plan::bin(&["--json".as_ref(), p.as_os_str()], Expect::Ok).extra(p)
        }),
        // Interrupts, each followed by a rerun that must equal a clean run.
        ("SIGKILL once the lock file exists", |_| {
            interrupted("KILL", When::Lock)
        }),
        ("SIGINT while files are staged", |_| {
            interrupted("INT", When::Staged)
        }),
        ("SIGTERM once an asset is committed", |_| {
            interrupted("TERM", When::Committed)
        }),
        ("SIGKILL once a picture is written", |_| {
            interrupted("KILL", When::Picture)
        }),
        ("SIGINT at seeded point 1", |_| {
            interrupted("INT", When::After(share(1)))
        }),
        ("SIGTERM at seeded point 2", |_| {
            interrupted("TERM", When::After(share(2)))
        }),
        ("SIGKILL at seeded point 3", |_| {
            interrupted("KILL", When::After(share(3)))
        }),
        ("SIGINT at seeded point 4", |_| {
            interrupted("INT", When::After(share(4)))
        }),
        ("SIGKILL at seeded point 5", |_| {
            interrupted("KILL", When::After(share(5)))
        }),
        ("SIGKILL of a forced rerun over a complete output", |t| {
            t.prior();
            Plan::custom(|t| {
                let r = interrupt(t, "KILL", When::After(share(6)), &["--force".as_ref()])
                    .and_then(|landed| {
                        finish(t)?;
                        equals_clean(&t.lands)?;
                        Ok(format!("killed mid-run: {landed}; earlier folders complete; the rerun equals a clean run"))
                    });
                r.map_or_else(Observed::err, Observed::ok)
            })
        }),
        ("SIGKILL, SIGTERM of the rerun, then a rerun", |_| {
            Plan::custom(|t| {
                let r = interrupt(t, "KILL", When::Staged, &[])
                    .and_then(|a| Ok((a, interrupt(t, "TERM", When::Committed, &[])?)))
                    .and_then(|(a, b)| {
                        finish(t)?;
                        equals_clean(&t.lands)?;
                        Ok(format!(
                            "killed mid-run: {a}, {b}; the last rerun equals a clean run"
                        ))
                    });
                r.map_or_else(Observed::err, Observed::ok)
            })
        }),
        // Concurrent runs.
        (
            "a run stopped while it holds the lock, and a second run",
            |_| {
                Plan::custom(|t| {
                    let mut child = precompute(t, &[])
                        .stdout(Stdio::null())
                        .stderr(Stdio::piped())
                        .spawn()
                        .unwrap();
                    let t0 = Instant::now();
                    // `pictures` is made once the lock is held and the folders checked.
                    while !t.lands.join("pictures").exists()
                        && child.try_wait().unwrap().is_none()
                        && t0.elapsed() < Duration::from_secs(30)
                    {
                        std::thread::sleep(Duration::from_micros(200));
                    }
                    let stopped = child.try_wait().unwrap().is_none()
                        && Command::new("kill")
                            .args(["-STOP", &child.id().to_string()])
                            .status()
                            .unwrap()
                            .success();
                    let second = lib_run(&t.parsed(), &t.out, false, true);
                    if stopped {
                        Command::new("kill")
                            .args(["-CONT", &child.id().to_string()])
                            .status()
                            .unwrap();
                    }
                    let first = bin_observed(&child.wait_with_output().unwrap());
                    if let Some(p) = first.panicked.or(second.panicked) {
                        return Observed::err(format!("panicked: {p}"));
                    }
                    if let Err(e) = &first.result {
                        return Observed::err(format!("the stopped run failed: {e}"));
                    }
                    match (&second.result, stopped) {
                        (Err(e), true) if e.contains("lock held") && e.contains(LOCK_FILE) => {}
                        (Ok(_), false) => {}
                        (r, _) => {
                            return Observed::err(format!(
                                "stopped: {stopped}; the second run: {r:?}"
                            ));
                        }
                    }
                    match equals_clean(&t.lands) {
                        Ok(()) => Observed::ok(format!(
                            "stopped: {stopped}; the second run: {:?}; the first ends, equal to a clean run",
                            second
                                .result
                                .map_err(|e| e.replace(&t.base.display().to_string(), "ROOT"))
                        )),
                        Err(e) => Observed::err(e),
                    }
                })
            },
        ),
        ("two commands at once in one folder", |_| {
            Plan::custom(|t| {
                let spawn = || {
                    precompute(t, &[])
                        .stdout(Stdio::null())
                        .stderr(Stdio::piped())
                        .spawn()
                        .unwrap()
                };
                let (a, b) = (spawn(), spawn());
                let (a, b) = (
                    bin_observed(&a.wait_with_output().unwrap()),
                    bin_observed(&b.wait_with_output().unwrap()),
                );
                let locked = |o: &Observed| matches!(&o.result, Err(e) if e.contains("lock held"));
                for o in [&a, &b] {
                    if o.panicked.is_some() || (o.result.is_err() && !locked(o)) {
                        return Observed::err(format!("{:?} {:?}", o.result, o.panicked));
                    }
                }
                if locked(&a) && locked(&b) {
                    return Observed::err("both runs were refused");
                }
                match equals_clean(&t.lands) {
                    Ok(()) => Observed::ok(format!(
                        "{}, {}; the files are a clean run's",
                        if locked(&a) {
                            "refused: lock held"
                        } else {
                            "succeeded"
                        },
                        if locked(&b) {
                            "refused: lock held"
                        } else {
                            "succeeded"
                        }
                    )),
                    Err(e) => Observed::err(e),
                }
            })
        }),
    ];
    let mut failures = run_cases(cases);
    // Most interrupts land mid-run (a run takes a few tens of milliseconds; a signal that comes
    // after its end still checks the rerun).
    let landed = LANDED.load(std::sync::atomic::Ordering::Relaxed);
    eprintln!("{landed} of 13 interrupts landed mid-run");
    if landed < 4 {
        failures.push(format!("only {landed} of 13 interrupts landed mid-run"));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
