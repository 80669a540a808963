//! Atomic file replacement: readers see either the old file or the whole new one.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{IoError, Result};

/// Per-process counter so two threads writing the same target do not share a temp file.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically.
///
/// The bytes go to a temporary file `.{filename}.tmp-{pid}-{n}` in the same
/// folder (so the rename cannot cross file systems), which is flushed to disk
/// and then renamed over `path`. Missing parent folders are created. On any
/// error the temporary file is removed and `path` is left as it was.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let write_err = |source| IoError::Write {
        path: path.to_path_buf(),
        cause: source,
    };
    let name = path.file_name().ok_or_else(|| {
        write_err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path does not name a file",
        ))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    fs::create_dir_all(dir).map_err(write_err)?;

    let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp: PathBuf = dir.join(format!(".{}.tmp-{}-{}", name.to_string_lossy(), std::process::id(), n));
    let result = write_then_rename(&tmp, path, bytes);
    if result.is_err() {
        // Best effort: the file may not exist if creating it was what failed.
        let _ = fs::remove_file(&tmp);
    }
    result.map_err(write_err)?;
    sync_dir(dir);
    Ok(())
}

/// Writes of the file named by `PGANEUS_DIE_WRITING` so far in this process.
static WRITES_OF_WATCHED: AtomicU64 = AtomicU64::new(0);

/// A fault to inject for tests of what a kill in the middle of a write leaves: with
/// `PGANEUS_DIE_WRITING=NAME:K` set, the process dies (abort, no clean-up) half-way through its K-th write
/// of a file named NAME, after half the bytes reached the temporary file and before the rename.
fn dies_writing(target: &Path) -> bool {
    let Ok(spec) = std::env::var("PGANEUS_DIE_WRITING") else {
        return false;
    };
    let Some((name, k)) = spec.rsplit_once(':') else {
        return false;
    };
    if target.file_name().is_none_or(|n| n.to_string_lossy() != name) {
        return false;
    }
    WRITES_OF_WATCHED.fetch_add(1, Ordering::Relaxed) + 1 == k.parse::<u64>().unwrap_or(0)
}

fn write_then_rename(tmp: &Path, target: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut file = fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(tmp)?;
    if dies_writing(target) {
        file.write_all(&bytes[..bytes.len() / 2])?;
        file.sync_all()?;
        std::process::abort();
    }
    file.write_all(bytes)?;
    // fsync before rename, otherwise a crash can leave the new name on empty data.
    file.sync_all()?;
    drop(file);
    fs::rename(tmp, target)
}

/// Makes the rename itself durable. Not possible on every platform (Windows
/// cannot open folders this way), and the data is already safe, so errors are ignored.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// A folder written beside its target and swapped in whole: `path()` is where to write; [`Self::commit`]
/// moves it to the target (an existing target is replaced only then); dropped without a commit, the
/// partial folder is removed, so a failure part-way leaves the old folder, or none, as it was.
pub struct StagedDir {
    target: PathBuf,
    partial: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// A fresh partial folder `.{name}.partial-{pid}` beside `target`.
    pub fn new(target: &Path) -> Result<Self> {
        let err = |source| IoError::Write {
            path: target.to_path_buf(),
            cause: source,
        };
        let name = target.file_name().ok_or_else(|| {
            err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "the path does not name a folder",
            ))
        })?;
        let partial = target.with_file_name(format!(".{}.partial-{}", name.to_string_lossy(), std::process::id()));
        let _ = fs::remove_dir_all(&partial);
        fs::create_dir_all(&partial).map_err(err)?;
        Ok(Self {
            target: target.to_path_buf(),
            partial,
            committed: false,
        })
    }

    /// Where the folder's contents go until the commit.
    pub fn path(&self) -> &Path {
        &self.partial
    }

    /// Moves the finished folder to the target, replacing what was there.
    pub fn commit(mut self) -> Result<()> {
        let err = |source| IoError::Write {
            path: self.target.clone(),
            cause: source,
        };
        if self.target.exists() {
            let old = self.target.with_file_name(format!(
                ".{}.old-{}",
                self.target.file_name().unwrap_or_default().to_string_lossy(),
                std::process::id()
            ));
            let _ = fs::remove_dir_all(&old);
            fs::rename(&self.target, &old).map_err(err)?;
            fs::rename(&self.partial, &self.target).map_err(err)?;
            let _ = fs::remove_dir_all(&old);
        } else {
            fs::rename(&self.partial, &self.target).map_err(err)?;
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.partial);
        }
    }
}
