//! Planar-face merging on every scene of `../shared/scenes` (issue 3): each merges into faces the
//! validator accepts, with the triangles' area conserved; prints a table per scene (faces by
//! kind, holes, dropped and split groups, merge time).
//!
//! Skips with a message when `../shared/scenes` is absent, as in a fresh clone.

use std::path::{Path, PathBuf};
use std::time::Instant;
use wavrad::faces::{
    merge_planar_faces, triangulate_face, validate_faces, FaceKind, DEGENERATE_AREA_REL,
};

mod common;
use common::faces::total_area;

const LIMIT: usize = 5_000_000;

fn shared_scenes() -> Option<Vec<PathBuf>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if !dir.is_dir() {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            dir.display()
        );
        return None;
    }
    Some(wavrad::scene::scene_files(&dir))
}

#[test]
fn every_shared_scene_merges_into_valid_faces_with_its_area() {
    let Some(paths) = shared_scenes() else {
        return;
    };
    println!(
        "{:<34} {:>9} {:>6} {:>5} {:>5} {:>5} {:>5} {:>7} {:>5} {:>8} {:>7}",
        "scene",
        "triangles",
        "faces",
        "tri",
        "par",
        "ext",
        "holes",
        "dropped",
        "split",
        "merge_ms",
        "tri_ms"
    );
    for path in paths {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let scene = wavrad::scene::load_scene_from_path(&path, LIMIT)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let start = Instant::now();
        let f = merge_planar_faces(&scene);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let problems = validate_faces(&f);
        assert!(
            problems.is_empty(),
            "{name}: {} problems, first: {:#?}",
            problems.len(),
            problems
                .iter()
                .take(10)
                .map(|p| p.to_string())
                .collect::<Vec<_>>()
        );
        let diag = scene.diagonal();
        let expected: f64 = scene
            .triangles
            .iter()
            .map(|t| t.area())
            .filter(|&a| a > DEGENERATE_AREA_REL * diag * diag)
            .sum();
        // Less what overlapping coplanar surfaces lost (every piece of surface counted once).
        let expected = expected - f.overlap_area_removed_m2;
        let got = total_area(&f);
        assert!(
            (got - expected).abs() <= 1e-9 * expected,
            "{name}: faces cover {got} m^2, triangles {expected} m^2 (rel {:e})",
            (got - expected) / expected
        );
        // The ear-clipping triangulator (for `--domain tessellated`) handles every real face.
        let t_start = Instant::now();
        for face in f.faces.iter().filter(|f| f.kind == FaceKind::Extended) {
            let tris = triangulate_face(face)
                .unwrap_or_else(|e| panic!("{name}: face {} does not triangulate: {e}", face.id.0));
            let area: f64 = tris
                .iter()
                .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).dot(face.normal))
                .sum();
            let perimeter: f64 = std::iter::once(&face.outer)
                .chain(&face.holes)
                .map(|r| {
                    (0..r.len())
                        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
                        .sum::<f64>()
                })
                .sum();
            assert!(
                (area - face.area_m2).abs() <= f.tolerance_m * perimeter + 1e-9 * face.area_m2,
                "{name}: face {} triangulates to {area} m^2, not {} m^2",
                face.id.0,
                face.area_m2
            );
        }
        let tri_ms = t_start.elapsed().as_secs_f64() * 1e3;
        let count = |k: FaceKind| f.faces.iter().filter(|f| f.kind == k).count();
        println!(
            "{:<34} {:>9} {:>6} {:>5} {:>5} {:>5} {:>5} {:>7} {:>5} {:>8.1} {:>7.1}",
            name,
            f.triangles_in,
            f.faces.len(),
            count(FaceKind::Triangle),
            count(FaceKind::Parallelogram),
            count(FaceKind::Extended),
            f.faces.iter().map(|f| f.holes.len()).sum::<usize>(),
            f.degenerate_dropped,
            f.groups_split,
            ms,
            tri_ms
        );
    }
}
