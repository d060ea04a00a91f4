//! The shooting loop (DESIGN.md 5.1): punctual lights shoot first, then emitters their emission
//! (direct shots), then the root with the most unshot power until the unshot ratio reaches the
//! target. Receivers of one shot are processed in parallel; the shooter is read-only meanwhile.
//!
//! Invariant: after every shot each root's unshot power is up to date and `dh` is clear.

use super::*;
/// Can any point of `a` (front side) see any point of `b` (front side)?
fn faces_each_other(a: &ElementRoot, b: &ElementRoot, eps: f64) -> bool {
    let ca = a.corners();
    let cb = b.corners();
    let b_in_front_of_a = cb.iter().any(|p| a.normal.dot(*p - ca[0]) > eps);
    let a_in_front_of_b = ca.iter().any(|p| b.normal.dot(*p - cb[0]) > eps);
    b_in_front_of_a && a_in_front_of_b
}

/// Runs the shooting loop. `observe` is called after every shot; `cancel` stops the solve at the
/// next check (between and inside shots).
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
        .map(|r| {
            let basis = bases.of(r.shape);
            let mut h = Hierarchy::new(basis.len());
            cover::extend(&mut h, r, &rules.cover, basis);
            node_reflectance::extend(&mut h, r);
            h
        })
        .collect();
    // Emitted power: exitance over each face (an extended root's domain emits only where its face is).
    let mut emitted = [0.0; 3];
    for r in &roots {
        for ch in 0..3 {
            emitted[ch] += r.exitance[ch] * r.face_area_m2;
        }
    }
    let links = AtomicU64::new(0);
    let capped = AtomicU64::new(0);
    let touching = AtomicU64::new(0);
    let node_sum_splits = AtomicU64::new(0);
    // A shadow ray towards a directional light ends this far away: beyond the scene.
    let far = 4.0 * diagonal;
    let light_estimate: f64 = lights
        .iter()
        .map(|l| lights::unoccluded_power_estimate(l, &roots, far))
        .sum();
    let threshold = params.tolerance * (mean_rgb_sum(emitted) + light_estimate);
    let min_edge = MIN_EDGE_REL * diagonal;
    let facing_eps = 1e-9 * diagonal;
    let mut convergence = Vec::new();
    let mut iterations = 0u64;

    // Punctual lights shoot first; what they deliver onto the surfaces counts as emitted.
    let mut stop = StopReason::Converged;
    for light in lights {
        if cancel.load(Ordering::Relaxed) {
            break;
        }
        let shot = lights::LightShot {
            roots: &roots,
            bases: &bases,
            rules: &rules,
            psi: &psi,
            visibility,
            light,
            threshold,
            min_edge,
            far,
            quantity: params.quantity,
            links: &links,
            capped: &capped,
            cancel,
        };
        hierarchies.par_iter_mut().enumerate().for_each(|(ri, h)| {
            if h.nodes.is_empty() {
                return;
            }
            shot.transfer(ri, h, 0);
            if h.touched {
                h.push_pull(bases.of(roots[ri].shape), roots[ri].rho, true);
            }
        });
        iterations += 1;
    }
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
    // Unshot power, counted over each face only (never over the empty part of a domain).
    let unshot_power =
        |h: &Hierarchy, r: &ElementRoot| -> f64 { mean_rgb_sum(face_integral(h, &h.u, r)) };

    // Emitters' unshot radiosity starts at their exitance; direct shots send it first.
    let mut direct_queue: Vec<usize> = (0..roots.len())
        .filter(|&i| mean_rgb_sum(roots[i].exitance) > 0.0)
        .collect();
    direct_queue.sort_by(|&a, &b| {
        (mean_rgb_sum(roots[b].exitance) * roots[b].face_area_m2)
            .total_cmp(&(mean_rgb_sum(roots[a].exitance) * roots[a].face_area_m2))
    });
    for &i in &direct_queue {
        // The emission is a constant: coefficient 0 of every node (what lights left unshot stays).
        let h = &mut hierarchies[i];
        let n = h.len;
        for node in 0..h.nodes.len() {
            for ch in 0..3 {
                h.u[node * n][ch] += roots[i].exitance[ch];
            }
        }
    }
    // Per root, its unshot power (kept up to date after every shot).
    let mut unshot: Vec<f64> = hierarchies
        .iter()
        .zip(&roots)
        .map(|(h, r)| unshot_power(h, r))
        .collect();
    let ratio = |unshot: &[f64]| {
        if emitted_total > 0.0 {
            unshot.iter().sum::<f64>() / emitted_total
        } else {
            0.0
        }
    };
    let mut direct_iter = direct_queue.into_iter();
    loop {
        let r = ratio(&unshot);
        let progress = Progress {
            iterations,
            unshot_ratio: r,
            elements: hierarchies.iter().map(|h| h.leaf_count() as u64).sum(),
            links: links.load(Ordering::Relaxed),
            seconds: start.elapsed().as_secs_f64(),
        };
        convergence.push(progress);
        observe(&progress);
        if cancel.load(Ordering::Relaxed) {
            stop = StopReason::Cancelled;
            break;
        }
        if params.max_seconds.is_some_and(|m| progress.seconds >= m) {
            stop = StopReason::TimeBudget;
            break;
        }
        if iterations >= params.max_iterations {
            stop = StopReason::IterationLimit;
            break;
        }
        // Pick the shooter: next direct emitter, else the root with most unshot power.
        let (shooter, direct) = match direct_iter.next() {
            Some(i) => (i, true),
            None => {
                if r <= params.target_unshot {
                    break;
                }
                let best = (0..roots.len()).max_by(|&a, &b| unshot[a].total_cmp(&unshot[b]));
                match best {
                    Some(b) if unshot[b] > 0.0 => (b, false),
                    _ => break,
                }
            }
        };
        let sbasis_len = bases.of(roots[shooter].shape).len();
        let source_h = std::mem::take(&mut hierarchies[shooter]);
        let mut root_coeffs = [[0.0; 3]; MAX_FUNCTIONS];
        if direct {
            // The emission alone (a constant), whatever else the emitter already received.
            root_coeffs[0] = roots[shooter].exitance;
        } else {
            root_coeffs[..sbasis_len].copy_from_slice(source_h.coeffs(&source_h.u, 0));
        }
        let cover = source_h.covers.first().copied();
        let source_face_means = if direct {
            None
        } else {
            roots[shooter]
                .mask
                .as_ref()
                .map(|_| cover::face_means(&source_h, &source_h.u))
        };
        let source = Source {
            face_mean: Source::face_mean(
                &root_coeffs[..sbasis_len],
                cover.as_ref(),
                source_face_means.as_ref().map(|m| m[0]),
            ),
            map: ChildMap::IDENTITY,
            depth: 0,
            node: Some(0),
            coeffs: root_coeffs,
            rings: partial_face_rings(&roots[shooter], &ChildMap::IDENTITY, cover.as_ref()),
            cover,
        };
        {
            let ctx = ShotContext {
                roots: &roots,
                bases: &bases,
                rules: &rules,
                psi: &psi,
                // Every shot: split links add up under a large emitter's shadows, and wherever a
                // later shot's source is split for its radiosity's detail (without the check on
                // those shots, the M1 furnace was 7 % off near its corners; README).
                node_sums: params.node_sums,
                visibility,
                source_root: shooter,
                source_hierarchy: &source_h,
                direct,
                source_face_means: source_face_means.as_deref(),
                threshold,
                min_edge,
                quantity: params.quantity,
                links: &links,
                capped: &capped,
                touching: &touching,
                node_sum_splits: &node_sum_splits,
                cancel,
            };
            hierarchies
                .par_iter_mut()
                .zip(unshot.par_iter_mut())
                .enumerate()
                .for_each(|(ri, (h, power))| {
                    if ri == shooter
                        || h.nodes.is_empty()
                        || !faces_each_other(&roots[shooter], &roots[ri], facing_eps)
                    {
                        return;
                    }
                    let mut record = ShotRecord::default();
                    ctx.transfer(&source, ri, h, 0, &mut record);
                    if ctx.node_sums {
                        ctx.refine_by_node_sums(record, ri, h);
                    }
                    if h.touched {
                        h.push_pull(bases.of(roots[ri].shape), roots[ri].rho, direct);
                        *power = unshot_power(h, &roots[ri]);
                    }
                });
        }
        hierarchies[shooter] = source_h;
        let hs = &mut hierarchies[shooter];
        if direct {
            // Remove exactly the emission that was shot; received light stays unshot.
            for ch in 0..3 {
                hs.u[0][ch] -= roots[shooter].exitance[ch];
            }
            // Keep deeper levels consistent: the emission is a constant, so only coefficient 0 of
            // every node changes by the same amount.
            let n = hs.len;
            for node in 1..hs.nodes.len() {
                for ch in 0..3 {
                    hs.u[node * n][ch] -= roots[shooter].exitance[ch];
                }
            }
        } else {
            hs.u.iter_mut().for_each(|c| *c = [0.0; 3]);
        }
        unshot[shooter] = unshot_power(hs, &roots[shooter]);
        iterations += 1;
    }
    let last = *convergence.last().expect("at least one progress row");
    let stats = SolveStats {
        iterations,
        links: links.load(Ordering::Relaxed),
        elements: last.elements,
        rays: visibility.rays_traced(),
        seconds: start.elapsed().as_secs_f64(),
        unshot_ratio: last.unshot_ratio,
        emitted_power: emitted,
        stop_reason: Some(stop),
        refinement_capped: capped.load(Ordering::Relaxed),
        touching_fallbacks: touching.load(Ordering::Relaxed),
        node_sum_splits: node_sum_splits.load(Ordering::Relaxed),
    };
    Solution {
        roots,
        hierarchies,
        params,
        stats,
        convergence,
        bases,
    }
}
