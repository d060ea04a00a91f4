//! Sanity of whole solves on real scenes: no NaN, no negative face mean, an unshot ratio that never
//! rises, and a converged stop. The bundled samples run in `cargo test`; the larger lit scene of
//! `../shared/scenes/` runs in an ignored test (it skips, saying so, when `../shared` is absent):
//! `cargo test --release --test lit_scenes -- --ignored --nocapture`.

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
            mean.iter().all(|c| c.is_finite() && *c >= -1e-9),
            "{name}: root {i} (face {}) has mean {mean:?}",
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

#[test]
fn bundled_samples_solve_cleanly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for scene in [
        "scenes/cornell_box/cornell_box.gltf",
        "scenes/kenney_building_small_c/kenney_building_small_c_lit.glb",
    ] {
        check(&root.join(scene), SolverParams::default());
    }
}

/// About four minutes at M1 in release mode on two cores.
#[test]
#[ignore]
fn shared_lit_scenes_solve_cleanly() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/scenes/redeclipse_dutility/redeclipse_dutility_lit.glb");
    if !path.exists() {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            path.display()
        );
        return;
    }
    check(
        &path,
        SolverParams {
            order: 1,
            ..Default::default()
        },
    );
}
