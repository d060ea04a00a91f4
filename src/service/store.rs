//! The embedded job store: one directory per job under `data_dir/jobs/{id}/`, plain files, every
//! write atomic (temporary file, fsync, rename) and the directory fsynced after it changes.
//!
//! Layout of a job directory:
//! - `input.glb` or `input.gltf`: the uploaded scene, as received (directories written before
//!   the baked scene existed hold it as `scene.glb` or `scene.gltf`: [`FileStore::scene_path`]
//!   still finds it there, and [`FileStore::predates_baking`] says so);
//! - `params.json`: the job parameters, defaults filled in;
//! - `state.json`: the job's [`JobRecord`](super::jobs::JobRecord), rewritten at every change of state;
//! - the outputs of [`run_job`](crate::job::run_job): `result.json`, `lightmap*.exr`,
//!   `convergence.csv`, `preview.png`, `scene.glb` (the baked scene);
//! - `solution.bin`: a succeeded job's solution ([`crate::output::solution_file`]), written before
//!   `state.json` says `succeeded`, read back to answer probe requests after a restart.
//!
//! Deleting a job renames its directory into `data_dir/trash/` (atomic: the job is there or it is
//! not) and removes it from there; whatever a crash leaves in the trash is removed at the next start.
//!
//! This is the shape of the `JobStore` interface of docs/design.md section 8; a database-backed store
//! would implement the same operations.

use crate::fsutil::write_atomic;
use serde::{Deserialize, Serialize};
use std::collections::hash_map::RandomState;
use std::collections::{BTreeMap, HashMap};
use std::hash::BuildHasher;
use std::io;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// File name of the uploaded scene when it is a GLB.
pub const INPUT_GLB: &str = "input.glb";
/// File name of the uploaded scene when it is glTF JSON.
pub const INPUT_GLTF: &str = "input.gltf";
/// Where versions before the baked scene stored an uploaded GLB (now the baked scene's name).
pub const LEGACY_SCENE_GLB: &str = "scene.glb";
/// Where versions before the baked scene stored uploaded glTF JSON.
pub const LEGACY_SCENE_GLTF: &str = "scene.gltf";
/// The job parameters.
pub const PARAMS_FILE: &str = "params.json";
/// The job's state record.
pub const STATE_FILE: &str = "state.json";
/// The manifest of a multipart upload's extra files: `[{"uri": "...", "file": "part-0"}, ...]`.
pub const PARTS_FILE: &str = "parts.json";
/// The result document written by a successful solve.
pub const RESULT_FILE: &str = "result.json";
/// The per-shot convergence table.
pub const CONVERGENCE_FILE: &str = "convergence.csv";
/// A succeeded job's solution, for probe requests.
pub const SOLUTION_FILE: &str = crate::output::solution_file::SOLUTION_FILE;

/// Attempts at finding an unused job id before giving up (collisions need two jobs in the same
/// millisecond with the same 20 random bits).
const ID_ATTEMPTS: usize = 16;

/// A job identifier: 16 lowercase hex digits, the creation time in milliseconds (11 digits, so ids
/// sort by creation) followed by 20 random bits.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JobId(String);

impl JobId {
    pub(crate) fn generate(created: SystemTime) -> JobId {
        let ms = super::time::unix_millis(created) & 0xfff_ffff_ffff;
        let random = RandomState::new().hash_one(ms) & 0xf_ffff;
        JobId(format!("{ms:011x}{random:05x}"))
    }

    /// The id if `s` has the shape of one (16 lowercase hex digits), so it is a safe file name.
    pub fn parse(s: &str) -> Option<JobId> {
        (s.len() == 16 && s.bytes().all(|c| matches!(c, b'0'..=b'9' | b'a'..=b'f')))
            .then(|| JobId(s.to_string()))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }

    #[cfg(test)]
    pub(crate) fn for_tests(id: &str) -> JobId {
        JobId(id.to_string())
    }
}

impl std::fmt::Display for JobId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Which kind of scene file was uploaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneFormat {
    Glb,
    Gltf,
}

impl SceneFormat {
    /// GLB when the bytes start with the GLB magic, glTF JSON otherwise.
    pub fn sniff(bytes: &[u8]) -> SceneFormat {
        if bytes.starts_with(b"glTF") {
            SceneFormat::Glb
        } else {
            SceneFormat::Gltf
        }
    }

    pub fn file_name(self) -> &'static str {
        match self {
            SceneFormat::Glb => INPUT_GLB,
            SceneFormat::Gltf => INPUT_GLTF,
        }
    }
}

/// The job directories under a data directory.
#[derive(Debug, Clone)]
pub struct FileStore {
    jobs: PathBuf,
    trash: PathBuf,
}

impl FileStore {
    /// Creates `data_dir/jobs` and `data_dir/trash` as needed and empties the trash.
    pub fn open(data_dir: &Path) -> io::Result<FileStore> {
        let store = FileStore {
            jobs: data_dir.join("jobs"),
            trash: data_dir.join("trash"),
        };
        std::fs::create_dir_all(&store.jobs)?;
        std::fs::create_dir_all(&store.trash)?;
        for entry in std::fs::read_dir(&store.trash)? {
            let path = entry?.path();
            if let Err(e) = std::fs::remove_dir_all(&path) {
                tracing::warn!(path = %path.display(), error = %e, "could not empty the trash");
            }
        }
        Ok(store)
    }

    /// The directory of job `id` (it may not exist).
    pub fn job_dir(&self, id: &JobId) -> PathBuf {
        self.jobs.join(id.as_str())
    }

    /// Allocates a fresh id and creates its empty directory.
    pub fn create_job_dir(&self, created: SystemTime) -> io::Result<JobId> {
        for _ in 0..ID_ATTEMPTS {
            let id = JobId::generate(created);
            match std::fs::create_dir(self.job_dir(&id)) {
                Ok(()) => {
                    sync_dir(&self.jobs)?;
                    return Ok(id);
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
        Err(io::Error::other("could not find an unused job id"))
    }

    /// Writes the files of a new job into its (existing) directory: scene, the files it
    /// references (multipart uploads), parameters, and last the state (the commit point).
    pub fn write_new_job(
        &self,
        id: &JobId,
        scene: &[u8],
        parts: &BTreeMap<String, Vec<u8>>,
        params: &impl Serialize,
        state: &impl Serialize,
    ) -> io::Result<()> {
        let dir = self.job_dir(id);
        write_atomic(&dir.join(SceneFormat::sniff(scene).file_name()), scene)?;
        if !parts.is_empty() {
            let mut manifest = Vec::with_capacity(parts.len());
            for (n, (uri, bytes)) in parts.iter().enumerate() {
                let file = format!("part-{n}");
                write_atomic(&dir.join(&file), bytes)?;
                manifest.push(PartEntry {
                    uri: uri.clone(),
                    file,
                });
            }
            write_atomic(&dir.join(PARTS_FILE), &to_json(&manifest)?)?;
        }
        write_atomic(&dir.join(PARAMS_FILE), &to_json(params)?)?;
        write_atomic(&dir.join(STATE_FILE), &to_json(state)?)?;
        sync_dir(&dir)
    }

    /// The files a multipart upload sent with its scene, by URI (empty for other uploads).
    pub fn read_parts(&self, id: &JobId) -> io::Result<HashMap<String, Vec<u8>>> {
        let dir = self.job_dir(id);
        let manifest = match std::fs::read(dir.join(PARTS_FILE)) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(HashMap::new()),
            Err(e) => return Err(e),
        };
        let entries: Vec<PartEntry> = serde_json::from_slice(&manifest).map_err(|e| {
            io::Error::new(io::ErrorKind::InvalidData, format!("{PARTS_FILE}: {e}"))
        })?;
        let mut parts = HashMap::with_capacity(entries.len());
        for entry in entries {
            // Only names this store writes: never a path out of the job directory.
            let valid = entry
                .file
                .strip_prefix("part-")
                .is_some_and(|n| !n.is_empty() && n.bytes().all(|c| c.is_ascii_digit()));
            if !valid {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("{PARTS_FILE} names '{}', not a part file", entry.file),
                ));
            }
            parts.insert(entry.uri, std::fs::read(dir.join(&entry.file))?);
        }
        Ok(parts)
    }

    /// The ids of every job directory, oldest first (ids sort by creation). Entries that are not
    /// job directories are skipped.
    pub fn list_job_ids(&self) -> io::Result<Vec<JobId>> {
        let mut ids = Vec::new();
        for entry in std::fs::read_dir(&self.jobs)? {
            let entry = entry?;
            if !entry.file_type()?.is_dir() {
                continue;
            }
            match entry.file_name().to_str().and_then(JobId::parse) {
                Some(id) => ids.push(id),
                None => tracing::warn!(
                    path = %entry.path().display(),
                    "not a job directory; left alone"
                ),
            }
        }
        ids.sort();
        Ok(ids)
    }

    /// Reads a small file of job `id` (`params.json`, `state.json`).
    pub fn read_file(&self, id: &JobId, name: &str) -> io::Result<Vec<u8>> {
        std::fs::read(self.job_dir(id).join(name))
    }

    /// Whether job `id` has its committed state (`state.json`), i.e. was accepted.
    pub fn is_committed(&self, id: &JobId) -> bool {
        self.job_dir(id).join(STATE_FILE).is_file()
    }

    /// Rewrites `state.json` of job `id`.
    pub fn write_state(&self, id: &JobId, state: &impl Serialize) -> io::Result<()> {
        let dir = self.job_dir(id);
        write_atomic(&dir.join(STATE_FILE), &to_json(state)?)?;
        sync_dir(&dir)
    }

    /// Path of the uploaded scene of job `id`: `input.*`, or in a directory that predates the
    /// baked scene ([`FileStore::predates_baking`]) `scene.*`.
    pub fn scene_path(&self, id: &JobId) -> io::Result<PathBuf> {
        let dir = self.job_dir(id);
        let names: &[&str] = if self.predates_baking(id) {
            &[LEGACY_SCENE_GLB, LEGACY_SCENE_GLTF]
        } else {
            &[INPUT_GLB, INPUT_GLTF]
        };
        names
            .iter()
            .map(|name| dir.join(name))
            .find(|p| p.is_file())
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::NotFound,
                    format!("job {id} has no scene file in {}", dir.display()),
                )
            })
    }

    /// True when job `id`'s directory was written by a version before the baked scene: no
    /// `input.*`, the upload stored as `scene.glb` or `scene.gltf` (so its `scene.glb`, if any,
    /// is the upload, never a baked scene).
    pub fn predates_baking(&self, id: &JobId) -> bool {
        let dir = self.job_dir(id);
        !dir.join(INPUT_GLB).is_file()
            && !dir.join(INPUT_GLTF).is_file()
            && (dir.join(LEGACY_SCENE_GLB).is_file() || dir.join(LEGACY_SCENE_GLTF).is_file())
    }

    /// Moves the upload of a directory that [predates baking](FileStore::predates_baking) to
    /// `input.*`, before the job runs again (its run writes `scene.glb`, the baked scene).
    pub fn adopt_legacy_upload(&self, id: &JobId) -> io::Result<()> {
        if !self.predates_baking(id) {
            return Ok(());
        }
        let dir = self.job_dir(id);
        for (old, new) in [
            (LEGACY_SCENE_GLB, INPUT_GLB),
            (LEGACY_SCENE_GLTF, INPUT_GLTF),
        ] {
            if dir.join(old).is_file() {
                std::fs::rename(dir.join(old), dir.join(new))?;
                return sync_dir(&dir);
            }
        }
        Ok(())
    }

    /// Path of an output file `name` (a plain file name, never a path) of job `id`.
    pub fn file_path(&self, id: &JobId, name: &str) -> PathBuf {
        self.job_dir(id).join(name)
    }

    /// Moves the job's directory to the trash (atomic), then removes it. A job directory that is
    /// already gone is not an error.
    pub fn delete_job(&self, id: &JobId) -> io::Result<()> {
        let dir = self.job_dir(id);
        let tombstone = self.trash.join(id.as_str());
        match std::fs::rename(&dir, &tombstone) {
            Ok(()) => {
                sync_dir(&self.jobs)?;
                std::fs::remove_dir_all(&tombstone)
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
            Err(e) => {
                tracing::warn!(job = %id, error = %e, "rename to trash failed; removing in place");
                std::fs::remove_dir_all(&dir)
            }
        }
    }

    /// Removes a job directory that never became a job (a failed or refused submission).
    pub fn discard(&self, id: &JobId) {
        if let Err(e) = std::fs::remove_dir_all(self.job_dir(id)) {
            tracing::warn!(job = %id, error = %e, "could not remove an abandoned job directory");
        }
    }
}

/// One entry of `parts.json`.
#[derive(Debug, Serialize, Deserialize)]
struct PartEntry {
    uri: String,
    file: String,
}

fn to_json(value: &impl Serialize) -> io::Result<Vec<u8>> {
    serde_json::to_vec_pretty(value).map_err(io::Error::other)
}

/// Makes a directory's entries (new, renamed files) durable.
fn sync_dir(dir: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_sort_by_creation_and_are_hex() {
        let a = JobId::generate(super::super::time::from_unix_millis(1_700_000_000_000));
        let b = JobId::generate(super::super::time::from_unix_millis(1_700_000_000_001));
        assert_eq!(a.as_str().len(), 16);
        assert!(a.as_str().bytes().all(|c| c.is_ascii_hexdigit()));
        assert!(a < b);
    }

    /// A directory of the version before the baked scene (upload as `scene.glb`): its scene is
    /// found there, it predates baking, and before it runs again the upload moves to
    /// `input.glb` (so the run's baked `scene.glb` cannot replace it).
    #[test]
    fn a_legacy_upload_is_found_and_adopted() {
        let dir =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/tmp-store-legacy");
        let _ = std::fs::remove_dir_all(&dir);
        let store = FileStore::open(&dir).unwrap();
        let id = store
            .create_job_dir(super::super::time::from_unix_millis(1_700_000_000_000))
            .unwrap();
        std::fs::write(store.job_dir(&id).join(LEGACY_SCENE_GLB), b"glTF old").unwrap();
        assert!(store.predates_baking(&id));
        assert!(store.scene_path(&id).unwrap().ends_with(LEGACY_SCENE_GLB));
        store.adopt_legacy_upload(&id).unwrap();
        assert!(!store.predates_baking(&id));
        let path = store.scene_path(&id).unwrap();
        assert!(path.ends_with(INPUT_GLB));
        assert_eq!(std::fs::read(path).unwrap(), b"glTF old");
        // A new job's baked scene beside its input does not make it look old.
        std::fs::write(store.job_dir(&id).join(LEGACY_SCENE_GLB), b"glTF baked").unwrap();
        assert!(!store.predates_baking(&id));
        assert!(store.scene_path(&id).unwrap().ends_with(INPUT_GLB));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn parse_accepts_only_ids() {
        assert!(JobId::parse("0123456789abcdef").is_some());
        assert!(JobId::parse("0123456789ABCDEF").is_none());
        assert!(JobId::parse("../../etc/passwd").is_none());
        assert!(JobId::parse("0123456789abcde").is_none());
    }

    #[test]
    fn parts_round_trip_and_uncommitted_dirs_are_visible() {
        let dir =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/tmp-store-unit");
        let _ = std::fs::remove_dir_all(&dir);
        let store = FileStore::open(&dir).unwrap();
        let id = store
            .create_job_dir(super::super::time::from_unix_millis(1_700_000_000_000))
            .unwrap();
        assert!(!store.is_committed(&id));
        let mut parts = BTreeMap::new();
        parts.insert("sub dir/b.bin".to_string(), vec![1u8, 2, 3]);
        store
            .write_new_job(
                &id,
                b"{}",
                &parts,
                &serde_json::json!({}),
                &serde_json::json!({}),
            )
            .unwrap();
        assert!(store.is_committed(&id));
        let back = store.read_parts(&id).unwrap();
        assert_eq!(back["sub dir/b.bin"], vec![1u8, 2, 3]);
        assert_eq!(store.list_job_ids().unwrap(), vec![id.clone()]);
        store.delete_job(&id).unwrap();
        assert!(store.list_job_ids().unwrap().is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn sniffs_glb_magic() {
        assert_eq!(SceneFormat::sniff(b"glTF\x02\0\0\0"), SceneFormat::Glb);
        assert_eq!(SceneFormat::sniff(b"{\"asset\":{}}"), SceneFormat::Gltf);
    }
}
