//! Benchmark: the speed-accuracy chart. For every data set of `tests/data/reference/` (copied from
//! `../shared/reference/`), each order, both domain modes and a sweep of `--tolerance`, it solves
//! with the `wavrad` binary and prints the solve time, the elements and the normalised RMS error
//! against the Monte Carlo reference (`wavrad::reference`: per channel
//! `sqrt(mean((L - L_ref)^2)) / mean(L_ref)`, averaged over channels).
//!
//! Run: `cargo bench --bench accuracy` (release build; tens of minutes on two cores: the finest
//! tolerances on the Red Eclipse level dominate). `WAVRAD_ACCURACY_SETS=cornell_box,kenney_building_small_c_lit`
//! limits the data sets, `WAVRAD_ACCURACY_TOLERANCES=1e-5,1e-6` the sweep.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use wavrad::output::probes::ProbeValue;
use wavrad::reference::ReferenceSet;

const TOLERANCES: [f64; 4] = [1e-4, 1e-5, 3e-6, 1e-6];

fn read_json(path: &Path) -> Option<Value> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

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
    let mut sets: Vec<PathBuf> = dirs
        .flatten()
        .map(|d| d.path())
        .filter(|p| p.join("reference.json").exists())
        .collect();
    sets.sort();
    if let Some(only) = list_env("WAVRAD_ACCURACY_SETS") {
        sets.retain(|p| {
            p.file_name()
                .is_some_and(|n| only.iter().any(|o| o == &*n.to_string_lossy()))
        });
    }
    let tolerances: Vec<f64> = list_env("WAVRAD_ACCURACY_TOLERANCES")
        .map(|v| v.iter().filter_map(|t| t.parse().ok()).collect())
        .unwrap_or_else(|| TOLERANCES.to_vec());
    let out = std::env::temp_dir().join(format!("wavrad-bench-accuracy-{}", std::process::id()));
    println!(
        "{:<30} {:>5} {:>12} {:>9} {:>9} {:>9} {:>8}",
        "data set", "order", "domain", "tolerance", "seconds", "elements", "nrms %"
    );
    for set in sets {
        let name = set.file_name().unwrap_or_default().to_string_lossy();
        let reference = match ReferenceSet::load(&set) {
            Ok(r) => r,
            Err(e) => {
                println!("{name}: {e}");
                continue;
            }
        };
        let scene = reference.scene_in(root);
        for order in [1, 2, 3] {
            for domain in ["extended", "tessellated"] {
                for &tolerance in &tolerances {
                    let status = Command::new(env!("CARGO_BIN_EXE_wavrad"))
                        .args(["solve"])
                        .arg(&scene)
                        .arg("--out")
                        .arg(&out)
                        .args(["--order", &order.to_string(), "--domain", domain])
                        .args(["--tolerance", &tolerance.to_string()])
                        .arg("--probes")
                        .arg(set.join("probes.json"))
                        .stderr(std::process::Stdio::null())
                        .stdout(std::process::Stdio::null())
                        .status();
                    let result = read_json(&out.join("result.json"));
                    let values: Option<Vec<ProbeValue>> =
                        std::fs::read(out.join("probe_values.json"))
                            .ok()
                            .and_then(|b| serde_json::from_slice(&b).ok());
                    let (Ok(status), Some(result), Some(values)) = (status, result, values) else {
                        println!("{name} M{order} {domain} {tolerance:e}: the solve did not run");
                        continue;
                    };
                    let error = reference.error(&values).map_or(f64::NAN, |e| e.nrms);
                    let s = &result["stats"];
                    println!(
                        "{:<30} {:>5} {:>12} {:>9.0e} {:>9.2} {:>9} {:>8.2}{}",
                        name,
                        format!("M{order}"),
                        domain,
                        tolerance,
                        s["seconds"].as_f64().unwrap_or(f64::NAN),
                        s["elements"].as_u64().unwrap_or(0),
                        error * 100.0,
                        if status.success() { "" } else { "  (failed)" },
                    );
                    let _ = std::fs::remove_dir_all(&out);
                }
            }
        }
    }
}
