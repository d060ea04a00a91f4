//! The HTTP service over a real socket (port 0), what clients read besides the job document:
//! progress (ETA, server-sent events), probes of a succeeded job's solution, Prometheus metrics,
//! the OpenAPI document (exactly the router's routes) and the dashboard page.

use reqwest::StatusCode;
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use wavrad::service::ServiceConfig;

mod common;
use common::scenes::{cluttered_scene, long_first_shot, never_converging_scene, small_scene};
use common::service::{
    client, data_dir, delete_job, error_of, expect_error, get, get_job, job_id, post_probes,
    probe_ok, start, submit_ok, wait_for,
};

/// The OpenAPI document served at /v1/openapi.json describes exactly the routes of the router:
/// every (path, method) of the route table is documented, every documented operation is in the
/// table, and the live router answers each documented operation (not with the route fallback).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_describes_exactly_the_routes() {
    use std::collections::BTreeSet;
    let base = start(ServiceConfig::new(data_dir("http-openapi"))).await;
    let client = client();
    let response = get(&client, format!("{base}/v1/openapi.json")).await;
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

/// While a converging solve runs, its progress carries an ETA fitted on the unshot decay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_running_job_reports_an_eta() {
    let base = start(ServiceConfig::new(data_dir("http-eta"))).await;
    let client = client();
    let job = submit_ok(
        &client,
        &base,
        // The time budget bounds the job on a loaded machine; it stops `succeeded` either way.
        "order=1&target_unshot=1e-3&max_seconds=90",
        cluttered_scene(5),
    )
    .await;
    let id = job_id(&job);
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
        assert!(start.elapsed() < Duration::from_secs(300));
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let (eta, progress) = seen.expect("an ETA while running");
    println!("eta {eta} s at {progress}");
    assert!(eta.is_finite() && eta >= 0.0);
    let done = wait_for(&client, &base, &id, "succeeded", Duration::from_secs(300)).await;
    println!("finished at {}", done["progress"]);
    assert!(done["progress"]["eta_seconds"].is_null() || done["progress"]["eta_seconds"] == 0.0);
}

/// A solve whose first shot lasts seconds: its progress object moves within the shot (receivers
/// done increasing while no shot has finished), with an ETA, both when polled and on the event
/// stream, whose in-shot events come at most about twice a second; then the job is cancelled.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_progress_object_moves_within_a_long_shot() {
    let base = start(ServiceConfig::new(data_dir("http-progress-in-shot"))).await;
    let client = client();
    // `tests/progress.rs` solves the same scene with the same parameters.
    let job = submit_ok(&client, &base, "order=1&tolerance=3e-8", long_first_shot()).await;
    let id = job_id(&job);
    let mut stream = get(&client, format!("{base}/v1/jobs/{id}/events")).await;
    assert_eq!(stream.status(), StatusCode::OK);
    let start = Instant::now();
    let mut text = String::new();
    let mut within: Vec<Value> = Vec::new();
    let mut polled = None;
    while within.len() < 3
        || within.last().unwrap()["shot_receivers_done"] == within[0]["shot_receivers_done"]
    {
        assert!(start.elapsed() < Duration::from_secs(300), "{within:?}");
        let chunk = tokio::time::timeout(Duration::from_secs(60), stream.chunk())
            .await
            .expect("the stream moves within the shot")
            .unwrap()
            .expect("the stream stays open while the job runs");
        text.push_str(&String::from_utf8_lossy(&chunk));
        while let Some(end) = text.find("\n\n") {
            let block: String = text.drain(..end + 2).collect();
            let data: String = block
                .lines()
                .filter_map(|l| l.strip_prefix("data:"))
                .map(str::trim_start)
                .collect();
            if !block.contains("event: progress") && !block.contains("event:progress") {
                continue;
            }
            let p: Value = serde_json::from_str(&data).unwrap();
            if p["shot_receivers"].as_u64().unwrap() > 0 {
                assert_eq!(p["iterations"], 0, "within the first shot: {p}");
                within.push(p);
            }
        }
        if polled.is_none() && !within.is_empty() {
            let j = get_job(&client, &base, &id).await;
            if j["progress"]["shot_receivers"].as_u64().unwrap() > 0 {
                polled = Some(j["progress"].clone());
            }
        }
    }
    println!("in-shot events: {within:?}");
    let receivers = &within[0]["shot_receivers"];
    let done: Vec<u64> = within
        .iter()
        .map(|p| p["shot_receivers_done"].as_u64().unwrap())
        .collect();
    assert!(done.windows(2).all(|w| w[0] <= w[1]), "{done:?}");
    for p in &within {
        assert_eq!(&p["shot_receivers"], receivers);
        assert!(p["eta_seconds"].as_f64().is_some_and(|e| e > 0.0), "{p}");
    }
    let seconds: Vec<f64> = within
        .iter()
        .map(|p| p["seconds"].as_f64().unwrap())
        .collect();
    assert!(
        seconds.windows(2).all(|w| w[1] - w[0] >= 0.25),
        "at most about two events a second within a shot: {seconds:?}"
    );
    let polled = polled.expect("polling shows the shot in progress too");
    assert_eq!(polled["iterations"], 0);
    assert!(polled["shot_receivers_done"].as_u64().unwrap() <= receivers.as_u64().unwrap());
    let response = delete_job(&client, &base, &id).await;
    assert!(response.status().is_success(), "{}", response.status());
    let end = wait_for(&client, &base, &id, "cancelled", Duration::from_secs(120)).await;
    assert!(end["progress"]["eta_seconds"].is_null() || end["progress"]["eta_seconds"] == 0.0);
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
    let base = start(ServiceConfig::new(data_dir("http-events"))).await;
    let client = client();
    let job = submit_ok(&client, &base, "order=1&tolerance=1e-4", cluttered_scene(3)).await;
    let id = job_id(&job);
    let response = get(&client, format!("{base}/v1/jobs/{id}/events")).await;
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

    let late = get(&client, format!("{base}/v1/jobs/{id}/events")).await;
    let events = read_events(late).await;
    let names: Vec<&str> = events.iter().map(|(e, _)| e.as_str()).collect();
    assert_eq!(names, ["progress", "done"]);
    assert_eq!(events[0].1, done["progress"]);
    let missing = get(&client, format!("{base}/v1/jobs/0000000000000000/events")).await;
    error_of(missing, StatusCode::NOT_FOUND).await;
}

/// `POST /v1/jobs/{id}/probes` evaluates a succeeded job's solution at the given points (the
/// emitting wall shows at least its own emission, a point in mid-air has no value); bad bodies
/// are 400, unfinished jobs 409. A job whose solution left memory (`--probe-cache-jobs`) is
/// answered from its `solution.bin` with the same values; without a usable one (a job from an
/// older version, a damaged file) it is a 409 that says what to do.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probes_are_evaluated_on_a_succeeded_job() {
    let dir = data_dir("http-probes");
    let mut config = ServiceConfig::new(dir.clone());
    config.probe_cache_jobs = 1;
    config.max_probes = 3;
    let base = start(config).await;
    let client = client();
    let first = submit_ok(&client, &base, "order=2", small_scene(0.5)).await;
    let first = job_id(&first);
    wait_for(&client, &base, &first, "succeeded", Duration::from_secs(60)).await;

    let points = json!([
        {"p": [0.0, 0.5, 0.5], "n": [1.0, 0.0, 0.0]},
        {"p": [1.0, 0.25, 0.75], "n": [-1.0, 0.0, 0.0]},
        {"p": [0.5, 0.5, 0.5], "n": [0.0, 0.0, 1.0]}
    ]);
    let values = probe_ok(&client, &base, &first, &points).await;
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
        let response = post_probes(&client, &base, &first, &bad).await;
        expect_error(response, StatusCode::BAD_REQUEST, "bad_probes").await;
    }
    let four = json!([points[0], points[1], points[2], points[0]]);
    let response = post_probes(&client, &base, &first, &four).await;
    let error = expect_error(response, StatusCode::BAD_REQUEST, "too_many_probes").await;
    assert!(error["message"].as_str().unwrap().contains("--max-probes"));
    let response = post_probes(&client, &base, "0000000000000000", &points).await;
    error_of(response, StatusCode::NOT_FOUND).await;

    // A running job has no solution to probe yet.
    let busy = submit_ok(
        &client,
        &base,
        "order=1&target_unshot=1e-9&max_seconds=20",
        never_converging_scene(),
    )
    .await;
    let busy = job_id(&busy);
    let response = post_probes(&client, &base, &busy, &points).await;
    expect_error(response, StatusCode::CONFLICT, "job_not_succeeded").await;
    let response = delete_job(&client, &base, &busy).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    wait_for(&client, &base, &busy, "cancelled", Duration::from_secs(10)).await;

    // With --probe-cache-jobs 1, the next succeeded job's solution replaces the first's.
    let second = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let second = job_id(&second);
    wait_for(
        &client,
        &base,
        &second,
        "succeeded",
        Duration::from_secs(60),
    )
    .await;
    let response = post_probes(&client, &base, &second, &points).await;
    assert_eq!(response.status(), StatusCode::OK);
    // The first job's solution is no longer in memory: it is loaded from its solution.bin.
    let solution_file = dir.join("jobs").join(&first).join("solution.bin");
    assert!(solution_file.is_file());
    let reloaded = probe_ok(&client, &base, &first, &points).await;
    assert_eq!(
        reloaded.as_array().unwrap(),
        values,
        "same values from disk"
    );

    // A job finished by an older version (no solution.bin), or a damaged file: 409, what to do.
    let response = post_probes(&client, &base, &second, &points).await; // evicts the first again
    assert_eq!(response.status(), StatusCode::OK);
    let saved = std::fs::read(&solution_file).unwrap();
    std::fs::remove_file(&solution_file).unwrap();
    let response = post_probes(&client, &base, &first, &points).await;
    let error = expect_error(response, StatusCode::CONFLICT, "solution_unavailable").await;
    let message = error["message"].as_str().unwrap();
    assert!(message.contains("older version"), "{message}");
    assert!(message.contains("submit the scene again"), "{message}");
    for damaged in [
        saved[..saved.len() / 2].to_vec(),
        b"not a solution".to_vec(),
    ] {
        std::fs::write(&solution_file, damaged).unwrap();
        let response = post_probes(&client, &base, &first, &points).await;
        let error = expect_error(response, StatusCode::CONFLICT, "solution_unavailable").await;
        let message = error["message"].as_str().unwrap();
        assert!(message.contains("cannot be used"), "{message}");
    }
    std::fs::write(&solution_file, &saved).unwrap();
    let response = post_probes(&client, &base, &first, &points).await;
    assert_eq!(response.status(), StatusCode::OK);
}

/// `/metrics` is Prometheus text, every series `wavrad_*`, counting what happened.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_count_jobs_and_solves() {
    let base = start(ServiceConfig::new(data_dir("http-metrics"))).await;
    let client = client();
    let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    let id = job["id"].as_str().unwrap();
    wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    // The counters are updated just after the state: poll briefly.
    let start = Instant::now();
    let text = loop {
        let r = get(&client, format!("{base}/metrics")).await;
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

/// `GET /` is the dashboard: a self-contained HTML page that reads `GET /v1/jobs`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_page_is_served() {
    let base = start(ServiceConfig::new(data_dir("http-dashboard"))).await;
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
