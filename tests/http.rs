//! The HTTP service over a real socket (port 0): submit, poll, download, refuse bad input,
//! limits, cancel.

use base64::Engine;
use glam::DVec3;
use reqwest::{Client, StatusCode};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wavrad::scene::gltf_writer::{glb_from_parts, SceneBuilder};
use wavrad::service::{Server, ServiceConfig};

mod common;
use common::multipart;

/// A fresh, empty data directory for one test.
fn data_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("http-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Starts a server on 127.0.0.1 port 0; returns its base URL.
async fn start(config: ServiceConfig) -> String {
    let server = Server::bind(config, "127.0.0.1:0".parse().unwrap())
        .await
        .expect("server binds");
    let base = format!("http://{}", server.local_addr());
    tokio::spawn(server.run_until(std::future::pending()));
    base
}

fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap()
}

/// A unit box seen from inside, one quad per side, rho 0.5, the -x wall emitting.
fn small_scene(rho: f64) -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let wall = b.material([rho; 3], [0.0; 3], false);
    let lamp = b.material([rho; 3], [1.0; 3], false);
    b.inward_box(
        [lamp, wall, wall, wall, wall, wall],
        DVec3::ZERO,
        DVec3::ONE,
        1,
    );
    b.to_glb()
}

/// A closed box of white walls (rho = 1): no light is ever absorbed, so the solve never converges
/// and runs until cancelled or its time budget ends.
fn never_converging_scene() -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let wall = b.material([1.0; 3], [0.0; 3], false);
    let lamp = b.material([1.0; 3], [1.0; 3], false);
    b.inward_box(
        [lamp, wall, wall, wall, wall, wall],
        DVec3::ZERO,
        DVec3::ONE,
        3,
    );
    b.to_glb()
}

async fn submit(
    client: &Client,
    base: &str,
    query: &str,
    content_type: &str,
    body: Vec<u8>,
) -> reqwest::Response {
    client
        .post(format!("{base}/v1/jobs?{query}"))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .expect("POST /v1/jobs answers")
}

/// Submits a GLB and expects 202; returns the job document.
async fn submit_ok(client: &Client, base: &str, query: &str, glb: Vec<u8>) -> Value {
    let response = submit(client, base, query, "model/gltf-binary", glb).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let location = response
        .headers()
        .get("location")
        .expect("Location header")
        .to_str()
        .unwrap()
        .to_string();
    let job: Value = response.json().await.unwrap();
    assert_eq!(
        location,
        format!("/v1/jobs/{}", job["id"].as_str().unwrap())
    );
    job
}

/// GETs `url`, expects 200 and returns the JSON body.
async fn get_ok(client: &Client, url: String) -> Value {
    let response = client.get(url).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    response.json().await.unwrap()
}

async fn get_job(client: &Client, base: &str, id: &str) -> Value {
    get_ok(client, format!("{base}/v1/jobs/{id}")).await
}

/// Polls the job until its state is `state`; panics after `timeout`.
async fn wait_for(client: &Client, base: &str, id: &str, state: &str, timeout: Duration) -> Value {
    let start = Instant::now();
    loop {
        let job = get_job(client, base, id).await;
        if job["state"] == state {
            return job;
        }
        assert!(
            start.elapsed() < timeout,
            "job {id} is {} after {timeout:?}, expected {state}: {job}",
            job["state"]
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Checks the CONTRACT error shape and returns the error object.
async fn error_of(response: reqwest::Response, status: StatusCode) -> Value {
    assert_eq!(response.status(), status);
    assert!(
        response
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| v.starts_with("application/json")),
        "error responses are JSON"
    );
    let body: Value = response.json().await.unwrap();
    let error = body["error"].clone();
    let code = error["code"].as_str().expect("error.code");
    assert!(
        !code.is_empty() && code.bytes().all(|c| c.is_ascii_lowercase() || c == b'_'),
        "snake_case code: {code}"
    );
    assert!(
        !error["message"].as_str().expect("error.message").is_empty(),
        "non-empty message"
    );
    error
}

/// Reads an EXR from bytes; checks the size and that every value is finite and non-negative.
fn check_exr(bytes: &[u8]) -> (usize, usize) {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size: Vec2<usize>, _: &RgbaChannels| {
                (size, Vec::<[f32; 4]>::with_capacity(size.area()))
            },
            |pixels: &mut (Vec2<usize>, Vec<[f32; 4]>),
             _pos: Vec2<usize>,
             (r, g, b, a): (f32, f32, f32, f32)| { pixels.1.push([r, g, b, a]) },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes.to_vec()))
        .expect("a readable EXR");
    let (size, pixels) = &image.layer_data.channel_data.pixels;
    assert!(size.width() > 0 && size.height() > 0);
    assert_eq!(pixels.len(), size.area());
    for p in pixels {
        assert!(p.iter().all(|v| v.is_finite() && *v >= 0.0), "texel {p:?}");
    }
    assert!(
        pixels.iter().any(|p| p[0] > 0.0),
        "a lit box has some light in its lightmap"
    );
    (size.width(), size.height())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_small_scene_is_solved_and_its_outputs_downloaded() {
    let dir = data_dir("solve");
    let base = start(ServiceConfig::new(&dir)).await;
    let client = client();

    let health = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(health.status(), StatusCode::OK);
    assert_eq!(
        health.json::<Value>().await.unwrap(),
        json!({"status": "ok"})
    );

    let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let id = job["id"].as_str().unwrap().to_string();
    assert!(job["state"] == "queued" || job["state"] == "running");
    assert_eq!(job["params"]["order"], 1);
    let created = job["created"].as_str().unwrap();
    assert!(
        created.ends_with('Z') && created.len() == 24,
        "RFC 3339 UTC: {created}"
    );
    for key in ["unshot_ratio", "iterations", "elements", "links", "seconds"] {
        assert!(job["progress"][key].is_number(), "progress.{key}");
    }
    assert!(job["progress"]["eta_seconds"].is_null());

    // The job's files are on disk before the 202.
    let job_dir = dir.join("jobs").join(&id);
    for file in ["scene.glb", "params.json", "state.json"] {
        assert!(
            job_dir.join(file).is_file(),
            "{file} written before the 202"
        );
    }
    let params: Value =
        serde_json::from_slice(&std::fs::read(job_dir.join("params.json")).unwrap()).unwrap();
    assert_eq!(params["order"], 1);

    let done = wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
    assert!(done.get("error").is_none());
    assert_eq!(done["stop_reason"], "converged");
    assert!(done["progress"]["iterations"].as_u64().unwrap() > 0);
    assert_eq!(done["links"]["self"], format!("/v1/jobs/{id}"));

    let result = get_ok(&client, format!("{base}/v1/jobs/{id}/result")).await;
    assert_eq!(result["scene"]["triangles"], 12);
    assert_eq!(result["params"]["order"], 1);
    let page = &result["atlas"]["pages"][0];
    assert_eq!(page["file"], "lightmap.exr");

    let exr = client
        .get(format!("{base}/v1/jobs/{id}/lightmap.exr"))
        .send()
        .await
        .unwrap();
    assert_eq!(exr.status(), StatusCode::OK);
    assert_eq!(exr.headers()["content-type"], "image/x-exr");
    let (w, h) = check_exr(&exr.bytes().await.unwrap());
    assert_eq!(
        (w as u64, h as u64),
        (
            page["width"].as_u64().unwrap(),
            page["height"].as_u64().unwrap()
        )
    );

    let missing = client
        .get(format!("{base}/v1/jobs/{id}/lightmap-7.exr"))
        .send()
        .await
        .unwrap();
    error_of(missing, StatusCode::NOT_FOUND).await;

    let convergence = get_ok(&client, format!("{base}/v1/jobs/{id}/convergence")).await;
    let rows = convergence["rows"].as_array().unwrap();
    assert!(!rows.is_empty());
    for key in ["seconds", "unshot_ratio", "elements", "links"] {
        assert!(rows[0][key].is_number(), "row.{key}");
    }

    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"][0]["id"], id.as_str());

    // A finished job is deleted with its files.
    let deleted = client
        .delete(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    let gone = client
        .get(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    error_of(gone, StatusCode::NOT_FOUND).await;
    assert!(!job_dir.exists(), "the job's directory is gone");
}

/// One emitting triangle: the glTF JSON (its buffer has no URI yet) and the buffer's bytes,
/// positions (3 x VEC3 f32) then indices (3 x u32).
fn one_triangle_gltf(positions: [[f32; 3]; 3], indices: [u32; 3]) -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    for p in positions {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let root = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"emissiveFactor": [1.0, 1.0, 1.0]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12}
        ],
        "buffers": [{"byteLength": 48}]
    });
    (root, bin)
}

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_scenes_are_refused_and_the_server_keeps_working() {
    let mut config = ServiceConfig::new(data_dir("bad"));
    config.max_triangles = 12;
    let base = start(config).await;
    let client = client();

    // A GLB cut in half.
    let glb = small_scene(0.5);
    let truncated = glb[..glb.len() / 2].to_vec();
    let response = submit(&client, &base, "order=1", "model/gltf-binary", truncated).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(error["code"], "unreadable_scene");

    // glTF JSON whose index buffer points past the vertices.
    let (mut root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 5]);
    root["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    let body = serde_json::to_vec(&root).unwrap();
    let response = submit(&client, &base, "order=1", "model/gltf+json", body).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(error["code"], "invalid_scene");
    assert!(
        error["message"].as_str().unwrap().contains("out of range"),
        "{error}"
    );

    // A GLB with a NaN vertex position.
    let mut nan = TRIANGLE;
    nan[1][1] = f32::NAN;
    let (root, bin) = one_triangle_gltf(nan, [0, 1, 2]);
    let response = submit(
        &client,
        &base,
        "",
        "model/gltf-binary",
        glb_from_parts(&root, &bin),
    )
    .await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(error["code"], "invalid_scene");
    assert!(
        error["message"].as_str().unwrap().contains("NaN"),
        "{error}"
    );

    // Over --max-triangles (12 here).
    let mut b = SceneBuilder::new();
    let lamp = b.material([0.5; 3], [1.0; 3], false);
    b.inward_box([lamp; 6], DVec3::ZERO, DVec3::ONE, 2);
    let response = submit(&client, &base, "", "model/gltf-binary", b.to_glb()).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        error["message"].as_str().unwrap().contains("max-triangles"),
        "{error}"
    );

    // The same triangle without the NaN is fine (so it was the NaN that was refused).
    let (root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    let ok = submit(
        &client,
        &base,
        "order=1",
        "model/gltf-binary",
        glb_from_parts(&root, &bin),
    )
    .await;
    assert_eq!(ok.status(), StatusCode::ACCEPTED);

    // Nothing refused was stored or listed.
    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1);

    let health = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(health.status(), StatusCode::OK);
    let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    wait_for(
        &client,
        &base,
        job["id"].as_str().unwrap(),
        "succeeded",
        Duration::from_secs(60),
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_outside_the_contract_get_error_json() {
    let mut config = ServiceConfig::new(data_dir("errors"));
    config.max_body_bytes = 1024;
    let base = start(config).await;
    let client = client();

    let response = client
        .get(format!("{base}/v1/jobs/0123456789abcdef"))
        .send()
        .await
        .unwrap();
    assert_eq!(
        error_of(response, StatusCode::NOT_FOUND).await["code"],
        "job_not_found"
    );
    for path in ["result", "convergence", "lightmap.exr"] {
        let response = client
            .get(format!("{base}/v1/jobs/nope/{path}"))
            .send()
            .await
            .unwrap();
        error_of(response, StatusCode::NOT_FOUND).await;
    }
    let response = client
        .delete(format!("{base}/v1/jobs/nope"))
        .send()
        .await
        .unwrap();
    error_of(response, StatusCode::NOT_FOUND).await;

    let response = client
        .get(format!("{base}/no/such/route"))
        .send()
        .await
        .unwrap();
    error_of(response, StatusCode::NOT_FOUND).await;
    let response = client.put(format!("{base}/v1/jobs")).send().await.unwrap();
    error_of(response, StatusCode::METHOD_NOT_ALLOWED).await;

    let tiny = vec![0u8; 16];
    let response = submit(&client, &base, "order=1", "text/plain", tiny.clone()).await;
    let error = error_of(response, StatusCode::UNSUPPORTED_MEDIA_TYPE).await;
    let message = error["message"].as_str().unwrap();
    assert!(
        message.contains("model/gltf-binary") && message.contains("model/gltf+json"),
        "{message}"
    );
    let response = client
        .post(format!("{base}/v1/jobs"))
        .body(tiny.clone())
        .send()
        .await
        .unwrap();
    error_of(response, StatusCode::UNSUPPORTED_MEDIA_TYPE).await;

    for query in [
        "order=7",
        "order=two",
        "frobnicate=1",
        "target_unshot=0",
        "quantity=lux",
        "max_seconds=-1",
    ] {
        let response = submit(&client, &base, query, "model/gltf-binary", tiny.clone()).await;
        let error = error_of(response, StatusCode::BAD_REQUEST).await;
        assert_eq!(error["code"], "bad_parameters", "{query}");
    }
    let response = submit(&client, &base, "order=7", "model/gltf-binary", tiny.clone()).await;
    let error = error_of(response, StatusCode::BAD_REQUEST).await;
    assert!(error["message"].as_str().unwrap().contains("order"));

    let big = small_scene(0.5);
    assert!(big.len() > 1024);
    let response = submit(&client, &base, "order=1", "model/gltf-binary", big).await;
    assert_eq!(
        error_of(response, StatusCode::PAYLOAD_TOO_LARGE).await["code"],
        "payload_too_large"
    );

    let response = submit(&client, &base, "", "model/gltf-binary", Vec::new()).await;
    error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;

    // A buffer URI naming a file is never resolved on the server.
    let (mut root, _) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    root["buffers"][0]["uri"] = json!("/etc/passwd");
    let body = serde_json::to_vec(&root).unwrap();
    let response = submit(&client, &base, "", "model/gltf+json", body).await;
    error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;

    // Still alive and empty.
    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list, json!({"jobs": []}));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_refuses_and_cancelled_jobs_end() {
    let mut config = ServiceConfig::new(data_dir("queue"));
    config.workers = 1;
    config.max_queued = 1;
    let base = start(config).await;
    let client = client();

    // The single worker is held by a solve that cannot converge (30 s budget as a backstop).
    let busy = submit_ok(
        &client,
        &base,
        "order=1&target_unshot=1e-9&max_seconds=30",
        never_converging_scene(),
    )
    .await;
    let busy_id = busy["id"].as_str().unwrap().to_string();
    wait_for(&client, &base, &busy_id, "running", Duration::from_secs(10)).await;

    // Polling stays responsive while the solve uses every core.
    let polls = Instant::now();
    for _ in 0..10 {
        get_job(&client, &base, &busy_id).await;
    }
    assert!(
        polls.elapsed() < Duration::from_secs(2),
        "10 polls took {:?}",
        polls.elapsed()
    );

    // One job may wait; the next is refused.
    let waiting = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    assert_eq!(waiting["state"], "queued");
    let waiting_id = waiting["id"].as_str().unwrap().to_string();
    let refused = submit(
        &client,
        &base,
        "order=1",
        "model/gltf-binary",
        small_scene(0.5),
    )
    .await;
    let retry_after: u64 = refused.headers()["retry-after"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(retry_after > 0);
    assert_eq!(
        error_of(refused, StatusCode::TOO_MANY_REQUESTS).await["code"],
        "queue_full"
    );

    // Cancelling the waiting job ends it at once and frees its place.
    let response = client
        .delete(format!("{base}/v1/jobs/{waiting_id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let cancelled: Value = response.json().await.unwrap();
    assert_eq!(cancelled["state"], "cancelled");
    assert_eq!(
        get_job(&client, &base, &waiting_id).await["state"],
        "cancelled"
    );
    let result = client
        .get(format!("{base}/v1/jobs/{waiting_id}/result"))
        .send()
        .await
        .unwrap();
    assert_eq!(
        error_of(result, StatusCode::CONFLICT).await["code"],
        "job_not_succeeded"
    );

    let next = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let next_id = next["id"].as_str().unwrap().to_string();

    // Cancelling the running job stops it at the next shot, then its outputs are written. The
    // CONTRACT's 2 seconds hold on an idle machine (this takes ~0.1 s); the bound here leaves
    // room for a loaded test machine.
    // Wait (bounded) until the busy job has shot at least once, so the cancel lands mid-solve.
    let started = Instant::now();
    loop {
        let job = get_job(&client, &base, &busy_id).await;
        if job["progress"]["iterations"].as_u64().unwrap_or(0) > 0 {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(15),
            "the busy job never shot: {job}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let response = client
        .delete(format!("{base}/v1/jobs/{busy_id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let cancel_asked = Instant::now();
    let busy_end = wait_for(
        &client,
        &base,
        &busy_id,
        "cancelled",
        Duration::from_secs(15),
    )
    .await;
    println!("running job cancelled after {:?}", cancel_asked.elapsed());
    assert_eq!(busy_end["stop_reason"], "cancelled");

    // The worker is free again: the queued job runs.
    wait_for(
        &client,
        &base,
        &next_id,
        "succeeded",
        Duration::from_secs(60),
    )
    .await;

    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let ids: Vec<&str> = list["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_str().unwrap())
        .collect();
    assert_eq!(
        ids,
        vec![next_id.as_str(), waiting_id.as_str(), busy_id.as_str()],
        "newest first"
    );
}

/// A chunked upload has no Content-Length: the limit is enforced while reading, still as JSON 413.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_chunked_upload_is_refused() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut config = ServiceConfig::new(data_dir("chunked"));
    config.max_body_bytes = 1024;
    let base = start(config).await;
    let addr = base.trim_start_matches("http://");
    let mut stream = tokio::net::TcpStream::connect(addr).await.unwrap();
    let mut request = format!(
        "POST /v1/jobs?order=1 HTTP/1.1\r\nHost: {addr}\r\nContent-Type: model/gltf-binary\r\n\
         Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n1000\r\n"
    )
    .into_bytes();
    request.extend(std::iter::repeat_n(b'x', 0x1000));
    request.extend_from_slice(b"\r\n0\r\n\r\n");
    stream.write_all(&request).await.unwrap();
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(10), stream.read_to_end(&mut answer))
        .await
        .expect("the server answers")
        .unwrap();
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    let body = &answer[answer.find("\r\n\r\n").unwrap() + 4..];
    let body: Value = serde_json::from_str(body).unwrap();
    assert_eq!(body["error"]["code"], "payload_too_large");
}

/// The OpenAPI document served at /v1/openapi.json describes exactly the routes of the router:
/// every (path, method) of the route table is documented, every documented operation is in the
/// table, and the live router answers each documented operation (not with the route fallback).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_describes_exactly_the_routes() {
    use std::collections::BTreeSet;
    let base = start(ServiceConfig::new(data_dir("openapi"))).await;
    let client = client();
    let response = client
        .get(format!("{base}/v1/openapi.json"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let doc: Value = response.json().await.unwrap();
    assert_eq!(doc["openapi"], "3.1.0");
    let yaml =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.yaml")).unwrap();
    assert!(yaml.starts_with("openapi: 3.1"), "the YAML is the source");

    let mut documented = BTreeSet::new();
    for (path, item) in doc["paths"].as_object().unwrap() {
        for method in ["get", "post", "put", "patch", "delete"] {
            if item.get(method).is_some() {
                documented.insert((path.clone(), method.to_uppercase()));
            }
        }
    }
    let mut routed = BTreeSet::new();
    for route in wavrad::service::api_routes(1) {
        for path in route.documented {
            routed.insert((path.to_string(), route.method.to_string()));
        }
    }
    assert_eq!(routed, documented, "route table and OpenAPI document agree");

    for (path, method) in &documented {
        let url = format!(
            "{base}{}",
            path.replace("{id}", "0000000000000000").replace("{n}", "1")
        );
        let method = reqwest::Method::from_bytes(method.as_bytes()).unwrap();
        let response = client.request(method.clone(), &url).send().await.unwrap();
        let status = response.status();
        if status.is_client_error() {
            let body: Value = response.json().await.unwrap();
            let code = body["error"]["code"].as_str().unwrap().to_string();
            assert!(
                code != "not_found" && code != "method_not_allowed",
                "{method} {path}: the router does not answer it ({code})"
            );
        } else {
            assert!(status.is_success(), "{method} {path}: {status}");
        }
    }
    for schema in ["Job", "Progress", "Error"] {
        assert!(
            doc["components"]["schemas"][schema].is_object(),
            "schema {schema}"
        );
    }
}

/// A room lit from its -x wall holding a `k x k` grid of small double-sided cubes at jittered
/// heights: thousands of non-coplanar faces, so one shot of order 3 takes long.
fn cluttered_scene(k: u32) -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let wall = b.material([0.8; 3], [0.0; 3], false);
    let lamp = b.material([0.8; 3], [1.0; 3], false);
    let block = b.material([0.7; 3], [0.0; 3], true);
    let size = 10.0;
    b.inward_box(
        [lamp, wall, wall, wall, wall, wall],
        DVec3::ZERO,
        DVec3::splat(size),
        1,
    );
    let step = size / f64::from(k + 1);
    for i in 0..k {
        for j in 0..k {
            let h = 0.5 + 0.37 * f64::from((i * 7 + j * 13) % 11);
            let min = DVec3::new(step * f64::from(i + 1), step * f64::from(j + 1), h);
            let s = step * 0.4;
            let (x, y, z) = (DVec3::X * s, DVec3::Y * s, DVec3::Z * s);
            b.quad(block, min, y, z, 1);
            b.quad(block, min + x, y, z, 1);
            b.quad(block, min, z, x, 1);
            b.quad(block, min + y, z, x, 1);
            b.quad(block, min, x, y, 1);
            b.quad(block, min + z, x, y, 1);
        }
    }
    b.to_glb()
}

/// Every limit is a named setting, and a refusal names it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn limits_are_named_settings_and_refusals_name_them() {
    let mut config = ServiceConfig::new(data_dir("limits"));
    config.max_memory_bytes = 10_000;
    let base = start(config).await;
    let client = client();
    let response = submit(
        &client,
        &base,
        "order=3",
        "model/gltf-binary",
        small_scene(0.5),
    )
    .await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(error["code"], "memory_limit");
    let message = error["message"].as_str().unwrap();
    assert!(message.contains("--max-memory-bytes"), "{message}");
    assert!(message.contains("10000 bytes"), "{message}");

    let mut config = ServiceConfig::new(data_dir("limits-seconds"));
    config.max_job_seconds = Some(1);
    let base = start(config).await;
    // A job asking for more is capped; one asking for nothing gets the cap.
    let capped = submit_ok(
        &client,
        &base,
        "order=1&target_unshot=1e-9&max_seconds=30",
        never_converging_scene(),
    )
    .await;
    assert_eq!(capped["params"]["max_seconds"], 1.0);
    let id = capped["id"].as_str().unwrap();
    let started = Instant::now();
    let done = wait_for(&client, &base, id, "succeeded", Duration::from_secs(30)).await;
    assert_eq!(done["stop_reason"], "time_budget");
    assert!(started.elapsed() < Duration::from_secs(20));
    let free = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    assert_eq!(free["params"]["max_seconds"], 1.0);
    let shorter = submit_ok(&client, &base, "order=1&max_seconds=0.5", small_scene(0.5)).await;
    assert_eq!(shorter["params"]["max_seconds"], 0.5);
}

/// DELETE of a running job on a large scene: `cancelled` within 2 s even mid-shot.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_running_job_on_a_large_scene_is_cancelled_within_two_seconds() {
    let base = start(ServiceConfig::new(data_dir("cancel-large"))).await;
    let client = client();
    let job = submit_ok(
        &client,
        &base,
        "order=3&tolerance=1e-6&target_unshot=1e-6&max_seconds=120",
        cluttered_scene(24),
    )
    .await;
    let id = job["id"].as_str().unwrap().to_string();
    wait_for(&client, &base, &id, "running", Duration::from_secs(60)).await;
    // Into the first shot (the emitter's direct shot over ~14 000 faces, longer than 2 s here).
    tokio::time::sleep(Duration::from_millis(500)).await;
    let before = get_job(&client, &base, &id).await;
    println!("before cancel: {}", before["progress"]);
    assert_eq!(
        before["progress"]["iterations"], 0,
        "the cancel must arrive during the first shot"
    );
    let response = client
        .delete(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let asked = Instant::now();
    let end = wait_for(&client, &base, &id, "cancelled", Duration::from_secs(10)).await;
    let latency = asked.elapsed();
    println!("cancelled after {latency:?}: {}", end["progress"]);
    assert!(latency < Duration::from_secs(2), "took {latency:?}");
    assert_eq!(end["stop_reason"], "cancelled");
    // The interrupted shot is reported as the last progress (the solver counts it as an
    // iteration), so the end state cannot tell an interrupted shot from a finished one; what
    // shows the cancel landed mid-shot is `before` (no shot done yet) and the latency.
}

/// A finished job deleted goes with its files; `--retain-jobs` deletes the oldest beyond N.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_and_retention_remove_files() {
    let dir = data_dir("retain");
    let mut config = ServiceConfig::new(&dir);
    config.retain_jobs = Some(2);
    let base = start(config).await;
    let client = client();
    let mut ids = Vec::new();
    for _ in 0..3 {
        let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
        let id = job["id"].as_str().unwrap().to_string();
        wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
        ids.push(id);
    }
    let jobs = dir.join("jobs");
    // Retention runs just after the third job ends: the first goes, files and all.
    let waited = Instant::now();
    loop {
        let first = client
            .get(format!("{base}/v1/jobs/{}", ids[0]))
            .send()
            .await
            .unwrap();
        if first.status() == StatusCode::NOT_FOUND {
            error_of(first, StatusCode::NOT_FOUND).await;
            break;
        }
        assert!(
            waited.elapsed() < Duration::from_secs(5),
            "the oldest job stays"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(!jobs.join(&ids[0]).exists());
    assert!(jobs.join(&ids[1]).join("result.json").is_file());

    let response = client
        .delete(format!("{base}/v1/jobs/{}", ids[1]))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::NO_CONTENT);
    assert!(!jobs.join(&ids[1]).exists(), "deleted with its files");
    let again = client
        .delete(format!("{base}/v1/jobs/{}", ids[1]))
        .send()
        .await
        .unwrap();
    error_of(again, StatusCode::NOT_FOUND).await;
    assert!(jobs.join(&ids[2]).join("lightmap.exr").is_file());
    assert!(std::fs::read_dir(dir.join("trash"))
        .unwrap()
        .next()
        .is_none());
}

/// A .gltf with an external buffer is solved when the buffer is uploaded as a part named by its
/// URI; without it, or without a `scene` part, the upload is refused with what to fix.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_multipart_upload_resolves_external_files_by_name() {
    let base = start(ServiceConfig::new(data_dir("multipart"))).await;
    let client = client();
    let (mut root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    root["buffers"][0]["uri"] = json!("geometry/tri.bin");
    let gltf = serde_json::to_vec(&root).unwrap();

    let (content_type, body) = multipart(&[
        ("scene", "tri.gltf", "model/gltf+json", &gltf),
        (
            "geometry/tri.bin",
            "tri.bin",
            "application/octet-stream",
            &bin,
        ),
    ]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    let done = wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    assert_eq!(done["state"], "succeeded");

    let (content_type, body) = multipart(&[("scene", "tri.gltf", "model/gltf+json", &gltf)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        error["message"]
            .as_str()
            .unwrap()
            .contains("geometry/tri.bin"),
        "{error}"
    );

    let (content_type, body) =
        multipart(&[("tri.bin", "tri.bin", "application/octet-stream", &bin)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    let error = error_of(response, StatusCode::BAD_REQUEST).await;
    assert_eq!(error["code"], "bad_multipart");
    assert!(error["message"].as_str().unwrap().contains("'scene'"));
}

/// A retried POST with the same `Idempotency-Key` gets the job the first one created, also when
/// the retries race; a malformed key is a 400.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idempotency_key_returns_the_job_it_created() {
    let base = start(ServiceConfig::new(data_dir("idempotency"))).await;
    let client = client();
    let post = |key: &'static str| {
        client
            .post(format!("{base}/v1/jobs?order=1"))
            .header("content-type", "model/gltf-binary")
            .header("idempotency-key", key)
            .body(small_scene(0.5))
            .send()
    };
    let first = post("build-42").await.unwrap();
    assert_eq!(first.status(), StatusCode::ACCEPTED);
    assert!(first.headers().get("idempotent-replayed").is_none());
    let first: Value = first.json().await.unwrap();
    let again = post("build-42").await.unwrap();
    assert_eq!(again.status(), StatusCode::ACCEPTED);
    assert_eq!(again.headers()["idempotent-replayed"], "true");
    let again: Value = again.json().await.unwrap();
    assert_eq!(again["id"], first["id"]);

    // Two retries in flight at once still make one job.
    let (a, b) = tokio::join!(post("build-43"), post("build-43"));
    let a: Value = a.unwrap().json().await.unwrap();
    let b: Value = b.unwrap().json().await.unwrap();
    assert_eq!(a["id"], b["id"]);
    assert_ne!(a["id"], first["id"]);

    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 2);

    let bad = client
        .post(format!("{base}/v1/jobs?order=1"))
        .header("content-type", "model/gltf-binary")
        .header("idempotency-key", "x".repeat(300))
        .body(small_scene(0.5))
        .send()
        .await
        .unwrap();
    assert_eq!(
        error_of(bad, StatusCode::BAD_REQUEST).await["code"],
        "bad_idempotency_key"
    );
}

/// While a converging solve runs, its progress carries an ETA fitted on the unshot decay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_running_job_reports_an_eta() {
    let base = start(ServiceConfig::new(data_dir("eta"))).await;
    let client = client();
    let job = submit_ok(
        &client,
        &base,
        "order=1&target_unshot=1e-3",
        cluttered_scene(5),
    )
    .await;
    let id = job["id"].as_str().unwrap().to_string();
    let start = Instant::now();
    let mut seen = None;
    loop {
        let j = get_job(&client, &base, &id).await;
        let p = &j["progress"];
        if j["state"] == "running" && p["iterations"].as_u64().unwrap() >= 4 {
            if let Some(eta) = p["eta_seconds"].as_f64() {
                seen = Some((eta, p.clone()));
                break;
            }
        }
        if j["state"] != "running" && j["state"] != "queued" {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(60));
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let (eta, progress) = seen.expect("an ETA while running");
    println!("eta {eta} s at {progress}");
    assert!(eta.is_finite() && eta >= 0.0);
    let done = wait_for(&client, &base, &id, "succeeded", Duration::from_secs(120)).await;
    println!("finished at {}", done["progress"]);
    assert!(done["progress"]["eta_seconds"].is_null() || done["progress"]["eta_seconds"] == 0.0);
}

/// Reads server-sent events until the stream closes: (event, data) pairs.
async fn read_events(mut response: reqwest::Response) -> Vec<(String, Value)> {
    let mut text = String::new();
    while let Some(chunk) = tokio::time::timeout(Duration::from_secs(60), response.chunk())
        .await
        .expect("the stream moves")
        .unwrap()
    {
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    let mut events = Vec::new();
    for block in text.split("\n\n") {
        let mut event = None;
        let mut data = String::new();
        for line in block.lines() {
            if let Some(e) = line.strip_prefix("event:") {
                event = Some(e.trim().to_string());
            } else if let Some(d) = line.strip_prefix("data:") {
                data.push_str(d.trim_start());
            }
        }
        if let Some(event) = event {
            events.push((event, serde_json::from_str(&data).unwrap()));
        }
    }
    events
}

/// The event stream shows progress at each shot, then `done` with the same job polling shows; a
/// late client gets one progress and done.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn events_stream_progress_then_done() {
    let base = start(ServiceConfig::new(data_dir("events"))).await;
    let client = client();
    let job = submit_ok(&client, &base, "order=1&tolerance=1e-4", cluttered_scene(3)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let response = client
        .get(format!("{base}/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/event-stream"));
    let events = read_events(response).await;
    let (last, done) = events.last().expect("events");
    assert_eq!(last, "done");
    assert_eq!(done["state"], "succeeded");
    let progress: Vec<&Value> = events
        .iter()
        .filter(|(e, _)| e == "progress")
        .map(|(_, d)| d)
        .collect();
    assert_eq!(
        progress.len() + 1,
        events.len(),
        "only progress before done"
    );
    assert!(
        progress.len() >= 3,
        "progress at the shots: {}",
        progress.len()
    );
    let shots: Vec<u64> = progress
        .iter()
        .map(|p| p["iterations"].as_u64().unwrap())
        .collect();
    assert!(shots.windows(2).all(|w| w[0] <= w[1]), "{shots:?}");
    assert_eq!(
        *done,
        get_job(&client, &base, &id).await,
        "same state as polling"
    );

    let late = client
        .get(format!("{base}/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap();
    let events = read_events(late).await;
    let names: Vec<&str> = events.iter().map(|(e, _)| e.as_str()).collect();
    assert_eq!(names, ["progress", "done"]);
    assert_eq!(events[0].1, done["progress"]);
    let missing = client
        .get(format!("{base}/v1/jobs/0000000000000000/events"))
        .send()
        .await
        .unwrap();
    error_of(missing, StatusCode::NOT_FOUND).await;
}

/// With a token every /v1 route needs it (every operation of the route table, each method, plus
/// an unknown /v1 path); /healthz and /metrics stay open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bearer_token_guards_every_v1_route() {
    let mut config = ServiceConfig::new(data_dir("auth"));
    config.api_token = Some("s3cret-token".into());
    let base = start(config).await;
    let client = client();
    let mut operations: Vec<(reqwest::Method, String)> = Vec::new();
    for route in wavrad::service::api_routes(1) {
        let method = reqwest::Method::from_bytes(route.method.as_str().as_bytes()).unwrap();
        for path in route.documented {
            let path = path.replace("{id}", "0000000000000000").replace("{n}", "1");
            operations.push((method.clone(), path));
        }
    }
    operations.push((reqwest::Method::GET, "/v1/nope".into()));
    operations.push((reqwest::Method::PUT, "/v1/jobs".into()));
    let guarded: Vec<_> = operations
        .iter()
        .filter(|(_, p)| p.starts_with("/v1/"))
        .collect();
    assert!(guarded.len() >= 12, "{guarded:?}");
    for (method, path) in &guarded {
        let url = format!("{base}{path}");
        let request = || {
            let r = client.request(method.clone(), &url);
            if *method == reqwest::Method::POST {
                r.header("content-type", "model/gltf-binary")
                    .body(small_scene(0.5))
            } else {
                r
            }
        };
        let response = request().send().await.unwrap();
        assert_eq!(
            response
                .headers()
                .get("www-authenticate")
                .map(|v| v.as_bytes()),
            Some(&b"Bearer"[..]),
            "{method} {path}"
        );
        let error = error_of(response, StatusCode::UNAUTHORIZED).await;
        assert_eq!(error["code"], "unauthorized", "{method} {path}");
        assert!(error["message"].as_str().unwrap().contains("Bearer"));
        let wrong = request().bearer_auth("s3cret-tokeN").send().await.unwrap();
        error_of(wrong, StatusCode::UNAUTHORIZED).await;
        let right = request().bearer_auth("s3cret-token").send().await.unwrap();
        assert_ne!(
            right.status(),
            StatusCode::UNAUTHORIZED,
            "{method} {path} with the token"
        );
    }
    for open in ["/healthz", "/metrics", "/"] {
        let r = client.get(format!("{base}{open}")).send().await.unwrap();
        assert_eq!(r.status(), StatusCode::OK, "{open}");
    }
    // The one POST made with the token was accepted; nothing else created a job.
    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .bearer_auth("s3cret-token")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1);
}

/// `/metrics` is Prometheus text, every series `wavrad_*`, counting what happened.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_count_jobs_and_solves() {
    let base = start(ServiceConfig::new(data_dir("metrics"))).await;
    let client = client();
    let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let id = job["id"].as_str().unwrap();
    wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    // The counters are updated just after the state: poll briefly.
    let start = Instant::now();
    let text = loop {
        let r = client.get(format!("{base}/metrics")).send().await.unwrap();
        assert_eq!(r.status(), StatusCode::OK);
        assert!(r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/plain"));
        let text = r.text().await.unwrap();
        if text.contains("\nwavrad_solves_total 1\n") || start.elapsed() > Duration::from_secs(5) {
            break text;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    let value = |name: &str| -> f64 {
        text.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
            .unwrap_or_else(|| panic!("{name} in\n{text}"))
    };
    for line in text.lines().filter(|l| !l.is_empty()) {
        let name = line
            .strip_prefix("# HELP ")
            .or_else(|| line.strip_prefix("# TYPE "))
            .unwrap_or(line);
        assert!(name.starts_with("wavrad_"), "{line}");
    }
    // Every series the README lists is there, with its type.
    for name in [
        "wavrad_jobs",
        "wavrad_queue_depth",
        "wavrad_queue_capacity",
        "wavrad_running_elements",
        "wavrad_running_shots",
        "wavrad_solves_total",
        "wavrad_solve_seconds_total",
        "wavrad_shots_total",
        "wavrad_elements_total",
        "wavrad_rays_total",
    ] {
        assert!(
            text.lines()
                .any(|l| l.starts_with(&format!("# TYPE {name} "))),
            "{name} in\n{text}"
        );
    }
    for state in ["queued", "running", "succeeded", "failed", "cancelled"] {
        value(&format!("wavrad_jobs{{state=\"{state}\"}}"));
    }
    assert_eq!(value("wavrad_jobs{state=\"succeeded\"}"), 1.0);
    assert_eq!(value("wavrad_jobs{state=\"queued\"}"), 0.0);
    assert_eq!(value("wavrad_queue_depth"), 0.0);
    assert_eq!(value("wavrad_queue_capacity"), 64.0);
    assert_eq!(value("wavrad_solves_total"), 1.0);
    assert!(value("wavrad_shots_total") > 0.0);
    assert!(value("wavrad_rays_total") > 0.0);
    assert!(value("wavrad_elements_total") > 0.0);
    assert!(value("wavrad_solve_seconds_total") > 0.0);
}

/// Every file of `tests/data/malformed/` (written by its `make.py`: truncated, wrong magic, huge
/// counts, cyclic node graphs, NaN, missing buffers, data URIs lying about their size, ...) is
/// refused with a 4xx and a message, and the server keeps serving.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_files_get_4xx_and_the_server_stays_up() {
    let base = start(ServiceConfig::new(data_dir("malformed"))).await;
    let client = client();
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/malformed"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e != "py"))
        .collect();
    files.sort();
    assert!(files.len() >= 25, "the corpus is there: {}", files.len());
    // Each hostile shape the service must refuse, by category (issue 6), in both containers
    // where it applies.
    let categories: [(&str, &[&str]); 8] = [
        (
            "truncated",
            &[
                "truncated.glb",
                "truncated_header.glb",
                "truncated.gltf",
                "empty.glb",
            ],
        ),
        ("wrong magic", &["wrong_magic.glb", "wrong_version.glb"]),
        (
            "huge counts",
            &[
                "huge_accessor_count.gltf",
                "huge_accessor_count.glb",
                "huge_buffer_byte_length.gltf",
                "huge_chunk_count.glb",
                "length_lies.glb",
                "json_chunk_length_lies.glb",
            ],
        ),
        (
            "cyclic node graphs",
            &[
                "cyclic_nodes.gltf",
                "cyclic_nodes.glb",
                "self_child_node.gltf",
                "shared_children_nodes.gltf",
            ],
        ),
        (
            "NaN",
            &[
                "nan_positions.gltf",
                "nan_positions.glb",
                "nan_emission.gltf",
                "inf_positions.gltf",
                "inf_emission.gltf",
                "inf_emission_strength.gltf",
                "inf_light_intensity.gltf",
                "huge_translation.gltf",
            ],
        ),
        (
            "missing buffers",
            &[
                "missing_buffer.gltf",
                "no_buffers.gltf",
                "buffer_without_uri.gltf",
                "missing_bin_chunk.glb",
                "bin_chunk_shorter_than_buffer.glb",
            ],
        ),
        (
            "data URIs lying about their size",
            &[
                "data_uri_shorter_than_declared.gltf",
                "data_uri_longer_than_declared.gltf",
            ],
        ),
        (
            "fuzz crashes",
            &[
                "fuzz_accessor_count_zero.glb",
                "fuzz_position_accessor_out_of_range.gltf",
                "fuzz_position_accessor_vec2.gltf",
                "float_indices.gltf",
                "position_accessor_vec4_u8.gltf",
            ],
        ),
    ];
    for (category, names) in categories {
        for name in names {
            assert!(
                files.iter().any(|f| f.ends_with(name)),
                "{category}: {name} is in the corpus"
            );
        }
    }
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let content_type = match path.extension().and_then(|e| e.to_str()) {
            Some("gltf") => "model/gltf+json",
            _ => "model/gltf-binary",
        };
        let bytes = std::fs::read(&path).unwrap();
        let response = submit(&client, &base, "order=1", content_type, bytes).await;
        let status = response.status();
        assert!(status.is_client_error(), "{name}: {status}");
        let body: Value = response
            .json()
            .await
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let message = body["error"]["message"].as_str().unwrap_or("");
        assert!(message.len() > 10, "{name}: {body}");
        assert!(body["error"]["code"].is_string(), "{name}: {body}");
        println!("{name}: {status} {}: {message}", body["error"]["code"]);
        let health = client.get(format!("{base}/healthz")).send().await.unwrap();
        assert_eq!(health.status(), StatusCode::OK, "after {name}");
    }
    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list, json!({"jobs": []}), "no job was created");
}

/// The rarer answers are JSON errors too: 503 when `--max-in-flight` requests are being handled,
/// 408 when a request outlives `--request-timeout-seconds`, 500 when the store cannot be written.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn busy_timeout_and_internal_errors_are_json() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let dir = data_dir("rare");
    let mut config = ServiceConfig::new(&dir);
    config.max_in_flight = 1;
    config.request_timeout = Duration::from_secs(1);
    let base = start(config).await;
    let client = client();
    let addr = base.trim_start_matches("http://").to_string();

    // A slow upload holds the only request slot: it declares 1000 bytes and sends 10.
    let mut slow = tokio::net::TcpStream::connect(&addr).await.unwrap();
    let head = format!(
        "POST /v1/jobs?order=1 HTTP/1.1\r\nHost: {addr}\r\nContent-Type: model/gltf-binary\r\n\
         Content-Length: 1000\r\nConnection: close\r\n\r\nglTF\x02\0\0\0\0\0"
    );
    slow.write_all(head.as_bytes()).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let busy = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert!(busy.headers().contains_key("retry-after"));
    assert_eq!(
        error_of(busy, StatusCode::SERVICE_UNAVAILABLE).await["code"],
        "server_busy"
    );

    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(10), slow.read_to_end(&mut answer))
        .await
        .expect("the slow request is answered")
        .unwrap();
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    let body: Value =
        serde_json::from_str(&answer[answer.find("\r\n\r\n").unwrap() + 4..]).unwrap();
    assert_eq!(body["error"]["code"], "request_timeout");

    // The store's jobs directory turns into a file: storing a job fails, the server does not.
    std::fs::remove_dir_all(dir.join("jobs")).unwrap();
    std::fs::write(dir.join("jobs"), b"not a directory").unwrap();
    let response = submit(
        &client,
        &base,
        "order=1",
        "model/gltf-binary",
        small_scene(0.5),
    )
    .await;
    let error = error_of(response, StatusCode::INTERNAL_SERVER_ERROR).await;
    assert_eq!(error["code"], "internal_error");
    assert!(error["message"].as_str().unwrap().contains("server log"));
    let health = client.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(health.status(), StatusCode::OK);
}

/// `POST /v1/jobs/{id}/probes` evaluates a succeeded job's solution at the given points (the
/// emitting wall shows at least its own emission, a point in mid-air has no value); bad bodies
/// are 400, unfinished jobs 409. A job whose solution left memory (`--probe-cache-jobs`) is
/// answered from its `solution.bin` with the same values; without a usable one (a job from an
/// older version, a damaged file) it is a 409 that says what to do.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probes_are_evaluated_on_a_succeeded_job() {
    let dir = data_dir("probes");
    let mut config = ServiceConfig::new(dir.clone());
    config.probe_cache_jobs = 1;
    config.max_probes = 3;
    let base = start(config).await;
    let client = client();
    let probe = |id: &str, body: Value| {
        client
            .post(format!("{base}/v1/jobs/{id}/probes"))
            .header("content-type", "application/json")
            .body(body.to_string())
            .send()
    };
    let first = submit_ok(&client, &base, "order=2", small_scene(0.5)).await;
    let first = first["id"].as_str().unwrap().to_string();
    wait_for(&client, &base, &first, "succeeded", Duration::from_secs(60)).await;

    let points = json!([
        {"p": [0.0, 0.5, 0.5], "n": [1.0, 0.0, 0.0]},
        {"p": [1.0, 0.25, 0.75], "n": [-1.0, 0.0, 0.0]},
        {"p": [0.5, 0.5, 0.5], "n": [0.0, 0.0, 1.0]}
    ]);
    let response = probe(&first, points.clone()).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let values: Value = response.json().await.unwrap();
    println!("probe values: {values}");
    let values = values.as_array().unwrap();
    assert_eq!(values.len(), 3);
    let l = |i: usize| -> Vec<f64> {
        values[i]["L"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    // The lamp (L_e = 1) shows its emission plus what it reflects; the opposite wall only light.
    assert!(
        l(0).iter().all(|v| *v >= 1.0 && v.is_finite()),
        "{values:?}"
    );
    assert!(l(1).iter().all(|v| *v > 0.0 && *v < 1.0), "{values:?}");
    assert!(values[0]["face"].is_u64() && values[1]["face"].is_u64());
    assert_ne!(values[0]["face"], values[1]["face"]);
    assert!(values[2]["L"].is_null() && values[2]["error"].is_string());

    for bad in [
        json!({"p": [0, 0, 0]}),
        json!([{"p": [0, 0, 0], "n": [0, 0, 0]}]),
    ] {
        let response = probe(&first, bad).await.unwrap();
        assert_eq!(
            error_of(response, StatusCode::BAD_REQUEST).await["code"],
            "bad_probes"
        );
    }
    let four = json!([points[0], points[1], points[2], points[0]]);
    let response = probe(&first, four).await.unwrap();
    let error = error_of(response, StatusCode::BAD_REQUEST).await;
    assert_eq!(error["code"], "too_many_probes");
    assert!(error["message"].as_str().unwrap().contains("--max-probes"));
    let response = probe("0000000000000000", points.clone()).await.unwrap();
    error_of(response, StatusCode::NOT_FOUND).await;

    // A running job has no solution to probe yet.
    let busy = submit_ok(
        &client,
        &base,
        "order=1&target_unshot=1e-9&max_seconds=20",
        never_converging_scene(),
    )
    .await;
    let busy = busy["id"].as_str().unwrap().to_string();
    let response = probe(&busy, points.clone()).await.unwrap();
    assert_eq!(
        error_of(response, StatusCode::CONFLICT).await["code"],
        "job_not_succeeded"
    );
    let response = client
        .delete(format!("{base}/v1/jobs/{busy}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    wait_for(&client, &base, &busy, "cancelled", Duration::from_secs(10)).await;

    // With --probe-cache-jobs 1, the next succeeded job's solution replaces the first's.
    let second = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let second = second["id"].as_str().unwrap().to_string();
    wait_for(
        &client,
        &base,
        &second,
        "succeeded",
        Duration::from_secs(60),
    )
    .await;
    let response = probe(&second, points.clone()).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    // The first job's solution is no longer in memory: it is loaded from its solution.bin.
    let solution_file = dir.join("jobs").join(&first).join("solution.bin");
    assert!(solution_file.is_file());
    let response = probe(&first, points.clone()).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let reloaded: Value = response.json().await.unwrap();
    assert_eq!(
        reloaded.as_array().unwrap(),
        values,
        "same values from disk"
    );

    // A job finished by an older version (no solution.bin), or a damaged file: 409, what to do.
    let response = probe(&second, points.clone()).await.unwrap(); // evicts the first again
    assert_eq!(response.status(), StatusCode::OK);
    let saved = std::fs::read(&solution_file).unwrap();
    std::fs::remove_file(&solution_file).unwrap();
    let response = probe(&first, points.clone()).await.unwrap();
    let error = error_of(response, StatusCode::CONFLICT).await;
    assert_eq!(error["code"], "solution_unavailable");
    let message = error["message"].as_str().unwrap();
    assert!(message.contains("older version"), "{message}");
    assert!(message.contains("submit the scene again"), "{message}");
    for damaged in [
        saved[..saved.len() / 2].to_vec(),
        b"not a solution".to_vec(),
    ] {
        std::fs::write(&solution_file, damaged).unwrap();
        let response = probe(&first, points.clone()).await.unwrap();
        let error = error_of(response, StatusCode::CONFLICT).await;
        assert_eq!(error["code"], "solution_unavailable");
        let message = error["message"].as_str().unwrap();
        assert!(message.contains("cannot be used"), "{message}");
    }
    std::fs::write(&solution_file, &saved).unwrap();
    let response = probe(&first, points).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
}

/// `GET /` is the dashboard: a self-contained HTML page that reads `GET /v1/jobs`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_page_is_served() {
    let base = start(ServiceConfig::new(data_dir("dashboard"))).await;
    let response = client().get(format!("{base}/")).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/html"));
    assert!(response.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .contains("connect-src 'self'"));
    let page = response.text().await.unwrap();
    assert!(page.starts_with("<!doctype html>"));
    assert!(page.contains("fetch(\"/v1/jobs\""), "it polls the job list");
    assert!(
        !page.contains("innerHTML"),
        "server data is inserted as text only"
    );
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "no external resources"
    );
}

/// Over HTTP a texture's image is a named part of a multipart upload (never a file of the
/// server's): the job solves with it; a missing part, an image that cannot be decoded and glTF 1.0
/// are 422s that name what to fix.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_carries_its_images_as_named_parts() {
    let base = start(ServiceConfig::new(data_dir("textures"))).await;
    let client = client();
    let upload = |parts: &[(&str, &[u8])]| {
        let parts: Vec<(&str, &str, &str, &[u8])> = parts
            .iter()
            .map(|&(name, bytes)| (name, name, "application/octet-stream", bytes))
            .collect();
        multipart(&parts)
    };
    let (gltf, bin, png) = common::glowing_quad_gltf("2.0");
    let (content_type, body) = upload(&[("scene", &gltf), ("scene.bin", &bin), ("glow.png", &png)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    let result = get_ok(&client, format!("{base}/v1/jobs/{id}/result")).await;
    let mean = result["faces"][0]["mean_radiance"][0].as_f64().unwrap();
    let glow = common::glow();
    assert!(
        (mean - glow).abs() < 1e-6,
        "emission {mean}, texture {glow}"
    );

    let (old, _, _) = common::glowing_quad_gltf("1.0");
    let not_png: &[u8] = b"GIF89a, not a PNG";
    // (parts, what the message names)
    type Refusal<'a> = (Vec<(&'a str, &'a [u8])>, &'a str);
    let refusals: [Refusal; 3] = [
        (vec![("scene", &gltf), ("scene.bin", &bin)], "glow.png"),
        (
            vec![("scene", &gltf), ("scene.bin", &bin), ("glow.png", not_png)],
            "image 0",
        ),
        (
            vec![("scene", &old), ("scene.bin", &bin), ("glow.png", &png)],
            "asset.version",
        ),
    ];
    for (parts, needle) in refusals {
        let (content_type, body) = upload(&parts);
        let response = submit(&client, &base, "order=1", &content_type, body).await;
        let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
        let message = error["message"].as_str().unwrap_or_default();
        assert!(message.contains(needle), "{needle}: {error}");
    }
}
