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
        return front_contour_integral(x, n, polygon);
    }
    let mut clipped = Vec::with_capacity(polygon.len() + 2);
    clip_to_front(x, n, polygon, &mut clipped);
    front_contour_integral(x, n, &clipped)
}

/// Lambert's contour integral over a polygon wholly in front of `x`'s tangent plane.
fn front_contour_integral(x: DVec3, n: DVec3, clipped: &[DVec3]) -> f64 {
    if clipped.len() < 3 {
        return 0.0;
    }
    // A polygon lying in the tangent plane subtends no projected solid angle.
    let (height, extent2) = clipped.iter().fold((f64::MIN, 0.0f64), |(h, e), p| {
        let d = *p - x;
        (h.max(n.dot(d)), e.max(d.length_squared()))
    });
    if height <= 1e-12 * extent2.sqrt() {
        return 0.0;
    }
    let mut sum = 0.0;
    let m = clipped.len();
    for i in 0..m {
        let a = clipped[i] - x;
        let b = clipped[(i + 1) % m] - x;
        let c = a.cross(b);
        let cl = c.length();
        if cl <= 1e-300 {
            continue;
        }
        let angle = edge_angle(cl, a.dot(b));
        sum += angle * n.dot(c) / cl;
    }
    sum / (2.0 * PI)
}

/// The largest tangent [`edge_angle`] takes by its series: there the series' first term left out
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

/// `cross.atan2(dot)`: the angle between two vectors whose cross product has length `cross` and
/// whose dot product is `dot`. An edge of a many-sided face seen from afar subtends a small
/// angle, and a contour integral takes one per edge: below [`SERIES_MAX_TAN`] the arctangent's
/// series to `t^13` stands in for the library's `atan2` (a few multiplications against its
/// rounding-mode guarded evaluation), within `1e-12` of it relatively
/// (`tests::the_edge_angle_is_atan2`).
fn edge_angle(cross: f64, dot: f64) -> f64 {
    if dot > 0.0 && cross.abs() <= SERIES_MAX_TAN * dot {
        let t = cross / dot;
        let t2 = t * t;
        let series = ATAN_SERIES.iter().rev().fold(0.0, |acc, c| acc * t2 + c);
        t * series
    } else {
        cross.atan2(dot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The edge angle against the library's `atan2`: on a fine sweep of tangents through the
    /// series' range and past it, and at random lengths, within `1e-12` relatively (the series
    /// where the tangent is small, the library elsewhere).
    #[test]
    fn the_edge_angle_is_atan2() {
        let mut worst: f64 = 0.0;
        for i in 0..=20_000 {
            let t = 0.3 * f64::from(i) / 20_000.0;
            for dot in [1e-6, 1.0, 37.5] {
                let (cross, expected) = (t * dot, (t * dot).atan2(dot));
                let got = edge_angle(cross, dot);
                let rel = (got - expected).abs() / expected.abs().max(1e-300);
                worst = worst.max(rel);
            }
        }
        assert!(worst < 1e-12, "{worst}");
        let mut rnd = crate::shuffle::uniform_sequence(5);
        for _ in 0..100_000 {
            let (cross, dot) = ((rnd() - 0.2) * 3.0, (rnd() - 0.3) * 4.0);
            let expected = cross.atan2(dot);
            let got = edge_angle(cross, dot);
            assert!(
                (got - expected).abs() <= 1e-12 * expected.abs(),
                "{cross} {dot}: {got} {expected}"
            );
        }
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
