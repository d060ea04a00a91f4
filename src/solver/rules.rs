//! The solver's fixed tables at one order: the bases of both shapes ([`Bases`]), their quadrature
//! rules with the zones of influence ([`Rules`]), the receiver's basis at its control and corner
//! probe points ([`BasisAtControlPoints`]), the corner probe points themselves, and which of
//! them are rule points' twins ([`CheckTwins`]).
//!
//! Invariant: `BasisAtControlPoints::of(shape)` holds one row per rule point of `Rules::of(shape)`,
//! then one per [`corner_probe_points`]`(shape)`, in that order (the oracle indexes it so).

use super::basis::{Basis, MAX_FUNCTIONS};
use super::cover::{CoverRules, CHECK_POINTS};
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
    /// Per shape, for each of its [`corner_probe_points`], the rule point at the same place
    /// ([`check_twins`]).
    triangle_twins: CheckTwins,
    parallelogram_twins: CheckTwins,
}

/// For each check point of a shape, the index of the rule point at the same place (within
/// [`TWIN_EPS`] in reference coordinates), if any: a parallelogram's centre at M2. A receiver
/// on a native root takes that point's answer there instead of asking the source again
/// (`transfer::tests::a_check_point_on_a_rule_point_takes_its_irradiance`); an extended root's
/// node finds it among the points that stand in alike (`NodeCover::alike`).
pub(super) type CheckTwins = [Option<usize>; CHECK_POINTS];

/// How close, in reference coordinates, a check point must lie to a rule point to be its twin
/// (the same point but for rounding; `twins_are_the_centre_at_m2_only`).
pub(super) const TWIN_EPS: f64 = 1e-12;

/// The [`CheckTwins`] of `rule` and the check points `probes`.
fn check_twins(rule: &[QuadPoint], probes: &[DVec2]) -> CheckTwins {
    debug_assert!(probes.len() <= CHECK_POINTS);
    std::array::from_fn(|j| {
        let p = probes.get(j)?;
        rule.iter()
            .position(|q| (q.st - *p).abs().max_element() <= TWIN_EPS)
    })
}

impl Rules {
    pub(super) fn new(order: usize) -> Self {
        let triangle = rule(Shape::Triangle, order + 1);
        let parallelogram = rule(Shape::Parallelogram, order + 1);
        Rules {
            triangle_twins: check_twins(&triangle, corner_probe_points(Shape::Triangle)),
            parallelogram_twins: check_twins(
                &parallelogram,
                corner_probe_points(Shape::Parallelogram),
            ),
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
    /// The check points of `shape` that are rule points ([`CheckTwins`]).
    pub(super) fn twins(&self, shape: Shape) -> &CheckTwins {
        match shape {
            Shape::Triangle => &self.triangle_twins,
            Shape::Parallelogram => &self.parallelogram_twins,
        }
    }
    pub(super) fn of(&self, shape: Shape) -> &[QuadPoint] {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.cover.rule,
        }
    }
}

/// Each shape's basis functions at its rule's points (the receiver's control points), then at its
/// corner probe points.
pub(super) struct BasisAtControlPoints {
    triangle: Vec<[f64; MAX_FUNCTIONS]>,
    parallelogram: Vec<[f64; MAX_FUNCTIONS]>,
}

impl BasisAtControlPoints {
    pub(super) fn new(bases: &Bases, rules: &Rules) -> Self {
        let at = |shape: Shape| {
            rules
                .of(shape)
                .iter()
                .map(|q| q.st)
                .chain(corner_probe_points(shape).iter().copied())
                .map(|st| {
                    let mut phi = [0.0; MAX_FUNCTIONS];
                    bases.of(shape).eval(st, &mut phi);
                    phi
                })
                .collect()
        };
        BasisAtControlPoints {
            triangle: at(Shape::Triangle),
            parallelogram: at(Shape::Parallelogram),
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

    /// A check point is a rule point's twin only at a parallelogram's centre at M2 (the middle
    /// of the 3 x 3 Gauss rule); no triangle's, and no other order's.
    #[test]
    fn twins_are_the_centre_at_m2_only() {
        for order in 1..=3 {
            let r = Rules::new(order);
            assert_eq!(r.twins(Shape::Triangle), &[None; CHECK_POINTS], "M{order}");
            let twins = r.twins(Shape::Parallelogram);
            for (j, twin) in twins.iter().enumerate() {
                let centre = PARALLELOGRAM_CHECK_POINTS[j] == DVec2::splat(0.5);
                match twin {
                    Some(i) => {
                        assert!(order == 2 && centre, "M{order} check point {j}");
                        assert_eq!(r.cover.rule[*i].st, DVec2::splat(0.5));
                    }
                    None => assert!(order != 2 || !centre, "M{order} check point {j}"),
                }
            }
        }
    }
}
