//! Quadrature to received irradiance: a [`Source`] asked at the receiver node's rule points (then,
//! for the node-sum check, at its check points near the corners), the values projected onto the
//! receiver's basis, and what the points' rays said, as [`Received`] for the oracle.
//!
//! Invariants: only the rule points enter the projection `dh` and the link's own oracle; the check
//! points are recorded for the node's check after the shot. A point takes an earlier point's
//! answer only where it would be asked at the same place (the same stand-in), so the answers are
//! those of asking every point.

use super::basis::MAX_FUNCTIONS;
use super::element::receiving_point;
use super::near_verdicts::KnownVerdicts;
use super::quadrature::QuadPoint;
use super::source::{Rays, ReceiverNode, Source};
use crate::scene::Rgb;
use std::cell::Cell;

// Every evaluation zeroes its arrays of `MAX_POINTS` (a receiver's rule and check points); the
// rule points where the touching fallback stood in, and the rule and check points all of whose
// rays passed, are bits of a `u32`.
use super::cover::MAX_POINTS;
const _: () = assert!(MAX_POINTS <= u32::BITS as usize);

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
    /// The node's children (bit `c` for child `c`) from every point inside which (rule and check
    /// points, [`BasisAtControlPoints::children_of`](super::rules::BasisAtControlPoints)) rays
    /// were traced (or an earlier shot's verdicts for them read back) and all passed: where a
    /// link re-sent to a child is taken as seen whole. Never after [`Rays::AllPass`]: a link
    /// taken as seen whole is not passed on so again (the rays traced from a node sample what
    /// its children see, not its grandchildren); nor after [`Rays::Centre`] (one ray per point
    /// does not sample the source).
    pub seen_whole: u8,
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

impl Received {
    /// Adds rule point `k`'s irradiance and form factor, as `e` and `form_factors` hold them, to
    /// the projection `dh` and the exchange seen, at the point's weight (`q`), basis values
    /// (`psi_k`, one per function), covered fraction of its zone and the node's `area`; counts
    /// it among the `touching` points when the fallback stood in there.
    fn add_rule_point(
        &mut self,
        k: usize,
        q: &QuadPoint,
        psi_k: &[f64],
        covered: f64,
        area: f64,
        touching: bool,
    ) {
        self.exchange_seen_by_receiver += q.weight * covered * self.form_factors[k] * area;
        self.touching += u64::from(touching);
        let e = self.e[k];
        for (dh, &psi) in self.dh.iter_mut().zip(psi_k) {
            for ch in 0..3 {
                dh[ch] += q.weight * psi * e[ch];
            }
        }
    }
}

/// Asks `source` at `receiver`'s `rule` points (their basis values: `psi`, `nr` functions), then
/// at its first `check_points` check points ([`ReceiverNode::check_point`]), and projects the
/// rule points' irradiance onto the receiver's basis. A point that casts from where an earlier
/// one does takes that point's answer, asking the source nothing ([`ReceiverNode::alike`]: on
/// an extended root's node the first with the same stand-in, on a native root the first at the
/// same place). `rays` says how the shadow rays are decided, unless an earlier shot's verdicts
/// for this link are `known`. `kids`: the children each point lies in, for
/// [`Received::seen_whole`].
#[allow(clippy::too_many_arguments)]
pub(super) fn receive(
    source: &impl Source,
    receiver: &ReceiverNode,
    rule: &[QuadPoint],
    psi: &[[f64; MAX_FUNCTIONS]],
    kids: &[u8],
    nr: usize,
    check_points: usize,
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
        seen_whole: 0,
        seen: [0; MAX_POINTS],
        form_factors: [0.0; MAX_POINTS],
        verdict_rays: Cell::new(known.and_then(KnownVerdicts::verdict_rays)),
    };
    // The point asked before whose answer a point takes.
    let asked_before = |k: usize| -> Option<usize> {
        let i = usize::from(receiver.alike[k]);
        debug_assert!(i <= k);
        (i != k).then_some(i)
    };
    // Rule points where the touching fallback stood in; points all of whose rays passed.
    let mut touching = 0u32;
    let mut passed = 0u32;
    let covered = |k: usize| receiver.cover.as_ref().map_or(1.0, |c| c.alpha[k]);
    for k in 0..out.points {
        if let Some(i) = asked_before(k) {
            out.e[k] = out.e[i];
            out.seen[k] = out.seen[i];
            out.form_factors[k] = out.form_factors[i];
            passed |= (passed >> i & 1) << k;
            // A rule point copies a rule point (they come first): what it adds is its own
            // weight's share (nothing where the copied one had no answer: its values are
            // zero); the largest values and any-flags already hold the copied one's.
            if let Some(q) = rule.get(k) {
                let touched = touching & (1 << i) != 0;
                out.add_rule_point(
                    k,
                    q,
                    &psi[k][..nr],
                    covered(k),
                    receiver.patch.area,
                    touched,
                );
            }
            continue;
        }
        let x = match rule.get(k) {
            Some(q) => receiving_point(root, &receiver.patch, receiver.cover, k, q.st),
            None => receiver.check_point(k - nk),
        };
        // None: no ray sampled what this point's neighbours in a child may see.
        let Some(p) = source.irradiance_at(x, root.normal, ignore, rays, known.map(|v| v.point(k)))
        else {
            continue;
        };
        passed |= u32::from(p.any_visible && !p.any_blocked) << k;
        out.e[k] = p.e;
        out.seen[k] = p.seen;
        out.form_factors[k] = p.form_factor;
        let Some(q) = rule.get(k) else {
            continue;
        };
        out.unoccluded_max = out.unoccluded_max.max(p.unoccluded);
        out.any_visible |= p.any_visible;
        out.any_blocked |= p.any_blocked;
        out.source_side_err = out.source_side_err.max(p.source_side_err);
        out.coverage_err = out.coverage_err.max(p.coverage_err);
        touching |= u32::from(p.touching) << k;
        out.add_rule_point(
            k,
            q,
            &psi[k][..nr],
            covered(k),
            receiver.patch.area,
            p.touching,
        );
    }
    if rays == Rays::Trace {
        out.seen_whole = children_seen_whole(passed, &kids[..out.points]);
    }
    out
}

/// The children (bit `c`) every point inside which passed (bit `k` of `passed` for point `k`,
/// which lies in the children `kids[k]`): each point that did not pass takes its children out.
/// A child that holds none of the points counts as seen whole: with the check points every
/// child holds some (`control_points_know_the_children_they_lie_in`); with the rule points
/// alone the node-sum check, the only reader, is off.
fn children_seen_whole(passed: u32, kids: &[u8]) -> u8 {
    kids.iter()
        .enumerate()
        .filter(|&(k, _)| passed >> k & 1 == 0)
        .fold(0b1111, |whole, (_, &m)| whole & !m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Shape;
    use crate::solver::far_field::tests::{square_under_square, square_under_square_blocked_by};
    use crate::solver::hierarchy::Hierarchy;
    use crate::solver::near_verdicts::ALL_VISIBLE;
    use crate::solver::rules::{corner_probe_points, Bases, BasisAtControlPoints, Rules};
    use glam::{DVec2, DVec3};

    /// `node` asked about `source` at its M2 rule and check points with `rays`: what it
    /// received, and the rays `visibility` traced.
    fn receive_counting(
        source: &impl Source,
        node: &ReceiverNode,
        visibility: &crate::solver::visibility::Visibility,
        rays: Rays,
    ) -> (Received, u64) {
        let (bases, rules) = (Bases::new(2), Rules::new(2));
        let psi = BasisAtControlPoints::new(&bases, &rules);
        let shape = node.root.shape;
        let before = visibility.rays_traced();
        let got = receive(
            source,
            node,
            rules.of(shape),
            psi.of(shape),
            psi.children_of(shape),
            bases.of(shape).len(),
            corner_probe_points(shape).len(),
            rays,
            None,
        );
        (got, visibility.rays_traced() - before)
    }

    /// The children seen whole, against a brute force (a child is, when every point inside it
    /// passed), for every pattern of passing points of each shape's M2 control points.
    #[test]
    fn a_child_is_seen_whole_when_every_point_inside_it_passed() {
        let at = BasisAtControlPoints::new(&Bases::new(2), &Rules::new(2));
        for shape in [Shape::Triangle, Shape::Parallelogram] {
            let kids = at.children_of(shape);
            assert!(kids.len() < 16);
            for passed in 0..1u32 << kids.len() {
                let brute = (0..4)
                    .filter(|&c| {
                        (0..kids.len())
                            .filter(|&k| kids[k] & (1 << c) != 0)
                            .all(|k| passed & (1 << k) != 0)
                    })
                    .fold(0u8, |m, c| m | 1 << c);
                assert_eq!(
                    children_seen_whole(passed, kids),
                    brute,
                    "{shape:?} {passed:b}"
                );
            }
        }
    }

    /// The receiver of `square_under_square` (its root node) asked at its rule and check points
    /// with `rays`: what it received, and the rays traced.
    fn received(blocked: bool, rays: Rays) -> (Received, u64) {
        square_under_square(blocked, |source, root, visibility| {
            let h = Hierarchy::new(Bases::new(2).of(root.shape).len());
            let rules = Rules::new(2);
            let node = ReceiverNode::new(root, &h, 0, &rules);
            receive_counting(source, &node, visibility, rays)
        })
    }

    /// A blocker just under the receiver's corner at (1, 1) shades only points of child 3 (the
    /// rule point at (0.887, 0.887) and the check point at (0.98, 0.98)): the other three
    /// children are seen whole, as a brute force over the points' verdicts says.
    #[test]
    fn a_child_is_seen_whole_where_the_rays_from_its_points_all_passed() {
        let blocker = (DVec3::new(0.8, 0.8, 19.9), DVec3::new(1.0, 1.0, 19.9));
        let got = square_under_square_blocked_by(Some(blocker), |source, root, visibility| {
            let h = Hierarchy::new(Bases::new(2).of(root.shape).len());
            let rules = Rules::new(2);
            let node = ReceiverNode::new(root, &h, 0, &rules);
            receive_counting(source, &node, visibility, Rays::Trace).0
        });
        let kids = BasisAtControlPoints::new(&Bases::new(2), &Rules::new(2))
            .children_of(Shape::Parallelogram)
            .to_vec();
        let shaded: Vec<usize> = (0..got.points)
            .filter(|&k| got.seen[k] != ALL_VISIBLE)
            .collect();
        assert_eq!(
            shaded.len(),
            2,
            "the two points under the blocker: {shaded:?}"
        );
        assert!(
            shaded.iter().all(|&k| kids[k] == 0b1000),
            "{shaded:?} lie in child 3 only"
        );
        assert_eq!(got.seen_whole, 0b0111);
    }

    /// Rays taken as passing trace none and deliver what an open scene delivers, blocker or not;
    /// `seen_whole` says in which children traced rays all passed, and never passes a taken
    /// verdict on.
    #[test]
    fn rays_taken_as_passing_trace_none_and_see_the_source_whole() {
        let (open, open_rays) = received(false, Rays::Trace);
        assert!(open_rays > 0);
        assert!(open.seen_whole == 0b1111 && open.any_visible && !open.any_blocked);
        let (shadowed, _) = received(true, Rays::Trace);
        assert!(shadowed.any_blocked);
        // The blocker at half height is under some ray of every point: no child is seen whole.
        assert_eq!(shadowed.seen_whole, 0);
        assert!(shadowed.e[..shadowed.points] != open.e[..open.points]);
        let (taken, taken_rays) = received(true, Rays::AllPass);
        assert_eq!(taken_rays, 0);
        assert_eq!(taken.e[..taken.points], open.e[..open.points]);
        assert_eq!(taken.dh, open.dh);
        assert!(taken.any_visible && !taken.any_blocked);
        assert_eq!(taken.seen_whole, 0, "a taken verdict is not passed on");
    }

    /// A parallelogram's check point at its centre, where its M2 rule has a point, takes that
    /// point's irradiance, verdicts and form factor and traces no ray of its own; the other
    /// check points trace theirs. Behind the blocker, so that the points differ.
    #[test]
    fn a_check_point_on_a_rule_point_takes_its_irradiance() {
        let rules = Rules::new(2);
        let rule = rules.of(Shape::Parallelogram);
        let probes = corner_probe_points(Shape::Parallelogram);
        let centre = |st: DVec2| st == DVec2::splat(0.5);
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

    /// On an extended root's node that straddles the border of the face's hole, points whose
    /// stand-ins coincide (their closest face point) ask the source once: the rays are nine per
    /// distinct stand-in, and every value is what asking each point gives (the same node with
    /// every point its own, and each point's irradiance asked directly), among them a copied
    /// rule point's share of the projection and of the exchange seen (its zone partly covered).
    #[test]
    fn points_that_stand_in_alike_ask_the_source_once() {
        use crate::solver::cover::tests::{holed, maps_to_depth};
        use crate::solver::cover::NodeCover;
        use crate::solver::element::Patch;
        let rules = Rules::new(2);
        let shape = Shape::Parallelogram;
        let basis = crate::solver::basis::Basis::new(shape, 2);
        let mask = holed(0.4);
        // Rule points that take an earlier point's answer and weigh in the projection.
        let copied = |c: &NodeCover| -> Vec<usize> {
            (0..rules.of(shape).len())
                .filter(|&k| usize::from(c.alike[k]) != k && c.alpha[k] > 0.0)
                .collect()
        };
        let (map, cover) = maps_to_depth(3)
            .into_iter()
            .map(|m| (m, NodeCover::new(&mask, &m, &rules.cover, &basis, true)))
            .max_by_key(|(_, c)| copied(c).len())
            .expect("nodes");
        assert!(!copied(&cover).is_empty(), "{cover:?}");
        let mut own = cover;
        own.alike = std::array::from_fn(|k| k as u8);
        square_under_square(true, |source, receiver, visibility| {
            let mut root = receiver.clone();
            root.mask = Some(mask.clone());
            let ask = |cover: &NodeCover| {
                let node = ReceiverNode {
                    root: &root,
                    map,
                    depth: 3,
                    patch: Patch::new(&root, &map),
                    cover: Some(cover),
                    alike: &cover.alike,
                    reflectance_deviation: None,
                    spread_points: None,
                };
                receive_counting(source, &node, visibility, Rays::Trace)
            };
            let (got, rays) = ask(&cover);
            let (each, each_rays) = ask(&own);
            let nk = got.rule_points;
            let stand_ins: Vec<DVec3> = (0..got.points)
                .map(|k| match k.checked_sub(nk) {
                    None => root.frame.point(cover.visibility_point[k]),
                    Some(j) => root.frame.point(cover.check_point[j]),
                })
                .collect();
            let mut distinct = stand_ins.clone();
            distinct.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).expect("finite"));
            distinct.dedup();
            assert_eq!(rays, 9 * distinct.len() as u64);
            assert_eq!(each_rays, 9 * got.points as u64);
            assert!(distinct.len() < got.points);
            let ignore = source.ignored_faces(root.face.0);
            for (k, &x) in stand_ins.iter().enumerate() {
                let p = source
                    .irradiance_at(x, root.normal, ignore, Rays::Trace, None)
                    .expect("the source is in front of every point");
                assert_eq!((got.e[k], got.seen[k]), (p.e, p.seen), "point {k}");
                assert_eq!(got.form_factors[k], p.form_factor, "point {k}");
            }
            assert!(got.exchange_seen_by_receiver > 0.0);
            for k in copied(&cover) {
                assert_ne!(got.e[k], [0.0; 3], "copied point {k} receives");
            }
            assert_eq!(got.e, each.e);
            assert_eq!(got.dh, each.dh);
            assert_eq!(got.seen, each.seen);
            assert_eq!(got.form_factors, each.form_factors);
            assert_eq!(
                got.exchange_seen_by_receiver,
                each.exchange_seen_by_receiver
            );
            assert_eq!(
                (got.unoccluded_max, got.source_side_err, got.coverage_err),
                (each.unoccluded_max, each.source_side_err, each.coverage_err)
            );
            assert_eq!(
                (got.seen_whole, got.touching),
                (each.seen_whole, each.touching)
            );
        });
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
        assert_eq!(
            centre.seen_whole, 0,
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
