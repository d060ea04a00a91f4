//! How an extended root's elements cover its face (paper 3.3): per element, its status (empty,
//! full, partial), the covered fraction alpha of each quadrature point's zone of influence (the
//! emission weights), the points that stand in for its quadrature points and its check points in
//! visibility queries (their closest points on the face: `V'(Q,P) = V(Q,P')`) with, for a stored
//! node, the first point standing in at each one's place (`alike`), and its face moments
//! `m_i = (1/|e|) * integral over (face inside e) of phi_i`, which turn coefficients into integrals
//! over the face: `integral over (face inside e) of f = |e| * sum_i f_i m_i`.
//!
//! Invariants: a hierarchy of an extended root holds one [`NodeCover`] per node (computed when the
//! node is created, [`extend`], which only `Hierarchy`'s side-table owner calls); native roots
//! hold none. `alike[k] <= k` names the first point (rule points, then check points) whose
//! stand-in equals point `k`'s, `k` itself if none; a virtual source element's is the identity.
//! A full element has alpha 1, moments
//! `(1, 0, ...)` and its own quadrature points; an empty one alpha 0 and moments 0. Moments are
//! exact up to rounding (the clipped face split into signed triangles, a triangle rule exact for
//! the basis' products with 1), so power counted over the face never includes the empty part of a
//! domain.

use super::basis::{Basis, ChildMap, MAX_FUNCTIONS};
use super::hierarchy::Hierarchy;
use super::quadrature::QuadPoint;
use crate::domain::{ElementRoot, ElementStatus, FaceMask, StBox};
use crate::scene::Rgb;
use glam::DVec2;

/// Most points of a quadrature rule the solver uses (4 per axis, M3).
pub const MAX_RULE_POINTS: usize = 16;
const _: () =
    assert!(MAX_RULE_POINTS == (super::basis::MAX_ORDER + 1) * (super::basis::MAX_ORDER + 1));
/// A parallelogram's check points (`rules::corner_probe_points`: near the corners, the centre).
pub const CHECK_POINTS: usize = 5;

/// Most points a receiver node is asked at: its rule's, then its check points.
pub const MAX_POINTS: usize = MAX_RULE_POINTS + CHECK_POINTS;
const _: () = assert!(MAX_POINTS <= u8::MAX as usize);

/// The face inside one element of an extended root.
#[derive(Debug, Clone, Copy)]
pub struct NodeCover {
    pub status: ElementStatus,
    /// Per point of the element's quadrature rule: the covered fraction of its zone of influence.
    pub alpha: [f64; MAX_RULE_POINTS],
    /// Per point of the rule: the root point its visibility rays start from (the point itself
    /// when on the face, else its closest point on the face; left as the point itself in an empty
    /// virtual source element, which never casts a ray).
    pub visibility_point: [DVec2; MAX_RULE_POINTS],
    /// The same for the element's check points (`CoverRules::check_points`): computed once
    /// with the node, not at every transfer to it (a closest point is O(n) in the face's edges).
    pub check_point: [DVec2; CHECK_POINTS],
    /// Per point, in the order a receiver asks them (the rule's `n` points, then the check
    /// points at `n + j`): the first point that stands in at the same place, the point itself if
    /// none does. Off the face, several points often share their closest face point (beyond a
    /// vertex of the face, or across an edge along the root's axes): a receiver asks the source
    /// once for them all (`transfer::receive`). Set for stored nodes; a virtual source element
    /// (which never receives) keeps every point its own.
    pub alike: [u8; MAX_POINTS],
    /// `(1/|e|) * integral over (face inside e) of phi_i`, per basis function.
    pub moments: [f64; MAX_FUNCTIONS],
}

/// What computing covers needs: the element rule, its zones of influence, and a triangle rule for
/// the moments.
#[derive(Debug, Clone)]
pub struct CoverRules {
    pub rule: Vec<QuadPoint>,
    pub zones: Vec<StBox>,
    /// Exact for total degree 4 (the product of two M3 functions' degrees per axis is reached by
    /// `phi_i` alone: degree 2 per axis, 4 in all).
    pub moment_rule: Vec<QuadPoint>,
    /// The element's check points, in reference coordinates.
    pub check_points: [DVec2; CHECK_POINTS],
}

/// The box of root coordinates an element of a parallelogram root covers.
pub fn node_box(map: &ChildMap) -> StBox {
    debug_assert!(map.e1.y == 0.0 && map.e2.x == 0.0 && map.e1.x > 0.0 && map.e2.y > 0.0);
    StBox::new(map.o, map.o + map.e1 + map.e2)
}

impl NodeCover {
    /// The cover of the element with map `map` (in root coordinates) of a root with `mask`.
    /// `stored`: the element is a node of the hierarchy, which receives even when empty, so it
    /// needs its stand-ins; a virtual source element that is empty never emits and gets none.
    /// Moments are computed for every partly covered element: a partial source emits the face's
    /// exact mean (see `transfer`).
    pub fn new(
        mask: &FaceMask,
        map: &ChildMap,
        rules: &CoverRules,
        basis: &Basis,
        stored: bool,
    ) -> Self {
        Self::with_face(mask, map, rules, basis, stored).0
    }

    /// As [`NodeCover::new`], also returning the face inside a partly covered element (`clip`'s
    /// rings, in root coordinates), which its moments are integrated over: a caller that needs
    /// the face too (a virtual source's exact form factor) clips once.
    pub fn with_face(
        mask: &FaceMask,
        map: &ChildMap,
        rules: &CoverRules,
        basis: &Basis,
        stored: bool,
    ) -> (Self, Option<Vec<Vec<DVec2>>>) {
        let b = node_box(map);
        let n = rules.rule.len();
        debug_assert!(n <= MAX_RULE_POINTS && rules.zones.len() == n);
        let mut cover = NodeCover {
            status: mask.coverage(b).status,
            alpha: [0.0; MAX_RULE_POINTS],
            visibility_point: [DVec2::ZERO; MAX_RULE_POINTS],
            check_point: rules.check_points.map(|st| map.apply(st)),
            alike: std::array::from_fn(|k| k as u8),
            moments: [0.0; MAX_FUNCTIONS],
        };
        for (k, q) in rules.rule.iter().enumerate() {
            cover.visibility_point[k] = map.apply(q.st);
        }
        let mut face = None;
        match cover.status {
            ElementStatus::Full => {
                cover.alpha[..n].fill(1.0);
                cover.moments[0] = 1.0;
            }
            ElementStatus::Empty => {}
            ElementStatus::Partial => {
                for (k, z) in rules.zones.iter().enumerate() {
                    let zone = StBox::new(map.apply(z.min), map.apply(z.max));
                    cover.alpha[k] = mask.coverage(zone).fraction(&zone);
                }
                let rings = mask.clip(b);
                cover.moments = face_moments(&rings, map, b, rules, basis);
                face = Some(rings);
            }
        }
        // A full element's points are on the face; an empty element never emits: as a virtual
        // source it needs no stand-ins.
        let needs_stand_ins = match cover.status {
            ElementStatus::Full => false,
            ElementStatus::Empty => stored,
            ElementStatus::Partial => true,
        };
        if needs_stand_ins {
            let points = cover.visibility_point[..n].iter_mut();
            for p in points.chain(cover.check_point.iter_mut()) {
                *p = mask.closest_point(*p);
            }
        }
        if stored {
            cover.alike = alike_points(&cover.visibility_point[..n], &cover.check_point);
        }
        (cover, face)
    }

    /// Whether the element emits at all.
    pub fn emits(&self) -> bool {
        self.status != ElementStatus::Empty
    }
}

/// For each of the points `rule` then `check` (one list), the index of the first point equal to
/// it (itself if none): a node's stand-ins (`NodeCover::alike`), or a shape's reference points
/// (`Rules::alike`).
pub(super) fn alike_points(rule: &[DVec2], check: &[DVec2]) -> [u8; MAX_POINTS] {
    let mut points = [DVec2::ZERO; MAX_POINTS];
    let n = rule.len() + check.len();
    debug_assert!(n <= MAX_POINTS);
    for (slot, &p) in points.iter_mut().zip(rule.iter().chain(check)) {
        *slot = p;
    }
    std::array::from_fn(|k| {
        let first = (k < n)
            .then(|| points[..k].iter().position(|&p| p == points[k]))
            .flatten()
            .unwrap_or(k);
        first as u8
    })
}

/// `(1/|e|) * integral over (face inside e) of phi_i`, by signed triangles of the clipped face
/// (`rings`: the face inside the box `b`, as `FaceMask::clip` gives it).
fn face_moments(
    rings: &[Vec<DVec2>],
    map: &ChildMap,
    b: StBox,
    rules: &CoverRules,
    basis: &Basis,
) -> [f64; MAX_FUNCTIONS] {
    let nf = basis.len();
    let mut m = [0.0; MAX_FUNCTIONS];
    let mut phi = [0.0; MAX_FUNCTIONS];
    for ring in rings {
        let p0 = ring[0];
        for i in 1..ring.len() - 1 {
            let (p1, p2) = (ring[i], ring[i + 1]);
            let signed_area = 0.5 * (p1 - p0).perp_dot(p2 - p0);
            if signed_area == 0.0 {
                continue;
            }
            for q in &rules.moment_rule {
                let st = p0 + (p1 - p0) * q.st.x + (p2 - p0) * q.st.y;
                basis.eval(map.local(st), &mut phi);
                for a in 0..nf {
                    m[a] += signed_area * q.weight * phi[a];
                }
            }
        }
    }
    let box_area = b.area();
    for x in m.iter_mut().take(nf) {
        *x /= box_area;
    }
    m
}

/// Computes the covers of the nodes of `h` that have none yet (all nodes of a new hierarchy, the
/// children of a split). Does nothing for a native root.
pub(super) fn extend(h: &mut Hierarchy, root: &ElementRoot, rules: &CoverRules, basis: &Basis) {
    let Some(mask) = &root.mask else {
        return;
    };
    for i in h.covers.len()..h.nodes.len() {
        let cover = NodeCover::new(mask, &h.nodes[i].map, rules, basis, true);
        h.covers.push(cover);
    }
}

/// The cover of node `b` of `root`'s hierarchy: `None` for a native root. Every node of an
/// extended root has one ([`extend`] runs after each split), so a missing one panics.
pub fn of_node<'h>(h: &'h Hierarchy, root: &ElementRoot, b: usize) -> Option<&'h NodeCover> {
    h.debug_assert_side_tables(root);
    root.mask.as_ref().map(|_| &h.covers[b])
}

/// The integral over the face inside a leaf of area `area` (its box's) of the function whose
/// `n` coefficients are `coeff(a)`: `area * sum_a m_a c_a`, per channel.
fn leaf_face_integral(cover: &NodeCover, area: f64, n: usize, coeff: impl Fn(usize) -> Rgb) -> Rgb {
    let mut leaf = [0.0; 3];
    for a in 0..n {
        let m = cover.moments[a];
        if m == 0.0 {
            continue;
        }
        let c = coeff(a);
        for ch in 0..3 {
            leaf[ch] += area * m * c[ch];
        }
    }
    leaf
}

/// Per node of `h`, the mean over the face inside it of the function whose coefficients `array`
/// holds (the leaves' functions, integrated with their moments and summed up the tree; 0 for a
/// node the face does not cover). An inner node's own coefficients are its projection over the
/// whole element, empty part included: restricted to the face, they can integrate to much more or
/// less than its leaves do where the function grows off the face. For the hierarchy of an
/// extended root (it needs the covers).
pub fn face_means(h: &Hierarchy, array: &[Rgb]) -> Vec<Rgb> {
    debug_assert_eq!(h.covers.len(), h.nodes.len());
    let n = h.len;
    // Integrals over the face inside each node, relative to the root's area; children have larger
    // indices than their parent, so a reverse sweep sees them first.
    let mut integral = vec![[0.0; 3]; h.nodes.len()];
    for i in (0..h.nodes.len()).rev() {
        let node = &h.nodes[i];
        if node.is_leaf() {
            let area = node.map.e1.perp_dot(node.map.e2).abs();
            integral[i] = leaf_face_integral(&h.covers[i], area, n, |a| array[i * n + a]);
        } else {
            let first = node.first_child as usize;
            integral[i] =
                std::array::from_fn(|ch| (first..first + 4).map(|c| integral[c][ch]).sum());
        }
    }
    h.nodes
        .iter()
        .zip(&h.covers)
        .zip(integral)
        .map(|((node, cover), sum)| {
            let face_area = node.map.e1.perp_dot(node.map.e2).abs() * cover.moments[0];
            if face_area > 0.0 {
                sum.map(|x| x / face_area)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// The integral over the root's face of the function whose coefficients `array` holds (per node,
/// `h.len` each), per channel: `|root| * coefficient 0` for a native root; over the leaves of an
/// extended root, each weighted by its face moments.
pub fn face_integral(h: &Hierarchy, array: &[Rgb], root: &ElementRoot) -> Rgb {
    face_integral_by(h, root, false, |k| array[k])
}

/// As [`face_integral`], for the function whose coefficient `k` (node `k / h.len`, function
/// `k % h.len`) is `coeff(k)`. With `clamp_leaves`, each leaf's integral is clamped at 0 per
/// channel: the received light is never negative, but a polynomial fitted over a whole element can
/// dip below 0 on the part of it the face covers (output means use this; energy accounting not).
pub fn face_integral_by(
    h: &Hierarchy,
    root: &ElementRoot,
    clamp_leaves: bool,
    coeff: impl Fn(usize) -> Rgb,
) -> Rgb {
    // (`if`, not `max`: a NaN must stay visible.)
    let clamp = |x: f64| if clamp_leaves && x < 0.0 { 0.0 } else { x };
    if root.mask.is_none() {
        return coeff(0).map(|c| clamp(c * root.area_m2));
    }
    debug_assert_eq!(h.covers.len(), h.nodes.len());
    let n = h.len;
    let mut sum = [0.0; 3];
    for (i, node) in h.nodes.iter().enumerate() {
        let cover = &h.covers[i];
        if !node.is_leaf() || cover.status == ElementStatus::Empty {
            continue;
        }
        let area = root.area_m2 * node.map.e1.perp_dot(node.map.e2).abs();
        let leaf = leaf_face_integral(cover, area, n, |a| coeff(i * n + a));
        for ch in 0..3 {
            sum[ch] += clamp(leaf[ch]);
        }
    }
    sum
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::domain::{ExtendedDomain, Shape};
    use crate::solver::quadrature::{rule, zones_of_influence};
    use std::sync::Arc;

    fn rules(order: usize) -> CoverRules {
        CoverRules {
            rule: rule(Shape::Parallelogram, order + 1),
            zones: zones_of_influence(order + 1),
            moment_rule: rule(Shape::Triangle, 3),
            check_points: crate::solver::rules::PARALLELOGRAM_CHECK_POINTS,
        }
    }

    /// The unit square with a centred square hole of side `h` as a domain (its own
    /// parallelogram is the unit square).
    pub(in crate::solver) fn holed(h: f64) -> FaceMask {
        let v = |x: f64, y: f64| DVec2::new(x, y);
        let (a, b) = (0.5 - h / 2.0, 0.5 + h / 2.0);
        let outer = vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
        let hole = vec![v(a, a), v(a, b), v(b, b), v(b, a)];
        FaceMask::new(
            Arc::new(ExtendedDomain::from_plane_polygon(&outer, &[hole]).unwrap()),
            false,
            1e-9,
        )
    }

    #[test]
    fn moments_of_a_holed_square_match_the_exact_integrals() {
        // Over the whole domain: m_0 is the covered fraction; the hole is centred, so by symmetry
        // every function odd in s or in t integrates to 0 over the face.
        let mask = holed(0.5);
        // The domain may be the square in any of its symmetric frames: moments of odd functions
        // vanish whatever the frame.
        for order in 1..=3 {
            let basis = Basis::new(Shape::Parallelogram, order);
            let c = NodeCover::new(&mask, &ChildMap::IDENTITY, &rules(order), &basis, true);
            assert_eq!(c.status, ElementStatus::Partial);
            assert!((c.moments[0] - 0.75).abs() < 1e-13, "{}", c.moments[0]);
            if order >= 2 {
                // phi_1 ~ sqrt3 (2t - 1) and phi_3 ~ sqrt3 (2s - 1): odd, integral 0.
                for a in [1, 3] {
                    assert!(c.moments[a].abs() < 1e-13);
                }
            }
            if order == 3 {
                // phi = sqrt5 (6 s^2 - 6 s + 1) (times 1 in t; indices 2 and 6 are the two
                // quadratics, equal here by the hole's symmetry): integral 0 over the square, so its
                // face integral is minus its integral over the hole; Simpson gives that independently.
                let simpson = |f: &dyn Fn(f64) -> f64, a: f64, b: f64| {
                    let n = 2000;
                    let h = (b - a) / n as f64;
                    (0..=n)
                        .map(|i| {
                            let w = if i == 0 || i == n {
                                1.0
                            } else if i % 2 == 1 {
                                4.0
                            } else {
                                2.0
                            };
                            w * f(a + i as f64 * h)
                        })
                        .sum::<f64>()
                        * h
                        / 3.0
                };
                let p2 = |s: f64| 5f64.sqrt() * (6.0 * s * s - 6.0 * s + 1.0);
                // Over the face: integral over the square (0) minus over the hole (width 0.5 in t).
                let expected = -simpson(&p2, 0.25, 0.75) * 0.5;
                for a in [2, 6] {
                    let got = c.moments[a];
                    assert!(
                        (got - expected).abs() < 1e-9,
                        "quadratic moment {a}: {got} vs {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn covers_of_children_sum_to_the_parent() {
        // Area (m_0 |e|) is additive over the four children; alpha of a full child is 1.
        let mask = holed(0.3);
        let basis = Basis::new(Shape::Parallelogram, 2);
        let r = rules(2);
        let parent = NodeCover::new(&mask, &ChildMap::IDENTITY, &r, &basis, true);
        let maps = crate::solver::basis::child_maps(Shape::Parallelogram);
        let mut sum = 0.0;
        for m in &maps {
            let c = NodeCover::new(&mask, m, &r, &basis, true);
            sum += 0.25 * c.moments[0];
            for k in 0..r.rule.len() {
                assert!((0.0..=1.0).contains(&c.alpha[k]));
                let p = m.apply(r.rule[k].st);
                if mask.contains(p) {
                    assert_eq!(c.visibility_point[k], p);
                } else {
                    assert!(mask.contains(c.visibility_point[k]));
                    assert!(c.alpha[k] < 1.0);
                }
            }
        }
        assert!((sum - parent.moments[0]).abs() < 1e-13);
        assert!((parent.moments[0] - (1.0 - 0.09)).abs() < 1e-13);
    }
    /// A stored node's check points stand in as `mask.closest_point` would at every transfer:
    /// themselves on the face (full nodes among them), their closest face point off it; a
    /// virtual source element that is empty keeps them as they are (it never receives). The
    /// centre check point stands in exactly where the M2 rule's centre point does.
    #[test]
    fn check_points_stand_in_as_their_closest_face_points() {
        let mask = holed(0.5);
        let basis = Basis::new(Shape::Parallelogram, 2);
        let r = rules(2);
        let maps = maps_to_depth(3);
        let (mut off_face, mut full) = (0, 0);
        // The centre check point and the M2 rule's centre point, alike (`Rules::alike`).
        let centre = |st: &DVec2| *st == DVec2::splat(0.5);
        let centre_check = r
            .check_points
            .iter()
            .position(centre)
            .expect("centre check");
        let centre_rule = r
            .rule
            .iter()
            .position(|q| centre(&q.st))
            .expect("M2 centre");
        for m in &maps {
            let c = NodeCover::new(&mask, m, &r, &basis, true);
            full += usize::from(c.status == ElementStatus::Full);
            assert_eq!(
                c.check_point[centre_check], c.visibility_point[centre_rule],
                "{m:?}: a twin stands in where its rule point does"
            );
            for (j, &st) in r.check_points.iter().enumerate() {
                let p = m.apply(st);
                assert_eq!(c.check_point[j], mask.closest_point(p), "{m:?} point {j}");
                off_face += usize::from(!mask.contains(p));
            }
            let virtual_source = NodeCover::new(&mask, m, &r, &basis, false);
            if virtual_source.status == ElementStatus::Empty {
                let own = r.check_points.map(|st| m.apply(st));
                assert_eq!(virtual_source.check_point, own);
            }
        }
        assert!(off_face > 0, "some check points lie in the hole");
        assert!(full > 0, "some nodes are fully covered");
    }

    /// The maps of a parallelogram root's nodes, the root and its descendants to `depth`.
    pub(in crate::solver) fn maps_to_depth(depth: usize) -> Vec<ChildMap> {
        let mut level = vec![ChildMap::IDENTITY];
        let mut maps = level.clone();
        for _ in 0..depth {
            level = level
                .iter()
                .flat_map(|m| {
                    crate::solver::basis::child_maps(Shape::Parallelogram).map(|c| m.then(&c))
                })
                .collect();
            maps.extend_from_slice(&level);
        }
        maps
    }

    /// A stored node's `alike` names, for each point (rule points, then check points), the first
    /// point with the same stand-in, found here by a map keyed by the stand-ins' bits: off the
    /// face, some points share one at every order; on a full node only M2's centre does. A
    /// virtual source element keeps every point its own.
    #[test]
    fn points_that_stand_in_alike_name_the_first_of_them() {
        let mask = holed(0.5);
        for order in 1..=3 {
            let basis = Basis::new(Shape::Parallelogram, order);
            let r = rules(order);
            let n = r.rule.len();
            let (mut shared_off_face, mut shared_full, mut full_nodes) = (0, 0, 0);
            for m in &maps_to_depth(3) {
                let c = NodeCover::new(&mask, m, &r, &basis, true);
                full_nodes += usize::from(c.status == ElementStatus::Full);
                let points = c.visibility_point[..n].iter().chain(&c.check_point);
                let mut first = std::collections::HashMap::new();
                for (k, p) in points.enumerate() {
                    // `+ 0.0`: a negative zero is the same point.
                    let bits = ((p.x + 0.0).to_bits(), (p.y + 0.0).to_bits());
                    let f = *first.entry(bits).or_insert(k);
                    assert_eq!(usize::from(c.alike[k]), f, "M{order} {m:?} point {k}");
                    if f != k && c.status == ElementStatus::Full {
                        shared_full += 1;
                    } else if f != k {
                        shared_off_face += 1;
                    }
                }
                let virtual_source = NodeCover::new(&mask, m, &r, &basis, false);
                for (k, &a) in virtual_source.alike.iter().enumerate() {
                    assert_eq!(usize::from(a), k, "M{order} {m:?}: a virtual source's own");
                }
            }
            assert!(
                shared_off_face > 0,
                "M{order}: stand-ins off the face shared"
            );
            assert!(full_nodes > 0, "M{order}: some nodes are full");
            let centre_twin = usize::from(order == 2);
            assert_eq!(
                shared_full,
                centre_twin * full_nodes,
                "M{order}: full nodes"
            );
        }
    }

    #[test]
    fn face_means_integrate_the_leaves_over_the_face() {
        // A holed square split twice (the root, then its first child), each leaf holding its own
        // linear function; the stored inner nodes hold something else entirely, as a pulled
        // projection over the whole element may. Each node's face mean against a brute-force mean
        // over a fine grid of the face points inside it, evaluated at the leaf holding each point.
        let mask = holed(0.3);
        let shape = Shape::Parallelogram;
        let basis = Basis::new(shape, 2);
        let r = rules(2);
        let n = basis.len();
        let mut h = Hierarchy::new(n);
        let first = h.split(0, &basis, shape);
        h.split(first, &basis, shape);
        h.covers = h
            .nodes
            .iter()
            .map(|node| NodeCover::new(&mask, &node.map, &r, &basis, true))
            .collect();
        for (i, node) in h.nodes.iter().enumerate() {
            for a in 0..n {
                let x = if node.is_leaf() {
                    1.0 + 0.3 * i as f64 - 0.7 * a as f64
                } else {
                    100.0
                };
                h.u[i * n + a] = [x, 2.0 * x, -x];
            }
        }
        let means = face_means(&h, &h.u);
        let leaves: Vec<usize> = (0..h.nodes.len())
            .filter(|&i| h.nodes[i].is_leaf())
            .collect();
        let inside = |i: usize, p: DVec2| {
            let b = node_box(&h.nodes[i].map);
            p.x >= b.min.x && p.x < b.max.x && p.y >= b.min.y && p.y < b.max.y
        };
        let grid = 600;
        let mut phi = [0.0; MAX_FUNCTIONS];
        for (node, mean) in means.iter().enumerate() {
            let (mut sum, mut count) = (0.0, 0usize);
            for p in crate::solver::quadrature::unit_square_midpoints(grid) {
                if !inside(node, p) || !mask.contains(p) {
                    continue;
                }
                let leaf = *leaves.iter().find(|&&l| inside(l, p)).expect("a leaf");
                basis.eval(h.nodes[leaf].map.local(p), &mut phi);
                sum += (0..n).map(|a| phi[a] * h.u[leaf * n + a][0]).sum::<f64>();
                count += 1;
            }
            let brute = sum / count as f64;
            assert!(
                (mean[0] - brute).abs() < 2e-3 * brute.abs().max(1.0),
                "node {node}: {} vs brute force {brute}",
                mean[0]
            );
            assert!((mean[1] - 2.0 * mean[0]).abs() < 1e-12 && (mean[2] + mean[0]).abs() < 1e-12);
        }
    }
}
