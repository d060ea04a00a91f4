//! A bake is reproducible: two solves of one scene with the same settings and no time budget
//! write the same bytes to every output a pipeline caches or ships (lightmap pages, `atlas.png`,
//! `preview.png`, `scene.glb`); `result.json` and `convergence.csv` also carry seconds and the
//! process's peak memory, which are not compared.

use std::path::Path;

mod common;
use common::cli::solve_ok;

fn solve(scene: &Path, out: &Path) {
    solve_ok(scene, out, &["--order", "1", "--tolerance", "1e-5"]);
}

/// The Kenney building (holed faces, a lightmap page of many tiles) solved twice: before its
/// tiles were written in order, `lightmap.exr` differed from one run to the next.
#[test]
fn two_bakes_of_one_scene_are_the_same_bytes() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/kenney_building_small_c/kenney_building_small_c_lit.glb");
    let root = std::env::temp_dir().join(format!("wavrad-reproducible-{}", std::process::id()));
    let (a, b) = (root.join("a"), root.join("b"));
    solve(&scene, &a);
    solve(&scene, &b);
    for file in ["lightmap.exr", "atlas.png", "preview.png", "scene.glb"] {
        let read =
            |dir: &Path| std::fs::read(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(read(&a) == read(&b), "{file} differs between two bakes");
    }
    std::fs::remove_dir_all(&root).ok();
}
