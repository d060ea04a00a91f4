//! Jobs in memory: their state (one `tokio::sync::watch` channel per job, read by polling and by
//! server-sent events), the documents they are shown as, and the board that holds every job and
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

/// The progress object of docs/contract.md. Updated after every shot and, during a shot that
/// lasts longer than the solver's `REPORT_INTERVAL`, from within it (`shot_receivers_done`
/// moving while `iterations` stays: `tests/http_observe.rs`,
/// `the_progress_object_moves_within_a_long_shot`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProgressView {
    /// Unshot power / emitted power after the last finished shot (1 before the first shot).
    pub unshot_ratio: f64,
    /// Shots finished.
    pub iterations: u64,
    pub elements: u64,
    pub links: u64,
    /// Seconds of solving so far.
    pub seconds: f64,
    /// Receiver roots the shot in progress has finished (0 between shots). Absent from the
    /// `state.json` of jobs recorded before it existed: read as 0.
    #[serde(default)]
    pub shot_receivers_done: u64,
    /// Receiver roots the shot in progress visits (those facing the shooter; 0 between shots).
    #[serde(default)]
    pub shot_receivers: u64,
    /// Estimated seconds until the solve ends (the target reached, or the time budget spent):
    /// the solver's estimate (`Progress::eta_seconds`); null until it can be made and once the
    /// job has ended.
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
            shot_receivers_done: 0,
            shot_receivers: 0,
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
            shot_receivers_done: p.shot_receivers_done,
            shot_receivers: p.shot_receivers,
            eta_seconds: p.eta_seconds.filter(|e| e.is_finite()),
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
    /// Times a runner took the job (0 while it has not run).
    pub attempts: u32,
}

impl JobStatus {
    pub fn queued() -> Self {
        JobStatus {
            state: JobState::Queued,
            progress: ProgressView::default(),
            error: None,
            stop_reason: None,
            attempts: 0,
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
    /// The scene's name: the `name` parameter of the submission, else the file name of a
    /// multipart upload's `scene` part; absent when neither was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
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
    /// Times a runner (a replica, in cluster mode) took the job: 0 while queued for the first
    /// time, 1 once it ran (tests/http_jobs.rs, `a_finished_job_shows_one_attempt`).
    #[serde(default)]
    pub attempts: u32,
    pub links: JobLinks,
}

/// `state.json`: what a restarted service needs to know about a job besides its scene and params.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    pub id: String,
    /// The scene's name (absent from jobs recorded before it existed, and from unnamed jobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub state: JobState,
    pub created: String,
    pub created_unix_ms: u64,
    pub progress: ProgressView,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub idempotency_key: Option<String>,
    /// SHA-256 (hex) of the keyed request that created the job (`routes::submit`,
    /// `request_fingerprint`): a reuse of the key with another request is refused. Absent from
    /// unkeyed jobs and from records written before it existed (a retry then gets the job).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request_sha256: Option<String>,
    /// Times a runner took the job (absent from records written before it existed: 0).
    #[serde(default)]
    pub attempts: u32,
}

/// One job.
#[derive(Debug)]
pub struct Job {
    pub id: JobId,
    pub created: SystemTime,
    /// Order of acceptance (ties of `created` in the listing).
    pub seq: u64,
    pub params: JobParams,
    /// The `Idempotency-Key` of the POST that created it.
    pub idempotency_key: Option<String>,
    /// The fingerprint of that POST (`JobRecord::request_sha256`).
    pub request_sha256: Option<String>,
    /// The scene's name, as shown in the job document (`JobView::name`).
    pub name: Option<String>,
    /// The flag the solver checks (between shots and inside them): stop now.
    stop: AtomicBool,
    /// Set with `stop` when a client cancelled; `stop` alone means the server is shutting down
    /// and the job goes back to the queue.
    cancel: AtomicBool,
    status: watch::Sender<JobStatus>,
    /// Serialises writes of this job's state.json (the last writer writes the latest state).
    persist: Mutex<()>,
}

impl Job {
    pub fn new(id: JobId, created: SystemTime, seq: u64, params: JobParams) -> Job {
        Job::restore(id, created, seq, params, JobStatus::queued(), None)
    }

    /// A job with a given status (a job read back from the store, or a keyed submission).
    pub fn restore(
        id: JobId,
        created: SystemTime,
        seq: u64,
        params: JobParams,
        status: JobStatus,
        idempotency_key: Option<String>,
    ) -> Job {
        Job {
            id,
            created,
            seq,
            params,
            idempotency_key,
            request_sha256: None,
            name: None,
            stop: AtomicBool::new(false),
            cancel: AtomicBool::new(false),
            status: watch::Sender::new(status),
            persist: Mutex::new(()),
        }
    }

    /// The job with the fingerprint of the keyed request that created it.
    pub fn with_request_sha256(mut self, sha256: Option<String>) -> Job {
        self.request_sha256 = sha256;
        self
    }

    /// The job with its scene's name (already validated: `routes::submit`).
    pub fn with_name(mut self, name: Option<String>) -> Job {
        self.name = name;
        self
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

    /// The flag the solver checks between shots and inside them.
    pub fn cancel_flag(&self) -> &AtomicBool {
        &self.stop
    }

    /// A client cancelled: the job ends `cancelled`.
    pub fn request_cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
        self.stop.store(true, Ordering::SeqCst);
    }

    /// The server is shutting down: the solve stops and the job goes back to `queued`.
    pub fn request_requeue(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }

    pub fn cancel_requested(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }

    /// Applies `change` to the status atomically; `change` returns whether it changed anything.
    pub fn update(&self, change: impl FnOnce(&mut JobStatus) -> bool) -> bool {
        self.status.send_if_modified(change)
    }

    /// Records the solver's progress (after a shot, or from within one), its ETA included.
    pub fn set_progress(&self, progress: ProgressView) {
        self.status.send_modify(|s| s.progress = progress);
    }

    pub fn view(&self) -> JobView {
        let status = self.status.borrow();
        let base = format!("/v1/jobs/{}", self.id);
        JobView {
            id: self.id.to_string(),
            name: self.name.clone(),
            state: status.state,
            created: rfc3339(self.created),
            params: self.params.clone(),
            progress: status.progress,
            error: status.error.clone(),
            stop_reason: status.stop_reason.clone(),
            attempts: status.attempts,
            links: JobLinks {
                result: format!("{base}/result"),
                lightmap: format!("{base}/lightmap.exr"),
                convergence: format!("{base}/convergence"),
                self_: base,
            },
        }
    }

    pub fn record(&self) -> JobRecord {
        self.record_of(&self.status.borrow())
    }

    fn record_of(&self, status: &JobStatus) -> JobRecord {
        JobRecord {
            id: self.id.to_string(),
            name: self.name.clone(),
            state: status.state,
            created: rfc3339(self.created),
            created_unix_ms: unix_millis(self.created),
            progress: status.progress,
            error: status.error.clone(),
            stop_reason: status.stop_reason.clone(),
            idempotency_key: self.idempotency_key.clone(),
            request_sha256: self.request_sha256.clone(),
            attempts: status.attempts,
        }
    }

    /// Applies `change` to a copy of the status, writes it to `state.json`, and only then makes it
    /// the status everyone sees (blocking). For the transitions a client acts on (finished, or
    /// back in the queue): a client that saw a job `succeeded` finds it `succeeded` after a crash,
    /// never running it again. `change` returns whether it changed anything. Progress reports
    /// that arrive meanwhile are replaced (only the runner that owns the job makes them, and it
    /// is the caller).
    pub fn settle(
        &self,
        store: &super::store::FileStore,
        change: impl FnOnce(&mut JobStatus) -> bool,
    ) -> bool {
        let _guard = lock(&self.persist);
        let mut next = self.status();
        if !change(&mut next) {
            return false;
        }
        if let Err(e) = store.write_state(&self.id, &self.record_of(&next)) {
            tracing::error!(job = %self.id, error = %e, "could not write state.json");
        }
        self.status.send_replace(next);
        true
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
    /// Jobs by the `Idempotency-Key` that created them.
    keys: HashMap<String, Arc<Job>>,
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
            Self::insert(&mut b, &job);
            b.queue.push_back(job);
        }
        self.wake.notify_one();
        Ok(())
    }

    /// Adds a job read back from the store at start: queued again when `requeue` (even beyond
    /// `max_queued`: an accepted job is never dropped), listed as it was otherwise.
    pub fn restore(&self, job: Arc<Job>, requeue: bool) {
        {
            let mut b = lock(&self.board);
            Self::insert(&mut b, &job);
            if requeue {
                b.queue.push_back(job);
            }
        }
        if requeue {
            self.wake.notify_one();
        }
    }

    /// Puts a job that was stopped for a shutdown back at the head of the queue.
    pub fn requeue_front(&self, job: Arc<Job>) {
        lock(&self.board).queue.push_front(job);
        self.wake.notify_one();
    }

    fn insert(b: &mut Board, job: &Arc<Job>) {
        b.jobs.insert(job.id.to_string(), job.clone());
        if let Some(key) = &job.idempotency_key {
            b.keys.insert(key.clone(), job.clone());
        }
    }

    /// The job created by the POST with this `Idempotency-Key`.
    pub fn by_key(&self, key: &str) -> Option<Arc<Job>> {
        lock(&self.board).keys.get(key).cloned()
    }

    /// Finished jobs, oldest first (for `--retain-jobs`).
    pub fn finished_oldest_first(&self) -> Vec<Arc<Job>> {
        let mut jobs: Vec<Arc<Job>> = lock(&self.board)
            .jobs
            .values()
            .filter(|j| j.state().is_finished())
            .cloned()
            .collect();
        jobs.sort_by_key(|j| (j.created, j.seq));
        jobs
    }

    /// Number of jobs in each state.
    pub fn count_by_state(&self) -> [(JobState, usize); 5] {
        let mut counts = [
            (JobState::Queued, 0),
            (JobState::Running, 0),
            (JobState::Succeeded, 0),
            (JobState::Failed, 0),
            (JobState::Cancelled, 0),
        ];
        for job in lock(&self.board).jobs.values() {
            let state = job.state();
            if let Some(c) = counts.iter_mut().find(|c| c.0 == state) {
                c.1 += 1;
            }
        }
        counts
    }

    /// Takes `job` out of the queue; false when it was not waiting (a runner has it, or it ended).
    pub fn dequeue(&self, job: &Job) -> bool {
        let mut b = lock(&self.board);
        let before = b.queue.len();
        b.queue.retain(|j| j.id != job.id);
        b.queue.len() != before
    }

    /// Removes a job from the board (and the queue, and the idempotency keys).
    pub fn forget(&self, id: &str) -> Option<Arc<Job>> {
        let mut b = lock(&self.board);
        b.queue.retain(|j| j.id.as_str() != id);
        let job = b.jobs.remove(id)?;
        if let Some(key) = &job.idempotency_key {
            b.keys.remove(key);
        }
        Some(job)
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
    fn a_name_goes_into_the_record_and_the_view_and_old_records_have_none() {
        let board = JobBoard::new(4);
        let named = Job::new(
            JobId::for_tests("00000000000000aa"),
            from_unix_millis(0xaa),
            board.next_seq(),
            JobParams::default(),
        )
        .with_name(Some("room.gltf".into()));
        let record = serde_json::to_value(named.record()).unwrap();
        assert_eq!(record["name"], "room.gltf");
        assert_eq!(named.view().name.as_deref(), Some("room.gltf"));
        let unnamed = job(&board, 0xab);
        let record = serde_json::to_value(unnamed.record()).unwrap();
        assert!(record.get("name").is_none(), "{record}");
        assert!(serde_json::to_value(unnamed.view())
            .unwrap()
            .get("name")
            .is_none());
        // A state.json written before names existed reads back without one.
        let mut old = record;
        old.as_object_mut().unwrap().remove("name");
        let back: JobRecord = serde_json::from_value(old).unwrap();
        assert_eq!(back.name, None);
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

    /// Whoever sees a job finished (a poll, an event stream, the test killing the service right
    /// after) must find it finished in `state.json`, or a crash would run it again. A watcher
    /// spinning on the status reads the file the moment the change shows.
    #[test]
    fn a_settled_status_is_on_disk_before_anyone_sees_it() {
        use crate::service::store::{FileStore, STATE_FILE};
        let dir =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/tmp-settle-unit");
        let _ = std::fs::remove_dir_all(&dir);
        let store = FileStore::open(&dir).unwrap();
        for round in 0..10 {
            let id = store.create_job_dir(SystemTime::now()).unwrap();
            let job = Arc::new(Job::new(id, SystemTime::now(), round, JobParams::default()));
            job.persist(&store);
            let state_file = store.job_dir(&job.id).join(STATE_FILE);
            let watcher = {
                let seen = job.subscribe();
                std::thread::spawn(move || {
                    while !seen.has_changed().unwrap_or(true) {
                        std::hint::spin_loop();
                    }
                    let text = std::fs::read_to_string(&state_file).unwrap();
                    serde_json::from_str::<serde_json::Value>(&text).unwrap()["state"].clone()
                })
            };
            job.settle(&store, |s| {
                s.state = JobState::Succeeded;
                true
            });
            assert_eq!(watcher.join().unwrap(), "succeeded", "round {round}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn job_document_has_contract_fields() {
        let board = JobBoard::new(1);
        let j = job(&board, 1_709_210_096_789);
        let v = serde_json::to_value(j.view()).unwrap();
        assert_eq!(v["state"], "queued");
        assert_eq!(v["created"], "2024-02-29T12:34:56.789Z");
        assert!(v["progress"]["eta_seconds"].is_null());
        assert_eq!(v["progress"]["shot_receivers_done"], 0);
        assert_eq!(v["progress"]["shot_receivers"], 0);
        assert_eq!(v["progress"]["unshot_ratio"], 1.0);
        assert!(v.get("error").is_none());
        assert_eq!(v["links"]["self"], format!("/v1/jobs/{}", j.id));
    }
}
