//! Direct light against a brute-force integral, on the reference sets' scenes: the solve stopped
//! after its emitters' own shots (`max_iterations` = the emitting faces, quantity `H / pi`) is
//! compared at the reference probes with the irradiance from every emitting face integrated
//! point by point (a midpoint grid over each of its triangles, each sample's shadow ray through
//! the solver's BVH, whose verdicts `solver::visibility`'s brute-force twins pin). This splits an
//! error against the Monte Carlo references (`tests/reference.rs`) into the direct light's share
//! and the rest; the direct light is held to a bound per set.
//!
//! Print each set's figure and its worst probes:
//! `cargo test --release --test direct_light -- --nocapture` (Red Eclipse:
//! `-- --ignored --nocapture`).

use glam::DVec3;
use rayon::prelude::*;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use wavrad::domain::DomainMode;
use wavrad::output::probes::{evaluate_probes, ProbePoint};
use wavrad::pipeline::{bake, Prepared};
use wavrad::reference::ReferenceSet;
use wavrad::scene::{load_scene_from_path, Scene};
use wavrad::solver::{Quantity, SolverParams};

/// Bounds on each set's direct-light nrms at default settings, above what the solver reaches
/// with room for a refinement pattern's change (docs/accuracy.md, "Direct light against a
/// brute-force integral": what each reaches, and where its worst probes lie).
const CORNELL_BOUND: f64 = 0.005;
const KENNEY_BOUND: f64 = 0.02;
const RED_ECLIPSE_BOUND: f64 = 0.035;

/// Samples along each side of an emitting triangle's midpoint grid.
const GRID: usize = 128;

/// One set's direct light: the nrms of the solve's direct `H / pi` against the integral over
/// its probes (channel-averaged, over the integral's mean), and its worst probes.
struct DirectError {
    nrms: f64,
    /// (probe, solve, integral), the largest differences first.
    worst: Vec<(usize, f64, f64)>,
}

fn measure(set_name: &str) -> DirectError {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let set = ReferenceSet::load(&root.join("tests/data/reference").join(set_name))
        .expect("reference.json reads");
    let scene = load_scene_from_path(&set.scene_in(root), 5_000_000).expect("scene loads");
    let emitting: Vec<usize> = (0..scene.materials.len())
        .filter(|&m| scene.materials[m].emission.iter().any(|&c| c > 0.0))
        .collect();
    assert!(
        emitting
            .iter()
            .all(|&m| scene.materials[m].emissive_texture.is_none()),
        "{set_name}: the integral reads emission factors, not textures"
    );
    assert!(scene.lights.is_empty(), "{set_name}: emitting faces only");
    // Every emitting side shoots once, and nothing else: the emitters are shot first.
    let emitters: usize = wavrad::faces::merge_planar_faces(&scene)
        .faces
        .iter()
        .filter(|f| emitting.contains(&(f.material as usize)))
        .map(|f| if f.double_sided { 2 } else { 1 })
        .sum();
    let params = SolverParams {
        quantity: Quantity::Irradiance,
        max_iterations: emitters as u64,
        ..SolverParams::default()
    };
    let (prepared, solution) = bake(
        &scene,
        DomainMode::Extended,
        params,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .expect("bakes");
    assert_eq!(solution.stats.iterations, emitters as u64, "{set_name}");
    let probes = set.probes();
    let solved = evaluate_probes(&solution, &probes, prepared.diagonal);
    let pairs: Vec<(f64, f64)> = probes
        .par_iter()
        .zip(&solved)
        .map(|(probe, value)| {
            let l = value.l.expect("every probe finds its surface");
            let face = value.face.expect("a probe's face");
            let solve = (l[0] + l[1] + l[2]) / 3.0;
            (solve, direct_integral(&scene, &prepared, probe, face))
        })
        .collect();
    let mean = pairs.iter().map(|p| p.1).sum::<f64>() / pairs.len() as f64;
    let sq = pairs.iter().map(|(s, b)| (s - b).powi(2)).sum::<f64>() / pairs.len() as f64;
    let mut worst: Vec<(usize, f64, f64)> = pairs
        .iter()
        .enumerate()
        .map(|(i, &(s, b))| (i, s, b))
        .collect();
    worst.sort_by(|a, b| (b.1 - b.2).abs().total_cmp(&(a.1 - a.2).abs()));
    worst.truncate(5);
    println!(
        "{set_name}: direct light nrms {:.2} % against the integral ({} probes, mean H/pi {mean:.5})",
        100.0 * sq.sqrt() / mean,
        pairs.len()
    );
    for &(i, s, b) in &worst {
        println!(
            "  probe {i:4}: solve {s:.5}, integral {b:.5} ({:+.2} % of the mean)",
            100.0 * (s - b) / mean
        );
    }
    DirectError {
        nrms: sq.sqrt() / mean,
        worst,
    }
}

/// `H / pi` at the probe from every emitting face (channel-averaged): the sum over a midpoint
/// grid of each emitting triangle of `L_e cos cos / (pi r^2) dA`, each sample's shadow ray
/// ignoring the emitter's face and the probe's, as the solver's links do.
fn direct_integral(scene: &Scene, prepared: &Prepared, probe: &ProbePoint, face: u32) -> f64 {
    let p = DVec3::from(probe.p);
    let n = DVec3::from(probe.n).normalize();
    let mut total = 0.0;
    for f in &prepared.faces.faces {
        let material = &scene.materials[f.material as usize];
        let le = material.emission.iter().sum::<f64>() / 3.0;
        if le <= 0.0 {
            continue;
        }
        for t in &f.triangulation {
            let (a, e1, e2) = (t[0], t[1] - t[0], t[2] - t[0]);
            let cell = 0.5 * e1.cross(e2).length() / (GRID * GRID) as f64;
            let mut sum = 0.0;
            for i in 0..GRID {
                for j in 0..GRID {
                    // The unit square's cell centre, folded onto the triangle.
                    let (mut s, mut t) = (
                        (i as f64 + 0.5) / GRID as f64,
                        (j as f64 + 0.5) / GRID as f64,
                    );
                    if s + t > 1.0 {
                        (s, t) = (1.0 - s, 1.0 - t);
                    }
                    let q = a + e1 * s + e2 * t;
                    let d = q - p;
                    let r2 = d.length_squared();
                    let w = d / r2.sqrt();
                    let cos_p = n.dot(w);
                    let cos_q = if material.double_sided {
                        f.normal.dot(w).abs()
                    } else {
                        -f.normal.dot(w)
                    };
                    if cos_p > 0.0
                        && cos_q > 0.0
                        && prepared.visibility.visible(p, q, [f.id.0, face])
                    {
                        sum += cos_p * cos_q / r2;
                    }
                }
            }
            total += le * sum * cell / std::f64::consts::PI;
        }
    }
    total
}

/// The set's direct light is within `bound` of the integral.
fn assert_within(set_name: &str, bound: f64) {
    let e = measure(set_name);
    assert!(
        e.nrms < bound,
        "{set_name}: direct light nrms {:.4} over {bound}, worst (probe, solve, integral) {:?}",
        e.nrms,
        e.worst
    );
}

#[test]
fn the_cornell_box_direct_light_matches_the_integral() {
    assert_within("cornell_box", CORNELL_BOUND);
}

#[test]
fn the_kenney_building_direct_light_matches_the_integral() {
    assert_within("kenney_building_small_c_lit", KENNEY_BOUND);
}

#[test]
#[ignore = "a 25 s solve: cargo test --release --test direct_light -- --ignored --nocapture"]
fn the_red_eclipse_direct_light_matches_the_integral() {
    assert_within("redeclipse_dutility_lit", RED_ECLIPSE_BOUND);
}
