//! Sanity of whole solves on real scenes at default settings (M2, extended domains): no NaN, no
//! negative face mean, an unshot ratio that never rises, and a converged stop. The repository's
//! scenes always run (the samples and the lit Red Eclipse level of `tests/data/`); every other
//! `*_lit.glb` of `../shared/scenes/` runs too when `../shared` is there (the test says it skips
//! when it is not). Figures: `cargo test --test lit_scenes -- --nocapture`.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use wavrad::pipeline::bake;
use wavrad::scene::load_scene_from_path;
use wavrad::solver::{SolverParams, StopReason};

fn check(path: &Path, params: SolverParams) {
    let name = path.display();
    let scene = load_scene_from_path(path, 1_000_000).expect("scene loads");
    let (prepared, sol) = bake(
        &scene,
        Default::default(),
        params,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .expect("bakes");
    assert_eq!(sol.stats.stop_reason, Some(StopReason::Converged), "{name}");
    for pair in sol.convergence.windows(2) {
        assert!(
            pair[1].unshot_ratio <= pair[0].unshot_ratio * (1.0 + 1e-12),
            "{name}: unshot ratio rose from {} to {}",
            pair[0].unshot_ratio,
            pair[1].unshot_ratio
        );
    }
    for (i, r) in sol.roots.iter().enumerate() {
        let mean = sol.mean_value(i);
        assert!(
            mean.iter().all(|c| c.is_finite() && *c >= 0.0),
            "{name}: root {i} (face {}) has mean {mean:?}",
            r.face.0
        );
        // Before the reported mean's clamp at 0: a face in shadow may end a hair below 0 (a
        // higher-order source dipping below 0 near a shadow edge), never more.
        let raw = sol.mean_radiosity(i);
        let scale = 1e-5 * (1.0 + r.exitance.iter().fold(0.0f64, |a, &b| a.max(b)));
        assert!(
            raw.iter().all(|c| c.is_finite() && *c >= -scale),
            "{name}: root {i} (face {}) has mean radiosity {raw:?}",
            r.face.0
        );
    }
    println!(
        "{name}: {} faces, {} shots, {} elements, unshot {:.2e}, {:.1} s",
        prepared.faces.faces.len(),
        sol.stats.iterations,
        sol.stats.elements,
        sol.stats.unshot_ratio,
        sol.stats.seconds
    );
}

/// The scenes the repository carries: the samples and the lit Red Eclipse level of the references.
const IN_REPOSITORY: [&str; 3] = [
    "scenes/cornell_box/cornell_box.gltf",
    "scenes/kenney_building_small_c/kenney_building_small_c_lit.glb",
    "tests/data/redeclipse_dutility/redeclipse_dutility_lit.glb",
];

/// The repository's scenes (the Red Eclipse level takes about a minute at M2, release build).
#[test]
fn repository_scenes_solve_cleanly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for scene in IN_REPOSITORY {
        check(&root.join(scene), SolverParams::default());
    }
}

/// Lit scenes of `../shared/scenes/` above this many triangles are the scaling workload (a
/// level of 70 000 triangles does not converge in the time a test has): they are skipped here, with
/// the reason printed, and measured by the scale benchmarks instead.
const MAX_TEST_TRIANGLES: usize = 20_000;

/// Every other lit scene of `../shared/scenes/` (those with a copy in the repository are checked
/// above; those over [`MAX_TEST_TRIANGLES`] are skipped with the reason).
#[test]
fn shared_lit_scenes_solve_cleanly() {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    let Ok(dirs) = std::fs::read_dir(&shared) else {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            shared.display()
        );
        return;
    };
    let mut scenes: Vec<_> = dirs
        .flatten()
        .filter_map(|d| std::fs::read_dir(d.path()).ok())
        .flat_map(|files| files.flatten().map(|f| f.path()))
        .filter(|p| p.to_string_lossy().ends_with("_lit.glb"))
        .collect();
    let copied = |p: &Path| {
        IN_REPOSITORY
            .iter()
            .any(|r| Path::new(r).file_name() == p.file_name())
    };
    scenes.sort();
    assert!(
        !scenes.is_empty(),
        "no *_lit.glb under {}",
        shared.display()
    );
    for path in scenes {
        if copied(&path) {
            println!("{}: checked from its repository copy", path.display());
        } else if let Some(n) = triangle_count(&path).filter(|&n| n > MAX_TEST_TRIANGLES) {
            println!(
                "SKIP: {}: {n} triangles, over the {MAX_TEST_TRIANGLES} a test solves (the scaling workload)",
                path.display()
            );
        } else {
            check(&path, SolverParams::default());
        }
    }
}

/// The scene's triangle count, `None` when it does not load (then `check` reports why).
fn triangle_count(path: &Path) -> Option<usize> {
    load_scene_from_path(path, 1_000_000)
        .ok()
        .map(|s| s.triangles.len())
}
