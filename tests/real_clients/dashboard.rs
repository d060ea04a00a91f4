//! The dashboard in headless Chromium (npm `playwright-core`, Debian's `chromium`).
//!
//! `tests/js/dashboard.mjs` drives the page of a server started here with `--api-token`: it types
//! the token, uploads the Cornell box (.gltf with its .bin) through the form, watches it run and
//! converge, downloads its outputs through the page, uploads a never-converging box and cancels it
//! from the page, uploads it again with a one-second time budget, and loads the page at a phone's
//! width. It prints one JSON report, asserted on here and checked against the API.

use crate::common::clients;
use crate::common::scenes::never_converging_scene;
use crate::common::service::{client, data_dir, start};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;
use wavrad::service::ServiceConfig;

const TEST: &str = "the_dashboard_uploads_watches_cancels_and_downloads_in_chromium";
const TOKEN: &str = "dashboard-test-token";

/// The report of `dashboard.mjs`.
async fn run_script(node: &Path, chromium: &Path, base: &str, work: &Path, slow: &Path) -> Value {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box");
    let mut command = tokio::process::Command::new(node);
    command
        .arg(clients::js_dir().join("dashboard.mjs"))
        .current_dir(clients::js_dir())
        .env("WAVRAD_BASE", base)
        .env("WAVRAD_TOKEN", TOKEN)
        .env("WAVRAD_CHROMIUM", chromium)
        .env("SCENE_GLTF", scenes.join("cornell_box.gltf"))
        .env("SCENE_BIN", scenes.join("cornell_box.bin"))
        .env("SLOW_GLB", slow)
        .env("OUT_DIR", work)
        .kill_on_drop(true);
    let output = tokio::time::timeout(Duration::from_secs(600), command.output())
        .await
        .expect("dashboard.mjs ends within 10 minutes")
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    eprintln!("dashboard.mjs stderr:\n{stderr}");
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .unwrap_or_else(|| panic!("dashboard.mjs printed no report: {stdout}"));
    let report: Value = serde_json::from_str(line).expect("the report is JSON");
    println!("{}", serde_json::to_string_pretty(&report).unwrap());
    assert!(
        output.status.success() && report["error"].is_null(),
        "dashboard.mjs failed: {report}"
    );
    report
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_uploads_watches_cancels_and_downloads_in_chromium() {
    let Some(node) = clients::node() else {
        return clients::skip(TEST, "node is not on the PATH");
    };
    if clients::npm_package("playwright-core").is_none() {
        return clients::skip(TEST, "npm playwright-core is not installed in tests/js");
    }
    let Some(chromium) = clients::chromium() else {
        return clients::skip(TEST, "chromium is not installed");
    };
    let mut config = ServiceConfig::new(data_dir("dashboard-chromium"));
    config.api_token = Some(TOKEN.into());
    let base = start(config).await;
    let work = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("dashboard-chromium-files");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).unwrap();
    let slow = work.join("white_box.glb");
    std::fs::write(&slow, never_converging_scene()).unwrap();

    let report = run_script(&node, &chromium, &base, &work, &slow).await;

    assert_eq!(
        report["page_errors"],
        serde_json::json!([]),
        "no script error on the page"
    );
    // Without the token the page says what the server needs; the refused upload's 4xx message is
    // shown as the server wrote it.
    let without = report["without_token"].as_str().unwrap();
    assert!(without.starts_with("401"), "{without}");
    let refused = report["refused_upload"].as_str().unwrap();
    assert!(
        refused.starts_with("refused: 422 ") && refused.len() > 30,
        "the refusal's status and message are shown: {refused}"
    );

    // The Cornell box: its name, progress seen while it ran, then "converged".
    let first = &report["first"];
    assert_eq!(first["name"], "cornell_box.gltf");
    let seen = first["running_seen"].as_array().unwrap();
    assert!(
        seen.iter()
            .any(|s| s["progress"].as_str().unwrap().contains("unshot")),
        "the page showed the job's progress while it ran: {first}"
    );
    assert_eq!(first["final"]["badge"], "converged");
    assert_eq!(first["final"]["stop_reason"], "converged");

    // Downloads through the page carry the token: every file arrives, none is a 401.
    let downloads = report["downloads"].as_array().unwrap();
    for file in [
        "result",
        "lightmap.exr",
        "preview.png",
        "atlas.png",
        "scene.glb",
    ] {
        let d = downloads
            .iter()
            .find(|d| d["file"] == file)
            .unwrap_or_else(|| panic!("{file} downloaded: {downloads:?}"));
        assert!(d["bytes"].as_u64().unwrap() > 100, "{d}");
        assert_eq!(d["magic_ok"], true, "{d}");
        assert!(d["error"].is_null(), "{d}");
    }

    // The second job is cancelled from the page; the third stops on its time budget and shows
    // so, apart from "converged".
    let cancelled = &report["cancelled"];
    assert_eq!(cancelled["seen_running"], true, "{cancelled}");
    assert_eq!(cancelled["final"]["state"], "cancelled");
    let budget = &report["time_budget"];
    assert_eq!(budget["final"]["stop_reason"], "time_budget");
    let badge = budget["final"]["badge"].as_str().unwrap();
    assert!(badge.contains("time budget"), "{badge}");
    assert_ne!(
        budget["final"]["badge_color"], first["final"]["badge_color"],
        "a time budget looks different from convergence"
    );

    // A phone: no horizontal scrolling, the outputs of the converged job on screen.
    let phone = &report["phone"];
    assert!(
        phone["scroll_width"].as_f64().unwrap() <= phone["client_width"].as_f64().unwrap(),
        "{phone}"
    );
    assert_eq!(phone["client_width"], 390, "{phone}");
    assert_eq!(phone["outputs_visible"], true, "{phone}");
    assert_eq!(phone["outputs_inside"], true, "{phone}");

    // The API agrees with what the page showed.
    let client = client();
    let list: Value = client
        .get(format!("{base}/v1/jobs"))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let jobs = list["jobs"].as_array().unwrap();
    let job = |id: &Value| {
        jobs.iter()
            .find(|j| &j["id"] == id)
            .unwrap_or_else(|| panic!("job {id} listed"))
    };
    let j = job(&first["id"]);
    assert_eq!(j["name"], "cornell_box.gltf");
    assert_eq!(j["stop_reason"], "converged");
    assert_eq!(job(&cancelled["id"])["state"], "cancelled");
    let j = job(&budget["id"]);
    assert_eq!(j["name"], "white_box.glb");
    assert_eq!(j["state"], "succeeded");
    assert_eq!(j["stop_reason"], "time_budget");
    for shot in ["desktop", "phone"] {
        let path = work.join(format!("dashboard-{shot}.png"));
        assert!(
            std::fs::metadata(&path).is_ok_and(|m| m.len() > 1000),
            "{}",
            path.display()
        );
    }
}
