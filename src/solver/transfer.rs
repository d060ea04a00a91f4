//! Quadrature to received irradiance: a [`Source`] asked at the receiver node's rule points (then,
//! for the node-sum check, at its check points near the corners), the values projected onto the
//! receiver's basis, and what the points' rays said, as [`Received`] for the oracle.
//!
//! Invariant: only the rule points enter the projection `dh` and the link's own oracle; the check
//! points are recorded for the node's check after the shot.

use super::basis::MAX_FUNCTIONS;
use super::cover::{CHECK_POINTS, MAX_RULE_POINTS};
use super::element::receiving_point;
use super::near_verdicts::KnownVerdicts;
use super::quadrature::QuadPoint;
use super::rules::CheckTwins;
use super::source::{Rays, ReceiverNode, Source};
use crate::scene::Rgb;
use std::cell::Cell;

/// Most points a receiver is asked at: its rule's, then its check points (M3's 16 and a
/// parallelogram's 5). Every evaluation zeroes its arrays of this length.
pub(super) const MAX_POINTS: usize = MAX_RULE_POINTS + CHECK_POINTS;

/// What a source delivered at one receiver node's points.
pub(super) struct Received {
    /// Irradiance at the rule points, then at the check points.
    pub e: [Rgb; MAX_POINTS],
    /// How many of `e` are rule points, and how many in all.
    pub rule_points: usize,
    pub points: usize,
    /// The projection onto the receiver's basis (the link's coefficients).
    pub dh: [Rgb; MAX_FUNCTIONS],
    /// Over the rule points: did any ray pass, any ray stop?
    pub any_visible: bool,
    pub any_blocked: bool,
    /// Over the rule points: the largest unoccluded irradiance (weighted as the oracle's errors),
    /// the largest error the source's sampling may cause, the largest coverage error.
    pub unoccluded_max: f64,
    pub source_side_err: f64,
    pub coverage_err: f64,
    /// Unoccluded exchange (area x form factor) seen from the receiver's rule points.
    pub exchange_seen_by_receiver: f64,
    /// Rule points where the touching fallback stood in.
    pub touching: u64,
    /// Rays were traced from every point (rule and check points), and all passed. Never after
    /// [`Rays::AllPass`]: a link taken as seen whole is not passed on so again (the rays traced
    /// from a node sample what its children see, not its grandchildren); nor after
    /// [`Rays::Centre`] (one ray per point does not sample the source).
    pub all_pass: bool,
    /// Each point's shadow-ray verdicts ([`PointIrradiance::seen`](super::source::PointIrradiance),
    /// 0 where no ray was cast), and whether the oracle's verdict rays disagreed with them, once
    /// it asked (`oracle.rs`): what the link's receiver keeps for the shooter's next shots
    /// (`near_verdicts.rs`).
    pub seen: [u64; MAX_POINTS],
    pub verdict_rays: Cell<Option<bool>>,
    /// Each point's form factor of the source (0 where nothing reached it), kept with the rays'
    /// verdicts.
    pub form_factors: [f64; MAX_POINTS],
}

/// Asks `source` at `receiver`'s `rule` points (their basis values: `psi`, `nr` functions), then
/// at its first `check_points` check points ([`ReceiverNode::check_point`]; one whose `twins`
/// entry names a rule point takes that point's answer), and projects the rule points'
/// irradiance onto the receiver's basis; `rays` says how the shadow rays are decided, unless an
/// earlier shot's verdicts for this link are `known`.
#[allow(clippy::too_many_arguments)]
pub(super) fn receive(
    source: &impl Source,
    receiver: &ReceiverNode,
    rule: &[QuadPoint],
    psi: &[[f64; MAX_FUNCTIONS]],
    nr: usize,
    (check_points, twins): (usize, &CheckTwins),
    rays: Rays,
    known: Option<&KnownVerdicts>,
) -> Received {
    let root = receiver.root;
    let ignore = source.ignored_faces(root.face.0);
    let nk = rule.len();
    let mut out = Received {
        e: [[0.0; 3]; MAX_POINTS],
        rule_points: nk,
        points: nk + check_points,
        dh: [[0.0; 3]; MAX_FUNCTIONS],
        any_visible: false,
        any_blocked: false,
        unoccluded_max: 0.0,
        source_side_err: 0.0,
        coverage_err: 0.0,
        exchange_seen_by_receiver: 0.0,
        touching: 0,
        all_pass: rays == Rays::Trace,
        seen: [0; MAX_POINTS],
        form_factors: [0.0; MAX_POINTS],
        verdict_rays: Cell::new(known.and_then(KnownVerdicts::verdict_rays)),
    };
    for k in 0..out.points {
        // A check point where a rule point lies (a parallelogram's centre at M2) sees what it saw.
        if let Some(i) = k.checked_sub(nk).and_then(|j| twins[j]) {
            out.e[k] = out.e[i];
            out.seen[k] = out.seen[i];
            out.form_factors[k] = out.form_factors[i];
            continue;
        }
        let x = match rule.get(k) {
            Some(q) => receiving_point(root, &receiver.patch, receiver.cover, k, q.st),
            None => receiver.check_point(k - nk),
        };
        let Some(p) = source.irradiance_at(x, root.normal, ignore, rays, known.map(|v| v.point(k)))
        else {
            // No ray sampled what this point's neighbours in a child may see.
            out.all_pass = false;
            continue;
        };
        out.all_pass &= p.any_visible && !p.any_blocked;
        out.e[k] = p.e;
        out.seen[k] = p.seen;
        out.form_factors[k] = p.form_factor;
        let Some(q) = rule.get(k) else {
            continue;
        };
        let covered = receiver.cover.as_ref().map_or(1.0, |c| c.alpha[k]);
        out.exchange_seen_by_receiver += q.weight * covered * p.form_factor * receiver.patch.area;
        out.unoccluded_max = out.unoccluded_max.max(p.unoccluded);
        out.any_visible |= p.any_visible;
        out.any_blocked |= p.any_blocked;
        out.source_side_err = out.source_side_err.max(p.source_side_err);
        out.coverage_err = out.coverage_err.max(p.coverage_err);
        out.touching += u64::from(p.touching);
        for a in 0..nr {
            for ch in 0..3 {
                out.dh[a][ch] += q.weight * psi[k][a] * p.e[ch];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Shape;
    use crate::solver::far_field::tests::square_under_square;
    use crate::solver::hierarchy::Hierarchy;
    use crate::solver::rules::{corner_probe_points, Bases, BasisAtControlPoints, Rules, TWIN_EPS};
    use glam::DVec2;

    /// The receiver of `square_under_square` (its root node) asked at its rule and check points
    /// with `rays`: what it received, and the rays traced.
    fn received(blocked: bool, rays: Rays) -> (Received, u64) {
        let (bases, rules) = (Bases::new(2), Rules::new(2));
        let psi = BasisAtControlPoints::new(&bases, &rules);
        let shape = Shape::Parallelogram;
        square_under_square(blocked, |source, root, visibility| {
            let h = Hierarchy::new(bases.of(shape).len());
            let node = ReceiverNode::new(root, &h, 0);
            let before = visibility.rays_traced();
            let got = receive(
                source,
                &node,
                rules.of(shape),
                psi.of(shape),
                bases.of(shape).len(),
                (corner_probe_points(shape).len(), rules.twins(shape)),
                rays,
                None,
            );
            (got, visibility.rays_traced() - before)
        })
    }

    /// Rays taken as passing trace none and deliver what an open scene delivers, blocker or not;
    /// `all_pass` says whether traced rays all passed, and never passes a taken verdict on.
    #[test]
    fn rays_taken_as_passing_trace_none_and_see_the_source_whole() {
        let (open, open_rays) = received(false, Rays::Trace);
        assert!(open_rays > 0);
        assert!(open.all_pass && open.any_visible && !open.any_blocked);
        let (shadowed, _) = received(true, Rays::Trace);
        assert!(!shadowed.all_pass && shadowed.any_blocked);
        assert!(shadowed.e[..shadowed.points] != open.e[..open.points]);
        let (taken, taken_rays) = received(true, Rays::AllPass);
        assert_eq!(taken_rays, 0);
        assert_eq!(taken.e[..taken.points], open.e[..open.points]);
        assert_eq!(taken.dh, open.dh);
        assert!(taken.any_visible && !taken.any_blocked);
        assert!(!taken.all_pass, "a taken verdict is not passed on");
    }

    /// A parallelogram's check point at its centre, where its M2 rule has a point, takes that
    /// point's irradiance, verdicts and form factor and traces no ray of its own; the other
    /// check points trace theirs. Behind the blocker, so that the points differ.
    #[test]
    fn a_check_point_on_a_rule_point_takes_its_irradiance() {
        let rules = Rules::new(2);
        let rule = rules.of(Shape::Parallelogram);
        let probes = corner_probe_points(Shape::Parallelogram);
        let centre = |st: DVec2| (st - DVec2::splat(0.5)).abs().max_element() <= TWIN_EPS;
        let i = rule
            .iter()
            .position(|q| centre(q.st))
            .expect("M2 has a centre point");
        let j = probes
            .iter()
            .position(|&p| centre(p))
            .expect("a centre check point");
        let (got, rays) = received(true, Rays::Trace);
        let k = got.rule_points + j;
        assert_eq!(got.e[k], got.e[i]);
        assert_eq!(got.seen[k], got.seen[i]);
        assert_eq!(got.form_factors[k], got.form_factors[i]);
        assert!(got.form_factors[i] > 0.0);
        // The blocker hides the source from some points and not others: the copy is the twin's.
        assert!(
            (got.rule_points..got.points).any(|m| m != k && got.e[m] != got.e[k]),
            "another check point sees otherwise"
        );
        // Nine rays (the source's M2 rule) from each point but the twin.
        assert_eq!(rays, 9 * (got.points as u64 - 1));
    }

    /// One ray per point, to the source's centre: as many rays as points; with nothing in the
    /// way the same numbers as every sample traced; behind the blocker (it hides the source's
    /// centre from the receiver's middle, not from its corners) each point gets all or nothing.
    #[test]
    fn centre_rays_trace_one_ray_per_point_and_give_all_or_nothing() {
        let (open, _) = received(false, Rays::Trace);
        let (centre, rays) = received(false, Rays::Centre);
        // One point fewer: the check point at the centre is a rule point's twin.
        assert_eq!(rays, centre.points as u64 - 1);
        assert_eq!(centre.e[..centre.points], open.e[..open.points]);
        assert_eq!(centre.dh, open.dh);
        assert!(
            !centre.all_pass,
            "one ray per point is not passed on as seen whole"
        );
        let (shadowed, _) = received(true, Rays::Centre);
        let (mut dark, mut lit) = (0, 0);
        for k in 0..shadowed.points {
            if shadowed.e[k] == [0.0; 3] {
                dark += 1;
            } else {
                assert_eq!(shadowed.e[k], open.e[k], "point {k}");
                lit += 1;
            }
        }
        assert!(dark > 0 && lit > 0, "{dark} dark, {lit} lit");
        assert!(shadowed.any_visible && shadowed.any_blocked);
    }
}
