//! The traps: a user's files around `--out`, snapshots of them, and the clean run they are
//! compared with.

use super::*;

/// Two assets, one representation each, small enough for a run in a fraction of a second.
pub(super) const TINY: &str = "[[asset]]
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
pub(super) fn changed() -> String {
    TINY.replace("views = 4", "views = 6")
}

/// A closed box, as an OBJ mesh.
pub(super) const BOX_OBJ: &str = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

/// A scene of one mesh asset, `mesh` relative to the manifest.
pub(super) fn mesh_scene(mesh: &str) -> String {
    format!(
        "[[asset]]\nname = \"box\"\nmesh = \"{mesh}\"\n[asset.needs]\nscreen_px = [4, 16]\nquality_db = 10\n[asset.octree]\nresolution = 8\n[[asset]]\nname = \"chair\"\nshape = \"chair\"\n[asset.needs]\nscreen_px = [4, 16]\nquality_db = 10\n[asset.octree]\nresolution = 8\n"
    )
}

/// One entry of a snapshot, links not followed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Entry {
    Dir,
    File(Vec<u8>),
    Link(PathBuf),
}

pub(super) type Snap = BTreeMap<PathBuf, Entry>;

/// Every entry under `root` (not `root` itself): folders, files with their bytes, links with
/// their targets.
pub(super) fn snap(root: &Path) -> Snap {
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
pub(super) fn under<'a>(
    s: &'a Snap,
    dir: &'a Path,
) -> impl Iterator<Item = (&'a PathBuf, &'a Entry)> {
    s.iter().filter(move |(p, _)| p.starts_with(dir))
}

pub(super) fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status").is_ok_and(|s| {
        s.lines()
            .find(|l| l.starts_with("Uid:"))
            .and_then(|l| l.split_whitespace().nth(2))
            == Some("0")
    })
}

/// Runs a system command quietly; whether it succeeded.
pub(super) fn sh(cmd: &str, args: &[&std::ffi::OsStr]) -> bool {
    Command::new(cmd)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// The representations each asset of `scene` asks for: `(asset, [representation])`.
pub(super) fn layout(scene: &str) -> Vec<(String, Vec<&'static str>)> {
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
pub(super) struct Clean {
    /// `asset/representation` → the files and cache key its `asset.json` lists.
    pub(super) assets: BTreeMap<String, String>,
    /// Wall seconds of a clean run of the command.
    pub(super) seconds: f64,
    /// 4 KiB pages the files of a clean run take.
    pub(super) pages: u64,
    /// Entries (inodes) a clean run creates in its output folder.
    pub(super) entries: u64,
}

/// What an asset folder holds, as its `asset.json` says: compared with [`Clean::assets`].
pub(super) fn fingerprint(dir: &Path) -> Result<String, String> {
    let r = AssetReader::open(dir).map_err(|e| e.to_string())?;
    let d = r.description();
    Ok(format!("{:?} {}", d.files, d.cache_key))
}

pub(super) fn clean() -> &'static Clean {
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
pub(super) struct Trap {
    /// Removed on drop, after the attributes and mounts are undone.
    pub(super) _root: tempfile::TempDir,
    /// The root's path, links resolved (the paths errors name and snapshots hold).
    pub(super) base: PathBuf,
    /// The `--out` of the run.
    pub(super) out: PathBuf,
    /// A folder beside `out`.
    pub(super) outside: PathBuf,
    /// Where the run's files land: `out`, or where a link at `out` leads.
    pub(super) lands: PathBuf,
    /// The manifest and where it is written.
    pub(super) scene: String,
    pub(super) manifest: PathBuf,
    /// Entries altrep wrote in an earlier run (under `lands`).
    pub(super) owned: Snap,
    /// The user's files the case names: byte for byte the same after the run.
    pub(super) protect: Vec<PathBuf>,
    /// Paths given attributes (`chattr`), mounts, folders made read-only by mode: undone on drop.
    pub(super) attrs: bool,
    pub(super) mounts: Vec<PathBuf>,
    pub(super) modes: Vec<PathBuf>,
}

impl Trap {
    pub(super) fn new() -> Self {
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
    pub(super) fn at(&self, rel: &str) -> PathBuf {
        self.base.join(rel)
    }

    pub(super) fn parsed(&self) -> Manifest {
        Manifest::parse(&self.scene, &self.manifest).unwrap()
    }

    /// An earlier complete run of the case's scene into `out`: its entries are altrep's.
    pub(super) fn prior(&mut self) {
        let s = run_scene(&self.parsed(), &options(&self.out)).unwrap();
        assert!(s.ok(), "{}", s.table());
        self.owned = snap(&self.lands);
    }

    /// A file of the user's at `rel` (parents created), protected.
    pub(super) fn user(&mut self, rel: &str, bytes: &[u8]) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, bytes).unwrap();
        self.protect.push(p.clone());
        p
    }

    pub(super) fn dir(&self, rel: &str) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(&p).unwrap();
        p
    }

    /// A symbolic link at `rel` to `target` (parents of the link created).
    pub(super) fn link(&self, target: impl AsRef<Path>, rel: &str) -> PathBuf {
        let p = self.at(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        symlink(target, &p).unwrap();
        p
    }

    /// Makes `p` read-only for root too: the immutable attribute, else a read-only bind mount;
    /// for another user, its mode. Whether writes to it now fail whatever the user.
    pub(super) fn read_only(&mut self, p: &Path) -> bool {
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
    pub(super) fn read_only_mount(&mut self, p: &Path) -> bool {
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
    pub(super) fn append_only(&mut self, p: &Path) -> bool {
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
    pub(super) fn tmpfs(&mut self, p: &Path, opts: &str) -> bool {
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
    pub(super) fn full_disk(&mut self, free: u64) -> bool {
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
pub(super) enum Run {
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
pub(super) enum Expect {
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
