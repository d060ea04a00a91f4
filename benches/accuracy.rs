//! Benchmark: the speed-accuracy sweep over every data set of `tests/data/reference/` (copied from
//! `../shared/reference/`): each order, both domain modes and a sweep of `--tolerance`, each solve a
//! `wavrad solve` process, with its time, elements, memory and error against the Monte Carlo
//! reference. It is `wavrad bench sweep` (`wavrad::bench::sweep`, which owns the logic and the
//! metric) over the reference sets; it writes the sweep's CSV and chart to a temporary folder.
//!
//! Run: `cargo bench --bench accuracy` (release build; tens of minutes on two cores: the finest
//! tolerances on the Red Eclipse level dominate). `WAVRAD_ACCURACY_SETS=cornell_box,kenney_building_small_c_lit`
//! limits the data sets, `WAVRAD_ACCURACY_TOLERANCES=1e-5,1e-6` the sweep.

use std::path::Path;
use wavrad::bench::sweep::{run, summary, SweepOptions, DEFAULT_TOLERANCES, ORDERS};

fn list_env(name: &str) -> Option<Vec<String>> {
    std::env::var(name)
        .ok()
        .map(|v| v.split(',').map(|s| s.trim().to_string()).collect())
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let references = root.join("tests/data/reference");
    let Ok(dirs) = std::fs::read_dir(&references) else {
        println!("SKIP: {} is absent", references.display());
        return;
    };
    let mut sets: Vec<String> = dirs
        .flatten()
        .filter(|d| d.path().join("reference.json").exists())
        .map(|d| d.file_name().to_string_lossy().into_owned())
        .collect();
    sets.sort();
    if let Some(only) = list_env("WAVRAD_ACCURACY_SETS") {
        sets.retain(|s| only.contains(s));
    }
    let tolerances: Vec<f64> = list_env("WAVRAD_ACCURACY_TOLERANCES")
        .map(|v| v.iter().filter_map(|t| t.parse().ok()).collect())
        .unwrap_or_else(|| DEFAULT_TOLERANCES.to_vec());
    let options = SweepOptions {
        scenes: sets,
        out: std::env::temp_dir().join(format!("wavrad-bench-accuracy-{}", std::process::id())),
        orders: Some(ORDERS.to_vec()),
        tolerances: Some(tolerances),
        modes: None,
        max_seconds: 3600.0,
        exe: env!("CARGO_BIN_EXE_wavrad").into(),
        repo: root.to_path_buf(),
        resume: false,
    };
    match run(&options, &mut |line| println!("{line}")) {
        Ok(report) => {
            print!("{}", summary(&report));
            println!("CSV and chart: {}", options.out.display());
        }
        Err(e) => println!("the sweep did not run: {e}"),
    }
}
