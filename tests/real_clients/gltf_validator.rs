//! The Khronos glTF-Validator (npm `gltf-validator`) on `scene.glb` written by wavrad.
//!
//! Every sample scene (`scenes/`, `tests/data/` less `malformed/`) and, when `../shared/scenes`
//! exists, every `*_lit.glb` there up to `MAX_TRIANGLES` triangles is solved by `wavrad solve`
//! with a short time budget (convergence is not the point: the file's structure is), and the
//! validator (run by `tests/js/validate_gltf.mjs`) must report no error on its `scene.glb`.

use crate::common::cli::wavrad;
use crate::common::clients::{js_dir, node, npm_package, skip};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use wavrad::scene::{load_scene_from_path, scene_files};

/// Larger shared scenes are left out (their solve alone takes minutes in a debug build).
const MAX_TRIANGLES: usize = 10_000;

fn scenes() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = scene_files(&root.join("scenes"));
    files.extend(
        scene_files(&root.join("tests/data"))
            .into_iter()
            .filter(|p| !p.components().any(|c| c.as_os_str() == "malformed")),
    );
    files.extend(
        scene_files(&root.join("../shared/scenes"))
            .into_iter()
            .filter(|p| p.to_string_lossy().ends_with("_lit.glb")),
    );
    files
}

#[test]
fn the_khronos_validator_finds_no_error_in_any_baked_scene() {
    const TEST: &str = "the_khronos_validator_finds_no_error_in_any_baked_scene";
    let Some(node) = node() else {
        return skip(TEST, "node is not on the PATH");
    };
    if npm_package("gltf-validator").is_none() {
        return skip(
            TEST,
            "the npm package gltf-validator is not installed in tests/js",
        );
    }
    let work = std::env::temp_dir().join(format!("wavrad-validator-{}", std::process::id()));
    let mut baked = Vec::new();
    for (n, scene) in scenes().iter().enumerate() {
        if let Err(e) = load_scene_from_path(scene, MAX_TRIANGLES) {
            println!("{}: not baked ({e})", scene.display());
            continue;
        }
        let out = work.join(format!("{n}"));
        let run = wavrad(&[
            "solve",
            &scene.to_string_lossy(),
            "--out",
            &out.to_string_lossy(),
            "--max-seconds",
            "2",
        ]);
        if run.status.code() == Some(2) {
            // Nothing to solve (no emitter): no outputs.
            println!("{}: not solvable, skipped", scene.display());
            continue;
        }
        assert!(
            run.status.success(),
            "{}: {}",
            scene.display(),
            String::from_utf8_lossy(&run.stderr)
        );
        let glb = out.join("scene.glb");
        assert!(glb.is_file(), "{}: no scene.glb", scene.display());
        baked.push((scene.clone(), glb));
    }
    assert!(baked.len() >= 2, "the sample scenes were baked");
    let output = Command::new(node)
        .current_dir(js_dir())
        .arg("validate_gltf.mjs")
        .args(baked.iter().map(|(_, glb)| glb))
        .output()
        .expect("node runs");
    assert!(
        output.status.success(),
        "the validator failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let reports: Vec<Value> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON report per line"))
        .collect();
    assert_eq!(reports.len(), baked.len());
    let mut failed = Vec::new();
    for ((scene, _), report) in baked.iter().zip(&reports) {
        println!(
            "{}: {} error(s), {} warning(s), {} info(s)",
            scene.display(),
            report["errors"],
            report["warnings"],
            report["infos"]
        );
        if report["errors"].as_u64() != Some(0) {
            failed.push(format!("{}: {}", scene.display(), report["messages"]));
        }
    }
    let _ = std::fs::remove_dir_all(&work);
    assert!(
        failed.is_empty(),
        "validator errors:\n{}",
        failed.join("\n")
    );
}
