//! A finished job's outputs: `GET /v1/jobs/{id}/result`, `POST /v1/jobs/{id}/probes` (evaluated
//! on the job's solution, from memory or its saved `solution.bin`), `GET
//! /v1/jobs/{id}/convergence` (convergence.csv as JSON rows) and `GET /v1/jobs/{id}/{file}` (the
//! lightmap pages, the preview, the scene). Invariant: only the canonical output file names are
//! served (never a path a client spells), and a file not yet written is 404 with the job's state.

use super::find;
use super::submit::read_body;
use crate::job::ProbeSource;
use crate::output::page_file_name;
use crate::output::probes::{parse_probes, ProbePoint};
use crate::service::error::{clip, panic_message, ApiError};
use crate::service::extract::ApiPath;
use crate::service::jobs::{Job, JobState};
use crate::service::runner::load_probe_source;
use crate::service::store::{CONVERGENCE_FILE, RESULT_FILE};
use crate::service::AppState;
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use tokio::sync::SemaphorePermit;

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
/// `probe_values.json` (docs/contract.md), evaluated on the job's solution: in memory for the most recent
/// succeeded jobs (`--probe-cache-jobs`), else loaded from the job's `solution.bin`. A job without
/// a usable one (finished by an older version, or damaged) is 409 `solution_unavailable`.
pub async fn post_probes(
    State(state): State<AppState>,
    ApiPath(id): ApiPath<String>,
    request: Request,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    require_succeeded(&job, "probes are evaluated once it has succeeded")?;
    // Bodies are read and evaluated under the same bound as scene uploads.
    let (_permit, probes) = read_probe_request(&state, request).await?;
    let source = probe_source_of(&state, &job).await?;
    let values = tokio::task::spawn_blocking(move || source.evaluate(&probes))
        .await
        .map_err(|e| ApiError::internal("evaluating the probes failed", e))?;
    Ok(Json(values).into_response())
}

/// The body of a probe request, read and parsed under an upload permit (held by the caller while
/// it evaluates): 400 `bad_probes` for a body that is not a probe points file, 400
/// `too_many_probes` beyond `--max-probes`. One reading for both stores' routes.
pub(crate) async fn read_probe_request(
    state: &AppState,
    request: Request,
) -> Result<(SemaphorePermit<'_>, Vec<ProbePoint>), ApiError> {
    let permit = state
        .upload_permits()
        .acquire()
        .await
        .map_err(|e| ApiError::internal("the upload limiter is closed", e))?;
    let body = read_body(request, state.config().max_body_bytes).await?;
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
    Ok((permit, probes))
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
pub(crate) fn output_file_type(name: &str) -> Option<&'static str> {
    match name {
        "preview.png" | "atlas.png" => return Some("image/png"),
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

/// `GET /v1/jobs/{id}/{file}`: `lightmap.exr`, `lightmap-{n}.exr`, `preview.png`, `atlas.png`,
/// `scene.glb`.
pub async fn get_file(
    State(state): State<AppState>,
    ApiPath((id, name)): ApiPath<(String, String)>,
) -> Result<Response, ApiError> {
    let job = find(&state, &id)?;
    let Some(content_type) = output_file_type(&name) else {
        return Err(ApiError::file_not_found(format!(
            "a job has no '{}'; its files are result, convergence, lightmap.exr, \
             lightmap-{{n}}.exr (n >= 1), preview.png, atlas.png and scene.glb",
            clip(&name, 100)
        )));
    };
    if name == crate::output::BAKED_SCENE_FILE && state.store().predates_baking(&job.id) {
        // Its `scene.glb` is the upload, not a baked scene.
        return Err(ApiError::file_not_found(format!(
            "job {} predates baking: it was solved by a version that wrote no baked scene \
             (submit the scene again for one)",
            job.id
        )));
    }
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
        assert_eq!(output_file_type("atlas.png"), Some("image/png"));
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
}
