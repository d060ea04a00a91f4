//! The runners of a cluster replica: each claims the oldest queued job (woken by `NOTIFY`, else
//! every [`POLL`](super::POLL)), downloads its upload into a scratch directory under
//! `--data-dir`, solves it on the replica's solver pool while a heartbeat renews the lease,
//! records the progress and reads the cancel request every [`HEARTBEAT`](super::HEARTBEAT), then
//! uploads the outputs under the attempt's prefix and only then ends the attempt in the row.
//!
//! A heartbeat refused (a newer attempt holds the job) stops the solve and discards its outputs;
//! a shutdown stops the solve and gives the job back to the queue.

use super::db::{Finish, JobRow};
use super::objects::Objects;
use super::Cluster;
use crate::job::{run_job_keeping_solution, JobError, JobOutcome, ProbeSource};
use crate::scene::{load_scene, ExternalFiles, Scene};
use crate::service::error::ErrorBody;
use crate::service::jobs::{JobState, ProgressView};
use crate::service::runner::{final_progress, guarded, Finished};
use crate::service::store::SOLUTION_FILE;
use crate::service::AppState;
use crate::solver::StopReason;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// Longest a replica keeps retrying the write that ends an attempt while the database is away.
const FINISH_RETRY: Duration = Duration::from_secs(120);

/// Starts the LISTEN task and `workers` runners.
pub(crate) fn spawn(
    state: &AppState,
    cluster: &Arc<Cluster>,
    pool: Arc<rayon::ThreadPool>,
    workers: usize,
) {
    tokio::spawn(super::db::listen(
        cluster.settings.database_url.clone(),
        cluster.clone(),
    ));
    tokio::spawn(sweeper(state.clone(), cluster.clone()));
    for index in 0..workers {
        let state = state.clone();
        let cluster = cluster.clone();
        let pool = pool.clone();
        tokio::spawn(async move { runner(state, cluster, pool, index).await });
    }
}

/// Every [`POLL`](super::POLL), even while this replica's runners are busy: jobs whose lease
/// expired go back to the queue (or fail after `max_attempts`), and idle runners are woken.
async fn sweeper(state: AppState, cluster: Arc<Cluster>) {
    let mut shutdown = state.shutdown_signal();
    loop {
        match cluster
            .db
            .sweep_expired(cluster.settings.max_attempts)
            .await
        {
            Ok(0) => {}
            Ok(n) => {
                tracing::warn!(jobs = n, "leases expired: jobs queued again (or failed)");
                cluster.wake.notify_waiters();
            }
            Err(e) => tracing::debug!(error = %e, "cannot sweep expired leases"),
        }
        tokio::select! {
            () = tokio::time::sleep(super::POLL) => {}
            _ = shutdown.wait_for(|down| *down) => return,
        }
    }
}

async fn runner(
    state: AppState,
    cluster: Arc<Cluster>,
    pool: Arc<rayon::ThreadPool>,
    index: usize,
) {
    let mut shutdown = state.shutdown_signal();
    loop {
        if state.is_shutting_down() {
            return;
        }
        let lease = cluster.settings.lease_seconds as f64;
        match cluster.db.claim(&cluster.replica, lease).await {
            Ok(Some(job)) => {
                cluster.counters.claims.fetch_add(1, Ordering::Relaxed);
                tracing::info!(runner = index, job = %job.id, attempt = job.attempt, "claimed");
                run(&state, &cluster, &pool, job).await;
                continue;
            }
            Ok(None) => {}
            Err(e) => tracing::warn!(error = %e, "cannot claim a job (database unavailable?)"),
        }
        tokio::select! {
            () = cluster.wake.notified() => {}
            () = tokio::time::sleep(super::POLL) => {}
            _ = shutdown.wait_for(|down| *down) => return,
        }
    }
}

/// The flags and progress a running attempt shares between its solve and its heartbeat.
#[derive(Debug, Default)]
struct Attempt {
    /// The solver's stop flag.
    stop: AtomicBool,
    /// A client cancelled (the job ends `cancelled`).
    cancel: AtomicBool,
    /// A newer attempt holds the job: nothing more is written.
    lost: AtomicBool,
    progress: Mutex<ProgressView>,
}

async fn run(state: &AppState, cluster: &Arc<Cluster>, pool: &Arc<rayon::ThreadPool>, job: JobRow) {
    state.solve_started();
    let scratch = state
        .config()
        .data_dir
        .join("cluster-work")
        .join(format!("{}-attempt-{}", job.id, job.attempt));
    let attempt = Arc::new(Attempt::default());
    let heartbeat = tokio::spawn(heartbeat(
        cluster.clone(),
        job.id.clone(),
        job.attempt,
        attempt.clone(),
        state.shutdown_signal(),
    ));
    let finished = solve_attempt(state, cluster, pool, &job, &scratch, &attempt).await;
    heartbeat.abort();
    let _ = heartbeat.await;
    end_attempt(state, cluster, &job, &scratch, &attempt, finished).await;
    let _ = tokio::fs::remove_dir_all(&scratch).await;
    state.solve_ended();
}

/// Downloads the upload, solves it on the pool and saves the solution next to the outputs.
async fn solve_attempt(
    state: &AppState,
    cluster: &Cluster,
    pool: &Arc<rayon::ThreadPool>,
    job: &JobRow,
    scratch: &Path,
    attempt: &Arc<Attempt>,
) -> (Finished, Option<ProbeSource>) {
    let input = match download_input(&cluster.objects, job).await {
        Ok(input) => input,
        Err(e) => {
            return (
                Finished::Error(ErrorBody {
                    code: "input_unavailable".into(),
                    message: format!("the job's upload cannot be read from the object store: {e}"),
                }),
                None,
            )
        }
    };
    if let Err(e) = tokio::fs::create_dir_all(scratch).await {
        return (
            Finished::Error(ErrorBody {
                code: "output_error".into(),
                message: format!("cannot create the replica's scratch directory: {e}"),
            }),
            None,
        );
    }
    let (tx, rx) = tokio::sync::oneshot::channel();
    let max_triangles = state.config().max_triangles;
    let params = job.params.clone();
    let dir = scratch.to_path_buf();
    let shared = attempt.clone();
    pool.spawn(move || {
        let mut kept = None;
        let finished = guarded(|| {
            let scene = input.scene(max_triangles)?;
            let (outcome, solution) =
                run_job_keeping_solution(&scene, &params, None, &dir, &shared.stop, &mut |p| {
                    *shared
                        .progress
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner) = ProgressView::from(p);
                })?;
            if let Some(solution) = &solution {
                solution.save(&dir.join(SOLUTION_FILE))?;
            }
            kept = solution;
            Ok::<JobOutcome, JobError>(outcome)
        });
        let _ = tx.send((finished, kept));
    });
    rx.await.unwrap_or_else(|_| {
        (
            Finished::Error(ErrorBody {
                code: "internal_error".into(),
                message: "the solver task ended unexpectedly; the server log has details".into(),
            }),
            None,
        )
    })
}

/// Records how the attempt ended: outputs uploaded first, then the fenced write of the row.
async fn end_attempt(
    state: &AppState,
    cluster: &Cluster,
    job: &JobRow,
    scratch: &Path,
    attempt: &Attempt,
    (finished, solution): (Finished, Option<ProbeSource>),
) {
    if attempt.lost.load(Ordering::SeqCst) {
        cluster.counters.lost_leases.fetch_add(1, Ordering::Relaxed);
        tracing::warn!(job = %job.id, attempt = job.attempt, "lease lost: a newer attempt holds the job; outputs discarded");
        return;
    }
    if let Finished::Solved(outcome) = &finished {
        let seconds = outcome
            .result
            .get("stats")
            .and_then(|s| s.get("seconds"))
            .and_then(|v| v.as_f64());
        let progress = *attempt
            .progress
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        state.metrics().record_solve(
            seconds.unwrap_or(progress.seconds),
            progress.iterations,
            0,
            progress.elements,
        );
        let stopped = outcome.stop_reason == StopReason::Cancelled;
        if stopped && !attempt.cancel.load(Ordering::SeqCst) {
            // Stopped for a shutdown: back to the queue for another replica.
            match with_retry(|| cluster.db.release(&job.id, job.attempt)).await {
                Some(true) => tracing::info!(job = %job.id, "stopped for shutdown; queued again"),
                _ => {
                    tracing::warn!(job = %job.id, "could not give the job back; its lease expires")
                }
            }
            return;
        }
    }
    let (state_now, stop_reason, progress, error, result_attempt) = match &finished {
        Finished::Solved(outcome) => {
            if let Err(e) = upload_outputs(&cluster.objects, &job.id, job.attempt, scratch).await {
                tracing::error!(job = %job.id, error = %e, "cannot upload the outputs; the lease will expire and another replica retries");
                return;
            }
            let state_now = if outcome.stop_reason == StopReason::Cancelled {
                JobState::Cancelled
            } else {
                JobState::Succeeded
            };
            let mut progress = final_progress(&outcome.result).unwrap_or_else(|| {
                *attempt
                    .progress
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
            });
            progress.eta_seconds = None;
            (
                state_now,
                Some(outcome.stop_reason.as_str()),
                Some(progress),
                None,
                Some(job.attempt),
            )
        }
        Finished::Error(body) => (JobState::Failed, None, None, Some(body.clone()), None),
    };
    let end = Finish {
        state: state_now,
        stop_reason,
        progress: progress.as_ref(),
        error: error.as_ref(),
        result_attempt,
    };
    match with_retry(|| cluster.db.finish(&job.id, job.attempt, &end)).await {
        Some(true) => {
            if state_now == JobState::Succeeded {
                if let Some(solution) = solution {
                    state.keep_probe_source(&job.id, Arc::new(solution));
                }
            }
            tracing::info!(job = %job.id, attempt = job.attempt, state = state_now.as_str(), "job finished");
        }
        Some(false) => {
            cluster.counters.lost_leases.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(job = %job.id, attempt = job.attempt, "a newer attempt holds the job; this attempt's outputs are discarded");
            let _ = cluster.objects.delete_attempt(&job.id, job.attempt).await;
        }
        None => {
            tracing::error!(job = %job.id, "the database stayed unavailable; the lease will expire and another replica retries")
        }
    }
}

/// Runs `op` until it succeeds, for at most [`FINISH_RETRY`] (the database may be restarting).
async fn with_retry<T, F, Fut>(op: F) -> Option<T>
where
    F: Fn() -> Fut,
    Fut: std::future::Future<Output = Result<T, super::db::DbError>>,
{
    let start = std::time::Instant::now();
    loop {
        match op().await {
            Ok(v) => return Some(v),
            Err(e) if start.elapsed() < FINISH_RETRY => {
                tracing::warn!(error = %e, "database write failed; retrying");
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
            Err(e) => {
                tracing::error!(error = %e, "database write failed; giving up");
                return None;
            }
        }
    }
}

/// Renews the lease, records the progress and reads the cancel request every
/// [`HEARTBEAT`](super::HEARTBEAT) until aborted; sets the stop flag on a cancel, a lost lease
/// or a shutdown.
async fn heartbeat(
    cluster: Arc<Cluster>,
    id: String,
    number: i32,
    attempt: Arc<Attempt>,
    mut shutdown: tokio::sync::watch::Receiver<bool>,
) {
    let lease = cluster.settings.lease_seconds as f64;
    let mut tick = tokio::time::interval(super::HEARTBEAT);
    loop {
        let down = tokio::select! {
            _ = tick.tick() => false,
            seen = shutdown.wait_for(|down| *down) => seen.is_ok(),
        };
        if down {
            // The solve stops at its next check; the runner gives the job back.
            attempt.stop.store(true, Ordering::SeqCst);
            std::future::pending::<()>().await;
        }
        let progress = *attempt
            .progress
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        match cluster.db.heartbeat(&id, number, lease, &progress).await {
            Ok(Some(true)) => {
                if !attempt.cancel.swap(true, Ordering::SeqCst) {
                    cluster
                        .counters
                        .cancels_seen
                        .fetch_add(1, Ordering::Relaxed);
                    tracing::info!(job = %id, "cancel requested; stopping the solve");
                }
                attempt.stop.store(true, Ordering::SeqCst);
            }
            Ok(Some(false)) => {}
            Ok(None) => {
                attempt.lost.store(true, Ordering::SeqCst);
                attempt.stop.store(true, Ordering::SeqCst);
                return;
            }
            Err(e) => {
                tracing::warn!(job = %id, error = %e, "heartbeat failed (database unavailable?)")
            }
        }
    }
}

/// A job's upload, read back from the object store.
pub(crate) struct Input {
    scene: bytes::Bytes,
    parts: HashMap<String, Vec<u8>>,
}

impl Input {
    pub(crate) fn scene(&self, max_triangles: usize) -> Result<Scene, JobError> {
        let external = if self.parts.is_empty() {
            ExternalFiles::Refuse
        } else {
            ExternalFiles::Named(self.parts.clone())
        };
        Ok(load_scene(&self.scene, &external, max_triangles)?)
    }
}

pub(crate) async fn download_input(objects: &Objects, job: &JobRow) -> std::io::Result<Input> {
    let missing =
        |key: &str| std::io::Error::new(std::io::ErrorKind::NotFound, format!("{key} is missing"));
    let key = Objects::job_key(&job.id, &job.input_name);
    let scene = objects.get(&key).await?.ok_or_else(|| missing(&key))?;
    let mut parts = HashMap::with_capacity(job.parts.len());
    for (uri, object) in &job.parts {
        let key = Objects::job_key(&job.id, object);
        let bytes = objects.get(&key).await?.ok_or_else(|| missing(&key))?;
        parts.insert(uri.clone(), bytes.to_vec());
    }
    Ok(Input { scene, parts })
}

/// Uploads every file the solve wrote (outputs and `solution.bin`) under the attempt's prefix.
async fn upload_outputs(
    objects: &Objects,
    id: &str,
    attempt: i32,
    dir: &Path,
) -> std::io::Result<()> {
    let mut entries = tokio::fs::read_dir(dir).await?;
    let mut files: Vec<PathBuf> = Vec::new();
    while let Some(entry) = entries.next_entry().await? {
        if entry.file_type().await?.is_file() {
            files.push(entry.path());
        }
    }
    for path in files {
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        let bytes = tokio::fs::read(&path).await?;
        objects
            .put(&Objects::output_key(id, attempt, name), bytes.into())
            .await?;
    }
    Ok(())
}
