//! The radiosity kernel: point-to-point `G = cos cos / (pi r^2)` and the exact point-to-polygon
//! form factor (Lambert's contour integral) used for the constant part of every transfer.
//!
//! `point_polygon_form_factor(x, n, polygon)` is exact for an unoccluded planar polygon: the polygon
//! is first clipped to the half-space in front of `x`'s tangent plane, so it is also exact for
//! sources that cross the receiver's plane. Units: form factors are dimensionless.

use glam::DVec3;
use std::f64::consts::PI;

/// `cos(theta_x) cos(theta_y) / (pi r^2)` for points `x`, `y` with unit normals `nx`, `ny`;
/// zero when either point faces away.
#[inline]
pub fn geometric_kernel(x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 0.0;
    }
    let cx = nx.dot(d);
    let cy = -ny.dot(d);
    if cx <= 0.0 || cy <= 0.0 {
        return 0.0;
    }
    cx * cy / (PI * r2 * r2)
}

/// Clips a convex or concave planar polygon to `n . (p - x) >= 0` (Sutherland-Hodgman).
pub fn clip_to_front(x: DVec3, n: DVec3, polygon: &[DVec3], out: &mut Vec<DVec3>) {
    out.clear();
    let len = polygon.len();
    for i in 0..len {
        let a = polygon[i];
        let b = polygon[(i + 1) % len];
        let da = n.dot(a - x);
        let db = n.dot(b - x);
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push(a + (b - a) * t);
        }
    }
}

/// Exact form factor from a differential area at `x` (unit normal `n`) to a planar polygon,
/// without occlusion. Zero for a polygon entirely behind the tangent plane.
pub fn point_polygon_form_factor(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    signed_contour_form_factor(x, n, polygon).abs()
}

/// Exact form factor from a differential area at `x` to a planar face given as rings (outer
/// rings and holes of opposite orientations, as [`crate::domain::FaceMask::clip`] returns them),
/// without occlusion: the rings' signed contour integrals add up to the face's.
pub fn point_rings_form_factor(x: DVec3, n: DVec3, rings: &[Vec<DVec3>]) -> f64 {
    rings
        .iter()
        .map(|r| signed_contour_form_factor(x, n, r))
        .sum::<f64>()
        .abs()
}

/// How far from a source element, in radii of its corners' bounding sphere, a point must be for
/// the element's own quadrature rule at `order` (`quadrature::rule(shape, order + 1)`, the rule
/// the solver shoots with) to give its form factor within `1e-4` of the head-on value
/// `A / (pi d^2)`, when every corner is in front of the point's tangent plane. Beyond it the
/// solver takes the rule's sum instead of the contour integral (`Emitter::rule_suffices`).
/// Pinned by `the_rule_gives_the_form_factor_beyond_its_radii`.
pub fn rule_suffices_radii(order: usize) -> f64 {
    match order {
        1 => 12.0,
        2 => 4.0,
        _ => 3.0,
    }
}

/// Lambert's contour integral over the polygon clipped to the front of `x`'s tangent plane; its
/// sign follows the polygon's orientation.
fn signed_contour_form_factor(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    // Wholly in front (the usual case): clipping would copy the polygon; it runs once per
    // quadrature point of every link, so it allocates only when it cuts.
    if polygon.iter().all(|p| n.dot(*p - x) >= 0.0) {
        return contour_sum(x, n, polygon).form_factor();
    }
    let mut clipped = Vec::with_capacity(polygon.len() + 2);
    clip_to_front(x, n, polygon, &mut clipped);
    contour_sum(x, n, &clipped).form_factor()
}

/// One pass of Lambert's contour integral over a polygon as seen from `x` (normal `n`): the
/// edges' terms summed in order, and what decides whether the sum stands.
struct ContourSum {
    /// `sum` over the edges of `angle(a, b) n.(a x b) / |a x b|` ([`edge_term`]).
    terms: f64,
    /// The greatest height `n.(p - x)` of a vertex, and the largest `|p - x|^2`.
    highest: f64,
    extent2: f64,
    vertices: usize,
}

impl ContourSum {
    /// The form factor of a polygon wholly in front of the tangent plane: zero for fewer than
    /// three vertices, and for a polygon lying in the tangent plane (it subtends no projected
    /// solid angle).
    fn form_factor(&self) -> f64 {
        if self.vertices < 3 || self.highest <= 1e-12 * self.extent2.sqrt() {
            return 0.0;
        }
        self.terms / (2.0 * PI)
    }
}

/// The edges' terms of `polygon` (closed: its last vertex joins its first) from `x` (normal
/// `n`), with the vertices' greatest height and extent, in one pass.
fn contour_sum(x: DVec3, n: DVec3, polygon: &[DVec3]) -> ContourSum {
    let mut out = ContourSum {
        terms: 0.0,
        highest: f64::MIN,
        extent2: 0.0,
        vertices: polygon.len(),
    };
    let Some(&last) = polygon.last() else {
        return out;
    };
    let mut a = last - x;
    for &p in polygon {
        let b = p - x;
        out.highest = out.highest.max(n.dot(b));
        out.extent2 = out.extent2.max(b.length_squared());
        out.terms += edge_term(a.cross(b), a.dot(b), n);
        a = b;
    }
    out
}

/// The largest tangent [`edge_term`] takes by its series: there the series' first term left out
/// (`t^15 / 15`) is below `1e-13` of the angle.
const SERIES_MAX_TAN: f64 = 0.125;

/// The arctangent's series `t (1 - t^2/3 + t^4/5 - ... + t^12/13)`, in powers of `t^2`.
const ATAN_SERIES: [f64; 7] = [
    1.0,
    -1.0 / 3.0,
    1.0 / 5.0,
    -1.0 / 7.0,
    1.0 / 9.0,
    -1.0 / 11.0,
    1.0 / 13.0,
];

/// The arctangent's series over `t`, `S(t^2) = 1 - t^2/3 + ... + t^12/13`, by Estrin's scheme
/// (powers `t^4`, `t^8` and pairs of terms evaluated side by side: a contour integral's edges
/// are independent, and the processor overlaps the short chains of several where Horner's rule
/// would chain seven multiply-adds per edge).
#[inline]
fn series(t2: f64) -> f64 {
    let [k0, k1, k2, k3, k4, k5, k6] = ATAN_SERIES;
    let t4 = t2 * t2;
    let t8 = t4 * t4;
    (k0 + k1 * t2) + t4 * (k2 + k3 * t2) + t8 * ((k4 + k5 * t2) + t4 * k6)
}

/// An edge's term of the contour integral, `angle(a, b) n.c / |c|`, from the cross product
/// `c = a x b` and the dot product `dot = a.b` of the vectors from the point to its ends. An edge
/// of a many-sided face seen from afar subtends a small angle: where the tangent `t = |c| / dot`
/// is below [`SERIES_MAX_TAN`] the angle is `t S(t^2)`, `S` the arctangent's series to `t^13`,
/// so the term is `S(|c|^2 / dot^2) n.c / dot`: no square root, one division, no `atan2`. Within
/// `1e-12` of `atan2(|c|, dot) n.c / |c|` relatively (`tests::the_edge_term_is_the_atan2_one`).
/// Zero for an edge through the point's line of sight (`c` zero).
#[inline]
fn edge_term(c: DVec3, dot: f64, n: DVec3) -> f64 {
    let c2 = c.length_squared();
    if c2 <= 0.0 {
        return 0.0;
    }
    let nc = n.dot(c);
    if dot > 0.0 && c2 <= SERIES_MAX_TAN * SERIES_MAX_TAN * dot * dot {
        let r = 1.0 / dot;
        let t2 = c2 * r * r;
        series(t2) * nc * r
    } else {
        let cl = c2.sqrt();
        cl.atan2(dot) * nc / cl
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An edge's term as the library's `atan2` gives it: `atan2(|c|, dot) n.c / |c|`.
    fn atan2_term(c: DVec3, dot: f64, n: DVec3) -> f64 {
        let cl = c.length();
        cl.atan2(dot) * n.dot(c) / cl
    }

    /// Does [`edge_term`] take the edge of cross product `c` and dot product `dot` by the series?
    fn by_the_series(c: DVec3, dot: f64) -> bool {
        dot > 0.0 && c.length() <= SERIES_MAX_TAN * dot
    }

    /// The edge term against `atan2`'s, within `1e-12` of the angle: on a sweep of tangents
    /// through the series' range, at three lengths and normals at three slants, then for random
    /// pairs of vectors (either sign of the dot product, every tangent).
    #[test]
    fn the_edge_term_is_the_atan2_one() {
        let mut worst: f64 = 0.0;
        for i in 1..=20_000 {
            let t = SERIES_MAX_TAN * 1.01 * f64::from(i) / 20_000.0;
            for dot in [1e-6, 1.0, 37.5] {
                for n in [DVec3::Z, DVec3::new(0.6, 0.0, 0.8), DVec3::NEG_Y] {
                    let c = DVec3::new(0.0, 0.6, 0.8) * (t * dot);
                    let (got, expected) = (edge_term(c, dot, n), atan2_term(c, dot, n));
                    worst = worst.max((got - expected).abs() / t.atan());
                }
            }
        }
        assert!(worst < 1e-12, "{worst}");
        let mut rnd = crate::shuffle::uniform_sequence(5);
        let mut v = || DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
        let mut series_pairs = 0;
        for k in 0..100_000 {
            // Every other pair nearly parallel: the series' range.
            let a = v();
            let b = if k % 2 == 0 {
                a * 20.0 + v()
            } else {
                v() * 8.0
            };
            let n = v().normalize();
            let (c, dot) = (a.cross(b), a.dot(b));
            let (got, expected) = (edge_term(c, dot, n), atan2_term(c, dot, n));
            let angle = c.length().atan2(dot);
            assert!(
                (got - expected).abs() <= 1e-12 * angle,
                "{a} {b}: {got} {expected}"
            );
            series_pairs += usize::from(by_the_series(c, dot));
        }
        assert!(
            series_pairs > 1_000,
            "the random pairs reach the series: {series_pairs}"
        );
        assert_eq!(edge_term(DVec3::ZERO, 1.0, DVec3::Z), 0.0);
    }

    /// The one-pass contour integral against a twin that integrates the clipped polygon edge by
    /// edge with `atan2`: random polygons (stars about a random centre, in a random plane) seen
    /// from random points, some with the polygon crossing their tangent plane, within `1e-12` of
    /// the sum of the edges' absolute terms.
    #[test]
    fn the_contour_integral_is_its_atan2_twin() {
        let twin = |x: DVec3, n: DVec3, polygon: &[DVec3]| {
            let mut clipped = Vec::new();
            clip_to_front(x, n, polygon, &mut clipped);
            let (mut sum, mut scale, mut series_edges) = (0.0, 0.0, 0);
            for i in 0..clipped.len() {
                let (a, b) = (clipped[i] - x, clipped[(i + 1) % clipped.len()] - x);
                let (c, dot) = (a.cross(b), a.dot(b));
                if c.length() > 0.0 {
                    let term = atan2_term(c, dot, n);
                    sum += term;
                    scale += term.abs();
                    series_edges += usize::from(by_the_series(c, dot));
                }
            }
            (sum / (2.0 * PI), scale / (2.0 * PI), series_edges)
        };
        let mut rnd = crate::shuffle::uniform_sequence(17);
        let (mut cut, mut whole, mut series_edges) = (0, 0, 0);
        for k in 0..3_000 {
            let mut v = || DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            let (centre, u) = (v() * 4.0, v().normalize());
            let w = u.cross(v()).normalize();
            let sides = 3 + k % 70;
            let polygon: Vec<DVec3> = (0..sides)
                .map(|i| {
                    let angle = 2.0 * PI * i as f64 / sides as f64;
                    let r = 0.2 + (i % 3) as f64 * 0.4;
                    centre + (u * angle.cos() + w * angle.sin()) * r
                })
                .collect();
            let (x, n) = (v() * 6.0, v().normalize());
            let got = signed_contour_form_factor(x, n, &polygon);
            let (expected, scale, series) = twin(x, n, &polygon);
            series_edges += series;
            assert!(
                (got - expected).abs() <= 1e-12 * scale.max(1e-300),
                "{k}: {got} {expected}"
            );
            if polygon.iter().all(|p| n.dot(*p - x) >= 0.0) {
                whole += 1;
            } else if expected != 0.0 {
                cut += 1;
            }
        }
        assert!(cut > 300 && whole > 300, "{cut} cut, {whole} whole");
        assert!(series_edges > 10_000, "{series_edges} edges by the series");
    }

    /// What subtends no projected solid angle: fewer than three vertices, a polygon lying in the
    /// point's tangent plane, a polygon wholly behind it.
    #[test]
    fn degenerate_and_hidden_polygons_have_no_form_factor() {
        let square = unit_square_at(0.0);
        assert_eq!(
            point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &square),
            0.0
        );
        assert_eq!(
            point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &square[..2]),
            0.0
        );
        assert_eq!(point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &[]), 0.0);
        let below = unit_square_at(-1.0);
        assert_eq!(
            point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &below),
            0.0
        );
        assert!(point_polygon_form_factor(DVec3::ZERO, DVec3::NEG_Z, &below) > 0.2);
    }

    fn unit_square_at(z: f64) -> Vec<DVec3> {
        vec![
            DVec3::new(-0.5, -0.5, z),
            DVec3::new(0.5, -0.5, z),
            DVec3::new(0.5, 0.5, z),
            DVec3::new(-0.5, 0.5, z),
        ]
    }

    #[test]
    fn point_one_metre_under_unit_square_centre() {
        let f = point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &unit_square_at(1.0));
        assert!((f - 0.239456).abs() < 1e-6, "{f}");
        // Orientation of the polygon does not matter.
        let mut rev = unit_square_at(1.0);
        rev.reverse();
        assert!((point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &rev) - f).abs() < 1e-12);
    }

    #[test]
    fn a_holed_square_is_the_square_minus_its_hole() {
        // Outer counter-clockwise, hole clockwise: the rings' form factor is the difference of
        // the two squares' (each exact on its own), whichever way the whole is oriented.
        let outer = unit_square_at(1.0);
        let mut hole: Vec<DVec3> = outer
            .iter()
            .map(|p| DVec3::new(p.x * 0.5, p.y * 0.5, 1.0))
            .collect();
        let expected = point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &outer)
            - point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &hole);
        hole.reverse();
        let mut rings = vec![outer, hole];
        let f = point_rings_form_factor(DVec3::ZERO, DVec3::Z, &rings);
        assert!((f - expected).abs() < 1e-14 && f > 0.0, "{f} vs {expected}");
        for r in &mut rings {
            r.reverse();
        }
        assert!((point_rings_form_factor(DVec3::ZERO, DVec3::Z, &rings) - f).abs() < 1e-14);
    }

    #[test]
    fn hemisphere_covering_polygon_has_form_factor_one() {
        // A huge square above the point sees almost the whole hemisphere.
        let big: Vec<DVec3> = unit_square_at(1.0)
            .iter()
            .map(|p| DVec3::new(p.x * 1e7, p.y * 1e7, 1.0))
            .collect();
        let f = point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &big);
        assert!((f - 1.0).abs() < 1e-6, "{f}");
    }

    #[test]
    fn contour_matches_brute_force_quadrature_for_a_tilted_clipped_polygon() {
        // A square crossing the receiver's tangent plane: only the part in front counts.
        let poly = vec![
            DVec3::new(-0.5, 1.0, -0.5),
            DVec3::new(0.5, 1.0, -0.5),
            DVec3::new(0.5, 0.7, 1.0),
            DVec3::new(-0.5, 0.7, 1.0),
        ];
        let f = point_polygon_form_factor(DVec3::ZERO, DVec3::Z, &poly);
        let (o, u, v) = (poly[0], poly[1] - poly[0], poly[3] - poly[0]);
        let ny = u.cross(v).normalize();
        let ny = if ny.dot(-o) > 0.0 { ny } else { -ny };
        let area = u.cross(v).length();
        let n = 800;
        let mut q = 0.0;
        for i in 0..n {
            for j in 0..n {
                let y = o + u * ((i as f64 + 0.5) / n as f64) + v * ((j as f64 + 0.5) / n as f64);
                q += geometric_kernel(DVec3::ZERO, DVec3::Z, y, ny) * area / (n * n) as f64;
            }
        }
        assert!(
            (f - q).abs() < 1e-4 * q.max(1e-3),
            "contour {f} vs quadrature {q}"
        );
    }

    /// The solver's own rule against the exact contour integral, for random parallelograms and
    /// triangles seen from random points and normals at [`rule_suffices_radii`] and beyond, with
    /// every corner in front of the point's tangent plane: within `1e-4` of the head-on value at
    /// every order. Nearer (half the radii), the bound fails for some pair: the radii are not
    /// looser than they need be by more than a factor of 2.
    #[test]
    fn the_rule_gives_the_form_factor_beyond_its_radii() {
        use crate::domain::Shape;
        use crate::solver::quadrature::rule;
        let mut rnd = crate::shuffle::uniform_sequence(99);
        let mut v = || DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
        for shape in [Shape::Parallelogram, Shape::Triangle] {
            for order in 1..=3 {
                let points = rule(shape, order + 1);
                let radii = rule_suffices_radii(order);
                // The worst error relative to the head-on value, at the radii (times 1 to 3)
                // and at half of them.
                let (mut beyond, mut nearer) = (0.0f64, 0.0f64);
                let mut checked = 0;
                while checked < 40_000 {
                    let (u, w, dir, n) = (v(), v(), v(), v());
                    let cross = u.cross(w);
                    if cross.length() < 0.05 || dir.length() < 0.1 || n.length() < 0.1 {
                        continue;
                    }
                    let (normal, n) = (cross.normalize(), n.normalize());
                    let area = match shape {
                        Shape::Triangle => 0.5 * cross.length(),
                        Shape::Parallelogram => cross.length(),
                    };
                    let poly = match shape {
                        Shape::Parallelogram => vec![DVec3::ZERO, u, u + w, w],
                        Shape::Triangle => vec![DVec3::ZERO, u, w],
                    };
                    let crate::solver::element::Sphere { centre, radius } =
                        crate::solver::element::Sphere::around(&poly);
                    let at = (1.0 + 2.0 * (checked % 7) as f64 / 6.0) * radii;
                    let error = |k: f64| {
                        let x = centre + dir.normalize() * radius * k;
                        if normal.dot(x - centre) <= 0.0 || poly.iter().any(|p| n.dot(*p - x) < 0.0)
                        {
                            return None;
                        }
                        let exact = point_polygon_form_factor(x, n, &poly);
                        let sum: f64 = points
                            .iter()
                            .map(|q| {
                                let y = u * q.st.x + w * q.st.y;
                                geometric_kernel(x, n, y, normal) * area * q.weight
                            })
                            .sum();
                        Some((sum - exact).abs() / (area / (PI * x.distance_squared(centre))))
                    };
                    if let Some(near) = error(0.5 * radii) {
                        nearer = nearer.max(near);
                    }
                    let Some(far) = error(at) else {
                        continue;
                    };
                    beyond = beyond.max(far);
                    checked += 1;
                }
                assert!(
                    beyond <= 1e-4,
                    "{shape:?} M{order}: {beyond:e} at {radii} radii"
                );
                assert!(
                    nearer > 1e-4,
                    "{shape:?} M{order}: {nearer:e} at half the radii"
                );
            }
        }
    }
}
