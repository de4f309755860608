//! The output folder: its lock, and the temporaries an interrupted run left in it.

use std::fs::File;
use std::path::Path;
use std::time::Instant;

use super::run::{LOCK_FILE, LOCK_PATIENCE};
use crate::asset::STAGING_DIR;
use crate::representation::PipelineError;

/// Holds the output folder's lock for the run.
pub(super) struct OutputLock {
    _file: File,
}

pub(super) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PipelineError + '_ {
    move |source| PipelineError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Creates `out`, takes its lock and clears leftovers of interrupted runs. Errors: the folder
/// cannot be created or written, another run holds the lock.
pub(super) fn prepare_output(out: &Path) -> Result<OutputLock, PipelineError> {
    std::fs::create_dir_all(out).map_err(io(out))?;
    let lock_path = out.join(LOCK_FILE);
    // A folder altrep has run in holds its lock file. In any other folder, the names altrep
    // writes at the top must be free; and a symbolic link is never written through. Whether the
    // lock file exists is asked again when a name is found: a run that started beside this one
    // since (it will hold the lock) creates its lock file before any other name.
    let ran_here = lock_path.exists();
    for name in [
        "report.md",
        "report.json",
        "pictures",
        STAGING_DIR,
        LOCK_FILE,
    ] {
        let path = out.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        let reason = if meta.file_type().is_symlink() {
            "is a symbolic link, which altrep does not follow"
        } else if !ran_here && !lock_path.exists() {
            "exists in a folder altrep has not written into (no lock file)"
        } else if (name == "pictures" || name == STAGING_DIR) != meta.is_dir() {
            "is not what altrep writes under this name"
        } else {
            continue;
        };
        return Err(crate::asset::AssetError::NotOurs {
            path,
            reason: reason.into(),
        }
        .into());
    }
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(io(&lock_path))?;
    // A process spawned by another thread of this program holds copies of its descriptors,
    // and with them a lock this program just released, until it execs (microseconds, more on a
    // loaded machine): a lock still held after `LOCK_PATIENCE` is another run's.
    let waited = Instant::now();
    loop {
        match file.try_lock() {
            Ok(()) => break,
            Err(std::fs::TryLockError::WouldBlock) if waited.elapsed() < LOCK_PATIENCE => {
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(PipelineError::Locked { path: lock_path });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(io(&lock_path)(e)),
        }
    }
    let staging = out.join(STAGING_DIR);
    if staging.exists() {
        std::fs::remove_dir_all(&staging).map_err(io(&staging))?;
    }
    if ran_here {
        clear_temporaries(out)?;
    }
    Ok(OutputLock { _file: file })
}

/// Removes the temporary files a run killed while it wrote the report or a picture left in
/// `out` (`.report.md.tmpPID`, `pictures/.NAME.png.tmpPID`): files or links, never followed.
fn clear_temporaries(out: &Path) -> Result<(), PipelineError> {
    for dir in [out.to_path_buf(), out.join("pictures")] {
        let top = dir == out;
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name();
            let temporary = name
                .to_str()
                .and_then(crate::asset::temporary_of)
                .is_some_and(|t| {
                    if top {
                        t == "report.md" || t == "report.json"
                    } else {
                        t.ends_with(".png")
                    }
                });
            if temporary && e.file_type().is_ok_and(|t| !t.is_dir()) {
                let path = e.path();
                std::fs::remove_file(&path).map_err(io(&path))?;
            }
        }
    }
    Ok(())
}
