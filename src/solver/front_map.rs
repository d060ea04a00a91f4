//! The part of an element in front of a receiver point's tangent plane, as a quadrature domain:
//! [`FrontMap`] maps the unit square onto its part where an affine height is positive, with the
//! map's Jacobian, so any rule of the square becomes a rule of that part
//! (`ElementSource::front_rule`).
//!
//! Invariant: every mapped point lies in the part (height at least 0) and inside the square;
//! the weights times the Jacobian integrate the part exactly where the plane cuts two opposite
//! sides, and within a few percent where it cuts a corner off (`tests`).

use glam::DVec2;

/// The map of the unit square onto its part where `h(s, t) = h0 + hs s + ht t > 0`.
#[derive(Debug, Clone, Copy)]
pub(super) struct FrontMap {
    h0: f64,
    /// `h`'s slope along the inner coordinate (the larger in magnitude) and the outer one.
    inner: f64,
    outer: f64,
    /// Whether the inner coordinate is `t` (else `s`).
    inner_is_t: bool,
    /// The outer coordinate's range where the front part is not empty.
    outer_range: (f64, f64),
}

impl FrontMap {
    /// `None` when the front part is empty or `h` does not vary.
    pub(super) fn new(h0: f64, hs: f64, ht: f64) -> Option<FrontMap> {
        let inner_is_t = ht.abs() > hs.abs();
        let (inner, outer) = if inner_is_t { (ht, hs) } else { (hs, ht) };
        if inner == 0.0 {
            return None;
        }
        // The largest h over the inner coordinate at outer value b: h0 + max(inner, 0) + outer b.
        let top = h0 + inner.max(0.0);
        let outer_range = if outer > 0.0 {
            ((-top / outer).clamp(0.0, 1.0), 1.0)
        } else if outer < 0.0 {
            (0.0, (-top / outer).clamp(0.0, 1.0))
        } else if top > 0.0 {
            (0.0, 1.0)
        } else {
            return None;
        };
        (outer_range.1 > outer_range.0).then_some(FrontMap {
            h0,
            inner,
            outer,
            inner_is_t,
            outer_range,
        })
    }

    /// The front part's point for the unit square's `st`, and the map's Jacobian there.
    pub(super) fn apply(&self, st: DVec2) -> (DVec2, f64) {
        let (a, b) = if self.inner_is_t {
            (st.y, st.x)
        } else {
            (st.x, st.y)
        };
        let (b0, b1) = self.outer_range;
        let b = b0 + b * (b1 - b0);
        // Where h crosses 0 along the inner coordinate at this outer value.
        let zero = (-(self.h0 + self.outer * b) / self.inner).clamp(0.0, 1.0);
        let (a0, a1) = if self.inner > 0.0 {
            (zero, 1.0)
        } else {
            (0.0, zero)
        };
        let a = a0 + a * (a1 - a0);
        let jacobian = (b1 - b0) * (a1 - a0);
        let st = if self.inner_is_t {
            DVec2::new(b, a)
        } else {
            DVec2::new(a, b)
        };
        (st, jacobian)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Shape;
    use crate::solver::quadrature;

    /// The front rule's points all lie in the front part and its weights integrate it: for
    /// random planes cutting the unit square, the weights sum to the front part's area and
    /// integrate `s t` over it as a fine midpoint grid does (both over the same part).
    #[test]
    fn the_front_rule_integrates_the_front_part() {
        let rule = quadrature::rule(Shape::Parallelogram, 3);
        let mut rnd = crate::shuffle::uniform_sequence(41);
        let mut cut = 0;
        for _ in 0..500 {
            let (h0, hs, ht) = (rnd() * 2.0 - 1.0, rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            let h = |st: DVec2| h0 + hs * st.x + ht * st.y;
            let grid = 400;
            let (mut area, mut moment) = (0.0, 0.0);
            for i in 0..grid {
                for j in 0..grid {
                    let st = DVec2::new(
                        (i as f64 + 0.5) / grid as f64,
                        (j as f64 + 0.5) / grid as f64,
                    );
                    if h(st) > 0.0 {
                        area += 1.0 / (grid * grid) as f64;
                        moment += st.x * st.y / (grid * grid) as f64;
                    }
                }
            }
            let Some(map) = FrontMap::new(h0, hs, ht) else {
                assert!(area < 1e-3, "no map for a front part of area {area}");
                continue;
            };
            if area < 1.0 {
                cut += 1;
            }
            let (mut w_sum, mut m_sum) = (0.0, 0.0);
            for q in &rule {
                let (st, jacobian) = map.apply(q.st);
                assert!(h(st) >= -1e-12, "a point behind the plane: h = {}", h(st));
                assert!((0.0..=1.0).contains(&st.x) && (0.0..=1.0).contains(&st.y));
                w_sum += q.weight * jacobian;
                m_sum += q.weight * jacobian * st.x * st.y;
            }
            // The grid's own error along the cut (a strip of cells one cell wide), and the rule's
            // where the cut leaves through adjacent sides (the map's Jacobian has a kink there).
            let tol = 3.0 / grid as f64 + 0.05 * area;
            assert!((w_sum - area).abs() < tol, "area {w_sum} against {area}");
            assert!(
                (m_sum - moment).abs() < tol,
                "moment {m_sum} against {moment}"
            );
        }
        assert!(cut > 200, "only {cut} planes cut the square");
        // A cut through two opposite sides: the map is smooth and the rule exact on `s t`.
        let map = FrontMap::new(-0.3, 1.0, -0.2).expect("a front part");
        let (mut w_sum, mut m_sum) = (0.0, 0.0);
        for q in &rule {
            let (st, jacobian) = map.apply(q.st);
            w_sum += q.weight * jacobian;
            m_sum += q.weight * jacobian * st.x * st.y;
        }
        // Front: s > 0.3 + 0.2 t; area 0.6, and the integral of s t over it
        // (1 - (0.3 + 0.2 t)^2) t / 2 integrated over t.
        let moment = 0.5 * (0.5 - (0.09 / 2.0 + 0.12 / 3.0 + 0.04 / 4.0));
        assert!((w_sum - 0.6).abs() < 1e-12, "{w_sum}");
        assert!((m_sum - moment).abs() < 1e-12, "{m_sum} against {moment}");
    }
}
