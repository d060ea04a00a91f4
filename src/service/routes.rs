//! Request handlers of the v1 API and `/healthz`; the router that maps routes to them is
//! `crate::service::api_routes`, in one place.
//!
//! Here: the service's own pages (dashboard, `/healthz`, `/metrics`, the OpenAPI document) and a
//! job's life (`GET /v1/jobs`, `GET`/`DELETE /v1/jobs/{id}`, its event stream). Submission
//! (`POST /v1/jobs`) is `submit`; a finished job's outputs (result, probes, convergence, files)
//! are `outputs`; the 3-D view page and the static files pages load (three.js) are `pages`. Every handler is re-exported here under its old path.

pub(crate) mod outputs;
mod pages;
pub(crate) mod submit;

pub use outputs::{get_convergence, get_file, get_result, post_probes};
pub use pages::{asset, viewer};
pub use submit::create_job;

use super::error::ApiError;
use super::extract::ApiPath;
use super::jobs::{Job, JobState, JobView};
use super::AppState;
use axum::body::Body;
use axum::extract::State;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use std::sync::Arc;

/// The OpenAPI document, embedded at build time.
pub const OPENAPI_YAML: &str = include_str!("../../api/openapi.yaml");

/// The OpenAPI document as JSON (parsed once).
pub fn openapi_document() -> Result<&'static serde_json::Value, &'static str> {
    static DOC: std::sync::LazyLock<Result<serde_json::Value, String>> =
        std::sync::LazyLock::new(|| {
            serde_norway::from_str(OPENAPI_YAML).map_err(|e| e.to_string())
        });
    DOC.as_ref().map_err(String::as_str)
}

/// `GET /v1/openapi.json`: `api/openapi.yaml` as JSON.
pub async fn openapi() -> Result<Json<&'static serde_json::Value>, ApiError> {
    openapi_document()
        .map(Json)
        .map_err(|e| ApiError::internal("the embedded OpenAPI document does not parse", e))
}

/// `GET /metrics`: Prometheus text.
pub async fn metrics(State(state): State<AppState>) -> Response {
    let mut response = Response::new(Body::from(super::metrics::render(&state)));
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; version=0.0.4; charset=utf-8"),
    );
    response
}

/// Seconds between keep-alive comments on an event stream.
const SSE_KEEP_ALIVE: std::time::Duration = std::time::Duration::from_secs(15);

/// Where an event stream is.
enum EventPhase {
    /// Nothing sent yet: send the current progress.
    Start,
    /// Following the job's watch channel.
    Follow,
    /// The job ended: send `done`.
    Done,
    /// Closed.
    End,
}

/// `GET /v1/jobs/{id}/events`: server-sent events, `progress` (the progress object) at every
/// change of the job's state (after every shot, and every `solver::REPORT_INTERVAL` within a long
/// shot: at most about two a second then), then `done` (the job) when it ends. Reads the same watch channel as
/// polling. A client that connects after the end gets one `progress` and `done`. The stream also
/// ends when the server shuts down.
pub async fn job_events(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    let rx = job.subscribe();
    let shutdown = state.shutdown_signal();
    let stream = futures_util::stream::unfold(
        (EventPhase::Start, job, rx, shutdown),
        |(phase, job, mut rx, mut shutdown)| async move {
            let progress_event = |job: &Job| {
                Event::default()
                    .event("progress")
                    .json_data(job.view().progress)
            };
            match phase {
                EventPhase::Start => {
                    rx.borrow_and_update();
                    let next = if job.state().is_finished() {
                        EventPhase::Done
                    } else {
                        EventPhase::Follow
                    };
                    Some((progress_event(&job), (next, job, rx, shutdown)))
                }
                EventPhase::Follow => {
                    let changed = tokio::select! {
                        changed = rx.changed() => changed.is_ok(),
                        _ = shutdown.wait_for(|down| *down) => false,
                    };
                    if !changed {
                        return None;
                    }
                    let finished = rx.borrow_and_update().state.is_finished();
                    let next = if finished {
                        EventPhase::Done
                    } else {
                        EventPhase::Follow
                    };
                    Some((progress_event(&job), (next, job, rx, shutdown)))
                }
                EventPhase::Done => {
                    let done = Event::default().event("done").json_data(job.view());
                    Some((done, (EventPhase::End, job, rx, shutdown)))
                }
                EventPhase::End => None,
            }
        },
    );
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(SSE_KEEP_ALIVE))
        .into_response())
}

/// The dashboard page, embedded at build time.
const DASHBOARD_HTML: &str = include_str!("assets/dashboard.html");

/// `GET /`: the dashboard, a page with an upload form (`POST /v1/jobs`, multipart) and the list
/// of jobs (polling `GET /v1/jobs`): their scene names, progress, stop reasons (a time budget
/// apart from convergence), outputs (fetched with the API token when one is typed in, saved
/// through blob URLs) and a cancel button. Checked in headless Chromium by
/// `tests/real_clients/dashboard.rs`.
pub async fn dashboard() -> Response {
    let mut response = Response::new(Body::from(DASHBOARD_HTML));
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    // Only its own inline script and style, requests to this server, and images it fetched
    // itself (blob URLs: previews fetched with the token).
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
             connect-src 'self'; img-src 'self' blob:",
        ),
    );
    response
}

/// `GET /healthz`.
pub async fn healthz() -> Json<serde_json::Value> {
    Json(serde_json::json!({"status": "ok"}))
}

/// The answer of `GET /v1/jobs`.
#[derive(Debug, Serialize)]
pub struct JobList {
    pub jobs: Vec<JobView>,
}

/// `GET /v1/jobs`: every job, newest first.
pub async fn list_jobs(State(state): State<AppState>) -> Json<JobList> {
    Json(JobList {
        jobs: state.jobs().list().iter().map(|j| j.view()).collect(),
    })
}

fn find(state: &AppState, id: &str) -> Result<Arc<Job>, ApiError> {
    state
        .jobs()
        .get(id)
        .ok_or_else(|| ApiError::job_not_found(id))
}

/// `GET /v1/jobs/{id}`.
pub async fn get_job(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Json<JobView>, ApiError> {
    Ok(Json(find(&state, &id)?.view()))
}

/// `DELETE /v1/jobs/{id}`: cancels a queued or running job (202 with the job), deletes a finished
/// one with its files (204).
pub async fn delete_job(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    if !job.state().is_finished() {
        job.request_cancel();
        if state.jobs().dequeue(&job) {
            // Still waiting: no runner will see it, so it ends here.
            let store = state.store().clone();
            let settled = job.clone();
            tokio::task::spawn_blocking(move || {
                settled.settle(&store, |s| {
                    if s.state != JobState::Queued {
                        return false;
                    }
                    s.state = JobState::Cancelled;
                    true
                })
            })
            .await
            .map_err(|e| ApiError::internal("recording the cancellation failed", e))?;
        }
        tracing::info!(job = %job.id, "cancel requested");
        return Ok((StatusCode::ACCEPTED, Json(job.view())).into_response());
    }
    let store = state.store().clone();
    let doomed = job.id.clone();
    tokio::task::spawn_blocking(move || store.delete_job(&doomed))
        .await
        .map_err(|e| ApiError::internal("deleting the job failed", e))?
        .map_err(|e| ApiError::internal("deleting the job's files failed", e))?;
    state.jobs().forget(job.id.as_str());
    state.forget_probe_source(job.id.as_str());
    tracing::info!(job = %job.id, "job deleted");
    Ok(StatusCode::NO_CONTENT.into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_openapi_document_parses() {
        let doc = openapi_document().unwrap();
        assert_eq!(doc["openapi"], "3.1.0");
        assert!(doc["paths"]["/v1/jobs"]["post"]["responses"]["202"].is_object());
    }
}
