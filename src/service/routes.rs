//! Request handlers of the v1 API and `/healthz`.

use super::error::{clip, panic_message, ApiError};
use super::extract::{ApiPath, ApiQuery};
use super::jobs::{Job, JobState, JobStatus, JobView};
use super::runner::load_probe_source;
use super::store::{CONVERGENCE_FILE, RESULT_FILE};
use super::{AppState, RETRY_AFTER_SECONDS};
use crate::job::ProbeSource;
use crate::job::{estimated_memory_bytes, JobParams};
use crate::output::page_file_name;
use crate::output::probes::parse_probes;
use crate::pipeline::check_solvable;
use crate::scene::{load_scene, ExternalFiles};
use axum::body::{Body, Bytes};
use axum::extract::multipart::MultipartError;
use axum::extract::{FromRequest, Multipart, Request, State};
use axum::http::{header, HeaderMap, HeaderName, HeaderValue, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::time::SystemTime;

/// Content types accepted for a scene upload: GLB (two names), then glTF JSON (two names).
const ACCEPTED_SCENE_TYPES: [&str; 4] = [
    "model/gltf-binary",
    "application/octet-stream",
    "model/gltf+json",
    "application/json",
];

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
/// change of the job's state, then `done` (the job) when it ends. Reads the same watch channel as
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

/// `GET /`: the dashboard, a page that lists the jobs (polling `GET /v1/jobs`, with the API token
/// when one is typed in), their progress, links to their outputs and a cancel button.
pub async fn dashboard() -> Response {
    let mut response = Response::new(Body::from(DASHBOARD_HTML));
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    // Only its own inline script and style, and requests to this server.
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
             connect-src 'self'; img-src 'self'",
        ),
    );
    response
}

/// `GET /healthz`.
pub async fn healthz() -> Json<serde_json::Value> {
    Json(serde_json::json!({"status": "ok"}))
}

/// `POST /v1/jobs`: validate parameters and scene, store the job, queue it; 202 with the job.
/// With an `Idempotency-Key` a retried POST gets the job the first one created.
pub async fn create_job(
    State(state): State<AppState>,
    ApiQuery(mut params): ApiQuery<JobParams>,
    request: Request,
) -> Result<Response, ApiError> {
    params.validate().map_err(ApiError::bad_parameters)?;
    if let Some(cap) = state.config().max_job_seconds {
        let cap = cap as f64;
        params.max_seconds = Some(params.max_seconds.map_or(cap, |s| s.min(cap)));
    }
    let key = idempotency_key(request.headers())?;
    if let Some(job) = key.as_deref().and_then(|k| state.jobs().by_key(k)) {
        return Ok(replay(&job));
    }
    let kind = check_content_type(request.headers())?;
    let max_body = state.config().max_body_bytes;
    if let Some(length) = content_length(request.headers()) {
        if length > max_body as u64 {
            return Err(too_large(max_body));
        }
    }
    // Refuse before receiving the body when the queue is already full (checked again on enqueue).
    if !state.jobs().has_room() {
        return Err(queue_full(&state));
    }
    let _permit = state
        .upload_permits()
        .acquire()
        .await
        .map_err(|e| ApiError::internal("the upload limiter is closed", e))?;
    let (body, parts) = match kind {
        BodyKind::Scene => (read_body(request, max_body).await?, BTreeMap::new()),
        BodyKind::Multipart => read_multipart(request, max_body).await?,
    };

    let max_triangles = state.config().max_triangles;
    let max_memory = state.config().max_memory_bytes;
    let order = params.order;
    let checked = body.clone();
    let parts = tokio::task::spawn_blocking(move || {
        let external = if parts.is_empty() {
            ExternalFiles::Refuse
        } else {
            ExternalFiles::Named(parts.into_iter().collect())
        };
        let scene = load_scene(&checked, &external, max_triangles)?;
        check_solvable(&scene)?;
        check_memory(scene.triangles.len(), order, max_memory)?;
        Ok::<_, ApiError>(match external {
            ExternalFiles::Named(parts) => parts.into_iter().collect(),
            _ => BTreeMap::new(),
        })
    })
    .await
    .map_err(|e| ApiError::internal("the scene check failed", e))??;

    // Keyed submissions are stored one at a time, so two concurrent retries make one job.
    let _keyed = match &key {
        Some(_) => Some(state.keyed_submissions().lock().await),
        None => None,
    };
    if let Some(job) = key.as_deref().and_then(|k| state.jobs().by_key(k)) {
        return Ok(replay(&job));
    }
    let created = SystemTime::now();
    let store = state.store().clone();
    let id = tokio::task::spawn_blocking(move || store.create_job_dir(created))
        .await
        .map_err(|e| ApiError::internal("storing the job failed", e))?
        .map_err(|e| ApiError::internal("storing the job failed", e))?;
    let job = Arc::new(Job::restore(
        id,
        created,
        state.jobs().next_seq(),
        params,
        JobStatus::queued(),
        key,
    ));
    let store = state.store().clone();
    let stored = job.clone();
    tokio::task::spawn_blocking(move || {
        let written =
            store.write_new_job(&stored.id, &body, &parts, &stored.params, &stored.record());
        if written.is_err() {
            store.discard(&stored.id);
        }
        written
    })
    .await
    .map_err(|e| ApiError::internal("storing the job failed", e))?
    .map_err(|e| ApiError::internal("storing the job failed", e))?;

    if let Err(job) = state.jobs().enqueue(job.clone()) {
        let store = state.store().clone();
        let _ = tokio::task::spawn_blocking(move || store.discard(&job.id)).await;
        return Err(queue_full(&state));
    }
    tracing::info!(job = %job.id, "job accepted");
    Ok(accepted(&job))
}

/// Longest `Idempotency-Key` accepted.
const MAX_IDEMPOTENCY_KEY: usize = 255;

/// The `Idempotency-Key` header: 1 to 255 printable ASCII characters.
fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let Some(value) = headers.get("idempotency-key") else {
        return Ok(None);
    };
    let text = value.to_str().ok().map(str::trim).unwrap_or("");
    let valid = !text.is_empty()
        && text.len() <= MAX_IDEMPOTENCY_KEY
        && text.bytes().all(|c| c.is_ascii_graphic() || c == b' ');
    if !valid {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "bad_idempotency_key",
            format!(
                "Idempotency-Key must be 1 to {MAX_IDEMPOTENCY_KEY} printable ASCII characters \
                 (a UUID is a good choice)"
            ),
        ));
    }
    Ok(Some(text.to_string()))
}

/// 202 with the job and its `Location`.
fn accepted(job: &Job) -> Response {
    let view = job.view();
    let mut response = (StatusCode::ACCEPTED, Json(&view)).into_response();
    if let Ok(location) = HeaderValue::from_str(&view.links.self_) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    response
}

/// The answer to a retried keyed POST: the job it created, as the first answer had it.
fn replay(job: &Job) -> Response {
    tracing::info!(job = %job.id, "idempotent retry: returning the existing job");
    let mut response = accepted(job);
    response.headers_mut().insert(
        HeaderName::from_static("idempotent-replayed"),
        HeaderValue::from_static("true"),
    );
    response
}

async fn read_body(request: Request, max_body: usize) -> Result<Bytes, ApiError> {
    match Bytes::from_request(request, &()).await {
        Ok(body) => Ok(body),
        Err(rejection) if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE => {
            Err(too_large(max_body))
        }
        Err(rejection) => Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "body_unreadable",
            format!(
                "the request body could not be read: {}",
                rejection.body_text()
            ),
        )),
    }
}

/// Part of a multipart upload that holds the scene.
const SCENE_PART: &str = "scene";

/// A `multipart/form-data` upload: the part `scene`, and the files it references, each a part
/// named by its URI (the part's name, else its file name).
async fn read_multipart(
    request: Request,
    max_body: usize,
) -> Result<(Bytes, BTreeMap<String, Vec<u8>>), ApiError> {
    let bad = |message: String| ApiError::new(StatusCode::BAD_REQUEST, "bad_multipart", message);
    let multipart_error = |e: MultipartError| {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            too_large(max_body)
        } else {
            bad(format!(
                "the multipart body could not be read: {}",
                e.body_text()
            ))
        }
    };
    let mut multipart = Multipart::from_request(request, &()).await.map_err(|e| {
        bad(format!(
            "not a readable multipart/form-data body: {}",
            e.body_text()
        ))
    })?;
    let mut scene = None;
    let mut parts = BTreeMap::new();
    while let Some(field) = multipart.next_field().await.map_err(multipart_error)? {
        let name =
            field
                .name()
                .filter(|n| !n.is_empty())
                .or(field.file_name())
                .map(str::to_string)
                .ok_or_else(|| {
                    bad("every part needs a name: 'scene' for the scene, the URI it uses for a file"
                    .into())
                })?;
        let bytes = field.bytes().await.map_err(multipart_error)?;
        if name == SCENE_PART {
            if scene.replace(bytes).is_some() {
                return Err(bad("the upload has two parts named 'scene'".into()));
            }
        } else if parts.insert(name.clone(), bytes.to_vec()).is_some() {
            return Err(bad(format!(
                "the upload has two parts named '{}'",
                clip(&name, 100)
            )));
        }
    }
    let scene = scene.ok_or_else(|| {
        bad(
            "the multipart upload has no part named 'scene' (the .gltf or .glb); add it, and one \
             part per file it references, named by its URI"
                .into(),
        )
    })?;
    Ok((scene, parts))
}

/// 422 when the solve's estimated memory exceeds `--max-memory-bytes`.
fn check_memory(triangles: usize, order: usize, max_memory: u64) -> Result<(), ApiError> {
    let estimate = estimated_memory_bytes(triangles, order);
    if estimate <= max_memory {
        return Ok(());
    }
    Err(ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "memory_limit",
        format!(
            "solving {triangles} triangles at order {order} needs an estimated {estimate} bytes, \
             more than this server allows per job ({max_memory} bytes, --max-memory-bytes); use a \
             lower order, simplify the scene, or ask the operator to raise the limit"
        ),
    ))
}

/// What a POST body holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum BodyKind {
    /// The scene itself (GLB or glTF JSON).
    Scene,
    /// `multipart/form-data`: the scene and the files it references.
    Multipart,
}

fn check_content_type(headers: &HeaderMap) -> Result<BodyKind, ApiError> {
    let given = headers
        .get(header::CONTENT_TYPE)
        .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
    let essence = given
        .as_deref()
        .and_then(|v| v.split(';').next())
        .map(|v| v.trim().to_ascii_lowercase());
    if let Some(essence) = &essence {
        if ACCEPTED_SCENE_TYPES.contains(&essence.as_str()) {
            return Ok(BodyKind::Scene);
        }
        if essence == "multipart/form-data" {
            return Ok(BodyKind::Multipart);
        }
    }
    let what = match &given {
        Some(v) => format!("content type '{}' is not accepted", clip(v, 100)),
        None => "the request has no Content-Type".to_string(),
    };
    Err(ApiError::new(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "unsupported_media_type",
        format!(
            "{what}; send the scene as model/gltf-binary (a GLB; also application/octet-stream) or \
             model/gltf+json (a self-contained glTF with data URIs; also application/json), or \
             multipart/form-data with a part 'scene' and one part per file it references"
        ),
    ))
}

fn content_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)?
        .to_str()
        .ok()?
        .trim()
        .parse()
        .ok()
}

fn too_large(max_body: usize) -> ApiError {
    ApiError::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        "payload_too_large",
        format!(
            "the scene is larger than this server accepts ({max_body} bytes, --max-body-bytes); \
             simplify it or ask the operator to raise the limit"
        ),
    )
}

fn queue_full(state: &AppState) -> ApiError {
    ApiError::queue_full(state.jobs().max_queued(), RETRY_AFTER_SECONDS)
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

/// 409 `job_not_succeeded` unless the job has succeeded; `what` says what waits for that.
fn require_succeeded(job: &Job, what: &str) -> Result<(), ApiError> {
    let job_state = job.state();
    if job_state == JobState::Succeeded {
        return Ok(());
    }
    Err(ApiError::conflict(
        "job_not_succeeded",
        format!("job {} is {}; {what}", job.id, job_state.as_str()),
    ))
}

/// `GET /v1/jobs/{id}/result`: result.json of a succeeded job.
pub async fn get_result(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    require_succeeded(
        &job,
        &format!(
            "its result exists once it has succeeded (poll GET /v1/jobs/{})",
            job.id
        ),
    )?;
    let bytes = read_job_file(&state, &job, RESULT_FILE).await?;
    Ok(file_response(bytes, "application/json"))
}

/// `POST /v1/jobs/{id}/probes`: the probe points file in the body; the answer is
/// `probe_values.json` (CONTRACT), evaluated on the job's solution: in memory for the most recent
/// succeeded jobs (`--probe-cache-jobs`), else loaded from the job's `solution.bin`. A job without
/// a usable one (finished by an older version, or damaged) is 409 `solution_unavailable`.
pub async fn post_probes(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
    request: Request,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    require_succeeded(&job, "probes are evaluated once it has succeeded")?;
    let max_body = state.config().max_body_bytes;
    // Bodies are read and evaluated under the same bound as scene uploads.
    let _permit = state
        .upload_permits()
        .acquire()
        .await
        .map_err(|e| ApiError::internal("the upload limiter is closed", e))?;
    let body = read_body(request, max_body).await?;
    let probes = parse_probes(&body).map_err(|e| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            "bad_probes",
            format!("{e} (body: a probe points file, [{{\"p\":[x,y,z],\"n\":[nx,ny,nz]}}, ...])"),
        )
    })?;
    let max_probes = state.config().max_probes;
    if probes.len() > max_probes {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "too_many_probes",
            format!(
                "{} probe points, more than this server evaluates in one request ({max_probes}, \
                 --max-probes); split them over several requests",
                probes.len()
            ),
        ));
    }
    let source = probe_source_of(&state, &job).await?;
    let values = tokio::task::spawn_blocking(move || source.evaluate(&probes))
        .await
        .map_err(|e| ApiError::internal("evaluating the probes failed", e))?;
    Ok(Json(values).into_response())
}

/// The solution of succeeded job `job` for probes: from memory, else loaded from its saved
/// solution on the blocking pool (one load at a time) and kept in memory.
async fn probe_source_of(state: &AppState, job: &Arc<Job>) -> Result<Arc<ProbeSource>, ApiError> {
    if let Some(source) = state.probe_source(job.id.as_str()) {
        return Ok(source);
    }
    let _loading = state.probe_loads().lock().await;
    // Another request may have loaded it while this one waited.
    if let Some(source) = state.probe_source(job.id.as_str()) {
        return Ok(source);
    }
    let store = state.store().clone();
    let id = job.id.clone();
    let max_triangles = state.config().max_triangles;
    let loaded = tokio::task::spawn_blocking(move || {
        catch_unwind(AssertUnwindSafe(|| {
            load_probe_source(&store, &id, max_triangles)
        }))
    })
    .await
    .map_err(|e| ApiError::internal("loading the saved solution failed", e))?;
    match loaded {
        Ok(Ok(source)) => {
            let source = Arc::new(source);
            // Not for a job deleted meanwhile.
            if state.jobs().get(job.id.as_str()).is_some() {
                state.keep_probe_source(job.id.as_str(), source.clone());
            }
            tracing::info!(job = %job.id, "saved solution loaded for probes");
            Ok(source)
        }
        Ok(Err(reason)) => Err(ApiError::conflict(
            "solution_unavailable",
            format!(
                "{reason}; submit the scene again with the same parameters (same input, same \
                 result) and ask its new job"
            ),
        )),
        Err(payload) => Err(ApiError::internal(
            "loading the saved solution panicked",
            panic_message(payload.as_ref()),
        )),
    }
}

/// One row of `GET /v1/jobs/{id}/convergence`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ConvergenceRow {
    pub seconds: f64,
    pub unshot_ratio: f64,
    pub elements: u64,
    pub links: u64,
}

/// The answer of `GET /v1/jobs/{id}/convergence`.
#[derive(Debug, Serialize)]
pub struct Convergence {
    pub rows: Vec<ConvergenceRow>,
}

/// `GET /v1/jobs/{id}/convergence`: convergence.csv as JSON rows.
pub async fn get_convergence(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Json<Convergence>, ApiError> {
    let job = find(&state, &id)?;
    let job_state = job.state();
    if !job_state.is_finished() {
        return Err(ApiError::conflict(
            "job_not_finished",
            format!(
                "job {} is {}; its convergence table is written when it ends (the job's progress \
                 object shows the latest shot)",
                job.id,
                job_state.as_str()
            ),
        ));
    }
    let bytes = read_job_file(&state, &job, CONVERGENCE_FILE).await?;
    let rows = parse_convergence(&String::from_utf8_lossy(&bytes))
        .map_err(|e| ApiError::internal("convergence.csv is malformed", e))?;
    Ok(Json(Convergence { rows }))
}

/// Parses `seconds,unshot_ratio,elements,links` rows after the header line.
pub fn parse_convergence(text: &str) -> Result<Vec<ConvergenceRow>, String> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |what: &str| format!("line {}: {what}: '{}'", n + 1, clip(line, 100));
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let [seconds, unshot_ratio, elements, links] = fields[..] else {
            return Err(bad("expected 4 fields"));
        };
        rows.push(ConvergenceRow {
            seconds: seconds.parse().map_err(|_| bad("bad seconds"))?,
            unshot_ratio: unshot_ratio.parse().map_err(|_| bad("bad unshot_ratio"))?,
            elements: elements.parse().map_err(|_| bad("bad elements"))?,
            links: links.parse().map_err(|_| bad("bad links"))?,
        });
    }
    Ok(rows)
}

/// The downloadable output files of a job (besides result.json) and their content types.
fn output_file_type(name: &str) -> Option<&'static str> {
    match name {
        "preview.png" => return Some("image/png"),
        "scene.glb" => return Some("model/gltf-binary"),
        _ => {}
    }
    let page: usize = if name == "lightmap.exr" {
        0
    } else {
        name.strip_prefix("lightmap-")?
            .strip_suffix(".exr")?
            .parse()
            .ok()?
    };
    // Only the canonical spelling (`lightmap-1.exr`, not `lightmap-01.exr` or `lightmap-0.exr`).
    (page_file_name(page) == name).then_some("image/x-exr")
}

/// `GET /v1/jobs/{id}/{file}`: `lightmap.exr`, `lightmap-{n}.exr`, `preview.png`, `scene.glb`.
pub async fn get_file(
    State(state): State<AppState>,
    ApiPath((id, name)): ApiPath<(String, String)>,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    let Some(content_type) = output_file_type(&name) else {
        return Err(ApiError::file_not_found(format!(
            "a job has no '{}'; its files are result, convergence, lightmap.exr, \
             lightmap-{{n}}.exr (n >= 1), preview.png and scene.glb",
            clip(&name, 100)
        )));
    };
    let bytes = read_job_file(&state, &job, &name).await?;
    Ok(file_response(bytes, content_type))
}

/// Reads an output file of `job`; 404 when it does not exist.
async fn read_job_file(state: &AppState, job: &Job, name: &str) -> Result<Vec<u8>, ApiError> {
    let path = state.store().file_path(&job.id, name);
    match tokio::fs::read(&path).await {
        Ok(bytes) => Ok(bytes),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let state_now = job.state();
            let hint = if state_now.is_finished() {
                format!("this {} job did not write it", state_now.as_str())
            } else {
                format!(
                    "the job is {}; outputs appear when it ends",
                    state_now.as_str()
                )
            };
            Err(ApiError::file_not_found(format!(
                "job {} has no {name}: {hint}",
                job.id
            )))
        }
        Err(e) => Err(ApiError::internal("reading a job file failed", e)),
    }
}

fn file_response(bytes: Vec<u8>, content_type: &'static str) -> Response {
    let mut response = Response::new(Body::from(bytes));
    response
        .headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    response
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

    #[test]
    fn output_file_names() {
        assert_eq!(output_file_type("lightmap.exr"), Some("image/x-exr"));
        assert_eq!(output_file_type("lightmap-3.exr"), Some("image/x-exr"));
        assert_eq!(output_file_type("lightmap-0.exr"), None);
        assert_eq!(output_file_type("lightmap-03.exr"), None);
        assert_eq!(output_file_type("lightmap-+3.exr"), None);
        assert_eq!(output_file_type("lightmap-.exr"), None);
        assert_eq!(output_file_type("state.json"), None);
        assert_eq!(output_file_type("../x"), None);
        assert_eq!(output_file_type("preview.png"), Some("image/png"));
    }

    #[test]
    fn convergence_rows() {
        let rows = parse_convergence(
            "seconds,unshot_ratio,elements,links\n0.001000,5.0e-1,12,30\n0.002,1e-3,14,44\n",
        )
        .unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].links, 44);
        assert!(parse_convergence("h\n1,2,3\n").is_err());
    }

    #[test]
    fn content_types() {
        let mut h = HeaderMap::new();
        assert!(check_content_type(&h).is_err());
        h.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("Model/glTF-Binary; x=1"),
        );
        assert!(check_content_type(&h).is_ok());
        h.insert(header::CONTENT_TYPE, HeaderValue::from_static("text/plain"));
        let e = check_content_type(&h).unwrap_err();
        assert_eq!(e.status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
        assert!(e.message.contains("model/gltf-binary"));
    }
}
