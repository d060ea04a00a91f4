//! Benchmark: the speed-accuracy chart. For every data set of `../shared/reference/` (skipped, with
//! a line saying so, when `../shared` is absent), each order, both domain modes and a sweep of
//! `--tolerance`, it solves with the `wavrad` binary and prints the solve time, the elements and
//! the normalised RMS error against the Monte Carlo reference (the metric of
//! `../shared/reference/README.md`: per channel `sqrt(mean((L - L_ref)^2)) / mean(L_ref)`,
//! averaged over channels).
//!
//! Run: `cargo bench --bench accuracy` (release build; tens of minutes on two cores: the finest
//! tolerances on the Red Eclipse level dominate). `WAVRAD_ACCURACY_SETS=cornell_box,kenney_building_small_c_lit`
//! limits the data sets, `WAVRAD_ACCURACY_TOLERANCES=1e-5,1e-6` the sweep.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

const TOLERANCES: [f64; 4] = [1e-4, 1e-5, 3e-6, 1e-6];

fn read_json(path: &Path) -> Option<Value> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// `nrms` of `values` (probe_values.json) against `points` (reference.json "points").
fn nrms(values: &[Value], points: &[Value]) -> Option<f64> {
    if values.len() != points.len() || points.is_empty() {
        return None;
    }
    let rgb = |v: &Value| -> Option<[f64; 3]> {
        let a = v.as_array()?;
        Some([
            a.first()?.as_f64()?,
            a.get(1)?.as_f64()?,
            a.get(2)?.as_f64()?,
        ])
    };
    let n = points.len() as f64;
    let mut total = 0.0;
    for c in 0..3 {
        let (mut sq, mut mean) = (0.0, 0.0);
        for (v, p) in values.iter().zip(points) {
            let l = rgb(&v["L"])?[c];
            let r = rgb(&p["L"])?[c];
            sq += (l - r) * (l - r);
            mean += r;
        }
        total += (sq / n).sqrt() / (mean / n) / 3.0;
    }
    Some(total)
}

fn list_env(name: &str) -> Option<Vec<String>> {
    std::env::var(name)
        .ok()
        .map(|v| v.split(',').map(|s| s.trim().to_string()).collect())
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared");
    let references = shared.join("reference");
    let Ok(dirs) = std::fs::read_dir(&references) else {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            references.display()
        );
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
        let Some(reference) = read_json(&set.join("reference.json")) else {
            println!("{name}: unreadable reference.json");
            continue;
        };
        let (Some(scene), Some(points)) =
            (reference["scene"].as_str(), reference["points"].as_array())
        else {
            println!("{name}: reference.json lacks scene or points");
            continue;
        };
        for order in [1, 2, 3] {
            for domain in ["extended", "tessellated"] {
                for &tolerance in &tolerances {
                    let status = Command::new(env!("CARGO_BIN_EXE_wavrad"))
                        .args(["solve"])
                        .arg(shared.join(scene))
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
                    let values = read_json(&out.join("probe_values.json"));
                    let (Ok(status), Some(result), Some(values)) = (status, result, values) else {
                        println!("{name} M{order} {domain} {tolerance:e}: the solve did not run");
                        continue;
                    };
                    let error = values
                        .as_array()
                        .and_then(|v| nrms(v, points))
                        .unwrap_or(f64::NAN);
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
