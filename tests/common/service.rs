//! Talking to the HTTP job service the way its tests do: a fresh data directory, an in-process
//! server on 127.0.0.1 port 0, a client, submitting and polling jobs, reading results and probes,
//! multipart bodies, and the checks of the error JSON of docs/contract.md
//! `{"error": {"code": "snake_case", "message": "..."}}` (`error_of`, `expect_error`, and
//! `expect_raw_error` for requests written by hand on a socket).
//!
//! Every helper that expects success asserts the status it expects; only the `wait_*` helpers poll.

use reqwest::{Client, Response, StatusCode};
use serde_json::Value;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wavrad::service::{Server, ServiceConfig};

/// A fresh, empty data directory for one test, `name` unique among all tests.
pub fn data_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Starts a server on 127.0.0.1 port 0 in this process; returns its base URL.
pub async fn start(config: ServiceConfig) -> String {
    let server = Server::bind(config, "127.0.0.1:0".parse().unwrap())
        .await
        .expect("server binds");
    let base = format!("http://{}", server.local_addr());
    tokio::spawn(server.run_until(std::future::pending()));
    base
}

/// A client whose requests give up after 30 s.
pub fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap()
}

/// `POST /v1/jobs?{query}` with `body` as `content_type`; any answer.
pub async fn submit(
    client: &Client,
    base: &str,
    query: &str,
    content_type: &str,
    body: Vec<u8>,
) -> Response {
    client
        .post(format!("{base}/v1/jobs?{query}"))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .expect("POST /v1/jobs answers")
}

/// Submits a GLB and expects 202 with a `Location` naming the job; returns the job document.
pub async fn submit_ok(client: &Client, base: &str, query: &str, glb: Vec<u8>) -> Value {
    submit_glb(client, base, query, glb, None).await
}

/// `submit_ok` with an `Idempotency-Key` header.
pub async fn submit_ok_keyed(
    client: &Client,
    base: &str,
    query: &str,
    glb: Vec<u8>,
    key: &str,
) -> Value {
    submit_glb(client, base, query, glb, Some(key)).await
}

async fn submit_glb(
    client: &Client,
    base: &str,
    query: &str,
    glb: Vec<u8>,
    key: Option<&str>,
) -> Value {
    let mut request = client
        .post(format!("{base}/v1/jobs?{query}"))
        .header("content-type", "model/gltf-binary");
    if let Some(key) = key {
        request = request.header("idempotency-key", key);
    }
    let response = request
        .body(glb)
        .send()
        .await
        .expect("POST /v1/jobs answers");
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let location = response
        .headers()
        .get("location")
        .expect("Location header")
        .to_str()
        .unwrap()
        .to_string();
    let job: Value = response.json().await.unwrap();
    assert_eq!(location, format!("/v1/jobs/{}", job_id(&job)));
    job
}

/// The `id` of a job document.
pub fn job_id(job: &Value) -> String {
    job["id"].as_str().expect("the job has an id").to_string()
}

/// GETs `url`; any answer.
pub async fn get(client: &Client, url: String) -> Response {
    client.get(url).send().await.unwrap()
}

/// GETs `url`, expects 200 and returns the JSON body.
pub async fn get_ok(client: &Client, url: String) -> Value {
    let response = client.get(&url).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK, "GET {url}");
    response.json().await.unwrap()
}

/// GETs `url`, expects 200 and returns the body's bytes.
pub async fn get_bytes(client: &Client, url: String) -> Vec<u8> {
    let response = client.get(&url).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK, "GET {url}");
    response.bytes().await.unwrap().to_vec()
}

/// `GET /v1/jobs/{id}`: the job document (200 expected).
pub async fn get_job(client: &Client, base: &str, id: &str) -> Value {
    get_ok(client, format!("{base}/v1/jobs/{id}")).await
}

/// `GET /v1/jobs`: the job list (200 expected).
pub async fn list_jobs(client: &Client, base: &str) -> Value {
    get_ok(client, format!("{base}/v1/jobs")).await
}

/// `DELETE /v1/jobs/{id}`; any answer.
pub async fn delete_job(client: &Client, base: &str, id: &str) -> Response {
    client
        .delete(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap()
}

/// `POST /v1/jobs/{id}/probes` with `body` as JSON; any answer.
pub async fn post_probes(client: &Client, base: &str, id: &str, body: &Value) -> Response {
    client
        .post(format!("{base}/v1/jobs/{id}/probes"))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap()
}

/// `post_probes`, expecting 200; returns the values.
pub async fn probe_ok(client: &Client, base: &str, id: &str, body: &Value) -> Value {
    let response = post_probes(client, base, id, body).await;
    assert_eq!(response.status(), StatusCode::OK, "probes of {id}");
    response.json().await.unwrap()
}

/// Polls the job (every 50 ms) until `done` holds for it; panics after `timeout`.
pub async fn wait_until(
    client: &Client,
    base: &str,
    id: &str,
    timeout: Duration,
    done: impl Fn(&Value) -> bool,
) -> Value {
    let start = Instant::now();
    loop {
        let job = get_job(client, base, id).await;
        if done(&job) {
            return job;
        }
        assert!(
            start.elapsed() < timeout,
            "job {id} is {} after {timeout:?}, still not what was awaited: {job}",
            job["state"]
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Polls the job until its state is `state`; panics after `timeout`.
pub async fn wait_for(
    client: &Client,
    base: &str,
    id: &str,
    state: &str,
    timeout: Duration,
) -> Value {
    wait_until(client, base, id, timeout, |job| job["state"] == state).await
}

/// Checks the error shape of docs/contract.md (the status, a JSON body, a snake_case `code`, a non-empty
/// `message`) and returns the error object.
pub async fn error_of(response: Response, status: StatusCode) -> Value {
    let url = response.url().clone();
    let got = response.status();
    let is_json = response
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    let text = response.text().await.unwrap();
    assert_eq!(got, status, "{url}: {text}");
    assert!(is_json, "error responses are JSON: {url}: {text}");
    let body: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{url}: {e}: {text}"));
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

/// `error_of`, and the error's `code` is `code`; returns the error object (for its message).
pub async fn expect_error(response: Response, status: StatusCode, code: &str) -> Value {
    let url = response.url().clone();
    let error = error_of(response, status).await;
    assert_eq!(error["code"], code, "{url}: {error}");
    error
}

/// `expect_error` for a request written by hand on a raw socket: reads the answer to its end (10 s
/// at most), checks its status line and the error JSON's `code`; returns the error object.
pub async fn expect_raw_error(
    stream: &mut tokio::net::TcpStream,
    status: StatusCode,
    code: &str,
) -> Value {
    use tokio::io::AsyncReadExt;
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(10), stream.read_to_end(&mut answer))
        .await
        .expect("the server answers")
        .unwrap();
    let answer = String::from_utf8_lossy(&answer);
    assert!(
        answer.starts_with(&format!("HTTP/1.1 {}", status.as_u16())),
        "{answer}"
    );
    let body = &answer[answer.find("\r\n\r\n").unwrap() + 4..];
    let body: Value = serde_json::from_str(body).unwrap();
    assert_eq!(body["error"]["code"], code, "{answer}");
    body["error"].clone()
}

/// A `multipart/form-data` body from (name, file name, content type, bytes) parts; returns the
/// content type (with its boundary) and the body.
pub fn multipart(parts: &[(&str, &str, &str, &[u8])]) -> (String, Vec<u8>) {
    let boundary = "wavrad-test-boundary-7d1f";
    let mut body = Vec::new();
    for (name, file, content_type, bytes) in parts {
        body.extend_from_slice(
            format!(
                "--{boundary}\r\nContent-Disposition: form-data; name=\"{name}\"; \
                 filename=\"{file}\"\r\nContent-Type: {content_type}\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    (format!("multipart/form-data; boundary={boundary}"), body)
}
