//! Quadrature rules on the reference shapes, weights normalised to sum to 1.
//!
//! - Gauss-Legendre on `[0,1]` with `n` points: exact for polynomials of degree `2n - 1`.
//! - Square `[0,1]^2`: tensor product, exact to degree `2n - 1` per axis.
//! - Triangle `s,t >= 0, s+t <= 1`: the collapsed (Duffy) product `s = a, t = b (1 - a)` with
//!   weight `w_a w_b (1 - a)` (times 2 to normalise), exact for total degree `<= 2n - 2`.
//!
//! Nodes are computed by Newton's method on the Legendre recurrence (no tables to mistype).
//!
//! Also the evenly spread point sets the solver's visibility checks use: the 4-d Kronecker
//! sequence ([`kronecker4`]) and its placement in a reference shape ([`inset_into`]).

use crate::domain::{Shape, StBox};
use glam::DVec2;

/// One point of a rule in reference coordinates with its normalised weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadPoint {
    pub st: DVec2,
    pub weight: f64,
}

/// Gauss-Legendre nodes and weights on `[0, 1]` (weights sum to 1), ascending.
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    assert!(n >= 1, "a Gauss rule needs at least one point");
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Initial guess (Tricomi), then Newton on P_n.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, x);
            dp = d;
            let dx = p / d;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let (_, d) = legendre_and_derivative(n, x);
        dp = if d != 0.0 { d } else { dp };
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push(((1.0 - x) * 0.5, w * 0.5));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// An `n`-per-axis rule on the given reference shape.
pub fn rule(shape: Shape, n: usize) -> Vec<QuadPoint> {
    let g = gauss_legendre(n);
    let mut out = Vec::with_capacity(n * n);
    for &(a, wa) in &g {
        for &(b, wb) in &g {
            out.push(match shape {
                Shape::Parallelogram => QuadPoint {
                    st: DVec2::new(a, b),
                    weight: wa * wb,
                },
                Shape::Triangle => QuadPoint {
                    st: DVec2::new(a, b * (1.0 - a)),
                    weight: 2.0 * wa * wb * (1.0 - a),
                },
            });
        }
    }
    out
}

/// The zones of influence of the points of `rule(Shape::Parallelogram, n)`, in the same order
/// (paper 3.3, figure 6): along each axis the points' weights, laid end to end in the points'
/// order, tile `[0, 1]`; a point's zone is the product of its two intervals. So each zone's area is
/// its point's weight, the zones tile the square, and each contains its point.
pub fn zones_of_influence(n: usize) -> Vec<StBox> {
    let g = gauss_legendre(n);
    let mut edges = Vec::with_capacity(n + 1);
    let mut acc = 0.0;
    edges.push(0.0);
    for &(_, w) in &g {
        acc += w;
        edges.push(acc);
    }
    // Rounding: the last edge is the square's side.
    edges[n] = 1.0;
    let mut out = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            out.push(StBox::new(
                DVec2::new(edges[i], edges[j]),
                DVec2::new(edges[i + 1], edges[j + 1]),
            ));
        }
    }
    out
}

/// Point `i` of the 4-d Kronecker sequence `frac(1/2 + (i + 1) / g^(j + 1))`, `g` the generalised
/// golden ratio (the real root of `x^5 = x + 1`), in `[0,1)^4`: its projections on every axis and
/// every pair of axes are evenly spread, for any number of points.
pub fn kronecker4(i: usize) -> [f64; 4] {
    const G: f64 = 1.167_303_978_261_418_7;
    let i = i as f64 + 1.0;
    std::array::from_fn(|j| (0.5 + i / G.powi(j as i32 + 1)).fract())
}

/// Point `p` of the unit square placed in the reference shape `inset` off its border: scaled into
/// `[inset, 1 - inset]^2`, or, for the triangle, folded across its hypotenuse and drawn towards the
/// centroid by `1 - 3 inset` (a uniform point stays uniform).
pub fn inset_into(shape: Shape, p: DVec2, inset: f64) -> DVec2 {
    match shape {
        Shape::Parallelogram => DVec2::splat(inset) + p * (1.0 - 2.0 * inset),
        Shape::Triangle => {
            let q = if p.x + p.y > 1.0 { DVec2::ONE - p } else { p };
            let c = DVec2::splat(1.0 / 3.0);
            c + (q - c) * (1.0 - 3.0 * inset)
        }
    }
}

/// The centres of a `grid` x `grid` partition of the unit square, `s` the outer coordinate: the
/// brute-force twin that tests integrate against.
#[cfg(test)]
pub(super) fn unit_square_midpoints(grid: usize) -> impl Iterator<Item = DVec2> {
    let at = move |k: usize| (k as f64 + 0.5) / grid as f64;
    (0..grid).flat_map(move |i| (0..grid).map(move |j| DVec2::new(at(i), at(j))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact integral of s^i t^j over the normalised reference shape.
    fn exact(shape: Shape, i: i32, j: i32) -> f64 {
        let fact = |n: i32| (1..=n).map(f64::from).product::<f64>();
        match shape {
            Shape::Parallelogram => 1.0 / ((i + 1) as f64 * (j + 1) as f64),
            // int_T s^i t^j = i! j! / (i + j + 2)!, normalised by the area 1/2.
            Shape::Triangle => 2.0 * fact(i) * fact(j) / fact(i + j + 2),
        }
    }

    #[test]
    fn gauss_legendre_is_exact_to_degree_2n_minus_1() {
        for n in 1..=8 {
            let g = gauss_legendre(n);
            assert!((g.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-14);
            for d in 0..(2 * n) as i32 {
                let q: f64 = g.iter().map(|(x, w)| w * x.powi(d)).sum();
                assert!(
                    (q - 1.0 / (d + 1) as f64).abs() < 1e-13,
                    "n={n} degree {d}: {q}"
                );
            }
            // And not exact one degree further (the rule is what it says, no more).
            let d = 2 * n as i32;
            let q: f64 = g.iter().map(|(x, w)| w * x.powi(d)).sum();
            assert!((q - 1.0 / (d + 1) as f64).abs() > 1e-12);
        }
    }

    #[test]
    fn shape_rules_integrate_monomials_exactly() {
        for n in 1..=5 {
            for shape in [Shape::Parallelogram, Shape::Triangle] {
                let r = rule(shape, n);
                let max_total = match shape {
                    Shape::Parallelogram => 2 * n as i32 - 1,
                    Shape::Triangle => 2 * n as i32 - 2,
                };
                for i in 0..=max_total {
                    for j in 0..=(max_total - i) {
                        let q: f64 = r
                            .iter()
                            .map(|p| p.weight * p.st.x.powi(i) * p.st.y.powi(j))
                            .sum();
                        let e = exact(shape, i, j);
                        assert!(
                            (q - e).abs() < 1e-13,
                            "{shape:?} n={n} s^{i} t^{j}: {q} vs {e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn zones_of_influence_tile_the_square_and_hold_their_points() {
        for n in 1..=4 {
            let zones = zones_of_influence(n);
            let points = rule(Shape::Parallelogram, n);
            assert_eq!(zones.len(), points.len());
            let total: f64 = zones.iter().map(|z| z.area()).sum();
            assert!((total - 1.0).abs() < 1e-14);
            for (z, p) in zones.iter().zip(&points) {
                assert!(
                    (z.area() - p.weight).abs() < 1e-14,
                    "a zone's area is its weight"
                );
                assert!(
                    z.min.x < p.st.x && p.st.x < z.max.x && z.min.y < p.st.y && p.st.y < z.max.y
                );
            }
        }
    }

    #[test]
    fn kronecker_points_spread_over_every_pair_of_axes() {
        // 64 points: every pair of axes puts at least one in each cell of a 4 x 4 grid, and none
        // holds more than twice its share.
        let points: Vec<[f64; 4]> = (0..64).map(kronecker4).collect();
        // The sequence's constant: the generalised golden ratio of dimension 4.
        // Point 0 on axis 0 is frac(1/2 + 1/g), and 1/g = 0.857: it wrapped once.
        let g = 1.0 / (kronecker4(0)[0] + 0.5);
        assert!((g.powi(5) - g - 1.0).abs() < 1e-12, "g = {g}");
        assert!(points.iter().flatten().all(|&x| (0.0..1.0).contains(&x)));
        for a in 0..4 {
            for b in (a + 1)..4 {
                let mut cells = [0usize; 16];
                for p in &points {
                    cells[(p[a] * 4.0) as usize * 4 + (p[b] * 4.0) as usize] += 1;
                }
                assert!(
                    cells.iter().all(|&c| (1..=8).contains(&c)),
                    "axes {a}, {b}: {cells:?}"
                );
            }
        }
    }

    #[test]
    fn inset_points_stay_inside_their_shape() {
        let e = 0.02;
        for i in 0..200 {
            let [a, b, _, _] = kronecker4(i);
            let p = inset_into(Shape::Parallelogram, DVec2::new(a, b), e);
            assert!(p.min_element() >= e && p.max_element() <= 1.0 - e, "{p}");
            let t = inset_into(Shape::Triangle, DVec2::new(a, b), e);
            // At least `e` inside each of the three sides (the hypotenuse's distance is in s + t).
            assert!(t.x >= e && t.y >= e && t.x + t.y <= 1.0 - e, "{t}");
        }
    }
}
