//! Durable file writes shared by every layer that writes files (outputs, the job store).
//!
//! Invariant: a reader never sees a partly written file. Every write goes to a temporary name
//! beside the target (unique per process and call), is fsynced, renamed over the target, and the
//! directory is fsynced; on failure the temporary file is removed and the target is untouched
//! (`tests::a_failed_write_leaves_the_target_untouched`).

use std::io;
use std::path::{Path, PathBuf};

/// A temporary name beside `path`, unique per process and call (so concurrent writers never share one).
fn temporary_path(path: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// Makes a rename in `path`'s directory durable (fsync of the directory; a no-op where unsupported).
fn sync_parent(path: &Path) -> io::Result<()> {
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = std::fs::File::open(dir) {
            d.sync_all()?;
        }
    }
    Ok(())
}

/// Writes `path` atomically through `write`, which creates and fills the temporary file it is
/// given: then fsync, rename over `path`, fsync of the directory.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&Path) -> io::Result<()>,
) -> io::Result<()> {
    let tmp = temporary_path(path);
    let result = (|| {
        write(&tmp)?;
        // A writable handle: some systems refuse to flush a read-only one.
        std::fs::OpenOptions::new()
            .write(true)
            .open(&tmp)?
            .sync_all()?;
        std::fs::rename(&tmp, path)?;
        sync_parent(path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `bytes` to `path` atomically ([`write_atomic_with`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |tmp| std::fs::write(tmp, bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory, removed when the test ends.
    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("wavrad-fsutil-{name}-"))
            .tempdir()
            .unwrap()
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_write_replaces_the_target_and_leaves_no_temporary() {
        let tmp = scratch("replace");
        let dir = tmp.path();
        let path = dir.join("a.json");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(entries(dir), ["a.json"]);
    }

    #[test]
    fn a_failed_write_leaves_the_target_untouched() {
        let tmp = scratch("failed");
        let dir = tmp.path();
        let path = dir.join("a.json");
        write_atomic(&path, b"kept").unwrap();
        let err = write_atomic_with(&path, |tmp| {
            std::fs::write(tmp, b"half")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        assert_eq!(std::fs::read(&path).unwrap(), b"kept");
        assert_eq!(entries(dir), ["a.json"]);
    }
}
