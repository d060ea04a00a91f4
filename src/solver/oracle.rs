//! The refinement oracle: an interaction's errors to a [`Verdict`], which the recursion
//! (`refine.rs`) acts on, after RenderPark's `EvaluateInteraction`. One oracle for every source,
//! element or punctual light.
//!
//! The errors, in the order they are taken: the projection's deviation at the control points;
//! at points near the corners (when every ray passed); a shadow boundary the rays may have missed
//! (rays between the corners, then spread over both elements); the exchange the receiver's
//! points missed (reciprocity); the reflectance a textured leaf misplaces; partial visibility
//! (the whole unoccluded transfer is at stake); a partly covered source's coverage error. A link
//! whose rays were taken as passing (`Rays::AllPass`), or cast one per point (`Rays::Centre`),
//! casts no ray to check the verdict.
//!
//! Invariant: a verdict other than `Accept` only when the error in transferred power exceeds the
//! threshold; `Capped` only when neither side may be split.

use super::basis::MAX_FUNCTIONS;
use super::quadrature;
use super::refine::ShotContext;
use super::rules::corner_probe_points;
use super::source::{Rays, ReceiverNode, Source};
use super::transfer::Received;
use super::{Quantity, MAX_DEPTH};
use crate::scene::Rgb;
use glam::DVec2;

/// What the recursion does with an interaction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Verdict {
    /// Within the threshold: gather the link.
    Accept,
    /// Above the threshold, but neither side may be split: gather the link, and count it.
    Capped,
    /// Split the source and send each child to the same receiver.
    SplitSource,
    /// Split the receiver and send the source to each child.
    SplitReceiver,
}

/// Evaluates the interaction of `source` with `receiver`, which received `received`; `weight`:
/// the oracle's channel weights at the receiver; `rays`: how the transfer decided its shadow
/// rays (taken as all passing, or one per point to the source's centre: no ray checks the
/// verdict either).
pub(super) fn evaluate(
    ctx: &ShotContext,
    source: &impl Source,
    receiver: &ReceiverNode,
    received: &Received,
    weight: Rgb,
    rays: Rays,
) -> Verdict {
    let root = receiver.root;
    let area = receiver.patch.area;
    let threshold = ctx.threshold;
    let psi = ctx.psi.of(root.shape);
    let nr = ctx.bases.of(root.shape).len();
    let nk = received.rule_points;
    let dh = &received.dh;
    // Received irradiance at the control points against its projection.
    let mut err = max_deviation(&psi[..nk], &received.e[..nk], dh, nr, weight);
    // A shadow boundary crossing the link: the control points cannot see where it runs, so the
    // whole unoccluded transfer is at stake.
    let mut partial = received.any_visible && received.any_blocked;
    if !partial && received.any_visible && err * area <= threshold {
        // The quadrature points are interior: the irradiance near the element's border (the
        // falloff towards a room's corners) is not sampled. Compare the unoccluded
        // irradiance of the source's mean at points near the corners with the projection.
        for j in 0..corner_probe_points(root.shape).len() {
            // Off the face, the stand-in receives for the point (see `receiving_point`).
            let x = receiver.check_point(j);
            let e = source.unoccluded_irradiance(x, root.normal);
            err = err.max(weighted_deviation(e, dh, &psi[nk + j], nr, weight));
        }
    }
    if rays == Rays::Trace
        && !partial
        && err * area <= threshold
        && received.unoccluded_max * area > threshold
    {
        // The quadrature rays agree, but they sample the interior only, and sparsely: a shadow
        // boundary near an element's border (a wall standing on a slab, an eave over a wall)
        // slips between them, and so does a strip of a large source seen through a gap. What
        // they said is kept with the link's other verdicts (`near_verdicts.rs`).
        partial = received.verdict_rays.get().unwrap_or_else(|| {
            let disagree = verdict_rays_disagree(ctx, source, receiver, received.any_visible);
            received.verdict_rays.set(Some(disagree));
            disagree
        });
    }
    // A source the receiver's points do not see (they lie behind its plane, or beside it)
    // while the source's points see the receiver: the link would carry nothing and pass.
    let missed = source.missed_by(receiver, received.exchange_seen_by_receiver);
    if let Some(unseen) = missed {
        err = err.max(unseen);
    }
    // A leaf whose reflectance varies reflects its mean: the light it puts in the wrong place.
    let reflect_err = reflectance_error(receiver, dh[0]);
    err = err.max(reflect_err);
    // The error the control points see across the receiver, before the partial-visibility bound.
    let receiver_err = err;
    if partial {
        err = err.max(received.unoccluded_max);
    }
    // A partly covered source whose alpha-weighted rule misses the face's shape: only
    // splitting the source sharpens it.
    let coverage_limited = received.coverage_err > err;
    let err = err.max(received.coverage_err) * area;
    if err > threshold {
        let can_split_r =
            receiver.depth < MAX_DEPTH && receiver.patch.min_edge() * 0.5 >= ctx.min_edge;
        let s = source.split();
        // Partial visibility: which side's refinement the error calls for. A shadow boundary
        // across the receiver (its control points disagree with its projection more than the
        // source's samples may be wrong at any point) splits the receiver, however large the
        // source; split source links would each carry too little error to refine it.
        // A source the receiver's points missed: only the receiver's refinement finds it.
        let receiver_first = missed.is_some()
            || reflect_err * area > threshold
            || (partial
                && receiver_err * area > threshold
                && receiver_err >= received.source_side_err);
        // The larger side is split, as in hierarchical radiosity; but splitting a source whose
        // radiosity has no finer detail only helps where visibility is partial or the source's
        // coverage is what limits the transfer.
        let split_source = s.can_split
            && (!can_split_r
                || coverage_limited
                || (s.area > area && !receiver_first && (partial || s.detail)));
        if split_source {
            Verdict::SplitSource
        } else if can_split_r {
            Verdict::SplitReceiver
        } else {
            Verdict::Capped
        }
    } else {
        Verdict::Accept
    }
}

/// Do shadow rays between the receiver and the source disagree with the quadrature rays' verdict
/// (`quadrature_visible`: all visible, or all blocked)? First from the receiver's corner probe
/// points to the source's corners (a light: to the light), then [`Source::spread_rays`] pairs of
/// points spread over both (a 4-d Kronecker sequence). A receiver point casts from its stand-in:
/// it receives as one (see `receiving_point`).
fn verdict_rays_disagree(
    ctx: &ShotContext,
    source: &impl Source,
    receiver: &ReceiverNode,
    quadrature_visible: bool,
) -> bool {
    let root = receiver.root;
    let n = root.normal;
    let ignore = source.ignored_faces(root.face.0);
    for j in 0..corner_probe_points(root.shape).len() {
        let x = receiver.check_point(j);
        let mut disagrees = |y| ctx.visibility.visible(x, y, ignore) != quadrature_visible;
        if source.corner_rays(x, n, &mut disagrees) {
            return true;
        }
    }
    // Then pairs spread over both elements: a large source seen from a small receiver through a
    // gap (a window reveal under a sky, a box's side behind a parapet) is lit through a strip
    // that the rule's points and the corners all miss.
    (0..source.spread_rays()).any(|i| {
        let [_, _, c, d] = quadrature::kronecker4(i);
        let x = receiver.spread_point(i);
        let mut disagrees = |y| ctx.visibility.visible(x, y, ignore) != quadrature_visible;
        source.spread_ray(x, n, DVec2::new(c, d), &mut disagrees)
    })
}

/// `sum_ch weight_ch |e_ch - projection_ch|` at a point where the receiver's basis functions take
/// the values `phi`: the oracle's measure of a projection's error there.
pub(super) fn weighted_deviation(
    e: Rgb,
    dh: &[Rgb; MAX_FUNCTIONS],
    phi: &[f64; MAX_FUNCTIONS],
    nr: usize,
    weight: Rgb,
) -> f64 {
    (0..3)
        .map(|ch| {
            let proj: f64 = (0..nr).map(|a| dh[a][ch] * phi[a]).sum();
            weight[ch] * (e[ch] - proj).abs()
        })
        .sum()
}

/// Per child of the node: the largest [`weighted_deviation`] over the points in it.
pub(super) fn child_deviation(
    psi: &[[f64; MAX_FUNCTIONS]],
    kids: &[u8],
    e: &[Rgb],
    dh: &[Rgb; MAX_FUNCTIONS],
    nr: usize,
    weight: Rgb,
) -> [f64; 4] {
    debug_assert_eq!(psi.len(), e.len(), "one value per point");
    debug_assert_eq!(psi.len(), kids.len(), "one set of children per point");
    let mut out = [0.0f64; 4];
    for ((phi, e), m) in psi.iter().zip(e).zip(kids) {
        let d = weighted_deviation(*e, dh, phi, nr, weight);
        for (c, o) in out.iter_mut().enumerate() {
            if m & (1 << c) != 0 {
                *o = o.max(d);
            }
        }
    }
    out
}

/// The oracle's error over a set of points: the largest [`weighted_deviation`] of the values `e`
/// from the projection `dh`, the receiver's basis taking the values `psi` at those points.
pub(super) fn max_deviation(
    psi: &[[f64; MAX_FUNCTIONS]],
    e: &[Rgb],
    dh: &[Rgb; MAX_FUNCTIONS],
    nr: usize,
    weight: Rgb,
) -> f64 {
    debug_assert_eq!(psi.len(), e.len(), "one value per point");
    psi.iter()
        .zip(e)
        .map(|(phi, e)| weighted_deviation(*e, dh, phi, nr, weight))
        .fold(0.0, f64::max)
}

/// What the oracle weighs each channel's irradiance error by: rho for radiance, 1 for irradiance.
pub(super) fn oracle_weight(quantity: Quantity, rho: Rgb) -> Rgb {
    match quantity {
        Quantity::Radiance => rho,
        Quantity::Irradiance => [1.0; 3],
    }
}

/// The reflected radiosity that a leaf receiver whose reflectance varies puts in the wrong place
/// when it receives irradiance of mean `mean_h`: its reflectance's mean absolute deviation times
/// `mean_h`, summed over channels (W/m^2). An element across a sharp colour change reflects their
/// mean; this is what its refinement moves back. Zero for inner nodes (their leaves reflect with
/// their own reflectance) and for roots of constant reflectance.
fn reflectance_error(receiver: &ReceiverNode, mean_h: Rgb) -> f64 {
    let Some(dev) = receiver.reflectance_deviation else {
        return 0.0;
    };
    (0..3).map(|ch| dev[ch] * mean_h[ch].abs()).sum()
}
