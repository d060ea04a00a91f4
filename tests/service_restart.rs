//! Durability over real process restarts: the `wavrad serve` binary is started on port 0, killed
//! abruptly (SIGKILL) or stopped (SIGTERM), and started again on the same data directory.

use reqwest::StatusCode;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::scenes::{box_scene, never_converging_scene};
use common::service::{
    client, data_dir, expect_error, get, get_bytes, get_job, job_id, list_jobs, probe_ok,
    submit_ok, submit_ok_keyed, wait_for, wait_until,
};

/// A running `wavrad serve` process and its base URL.
struct Service {
    child: Child,
    base: String,
}

impl Service {
    /// Starts the binary on 127.0.0.1 port 0 and reads the bound address from its first stdout
    /// line (`{"listening": "127.0.0.1:PORT"}`).
    fn start(data: &Path, extra: &[&str]) -> Service {
        Self::start_logging(data, extra, "warn", Stdio::inherit())
    }

    fn start_logging(data: &Path, extra: &[&str], level: &str, stderr: Stdio) -> Service {
        let mut child = Command::new(env!("CARGO_BIN_EXE_wavrad"))
            .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
            .arg(data)
            .args(extra)
            .env("RUST_LOG", level)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .expect("wavrad serve starts");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        BufReader::new(stdout).read_line(&mut line).unwrap();
        let v: Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"));
        let base = format!("http://{}", v["listening"].as_str().unwrap());
        Service { child, base }
    }

    fn kill(mut self) {
        self.child.kill().unwrap(); // SIGKILL: no chance to clean up
        self.child.wait().unwrap();
    }

    /// SIGTERM, then waits for the process to exit; returns how long it took.
    fn terminate(mut self) -> Duration {
        let t = Instant::now();
        // SAFETY: kill(2) with the pid of our own child.
        let rc = unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
        assert_eq!(rc, 0);
        let status = self.child.wait().unwrap();
        assert!(status.success(), "clean exit after SIGTERM: {status}");
        t.elapsed()
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_survives_a_kill_mid_solve_and_finishes_after_restart() {
    let data = data_dir("restart-kill");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();

    // A solve that cannot converge (rho = 1) and stops on its 3 s budget.
    let long = job_id(
        &submit_ok(
            &client,
            &base,
            "order=1&target_unshot=1e-9&max_seconds=3",
            never_converging_scene(),
        )
        .await,
    );
    // A second job waits behind it; its scene will be lost while the server is down.
    let orphan = job_id(&submit_ok(&client, &base, "order=1", box_scene(0.5, 1)).await);
    let running = wait_until(&client, &base, &long, Duration::from_secs(20), |j| {
        j["state"] == "running" && j["progress"]["iterations"].as_u64().unwrap() > 0
    })
    .await;
    assert_eq!(running["state"], "running");
    service.kill();

    // While the server is down: the queued job's scene disappears, and a submission that was
    // never committed (no state.json) is left behind.
    let jobs = data.join("jobs");
    std::fs::remove_file(jobs.join(&orphan).join("input.glb")).unwrap();
    let uncommitted = jobs.join("00000000001abcde");
    std::fs::create_dir(&uncommitted).unwrap();

    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let again = get_job(&client, &base, &long).await;
    assert!(
        again["state"] == "queued" || again["state"] == "running",
        "the interrupted job is queued again: {again}"
    );
    let lost = get_job(&client, &base, &orphan).await;
    assert_eq!(lost["state"], "failed", "{lost}");
    assert_eq!(lost["error"]["code"], "unreadable_job");
    assert!(lost["error"]["message"]
        .as_str()
        .unwrap()
        .contains("scene is missing"));
    assert!(!uncommitted.exists(), "uncommitted submission removed");

    let done = wait_until(&client, &base, &long, Duration::from_secs(60), |j| {
        j["state"] != "queued" && j["state"] != "running"
    })
    .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["stop_reason"], "time_budget");
    let result: Value =
        serde_json::from_slice(&get_bytes(&client, format!("{base}/v1/jobs/{long}/result")).await)
            .unwrap();
    assert!(result["stats"]["iterations"].as_u64().unwrap() > 0);
    drop(service);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn finished_results_survive_a_restart() {
    let data = data_dir("restart-finished");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let query = "order=1&name=box%20scene.glb";
    let id = job_id(&submit_ok_keyed(&client, &base, query, box_scene(0.5, 1), "k-1").await);
    let before = wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
    assert_eq!(before["name"], "box scene.glb");
    let result = get_bytes(&client, format!("{base}/v1/jobs/{id}/result")).await;
    let exr = get_bytes(&client, format!("{base}/v1/jobs/{id}/lightmap.exr")).await;
    service.kill();

    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let after = get_job(&client, &base, &id).await;
    assert_eq!(after, before, "the job is listed as it was (its name too)");
    assert_eq!(
        get_bytes(&client, format!("{base}/v1/jobs/{id}/result")).await,
        result
    );
    assert_eq!(
        get_bytes(&client, format!("{base}/v1/jobs/{id}/lightmap.exr")).await,
        exr
    );
    let list = list_jobs(&client, &base).await;
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1);
    // The idempotency key survived too: a retry gets the same job.
    let retried =
        job_id(&submit_ok_keyed(&client, &base, "order=1", box_scene(0.5, 1), "k-1").await);
    assert_eq!(retried, id);
    // So did the request it was made by: the key with another scene is refused.
    let reused = client
        .post(format!("{base}/v1/jobs?order=1"))
        .header("content-type", "model/gltf-binary")
        .header("idempotency-key", "k-1")
        .body(box_scene(0.7, 1))
        .send()
        .await
        .unwrap();
    expect_error(
        reused,
        StatusCode::UNPROCESSABLE_ENTITY,
        "idempotency_key_reused",
    )
    .await;
    drop(service);
}

/// A second `wavrad serve` on a data directory another one holds refuses to start: it exits
/// nonzero (2) naming the holder's pid and when it started, and touches nothing; after a kill -9
/// of the holder (the OS drops its lock, no stale lock file counts) a new server starts there.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_server_on_one_data_dir_refuses_to_start() {
    let data = data_dir("restart-lock");
    let client = client();
    let first = Service::start(&data, &[]);
    let pid = first.child.id();
    let id = job_id(&submit_ok(&client, &first.base, "order=1", box_scene(0.5, 1)).await);
    let second = Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(&data)
        .env("RUST_LOG", "warn")
        .output()
        .expect("wavrad serve runs");
    assert_eq!(second.status.code(), Some(2), "{second:?}");
    assert!(second.stdout.is_empty(), "it never listened: {second:?}");
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(
        stderr.contains(&format!("process {pid} (started 20")),
        "{stderr}"
    );
    assert!(stderr.contains("--data-dir"), "{stderr}");
    // The first server is unharmed.
    get_job(&client, &first.base, &id).await;

    first.kill();
    assert!(
        data.join("wavrad.lock").is_file(),
        "the file stays; its lock does not"
    );
    let again = Service::start(&data, &[]);
    let job = get_job(&client, &again.base, &id).await;
    assert_eq!(job["id"], id.as_str());
    drop(again);
}

/// SIGTERM: the server stops accepting, the running job stops at its next check and is persisted
/// as queued, the process exits 0; the next start runs the job to its end.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_requeues_the_running_job() {
    let data = data_dir("restart-sigterm");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let id = job_id(
        &submit_ok(
            &client,
            &base,
            "order=1&target_unshot=1e-9&max_seconds=3",
            never_converging_scene(),
        )
        .await,
    );
    wait_for(&client, &base, &id, "running", Duration::from_secs(20)).await;
    let took = service.terminate();
    assert!(took < Duration::from_secs(2), "shutdown took {took:?}");
    let record: Value = serde_json::from_slice(
        &std::fs::read(data.join("jobs").join(&id).join("state.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(record["state"], "queued", "{record}");

    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let done = wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
    assert_eq!(done["stop_reason"], "time_budget");
    drop(service);
}

/// `--log-format json`: every log line is a JSON object; what a request handler logs carries a
/// `request` span (method, uri), what a solve logs a `job` span with the job's id.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_logs_carry_request_and_job_spans() {
    let data = data_dir("restart-json-logs");
    std::fs::create_dir_all(&data).unwrap();
    let log_path = data.join("server.log");
    let log = std::fs::File::create(&log_path).unwrap();
    let client = client();
    let service = Service::start_logging(&data, &["--log-format", "json"], "info", log.into());
    let base = service.base.clone();
    let id = job_id(&submit_ok(&client, &base, "order=1", box_scene(0.5, 1)).await);
    wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
    service.terminate();
    let text = std::fs::read_to_string(&log_path).unwrap();
    let lines: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    let accepted = lines
        .iter()
        .find(|l| l["fields"]["message"] == "job accepted")
        .expect("the acceptance is logged");
    assert_eq!(accepted["span"]["name"], "request", "{accepted}");
    assert_eq!(accepted["span"]["method"], "POST");
    let solved = lines
        .iter()
        .find(|l| l["fields"]["message"] == "job finished")
        .expect("the end of the solve is logged");
    assert_eq!(solved["span"]["name"], "job", "{solved}");
    assert_eq!(solved["span"]["id"], id.as_str());
}

/// `--retain-jobs N` also applies at start: a restart with a smaller N deletes the oldest finished
/// jobs, files and all, and keeps the newest.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn retain_jobs_applies_at_start() {
    let data = data_dir("restart-retain");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let mut ids = Vec::new();
    for _ in 0..3 {
        let id = job_id(&submit_ok(&client, &base, "order=1", box_scene(0.5, 1)).await);
        wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
        ids.push(id);
    }
    service.kill();

    let service = Service::start(&data, &["--retain-jobs", "1"]);
    let base = service.base.clone();
    for old in &ids[..2] {
        let r = get(&client, format!("{base}/v1/jobs/{old}")).await;
        expect_error(r, StatusCode::NOT_FOUND, "job_not_found").await;
        assert!(
            !data.join("jobs").join(old).exists(),
            "{old}'s files deleted"
        );
    }
    let kept = get_job(&client, &base, &ids[2]).await;
    assert_eq!(kept["state"], "succeeded");
    assert!(data
        .join("jobs")
        .join(&ids[2])
        .join("result.json")
        .is_file());
    drop(service);
}

/// Probes are part of a succeeded job's results: after a restart (SIGKILL), `POST
/// /v1/jobs/{id}/probes` answers from the job's saved `solution.bin` with the values it gave
/// before, for a job solved in either domain mode.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probes_answer_the_same_after_a_restart() {
    let data = data_dir("restart-probes");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let points = json!([
        {"p": [0.5, 1.0, 0.5], "n": [0.0, -1.0, 0.0]},
        {"p": [0.3, 0.0, 0.7], "n": [0.0, 1.0, 0.0]},
        {"p": [0.0, 0.2, 0.9], "n": [1.0, 0.0, 0.0]},
        {"p": [0.5, 0.5, 0.5], "n": [0.0, 0.0, 1.0]}
    ]);
    let mut before = Vec::new();
    for query in [
        "order=2",
        "order=3&domain=tessellated&quantity=irradiance&indirect_only=true",
    ] {
        let id = job_id(&submit_ok(&client, &base, query, box_scene(0.5, 2)).await);
        wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
        assert!(data.join("jobs").join(&id).join("solution.bin").is_file());
        let values = probe_ok(&client, &base, &id, &points).await;
        assert!(values[0]["L"][0].as_f64().unwrap() > 0.0, "{values}");
        assert!(values[3]["L"].is_null());
        before.push((id, values));
    }
    service.kill();

    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    for (id, values) in &before {
        let after = probe_ok(&client, &base, id, &points).await;
        assert_eq!(
            &after, values,
            "job {id}: the same values after the restart"
        );
    }
    drop(service);
}

/// A job directory written by the version before the baked scene (the upload stored as
/// `scene.glb`, no `input.*`), built by hand from a finished job's files: after a start it still
/// answers its result, lightmap and probes, and its `scene.glb` route answers 404
/// `file_not_found` saying it predates baking, never the upload.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_directory_from_before_baking_still_answers() {
    let data = data_dir("restart-legacy");
    let client = client();
    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    let id = job_id(&submit_ok(&client, &base, "order=1", box_scene(0.5, 2)).await);
    wait_for(&client, &base, &id, "succeeded", Duration::from_secs(60)).await;
    let baked = get(&client, format!("{base}/v1/jobs/{id}/scene.glb")).await;
    assert_eq!(baked.status(), StatusCode::OK);
    assert_eq!(baked.headers()["content-type"], "model/gltf-binary");
    let points = json!([{"p": [0.5, 1.0, 0.5], "n": [0.0, -1.0, 0.0]}]);
    let values = probe_ok(&client, &base, &id, &points).await;
    let result = get_bytes(&client, format!("{base}/v1/jobs/{id}/result")).await;
    service.kill();

    // The old layout: the upload under the name the baked scene has now, no input.glb.
    let dir = data.join("jobs").join(&id);
    let upload = std::fs::read(dir.join("input.glb")).unwrap();
    std::fs::remove_file(dir.join("input.glb")).unwrap();
    std::fs::write(dir.join("scene.glb"), &upload).unwrap();

    let service = Service::start(&data, &[]);
    let base = service.base.clone();
    assert_eq!(get_job(&client, &base, &id).await["state"], "succeeded");
    assert_eq!(
        get_bytes(&client, format!("{base}/v1/jobs/{id}/result")).await,
        result
    );
    let exr = get(&client, format!("{base}/v1/jobs/{id}/lightmap.exr")).await;
    assert_eq!(exr.status(), StatusCode::OK);
    assert_eq!(probe_ok(&client, &base, &id, &points).await, values);
    let old = expect_error(
        get(&client, format!("{base}/v1/jobs/{id}/scene.glb")).await,
        StatusCode::NOT_FOUND,
        "file_not_found",
    )
    .await;
    let message = old["message"].as_str().unwrap();
    assert!(message.contains("predates baking"), "{message}");
    // The upload is still where the old version put it, untouched.
    assert_eq!(std::fs::read(dir.join("scene.glb")).unwrap(), upload);
    drop(service);
}
