//! The solver's fixed tables at one order: the bases of both shapes ([`Bases`]), their quadrature
//! rules with the zones of influence ([`Rules`]), the receiver's basis at its control and corner
//! probe points ([`BasisAtControlPoints`]), and the corner probe points themselves.
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
}

impl Rules {
    pub(super) fn new(order: usize) -> Self {
        Rules {
            triangle: rule(Shape::Triangle, order + 1),
            cover: CoverRules {
                rule: rule(Shape::Parallelogram, order + 1),
                zones: zones_of_influence(order + 1),
                moment_rule: rule(Shape::Triangle, 3),
                check_points: PARALLELOGRAM_CHECK_POINTS,
            },
            form_factor_radii: kernel::rule_suffices_radii(order),
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
