//! Multi-wavelet bases M1, M2, M3 on the reference shapes, with exact push and pull maps.
//!
//! - Parallelogram: tensor products of orthonormal shifted Legendre polynomials on `[0,1]`
//!   (`1`, `sqrt3 (2s-1)`, `sqrt5 (6s^2-6s+1)`): `order^2` functions.
//! - Triangle: orthonormal polynomials of total degree `< order` (1, 3, 6 functions), built by
//!   Gram-Schmidt on monomials with an exact quadrature.
//!
//! Both are orthonormal for the reference shape's measure normalised to 1, so an element's first
//! coefficient is the mean of its function (scale invariance: coefficients do not depend on area).
//!
//! Subdivision is 4-way: dyadic quarters of the square; for the triangle the three corner triangles
//! and the middle one (orientation preserved). `push` maps parent coefficients to a child's (exact
//! restriction, the parent's polynomial lies in the child's space); `pull` is the L2 projection of
//! the four children back onto the parent (its adjoint, so `pull(push(c)) = c` and power is kept).

use super::quadrature::rule;
use crate::domain::Shape;
use crate::scene::Rgb;
use glam::DVec2;

/// Highest supported order (M3).
pub const MAX_ORDER: usize = 3;
/// Most basis functions of any supported basis (M3 on the square).
pub const MAX_FUNCTIONS: usize = MAX_ORDER * MAX_ORDER;

/// The affine map of child `c` in its parent's reference coordinates: `o + a e1 + b e2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChildMap {
    pub o: DVec2,
    pub e1: DVec2,
    pub e2: DVec2,
}

impl ChildMap {
    pub const IDENTITY: ChildMap = ChildMap {
        o: DVec2::ZERO,
        e1: DVec2::X,
        e2: DVec2::Y,
    };

    pub fn apply(&self, st: DVec2) -> DVec2 {
        self.o + self.e1 * st.x + self.e2 * st.y
    }

    /// `self` followed by the child map `c` (the child's map in the root's coordinates).
    pub fn then(&self, c: &ChildMap) -> ChildMap {
        ChildMap {
            o: self.apply(c.o),
            e1: self.e1 * c.e1.x + self.e2 * c.e1.y,
            e2: self.e1 * c.e2.x + self.e2 * c.e2.y,
        }
    }

    /// Inverse image of a root point in this map's local coordinates.
    pub fn local(&self, st: DVec2) -> DVec2 {
        let d = st - self.o;
        let det = self.e1.perp_dot(self.e2);
        DVec2::new(d.perp_dot(self.e2) / det, self.e1.perp_dot(d) / det)
    }
}

/// The four children of a reference shape.
pub fn child_maps(shape: Shape) -> [ChildMap; 4] {
    let h = 0.5;
    let m = |o: (f64, f64), e1: (f64, f64), e2: (f64, f64)| ChildMap {
        o: DVec2::new(o.0, o.1),
        e1: DVec2::new(e1.0, e1.1),
        e2: DVec2::new(e2.0, e2.1),
    };
    match shape {
        Shape::Parallelogram => [
            m((0.0, 0.0), (h, 0.0), (0.0, h)),
            m((h, 0.0), (h, 0.0), (0.0, h)),
            m((0.0, h), (h, 0.0), (0.0, h)),
            m((h, h), (h, 0.0), (0.0, h)),
        ],
        Shape::Triangle => [
            m((0.0, 0.0), (h, 0.0), (0.0, h)),
            m((h, 0.0), (h, 0.0), (0.0, h)),
            m((0.0, h), (h, 0.0), (0.0, h)),
            m((h, h), (-h, 0.0), (0.0, -h)),
        ],
    }
}

/// An orthonormal polynomial basis of one order on one shape, with its push matrices.
#[derive(Debug, Clone)]
pub struct Basis {
    pub shape: Shape,
    pub order: usize,
    len: usize,
    /// Triangle only: per function, coefficients over the monomials `s^i t^j` of `monomials`.
    triangle_coeffs: Vec<Vec<f64>>,
    monomials: Vec<(i32, i32)>,
    /// `push[c][j * len + i]`: coefficient j of child c from parent coefficient i.
    push: [Vec<f64>; 4],
    /// Per function, a bound on its magnitude over the element ([`Basis::max_abs`]).
    max_abs: [f64; MAX_FUNCTIONS],
}

fn legendre01(k: usize, s: f64) -> f64 {
    match k {
        0 => 1.0,
        1 => 3f64.sqrt() * (2.0 * s - 1.0),
        _ => 5f64.sqrt() * (6.0 * s * s - 6.0 * s + 1.0),
    }
}

impl Basis {
    pub fn new(shape: Shape, order: usize) -> Self {
        assert!((1..=MAX_ORDER).contains(&order), "order must be 1..=3");
        let (len, monomials, triangle_coeffs) = match shape {
            Shape::Parallelogram => (order * order, Vec::new(), Vec::new()),
            Shape::Triangle => {
                let monomials: Vec<(i32, i32)> = (0..order as i32)
                    .flat_map(|d| (0..=d).map(move |j| (d - j, j)))
                    .collect();
                let coeffs = gram_schmidt_triangle(&monomials, order);
                (monomials.len(), monomials, coeffs)
            }
        };
        let mut basis = Basis {
            shape,
            order,
            len,
            triangle_coeffs,
            monomials,
            push: Default::default(),
            max_abs: [0.0; MAX_FUNCTIONS],
        };
        basis.max_abs = basis.magnitude_bounds();
        let q = rule(shape, order + 1);
        let maps = child_maps(shape);
        let mut phi_parent = [0.0; MAX_FUNCTIONS];
        let mut phi_child = [0.0; MAX_FUNCTIONS];
        for (c, map) in maps.iter().enumerate() {
            let mut p = vec![0.0; len * len];
            for qp in &q {
                basis.eval(map.apply(qp.st), &mut phi_parent);
                basis.eval(qp.st, &mut phi_child);
                for j in 0..len {
                    for i in 0..len {
                        p[j * len + i] += qp.weight * phi_parent[i] * phi_child[j];
                    }
                }
            }
            basis.push[c] = p;
        }
        basis
    }

    /// A bound on the magnitude of function `a` over the element: its largest magnitude on a grid
    /// of 101 x 101 points (corners and edges included), plus 2 %, which covers what the grid can
    /// miss of a polynomial of degree 2 per variable at that spacing
    /// (`magnitude_bounds_hold_at_random_points`).
    pub fn max_abs(&self, a: usize) -> f64 {
        self.max_abs[a]
    }

    fn magnitude_bounds(&self) -> [f64; MAX_FUNCTIONS] {
        const STEPS: u32 = 100;
        let mut bound = [0.0f64; MAX_FUNCTIONS];
        let mut phi = [0.0; MAX_FUNCTIONS];
        for i in 0..=STEPS {
            for j in 0..=STEPS {
                if self.shape == Shape::Triangle && i + j > STEPS {
                    continue;
                }
                let st = DVec2::new(f64::from(i), f64::from(j)) / f64::from(STEPS);
                self.eval(st, &mut phi[..self.len]);
                for (b, p) in bound.iter_mut().zip(&phi[..self.len]) {
                    *b = b.max(p.abs());
                }
            }
        }
        bound.map(|b| 1.02 * b)
    }

    /// Number of basis functions.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Evaluates every basis function at reference point `st` into `out[..len]`.
    pub fn eval(&self, st: DVec2, out: &mut [f64]) {
        match self.shape {
            Shape::Parallelogram => {
                for j in 0..self.order {
                    let lt = legendre01(j, st.y);
                    for i in 0..self.order {
                        out[j * self.order + i] = legendre01(i, st.x) * lt;
                    }
                }
            }
            Shape::Triangle => {
                let mut mono = [0.0; MAX_FUNCTIONS];
                for (k, &(i, j)) in self.monomials.iter().enumerate() {
                    mono[k] = st.x.powi(i) * st.y.powi(j);
                }
                for (f, c) in self.triangle_coeffs.iter().enumerate() {
                    out[f] = c.iter().zip(&mono).map(|(a, b)| a * b).sum();
                }
            }
        }
    }

    /// Value at `st` of the function with coefficients `coeffs`.
    pub fn value(&self, coeffs: &[Rgb], st: DVec2) -> Rgb {
        let mut phi = [0.0; MAX_FUNCTIONS];
        self.eval(st, &mut phi);
        let mut v = [0.0; 3];
        for (c, p) in coeffs.iter().zip(&phi[..self.len]) {
            for k in 0..3 {
                v[k] += c[k] * p;
            }
        }
        v
    }

    /// Child `c`'s coefficients of the parent's function.
    pub fn push(&self, c: usize, parent: &[Rgb], child: &mut [Rgb]) {
        let p = &self.push[c];
        for j in 0..self.len {
            let mut acc = [0.0; 3];
            for i in 0..self.len {
                let w = p[j * self.len + i];
                for k in 0..3 {
                    acc[k] += w * parent[i][k];
                }
            }
            child[j] = acc;
        }
    }

    /// Adds the parent projection of child `c`'s function (one quarter of the parent) to `parent`.
    pub fn pull_add(&self, c: usize, child: &[Rgb], parent: &mut [Rgb]) {
        let p = &self.push[c];
        for i in 0..self.len {
            for j in 0..self.len {
                let w = 0.25 * p[j * self.len + i];
                for k in 0..3 {
                    parent[i][k] += w * child[j][k];
                }
            }
        }
    }
}

/// Gram-Schmidt over monomials (graded order) on the normalised reference triangle.
fn gram_schmidt_triangle(monomials: &[(i32, i32)], order: usize) -> Vec<Vec<f64>> {
    let q = rule(Shape::Triangle, order + 1);
    let n = monomials.len();
    let values = |coeffs: &[f64], st: DVec2| -> f64 {
        monomials
            .iter()
            .zip(coeffs)
            .map(|(&(i, j), c)| c * st.x.powi(i) * st.y.powi(j))
            .sum()
    };
    let inner = |a: &[f64], b: &[f64]| -> f64 {
        q.iter()
            .map(|p| p.weight * values(a, p.st) * values(b, p.st))
            .sum()
    };
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for k in 0..n {
        let mut v = vec![0.0; n];
        v[k] = 1.0;
        for b in &basis {
            let d = inner(&v, b);
            for (x, y) in v.iter_mut().zip(b) {
                *x -= d * y;
            }
        }
        let norm = inner(&v, &v).sqrt();
        for x in &mut v {
            *x /= norm;
        }
        basis.push(v);
    }
    basis
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `max_abs` against 200 000 random points of each shape and order: never exceeded, and
    /// approached within 5 % (the bound is not loose).
    #[test]
    fn magnitude_bounds_hold_at_random_points() {
        let mut rnd = crate::shuffle::uniform_sequence(4242);
        let mut phi = [0.0; MAX_FUNCTIONS];
        for (shape, order) in shapes_and_orders() {
            let basis = Basis::new(shape, order);
            let mut seen = [0.0f64; MAX_FUNCTIONS];
            for _ in 0..200_000 {
                let mut st = DVec2::new(rnd(), rnd());
                if shape == Shape::Triangle && st.x + st.y > 1.0 {
                    st = DVec2::ONE - st;
                }
                basis.eval(st, &mut phi[..basis.len()]);
                for a in 0..basis.len() {
                    seen[a] = seen[a].max(phi[a].abs());
                    assert!(
                        phi[a].abs() <= basis.max_abs(a),
                        "{shape:?} M{order} f{a} at {st}"
                    );
                }
            }
            for a in 0..basis.len() {
                assert!(
                    seen[a] >= basis.max_abs(a) / 1.05,
                    "{shape:?} M{order} f{a}: {} of {}",
                    seen[a],
                    basis.max_abs(a)
                );
            }
        }
    }

    fn shapes_and_orders() -> impl Iterator<Item = (Shape, usize)> {
        [Shape::Parallelogram, Shape::Triangle]
            .into_iter()
            .flat_map(|s| (1..=MAX_ORDER).map(move |o| (s, o)))
    }

    #[test]
    fn gram_matrices_are_identity() {
        for (shape, order) in shapes_and_orders() {
            let b = Basis::new(shape, order);
            let q = rule(shape, order + 2);
            let mut phi = [0.0; MAX_FUNCTIONS];
            let n = b.len();
            let mut g = vec![0.0; n * n];
            for p in &q {
                b.eval(p.st, &mut phi);
                for i in 0..n {
                    for j in 0..n {
                        g[i * n + j] += p.weight * phi[i] * phi[j];
                    }
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!(
                        (g[i * n + j] - e).abs() < 1e-12,
                        "{shape:?} M{order} G[{i}][{j}] = {}",
                        g[i * n + j]
                    );
                }
            }
            assert_eq!(
                n,
                match shape {
                    Shape::Parallelogram => order * order,
                    Shape::Triangle => order * (order + 1) / 2,
                }
            );
        }
    }

    #[test]
    fn pull_after_push_is_identity_and_polynomials_survive_push() {
        for (shape, order) in shapes_and_orders() {
            let b = Basis::new(shape, order);
            let n = b.len();
            let parent: Vec<Rgb> = (0..n)
                .map(|i| [1.0 + i as f64, -0.5 * i as f64, 0.25])
                .collect();
            let mut back = vec![[0.0; 3]; n];
            let maps = child_maps(shape);
            for (c, map) in maps.iter().enumerate() {
                let mut child = vec![[0.0; 3]; n];
                b.push(c, &parent, &mut child);
                // The child's function equals the parent's on the child (exact restriction).
                for st in [
                    DVec2::new(0.2, 0.3),
                    DVec2::new(0.1, 0.1),
                    DVec2::new(0.6, 0.2),
                ] {
                    let vc = b.value(&child, st);
                    let vp = b.value(&parent, map.apply(st));
                    for k in 0..3 {
                        assert!(
                            (vc[k] - vp[k]).abs() < 1e-12,
                            "{shape:?} M{order} child {c}"
                        );
                    }
                }
                b.pull_add(c, &child, &mut back);
            }
            for i in 0..n {
                for k in 0..3 {
                    assert!(
                        (back[i][k] - parent[i][k]).abs() < 1e-12,
                        "{shape:?} M{order} coefficient {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn push_pull_conserves_power() {
        // Power (mean times area) of four independent children equals the pulled parent's.
        for (shape, order) in shapes_and_orders() {
            let b = Basis::new(shape, order);
            let n = b.len();
            let mut parent = vec![[0.0; 3]; n];
            let mut child_mean_sum = 0.0;
            for c in 0..4 {
                let child: Vec<Rgb> = (0..n)
                    .map(|i| [(c * 7 + i) as f64 * 0.3 + 1.0, 0.0, 0.0])
                    .collect();
                child_mean_sum += child[0][0];
                b.pull_add(c, &child, &mut parent);
            }
            assert!(
                (parent[0][0] - 0.25 * child_mean_sum).abs() < 1e-12,
                "{shape:?} M{order}"
            );
        }
    }
}
