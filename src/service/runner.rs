//! Runners: `workers` Tokio tasks that take queued jobs and solve each on a dedicated rayon pool,
//! so the Tokio threads that answer requests are never the ones solving.
//!
//! A solve runs under `catch_unwind` on a pool thread: a panic fails that job (state `failed`, the
//! panic's text as its error) and never the server. The pool's threads run at a lower scheduling
//! priority than the request threads, so polling stays responsive while a solve uses every core.

use super::error::{panic_message, ErrorBody};
use super::jobs::{Job, JobState, JobStatus, ProgressView};
use super::store::{FileStore, JobId, SOLUTION_FILE};
use super::AppState;
use crate::job::{run_job_keeping_solution, JobError, JobOutcome, ProbeSource};
use crate::scene::{load_scene, ExternalFiles, Scene, SceneError};
use crate::solver::StopReason;
use std::io;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use tokio::sync::oneshot;

/// Nice value of the solver threads (Linux): request handling wins the CPU when both want it.
#[cfg(target_os = "linux")]
const SOLVER_NICE: libc::c_int = 5;

/// Builds the solver pool: a thread per core (`RAYON_NUM_THREADS` when set), plus one per runner
/// (`workers`): a solve's own thread waits while the pool runs each shot, reporting its progress
/// (`solver::progress`), so the cores stay busy. Named threads, lower priority.
pub(crate) fn solver_pool(workers: usize) -> io::Result<rayon::ThreadPool> {
    let cores = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    rayon::ThreadPoolBuilder::new()
        .num_threads(cores + workers)
        .stack_size(crate::solver::SOLVER_STACK_BYTES)
        .thread_name(|i| format!("wavrad-solve-{i}"))
        .start_handler(|_| lower_thread_priority())
        .panic_handler(|payload| {
            // Solves catch their own panics; this only sees a panic outside one.
            tracing::error!(panic = %panic_message(payload.as_ref()), "solver pool task panicked");
        })
        .build()
        .map_err(io::Error::other)
}

fn lower_thread_priority() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: setpriority only reads its integer arguments. On Linux, PRIO_PROCESS with
        // who = 0 applies to the calling thread alone.
        let rc = unsafe { libc::setpriority(libc::PRIO_PROCESS as _, 0, SOLVER_NICE) };
        if rc != 0 {
            tracing::debug!("could not lower the solver thread's priority");
        }
    }
}

/// Starts `workers` runner tasks on the current Tokio runtime.
pub(crate) fn spawn_runners(state: &AppState, pool: Arc<rayon::ThreadPool>, workers: usize) {
    for index in 0..workers {
        let state = state.clone();
        let pool = pool.clone();
        tokio::spawn(async move { runner(state, pool, index).await });
    }
}

async fn runner(state: AppState, pool: Arc<rayon::ThreadPool>, index: usize) {
    loop {
        let job = state.jobs().next().await;
        if state.is_shutting_down() {
            state.jobs().requeue_front(job);
            return;
        }
        tracing::debug!(runner = index, job = %job.id, "runner took a job");
        let (done_tx, done_rx) = oneshot::channel::<()>();
        let task_state = state.clone();
        let task_job = job.clone();
        pool.spawn(move || {
            process(&task_state, &task_job);
            let _ = done_tx.send(());
        });
        if done_rx.await.is_err() {
            // The pool task ended without signalling: only possible if `process` itself panicked
            // outside its catch_unwind. Make sure the job does not stay `running`.
            let store = state.store().clone();
            let job = job.clone();
            let _ = tokio::task::spawn_blocking(move || {
                job.settle(&store, |s| {
                    if s.state.is_finished() {
                        return false;
                    }
                    s.state = JobState::Failed;
                    s.error = Some(ErrorBody {
                        code: "internal_error".into(),
                        message: "the solver task ended unexpectedly; the server log has details"
                            .into(),
                    });
                    true
                })
            })
            .await;
        }
    }
}

/// Runs one job to its end on the calling (pool) thread: queued -> running -> finished (or back
/// to queued when the server shuts down), with state.json written at each step.
fn process(state: &AppState, job: &Arc<Job>) {
    state.solve_started();
    process_inner(state, job);
    state.solve_ended();
}

fn process_inner(state: &AppState, job: &Arc<Job>) {
    let store = state.store();
    let start = job.update(|s| {
        if s.state != JobState::Queued {
            return false;
        }
        s.state = if job.cancel_requested() {
            JobState::Cancelled
        } else {
            s.attempts += 1;
            JobState::Running
        };
        true
    });
    if !start {
        return;
    }
    job.persist(store);
    if job.state() != JobState::Running {
        tracing::info!(job = %job.id, "cancelled before it started");
        return;
    }
    if state.is_shutting_down() {
        job.request_requeue();
    }
    let span = tracing::info_span!("job", id = %job.id);
    let _enter = span.enter();
    tracing::info!("solving");
    let max_triangles = state.config().max_triangles;
    let mut solution = None;
    let finished = guarded(|| solve(state, job, max_triangles, &mut solution));
    record_metrics(state, job, &finished);
    if let (Finished::Solved(outcome), Some(solution)) = (&finished, solution) {
        if outcome.stop_reason != StopReason::Cancelled {
            // Kept before the job shows `succeeded`, so a probe request right after finds it.
            state.keep_probe_source(job.id.as_str(), Arc::new(solution));
        }
    }
    if let Finished::Solved(outcome) = &finished {
        if outcome.stop_reason == StopReason::Cancelled && !job.cancel_requested() {
            // Stopped for a shutdown: back to the queue, to start over at the next start.
            job.settle(store, |s| {
                *s = JobStatus {
                    attempts: s.attempts,
                    ..JobStatus::queued()
                };
                true
            });
            tracing::info!("stopped for shutdown; queued again");
            return;
        }
    }
    job.settle(store, |s| {
        match finished {
            Finished::Solved(outcome) => {
                s.state = if outcome.stop_reason == StopReason::Cancelled {
                    JobState::Cancelled
                } else {
                    JobState::Succeeded
                };
                s.stop_reason = Some(outcome.stop_reason.as_str().to_string());
                if let Some(p) = final_progress(&outcome.result) {
                    s.progress = p;
                }
            }
            Finished::Error(body) => {
                s.state = JobState::Failed;
                s.error = Some(body);
            }
        }
        // An ended job has no time left (a solve cancelled within a shot keeps that shot's
        // progress, whose estimate no longer holds).
        s.progress.eta_seconds = None;
        true
    });
    tracing::info!(state = job.state().as_str(), "job finished");
    enforce_retention(state);
}

fn record_metrics(state: &AppState, job: &Job, finished: &Finished) {
    let Finished::Solved(outcome) = finished else {
        return;
    };
    let stats = outcome.result.get("stats");
    let number = |key: &str| stats.and_then(|s| s.get(key)).and_then(|v| v.as_u64());
    let progress = job.status().progress;
    let seconds = stats
        .and_then(|s| s.get("seconds"))
        .and_then(|v| v.as_f64())
        .unwrap_or(progress.seconds);
    state.metrics().record_solve(
        seconds,
        number("iterations").unwrap_or(progress.iterations),
        number("rays").unwrap_or(0),
        number("elements").unwrap_or(progress.elements),
    );
}

/// `--retain-jobs N`: deletes the oldest finished jobs, with their files, beyond N (blocking).
pub(crate) fn enforce_retention(state: &AppState) {
    let Some(keep) = state.config().retain_jobs else {
        return;
    };
    let finished = state.jobs().finished_oldest_first();
    let excess = finished.len().saturating_sub(keep);
    for job in finished.into_iter().take(excess) {
        match state.store().delete_job(&job.id) {
            Ok(()) => {
                state.jobs().forget(job.id.as_str());
                state.forget_probe_source(job.id.as_str());
                tracing::info!(job = %job.id, "deleted by --retain-jobs");
            }
            Err(e) => tracing::error!(job = %job.id, error = %e, "could not delete an old job"),
        }
    }
}

pub(crate) enum Finished {
    Solved(JobOutcome),
    Error(ErrorBody),
}

/// Runs a solve; its error or panic becomes the job's error (a panic never leaves this frame, so
/// it cannot reach rayon, which would abort the process).
pub(crate) fn guarded(solve: impl FnOnce() -> Result<JobOutcome, JobError>) -> Finished {
    match catch_unwind(AssertUnwindSafe(solve)) {
        Ok(Ok(outcome)) => Finished::Solved(outcome),
        Ok(Err(e)) => Finished::Error(job_error_body(&e)),
        Err(payload) => {
            let text = panic_message(payload.as_ref());
            tracing::error!(panic = %text, "the solver panicked");
            Finished::Error(ErrorBody {
                code: "solver_panic".into(),
                message: format!(
                    "the solver failed unexpectedly ({text}); this is a bug: please report it with the scene"
                ),
            })
        }
    }
}

/// Loads the job's scene from its directory (the upload is not kept in memory while queued) and
/// solves it, writing the outputs next to it; the solution goes to `solution` for probe requests.
fn solve(
    state: &AppState,
    job: &Job,
    max_triangles: usize,
    solution: &mut Option<ProbeSource>,
) -> Result<JobOutcome, JobError> {
    let store = state.store();
    let scene = load_job_scene(store, &job.id, max_triangles)?;
    let dir = store.job_dir(&job.id);
    let (outcome, kept) = run_job_keeping_solution(
        &scene,
        &job.params,
        None,
        &dir,
        job.cancel_flag(),
        &mut |p| job.set_progress(ProgressView::from(p)),
    )?;
    if let Some(kept) = &kept {
        // Before state.json says `succeeded`: every succeeded job has its solution on disk.
        kept.save(&store.file_path(&job.id, SOLUTION_FILE))?;
    }
    *solution = kept;
    Ok(outcome)
}

/// The stored scene of job `id` (with the files of a multipart upload).
fn load_job_scene(store: &FileStore, id: &JobId, max_triangles: usize) -> Result<Scene, JobError> {
    let path = store.scene_path(id)?;
    let bytes = std::fs::read(&path)?;
    let parts = store.read_parts(id)?;
    let external = if parts.is_empty() {
        ExternalFiles::Refuse
    } else {
        ExternalFiles::Named(parts)
    };
    Ok(load_scene(&bytes, &external, max_triangles)?)
}

/// The solution of succeeded job `id` from its `solution.bin` (blocking: loads the scene and
/// rebuilds its element roots). The error says why it cannot be had and what to do.
pub(crate) fn load_probe_source(
    store: &FileStore,
    id: &JobId,
    max_triangles: usize,
) -> Result<ProbeSource, String> {
    let path = store.file_path(id, SOLUTION_FILE);
    if !path.is_file() {
        return Err(format!(
            "job {id} has no saved solution ({SOLUTION_FILE}): it finished under an older version \
             of the server, which did not save solutions"
        ));
    }
    let scene = load_job_scene(store, id, max_triangles).map_err(|e| {
        tracing::warn!(job = %id, error = %e, "the stored scene of a succeeded job does not load");
        format!("job {id}'s stored scene cannot be loaded again: {e}")
    })?;
    ProbeSource::load(&path, &scene).map_err(|e| {
        tracing::warn!(job = %id, error = %e, "a saved solution cannot be used");
        format!("job {id}'s saved solution cannot be used: {e}")
    })
}

fn job_error_body(e: &JobError) -> ErrorBody {
    match e {
        JobError::Scene(scene) => scene_error_body(scene),
        JobError::Io(io) => {
            tracing::error!(error = %io, "job I/O failed");
            ErrorBody {
                code: "output_error".into(),
                message: format!("reading the scene or writing the outputs failed: {io}"),
            }
        }
    }
}

fn scene_error_body(e: &SceneError) -> ErrorBody {
    ErrorBody {
        code: e.code().into(),
        message: e.to_string(),
    }
}

/// The progress object of a finished solve, from result.json's `stats`.
pub(crate) fn final_progress(result: &serde_json::Value) -> Option<ProgressView> {
    let stats = result.get("stats")?;
    Some(ProgressView {
        unshot_ratio: stats.get("unshot_ratio")?.as_f64()?,
        iterations: stats.get("iterations")?.as_u64()?,
        elements: stats.get("elements")?.as_u64()?,
        links: stats.get("links")?.as_u64()?,
        seconds: stats.get("seconds")?.as_f64()?,
        shot_receivers_done: 0,
        shot_receivers: 0,
        eta_seconds: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panicking_solve_fails_its_job_and_not_the_pool() {
        let pool = solver_pool(1).unwrap();
        let finished = pool.install(|| guarded(|| panic!("boom in a shot")));
        let Finished::Error(body) = finished else {
            panic!("a panic is an error")
        };
        assert_eq!(body.code, "solver_panic");
        assert!(body.message.contains("boom in a shot"));
        // The pool still works.
        assert_eq!(pool.install(|| 2 + 2), 4);
    }

    #[test]
    fn scene_errors_keep_their_code() {
        let finished = guarded(|| Err(JobError::Scene(SceneError::Unsolvable("nothing".into()))));
        let Finished::Error(body) = finished else {
            panic!("an error")
        };
        assert_eq!(body.code, "unsolvable_scene");
    }
}
