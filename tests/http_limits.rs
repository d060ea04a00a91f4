//! The HTTP service over a real socket (port 0), requests it refuses: outside the contract (unknown
//! routes and jobs, wrong media types, bad parameters), over a limit (body size, memory, job
//! seconds, in-flight requests, request time), without the bearer token; and a store that cannot be
//! written. Every refusal is the error JSON of docs/contract.md and names what to change.

use reqwest::StatusCode;
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use wavrad::service::ServiceConfig;

mod common;
use common::scenes::{never_converging_scene, one_triangle_gltf, small_scene, TRIANGLE};
use common::service::{
    client, data_dir, delete_job, error_of, expect_error, expect_raw_error, get, list_jobs, start,
    submit, submit_ok, wait_for,
};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_outside_the_contract_get_error_json() {
    let mut config = ServiceConfig::new(data_dir("http-errors"));
    config.max_body_bytes = 1024;
    let base = start(config).await;
    let client = client();

    let response = get(&client, format!("{base}/v1/jobs/0123456789abcdef")).await;
    expect_error(response, StatusCode::NOT_FOUND, "job_not_found").await;
    for path in ["result", "convergence", "lightmap.exr"] {
        let response = get(&client, format!("{base}/v1/jobs/nope/{path}")).await;
        error_of(response, StatusCode::NOT_FOUND).await;
    }
    let response = delete_job(&client, &base, "nope").await;
    error_of(response, StatusCode::NOT_FOUND).await;

    let response = get(&client, format!("{base}/no/such/route")).await;
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
        "gutter=33",
        "gutter=-1",
        "atlas_max_size=1002",
        "atlas_max_size=128",
        "atlas_pow2=maybe",
    ] {
        let response = submit(&client, &base, query, "model/gltf-binary", tiny.clone()).await;
        expect_error(response, StatusCode::BAD_REQUEST, "bad_parameters").await;
    }
    let response = submit(&client, &base, "order=7", "model/gltf-binary", tiny.clone()).await;
    let error = error_of(response, StatusCode::BAD_REQUEST).await;
    assert!(error["message"].as_str().unwrap().contains("order"));
    let response = submit(
        &client,
        &base,
        "atlas_max_size=1002",
        "model/gltf-binary",
        tiny.clone(),
    )
    .await;
    let error = error_of(response, StatusCode::BAD_REQUEST).await;
    let message = error["message"].as_str().unwrap();
    assert!(
        message.contains("atlas_max_size") && message.contains("multiple of 4"),
        "{message}"
    );

    let big = small_scene(0.5);
    assert!(big.len() > 1024);
    let response = submit(&client, &base, "order=1", "model/gltf-binary", big).await;
    expect_error(response, StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large").await;

    let response = submit(&client, &base, "", "model/gltf-binary", Vec::new()).await;
    error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;

    // A buffer URI naming a file is never resolved on the server.
    let (mut root, _) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    root["buffers"][0]["uri"] = json!("/etc/passwd");
    let body = serde_json::to_vec(&root).unwrap();
    let response = submit(&client, &base, "", "model/gltf+json", body).await;
    error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;

    // Still alive and empty.
    let list = list_jobs(&client, &base).await;
    assert_eq!(list, json!({"jobs": []}));
}

/// A chunked upload has no Content-Length: the limit is enforced while reading, still as JSON 413.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_chunked_upload_is_refused() {
    use tokio::io::AsyncWriteExt;
    let mut config = ServiceConfig::new(data_dir("http-chunked"));
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
    expect_raw_error(
        &mut stream,
        StatusCode::PAYLOAD_TOO_LARGE,
        "payload_too_large",
    )
    .await;
}

/// Every limit is a named setting, and a refusal names it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn limits_are_named_settings_and_refusals_name_them() {
    let mut config = ServiceConfig::new(data_dir("http-limits"));
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
    let error = expect_error(response, StatusCode::UNPROCESSABLE_ENTITY, "memory_limit").await;
    let message = error["message"].as_str().unwrap();
    assert!(message.contains("--max-memory-bytes"), "{message}");
    assert!(message.contains("10000 bytes"), "{message}");

    let mut config = ServiceConfig::new(data_dir("http-limits-seconds"));
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

/// The rarer answers are JSON errors too: 503 when `--max-in-flight` requests are being handled,
/// 408 when a request outlives `--request-timeout-seconds`, 500 when the store cannot be written.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn busy_timeout_and_internal_errors_are_json() {
    use tokio::io::AsyncWriteExt;
    let dir = data_dir("http-rare");
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
    let busy = get(&client, format!("{base}/healthz")).await;
    assert!(busy.headers().contains_key("retry-after"));
    expect_error(busy, StatusCode::SERVICE_UNAVAILABLE, "server_busy").await;

    expect_raw_error(&mut slow, StatusCode::REQUEST_TIMEOUT, "request_timeout").await;

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
    let error = expect_error(
        response,
        StatusCode::INTERNAL_SERVER_ERROR,
        "internal_error",
    )
    .await;
    assert!(error["message"].as_str().unwrap().contains("server log"));
    let health = get(&client, format!("{base}/healthz")).await;
    assert_eq!(health.status(), StatusCode::OK);
}

/// With a token every /v1 route needs it (every operation of the route table, each method, plus
/// an unknown /v1 path); /healthz and /metrics stay open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bearer_token_guards_every_v1_route() {
    let mut config = ServiceConfig::new(data_dir("http-auth"));
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
        let error = expect_error(response, StatusCode::UNAUTHORIZED, "unauthorized").await;
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
        let r = get(&client, format!("{base}{open}")).await;
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
