//! `POST /v1/jobs`: a job's submission. Validates the parameters (the job's, and its scene's
//! `name`: `submit_query`, `job_name`), the `Idempotency-Key`, the content type and length, reads the body (a scene, or multipart with the scene and its external
//! files) under the upload limit, loads and checks the scene, estimates the memory, stores the
//! job and queues it. Invariant: a job is on disk before its 202 is sent, and a submission that
//! is refused leaves nothing behind (a job that does not fit the queue is discarded).

use crate::job::{estimated_memory_bytes, JobParams};
use crate::pipeline::check_solvable;
use crate::scene::{load_scene, ExternalFiles};
use crate::service::error::{clip, ApiError};
use crate::service::jobs::{Job, JobStatus};
use crate::service::{AppState, RETRY_AFTER_SECONDS};
use axum::body::Bytes;
use axum::extract::multipart::MultipartError;
use axum::extract::{FromRequest, Multipart, RawQuery, Request, State};
use axum::http::{header, HeaderMap, HeaderName, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::SystemTime;

/// Content types accepted for a scene upload: GLB (two names), then glTF JSON (two names).
const ACCEPTED_SCENE_TYPES: [&str; 4] = [
    "model/gltf-binary",
    "application/octet-stream",
    "model/gltf+json",
    "application/json",
];

/// `POST /v1/jobs`: validate parameters and scene, store the job, queue it; 202 with the job.
/// With an `Idempotency-Key` a retried POST gets the job the first one created.
pub async fn create_job(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    request: Request,
) -> Result<Response, ApiError> {
    let (mut params, name) = submit_query(query.as_deref())?;
    params.validate().map_err(ApiError::bad_parameters)?;
    // The parameters as asked (defaults filled in), before the server's cap: what a retry repeats.
    let params_asked = params.clone();
    if let Some(cap) = state.config().max_job_seconds {
        let cap = cap as f64;
        params.max_seconds = Some(params.max_seconds.map_or(cap, |s| s.min(cap)));
    }
    let key = idempotency_key(request.headers())?;
    let kind = check_content_type(request.headers())?;
    let max_body = state.config().max_body_bytes;
    if let Some(length) = content_length(request.headers()) {
        if length > max_body as u64 {
            return Err(too_large(max_body));
        }
    }
    // A retry of a known key is answered from its job, however full the queue; any other
    // submission is refused before its body is received when the queue is already full
    // (checked again on enqueue).
    let known = key.as_deref().and_then(|k| state.jobs().by_key(k));
    if known.is_none() && !state.jobs().has_room() {
        return Err(queue_full(&state));
    }
    let _permit = state
        .upload_permits()
        .acquire()
        .await
        .map_err(|e| ApiError::internal("the upload limiter is closed", e))?;
    let (body, parts, file_name) = match kind {
        BodyKind::Scene => (read_body(request, max_body).await?, BTreeMap::new(), None),
        BodyKind::Multipart => read_multipart(request, max_body).await?,
    };
    // Hashing a large upload takes a while: off the async threads.
    let (fingerprint, parts) = match key {
        None => (None, parts),
        Some(_) => {
            let hashed = body.clone();
            tokio::task::spawn_blocking(move || {
                let fingerprint = request_fingerprint(&params_asked, &hashed, &parts);
                (Some(fingerprint), parts)
            })
            .await
            .map_err(|e| ApiError::internal("hashing the request failed", e))?
        }
    };
    if let (Some(job), Some(fingerprint)) = (&known, &fingerprint) {
        return replay_or_refuse(job, fingerprint);
    }
    let name = name.or_else(|| file_name.as_deref().and_then(name_of_file));

    let parts = check_scene(&state, &body, parts, params.order).await?;

    // Keyed submissions are stored one at a time, so two concurrent retries make one job.
    let _keyed = match &key {
        Some(_) => Some(state.keyed_submissions().lock().await),
        None => None,
    };
    if let (Some(job), Some(fingerprint)) = (
        key.as_deref().and_then(|k| state.jobs().by_key(k)),
        &fingerprint,
    ) {
        return replay_or_refuse(&job, fingerprint);
    }
    let created = SystemTime::now();
    let store = state.store().clone();
    let id = tokio::task::spawn_blocking(move || store.create_job_dir(created))
        .await
        .map_err(|e| ApiError::internal("storing the job failed", e))?
        .map_err(|e| ApiError::internal("storing the job failed", e))?;
    let job = Arc::new(
        Job::restore(
            id,
            created,
            state.jobs().next_seq(),
            params,
            JobStatus::queued(),
            key,
        )
        .with_name(name)
        .with_request_sha256(fingerprint),
    );
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

/// The query parameter that names the job's scene (not one of `JobParams`).
const NAME_PARAM: &str = "name";

/// Longest scene name accepted, in characters.
pub const MAX_JOB_NAME_CHARS: usize = 200;

/// The query of `POST /v1/jobs`: the job's parameters (`JobParams`, unknown names refused) and
/// the optional `name` of its scene (`job_name`). 400 `bad_parameters` naming what is wrong.
pub(crate) fn submit_query(query: Option<&str>) -> Result<(JobParams, Option<String>), ApiError> {
    let bad = |e: &dyn std::fmt::Display| {
        ApiError::bad_parameters(format!(
            "Failed to deserialize query string: {e}; parameters and their ranges are listed in \
             api/openapi.yaml"
        ))
    };
    let pairs: Vec<(String, String)> =
        serde_urlencoded::from_str(query.unwrap_or("")).map_err(|e| bad(&e))?;
    let mut name = None;
    let mut rest = Vec::with_capacity(pairs.len());
    for (key, value) in pairs {
        if key != NAME_PARAM {
            rest.push((key, value));
        } else if name.replace(value).is_some() {
            return Err(ApiError::bad_parameters(
                "the parameter 'name' is given twice",
            ));
        }
    }
    let rest = serde_urlencoded::to_string(&rest).map_err(|e| bad(&e))?;
    let params: JobParams = serde_urlencoded::from_str(&rest).map_err(|e| bad(&e))?;
    let name = name
        .map(|n| job_name(&n))
        .transpose()
        .map_err(ApiError::bad_parameters)?;
    Ok((params, name))
}

/// A scene name given as the `name` parameter: 1 to `MAX_JOB_NAME_CHARS` characters, no control
/// characters (tests/http_uploads.rs, `a_job_carries_the_name_of_its_scene`).
pub(crate) fn job_name(name: &str) -> Result<String, String> {
    let chars = name.chars().count();
    if chars == 0 || chars > MAX_JOB_NAME_CHARS {
        return Err(format!(
            "name must be 1 to {MAX_JOB_NAME_CHARS} characters (got {chars}); it names the scene \
             in the job list"
        ));
    }
    if name.trim().is_empty() || name.chars().any(char::is_control) {
        return Err(
            "name must be printable text: no control characters (tabs, line breaks), not only \
             spaces"
                .into(),
        );
    }
    Ok(name.to_string())
}

/// The default name of a multipart upload: its `scene` part's file name, without any folder a
/// client put in it, control characters dropped, clipped to `MAX_JOB_NAME_CHARS` characters;
/// none when nothing is left.
pub(crate) fn name_of_file(file_name: &str) -> Option<String> {
    let base = file_name.rsplit(['/', '\\']).next().unwrap_or(file_name);
    let name: String = base
        .chars()
        .filter(|c| !c.is_control())
        .take(MAX_JOB_NAME_CHARS)
        .collect();
    (!name.trim().is_empty()).then_some(name)
}

/// Loads the uploaded scene (off the async threads) as a solve would and refuses what cannot be
/// solved: 422 for an unreadable or unsolvable scene, one over `--max-triangles`, or one whose
/// estimated memory at `order` exceeds `--max-memory-bytes`. Returns the multipart parts the
/// scene uses (those it names by URI). One check for the local and the cluster routes.
pub(crate) async fn check_scene(
    state: &AppState,
    body: &Bytes,
    parts: BTreeMap<String, Vec<u8>>,
    order: usize,
) -> Result<BTreeMap<String, Vec<u8>>, ApiError> {
    let max_triangles = state.config().max_triangles;
    let max_memory = state.config().max_memory_bytes;
    let checked = body.clone();
    tokio::task::spawn_blocking(move || {
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
    .map_err(|e| ApiError::internal("the scene check failed", e))?
}

/// Longest `Idempotency-Key` accepted.
const MAX_IDEMPOTENCY_KEY: usize = 255;

/// The `Idempotency-Key` header: 1 to 255 printable ASCII characters.
pub(crate) fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
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

/// A keyed POST whose key names `job`: the job when the request is the one that created it (same
/// fingerprint, or a job recorded before fingerprints were kept), else 422
/// `idempotency_key_reused` (tests/http_jobs.rs, `an_idempotency_key_reused_with_another_request_is_refused`).
fn replay_or_refuse(job: &Job, fingerprint: &str) -> Result<Response, ApiError> {
    match &job.request_sha256 {
        Some(recorded) if recorded != fingerprint => {
            let key = job.idempotency_key.as_deref().unwrap_or("");
            Err(ApiError::idempotency_key_reused(key, job.id.as_str()))
        }
        _ => Ok(replay(job)),
    }
}

/// The fingerprint of a keyed submission, SHA-256 in hex over what makes the job's solve: the
/// parameters as asked (defaults filled in, so `order=2` and no `order` are one request, and the
/// order of the query's pairs does not count), the scene's bytes, and a multipart upload's
/// parts by URI (so a multipart boundary does not count). The scene's `name` is a label and
/// does not count (a retry may name it otherwise: tests/service_restart.rs,
/// `finished_results_survive_a_restart`). Each piece is length-prefixed, so no two different
/// requests share a byte stream.
pub(crate) fn request_fingerprint(
    params: &JobParams,
    scene: &[u8],
    parts: &BTreeMap<String, Vec<u8>>,
) -> String {
    use sha2::{Digest, Sha256};
    let mut hash = Sha256::new();
    let mut piece = |bytes: &[u8]| {
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(bytes);
    };
    piece(b"wavrad-submit-v1");
    // Serialising plain numbers, booleans and enums cannot fail; an empty piece would do anyway.
    piece(&serde_json::to_vec(params).unwrap_or_default());
    piece(scene);
    piece(&(parts.len() as u64).to_le_bytes());
    for (uri, bytes) in parts {
        piece(uri.as_bytes());
        piece(bytes);
    }
    let digest = hash.finalize();
    digest.iter().map(|b| format!("{b:02x}")).collect()
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

pub(crate) async fn read_body(request: Request, max_body: usize) -> Result<Bytes, ApiError> {
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
/// named by its URI (the part's name, else its file name). Also returns the `scene` part's file
/// name, when it has one.
pub(crate) async fn read_multipart(
    request: Request,
    max_body: usize,
) -> Result<(Bytes, BTreeMap<String, Vec<u8>>, Option<String>), ApiError> {
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
    let mut scene_file = None;
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
        let file_name = field.file_name().map(str::to_string);
        let bytes = field.bytes().await.map_err(multipart_error)?;
        if name == SCENE_PART {
            scene_file = file_name;
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
    Ok((scene, parts, scene_file))
}

/// 422 when the solve's estimated memory exceeds `--max-memory-bytes`.
pub(crate) fn check_memory(
    triangles: usize,
    order: usize,
    max_memory: u64,
) -> Result<(), ApiError> {
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
pub(crate) enum BodyKind {
    /// The scene itself (GLB or glTF JSON).
    Scene,
    /// `multipart/form-data`: the scene and the files it references.
    Multipart,
}

pub(crate) fn check_content_type(headers: &HeaderMap) -> Result<BodyKind, ApiError> {
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

pub(crate) fn content_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)?
        .to_str()
        .ok()?
        .trim()
        .parse()
        .ok()
}

pub(crate) fn too_large(max_body: usize) -> ApiError {
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

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn the_name_is_taken_out_of_the_job_parameters() {
        let (params, name) = submit_query(Some("order=1&name=Cornell%20box.gltf")).unwrap();
        assert_eq!(params.order, 1);
        assert_eq!(name.as_deref(), Some("Cornell box.gltf"));
        let (params, name) = submit_query(None).unwrap();
        assert_eq!(params, JobParams::default());
        assert_eq!(name, None);
        for bad in [
            "name=",
            "name=%20%20",
            "name=a%0Ab",
            "name=a&name=b",
            "nam=x",
            "order=x",
        ] {
            let e = submit_query(Some(bad)).unwrap_err();
            assert_eq!(e.code, "bad_parameters", "{bad}");
        }
        let long = format!("name={}", "é".repeat(MAX_JOB_NAME_CHARS + 1));
        assert!(submit_query(Some(&long)).is_err());
        let longest = format!("name={}", "é".repeat(MAX_JOB_NAME_CHARS));
        assert!(submit_query(Some(&longest)).is_ok());
    }

    #[test]
    fn a_file_name_names_the_job_without_its_folder() {
        assert_eq!(name_of_file("scenes/box.glb").as_deref(), Some("box.glb"));
        assert_eq!(
            name_of_file("C:\\x\\room.gltf").as_deref(),
            Some("room.gltf")
        );
        assert_eq!(name_of_file("a\tb.glb").as_deref(), Some("ab.glb"));
        assert_eq!(name_of_file("dir/"), None);
        let long = "x".repeat(500);
        assert_eq!(
            name_of_file(&long).map(|n| n.len()),
            Some(MAX_JOB_NAME_CHARS)
        );
    }
}
