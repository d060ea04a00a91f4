//! The dashboard's 3-D view in headless Chromium: a finished bake of the Cornell box rendered
//! from `scene.glb` with its lightmaps only, read back at a grid of canvas pixels and compared with
//! the solution (probes) at the surface points under them.

use crate::common::clients::{self, skip};
use crate::common::service::{client, data_dir, multipart, probe_ok, start, wait_for};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;
use std::time::Duration;
use wavrad::service::ServiceConfig;

const TEST: &str = "viewer_renders_the_bake_with_lightmaps_only";

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_renders_the_bake_with_lightmaps_only() {
    let Some(node) = clients::node() else {
        return skip(TEST, "node is not on the PATH");
    };
    if clients::npm_package("playwright-core").is_none() {
        return skip(TEST, "tests/js/node_modules/playwright-core is missing");
    }
    let Some(chromium) = clients::chromium() else {
        return skip(TEST, "chromium is not installed");
    };
    let base = start(ServiceConfig::new(data_dir("real-clients-viewer"))).await;
    let client = client();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box");
    let gltf = std::fs::read(dir.join("cornell_box.gltf")).unwrap();
    let bin = std::fs::read(dir.join("cornell_box.bin")).unwrap();
    let (content_type, body) = multipart(&[
        ("scene", "cornell_box.gltf", "model/gltf+json", &gltf),
        (
            "cornell_box.bin",
            "cornell_box.bin",
            "application/octet-stream",
            &bin,
        ),
    ]);
    let response = client
        .post(format!("{base}/v1/jobs?tolerance=2e-5&target_unshot=0.01"))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 202, "{}", response.text().await.unwrap());
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    wait_for(&client, &base, &id, "succeeded", Duration::from_secs(300)).await;

    let screenshot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("viewer.png");
    let output = Command::new(node)
        .current_dir(clients::js_dir())
        .env("WAVRAD_CHROMIUM", chromium)
        .args(["viewer.mjs", &base, &id, "", screenshot.to_str().unwrap()])
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "viewer.mjs failed: {}\n{stdout}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report: Value = serde_json::from_str(stdout.lines().last().unwrap_or("")).unwrap();
    assert!(report["error"].is_null(), "the page failed: {report}");
    assert_eq!(report["errors"], json!([]), "errors in the page");
    assert!(
        report["lightmapped"].as_u64().unwrap() > 0,
        "no material carries a lightmap"
    );
    let exposure = report["exposure"].as_f64().unwrap();

    // Pixels over a surface, away from clipping, judged against the solution under them.
    let hits: Vec<&Value> = report["samples"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| !s["surface"].is_null())
        .collect();
    assert!(
        hits.len() >= 50,
        "only {} pixels over the scene",
        hits.len()
    );
    let probes: Vec<Value> = hits
        .iter()
        .map(|s| json!({"p": s["surface"]["point"], "n": s["surface"]["normal"]}))
        .collect();
    let values = probe_ok(&client, &base, &id, &json!(probes)).await;
    let mut judged = 0;
    let mut within = 0;
    let mut worst = Vec::new();
    for (sample, value) in hits.iter().zip(values.as_array().unwrap()) {
        let Some(l) = value["L"].as_array() else {
            continue;
        };
        for c in 0..3 {
            let expected = l[c].as_f64().unwrap() * exposure;
            if expected > 0.95 {
                continue; // clipped by the display
            }
            let shown = srgb_to_linear(sample["rgb"][c].as_f64().unwrap() / 255.0);
            judged += 1;
            // 5 %, with a floor for 8-bit steps in the darks.
            if (shown - expected).abs() <= 0.05 * expected + 0.002 {
                within += 1;
            } else if worst.len() < 8 {
                worst.push(format!(
                    "{:?}: shown {shown:.4} expected {expected:.4}",
                    sample["surface"]["point"]
                ));
            }
        }
    }
    assert!(judged >= 150, "only {judged} channel values judged");
    let share = within as f64 / judged as f64;
    eprintln!(
        "3-D view: {within}/{judged} channel values within 5 % of the solution ({:.1} %)",
        100.0 * share
    );
    assert!(
        share >= 0.9,
        "{within}/{judged} within 5 %; e.g. {worst:#?}"
    );
}
