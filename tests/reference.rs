//! Accuracy against independent Monte Carlo references (issue 5): every data set of
//! `tests/data/reference/` (copied from `../shared/reference/`; its README defines the metric) is
//! solved at default settings and its normalised RMS error printed beside the reference's own noise
//! floor, and held to issue 5's target: nrms <= 3 % on every set.
//!
//! Print the table: `cargo test --release --test reference -- --nocapture`.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use wavrad::domain::DomainMode;
use wavrad::output::probes::evaluate_probes;
use wavrad::pipeline::bake;
use wavrad::reference::{ReferenceError, ReferenceSet};
use wavrad::scene::load_scene_from_path;
use wavrad::solver::SolverParams;

/// Issue 5's target at default settings.
const TARGET_NRMS: f64 = 0.03;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every set, solved at default settings: (name, error, noise floor, seconds).
fn measure() -> Vec<(String, ReferenceError, f64, f64)> {
    let dir = root().join("tests/data/reference");
    let mut sets: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("tests/data/reference is in the repository")
        .flatten()
        .map(|d| d.path())
        .filter(|p| p.join("reference.json").exists())
        .collect();
    sets.sort();
    assert_eq!(sets.len(), 4, "the four data sets of ../shared/reference");
    // `WAVRAD_REFERENCE_SETS=cornell_box,kenney_building_small_c_lit` measures only those sets
    // (a quicker check while working; the test passes only on what it measured).
    let only = std::env::var("WAVRAD_REFERENCE_SETS").ok();
    let mut out = Vec::new();
    for set_dir in sets {
        let name = set_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|s| s == name))
        {
            continue;
        }
        let set = ReferenceSet::load(&set_dir).expect("reference.json reads");
        let scene = load_scene_from_path(&set.scene_in(root()), 5_000_000).expect("scene loads");
        let start = Instant::now();
        let (prepared, solution) = bake(
            &scene,
            DomainMode::Extended,
            SolverParams::default(),
            &AtomicBool::new(false),
            &mut |_| {},
        )
        .expect("bakes");
        let seconds = start.elapsed().as_secs_f64();
        let values = evaluate_probes(&solution, &set.probes(), prepared.diagonal);
        let error = set
            .error(&values)
            .unwrap_or_else(|| panic!("{name}: a probe found no surface"));
        out.push((name, error, set.noise_floor(), seconds));
    }
    println!(
        "{:<30} {:>8} {:>8} {:>26} {:>8}",
        "data set", "nrms %", "floor %", "rms (R, G, B)", "seconds"
    );
    for (name, e, floor, seconds) in &out {
        println!(
            "{:<30} {:>8.2} {:>8.2} {:>8.5} {:>8.5} {:>8.5} {:>8.1}{}",
            name,
            e.nrms * 100.0,
            floor * 100.0,
            e.rms[0],
            e.rms[1],
            e.rms[2],
            seconds,
            if e.nrms > TARGET_NRMS {
                "  MISSES the 3 % target"
            } else {
                ""
            }
        );
    }
    out
}

#[test]
fn every_reference_set_meets_the_target() {
    let misses: Vec<String> = measure()
        .into_iter()
        .filter(|(_, e, _, _)| e.nrms > TARGET_NRMS)
        .map(|(name, e, _, _)| format!("{name} {:.2} %", e.nrms * 100.0))
        .collect();
    assert!(misses.is_empty(), "above 3 %: {misses:?}");
}
