//! `wavrad bench visibility` (issue 19): the occluded count of segments traced through the
//! solver's own BVH (bounding faces left out, as in a solve) equals a brute-force count over every
//! triangle of the scene, on small scenes of tests/data; `--generate` is reproducible.

use std::path::Path;
use std::process::Command;
use wavrad::bench::visibility::{brute_force_occluded, parse_segments};

mod common;
use common::scenes::cluttered_scene;

fn wavrad(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("wavrad runs")
}

/// A fresh directory for one test's files, removed when the test ends.
fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("wavrad-bench-vis-")
        .tempdir()
        .unwrap()
}

/// Generates `n` segments on `scene`, traces them with 1 and 2 threads, and compares the occluded
/// counts with the brute force; returns (occluded, segments).
fn check(scene: &Path, dir: &Path, n: usize, name: &str) -> (usize, usize) {
    let scene_arg = scene.to_str().unwrap();
    let file = dir.join(format!("{name}.json"));
    let file_arg = file.to_str().unwrap();
    let n_arg = n.to_string();
    let made = wavrad(&[
        "bench",
        "visibility",
        scene_arg,
        "--generate",
        &n_arg,
        "--out",
        file_arg,
    ]);
    assert!(made.status.success(), "{made:?}");
    let bytes = std::fs::read(&file).unwrap();
    // The same seed makes the same file.
    let again = dir.join(format!("{name}-again.json"));
    let made = wavrad(&[
        "bench",
        "visibility",
        scene_arg,
        "--generate",
        &n_arg,
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(made.status.success(), "{made:?}");
    assert_eq!(std::fs::read(&again).unwrap(), bytes, "seeded generation");
    let segments = parse_segments(&bytes).unwrap();
    assert_eq!(segments.len(), n);

    let loaded = wavrad::scene::load_scene_from_path(scene, 5_000_000).unwrap();
    let expected = brute_force_occluded(&loaded, &segments);
    for threads in ["1", "2"] {
        let run = wavrad(&[
            "bench",
            "visibility",
            scene_arg,
            "--segments",
            file_arg,
            "--threads",
            threads,
        ]);
        assert!(run.status.success(), "{run:?}");
        let line: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(line["segments"], n);
        assert_eq!(line["occluded"], expected, "{threads} thread(s): {line}");
        assert!(line["seconds"].as_f64().unwrap() >= 0.0);
        assert!(line["per_second"].as_f64().unwrap() > 0.0);
        let path = line["code_path"].as_str().unwrap_or_default();
        assert!(["x86-64-v3", "baseline"].contains(&path), "{line}");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains("BVH build"), "{stderr}");
    }
    (expected, n)
}

#[test]
fn occluded_counts_equal_a_brute_force_count_over_every_triangle() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let tmp = scratch();
    let dir = tmp.path();
    // A closed empty room: its walls bound it (left out of the BVH) and occlude nothing.
    let (occluded, _) = check(&data.join("analytic/cube_onelight.glb"), dir, 5_000, "cube");
    assert_eq!(occluded, 0);
    // A room cluttered with boxes.
    let cluttered = dir.join("cluttered.glb");
    std::fs::write(&cluttered, cluttered_scene(3)).unwrap();
    let (occluded, n) = check(&cluttered, dir, 20_000, "cluttered");
    assert!(
        occluded > n / 50 && occluded < n,
        "{occluded} of {n}: a mix"
    );
    // A game level: thousands of faces, many occluded segments.
    let (occluded, n) = check(
        &data.join("redeclipse_dutility/redeclipse_dutility_lit.glb"),
        dir,
        2_000,
        "dutility",
    );
    assert!(
        occluded > n / 10 && occluded < n,
        "{occluded} of {n}: a mix"
    );
}

#[test]
fn bad_segments_and_options_are_refused() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/analytic/furnace.glb");
    let tmp = scratch();
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, "[[1, 2, 3]]").unwrap();
    let run = wavrad(&[
        "bench",
        "visibility",
        scene.to_str().unwrap(),
        "--segments",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2), "{run:?}");
    assert!(String::from_utf8_lossy(&run.stderr).contains("bad.json"));
    let run = wavrad(&["bench", "visibility", scene.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{run:?}");
}
