//! The exclusive lock on a data directory: one `wavrad serve` owns a `--data-dir` at a time.
//!
//! Invariants: the lock is an OS advisory lock (`flock` on Unix, `LockFileEx` on Windows, through
//! `fs4`) on `data_dir/wavrad.lock`, held for as long as the [`DataDirLock`] lives (the service's
//! state owns it), so the kernel releases it when the process ends however it ends: a killed
//! server leaves no stale lock behind, and the file's presence means nothing by itself. The file
//! holds the owner's pid and start time (JSON), read only to name the owner in the refusal
//! (`tests/service_restart.rs`, `a_second_server_on_one_data_dir_refuses_to_start`).

use fs4::fs_std::FileExt;
use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::Path;

/// The lock file's name inside the data directory.
pub const LOCK_FILE: &str = "wavrad.lock";

/// What the lock file says about its owner.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
struct Owner {
    pid: u32,
    /// RFC 3339, when the owner took the lock.
    started: String,
}

/// The held lock on a data directory; released when dropped (or when the process ends).
#[derive(Debug)]
pub struct DataDirLock {
    /// Kept open: closing it releases the lock.
    _file: File,
}

impl DataDirLock {
    /// Creates `data_dir` as needed and takes its lock, or fails with
    /// `io::ErrorKind::ResourceBusy` naming the process that holds it (pid and start time).
    pub fn acquire(data_dir: &Path) -> io::Result<DataDirLock> {
        std::fs::create_dir_all(data_dir)?;
        let path = data_dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
        if !FileExt::try_lock_exclusive(&file)? {
            let mut text = String::new();
            // The owner may be between taking the lock and writing its name: then it is unknown.
            let owner = file
                .read_to_string(&mut text)
                .ok()
                .and_then(|_| serde_json::from_str::<Owner>(&text).ok());
            let who = match owner {
                Some(o) => format!("process {} (started {})", o.pid, o.started),
                None => "another process (its pid is not recorded yet)".to_string(),
            };
            return Err(io::Error::new(
                io::ErrorKind::ResourceBusy,
                format!(
                    "the data directory {} is in use by another wavrad serve: {who} holds {}; \
                     stop that server first, or give this one another --data-dir",
                    data_dir.display(),
                    path.display()
                ),
            ));
        }
        let owner = Owner {
            pid: std::process::id(),
            started: super::time::rfc3339(std::time::SystemTime::now()),
        };
        let json = serde_json::to_vec(&owner).map_err(io::Error::other)?;
        file.set_len(0)?;
        file.seek(SeekFrom::Start(0))?;
        file.write_all(&json)?;
        file.sync_all()?;
        Ok(DataDirLock { _file: file })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second lock on one directory is refused while the first is held (two open file
    /// descriptions conflict under `flock` even within one process), naming this process; it is
    /// granted once the first is dropped.
    #[test]
    fn a_held_lock_refuses_a_second_and_is_released_on_drop() {
        let dir = std::env::temp_dir().join(format!("wavrad-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let first = DataDirLock::acquire(&dir).expect("first lock");
        let e = DataDirLock::acquire(&dir).expect_err("second lock refused");
        assert_eq!(e.kind(), io::ErrorKind::ResourceBusy);
        let message = e.to_string();
        assert!(
            message.contains(&format!("process {}", std::process::id())),
            "{message}"
        );
        assert!(message.contains("--data-dir"), "{message}");
        drop(first);
        let again = DataDirLock::acquire(&dir).expect("granted after release");
        drop(again);
        assert!(dir.join(LOCK_FILE).is_file());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
