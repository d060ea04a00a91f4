//! Restart recovery: at start the store's job directories are read back onto the board. Finished
//! jobs are listed as they were; queued and running jobs are queued again (they start over); a job
//! whose files cannot be read is failed with the reason, never dropped. A directory without
//! `state.json` is a submission that was never accepted (its 202 was not sent) and is removed.

use super::error::ErrorBody;
use super::jobs::{Job, JobBoard, JobRecord, JobState, JobStatus, ProgressView};
use super::store::{FileStore, JobId, PARAMS_FILE, STATE_FILE};
use super::time::from_unix_millis;
use crate::job::JobParams;
use std::sync::Arc;

/// What recovery found.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Recovered {
    /// Finished jobs listed as they were.
    pub finished: usize,
    /// Queued or running jobs queued again.
    pub requeued: usize,
    /// Jobs failed because their files could not be read.
    pub failed: usize,
    /// Uncommitted submissions removed.
    pub discarded: usize,
}

/// Reads every job directory of `store` onto `board` (blocking: call before serving).
pub fn recover(store: &FileStore, board: &JobBoard) -> std::io::Result<Recovered> {
    let mut found = Recovered::default();
    for id in store.list_job_ids()? {
        if !store.is_committed(&id) {
            tracing::info!(job = %id, "removing a submission that was never accepted");
            store.discard(&id);
            found.discarded += 1;
            continue;
        }
        let (job, outcome) = read_job(store, &id, board.next_seq());
        let job = Arc::new(job);
        match outcome {
            Outcome::Finished => found.finished += 1,
            Outcome::Requeue => found.requeued += 1,
            Outcome::Failed => found.failed += 1,
        }
        if outcome != Outcome::Finished {
            // Record the new state (queued again, or failed with its reason).
            job.persist(store);
        }
        board.restore(job, outcome == Outcome::Requeue);
    }
    tracing::info!(
        finished = found.finished,
        requeued = found.requeued,
        failed = found.failed,
        discarded = found.discarded,
        "job store recovered"
    );
    Ok(found)
}

/// Error code of a job failed at recovery.
pub const RECOVERY_ERROR: &str = "unreadable_job";

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Finished,
    Requeue,
    Failed,
}

/// The job of directory `id`, and what recovery does with it.
fn read_job(store: &FileStore, id: &JobId, seq: u64) -> (Job, Outcome) {
    let record: Result<JobRecord, String> = store
        .read_file(id, STATE_FILE)
        .map_err(|e| format!("{STATE_FILE} cannot be read: {e}"))
        .and_then(|b| {
            serde_json::from_slice(&b).map_err(|e| format!("{STATE_FILE} is malformed: {e}"))
        });
    let params: Result<JobParams, String> = store
        .read_file(id, PARAMS_FILE)
        .map_err(|e| format!("{PARAMS_FILE} cannot be read: {e}"))
        .and_then(|b| {
            serde_json::from_slice(&b).map_err(|e| format!("{PARAMS_FILE} is malformed: {e}"))
        });
    // The id is the creation time in milliseconds (first 11 hex digits): a fallback for a
    // record that cannot be read.
    let created_ms = record
        .as_ref()
        .map(|r| r.created_unix_ms)
        .unwrap_or_else(|_| u64::from_str_radix(&id.as_str()[..11], 16).unwrap_or(0));
    let created = from_unix_millis(created_ms);
    let key = record.as_ref().ok().and_then(|r| r.idempotency_key.clone());
    let name = record.as_ref().ok().and_then(|r| r.name.clone());
    let sha256 = record.as_ref().ok().and_then(|r| r.request_sha256.clone());
    let fail = |reason: String| {
        JobStatus {
        state: JobState::Failed,
        progress: ProgressView::default(),
        error: Some(ErrorBody {
            code: RECOVERY_ERROR.into(),
            message: format!(
                "the service restarted and could not read this job back ({reason}); submit the scene again"
            ),
        }),
        stop_reason: None,
        attempts: 0,
    }
    };
    let record = match record {
        Ok(r) => r,
        Err(reason) => {
            let params = params.unwrap_or_default();
            let job = Job::restore(id.clone(), created, seq, params, fail(reason), key);
            return (job, Outcome::Failed);
        }
    };
    if record.state.is_finished() {
        let status = JobStatus {
            state: record.state,
            progress: record.progress,
            error: record.error,
            stop_reason: record.stop_reason,
            attempts: record.attempts,
        };
        let params = params.unwrap_or_default();
        let job = Job::restore(id.clone(), created, seq, params, status, key)
            .with_name(name)
            .with_request_sha256(sha256);
        return (job, Outcome::Finished);
    }
    // Queued or running: it runs again from the start if its input is still there.
    let input = params.and_then(|p| {
        // Its run writes the baked `scene.glb`: an upload stored under that name moves first.
        store
            .adopt_legacy_upload(id)
            .map_err(|e| format!("the scene cannot be moved to its new name: {e}"))?;
        let scene = store
            .scene_path(id)
            .map_err(|e| format!("the scene is missing: {e}"))?;
        std::fs::File::open(&scene).map_err(|e| format!("the scene cannot be read: {e}"))?;
        store
            .read_parts(id)
            .map_err(|e| format!("the uploaded parts cannot be read: {e}"))?;
        Ok(p)
    });
    match input {
        Ok(params) => {
            tracing::info!(job = %id, was = record.state.as_str(), "queued again after a restart");
            (
                Job::restore(
                    id.clone(),
                    created,
                    seq,
                    params,
                    JobStatus {
                        attempts: record.attempts,
                        ..JobStatus::queued()
                    },
                    key,
                )
                .with_name(name)
                .with_request_sha256(sha256),
                Outcome::Requeue,
            )
        }
        Err(reason) => {
            tracing::warn!(job = %id, %reason, "job failed at recovery");
            (
                Job::restore(
                    id.clone(),
                    created,
                    seq,
                    JobParams::default(),
                    fail(reason),
                    key,
                )
                .with_name(name)
                .with_request_sha256(sha256),
                Outcome::Failed,
            )
        }
    }
}
