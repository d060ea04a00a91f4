//! Benchmark: solve time, elements and peak memory for the bundled sample scenes at M1-M3 in both
//! domain modes, to unshot ratio 1e-3 (issue 5). Each solve runs in its own `wavrad` process, so the
//! peak resident memory it reports (result.json `stats.peak_memory_bytes`, VmHWM) is its own.
//!
//! Run: `cargo bench --bench solve` (release build; a few minutes on two cores).
//!
//! `cargo bench --bench solve -- scale [--max-n N] [--no-zdm2] [--max-seconds S]` runs the scaling
//! benchmark of issue 17 instead (`solve/scale.rs`); with no argument the output above is unchanged.

#[path = "solve/scale.rs"]
mod scale;

use std::path::Path;
use std::process::Command;

const SCENES: [&str; 2] = [
    "scenes/cornell_box/cornell_box.gltf",
    "scenes/kenney_building_small_c/kenney_building_small_c_lit.glb",
];

fn main() {
    // Cargo passes `--bench` to every benchmark binary; the rest is the user's, after `--`.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    match args.first().map(String::as_str) {
        None => samples(),
        Some("scale") => scale::run(&args[1..]),
        Some(other) => {
            eprintln!(
                "unknown argument '{other}': `cargo bench --bench solve [-- scale [OPTIONS]]`"
            );
            std::process::exit(2);
        }
    }
}

/// The bundled samples at M1-M3 in both domain modes (the default output).
fn samples() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("wavrad-bench-solve-{}", std::process::id()));
    println!(
        "{:<36} {:>5} {:>12} {:>9} {:>9} {:>7} {:>9} {:>8}",
        "scene", "order", "domain", "seconds", "elements", "shots", "peak_MB", "unshot"
    );
    for scene in SCENES {
        for order in [1, 2, 3] {
            for domain in ["extended", "tessellated"] {
                let status = Command::new(env!("CARGO_BIN_EXE_wavrad"))
                    .current_dir(root)
                    .args(["solve", scene, "--out"])
                    .arg(&out)
                    .args(["--order", &order.to_string(), "--domain", domain])
                    .args(["--target-unshot", "1e-3"])
                    .stderr(std::process::Stdio::null())
                    .status();
                let result = std::fs::read(out.join("result.json"))
                    .ok()
                    .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok());
                let (Ok(status), Some(result)) = (status, result) else {
                    println!("{scene} M{order} {domain}: the solve did not run");
                    continue;
                };
                if !status.success() {
                    println!("{scene} M{order} {domain}: exit {status}");
                    continue;
                }
                let s = &result["stats"];
                let name = Path::new(scene)
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy();
                println!(
                    "{:<36} {:>5} {:>12} {:>9.2} {:>9} {:>7} {:>9.1} {:>8.1e}",
                    name,
                    format!("M{order}"),
                    domain,
                    s["seconds"].as_f64().unwrap_or(f64::NAN),
                    s["elements"].as_u64().unwrap_or(0),
                    s["iterations"].as_u64().unwrap_or(0),
                    s["peak_memory_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6,
                    s["unshot_ratio"].as_f64().unwrap_or(f64::NAN),
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&out);
}
