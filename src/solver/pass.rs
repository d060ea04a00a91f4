//! One pass of shooters: which roots shoot together (`pick_shooters`: the next emitter's direct
//! shot alone, else the root with the most unshot power and roots of at least half its power that
//! face none of the pass's others), the plan over the receivers (what each would get with no
//! occluder: the cost weights of the progress and the ETA, and at the first direct shot the
//! indirect phase foreseen from it, `forecast_inputs.rs`; and which shooters it takes as one far
//! link, decided there once for the loop), and the parallel loop in which every
//! receiver takes each shooter's light (a far link, or links refined and judged on their nodes'
//! sums).
//!
//! Invariants: no root of a pass receives from another of it (`faces_each_other`, asserted in
//! debug builds), so a pass changes only the order of shots; the shooters' trees are read-only
//! during the pass and given back after it; after the pass each receiver's unshot power is up to
//! date.

use super::basis::MAX_FUNCTIONS;
use super::cover::{self, face_integral};
use super::element::Sphere;
use super::element_source::{ElementShot, ElementSource, SourceElement};
use super::eta::{ShotKind, ShotPlan};
use super::far_field;
use super::far_verdicts::{FarVerdicts, VerdictTable};
use super::forecast_inputs::foresee_after_direct_shot;
use super::hierarchy::Hierarchy;
use super::progress::{with_reports, CostUnits, Reporter, ShotCounter, ShotCounts};
use super::refine::{Shot, ShotContext};
use super::shot_record::ShotRecord;
use super::source::Rays;
use super::unoccluded::{faces_each_other, unoccluded_received};
use super::{mean_rgb_sum, DIRECT_DETAIL_TIGHTENING};
use crate::domain::ElementRoot;
use crate::scene::Rgb;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The power of a receiver's received share in its cost weight ([`receiver_cost_weight`]):
/// below 1, as a sky's most exposed receivers take their light on few links. Fitted on the
/// scaling benchmark's scenes so that the ETA stays within 2 of the time left on each
/// (docs/performance-notes.md, "Points that stand in alike ask once; receivers weighed by a
/// power 3/4"), like the forecast's constants.
const RECEIVER_COST_EXPONENT: f64 = 0.75;

/// A receiver's weight in a shot's cost, which the shot's progress (the fraction done the ETA
/// reads) counts: `1 + (p / threshold)^RECEIVER_COST_EXPONENT`, `p` what it would receive with
/// no occluder (its links grow with it, slower than it), 0 for a receiver the shot does not
/// visit (`p < 0`). Pinned by `a_receivers_cost_weight_grows_slower_than_its_share`.
fn receiver_cost_weight(p: f64, threshold: f64) -> f64 {
    if p >= 0.0 {
        1.0 + (p / threshold).powf(RECEIVER_COST_EXPONENT)
    } else {
        0.0
    }
}

/// At most this many roots shoot in one indirect pass (`pick_shooters`): a pass's fixed costs
/// (the plan over every root, starting and ending a parallel loop, its last receivers) are paid
/// once for all of them.
const PASS_MAX: usize = 8;
// The plan keeps each root's far links to a pass's shooters as the bits of a `u8`.
const _: () = assert!(PASS_MAX <= u8::BITS as usize);

/// A root joins the pass of the root with the most unshot power when it holds at least this
/// share of that power (the pass keeps close to the order of shots one at a time).
const PASS_SHARE: f64 = 0.5;

/// A pass looks no further than this many roots after the first, by decreasing unshot power.
const PASS_CANDIDATES: usize = 8 * PASS_MAX;

/// The next pass's shooters and whether it is a direct shot: the next emitter's emission alone;
/// else the root with the most unshot power, and after it, among the [`PASS_CANDIDATES`] next by
/// decreasing unshot power, those with at least [`PASS_SHARE`] of its power that face none of
/// those taken, the pass `max_shots` roots at most (and [`PASS_MAX`]). No root of a pass
/// receives from another, so shooting them together changes only the order of shots
/// (`tests::a_pass_takes_roots_that_face_none_of_its_others`). `None` once converged (or nothing
/// is left to shoot).
pub(super) fn pick_shooters(
    direct: &mut impl Iterator<Item = usize>,
    unshot: &[f64],
    (ratio, target, max_shots): (f64, f64, u64),
    (roots, spheres): (&[ElementRoot], &[Sphere]),
    facing_eps: f64,
) -> Option<(Vec<usize>, bool)> {
    if let Some(i) = direct.next() {
        return Some((vec![i], true));
    }
    if ratio <= target {
        return None;
    }
    let best = (0..unshot.len()).max_by(|&a, &b| unshot[a].total_cmp(&unshot[b]))?;
    if unshot[best] <= 0.0 {
        return None;
    }
    let floor = PASS_SHARE * unshot[best];
    let mut candidates: Vec<usize> = (0..unshot.len())
        .filter(|&i| i != best && unshot[i] >= floor)
        .collect();
    // Largest first, ties by index (deterministic); no further than `PASS_CANDIDATES`.
    let order = |a: &usize, b: &usize| unshot[*b].total_cmp(&unshot[*a]).then(a.cmp(b));
    if candidates.len() > PASS_CANDIDATES {
        candidates.select_nth_unstable_by(PASS_CANDIDATES, order);
        candidates.truncate(PASS_CANDIDATES);
    }
    candidates.sort_unstable_by(order);
    let most = usize::try_from(max_shots)
        .unwrap_or(PASS_MAX)
        .clamp(1, PASS_MAX);
    let mut pass = vec![best];
    for c in candidates {
        if pass.len() == most {
            break;
        }
        if pass
            .iter()
            .all(|&s| !faces_each_other(&roots[s], &spheres[s], &roots[c], &spheres[c], facing_eps))
        {
            pass.push(c);
        }
    }
    Some((pass, false))
}

/// A root that shoots in a pass: its hierarchy, taken out of the solve's for the pass (read-only:
/// no root of the pass receives), its unshot radiosity's face means, the element it shoots as,
/// and the power it sends.
struct Shooter {
    index: usize,
    hierarchy: Hierarchy,
    face_means: Option<Vec<Rgb>>,
    element: SourceElement,
    power: f64,
}

impl Shooter {
    fn take(ctx: &ShotContext, index: usize, direct: bool, h: &mut Hierarchy, unshot: f64) -> Self {
        let sroot = &ctx.roots[index];
        let n = ctx.bases.of(sroot.shape).len();
        let hierarchy = std::mem::take(h);
        let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
        if direct {
            // The emission alone (a constant), whatever else the emitter already received.
            coeffs[0] = sroot.exitance;
        } else {
            coeffs[..n].copy_from_slice(hierarchy.coeffs(&hierarchy.u, 0));
        }
        let face_means = if direct {
            None
        } else {
            sroot
                .mask
                .as_ref()
                .map(|_| cover::face_means(&hierarchy, &hierarchy.u))
        };
        let cover = hierarchy.covers.first().copied();
        let stored_mean = face_means.as_ref().map(|m| m[0]);
        let element = SourceElement::root(sroot, coeffs, n, cover, stored_mean);
        let power = if direct {
            mean_rgb_sum(sroot.exitance) * sroot.face_area_m2
        } else {
            unshot
        };
        Shooter {
            index,
            hierarchy,
            face_means,
            element,
            power,
        }
    }

    fn shot<'a>(&'a self, ctx: &ShotContext<'a>, direct: bool) -> ElementShot<'a> {
        ElementShot {
            roots: ctx.roots,
            bases: ctx.bases,
            rules: ctx.rules,
            visibility: ctx.visibility,
            source_root: self.index,
            source_hierarchy: &self.hierarchy,
            direct,
            source_face_means: self.face_means.as_deref(),
            min_edge: ctx.min_edge,
        }
    }
}

/// One pass of the roots `shooters` (of `kind`; a direct shot is alone in its pass, an indirect
/// pass's roots face no other of them: `pick_shooters`) onto every root that faces one of them,
/// the receivers in parallel, each taking the pass's shooters in turn; each receiver's unshot
/// power is updated. The pass's plan goes to `reporter` (after `iterations` shots), and a long
/// pass reports from within to it. Returns false when the time budget ended within the pass and
/// receivers were left out (`tests/progress.rs` `the_time_budget_stops_within_a_long_shot`).
pub(super) fn shoot(
    ctx: &ShotContext,
    (shooters, kind): (&[usize], ShotKind),
    facing_eps: f64,
    target_unshot: f64,
    (hierarchies, unshot, far_verdicts): (&mut [Hierarchy], &mut [f64], &mut FarVerdicts),
    (reporter, iterations): (&mut Reporter, u64),
) -> bool {
    let direct = matches!(kind, ShotKind::Direct { .. });
    let k = shooters.len();
    debug_assert!((1..=PASS_MAX).contains(&k) && (!direct || k == 1));
    let ctx = &ShotContext {
        detail_threshold: if direct {
            ctx.threshold / DIRECT_DETAIL_TIGHTENING
        } else {
            ctx.threshold
        },
        split_in_parallel: direct,
        ..*ctx
    };
    let roots = ctx.roots;
    debug_assert!(
        shooters
            .iter()
            .enumerate()
            .all(|(i, &a)| shooters[i + 1..].iter().all(|&b| {
                let (sa, sb) = (&ctx.spheres[a], &ctx.spheres[b]);
                !faces_each_other(&roots[a], sa, &roots[b], sb, facing_eps)
            })),
        "no root of a pass receives from another"
    );
    if !direct {
        // Only indirect passes keep their far links' verdicts: an emitter's direct shot comes
        // before them all, and the emitter that dominates a level, a sky panel, reflects nothing
        // and never shoots again (an emitter that reflects keeps its table from its first
        // indirect pass on).
        for &s in shooters {
            far_verdicts.reserve(s);
        }
    }
    let far_verdicts = &*far_verdicts;
    let taken: Vec<Shooter> = shooters
        .iter()
        .map(|&s| Shooter::take(ctx, s, direct, &mut hierarchies[s], unshot[s]))
        .collect();
    let shots: Vec<ElementShot> = taken.iter().map(|t| t.shot(ctx, direct)).collect();
    // What each shooter may send at most: receivers whose share of it is within the threshold
    // take it as one far link (`far_field.rs`).
    let power_bounds: Vec<f64> = shots
        .iter()
        .zip(&taken)
        .map(|(s, t)| {
            s.source(&t.element, [1.0; 3])
                .map_or(0.0, |s| s.power_bound())
        })
        .collect();
    // Per root and shooter, what it would receive with no occluder (-1 when not visited: it
    // does not face the shooter, or shoots in this pass): its cost grows with it over the
    // threshold (links under a soft shadow), slower than linearly (`receiver_cost_weight`),
    // and its reflectance sends it back. Beside it, bit
    // `j` set: the root takes shooter `j`'s light as one far link (`takes_far_link`, decided
    // here once for the plan and the loop).
    let (received, far_links): (Vec<[f64; PASS_MAX]>, Vec<u8>) = hierarchies
        .par_iter()
        .enumerate()
        .map(|(ri, h)| {
            let mut p = [-1.0; PASS_MAX];
            let mut far_bits = 0u8;
            if h.nodes.is_empty() {
                return (p, far_bits);
            }
            for (j, t) in taken.iter().enumerate() {
                let (sroot, ssphere) = (&roots[t.index], &ctx.spheres[t.index]);
                let (root, sphere) = (&roots[ri], &ctx.spheres[ri]);
                if ri != t.index && faces_each_other(sroot, ssphere, root, sphere, facing_eps) {
                    let far = takes_far_link(power_bounds[j], ssphere, sphere, ctx.threshold);
                    far_bits |= u8::from(far) << j;
                    p[j] = unoccluded_received(ctx, t.index, t.power, ri, far);
                }
            }
            (p, far_bits)
        })
        .unzip();
    let visited = |ri: usize| received[ri][..k].iter().any(|&p| p >= 0.0);
    let receivers = (0..roots.len()).filter(|&ri| visited(ri)).count() as u64;
    let weights = |ri: usize| {
        received[ri][..k]
            .iter()
            .map(|&p| receiver_cost_weight(p, ctx.threshold))
            .sum::<f64>()
    };
    let units = CostUnits::new((0..roots.len()).map(weights).sum());
    let expected = |ri: usize| {
        let p: f64 = received[ri][..k].iter().map(|&p| p.max(0.0)).sum();
        p * mean_rgb_sum(roots[ri].rho) / 3.0
    };
    let returns = (0..roots.len()).map(expected).sum();
    if direct && !reporter.has_forecast() {
        let first: Vec<f64> = received.iter().map(|p| p[0]).collect();
        let f = foresee_after_direct_shot(
            ctx,
            (hierarchies, &*unshot),
            (shooters[0], &first),
            target_unshot,
            facing_eps,
        );
        reporter.indirect_foreseen(f);
    }
    let returns_units = CostUnits::new(returns);
    // What the pass's loop over its receivers costs (its plan above not counted), for
    // `RUST_LOG=wavrad::solver::pass=trace` (docs/performance-notes.md, "What a shot costs
    // against the power it sends").
    let cost_before = tracing::enabled!(tracing::Level::TRACE).then(|| {
        let (rays, links) = (ctx.visibility.rays_traced(), ctx.links.get());
        (Instant::now(), rays, links)
    });
    let power = taken.iter().map(|t| t.power).sum();
    reporter.shot_started(
        iterations,
        ShotPlan {
            kind,
            power,
            returns,
        },
    );
    let interrupted = AtomicBool::new(false);
    // A direct shot's receivers are few and costly: one at a time.
    let chunk = if direct { 1 } else { PASS_CHUNK };
    let work = |done: &ShotCounter| {
        hierarchies
            .par_chunks_mut(chunk)
            .zip(unshot.par_chunks_mut(chunk))
            .enumerate()
            // Pieces split down to one chunk: rayon's default leaves pieces of many receivers
            // that run on one thread to their end, however many of them are costly, while the
            // other threads wait (docs/performance-notes.md, "Both cores all the time").
            .with_max_len(1)
            // The shooters as far sources: built once per piece of the loop (a chunk of
            // receivers), not per link (they are not `Sync`: their corner stand-ins are filled
            // lazily).
            .for_each_init(
                || -> Vec<_> {
                    shots
                        .iter()
                        .zip(&taken)
                        .map(|(s, t)| s.source(&t.element, [1.0; 3]))
                        .collect()
                },
                |far_sources, (c, (hs, powers))| {
                    let first = c * chunk;
                    if ctx.past_deadline() {
                        if (first..first + hs.len()).any(visited) {
                            interrupted.store(true, Ordering::Relaxed);
                        }
                        return;
                    }
                    // Whether each receiver took any light this pass (its unshot power changed).
                    let mut took_light = [false; PASS_CHUNK];
                    // Shooter by shooter over the piece: the rays of neighbouring receivers to
                    // one shooter follow one another through the visibility structure.
                    for (j, t) in taken.iter().enumerate() {
                        for (i, h) in hs.iter_mut().enumerate() {
                            let ri = first + i;
                            let received = received[ri][j];
                            if received < 0.0 {
                                continue;
                            }
                            took_light[i] |= receive_one(
                                ctx,
                                (
                                    &shots[j],
                                    t,
                                    far_sources[j].as_ref(),
                                    far_verdicts.table(t.index),
                                ),
                                far_links[ri] >> j & 1 == 1,
                                received,
                                ri,
                                h,
                                direct,
                            );
                        }
                    }
                    let mut finished = ShotCounts::default();
                    for (i, (h, power)) in hs.iter_mut().zip(powers.iter_mut()).enumerate() {
                        let ri = first + i;
                        if !visited(ri) {
                            continue;
                        }
                        let before = *power;
                        if h.touched {
                            h.push_pull(ctx.bases.of(roots[ri].shape), roots[ri].rho, direct);
                            took_light[i] = true;
                        }
                        if took_light[i] {
                            *power = unshot_power(h, &roots[ri]);
                        }
                        finished.receiver(
                            units.of(weights(ri)),
                            returns_units.of(expected(ri)),
                            returns_units.of(*power - before),
                        );
                    }
                    done.add(finished);
                },
            )
    };
    with_reports(work, &mut |c| reporter.within_shot(c, receivers));
    if let Some((start, rays, links)) = cost_before {
        tracing::trace!(
            direct,
            shooters = k,
            power,
            received = received.iter().flatten().filter(|&&p| p > 0.0).sum::<f64>(),
            threshold = ctx.threshold,
            receivers,
            seconds = start.elapsed().as_secs_f64(),
            rays = ctx.visibility.rays_traced() - rays,
            links = ctx.links.get() - links,
            "shot cost"
        );
    }
    drop(shots);
    for t in taken {
        hierarchies[t.index] = t.hierarchy;
    }
    !interrupted.load(Ordering::Relaxed)
}

/// Receivers a piece of a pass's parallel loop takes together, shooter by shooter.
const PASS_CHUNK: usize = 32;

/// Receiver root `ri` (tree `h`) takes one shooter's light: as one far link when `far` (the
/// plan's [`takes_far_link`]: its whole share is within the threshold, `far_field.rs`; its ray's
/// verdict read from the shooter's table when an earlier shot traced it, `far_verdicts.rs`), else
/// refined link by link (and judged on its nodes' sums); `received` is the plan's estimate of its
/// share with no occluder. Whether it took light without a push-pull pending (a far link's
/// constant).
fn receive_one(
    ctx: &ShotContext,
    (shot, shooter, far_source, verdicts): (
        &ElementShot,
        &Shooter,
        Option<&ElementSource>,
        Option<&VerdictTable>,
    ),
    far: bool,
    received: f64,
    ri: usize,
    h: &mut Hierarchy,
    direct: bool,
) -> bool {
    let roots = ctx.roots;
    let (s, r) = (&ctx.spheres[shooter.index], &ctx.spheres[ri]);
    if far {
        let verdict = verdicts.map(|v| (v, ri));
        let e = far_source
            .and_then(|fs| far_field::far_irradiance(fs, &roots[ri], ctx.link_points[ri], verdict));
        return e.is_some_and(|e| ctx.accept_far(h, &roots[ri], e, direct));
    }
    let mut record = ShotRecord::default();
    let rays = if !direct && centre_rays_suffice(received, ctx.threshold, s, r) {
        Rays::Centre
    } else {
        Rays::Trace
    };
    ctx.transfer(shot, &shooter.element, ri, h, 0, &mut record, rays);
    if ctx.node_sums {
        ctx.refine_by_node_sums(shot, record, ri, h);
    }
    false
}

/// Whether a receiver (bounding sphere `receiver`) takes a shot as one far link: the most the
/// shooter (`shooter`, sending at most `power_bound`) can send it is within the oracle's
/// `threshold` (`far_field.rs`). The plan estimates such a receiver at its centre alone.
fn takes_far_link(power_bound: f64, shooter: &Sphere, receiver: &Sphere, threshold: f64) -> bool {
    power_bound * far_field::transfer_fraction_bound(shooter, receiver) <= threshold
}

/// The largest share of the oracle's threshold a near receiver may get from an indirect shot, with
/// no occluder, and still have its links decide visibility by one ray per point
/// ([`centre_rays_suffice`]; docs/performance-notes.md, "What a shot costs against the power it
/// sends").
const CENTRE_RAY_SHARE: f64 = 1.0 / 16.0;

/// Whether a near receiver's links may decide their visibility by one ray per receiver point
/// ([`Rays::Centre`]): it would get at most [`CENTRE_RAY_SHARE`] of the oracle's `threshold` with
/// no occluder (`received`, the plan's estimate) and its bounding sphere is apart from the
/// shooter's (where they touch, the estimate from five points misses most of the transfer).
/// `tests::centre_rays_need_a_small_share_and_no_contact`.
fn centre_rays_suffice(received: f64, threshold: f64, shooter: &Sphere, receiver: &Sphere) -> bool {
    let apart = shooter.centre.distance(receiver.centre) > shooter.radius + receiver.radius;
    apart && received <= CENTRE_RAY_SHARE * threshold
}

/// Unshot power, counted over each face only (never over the empty part of a domain).
pub(super) fn unshot_power(h: &Hierarchy, r: &ElementRoot) -> f64 {
    mean_rgb_sum(face_integral(h, &h.u, r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::element::tests::parallelogram_root;
    use glam::DVec3;

    /// A receiver not visited weighs nothing; one that would receive nothing, 1; one that would
    /// receive the threshold, 2; above, its weight grows slower than what it would receive.
    #[test]
    fn a_receivers_cost_weight_grows_slower_than_its_share() {
        let t = 1e-3;
        assert_eq!(receiver_cost_weight(-1.0, t), 0.0);
        assert_eq!(receiver_cost_weight(0.0, t), 1.0);
        assert_eq!(receiver_cost_weight(t, t), 2.0);
        let (w1, w2) = (
            receiver_cost_weight(1e4 * t, t),
            receiver_cost_weight(1e6 * t, t),
        );
        assert!(w2 > w1 && w2 - 1.0 < 100.0 * (w1 - 1.0), "{w1} {w2}");
        assert!(((w2 - 1.0) / (w1 - 1.0) - 100f64.powf(RECEIVER_COST_EXPONENT)).abs() < 1e-9);
    }

    /// A pass: the root with the most unshot power first, then by decreasing power (ties by
    /// index) the roots with at least `PASS_SHARE` of it that face none of those taken, at most
    /// `PASS_MAX`; a direct shot alone; nothing once the ratio is at the target.
    #[test]
    fn a_pass_takes_roots_that_face_none_of_its_others() {
        // Twelve floor tiles facing up (coplanar: none faces another) and a ceiling above the
        // first two, facing down (it faces them).
        let tile = |x: f64| parallelogram_root(DVec3::new(x, 0.0, 0.0), DVec3::X, DVec3::Y);
        let mut roots: Vec<ElementRoot> = (0..12).map(|i| tile(2.0 * f64::from(i))).collect();
        roots.push(parallelogram_root(
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::Y,
            DVec3::X * 3.0,
        ));
        let spheres: Vec<Sphere> = roots.iter().map(Sphere::of_root).collect();
        let mut unshot = vec![6.0; 13];
        unshot[0] = 10.0;
        unshot[12] = 9.0; // the ceiling: faces tile 0
        unshot[1] = 8.0;
        unshot[2] = 4.9; // below half of the best
        unshot[5] = 7.0;
        let pick = |unshot: &[f64], direct: &mut std::vec::IntoIter<usize>, ratio: f64| {
            pick_shooters(direct, unshot, (ratio, 1e-3, 100), (&roots, &spheres), 1e-9)
        };
        let (pass, direct) = pick(&unshot, &mut vec![].into_iter(), 1.0).unwrap();
        assert!(!direct);
        assert_eq!(pass, vec![0, 1, 5, 3, 4, 6, 7, 8]);
        assert_eq!(pass.len(), PASS_MAX);
        for (i, &a) in pass.iter().enumerate() {
            for &b in &pass[i + 1..] {
                let (ra, rb) = (&roots[a], &roots[b]);
                assert!(!faces_each_other(ra, &spheres[a], rb, &spheres[b], 1e-9));
            }
        }
        // The ceiling first: every tile lies in front of its plane and it in front of theirs.
        unshot[12] = 11.0;
        let (pass, _) = pick(&unshot, &mut vec![].into_iter(), 1.0).unwrap();
        assert_eq!(pass, vec![12]);
        // Below half of the best power no root joins, even with room left in the pass.
        let few = [
            10.0, 4.9, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ];
        let (pass, _) = pick(&few, &mut vec![].into_iter(), 1.0).unwrap();
        assert_eq!(pass, vec![0, 2]);
        // No more shots than the solve may still make.
        let capped = pick_shooters(
            &mut vec![].into_iter(),
            &unshot[..12],
            (1.0, 1e-3, 3),
            (&roots[..12], &spheres[..12]),
            1e-9,
        );
        assert_eq!(capped.unwrap().0.len(), 3);
        // Among many candidates, the largest (then the lowest indices) still come first.
        let tiles: Vec<ElementRoot> = (0..100).map(|i| tile(2.0 * f64::from(i))).collect();
        let tile_spheres: Vec<Sphere> = tiles.iter().map(Sphere::of_root).collect();
        let mut many = vec![6.0; 100];
        many[40] = 10.0;
        many[77] = 7.0;
        let (pass, _) = pick_shooters(
            &mut vec![].into_iter(),
            &many,
            (1.0, 1e-3, 100),
            (&tiles, &tile_spheres),
            1e-9,
        )
        .unwrap();
        assert_eq!(pass, vec![40, 77, 0, 1, 2, 3, 4, 5]);
        // A direct shot is alone; at the target nothing is left.
        let direct_queue = vec![3, 4];
        let (pass, direct) = pick(&unshot, &mut direct_queue.into_iter(), 1.0).unwrap();
        assert_eq!((pass, direct), (vec![3], true));
        assert!(pick(&unshot, &mut vec![].into_iter(), 1e-4).is_none());
    }

    /// One ray per point only for a receiver apart from the shooter that would get at most the
    /// share of the threshold: touching spheres, or a larger share, trace every sample.
    #[test]
    fn centre_rays_need_a_small_share_and_no_contact() {
        let sphere = |x: f64| Sphere {
            centre: DVec3::new(x, 0.0, 0.0),
            radius: 1.0,
        };
        let (threshold, shooter) = (1.0, sphere(0.0));
        let small = CENTRE_RAY_SHARE * threshold;
        assert!(centre_rays_suffice(
            small,
            threshold,
            &shooter,
            &sphere(2.5)
        ));
        assert!(centre_rays_suffice(0.0, threshold, &shooter, &sphere(2.5)));
        assert!(!centre_rays_suffice(
            small,
            threshold,
            &shooter,
            &sphere(1.5)
        ));
        assert!(!centre_rays_suffice(
            small,
            threshold,
            &shooter,
            &sphere(2.0)
        ));
        assert!(!centre_rays_suffice(
            1.01 * small,
            threshold,
            &shooter,
            &sphere(2.5)
        ));
    }
}
