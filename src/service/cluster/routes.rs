//! The job routes of a cluster replica, answered from the `jobs` row and the object store so
//! every replica answers for every job: submission (the upload in the object store before the
//! 202, the idempotency key unique in the database, a key reused with another request 422
//! `idempotency_key_reused`), the job and the list, cancel and delete, the event stream (the row
//! polled), result, convergence, files and probes (the outputs of the attempt the row names).
//! [`handler`] gives the router the handler of a route; the paths, methods, validation and
//! answers are the local store's (`crate::service::routes`), whose checks are reused.

use super::db::{JobRow, NewJob};
use super::objects::Objects;
use super::worker::download_input;
use super::Cluster;
use crate::job::ProbeSource;
use crate::service::error::{clip, ApiError};
use crate::service::extract::ApiPath;
use crate::service::jobs::{JobState, JobView};
use crate::service::routes::outputs::{
    output_file_type, parse_convergence, read_probe_request, Convergence,
};
use crate::service::routes::submit::{self as local, BodyKind};
use crate::service::routes::JobList;
use crate::service::store::{JobId, SceneFormat, CONVERGENCE_FILE, RESULT_FILE, SOLUTION_FILE};
use crate::service::{AppState, RETRY_AFTER_SECONDS};
use axum::body::Bytes;
use axum::extract::{RawQuery, Request, State};
use axum::handler::Handler;
use axum::http::{header, HeaderName, HeaderValue, Method, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{delete, get, post, MethodRouter};
use axum::Json;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

/// How often an event stream reads its job's row.
const EVENT_POLL: Duration = Duration::from_millis(250);

/// The cluster handler of route (`path`, `method`) of `crate::service::api_routes`; None for the
/// routes that do not touch jobs (pages, health, metrics, the OpenAPI document).
pub(crate) fn handler(
    path: &str,
    method: &Method,
    max_body: usize,
) -> Option<MethodRouter<AppState>> {
    let limit = axum::extract::DefaultBodyLimit::max(max_body);
    Some(match (path, method.as_str()) {
        ("/v1/jobs", "GET") => get(list_jobs),
        ("/v1/jobs", "POST") => post(create_job.layer(limit)),
        ("/v1/jobs/{id}", "GET") => get(get_job),
        ("/v1/jobs/{id}", "DELETE") => delete(delete_job),
        ("/v1/jobs/{id}/events", "GET") => get(job_events),
        ("/v1/jobs/{id}/result", "GET") => get(get_result),
        ("/v1/jobs/{id}/probes", "POST") => post(post_probes.layer(limit)),
        ("/v1/jobs/{id}/convergence", "GET") => get(get_convergence),
        ("/v1/jobs/{id}/{file}", "GET") => get(get_file),
        _ => return None,
    })
}

fn cluster(state: &AppState) -> Result<&Arc<Cluster>, ApiError> {
    state
        .cluster()
        .ok_or_else(|| ApiError::internal("cluster route without cluster mode", "no cluster"))
}

/// 503 while the database cannot be reached (a replica reconnects at its next query).
fn unavailable(e: impl std::fmt::Display) -> ApiError {
    tracing::warn!(error = %e, "database unavailable");
    ApiError {
        retry_after: Some(1),
        ..ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "database_unavailable",
            "the job database cannot be reached right now; retry shortly",
        )
    }
}

fn storage_error(e: impl std::fmt::Display) -> ApiError {
    tracing::warn!(error = %e, "object store unavailable");
    ApiError {
        retry_after: Some(1),
        ..ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "object_store_unavailable",
            "the object store cannot be reached right now; retry shortly",
        )
    }
}

async fn find(cluster: &Cluster, id: &str) -> Result<JobRow, ApiError> {
    if JobId::parse(id).is_none() {
        return Err(ApiError::job_not_found(id));
    }
    cluster
        .db
        .get(id)
        .await
        .map_err(unavailable)?
        .ok_or_else(|| ApiError::job_not_found(id))
}

/// `GET /v1/jobs`.
pub async fn list_jobs(State(state): State<AppState>) -> Result<Json<JobList>, ApiError> {
    let rows = cluster(&state)?.db.list().await.map_err(unavailable)?;
    Ok(Json(JobList {
        jobs: rows.iter().map(JobRow::view).collect(),
    }))
}

/// `GET /v1/jobs/{id}`.
pub async fn get_job(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Json<JobView>, ApiError> {
    Ok(Json(find(cluster(&state)?, &id).await?.view()))
}

/// The answer for a key already used: the same job when the request is the same, else 422.
fn keyed_answer(row: &JobRow, key: &str, hash: &str) -> Result<Response, ApiError> {
    if row.request_hash.as_deref() != Some(hash) {
        return Err(ApiError::idempotency_key_reused(key, &row.id));
    }
    tracing::info!(job = %row.id, "idempotent retry: returning the existing job");
    let mut response = accepted(&row.view());
    response.headers_mut().insert(
        HeaderName::from_static("idempotent-replayed"),
        HeaderValue::from_static("true"),
    );
    Ok(response)
}

fn accepted(view: &JobView) -> Response {
    let mut response = (StatusCode::ACCEPTED, Json(view)).into_response();
    if let Ok(location) = HeaderValue::from_str(&view.links.self_) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    response
}

/// `POST /v1/jobs`: the local store's checks, then the upload to the object store, then the row.
pub async fn create_job(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    request: Request,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?.clone();
    let (mut params, name) = local::submit_query(query.as_deref())?;
    params.validate().map_err(ApiError::bad_parameters)?;
    if let Some(cap) = state.config().max_job_seconds {
        let cap = cap as f64;
        params.max_seconds = Some(params.max_seconds.map_or(cap, |s| s.min(cap)));
    }
    let key = local::idempotency_key(request.headers())?;
    let kind = local::check_content_type(request.headers())?;
    let max_body = state.config().max_body_bytes;
    if let Some(length) = local::content_length(request.headers()) {
        if length > max_body as u64 {
            return Err(local::too_large(max_body));
        }
    }
    let max_queued = state.config().max_queued;
    if key.is_none() && cluster.db.queued().await.map_err(unavailable)? >= max_queued as i64 {
        return Err(ApiError::queue_full(max_queued, RETRY_AFTER_SECONDS));
    }
    let _permit = state
        .upload_permits()
        .acquire()
        .await
        .map_err(|e| ApiError::internal("the upload limiter is closed", e))?;
    let (body, parts, file_name) = match kind {
        BodyKind::Scene => (
            local::read_body(request, max_body).await?,
            BTreeMap::new(),
            None,
        ),
        BodyKind::Multipart => local::read_multipart(request, max_body).await?,
    };
    let name = name.or_else(|| file_name.as_deref().and_then(local::name_of_file));
    // Hashing a large upload takes a while: off the async threads.
    let (hash, parts) = {
        let (hashed, fingerprinted) = (body.clone(), params.clone());
        tokio::task::spawn_blocking(move || {
            (
                local::request_fingerprint(&fingerprinted, &hashed, &parts),
                parts,
            )
        })
        .await
        .map_err(|e| ApiError::internal("hashing the request failed", e))?
    };
    if let Some(key) = &key {
        if let Some(row) = cluster.db.by_key(key).await.map_err(unavailable)? {
            return keyed_answer(&row, key, &hash);
        }
        if cluster.db.queued().await.map_err(unavailable)? >= max_queued as i64 {
            return Err(ApiError::queue_full(max_queued, RETRY_AFTER_SECONDS));
        }
    }

    let parts = local::check_scene(&state, &body, parts, params.order).await?;

    let created = SystemTime::now();
    let id = JobId::generate(created);
    let input_name = SceneFormat::sniff(&body).file_name();
    cluster
        .objects
        .put(&Objects::job_key(id.as_str(), input_name), body)
        .await
        .map_err(storage_error)?;
    let mut part_names = BTreeMap::new();
    for (n, (uri, bytes)) in parts.into_iter().enumerate() {
        let object = format!("part-{n}");
        cluster
            .objects
            .put(&Objects::job_key(id.as_str(), &object), Bytes::from(bytes))
            .await
            .map_err(storage_error)?;
        part_names.insert(uri, object);
    }
    let new = NewJob {
        id: id.as_str(),
        name: name.as_deref(),
        created,
        params: &params,
        input_name,
        parts: &part_names,
        idempotency_key: key.as_deref(),
        request_hash: &hash,
    };
    let inserted = cluster.db.insert(&new).await;
    match inserted {
        Ok(Some(row)) => {
            tracing::info!(job = %row.id, "job accepted");
            Ok(accepted(&row.view()))
        }
        Ok(None) => {
            // Another replica stored the same key meanwhile: its job is the answer.
            let _ = cluster.objects.delete_job(id.as_str()).await;
            let key = key.unwrap_or_default();
            match cluster.db.by_key(&key).await.map_err(unavailable)? {
                Some(row) => keyed_answer(&row, &key, &hash),
                None => Err(unavailable("the job of an idempotency key vanished")),
            }
        }
        Err(e) => {
            let _ = cluster.objects.delete_job(id.as_str()).await;
            Err(unavailable(e))
        }
    }
}

/// `DELETE /v1/jobs/{id}`: a queued job ends `cancelled`, a running one gets a cancel request
/// (its replica's heartbeat stops the solve), both 202; a finished one is deleted with its
/// objects (204).
pub async fn delete_job(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?;
    let row = find(cluster, &id).await?;
    if !row.state.is_finished() {
        if let Some(row) = cluster.db.cancel(&row.id).await.map_err(unavailable)? {
            tracing::info!(job = %row.id, "cancel requested");
            return Ok((StatusCode::ACCEPTED, Json(row.view())).into_response());
        }
        // It finished meanwhile: answer with what it is now.
        let row = find(cluster, &id).await?;
        return Ok((StatusCode::ACCEPTED, Json(row.view())).into_response());
    }
    if cluster
        .db
        .delete_finished(&row.id)
        .await
        .map_err(unavailable)?
    {
        cluster
            .objects
            .delete_job(&row.id)
            .await
            .map_err(storage_error)?;
        state.forget_probe_source(&row.id);
        tracing::info!(job = %row.id, "job deleted");
    }
    Ok(StatusCode::NO_CONTENT.into_response())
}

/// `GET /v1/jobs/{id}/events`: `progress` at every change of the row (read every
/// [`EVENT_POLL`]), then `done` with the job.
pub async fn job_events(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?.clone();
    let row = find(&cluster, &id).await?;
    let shutdown = state.shutdown_signal();
    // (last row sent, finished and done sent)
    let stream = futures_util::stream::unfold(
        (Some(row), None::<JobView>, false, shutdown),
        move |(first, last, ended, mut shutdown)| {
            let cluster = cluster.clone();
            let id = id.clone();
            async move {
                if ended {
                    return None;
                }
                if let Some(row) = first {
                    let view = row.view();
                    let event = Event::default().event("progress").json_data(view.progress);
                    return Some((event, (None, Some(view), false, shutdown)));
                }
                let last = last?;
                if last.state.is_finished() {
                    let event = Event::default().event("done").json_data(&last);
                    return Some((event, (None, None, true, shutdown)));
                }
                loop {
                    tokio::select! {
                        () = tokio::time::sleep(EVENT_POLL) => {}
                        _ = shutdown.wait_for(|down| *down) => return None,
                    }
                    let Ok(Some(row)) = cluster.db.get(&id).await else {
                        continue;
                    };
                    let view = row.view();
                    if view.progress != last.progress || view.state != last.state {
                        let event = Event::default().event("progress").json_data(view.progress);
                        return Some((event, (None, Some(view), false, shutdown)));
                    }
                }
            }
        },
    );
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response())
}

fn require_succeeded(row: &JobRow, what: &str) -> Result<(), ApiError> {
    if row.state == JobState::Succeeded {
        return Ok(());
    }
    Err(ApiError::conflict(
        "job_not_succeeded",
        format!("job {} is {}; {what}", row.id, row.state.as_str()),
    ))
}

/// An output of the attempt the row names; 404 when there is none.
async fn read_output(cluster: &Cluster, row: &JobRow, name: &str) -> Result<Bytes, ApiError> {
    let not_found = || {
        let hint = if row.state.is_finished() {
            format!("this {} job did not write it", row.state.as_str())
        } else {
            format!(
                "the job is {}; outputs appear when it ends",
                row.state.as_str()
            )
        };
        ApiError::file_not_found(format!("job {} has no {name}: {hint}", row.id))
    };
    let Some(attempt) = row.result_attempt else {
        return Err(not_found());
    };
    cluster
        .objects
        .get(&Objects::output_key(&row.id, attempt, name))
        .await
        .map_err(storage_error)?
        .ok_or_else(not_found)
}

fn file_response(bytes: Bytes, content_type: &'static str) -> Response {
    let mut response = Response::new(axum::body::Body::from(bytes));
    response
        .headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    response
}

/// `GET /v1/jobs/{id}/result`.
pub async fn get_result(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?;
    let row = find(cluster, &id).await?;
    require_succeeded(
        &row,
        &format!(
            "its result exists once it has succeeded (poll GET /v1/jobs/{})",
            row.id
        ),
    )?;
    let bytes = read_output(cluster, &row, RESULT_FILE).await?;
    Ok(file_response(bytes, "application/json"))
}

/// `GET /v1/jobs/{id}/convergence`.
pub async fn get_convergence(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
) -> Result<Json<Convergence>, ApiError> {
    let cluster = cluster(&state)?;
    let row = find(cluster, &id).await?;
    if !row.state.is_finished() {
        return Err(ApiError::conflict(
            "job_not_finished",
            format!(
                "job {} is {}; its convergence table is written when it ends (the job's progress \
                 object shows the latest shot)",
                row.id,
                row.state.as_str()
            ),
        ));
    }
    let bytes = read_output(cluster, &row, CONVERGENCE_FILE).await?;
    let rows = parse_convergence(&String::from_utf8_lossy(&bytes))
        .map_err(|e| ApiError::internal("convergence.csv is malformed", e))?;
    Ok(Json(Convergence { rows }))
}

/// `GET /v1/jobs/{id}/{file}`.
pub async fn get_file(
    State(state): State<AppState>,
    ApiPath((id, name)): ApiPath<(String, String)>,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?;
    let row = find(cluster, &id).await?;
    let Some(content_type) = output_file_type(&name) else {
        return Err(ApiError::file_not_found(format!(
            "a job has no '{}'; its files are result, convergence, lightmap.exr, \
             lightmap-{{n}}.exr (n >= 1), preview.png, atlas.png and scene.glb",
            clip(&name, 100)
        )));
    };
    let bytes = read_output(cluster, &row, &name).await?;
    Ok(file_response(bytes, content_type))
}

/// `POST /v1/jobs/{id}/probes`: evaluated on the solution in this replica's memory, else the
/// one the object store holds for the job's attempt (loaded one at a time).
pub async fn post_probes(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
    request: Request,
) -> Result<Response, ApiError> {
    let cluster = cluster(&state)?.clone();
    let row = find(&cluster, &id).await?;
    require_succeeded(&row, "probes are evaluated once it has succeeded")?;
    let (_permit, probes) = read_probe_request(&state, request).await?;
    let source = match state.probe_source(&row.id) {
        Some(source) => source,
        None => {
            let _loading = state.probe_loads().lock().await;
            match state.probe_source(&row.id) {
                Some(source) => source,
                None => {
                    let source = Arc::new(load_probe_source(&state, &cluster, &row).await?);
                    state.keep_probe_source(&row.id, source.clone());
                    source
                }
            }
        }
    };
    let values = tokio::task::spawn_blocking(move || source.evaluate(&probes))
        .await
        .map_err(|e| ApiError::internal("evaluating the probes failed", e))?;
    Ok(Json(values).into_response())
}

async fn load_probe_source(
    state: &AppState,
    cluster: &Cluster,
    row: &JobRow,
) -> Result<ProbeSource, ApiError> {
    let unavailable_solution = |reason: String| {
        ApiError::conflict(
            "solution_unavailable",
            format!(
                "{reason}; submit the scene again with the same parameters (same input, same \
                 result) and ask its new job"
            ),
        )
    };
    let solution = read_output(cluster, row, SOLUTION_FILE)
        .await
        .map_err(|_| unavailable_solution(format!("job {} has no saved solution", row.id)))?;
    let input = download_input(&cluster.objects, row)
        .await
        .map_err(storage_error)?;
    let dir = state.config().data_dir.join("cluster-work");
    let path = dir.join(format!("probe-{}-{}.bin", row.id, std::process::id()));
    let max_triangles = state.config().max_triangles;
    let id = row.id.clone();
    tokio::task::spawn_blocking(move || {
        std::fs::create_dir_all(&dir).map_err(|e| format!("scratch directory: {e}"))?;
        std::fs::write(&path, &solution).map_err(|e| format!("scratch file: {e}"))?;
        let scene = input
            .scene(max_triangles)
            .map_err(|e| format!("job {id}'s stored scene cannot be loaded again: {e}"));
        let loaded = scene.and_then(|scene| {
            ProbeSource::load(&path, &scene)
                .map_err(|e| format!("job {id}'s saved solution cannot be used: {e}"))
        });
        let _ = std::fs::remove_file(&path);
        loaded
    })
    .await
    .map_err(|e| ApiError::internal("loading the saved solution failed", e))?
    .map_err(unavailable_solution)
}
