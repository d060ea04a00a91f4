//! The part of an element in front of a receiver point's tangent plane, as a quadrature domain:
//! [`FrontMap`] carries a point of the element's rule onto the part where an affine height is
//! positive, with the ratio of the map's Jacobian to the rule's own, so the element's rule
//! becomes a rule of that part (`ElementSource::front_rule`).
//!
//! Both reference shapes are a unit square `(a, b)` seen through a map: the identity for a
//! parallelogram, the collapse `(s, t) = (a, b (1 - a))` for a triangle (`quadrature::rule`
//! builds its triangle rule so). Along `b` the height is affine for both, so the front part is,
//! for each `a` in a range, one interval of `b`: the map takes `a` to that range and `b` to that
//! interval.
//!
//! Invariant: every mapped point lies in the part (height at least 0) and inside the shape. The
//! weights integrate the part exactly where the map is smooth (a parallelogram cut through two
//! opposite sides or a corner off, a triangle cut parallel to its collapsed side), and within a
//! few percent on average elsewhere, where the map's Jacobian has a kink (`tests`): the points
//! are visibility samples, and the exact form factor scales what they see.

use crate::domain::Shape;
use glam::DVec2;

/// The map of a reference shape onto its part where `h(s, t) = h0 + hs s + ht t > 0`.
#[derive(Debug, Clone, Copy)]
pub(super) struct FrontMap {
    triangle: bool,
    /// A parallelogram's `b` is its `s` (else `t`): the inner coordinate is the one `h` varies
    /// most along.
    swapped: bool,
    /// `h` over the square: `p0 + p1 a` plus `b` times `q0 + q1 a`.
    p: (f64, f64),
    q: (f64, f64),
    /// The range of `a` where the front part is not empty.
    outer: (f64, f64),
}

impl FrontMap {
    /// `None` when the front part is empty or `h` does not vary.
    pub(super) fn new(shape: Shape, h0: f64, hs: f64, ht: f64) -> Option<FrontMap> {
        let (triangle, swapped, p, q) = match shape {
            // (s, t) = (a, b (1 - a)): h = h0 + hs a + b ht (1 - a).
            Shape::Triangle => (true, false, (h0, hs), (ht, -ht)),
            Shape::Parallelogram if hs.abs() > ht.abs() => (false, true, (h0, ht), (hs, 0.0)),
            Shape::Parallelogram => (false, false, (h0, hs), (ht, 0.0)),
        };
        if q == (0.0, 0.0) && p.1 == 0.0 {
            return None;
        }
        // The largest h over b at a: p(a) + max(q(a), 0), linear in a since q keeps its sign on
        // [0, 1) (a triangle's q vanishes only at a = 1).
        let (l0, l1) = if q.0 > 0.0 { (p.0 + q.0, p.1 + q.1) } else { p };
        let outer = if l1 > 0.0 {
            ((-l0 / l1).clamp(0.0, 1.0), 1.0)
        } else if l1 < 0.0 {
            (0.0, (-l0 / l1).clamp(0.0, 1.0))
        } else if l0 > 0.0 {
            (0.0, 1.0)
        } else {
            return None;
        };
        (outer.1 > outer.0).then_some(FrontMap {
            triangle,
            swapped,
            p,
            q,
            outer,
        })
    }

    /// The front part's point for the rule's point `st` of the whole shape, and the factor its
    /// weight takes (the map's Jacobian over the rule's own at `st`).
    pub(super) fn apply(&self, st: DVec2) -> (DVec2, f64) {
        let (a, b) = self.square_of(st);
        let (a0, a1) = self.outer;
        let a_front = a0 + a * (a1 - a0);
        // Where h crosses 0 along b at a_front: p + b q = 0.
        let (p, q) = (self.p.0 + self.p.1 * a_front, self.q.0 + self.q.1 * a_front);
        let (b0, b1) = if q > 0.0 {
            ((-p / q).clamp(0.0, 1.0), 1.0)
        } else if q < 0.0 {
            (0.0, (-p / q).clamp(0.0, 1.0))
        } else {
            (0.0, 1.0)
        };
        let b_front = b0 + b * (b1 - b0);
        let mut factor = (a1 - a0) * (b1 - b0);
        if self.triangle {
            // The collapse's own Jacobian, 1 - a, at the two points.
            factor *= (1.0 - a_front) / (1.0 - a);
        }
        (self.shape_point(a_front, b_front), factor)
    }

    fn square_of(&self, st: DVec2) -> (f64, f64) {
        if self.triangle {
            // The rule's points are interior: s < 1.
            (st.x, st.y / (1.0 - st.x))
        } else if self.swapped {
            (st.y, st.x)
        } else {
            (st.x, st.y)
        }
    }

    fn shape_point(&self, a: f64, b: f64) -> DVec2 {
        if self.triangle {
            DVec2::new(a, b * (1.0 - a))
        } else if self.swapped {
            DVec2::new(b, a)
        } else {
            DVec2::new(a, b)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::quadrature;

    /// The front part of `shape` where `h > 0`, on a fine midpoint grid of the unit square: its
    /// share of the shape's area, and of the integral of `s t`.
    fn grid_front(shape: Shape, h: impl Fn(DVec2) -> f64) -> (f64, f64) {
        let grid = 400;
        let cell = 1.0 / (grid * grid) as f64;
        let area = match shape {
            Shape::Parallelogram => 1.0,
            Shape::Triangle => 0.5,
        };
        let (mut share, mut moment) = (0.0, 0.0);
        for st in quadrature::unit_square_midpoints(grid) {
            let inside = shape == Shape::Parallelogram || st.x + st.y < 1.0;
            if inside && h(st) > 0.0 {
                share += cell / area;
                moment += st.x * st.y * cell / area;
            }
        }
        (share, moment)
    }

    /// The mapped rule of `shape` for `h`: its weights' sum and its integral of `s t`, every
    /// point checked to lie in the front part and in the shape.
    fn mapped(shape: Shape, map: &FrontMap, h: impl Fn(DVec2) -> f64) -> (f64, f64) {
        let (mut share, mut moment) = (0.0, 0.0);
        for q in &quadrature::rule(shape, 3) {
            let (st, factor) = map.apply(q.st);
            assert!(h(st) >= -1e-12, "a point behind the plane: h = {}", h(st));
            assert!(st.x >= 0.0 && st.y >= 0.0, "{st}");
            match shape {
                Shape::Parallelogram => assert!(st.x <= 1.0 && st.y <= 1.0, "{st}"),
                Shape::Triangle => assert!(st.x + st.y <= 1.0 + 1e-12, "{st}"),
            }
            share += q.weight * factor;
            moment += q.weight * factor * st.x * st.y;
        }
        (share, moment)
    }

    /// The front rule's points all lie in the front part and its weights integrate it: for
    /// random planes cutting a parallelogram or a triangle, the weights sum to the front part's
    /// share of the shape and integrate `s t` over it as a fine midpoint grid does. Where the
    /// map's Jacobian has a kink (the cut leaves through adjacent sides) the rule is not exact:
    /// on average within 1.5 % of the shape, at worst within 10 % (a small corner behind the
    /// plane that every point's column misses), plus the grid's own error.
    #[test]
    fn the_front_rule_integrates_the_front_part() {
        let mut rnd = crate::shuffle::uniform_sequence(41);
        for shape in [Shape::Parallelogram, Shape::Triangle] {
            let (mut cut, mut errors) = (0, Vec::new());
            for _ in 0..300 {
                let (h0, hs, ht) = (rnd() * 2.0 - 1.0, rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
                let h = |st: DVec2| h0 + hs * st.x + ht * st.y;
                let (share, moment) = grid_front(shape, h);
                let Some(map) = FrontMap::new(shape, h0, hs, ht) else {
                    assert!(
                        share < 1e-3,
                        "{shape:?}: no map for a front part of {share}"
                    );
                    continue;
                };
                if share < 1.0 {
                    cut += 1;
                }
                let (w, m) = mapped(shape, &map, h);
                let grid_err = 0.01;
                assert!(
                    (w - share).abs() < 0.1 + grid_err,
                    "{shape:?}: share {w} against {share}"
                );
                assert!(
                    (m - moment).abs() < 0.1 + grid_err,
                    "{shape:?}: moment {m} against {moment}"
                );
                errors.push((w - share).abs());
            }
            assert!(cut > 100, "{shape:?}: only {cut} planes cut the shape");
            let mean = errors.iter().sum::<f64>() / errors.len() as f64;
            assert!(mean < 0.015, "{shape:?}: mean error {mean}");
        }
        // A cut through two opposite sides of a parallelogram: the map is smooth and the rule
        // exact on `s t`. Front: s > 0.3 + 0.2 t; area 0.6, and the integral of s t over it
        // (1 - (0.3 + 0.2 t)^2) t / 2 integrated over t.
        let map = FrontMap::new(Shape::Parallelogram, -0.3, 1.0, -0.2).expect("a front part");
        let (w, m) = mapped(Shape::Parallelogram, &map, |st| st.x - 0.3 - 0.2 * st.y);
        let moment = 0.5 * (0.5 - (0.09 / 2.0 + 0.12 / 3.0 + 0.04 / 4.0));
        assert!((w - 0.6).abs() < 1e-12, "{w}");
        assert!((m - moment).abs() < 1e-12, "{m} against {moment}");
        // A triangle cut parallel to its collapsed side (s > 0.5): the map is smooth, the share
        // is (1 - 0.5)^2 = 0.25 exactly.
        let map = FrontMap::new(Shape::Triangle, -0.5, 1.0, 0.0).expect("a front part");
        let (w, _) = mapped(Shape::Triangle, &map, |st| st.x - 0.5);
        assert!((w - 0.25).abs() < 1e-12, "{w}");
    }
}
