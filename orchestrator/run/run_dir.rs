//! The run directory: one per run, never shared. The default name carries the run's id, so
//! runs started in the same second get different directories; `--out` into a directory that
//! already holds files is refused unless `--force`, which clears a previous run's directory
//! (never one that a running deployment holds, nor a directory that is not a run's). While
//! the run lasts the orchestrator holds an exclusive lock on `DIR/.glint-run.lock`: the
//! services read `DIR/scenario.toml`, and no other run may rewrite it under them.

use std::fs::File;
use std::path::{Path, PathBuf};

use rustix::fs::{flock, FlockOperation};

/// Lock file inside a run directory, held for the whole run.
const LOCK: &str = ".glint-run.lock";

/// A bad `--out`: the user's to fix (exit 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct OutDirError(pub String);

/// The run directory, locked for this run until dropped.
pub struct RunDir {
    pub path: PathBuf,
    _lock: File,
}

/// Creates (or, with `replace`, clears) the run directory and takes its lock. `name` and `id`
/// make the default `runs/<name>-<UTC stamp>-<id>`.
pub fn prepare(out: Option<&Path>, name: &str, id: &str, replace: bool) -> anyhow::Result<RunDir> {
    let path = match out {
        Some(p) => p.to_path_buf(),
        None => PathBuf::from("runs").join(format!("{name}-{}-{id}", crate::run::utc_stamp())),
    };
    if path.exists() && !path.is_dir() {
        return Err(OutDirError(format!("{} is a file, not a directory", path.display())).into());
    }
    let holds_files = std::fs::read_dir(&path).is_ok_and(|mut d| d.next().is_some());
    if holds_files {
        let shown = path.display();
        if !replace {
            return Err(OutDirError(format!(
                "{shown} already holds files (a previous run?): choose another --out, or pass \
                 --force to replace that run"
            ))
            .into());
        }
        if !is_run_dir(&path) {
            return Err(OutDirError(format!(
                "{shown} is not a glint run directory (no scenario.toml or report.json): \
                 --force replaces only a previous run"
            ))
            .into());
        }
        let lock = lock(&path)?;
        clear(&path)?;
        return Ok(RunDir { path, _lock: lock });
    }
    std::fs::create_dir_all(&path)
        .map_err(|e| anyhow::anyhow!("creating run directory {}: {e}", path.display()))?;
    let lock = lock(&path)?;
    Ok(RunDir { path, _lock: lock })
}

/// Takes the exclusive lock of `dir`, or says which deployment holds it.
fn lock(dir: &Path) -> anyhow::Result<File> {
    let lock = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.join(LOCK))?;
    if flock(&lock, FlockOperation::NonBlockingLockExclusive).is_err() {
        let shown = dir.display();
        return Err(OutDirError(format!("{shown} is in use by a running deployment")).into());
    }
    Ok(lock)
}

/// Whether `dir` looks like a run's: it has the files every run writes first or last.
fn is_run_dir(dir: &Path) -> bool {
    ["scenario.toml", "report.json"]
        .iter()
        .any(|f| dir.join(f).is_file())
}

/// Removes everything in `dir` but the lock file.
fn clear(dir: &Path) -> anyhow::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        if entry.file_name() == LOCK {
            continue;
        }
        let p = entry.path();
        if entry.file_type()?.is_dir() {
            std::fs::remove_dir_all(&p)?;
        } else {
            std::fs::remove_file(&p)?;
        }
    }
    Ok(())
}
