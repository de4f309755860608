//! Folders the study commands write into (`altrep demo`, `altrep report`): a fixed set of entries
//! per command, replaced only where altrep wrote them.
//!
//! A command that has written into a folder leaves a marker file there, `.altrep-COMMAND`. Before
//! any work, [`OutputClaim::check`] refuses every entry the command would write that already
//! exists in a folder without the marker (the user's `report.md` in a folder altrep never wrote
//! to), and every entry that is a symbolic link (altrep neither follows nor replaces links).
//! Entries the command does not name are never touched. The entries are then written into a
//! staging folder inside `--out` and renamed into place one by one ([`OutputClaim::commit`]), so
//! an interrupted run leaves each entry whole, old or new, and a rerun leaves no file of an older
//! run behind among them.

use std::path::{Path, PathBuf};

use super::{AssetError, replace_dir, write::io};

/// The entries a command writes into an output folder, checked and staged (module docs).
#[derive(Clone, Debug)]
pub struct OutputClaim {
    dir: PathBuf,
    command: &'static str,
    entries: Vec<String>,
    /// Entries already moved into place by [`OutputClaim::place`].
    placed: Vec<String>,
}

impl OutputClaim {
    /// The claim of `command` (`demo`, `report`) on `entries` (file or folder names) of `dir`.
    pub fn new(dir: &Path, command: &'static str, entries: Vec<String>) -> Self {
        Self {
            dir: dir.to_path_buf(),
            command,
            entries,
            placed: Vec::new(),
        }
    }

    fn marker(&self) -> PathBuf {
        self.dir.join(format!(".altrep-{}", self.command))
    }

    fn staging(&self) -> PathBuf {
        self.dir.join(format!(".altrep-{}-staging", self.command))
    }

    /// Checks, before any work, that the command may write its entries: `dir` is absent or a
    /// folder; no entry (nor the staging folder) is a symbolic link; and where the folder holds no
    /// marker of the command, no entry exists. Errors: [`AssetError::NotOurs`] naming the path,
    /// which is left as it is. Cost: one `lstat` per entry.
    pub fn check(&self) -> Result<(), AssetError> {
        let not_ours = |path: PathBuf, reason: String| AssetError::NotOurs { path, reason };
        match std::fs::metadata(&self.dir) {
            Ok(m) if !m.is_dir() => {
                return Err(not_ours(
                    self.dir.clone(),
                    "is a file, not an output folder".into(),
                ));
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(io(&self.dir)(e)),
        }
        let ours = std::fs::symlink_metadata(self.marker()).is_ok_and(|m| m.is_file());
        let staging = self.staging();
        let names = self.entries.iter().map(|e| self.dir.join(e));
        for path in names.chain([staging]) {
            let meta = match std::fs::symlink_metadata(&path) {
                Ok(m) => m,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                Err(e) => return Err(io(&path)(e)),
            };
            if meta.file_type().is_symlink() {
                return Err(not_ours(
                    path,
                    "is a symbolic link, which altrep neither follows nor replaces".into(),
                ));
            }
            if !ours {
                return Err(not_ours(
                    path,
                    format!(
                        "exists, and altrep {} has not written into this folder (no {}): \
                         choose another --out",
                        self.command,
                        self.marker()
                            .file_name()
                            .map(|n| n.to_string_lossy().into_owned())
                            .unwrap_or_default()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Creates `dir` and the marker, and returns an empty staging folder to write the entries
    /// into (an older run's staging folder, the command's own, is removed first). Errors: the
    /// file system's, naming the path.
    pub fn begin(&self) -> Result<PathBuf, AssetError> {
        std::fs::create_dir_all(&self.dir).map_err(io(&self.dir))?;
        let marker = self.marker();
        if !marker.is_file() {
            std::fs::write(&marker, b"").map_err(io(&marker))?;
        }
        let staging = self.staging();
        if std::fs::symlink_metadata(&staging).is_ok() {
            std::fs::remove_dir_all(&staging).map_err(io(&staging))?;
        }
        std::fs::create_dir(&staging).map_err(io(&staging))?;
        Ok(staging)
    }

    /// Moves the staged entry `name` (one of the claim's) into place now, before the others,
    /// as [`commit`](Self::commit) would: for an input a later step of the command reads from
    /// its final path. Errors: a name the claim does not hold, and the file system's.
    pub fn place(&mut self, name: &str) -> Result<PathBuf, AssetError> {
        let to = self.dir.join(name);
        if !self.entries.iter().any(|e| e == name) {
            return Err(AssetError::NotOurs {
                path: to,
                reason: format!("is not an entry altrep {} writes", self.command),
            });
        }
        self.check()?;
        let from = self.staging().join(name);
        if from.is_dir() {
            replace_dir(&from, &to)?;
        } else {
            std::fs::rename(&from, &to).map_err(io(&to))?;
        }
        self.placed.push(name.to_string());
        Ok(to)
    }

    /// Checks again, then moves every entry from the staging folder into place: a staged file
    /// replaces the old one by a rename, a staged folder replaces the old folder whole
    /// ([`replace_dir`]); an entry the command names but did not stage this time is removed (it
    /// is an older run's). The staging folder goes last. Errors: as [`check`](Self::check) and
    /// the file system's, naming the path.
    pub fn commit(&self) -> Result<(), AssetError> {
        self.check()?;
        let staging = self.staging();
        for name in self.entries.iter().filter(|e| !self.placed.contains(e)) {
            let (from, to) = (staging.join(name), self.dir.join(name));
            match std::fs::symlink_metadata(&from) {
                Ok(m) if m.is_dir() => replace_dir(&from, &to)?,
                Ok(_) => std::fs::rename(&from, &to).map_err(io(&to))?,
                Err(_) => match std::fs::symlink_metadata(&to) {
                    Ok(m) if m.is_dir() => std::fs::remove_dir_all(&to).map_err(io(&to))?,
                    Ok(_) => std::fs::remove_file(&to).map_err(io(&to))?,
                    Err(_) => {}
                },
            }
        }
        std::fs::remove_dir_all(&staging).map_err(io(&staging))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn claim(dir: &Path) -> OutputClaim {
        OutputClaim::new(dir, "test", vec!["report.md".into(), "pictures".into()])
    }

    #[test]
    fn the_users_entries_are_refused_and_ours_replaced_whole() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        // Absent folder: nothing to refuse.
        claim(&dir).check().unwrap();
        // The user's report.md in a folder altrep never wrote to: refused, left alone.
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("report.md"), "mine").unwrap();
        std::fs::write(dir.join("notes.txt"), "mine too").unwrap();
        let e = claim(&dir).check().unwrap_err();
        assert!(e.to_string().contains("report.md"), "{e}");
        assert_eq!(std::fs::read(dir.join("report.md")).unwrap(), b"mine");
        std::fs::remove_file(dir.join("report.md")).unwrap();
        // A first run: the entries land; what the claim does not name stays.
        let c = claim(&dir);
        c.check().unwrap();
        let staging = c.begin().unwrap();
        std::fs::write(staging.join("report.md"), "first").unwrap();
        std::fs::create_dir(staging.join("pictures")).unwrap();
        std::fs::write(staging.join("pictures/a.png"), "a").unwrap();
        c.commit().unwrap();
        assert_eq!(std::fs::read(dir.join("report.md")).unwrap(), b"first");
        assert!(dir.join("pictures/a.png").is_file());
        assert_eq!(std::fs::read(dir.join("notes.txt")).unwrap(), b"mine too");
        assert!(!c.staging().exists());
        // A rerun replaces them whole: no file of the older run is left, and an entry not
        // staged this time goes; one placed early stays.
        let mut c = c;
        c.check().unwrap();
        let staging = c.begin().unwrap();
        std::fs::create_dir(staging.join("pictures")).unwrap();
        std::fs::write(staging.join("pictures/b.png"), "b").unwrap();
        assert!(c.place("notes.txt").is_err());
        assert_eq!(c.place("pictures").unwrap(), dir.join("pictures"));
        assert!(!dir.join("pictures/a.png").exists());
        c.commit().unwrap();
        assert!(dir.join("pictures/b.png").is_file());
        assert!(!dir.join("report.md").exists());
        // A link at an entry is refused even in our folder, and left as it is.
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(tmp.path(), dir.join("report.md")).unwrap();
            let e = c.check().unwrap_err();
            assert!(e.to_string().contains("symbolic link"), "{e}");
            assert!(std::fs::symlink_metadata(dir.join("report.md")).is_ok());
        }
        // A file at --out is refused.
        let file = tmp.path().join("file");
        std::fs::write(&file, "x").unwrap();
        assert!(claim(&file).check().is_err());
    }
}
