//! The solver against exact values (issue 5's list): form factors from the transfer coefficients at
//! M1-M3, the furnace at probes in both domain modes, and faces with holes emitting and receiving.
//! Print the figures with `cargo test --test solver -- --nocapture`.

use glam::DVec3;
use std::sync::atomic::AtomicBool;
use wavrad::domain::DomainMode;
use wavrad::output::probes::{evaluate_probes, ProbePoint};
use wavrad::pipeline::{bake, Prepared};
use wavrad::scene::gltf_writer::SceneBuilder;
use wavrad::scene::{load_scene, ExternalFiles};
use wavrad::solver::{kernel, Solution, SolverParams};

fn solve(glb: &[u8], order: usize, mode: DomainMode) -> (Prepared, Solution) {
    let scene = load_scene(glb, &ExternalFiles::Refuse, 1_000_000).expect("scene loads");
    let params = SolverParams {
        order,
        ..Default::default()
    };
    bake(&scene, mode, params, &AtomicBool::new(false), &mut |_| {}).expect("bakes")
}

/// Area-weighted mean radiance of the roots of `material`.
fn mean_radiance(sol: &Solution, material: u32) -> f64 {
    let (mut sum, mut area) = (0.0, 0.0);
    for (i, r) in sol.roots.iter().enumerate() {
        if r.material == material {
            sum += sol.mean_value(i)[0] * r.face_area_m2;
            area += r.face_area_m2;
        }
    }
    sum / area
}

const MODES: [DomainMode; 2] = [DomainMode::Extended, DomainMode::Tessellated];

fn check(what: &str, got: f64, exact: f64, tolerance: f64) {
    let rel = (got - exact) / exact;
    println!("{what}: {got:.6} (exact {exact:.6}, {:+.3} %)", rel * 100.0);
    assert!(rel.abs() <= tolerance, "{what}: {got} vs {exact}");
}

#[test]
fn form_factors_of_unit_squares_at_every_order() {
    // Parallel unit squares 1 m apart: an emitter (L_e = 1) over a receiver of rho = 1, whose mean
    // radiance is the form factor.
    let mut b = SceneBuilder::new();
    let recv = b.material([1.0; 3], [0.0; 3], false);
    let emit = b.material([0.0; 3], [1.0; 3], false);
    b.quad(recv, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    b.quad(emit, DVec3::Z, DVec3::Y, DVec3::X, 1);
    let parallel = b.to_glb();
    // Perpendicular unit squares sharing an edge (the x axis).
    let mut b = SceneBuilder::new();
    let recv = b.material([1.0; 3], [0.0; 3], false);
    let emit = b.material([0.0; 3], [1.0; 3], false);
    b.quad(recv, DVec3::ZERO, DVec3::X, DVec3::Y, 1); // z = 0, normal +z
    b.quad(emit, DVec3::ZERO, DVec3::Z, DVec3::X, 1); // y = 0, normal +y
    let perpendicular = b.to_glb();
    for order in [1, 2, 3] {
        let (_, sol) = solve(&parallel, order, DomainMode::Extended);
        check(
            &format!("parallel squares M{order}"),
            mean_radiance(&sol, recv),
            0.199825,
            0.005,
        );
        let (_, sol) = solve(&perpendicular, order, DomainMode::Extended);
        check(
            &format!("perpendicular squares M{order}"),
            mean_radiance(&sol, recv),
            0.200044,
            0.005,
        );
    }
}

#[test]
fn point_one_metre_under_the_centre_of_a_unit_square_sees_its_form_factor() {
    // A large receiver (rho = 1) 1 m under an emitting unit square; the probe under the centre
    // reads the point-to-square form factor 0.239456.
    let mut b = SceneBuilder::new();
    let recv = b.material([1.0; 3], [0.0; 3], false);
    let emit = b.material([0.0; 3], [1.0; 3], false);
    b.quad(
        recv,
        DVec3::new(-2.0, -2.0, 0.0),
        DVec3::X * 4.0,
        DVec3::Y * 4.0,
        1,
    );
    b.quad(emit, DVec3::new(-0.5, -0.5, 1.0), DVec3::Y, DVec3::X, 1);
    let glb = b.to_glb();
    let probe = ProbePoint {
        p: [0.0, 0.0, 0.0],
        n: [0.0, 0.0, 1.0],
    };
    for order in [1, 2, 3] {
        let (prepared, sol) = solve(&glb, order, DomainMode::Extended);
        let v = evaluate_probes(&sol, std::slice::from_ref(&probe), prepared.diagonal);
        let l = v[0].l.expect("the probe is on the receiver");
        check(
            &format!("point under a square M{order}"),
            l[0],
            0.239456,
            0.005,
        );
    }
}

/// A one-sided emitter lights only its front half-space: a receiver reaching behind the emitter's
/// plane (an overhang above a wall's top, a domain larger than its face) stays dark there.
#[test]
fn nothing_is_received_behind_a_one_sided_emitter() {
    // Emitter: x, y in [0, 1] at z = 0, facing -z. Receiver: y = 1.5, facing down, z in [-1, 1];
    // with `arm`, an L (one extended face: its domain straddles the emitter's plane).
    let scene = |arm: bool| {
        let mut b = SceneBuilder::new();
        let recv = b.material([1.0; 3], [0.0; 3], false);
        let emit = b.material([0.0; 3], [1.0; 3], false);
        b.quad(emit, DVec3::ZERO, DVec3::Y, DVec3::X, 1);
        let origin = DVec3::new(0.0, 1.5, -1.0);
        b.quad(recv, origin, DVec3::X, DVec3::Z * 2.0, 1);
        if arm {
            b.quad(recv, origin + DVec3::X, DVec3::X * 0.5, DVec3::Z * 0.5, 1);
        }
        b.to_glb()
    };
    let probe = |z: f64| ProbePoint {
        p: [0.5, 1.5, z],
        n: [0.0, -1.0, 0.0],
    };
    let probes = [probe(-0.5), probe(0.5), probe(0.9)];
    for masked in [false, true] {
        let glb = scene(masked);
        for mode in MODES {
            for order in [1, 2] {
                let (prepared, sol) = solve(&glb, order, mode);
                let extended_roots = sol.roots.iter().filter(|r| r.mask.is_some()).count();
                assert_eq!(
                    extended_roots,
                    usize::from(masked && mode == DomainMode::Extended)
                );
                let v = evaluate_probes(&sol, &probes, prepared.diagonal);
                let l: Vec<f64> = v.iter().map(|p| p.l.expect("on the receiver")[0]).collect();
                println!(
                    "{mode:?} M{order}: in front {:.5}, behind {:.6} {:.6}",
                    l[0], l[1], l[2]
                );
                assert!(l[0] > 0.01, "the front half is lit");
                assert!(
                    l[1] < 0.01 * l[0] && l[2] < 0.01 * l[0],
                    "{mode:?} M{order}: light behind the emitter: {l:?}"
                );
            }
        }
    }
}

/// The largest relative error of the furnace's L = 2 over `probes` (red channel; the furnace is
/// grey).
fn worst_furnace_probe(prepared: &Prepared, sol: &Solution, probes: &[ProbePoint]) -> f64 {
    evaluate_probes(sol, probes, prepared.diagonal)
        .iter()
        .map(|v| (v.l.expect("on a wall")[0] - 2.0).abs() / 2.0)
        .fold(0.0, f64::max)
}

#[test]
fn furnace_is_two_at_every_probe_for_all_orders_and_both_modes() {
    // A closed unit cube, rho = 0.5 and L_e = 1 everywhere: L = 2 at every point.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [1.0; 3], false);
    b.inward_box([m; 6], DVec3::ZERO, DVec3::ONE, 2);
    let glb = b.to_glb();
    let mut probes = Vec::new();
    for &(u, v) in &[(0.1, 0.1), (0.5, 0.5), (0.93, 0.27), (0.02, 0.98)] {
        probes.push(ProbePoint {
            p: [u, v, 0.0],
            n: [0.0, 0.0, 1.0],
        });
        probes.push(ProbePoint {
            p: [u, 1.0, v],
            n: [0.0, -1.0, 0.0],
        });
        probes.push(ProbePoint {
            p: [1.0, u, v],
            n: [-1.0, 0.0, 0.0],
        });
    }
    for mode in MODES {
        for order in [1, 2, 3] {
            let (prepared, sol) = solve(&glb, order, mode);
            let worst = worst_furnace_probe(&prepared, &sol, &probes);
            println!(
                "furnace {mode:?} M{order}: worst probe {:.3} %",
                worst * 100.0
            );
            // Issue 5 asks 0.5 % at every order (measured: M1 0.37 %, M2 0.09 %, M3 0.07 %).
            // M1 is the hard case: a piecewise-constant receiver gathers links at several levels,
            // and a later shot's source, split for its radiosity's detail, sends many links that
            // each pass the oracle while their sum does not. With the node-sum check after direct
            // shots only, M1 was 2.5 % off here and 7 % off 1 cm from a corner.
            let bound = 0.005;
            assert!(
                worst <= bound,
                "{mode:?} M{order}: worst probe off by {worst}"
            );
        }
    }
}

/// A unit square at height `z` facing `normal_up`, with or without a centred 0.5 x 0.5 hole, as
/// eight triangles (the ring between two squares) or two.
/// The furnace again, with every wall a ring (material `a`) around a centre square (material
/// `b`): each ring is an extended face with a hole, so extended mode solves on masked domains.
#[test]
fn furnace_with_holed_walls_in_both_modes() {
    let mut b = SceneBuilder::new();
    let ring = b.material([0.5; 3], [1.0; 3], false);
    let centre = b.material([0.5; 3], [1.0; 3], false);
    let walls = [
        (DVec3::ZERO, DVec3::X, DVec3::Y),
        (DVec3::Z, DVec3::Y, DVec3::X),
        (DVec3::ZERO, DVec3::Z, DVec3::X),
        (DVec3::Y, DVec3::X, DVec3::Z),
        (DVec3::ZERO, DVec3::Y, DVec3::Z),
        (DVec3::X, DVec3::Z, DVec3::Y),
    ];
    for (o, e1, e2) in walls {
        // A 3 x 3 grid of quads of unequal widths (0.3, 0.3, 0.4): the middle one is the centre.
        let cuts = [0.0, 0.3, 0.6, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                let m = if i == 1 && j == 1 { centre } else { ring };
                b.quad(
                    m,
                    o + e1 * cuts[i] + e2 * cuts[j],
                    e1 * (cuts[i + 1] - cuts[i]),
                    e2 * (cuts[j + 1] - cuts[j]),
                    1,
                );
            }
        }
    }
    let glb = b.to_glb();
    let mut probes = Vec::new();
    for &(u, v) in &[
        (0.1, 0.1),
        (0.45, 0.45),
        (0.7, 0.35),
        (0.02, 0.98),
        (0.29, 0.5),
    ] {
        probes.push(ProbePoint {
            p: [u, v, 0.0],
            n: [0.0, 0.0, 1.0],
        });
        probes.push(ProbePoint {
            p: [1.0, u, v],
            n: [-1.0, 0.0, 0.0],
        });
    }
    for mode in MODES {
        for order in [1, 2, 3] {
            let (prepared, sol) = solve(&glb, order, mode);
            if mode == DomainMode::Extended {
                assert!(sol.roots.iter().filter(|r| r.mask.is_some()).count() == 6);
            }
            let worst_mean = (0..sol.roots.len())
                .map(|i| (sol.mean_value(i)[0] - 2.0).abs() / 2.0)
                .fold(0.0, f64::max);
            let worst_probe = worst_furnace_probe(&prepared, &sol, &probes);
            println!(
                "holed furnace {mode:?} M{order}: worst face mean {:.3} %, worst probe {:.3} %",
                worst_mean * 100.0,
                worst_probe * 100.0
            );
            // Face means hold the furnace in both modes. Probes (this test's own, beyond the
            // issue's plain furnace): extended domains meet 0.5 % at M2 and M3 (0.17 / 0.13 %
            // measured), M1 comes near (0.68 %); the tessellated baseline misses it at the
            // triangles' corners around the holes (2.5 / 0.70 / 0.39 % measured): a small corner
            // triangle may carry a larger radiance error within the same power bound. Bounds at
            // their measured sizes.
            let mean_bound = if order == 1 { 0.01 } else { 0.005 };
            assert!(
                worst_mean <= mean_bound,
                "{mode:?} M{order}: a face mean is off by {worst_mean}"
            );
            let bound = match (mode, order) {
                (DomainMode::Extended, 1) => 0.008,
                (DomainMode::Extended, _) => 0.005,
                (DomainMode::Tessellated, 1) => 0.03,
                (DomainMode::Tessellated, _) => 0.01,
            };
            assert!(
                worst_probe <= bound,
                "{mode:?} M{order}: worst probe off by {worst_probe}"
            );
        }
    }
}

fn square(b: &mut SceneBuilder, m: u32, z: f64, facing_up: bool, hole: bool) {
    let (u, v) = if facing_up {
        (DVec3::X, DVec3::Y)
    } else {
        (DVec3::Y, DVec3::X)
    };
    let o = DVec3::new(-0.5, -0.5, z);
    if !hole {
        b.quad(m, o, u, v, 1);
        return;
    }
    // Four strips around the hole: [0,1]x[0,.25], [0,1]x[.75,1], [0,.25]x[.25,.75], [.75,1]x[.25,.75]
    // in (u, v) coordinates.
    b.quad(m, o, u, v * 0.25, 1);
    b.quad(m, o + v * 0.75, u, v * 0.25, 1);
    b.quad(m, o + v * 0.25, u * 0.25, v * 0.5, 1);
    b.quad(m, o + v * 0.25 + u * 0.75, u * 0.25, v * 0.5, 1);
}

#[test]
fn faces_with_holes_emit_and_receive_exactly() {
    for mode in MODES {
        for order in [1, 2, 3] {
            // A holed emitter over a full receiver.
            let mut b = SceneBuilder::new();
            let recv = b.material([1.0; 3], [0.0; 3], false);
            let emit = b.material([0.0; 3], [1.0; 3], false);
            square(&mut b, recv, 0.0, true, false);
            square(&mut b, emit, 1.0, false, true);
            let (prepared, sol) = solve(&b.to_glb(), order, mode);
            assert_eq!(
                prepared
                    .faces
                    .faces
                    .iter()
                    .filter(|f| f.holes.len() == 1)
                    .count(),
                1,
                "the emitter is one face with a hole"
            );
            // Extended mode solves it as one root on its domain, with the face as its mask;
            // tessellated mode as triangles.
            let emitter_roots: Vec<_> = sol.roots.iter().filter(|r| r.material == emit).collect();
            match mode {
                DomainMode::Extended => {
                    assert_eq!(emitter_roots.len(), 1);
                    assert!(emitter_roots[0].mask.is_some());
                    assert!((emitter_roots[0].face_area_m2 - 0.75).abs() < 1e-9);
                    assert!((emitter_roots[0].area_m2 - 1.0).abs() < 1e-9);
                }
                DomainMode::Tessellated => {
                    assert!(
                        emitter_roots.len() > 1 && emitter_roots.iter().all(|r| r.mask.is_none())
                    );
                }
            }
            check(
                &format!("{mode:?} M{order} holed emitter"),
                mean_radiance(&sol, recv),
                0.142710,
                0.01,
            );
            // A full emitter over a holed receiver.
            let mut b = SceneBuilder::new();
            let recv = b.material([1.0; 3], [0.0; 3], false);
            let emit = b.material([0.0; 3], [1.0; 3], false);
            square(&mut b, recv, 0.0, true, true);
            square(&mut b, emit, 1.0, false, false);
            let (_, sol) = solve(&b.to_glb(), order, mode);
            check(
                &format!("{mode:?} M{order} holed receiver"),
                mean_radiance(&sol, recv),
                0.190280,
                0.01,
            );
        }
    }
}

/// A ring of width `w` around a `1 - 2w` square hole, in the plane z = `z`, facing down.
fn ring_facing_down(b: &mut SceneBuilder, m: u32, z: f64, w: f64) {
    let (u, v) = (DVec3::Y, DVec3::X);
    let o = DVec3::new(-0.5, -0.5, z);
    b.quad(m, o, u, v * w, 1);
    b.quad(m, o + v * (1.0 - w), u, v * w, 1);
    b.quad(m, o + v * w, u * w, v * (1.0 - 2.0 * w), 1);
    b.quad(m, o + v * w + u * (1.0 - w), u * w, v * (1.0 - 2.0 * w), 1);
}

#[test]
fn an_eave_receives_the_light_of_the_walls_it_overhangs_in_both_modes() {
    // A closed box standing on a ground (rho = 0.5) under a sky panel; its roof overhangs the
    // walls as a ring (an eave) that looks down at the ground and along the walls. The ring fills
    // little of its extended domain, and the walls meet it inside the domain, not on an element
    // border: domain points over the roof see the walls from behind. Their stand-in on the face
    // must stand in for them in the kernel too, or the eave's elements average the walls' light
    // with nothing (it was 40 % too dark).
    for w in [0.1, 0.05] {
        let mean = |mode| {
            let mut b = SceneBuilder::new();
            let eave = b.material([1.0; 3], [0.0; 3], false);
            let sky = b.material([0.0; 3], [1.0; 3], false);
            let ground = b.material([0.5; 3], [0.0; 3], false);
            let roof = b.material([1.0; 3], [0.0; 3], false);
            let wall = b.material([0.5; 3], [0.0; 3], false);
            b.quad(
                ground,
                DVec3::new(-1.0, -1.0, 0.0),
                DVec3::X * 2.0,
                DVec3::Y * 2.0,
                1,
            );
            b.quad(
                sky,
                DVec3::new(-1.5, -1.5, 1.2),
                DVec3::Y * 3.0,
                DVec3::X * 3.0,
                1,
            );
            ring_facing_down(&mut b, eave, 1.0, w);
            let h = 0.5 - w;
            let (x, y, z) = (DVec3::X * 2.0 * h, DVec3::Y * 2.0 * h, DVec3::Z);
            b.quad(roof, DVec3::new(-h, -h, 1.0), y, x, 1);
            let lo = DVec3::new(-h, -h, 0.0);
            b.quad(wall, lo, z, y, 1); // -x, facing out
            b.quad(wall, lo + x, y, z, 1); // +x
            b.quad(wall, lo, x, z, 1); // -y
            b.quad(wall, lo + y, z, x, 1); // +y
            let (_, sol) = solve(&b.to_glb(), 2, mode);
            mean_radiance(&sol, eave)
        };
        let (extended, tessellated) = (mean(DomainMode::Extended), mean(DomainMode::Tessellated));
        check(
            &format!("eave of width {w}, extended against tessellated"),
            extended,
            tessellated,
            0.08,
        );
    }
}

/// A 3 x 3 m sky panel (L_e = 1, facing down) 19 cm over a black wall whose top meets a black
/// eave 5 cm deep: the eave's shadow on the wall's top is sharp, the sky large and grazing.
const SKY_Y: f64 = 1.84;
const EAVE_Y: f64 = 1.65;

/// A scene with a 3 x 3 m sky panel (L_e = 1, facing down, centred over the origin) at height
/// `sky_y`, and a black material (returned) for the rest.
fn under_a_sky(sky_y: f64) -> (SceneBuilder, u32) {
    let mut b = SceneBuilder::new();
    let sky = b.material([0.0; 3], [1.0; 3], false);
    let black = b.material([0.0; 3], [0.0; 3], false);
    b.quad(
        sky,
        DVec3::new(-1.5, sky_y, -1.5),
        DVec3::X * 3.0,
        DVec3::Z * 3.0,
        1,
    );
    (b, black)
}

fn eave_scene() -> Vec<u8> {
    let (mut b, black) = under_a_sky(SKY_Y);
    // The wall, z = -0.4, facing -z; the eave over it, facing down, 5 cm past the wall.
    b.quad(
        black,
        DVec3::new(-0.4, 0.0, -0.4),
        DVec3::Y * EAVE_Y,
        DVec3::X * 0.8,
        1,
    );
    b.quad(
        black,
        DVec3::new(-0.45, EAVE_Y, -0.45),
        DVec3::X * 0.9,
        DVec3::Z * 0.9,
        1,
    );
    b.to_glb()
}

/// The form factor at point `x` of a wall facing -z of a 3 x 3 m sky panel (facing down, centred
/// over the origin) at height `sky_y`, by brute force: the sky on a fine grid, without the samples
/// `q` that `blocked(x, q)` says are hidden.
fn wall_sky_form_factor(x: DVec3, sky_y: f64, blocked: impl Fn(DVec3, DVec3) -> bool) -> f64 {
    let n = 600;
    let cell = 9.0 / (n * n) as f64;
    let mut f = 0.0;
    for i in 0..n {
        for j in 0..n {
            let q = DVec3::new(
                -1.5 + 3.0 * (i as f64 + 0.5) / n as f64,
                sky_y,
                -1.5 + 3.0 * (j as f64 + 0.5) / n as f64,
            );
            let d = q - x;
            let r2 = d.length_squared();
            let (cos_x, cos_q) = (-d.z / r2.sqrt(), d.y / r2.sqrt());
            if cos_x <= 0.0 || cos_q <= 0.0 || blocked(x, q) {
                continue;
            }
            f += cos_x * cos_q / (std::f64::consts::PI * r2) * cell;
        }
    }
    f
}

/// The sky's visible form factor at wall point `x` (normal -z) under the eave, whose rectangle
/// each sample's ray is tested against analytically.
fn visible_sky_form_factor(x: DVec3) -> f64 {
    wall_sky_form_factor(x, SKY_Y, |x, q| {
        // Where the ray crosses the eave's plane: inside its rectangle, it is blocked.
        let c = x + (q - x) * ((EAVE_Y - x.y) / (q.y - x.y));
        c.x.abs() <= 0.45 && c.z.abs() <= 0.45
    })
}

/// `glb` solved for irradiance (`H / pi`) at `order`, extended, with or without the node-sum check.
fn solve_irradiance(glb: &[u8], order: usize, node_sums: bool) -> (Prepared, Solution) {
    let scene = load_scene(glb, &ExternalFiles::Refuse, 1000).expect("scene loads");
    let params = SolverParams {
        order,
        node_sums,
        quantity: wavrad::solver::Quantity::Irradiance,
        ..Default::default()
    };
    bake(
        &scene,
        DomainMode::Extended,
        params,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .expect("bakes")
}

/// RMS and worst error of the solved `H / pi` (the visible form factor, L_e = 1) against
/// `exact` at the wall points `points`.
fn eave_shadow_errors(
    glb: &[u8],
    order: usize,
    node_sums: bool,
    points: &[DVec3],
    exact: &[f64],
) -> (f64, f64) {
    let (prepared, sol) = solve_irradiance(glb, order, node_sums);
    let probes: Vec<ProbePoint> = points
        .iter()
        .map(|p| ProbePoint {
            p: p.to_array(),
            n: [0.0, 0.0, -1.0],
        })
        .collect();
    let errors: Vec<f64> = evaluate_probes(&sol, &probes, prepared.diagonal)
        .iter()
        .zip(exact)
        .map(|(v, e)| v.l.expect("on the wall")[0] - e)
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    (rms, errors.iter().fold(0.0, |m, e| m.max(e.abs())))
}

#[test]
fn an_eaves_shadow_on_a_wall_is_resolved_under_a_large_sky() {
    // The sky is split for its visibility into many links, each too small to refine the wall,
    // while together they draw the shadow's edge across one element: judging each node on the
    // sum of its links resolves it. The points run down the top 15 cm of the wall, where the
    // sky's visible form factor falls from 0.31 to 0 (at 9 mm under the eave).
    let glb = eave_scene();
    let points: Vec<DVec3> = (0..16)
        .flat_map(|i| {
            let y = EAVE_Y - 0.004 - 0.146 * (i as f64 / 15.0).powi(2);
            [DVec3::new(0.1, y, -0.4), DVec3::new(-0.27, y, -0.4)]
        })
        .collect();
    let exact: Vec<f64> = points.iter().map(|&p| visible_sky_form_factor(p)).collect();
    for order in [1, 2, 3] {
        let (rms_on, worst_on) = eave_shadow_errors(&glb, order, true, &points, &exact);
        let (rms_off, worst_off) = eave_shadow_errors(&glb, order, false, &points, &exact);
        println!(
            "eave shadow M{order}: rms {rms_on:.4} worst {worst_on:.4} with node sums; \
             rms {rms_off:.4} worst {worst_off:.4} without"
        );
        if order > 1 {
            // M1's constants are judged coarser still; its figure is printed, not held.
            // Measured: M2 0.0081 against 0.0364, M3 0.0055 against 0.0094.
            assert!(rms_on <= 0.7 * rms_off, "M{order}: {rms_on} vs {rms_off}");
            assert!(rms_on <= 0.012, "M{order}: rms {rms_on}");
        }
    }
}

/// A 1 m emitter tilted over the corner of a 20 m wall, facing the corner: the wall's quadrature
/// points all lie behind the emitter's plane, so from them the emitter is invisible, while the
/// corner beyond it is lit. Returns the glb, the emitter's corners and its normal.
fn tilted_emitter_over_a_wall_corner() -> (Vec<u8>, [DVec3; 4], DVec3) {
    let mut b = SceneBuilder::new();
    let wall = b.material([1.0; 3], [0.0; 3], false);
    let emit = b.material([0.0; 3], [1.0; 3], false);
    b.quad(
        wall,
        DVec3::new(-10.0, -10.0, 0.0),
        DVec3::X * 20.0,
        DVec3::Y * 20.0,
        1,
    );
    let normal = DVec3::new(1.0, 1.0, -1.2).normalize();
    let u = normal.cross(DVec3::Z).normalize();
    let v = normal.cross(u);
    let centre = DVec3::new(8.5, 8.5, 0.6);
    let origin = centre - (u + v) * 0.5;
    b.quad(emit, origin, u, v, 1);
    let corners = [origin, origin + u, origin + u + v, origin + v];
    (b.to_glb(), corners, normal)
}

#[test]
fn an_emitter_behind_which_a_walls_points_all_lie_still_lights_the_wall() {
    let (glb, emitter, normal) = tilted_emitter_over_a_wall_corner();
    // Every rule point of the wall's root (the 3 x 3 Gauss points at M2, +-7.75 m) is behind the
    // emitter's plane; the lit region is the corner beyond x + y = 16.3.
    assert!(normal.dot(DVec3::new(7.75, 7.75, 0.0) - DVec3::new(8.5, 8.5, 0.6)) < 0.0);
    let wall_polygon = [
        DVec3::new(-10.0, -10.0, 0.0),
        DVec3::new(10.0, -10.0, 0.0),
        DVec3::new(10.0, 10.0, 0.0),
        DVec3::new(-10.0, 10.0, 0.0),
    ];
    // Exact: the wall's mean radiance (rho = 1) is A_e F_ew / A_wall, with F_ew the emitter's
    // form factor to the wall, integrated over the emitter with the closed-form point-polygon
    // form factor on a fine midpoint grid.
    let n = 200;
    let (e1, e2) = (emitter[1] - emitter[0], emitter[3] - emitter[0]);
    let f_ew: f64 = (0..n * n)
        .map(|k| {
            let y = emitter[0]
                + e1 * ((k % n) as f64 + 0.5) / n as f64
                + e2 * ((k / n) as f64 + 0.5) / n as f64;
            kernel::point_polygon_form_factor(y, normal, &wall_polygon)
        })
        .sum::<f64>()
        / (n * n) as f64;
    let exact_mean = f_ew / 400.0;
    // Probes in the lit corner: L = the emitter's form factor from the point (rho = 1, L_e = 1).
    let probes: Vec<ProbePoint> = [(9.5, 9.0), (9.0, 9.5), (9.6, 9.6), (9.8, 8.8), (8.6, 9.4)]
        .iter()
        .map(|&(x, y)| ProbePoint {
            p: [x, y, 0.0],
            n: [0.0, 0.0, 1.0],
        })
        .collect();
    for mode in MODES {
        for order in [1, 2, 3] {
            let (prepared, sol) = solve(&glb, order, mode);
            let wall = sol
                .roots
                .iter()
                .position(|r| r.normal.z > 0.5)
                .expect("the wall");
            check(
                &format!("{mode:?} M{order}: wall mean radiance"),
                sol.mean_value(wall)[0],
                exact_mean,
                0.02,
            );
            let values = evaluate_probes(&sol, &probes, prepared.diagonal);
            for (p, v) in probes.iter().zip(&values) {
                let exact = kernel::point_polygon_form_factor(DVec3::from(p.p), DVec3::Z, &emitter);
                let got = v.l.expect("on the wall")[0];
                println!("  {:?}: {got:.5} (exact {exact:.5})", p.p);
                // Measured: M1 within 3 %, M2 and M3 within 0.15 %.
                let bound = if order == 1 { 0.05 } else { 0.01 };
                assert!(
                    (got - exact).abs() <= bound * exact,
                    "{mode:?} M{order} at {:?}: {got} vs {exact}",
                    p.p
                );
            }
        }
    }
}

/// A 3 x 3 m sky panel (L_e = 1, facing down) 15 cm over the base of a small black box
/// (15 x 2.5 x 15 cm) whose front (facing -z, 30 cm from the sky's centre line) looks at a black
/// parapet 7.5 cm high 10 cm in front of it: the front sees the sky through a strip about 22 cm
/// deep, between the sky's rule points and its corner probes, which the parapet or the box all
/// hide.
const STRIP_SKY_Y: f64 = 0.15;
const BOX_FRONT_Z: f64 = 0.3;
const PARAPET_Z: f64 = 0.2;
const PARAPET_TOP: f64 = 0.075;

fn parapet_scene() -> Vec<u8> {
    let (mut b, black) = under_a_sky(STRIP_SKY_Y);
    // The box: front (the face under test), top, back and sides, all facing out.
    let (o, w, h, d) = (
        DVec3::new(-0.075, 0.0, BOX_FRONT_Z),
        DVec3::X * 0.15,
        DVec3::Y * 0.025,
        DVec3::Z * 0.15,
    );
    b.quad(black, o, h, w, 1);
    b.quad(black, o + h, d, w, 1);
    b.quad(black, o + d, w, h, 1);
    b.quad(black, o, d, h, 1);
    b.quad(black, o + w, h, d, 1);
    // The parapet, facing the box.
    b.quad(
        black,
        DVec3::new(-1.5, 0.0, PARAPET_Z),
        DVec3::X * 3.0,
        DVec3::Y * PARAPET_TOP,
        1,
    );
    b.to_glb()
}

/// The sky's form factor at point `x` of the box's front (normal -z) over the parapet, each
/// sample's ray tested against the parapet analytically.
fn sky_over_the_parapet(x: DVec3) -> f64 {
    wall_sky_form_factor(x, STRIP_SKY_Y, |x, q| {
        // Beyond the parapet: the ray crosses its plane below its top, it is blocked.
        q.z < PARAPET_Z && {
            let c = x + (q - x) * ((PARAPET_Z - x.z) / (q.z - x.z));
            c.y <= PARAPET_TOP && c.x.abs() <= 1.5
        }
    })
}

#[test]
fn a_small_face_sees_a_large_sky_through_a_strip_over_a_parapet() {
    // Every ray from the front's rule points and corners to the sky's rule points and corners is
    // blocked (by the parapet, or, behind the front's plane, by the box), yet the sky above the
    // gap lights the front: rays spread over both elements find the strip.
    let glb = parapet_scene();
    // Exact: the front's mean visible form factor, on a midpoint grid.
    let (nx, ny) = (12, 4);
    let exact = (0..nx * ny)
        .map(|k| {
            let x = -0.075 + 0.15 * ((k % nx) as f64 + 0.5) / nx as f64;
            let y = 0.025 * ((k / nx) as f64 + 0.5) / ny as f64;
            sky_over_the_parapet(DVec3::new(x, y, BOX_FRONT_Z))
        })
        .sum::<f64>()
        / (nx * ny) as f64;
    for order in [1, 2, 3] {
        let (_, sol) = solve_irradiance(&glb, order, true);
        let front = sol
            .roots
            .iter()
            .position(|r| r.normal.z < -0.5 && r.face_area_m2 < 0.01)
            .expect("the box's front");
        // Measured: M1 -3.1 %, M2 +0.41 %, M3 -0.11 % (without the spread rays: 0 at every
        // order). M1's constants over the strip's partial links stay within the power budget.
        let bound = if order == 1 { 0.05 } else { 0.01 };
        check(
            &format!("M{order}: the box front's mean H / pi"),
            sol.mean_value(front)[0],
            exact,
            bound,
        );
    }
}

/// Tiles with gaps between them, facing up (a floor) and down (a ceiling), two posts between, and
/// a small emitter in the ceiling: small roots that light one another shot after shot, some of
/// them far enough apart for far links (`far_field.rs`).
fn tiled_room() -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let grey = b.material([0.7; 3], [0.0; 3], false);
    let lamp = b.material([0.0; 3], [5.0; 3], false);
    let (k, pitch, tile) = (8, 0.5, 0.3);
    for i in 0..k {
        for j in 0..k {
            let (x, y) = (f64::from(i) * pitch, f64::from(j) * pitch);
            b.quad(
                grey,
                DVec3::new(x, y, 0.0),
                DVec3::X * tile,
                DVec3::Y * tile,
                1,
            );
            b.quad(
                grey,
                DVec3::new(x, y, 2.0),
                DVec3::Y * tile,
                DVec3::X * tile,
                1,
            );
        }
    }
    lamp_and_pillars(&mut b, lamp, grey, 1.9);
    b.to_glb()
}

/// A small square lamp facing down at height `z` over the middle of a 4 m room, and two pillars
/// (of `grey`) beside it that shadow the floor.
fn lamp_and_pillars(b: &mut SceneBuilder, lamp: u32, grey: u32, z: f64) {
    b.quad(
        lamp,
        DVec3::new(1.9, 1.9, z),
        DVec3::Y * 0.2,
        DVec3::X * 0.2,
        1,
    );
    for x in [1.2, 2.7] {
        b.inward_box(
            [grey; 6],
            DVec3::new(x, 1.7, 0.1),
            DVec3::new(x + 0.2, 1.9, 1.8),
            1,
        );
    }
}

/// A closed grey room (six walls of one quad each, rho 0.8) lit by a small ceiling lamp, with
/// the tiled room's two pillars casting shadows and a low table with a square hole (a face
/// solved on its extended domain, so partly covered elements shoot and receive): few roots,
/// each shooting many times.
fn pillar_room() -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let grey = b.material([0.8; 3], [0.0; 3], false);
    let lamp = b.material([0.0; 3], [5.0; 3], false);
    b.inward_box([grey; 6], DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0), 1);
    lamp_and_pillars(&mut b, lamp, grey, 1.99);
    // The table: [0.3, 3.7]^2 less [1.5, 2.5]^2 at z = 0.05, facing up, in eight triangles.
    let z = 0.05;
    let at = |x: f64, y: f64| DVec3::new(x, y, z);
    let (o0, o1, i0, i1) = (0.3, 3.7, 1.5, 2.5);
    let ring = [
        at(o0, o0),
        at(o1, o0),
        at(o1, o1),
        at(o0, o1),
        at(i0, i0),
        at(i1, i0),
        at(i1, i1),
        at(i0, i1),
    ];
    let indices = [
        0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7,
    ];
    b.mesh(grey, &ring, &indices);
    b.to_glb()
}

/// The scene `glb` solved with the default parameters but for `change`.
fn solve_room(glb: &[u8], change: impl FnOnce(&mut SolverParams)) -> Solution {
    let scene = load_scene(glb, &ExternalFiles::Refuse, 1000).expect("scene loads");
    let mut params = SolverParams::default();
    change(&mut params);
    let cancel = AtomicBool::new(false);
    bake(&scene, DomainMode::Extended, params, &cancel, &mut |_| {})
        .expect("bakes")
        .1
}

/// Two solves of a room that must be the same but for their rays (`kept` reads verdicts
/// back that `traced` traces): the same shots, links, elements and radiosity everywhere, and
/// fewer rays in `kept`, after more than `shots` shots. Returns the two ray counts.
fn assert_same_light_fewer_rays(kept: &Solution, traced: &Solution, shots: u64) -> (u64, u64) {
    let (a, b) = (&kept.stats, &traced.stats);
    println!(
        "shots {} links {} elements {}; rays {} kept, {} traced",
        a.iterations, a.links, a.elements, a.rays, b.rays
    );
    assert!(a.iterations > shots, "the room needs many indirect shots");
    assert_eq!(
        (a.iterations, a.links, a.elements),
        (b.iterations, b.links, b.elements)
    );
    assert_eq!(kept.roots.len(), traced.roots.len());
    for root in 0..kept.roots.len() {
        for st in [(0.1, 0.1), (0.5, 0.5), (0.3, 0.8), (0.9, 0.2)] {
            let st = glam::DVec2::new(st.0, st.1);
            assert_eq!(
                kept.value_at(root, st),
                traced.value_at(root, st),
                "root {root}"
            );
        }
    }
    assert!(a.rays < b.rays, "{} rays against {}", a.rays, b.rays);
    (a.rays, b.rays)
}

/// The far links' verdicts kept between a root's shots (`far_verdicts.rs`) change no light:
/// with the tables and without (a budget of 0 bytes), the same shots, links, elements and
/// radiosity everywhere, and fewer rays with them (a few here, where most links are near ones;
/// the 70k-triangle level's figures are in docs/performance-notes.md).
#[test]
fn far_link_verdicts_kept_between_shots_change_no_light_and_save_rays() {
    let glb = tiled_room();
    let kept = solve_room(&glb, |_| {});
    let traced = solve_room(&glb, |p| p.far_verdict_bytes = 0);
    assert_same_light_fewer_rays(&kept, &traced, 100);
}

/// The near links' verdicts kept between a root's shots (`near_verdicts.rs`) change no light:
/// with the entries and without (a budget of 0 bytes), the same shots, links, elements and
/// radiosity at points of every root (the pillars cast shadows, so points' rays disagree among
/// themselves; the holed table is an extended root),
/// and at least a tenth fewer rays with them (the walls shoot again and again, and their near
/// links read what their earlier shots traced).
#[test]
fn near_link_verdicts_kept_between_shots_change_no_light_and_save_rays() {
    let glb = pillar_room();
    let coarse = |p: &mut SolverParams| p.tolerance = 1e-4;
    let kept = solve_room(&glb, coarse);
    let traced = solve_room(&glb, |p| {
        coarse(p);
        p.near_verdict_bytes = 0;
    });
    assert!(
        kept.roots.iter().any(|r| r.mask.is_some()),
        "the holed table is solved on its extended domain"
    );
    let (kept, traced) = assert_same_light_fewer_rays(&kept, &traced, 60);
    assert!(
        (kept as f64) < 0.9 * traced as f64,
        "{kept} rays against {traced}"
    );
}
