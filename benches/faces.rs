//! Benchmark: glTF import and planar-face merging on the shared scenes (issue 3's "well under a
//! second for the largest scene"). Prints one line per scene, best of five runs each, largest last.
//!
//! Run: `cargo bench --bench faces` (reads `../shared/scenes/`; prints SKIP when it is absent).

use std::path::Path;
use std::time::Instant;

use wavrad::faces::merge_planar_faces;

const RUNS: usize = 5;
const TRIANGLE_LIMIT: usize = 10_000_000;

fn main() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if !dir.is_dir() {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            dir.display()
        );
        return;
    }
    let mut rows = Vec::new();
    for path in wavrad::scene::scene_files(&dir) {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (mut import_s, mut merge_s) = (f64::INFINITY, f64::INFINITY);
        let (mut triangles, mut faces) = (0, 0);
        for _ in 0..RUNS {
            let t0 = Instant::now();
            let scene = match wavrad::scene::load_scene_from_path(&path, TRIANGLE_LIMIT) {
                Ok(s) => s,
                Err(e) => {
                    println!("{name}: does not load: {e}");
                    break;
                }
            };
            let t1 = Instant::now();
            let f = merge_planar_faces(&scene);
            let t2 = Instant::now();
            import_s = import_s.min((t1 - t0).as_secs_f64());
            merge_s = merge_s.min((t2 - t1).as_secs_f64());
            triangles = f.triangles_in;
            faces = f.faces.len();
        }
        rows.push((triangles, name, faces, import_s, merge_s));
    }
    rows.sort_by_key(|r| r.0);
    println!(
        "{:<36} {:>9} {:>7} {:>10} {:>10} {:>10}",
        "scene (best of 5, release)", "triangles", "faces", "import_ms", "merge_ms", "total_ms"
    );
    for (triangles, name, faces, import_s, merge_s) in &rows {
        println!(
            "{:<36} {:>9} {:>7} {:>10.1} {:>10.1} {:>10.1}",
            name,
            triangles,
            faces,
            import_s * 1e3,
            merge_s * 1e3,
            (import_s + merge_s) * 1e3
        );
    }
}
