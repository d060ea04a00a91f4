//! The shooting loop (docs/design.md section 5.1) as named steps: shoot the lights (punctual
//! lights first; what they deliver counts as emitted), then report, pick the shooters and shoot
//! them (one pass: the next emitter's direct shot alone, else roots of the most unshot power that
//! face none of each other; `pass.rs`), clear what was shot; until the unshot ratio reaches the
//! target. Owns the solve's counters, its stopping rule and its statistics.
//!
//! Invariant: after every pass each root's unshot power (`unshot`) is up to date, every `dh` is
//! clear, and `u` holds exactly what is left to shoot (a direct shot removes only the emission);
//! no root of a pass receives from another of it.

use super::cover::face_integral;
use super::element::Sphere;
use super::eta::{ShotKind, ShotPlan};
use super::far_field;
use super::far_verdicts::FarVerdicts;
use super::forecast_inputs::foresee_indirect;
use super::hierarchy::Hierarchy;
use super::lights;
use super::near_verdicts::VerdictBudget;
use super::pass::{pick_shooters, shoot, unshot_power};
use super::progress::{with_reports, CostUnits, Reporter, ShotCounter};
use super::refine::ShotContext;
use super::rules::{Bases, BasisAtControlPoints, Rules};
use super::shot_record::{LinkBytes, ShotRecord};
use super::source::{LightShot, Rays};
use super::striped_count::StripedCount;
use super::visibility::Visibility;
use super::{mean_rgb_sum, Progress, Solution, SolveStats, SolverParams, StopReason, MIN_EDGE_REL};
use crate::domain::ElementRoot;
use crate::scene::{PunctualLight, Rgb};
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Counters shared by every shot.
#[derive(Default)]
struct Counters {
    links: StripedCount,
    capped: AtomicU64,
    touching: AtomicU64,
    node_sum_splits: AtomicU64,
    link_records: Mutex<LinkBytes>,
}

/// Runs the shooting loop. `observe` is called after every pass of shots, and from within a
/// long pass (`Progress`); `cancel` stops the solve at the next check (between and inside
/// passes).
pub fn solve(
    roots: Vec<ElementRoot>,
    lights: &[PunctualLight],
    visibility: &Visibility,
    diagonal: f64,
    params: SolverParams,
    cancel: &AtomicBool,
    observe: &mut dyn FnMut(&Progress),
) -> Solution {
    let start = Instant::now();
    let bases = Bases::new(params.order);
    let rules = Rules::new(params.order);
    let psi = BasisAtControlPoints::new(&bases, &rules);
    let mut hierarchies: Vec<Hierarchy> = roots
        .iter()
        .map(|r| Hierarchy::of_root(r, bases.of(r.shape), &rules.cover))
        .collect();
    let mut emitted = emitted_power(&roots);
    let counters = Counters::default();
    let spheres: Vec<Sphere> = roots.iter().map(Sphere::of_root).collect();
    let link_points: Vec<DVec3> = roots.iter().map(far_field::link_point).collect();
    let near_verdicts = VerdictBudget::new(params.near_verdict_bytes);
    // A shadow ray towards a directional light ends this far away: beyond the scene.
    let far = 4.0 * diagonal;
    let light_estimate: f64 = lights
        .iter()
        .map(|l| lights::unoccluded_power_estimate(l, &roots, far))
        .sum();
    let ctx = ShotContext {
        roots: &roots,
        bases: &bases,
        rules: &rules,
        psi: &psi,
        // Lights' shots are judged link by link; element shots set this from the parameters.
        node_sums: false,
        split_in_parallel: false,
        visibility,
        threshold: params.tolerance * (mean_rgb_sum(emitted) + light_estimate),
        detail_threshold: params.tolerance * (mean_rgb_sum(emitted) + light_estimate),
        min_edge: MIN_EDGE_REL * diagonal,
        quantity: params.quantity,
        links: &counters.links,
        capped: &counters.capped,
        touching: &counters.touching,
        node_sum_splits: &counters.node_sum_splits,
        link_records: &counters.link_records,
        cancel,
        deadline: params
            .max_seconds
            .and_then(|m| start.checked_add(std::time::Duration::try_from_secs_f64(m).ok()?)),
        spheres: &spheres,
        link_points: &link_points,
        near_verdicts: &near_verdicts,
    };
    let mut convergence = Vec::new();
    let mut reporter = Reporter::new(
        start,
        observe,
        &counters.links,
        visibility,
        &params,
        roots.len(),
    );
    let mut iterations = shoot_lights(&ctx, lights, far, &mut hierarchies, &mut reporter);
    if !lights.is_empty() {
        // What the lights delivered: direct irradiance integrated over each face.
        for (h, r) in hierarchies.iter().zip(&roots) {
            let delivered = face_integral(h, &h.hd, r);
            for ch in 0..3 {
                emitted[ch] += delivered[ch];
            }
        }
    }
    let emitted_total = mean_rgb_sum(emitted);
    let direct_queue = emitters_to_shoot(&roots, &mut hierarchies);
    // Per root, its unshot power (kept up to date after every shot).
    let mut unshot: Vec<f64> = hierarchies
        .iter()
        .zip(&roots)
        .map(|(h, r)| unshot_power(h, r))
        .collect();
    let ctx = ShotContext {
        // Every shot: split links add up under a large emitter's shadows, and wherever a later
        // shot's source is split for its radiosity's detail (without the check on those shots,
        // the M1 furnace was 7 % off near its corners; README).
        node_sums: params.node_sums,
        ..ctx
    };
    let facing_eps = 1e-9 * diagonal;
    let mut direct_left = direct_queue.len();
    let mut direct_iter = direct_queue.into_iter();
    // What the ratio is taken against: the emitted power until the direct shots are done, then
    // the direct light the surfaces received (`received_direct`).
    let mut ratio_base = if direct_left == 0 {
        received_direct(&hierarchies, &roots)
    } else {
        emitted_total
    };
    let mut stop = StopReason::Converged;
    let mut far_verdicts = FarVerdicts::new(roots.len(), params.far_verdict_bytes);
    // Shots of the last pass (the first row stands for the start).
    let mut pass_shots = 1;
    loop {
        let ratio = unshot_ratio(&unshot, ratio_base);
        let elements = hierarchies.iter().map(leaf_count).sum();
        let progress = reporter.after_shot(iterations, ratio, ratio_base, elements);
        // One row per shot: the shots of a pass end together.
        convergence.extend((0..pass_shots).rev().map(|before| Progress {
            iterations: iterations - before,
            ..progress
        }));
        if let Some(reason) = must_stop(&progress, &params, cancel) {
            stop = reason;
            break;
        }
        let Some((shooters, direct)) = pick_shooters(
            &mut direct_iter,
            &unshot,
            (
                ratio,
                params.target_unshot,
                params.max_iterations.saturating_sub(iterations),
            ),
            (&roots, &spheres),
            facing_eps,
        ) else {
            break;
        };
        let kind = if direct {
            ShotKind::Direct {
                left: direct_iter.len(),
            }
        } else {
            ShotKind::Indirect
        };
        let completed = shoot(
            &ctx,
            (&shooters, kind),
            facing_eps,
            params.target_unshot,
            (&mut hierarchies, &mut unshot, &mut far_verdicts),
            (&mut reporter, iterations),
        );
        if !completed {
            // The budget ended within the pass: the receivers it reached keep their light, the
            // shooters keep their unshot power (the ratio stays an upper bound), and the check
            // at the top of the loop stops the solve.
            pass_shots = 1;
            continue;
        }
        for &s in &shooters {
            clear_unshot(&mut hierarchies[s], &roots[s], direct);
            unshot[s] = unshot_power(&hierarchies[s], &roots[s]);
        }
        iterations += shooters.len() as u64;
        pass_shots = shooters.len() as u64;
        if direct {
            direct_left -= 1;
            if direct_left == 0 {
                ratio_base = received_direct(&hierarchies, &roots);
                // The indirect phase foreseen from what the direct phase left.
                let target = params.target_unshot * ratio_base;
                let f = foresee_indirect(&ctx, &hierarchies, &unshot, target, facing_eps);
                reporter.indirect_foreseen(f);
            }
        }
    }
    tracing::debug!(bytes = far_verdicts.bytes(), "far links' verdicts kept");
    tracing::debug!(bytes = near_verdicts.used(), "near links' verdicts kept");
    for h in &mut hierarchies {
        h.forget_solve_caches();
    }
    let last = *convergence.last().expect("at least one progress row");
    let stats = SolveStats {
        iterations,
        links: counters.links.get(),
        elements: last.elements,
        rays: visibility.rays_traced(),
        seconds: start.elapsed().as_secs_f64(),
        unshot_ratio: last.unshot_ratio,
        emitted_power: emitted,
        stop_reason: Some(stop),
        refinement_capped: counters.capped.load(Ordering::Relaxed),
        touching_fallbacks: counters.touching.load(Ordering::Relaxed),
        node_sum_splits: counters.node_sum_splits.load(Ordering::Relaxed),
        bytes_per_element: bytes_per(
            hierarchies.iter().map(Hierarchy::bytes).sum(),
            last.elements,
        ),
        bytes_per_link: {
            let peak = *counters
                .link_records
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            bytes_per(peak.bytes, peak.links)
        },
    };
    Solution::new(roots, hierarchies, params, stats, convergence, bases)
}

/// `bytes / count`, 0 when nothing was counted.
fn bytes_per(bytes: u64, count: u64) -> f64 {
    if count == 0 {
        0.0
    } else {
        bytes as f64 / count as f64
    }
}

/// Emitted power: exitance over each face (an extended root's domain emits only where its face is).
fn emitted_power(roots: &[ElementRoot]) -> Rgb {
    let mut emitted = [0.0; 3];
    for r in roots {
        for ch in 0..3 {
            emitted[ch] += r.exitance[ch] * r.face_area_m2;
        }
    }
    emitted
}

/// The direct light (from emitters and punctual lights) the surfaces received, in W: the
/// stopping rule's base once the direct shots are done. In a closed scene it is the emitted power;
/// under a sky most of the emitted power leaves the scene, and unshot / emitted would understate
/// what is left to bounce inside (docs/design.md section 5.1; `tests/stopping_rule.rs`
/// `the_stopping_rule_counts_the_light_that_stays_in_an_open_scene`).
fn received_direct(hierarchies: &[Hierarchy], roots: &[ElementRoot]) -> f64 {
    hierarchies
        .iter()
        .zip(roots)
        .map(|(h, r)| mean_rgb_sum(face_integral(h, &h.hd, r)))
        .sum()
}

fn unshot_ratio(unshot: &[f64], base: f64) -> f64 {
    if base > 0.0 {
        unshot.iter().sum::<f64>() / base
    } else {
        0.0
    }
}

/// Leaf elements of a hierarchy, from its node count alone: every split turns one leaf into four.
fn leaf_count(h: &Hierarchy) -> u64 {
    let leaves = (h.nodes.len() as u64 * 3).div_ceil(4);
    debug_assert_eq!(leaves, h.leaf_count() as u64);
    leaves
}

/// Each punctual light shoots onto every receiver; returns the shots taken. A long shot reports
/// from within to `reporter`.
fn shoot_lights(
    ctx: &ShotContext,
    lights: &[PunctualLight],
    far: f64,
    hierarchies: &mut [Hierarchy],
    reporter: &mut Reporter,
) -> u64 {
    let mut shots = 0;
    let rho = mean_reflectance(ctx.roots);
    for light in lights {
        if ctx.cancel.load(Ordering::Relaxed) {
            break;
        }
        let shot = LightShot {
            light,
            far,
            visibility: ctx.visibility,
        };
        // What comes back of a light is taken as its power times the mean reflectance (its
        // receivers are not weighed: each counts one).
        let power = lights::unoccluded_power_estimate(light, ctx.roots, far);
        reporter.shot_started(
            shots,
            ShotPlan {
                kind: ShotKind::Light {
                    left: lights.len() - 1 - shots as usize,
                },
                power,
                returns: power * rho,
            },
        );
        let receivers = hierarchies.iter().filter(|h| !h.nodes.is_empty()).count() as u64;
        let units = CostUnits::new(receivers as f64);
        let hs = &mut *hierarchies;
        let work = |done: &ShotCounter| {
            hs.par_iter_mut().enumerate().for_each(|(ri, h)| {
                if h.nodes.is_empty() {
                    return;
                }
                let root = &ctx.roots[ri];
                ctx.transfer(
                    &shot,
                    &(),
                    ri,
                    h,
                    0,
                    &mut ShotRecord::default(),
                    Rays::Trace,
                );
                if h.touched {
                    h.push_pull(ctx.bases.of(root.shape), root.rho, true);
                }
                done.finished(units.of(1.0), 0, 0);
            })
        };
        with_reports(work, &mut |c| reporter.within_shot(c, receivers));
        shots += 1;
    }
    shots
}

/// Emitters' unshot radiosity starts at their exitance (what lights left unshot stays); returns
/// them in the order their direct shots go: most emitted power first.
fn emitters_to_shoot(roots: &[ElementRoot], hierarchies: &mut [Hierarchy]) -> Vec<usize> {
    let mut queue: Vec<usize> = (0..roots.len())
        .filter(|&i| mean_rgb_sum(roots[i].exitance) > 0.0)
        .collect();
    queue.sort_by(|&a, &b| {
        (mean_rgb_sum(roots[b].exitance) * roots[b].face_area_m2)
            .total_cmp(&(mean_rgb_sum(roots[a].exitance) * roots[a].face_area_m2))
    });
    for &i in &queue {
        // The emission is a constant: coefficient 0 of every node.
        add_to_unshot_constant(&mut hierarchies[i], roots[i].exitance, 1.0);
    }
    queue
}

/// Adds `sign * c` to the constant coefficient of every node's unshot radiosity.
fn add_to_unshot_constant(h: &mut Hierarchy, c: Rgb, sign: f64) {
    let n = h.len;
    for node in 0..h.nodes.len() {
        for ch in 0..3 {
            if sign > 0.0 {
                h.u[node * n][ch] += c[ch];
            } else {
                h.u[node * n][ch] -= c[ch];
            }
        }
    }
}

/// Why the loop must stop before the next shot, if it must (convergence is `pick_shooters`'s).
fn must_stop(
    progress: &Progress,
    params: &SolverParams,
    cancel: &AtomicBool,
) -> Option<StopReason> {
    if cancel.load(Ordering::Relaxed) {
        Some(StopReason::Cancelled)
    } else if params.max_seconds.is_some_and(|m| progress.seconds >= m) {
        Some(StopReason::TimeBudget)
    } else if progress.iterations >= params.max_iterations {
        Some(StopReason::IterationLimit)
    } else {
        None
    }
}

/// After a shot, what the shooter shot is no longer unshot: on a direct shot exactly the emission
/// (received light stays unshot), else everything.
fn clear_unshot(h: &mut Hierarchy, root: &ElementRoot, direct: bool) {
    if direct {
        // The emission is a constant: coefficient 0 of every node changes by the same amount.
        add_to_unshot_constant(h, root.exitance, -1.0);
    } else {
        h.u.iter_mut().for_each(|c| *c = [0.0; 3]);
    }
}

/// The roots' mean reflectance, weighted by their face areas.
fn mean_reflectance(roots: &[ElementRoot]) -> f64 {
    let area: f64 = roots.iter().map(|r| r.face_area_m2).sum();
    if area <= 0.0 {
        return 0.0;
    }
    roots
        .iter()
        .map(|r| mean_rgb_sum(r.rho) / 3.0 * r.face_area_m2)
        .sum::<f64>()
        / area
}
