//! The solver's fixed tables at one order: the bases of both shapes ([`Bases`]), their quadrature
//! rules with the zones of influence ([`Rules`]), the receiver's basis at its control and corner
//! probe points ([`BasisAtControlPoints`]), the corner probe points themselves, and which of
//! a shape's points lie where an earlier one does ([`Rules::alike`]).
//!
//! Invariant: `BasisAtControlPoints::of(shape)` holds one row per rule point of `Rules::of(shape)`,
//! then one per [`corner_probe_points`]`(shape)`, in that order (the oracle indexes it so).

use super::basis::{Basis, MAX_FUNCTIONS};
use super::cover::{alike_points, CoverRules, CHECK_POINTS, MAX_POINTS};
use super::kernel;
use super::quadrature::{rule, zones_of_influence, QuadPoint};
use crate::domain::Shape;
use glam::DVec2;

#[derive(Debug, Clone)]
pub(super) struct Bases {
    triangle: Basis,
    parallelogram: Basis,
}

impl Bases {
    pub(super) fn new(order: usize) -> Self {
        Bases {
            triangle: Basis::new(Shape::Triangle, order),
            parallelogram: Basis::new(Shape::Parallelogram, order),
        }
    }
    pub(super) fn of(&self, shape: Shape) -> &Basis {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.parallelogram,
        }
    }
}

/// Quadrature rules per shape at the solver's order.
pub(super) struct Rules {
    pub(super) triangle: Vec<QuadPoint>,
    /// The parallelogram rule (`cover.rule`) with its zones of influence.
    pub(super) cover: CoverRules,
    /// Beyond how many radii of a source element its rule gives the form factor
    /// ([`kernel::rule_suffices_radii`]).
    pub(super) form_factor_radii: f64,
    /// Per shape, [`Rules::alike`].
    triangle_alike: [u8; MAX_POINTS],
    parallelogram_alike: [u8; MAX_POINTS],
}

/// [`Rules::alike`] of `shape` with the rule `rule`.
fn alike_in_reference(rule: &[QuadPoint], shape: Shape) -> [u8; MAX_POINTS] {
    let st: Vec<DVec2> = rule.iter().map(|q| q.st).collect();
    alike_points(&st, corner_probe_points(shape))
}

impl Rules {
    pub(super) fn new(order: usize) -> Self {
        let triangle = rule(Shape::Triangle, order + 1);
        let parallelogram = rule(Shape::Parallelogram, order + 1);
        Rules {
            triangle_alike: alike_in_reference(&triangle, Shape::Triangle),
            parallelogram_alike: alike_in_reference(&parallelogram, Shape::Parallelogram),
            triangle,
            cover: CoverRules {
                rule: parallelogram,
                zones: zones_of_influence(order + 1),
                moment_rule: rule(Shape::Triangle, 3),
                check_points: PARALLELOGRAM_CHECK_POINTS,
            },
            form_factor_radii: kernel::rule_suffices_radii(order),
        }
    }
    /// For each of `shape`'s points (its rule's, then its [`corner_probe_points`]), the first
    /// point at the same place in reference coordinates, itself if none: a parallelogram's
    /// centre at M2, which is a rule point and a check point. A receiver on a native root takes
    /// that point's answer instead of asking the source again
    /// (`transfer::tests::a_check_point_on_a_rule_point_takes_its_irradiance`); an extended
    /// root's node takes its own stand-ins' (`NodeCover::alike`), computed alike.
    pub(super) fn alike(&self, shape: Shape) -> &[u8; MAX_POINTS] {
        match shape {
            Shape::Triangle => &self.triangle_alike,
            Shape::Parallelogram => &self.parallelogram_alike,
        }
    }
    pub(super) fn of(&self, shape: Shape) -> &[QuadPoint] {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.cover.rule,
        }
    }
}

/// A shape's control points: its rule's points, then its corner probe points.
fn control_points(rules: &Rules, shape: Shape) -> impl Iterator<Item = DVec2> + '_ {
    rules
        .of(shape)
        .iter()
        .map(|q| q.st)
        .chain(corner_probe_points(shape).iter().copied())
}

/// Each shape's basis functions at its rule's points (the receiver's control points), then at its
/// corner probe points.
pub(super) struct BasisAtControlPoints {
    triangle: Vec<[f64; MAX_FUNCTIONS]>,
    parallelogram: Vec<[f64; MAX_FUNCTIONS]>,
    triangle_children: Vec<u8>,
    parallelogram_children: Vec<u8>,
}

impl BasisAtControlPoints {
    pub(super) fn new(bases: &Bases, rules: &Rules) -> Self {
        let at = |shape: Shape| {
            control_points(rules, shape)
                .map(|st| {
                    let mut phi = [0.0; MAX_FUNCTIONS];
                    bases.of(shape).eval(st, &mut phi);
                    phi
                })
                .collect()
        };
        let kids = |shape: Shape| -> Vec<u8> {
            let maps = super::basis::child_maps(shape);
            control_points(rules, shape)
                .map(|st| {
                    let mut m = 0u8;
                    for (c, map) in maps.iter().enumerate() {
                        let l = map.local(st);
                        let e = 1e-9;
                        let inside = match shape {
                            Shape::Parallelogram => {
                                l.x >= -e && l.y >= -e && l.x <= 1.0 + e && l.y <= 1.0 + e
                            }
                            Shape::Triangle => l.x >= -e && l.y >= -e && l.x + l.y <= 1.0 + e,
                        };
                        if inside {
                            m |= 1 << c;
                        }
                    }
                    debug_assert!(m != 0);
                    m
                })
                .collect()
        };
        BasisAtControlPoints {
            triangle: at(Shape::Triangle),
            parallelogram: at(Shape::Parallelogram),
            triangle_children: kids(Shape::Triangle),
            parallelogram_children: kids(Shape::Parallelogram),
        }
    }
    pub(super) fn children_of(&self, shape: Shape) -> &[u8] {
        match shape {
            Shape::Triangle => &self.triangle_children,
            Shape::Parallelogram => &self.parallelogram_children,
        }
    }
    pub(super) fn of(&self, shape: Shape) -> &[[f64; MAX_FUNCTIONS]] {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.parallelogram,
        }
    }
}

/// A parallelogram's [`corner_probe_points`].
pub(super) const PARALLELOGRAM_CHECK_POINTS: [DVec2; CHECK_POINTS] = {
    const E: f64 = CORNER_INSET;
    [
        DVec2::new(E, E),
        DVec2::new(1.0 - E, E),
        DVec2::new(1.0 - E, 1.0 - E),
        DVec2::new(E, 1.0 - E),
        DVec2::new(0.5, 0.5),
    ]
};

/// Points near the corners of a reference shape, inset by [`CORNER_INSET`], and its centroid.
pub(super) fn corner_probe_points(shape: Shape) -> &'static [DVec2] {
    const E: f64 = CORNER_INSET;
    const TRIANGLE: [DVec2; 4] = [
        DVec2::new(E, E),
        DVec2::new(1.0 - 2.0 * E, E),
        DVec2::new(E, 1.0 - 2.0 * E),
        DVec2::new(1.0 / 3.0, 1.0 / 3.0),
    ];
    match shape {
        Shape::Parallelogram => &PARALLELOGRAM_CHECK_POINTS,
        Shape::Triangle => &TRIANGLE,
    }
}

/// How far inside an element its corner probe points, and the spread rays' points, sit, in
/// reference coordinates: off the element's border, where rays would graze the surfaces it meets.
pub(super) const CORNER_INSET: f64 = 0.02;

#[cfg(test)]
mod tests {
    use super::*;

    /// Each control point counts for the children whose closed region holds it, checked against
    /// a brute-force twin (the point against the child's region, by a box or half-plane test in
    /// the parent's coordinates): every point in at least one child.
    #[test]
    fn control_points_know_the_children_they_lie_in() {
        let inside = |shape: Shape, c: usize, st: DVec2| -> bool {
            let e = 1e-9;
            let (x, y) = (st.x, st.y);
            match (shape, c) {
                (Shape::Parallelogram, c) => {
                    let (x0, y0) = ((c % 2) as f64 * 0.5, (c / 2) as f64 * 0.5);
                    x >= x0 - e && x <= x0 + 0.5 + e && y >= y0 - e && y <= y0 + 0.5 + e
                }
                (Shape::Triangle, 0) => x >= -e && y >= -e && x + y <= 0.5 + e,
                (Shape::Triangle, 1) => x >= 0.5 - e && y >= -e && x + y <= 1.0 + e,
                (Shape::Triangle, 2) => x >= -e && y >= 0.5 - e && x + y <= 1.0 + e,
                (Shape::Triangle, _) => x <= 0.5 + e && y <= 0.5 + e && x + y >= 0.5 - e,
            }
        };
        for order in 1..=3 {
            let rules = Rules::new(order);
            let bases = Bases::new(order);
            let at = BasisAtControlPoints::new(&bases, &rules);
            for shape in [Shape::Triangle, Shape::Parallelogram] {
                let points: Vec<DVec2> = control_points(&rules, shape).collect();
                let kids = at.children_of(shape);
                assert_eq!(kids.len(), points.len());
                for (st, &m) in points.iter().zip(kids) {
                    assert_ne!(m, 0, "M{order} {shape:?} {st}");
                    for c in 0..4 {
                        assert_eq!(
                            m & (1 << c) != 0,
                            inside(shape, c, *st),
                            "{shape:?} {st} {c}"
                        );
                    }
                }
            }
        }
    }

    /// Per child, the deviation is the largest over the points the child holds, so the largest
    /// over the children is the node's own (`oracle::max_deviation`), each point counting.
    #[test]
    fn the_children_deviations_cover_the_nodes() {
        use super::super::oracle::{child_deviation, max_deviation, weighted_deviation};
        let rules = Rules::new(2);
        let bases = Bases::new(2);
        let at = BasisAtControlPoints::new(&bases, &rules);
        for shape in [Shape::Triangle, Shape::Parallelogram] {
            let psi = at.of(shape);
            let nr = bases.of(shape).len();
            let e: Vec<[f64; 3]> = (0..psi.len())
                .map(|k| [k as f64 * 0.37 % 1.0, (k * k) as f64 * 0.11 % 1.0, 0.5])
                .collect();
            let mut dh = [[0.0; 3]; MAX_FUNCTIONS];
            dh[0] = [0.4, 0.3, 0.5];
            let weight = [0.5, 0.7, 0.9];
            let per_child = child_deviation(psi, at.children_of(shape), &e, &dh, nr, weight);
            let whole = max_deviation(psi, &e, &dh, nr, weight);
            assert_eq!(per_child.iter().copied().fold(0.0, f64::max), whole);
            // Each child's is the largest over exactly the points it holds.
            let kids = at.children_of(shape);
            for (c, &got) in per_child.iter().enumerate() {
                let own = psi
                    .iter()
                    .zip(kids)
                    .enumerate()
                    .filter(|(_, (_, m))| *m & (1 << c) != 0)
                    .map(|(k, (phi, _))| weighted_deviation(e[k], &dh, phi, nr, weight))
                    .fold(0.0, f64::max);
                assert_eq!(got, own, "{shape:?} child {c}");
            }
        }
    }

    /// A point lies where an earlier one does only at a parallelogram's centre at M2 (the
    /// middle of the 3 x 3 Gauss rule, and a check point): no triangle's, no other order's.
    #[test]
    fn points_alike_are_the_centre_at_m2_only() {
        for order in 1..=3 {
            let r = Rules::new(order);
            let own: [u8; MAX_POINTS] = std::array::from_fn(|k| k as u8);
            assert_eq!(r.alike(Shape::Triangle), &own, "M{order}");
            let n = r.cover.rule.len();
            let alike = r.alike(Shape::Parallelogram);
            for (k, &a) in alike.iter().enumerate() {
                let centre_check = k >= n
                    && k < n + CHECK_POINTS
                    && PARALLELOGRAM_CHECK_POINTS[k - n] == DVec2::splat(0.5);
                if usize::from(a) == k {
                    assert!(order != 2 || !centre_check, "M{order} point {k}");
                } else {
                    assert!(order == 2 && centre_check, "M{order} point {k}");
                    assert_eq!(r.cover.rule[usize::from(a)].st, DVec2::splat(0.5));
                }
            }
        }
    }
}
