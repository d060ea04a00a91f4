//! Jobs in memory: their state (one `tokio::sync::watch` channel per job, read by polling and, later,
//! by server-sent events), the documents they are shown as, and the board that holds every job and
//! the bounded queue of those waiting for a runner.

use super::error::ErrorBody;
use super::store::JobId;
use super::time::{rfc3339, unix_millis};
use crate::job::JobParams;
use crate::solver::Progress;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::SystemTime;
use tokio::sync::{watch, Notify};

/// Where a job is in its life. `succeeded`, `failed` and `cancelled` are final.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub fn is_finished(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
}

/// The CONTRACT's progress object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProgressView {
    /// Unshot power / emitted power (1 before the first shot).
    pub unshot_ratio: f64,
    pub iterations: u64,
    pub elements: u64,
    pub links: u64,
    /// Seconds of solving so far.
    pub seconds: f64,
    /// Estimated seconds to convergence; not estimated yet (always null).
    pub eta_seconds: Option<f64>,
}

impl Default for ProgressView {
    fn default() -> Self {
        ProgressView {
            unshot_ratio: 1.0,
            iterations: 0,
            elements: 0,
            links: 0,
            seconds: 0.0,
            eta_seconds: None,
        }
    }
}

impl From<&Progress> for ProgressView {
    fn from(p: &Progress) -> Self {
        ProgressView {
            unshot_ratio: p.unshot_ratio,
            iterations: p.iterations,
            elements: p.elements,
            links: p.links,
            seconds: p.seconds,
            eta_seconds: None,
        }
    }
}

/// What changes during a job's life (the value of its watch channel).
#[derive(Debug, Clone, PartialEq)]
pub struct JobStatus {
    pub state: JobState,
    pub progress: ProgressView,
    /// Why the job failed (state `failed`).
    pub error: Option<ErrorBody>,
    /// The solver's stop reason of a finished solve (`converged`, `time_budget`, ...).
    pub stop_reason: Option<String>,
}

impl JobStatus {
    fn queued() -> Self {
        JobStatus {
            state: JobState::Queued,
            progress: ProgressView::default(),
            error: None,
            stop_reason: None,
        }
    }
}

/// Links of a job document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobLinks {
    #[serde(rename = "self")]
    pub self_: String,
    pub result: String,
    pub lightmap: String,
    pub convergence: String,
}

/// The job document of the HTTP API.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobView {
    pub id: String,
    pub state: JobState,
    /// RFC 3339 UTC.
    pub created: String,
    pub params: JobParams,
    pub progress: ProgressView,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    /// Why the solve stopped (`converged`, `time_budget`, `cancelled`, `iteration_limit`), once it
    /// has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
    pub links: JobLinks,
}

/// `state.json`: what a restarted service needs to know about a job besides its scene and params.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    pub id: String,
    pub state: JobState,
    pub created: String,
    pub created_unix_ms: u64,
    pub progress: ProgressView,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
}

/// One job.
#[derive(Debug)]
pub struct Job {
    pub id: JobId,
    pub created: SystemTime,
    /// Order of acceptance (ties of `created` in the listing).
    pub seq: u64,
    pub params: JobParams,
    cancel: AtomicBool,
    status: watch::Sender<JobStatus>,
    /// Serialises writes of this job's state.json (the last writer writes the latest state).
    persist: Mutex<()>,
}

impl Job {
    pub fn new(id: JobId, created: SystemTime, seq: u64, params: JobParams) -> Job {
        Job {
            id,
            created,
            seq,
            params,
            cancel: AtomicBool::new(false),
            status: watch::Sender::new(JobStatus::queued()),
            persist: Mutex::new(()),
        }
    }

    pub fn status(&self) -> JobStatus {
        self.status.borrow().clone()
    }

    pub fn state(&self) -> JobState {
        self.status.borrow().state
    }

    /// A receiver that sees every later change (for server-sent events).
    pub fn subscribe(&self) -> watch::Receiver<JobStatus> {
        self.status.subscribe()
    }

    /// The flag the solver checks between shots.
    pub fn cancel_flag(&self) -> &AtomicBool {
        &self.cancel
    }

    pub fn request_cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
    }

    pub fn cancel_requested(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }

    /// Applies `change` to the status atomically; `change` returns whether it changed anything.
    pub fn update(&self, change: impl FnOnce(&mut JobStatus) -> bool) -> bool {
        self.status.send_if_modified(change)
    }

    /// Records the progress of a shot.
    pub fn set_progress(&self, progress: ProgressView) {
        self.status.send_modify(|s| s.progress = progress);
    }

    pub fn view(&self) -> JobView {
        let status = self.status.borrow();
        let base = format!("/v1/jobs/{}", self.id);
        JobView {
            id: self.id.to_string(),
            state: status.state,
            created: rfc3339(self.created),
            params: self.params.clone(),
            progress: status.progress,
            error: status.error.clone(),
            stop_reason: status.stop_reason.clone(),
            links: JobLinks {
                result: format!("{base}/result"),
                lightmap: format!("{base}/lightmap.exr"),
                convergence: format!("{base}/convergence"),
                self_: base,
            },
        }
    }

    pub fn record(&self) -> JobRecord {
        let status = self.status.borrow();
        JobRecord {
            id: self.id.to_string(),
            state: status.state,
            created: rfc3339(self.created),
            created_unix_ms: unix_millis(self.created),
            progress: status.progress,
            error: status.error.clone(),
            stop_reason: status.stop_reason.clone(),
        }
    }

    /// Writes the current state to `state.json` (blocking). Failures are logged: the job goes on,
    /// and the in-memory state stays the truth for this process.
    pub fn persist(&self, store: &super::store::FileStore) {
        let _guard = lock(&self.persist);
        if let Err(e) = store.write_state(&self.id, &self.record()) {
            tracing::error!(job = %self.id, error = %e, "could not write state.json");
        }
    }
}

/// Locks a mutex whose critical sections cannot leave it inconsistent (none of them panics midway),
/// so a poisoned lock is still usable.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

#[derive(Debug, Default)]
struct Board {
    jobs: HashMap<String, Arc<Job>>,
    queue: VecDeque<Arc<Job>>,
    next_seq: u64,
}

/// Every job this process knows, and the bounded queue of jobs waiting for a runner.
#[derive(Debug)]
pub struct JobBoard {
    board: Mutex<Board>,
    wake: Notify,
    max_queued: usize,
}

impl JobBoard {
    pub fn new(max_queued: usize) -> JobBoard {
        JobBoard {
            board: Mutex::new(Board::default()),
            wake: Notify::new(),
            max_queued,
        }
    }

    pub fn max_queued(&self) -> usize {
        self.max_queued
    }

    /// A sequence number for a new job.
    pub fn next_seq(&self) -> u64 {
        let mut b = lock(&self.board);
        b.next_seq += 1;
        b.next_seq
    }

    pub fn get(&self, id: &str) -> Option<Arc<Job>> {
        lock(&self.board).jobs.get(id).cloned()
    }

    /// Every job, newest first.
    pub fn list(&self) -> Vec<Arc<Job>> {
        let mut jobs: Vec<Arc<Job>> = lock(&self.board).jobs.values().cloned().collect();
        jobs.sort_by_key(|j| std::cmp::Reverse((j.created, j.seq)));
        jobs
    }

    /// Jobs waiting for a runner.
    pub fn queued(&self) -> usize {
        lock(&self.board).queue.len()
    }

    /// True when one more job could be queued now.
    pub fn has_room(&self) -> bool {
        self.queued() < self.max_queued
    }

    /// Adds `job` to the board and the end of the queue, or gives it back when the queue is full.
    pub fn enqueue(&self, job: Arc<Job>) -> Result<(), Arc<Job>> {
        {
            let mut b = lock(&self.board);
            if b.queue.len() >= self.max_queued {
                return Err(job);
            }
            b.jobs.insert(job.id.to_string(), job.clone());
            b.queue.push_back(job);
        }
        self.wake.notify_one();
        Ok(())
    }

    /// Takes `job` out of the queue; false when it was not waiting (a runner has it, or it ended).
    pub fn dequeue(&self, job: &Job) -> bool {
        let mut b = lock(&self.board);
        let before = b.queue.len();
        b.queue.retain(|j| j.id != job.id);
        b.queue.len() != before
    }

    /// Removes a job from the board (and the queue).
    pub fn forget(&self, id: &str) -> Option<Arc<Job>> {
        let mut b = lock(&self.board);
        b.queue.retain(|j| j.id.as_str() != id);
        b.jobs.remove(id)
    }

    /// The next queued job, waiting until there is one.
    pub async fn next(&self) -> Arc<Job> {
        loop {
            if let Some(job) = lock(&self.board).queue.pop_front() {
                return job;
            }
            // `notify_one` stores a permit when no runner is waiting, so a job queued between the
            // check above and this wait still wakes us.
            self.wake.notified().await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::service::time::from_unix_millis;

    fn job(board: &JobBoard, ms: u64) -> Arc<Job> {
        let id = format!("{ms:016x}");
        Arc::new(Job::new(
            JobId::for_tests(&id),
            from_unix_millis(ms),
            board.next_seq(),
            JobParams::default(),
        ))
    }

    #[test]
    fn queue_is_bounded_and_listing_is_newest_first() {
        let board = JobBoard::new(2);
        let a = job(&board, 1);
        let b = job(&board, 2);
        let c = job(&board, 3);
        assert!(board.enqueue(a.clone()).is_ok());
        assert!(board.enqueue(b.clone()).is_ok());
        assert!(board.enqueue(c.clone()).is_err());
        assert!(!board.has_room());
        let ids: Vec<_> = board.list().iter().map(|j| j.id.to_string()).collect();
        assert_eq!(ids, vec![b.id.to_string(), a.id.to_string()]);
        assert!(board.dequeue(&a));
        assert!(!board.dequeue(&a));
        assert!(board.has_room());
        assert!(board.forget(a.id.as_str()).is_some());
        assert_eq!(board.list().len(), 1);
    }

    #[test]
    fn job_document_has_contract_fields() {
        let board = JobBoard::new(1);
        let j = job(&board, 1_709_210_096_789);
        let v = serde_json::to_value(j.view()).unwrap();
        assert_eq!(v["state"], "queued");
        assert_eq!(v["created"], "2024-02-29T12:34:56.789Z");
        assert!(v["progress"]["eta_seconds"].is_null());
        assert_eq!(v["progress"]["unshot_ratio"], 1.0);
        assert!(v.get("error").is_none());
        assert_eq!(v["links"]["self"], format!("/v1/jobs/{}", j.id));
    }
}
