//! Direct light against a brute-force integral, on the reference sets' scenes lit by emitting
//! faces: the default solve stopped after its emitters' own shots (`max_iterations` = the
//! emitting roots, which the solver shoots first) is compared at the reference probes with the
//! radiance the emitting faces give them directly, integrated point by point: the probe face's
//! reflectance times `L_e cos cos / (pi r^2) dA` summed over a low-discrepancy set of points of
//! each emitting triangle, each sample's shadow ray through the solver's BVH (whose verdicts
//! `solver::visibility`'s brute-force twins pin). The refinement is the default solve's, so this
//! is the direct light's part of the error against the Monte Carlo references
//! (`tests/reference.rs`), held to a bound per set. The metric is the references' nrms (per
//! channel, over the integral's mean, averaged over the channels).
//!
//! Print each set's figure and its worst probes:
//! `cargo test --release --test direct_light -- --include-ignored --nocapture` (Red Eclipse is
//! the ignored one).

use glam::DVec3;
use rayon::prelude::*;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use wavrad::domain::DomainMode;
use wavrad::output::probes::{evaluate_probes, ProbePoint};
use wavrad::pipeline::{bake, prepare, Prepared};
use wavrad::reference::ReferenceSet;
use wavrad::scene::{load_scene_from_path, Rgb, Scene};
use wavrad::solver::SolverParams;

/// Bounds on each set's direct-light nrms at default settings, above what the solver reaches
/// with room for a refinement pattern's change (docs/accuracy.md, "Direct light against a
/// brute-force integral": what each reaches, and where its worst probes lie).
const CUBE_BOUND: f64 = 0.005;
const CORNELL_BOUND: f64 = 0.005;
const KENNEY_BOUND: f64 = 0.025;
const RED_ECLIPSE_BOUND: f64 = 0.04;

/// Samples of the integral over each emitting face.
const SAMPLES: usize = 1 << 18;
/// The fewest samples of one emitting triangle.
const MIN_TRIANGLE_SAMPLES: usize = 64;

/// One set's direct light: the nrms of the solve's direct radiance against the integral over
/// its probes, and its worst probes.
struct DirectError {
    nrms: f64,
    /// (probe, solve, integral), channel-averaged, the largest differences first.
    worst: Vec<(usize, f64, f64)>,
}

fn measure(set_name: &str) -> DirectError {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let set = ReferenceSet::load(&root.join("tests/data/reference").join(set_name))
        .expect("reference.json reads");
    let scene = load_scene_from_path(&set.scene_in(root), 5_000_000).expect("scene loads");
    assert!(
        scene
            .materials
            .iter()
            .all(|m| m.base_color_texture.is_none() && m.emissive_texture.is_none()),
        "{set_name}: the integral reads reflectance and emission factors, not textures"
    );
    assert!(scene.lights.is_empty(), "{set_name}: emitting faces only");
    // Every emitting root shoots once (the roots `bake` builds, counted on a first `prepare`).
    let emitting_roots = prepare(&scene, DomainMode::Extended)
        .roots
        .iter()
        .filter(|r| r.exitance.iter().any(|&c| c > 0.0))
        .count() as u64;
    let params = SolverParams {
        max_iterations: emitting_roots,
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
    assert_eq!(solution.stats.iterations, emitting_roots, "{set_name}");
    let probes = set.probes();
    let solved = evaluate_probes(&solution, &probes, prepared.diagonal);
    // Per probe: (the solve's radiance, the integral's).
    let radiances: Vec<(Rgb, Rgb)> = probes
        .par_iter()
        .zip(&solved)
        .map(|(probe, value)| {
            assert!(value.error.is_none(), "{set_name}: {:?}", value.error);
            let solve = value.l.expect("every probe finds its surface");
            let face = value.face.expect("a probe's face");
            (solve, direct_radiance(&scene, &prepared, probe, face))
        })
        .collect();
    // The references' metric, with the integral standing in for the path tracer.
    let mut integral_set = set.clone();
    for (point, (_, integral)) in integral_set.points.iter_mut().zip(&radiances) {
        point.l = *integral;
    }
    let nrms = integral_set
        .error(&solved)
        .expect("a value at every probe")
        .nrms;
    let count = radiances.len() as f64;
    let grey = |rgb: &Rgb| rgb.iter().sum::<f64>() / 3.0;
    let mean = radiances.iter().map(|r| grey(&r.1)).sum::<f64>() / count;
    let mut worst: Vec<(usize, f64, f64)> = radiances
        .iter()
        .enumerate()
        .map(|(i, (solve, integral))| (i, grey(solve), grey(integral)))
        .collect();
    worst.sort_by(|a, b| (b.1 - b.2).abs().total_cmp(&(a.1 - a.2).abs()));
    worst.truncate(5);
    println!(
        "{set_name}: direct light nrms {:.2} % against the integral ({} probes, mean L {mean:.5})",
        100.0 * nrms,
        radiances.len()
    );
    for &(i, solve, integral) in &worst {
        println!(
            "  probe {i:4}: solve {solve:.5}, integral {integral:.5} ({:+.2} % of the mean)",
            100.0 * (solve - integral) / mean
        );
    }
    DirectError { nrms, worst }
}

/// The radiance the emitting faces give the probe directly: the reflectance of the probe's face
/// times `L_e cos cos / (pi r^2) dA` summed over [`SAMPLES`] points of each emitting face, shared
/// among its triangles by area (`r2_point`, at least [`MIN_TRIANGLE_SAMPLES`] a triangle), each
/// sample's shadow ray ignoring the emitter's face and the probe's, as the solver's links do.
fn direct_radiance(scene: &Scene, prepared: &Prepared, probe: &ProbePoint, face: u32) -> Rgb {
    let p = DVec3::from(probe.p);
    let n = DVec3::from(probe.n).normalize();
    let receiver = prepared
        .faces
        .faces
        .iter()
        .find(|f| f.id.0 == face)
        .expect("the probe's face");
    let rho = scene.materials[receiver.material as usize].rho;
    let mut irradiance_over_pi = [0.0; 3];
    for f in &prepared.faces.faces {
        let material = &scene.materials[f.material as usize];
        if material.emission.iter().all(|&c| c <= 0.0) {
            continue;
        }
        for tri in &f.triangulation {
            let (a, e1, e2) = (tri[0], tri[1] - tri[0], tri[2] - tri[0]);
            let area = 0.5 * e1.cross(e2).length();
            let samples =
                ((SAMPLES as f64 * area / f.area_m2).ceil() as usize).max(MIN_TRIANGLE_SAMPLES);
            // Each sample's area: the fold below maps the unit square two to one onto the
            // triangle, so equal weights sum to its area.
            let weight = area / samples as f64;
            let mut geometry = 0.0;
            for k in 0..samples {
                let (mut s, mut t) = r2_point(k);
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
                if cos_p > 0.0 && cos_q > 0.0 && prepared.visibility.visible(p, q, [f.id.0, face]) {
                    geometry += cos_p * cos_q / r2;
                }
            }
            for (c, e) in irradiance_over_pi.iter_mut().enumerate() {
                *e += material.emission[c] * geometry * weight / std::f64::consts::PI;
            }
        }
    }
    [0, 1, 2].map(|c| rho[c] * irradiance_over_pi[c])
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
fn the_cube_direct_light_matches_the_integral() {
    assert_within("cube_onelight", CUBE_BOUND);
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
#[ignore = "the Red Eclipse level's direct shot: cargo test --release --test direct_light -- --ignored"]
fn the_red_eclipse_direct_light_matches_the_integral() {
    assert_within("redeclipse_dutility_lit", RED_ECLIPSE_BOUND);
}

/// Point `k` of Roberts' R2 sequence on the unit square: a low-discrepancy set with no row or
/// column along the axes, so a scene's axis-aligned edges do not alias with it as they would
/// with a grid.
fn r2_point(k: usize) -> (f64, f64) {
    // The plastic number, the real root of x^3 = x + 1.
    const PLASTIC: f64 = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / PLASTIC, 1.0 / (PLASTIC * PLASTIC));
    ((0.5 + a1 * k as f64).fract(), (0.5 + a2 * k as f64).fract())
}
