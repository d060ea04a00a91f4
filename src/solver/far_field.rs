//! Far receivers of a shot: a receiver root whose whole transfer from the shooter is bounded
//! within the oracle's threshold, before any ray or quadrature, takes the shot as one constant
//! link: the source's irradiance at the receiver's centre (its quadrature, scaled to the form
//! factor of `ElementSource::form_factor`, or beyond the rule's radii the rule's own sum even on
//! a partly covered element: `ElementSource::far_irradiance_at`), a constant over the root, with
//! one shadow ray (to the source's centre) deciding its visibility. The oracle would accept a
//! link of that size at the root whatever its visibility (`oracle.rs`: an error above the
//! threshold is needed for any other verdict), so the refinement's result is within the same
//! budget; what it saves is the quadrature at every rule and check point of every far receiver,
//! shot after shot, which made a level's cost grow like the square of its faces; and its one ray
//! replaces the rays to every rule point (on a large city the far links are most of the indirect
//! phase: `a_far_link_takes_the_whole_source_on_one_ray`).
//!
//! The bound: a Lambertian source's power into a cone of half-angle `theta` is at most
//! `sin^2 theta` of it, and a sphere of radius `r` seen from distance `d` subtends
//! `sin theta = r / d`; so a receiver in a sphere of radius `r_R` whose centre lies `D` from the
//! shooter's sphere's centre (radius `r_S`) receives at most `P (r_R / (D - r_S))^2` of the power
//! `P` the shooter may send. Pinned by `far_field_bound_holds_for_random_pairs` below and, end to
//! end, by the reference and analytic tests.
//!
//! Invariant: a far link is one constant over the receiver's root (added to every node of its
//! tree, or gathered at its root node where the reflectance varies: `ShotContext::accept_far`),
//! and counted like any link.

use super::element::{visibility_point, Sphere};
use super::element_source::ElementSource;
use super::far_verdicts::VerdictTable;
#[cfg(test)]
use super::kernel::point_polygon_form_factor;
use super::source::Source;
use crate::domain::{ElementRoot, Shape};
use crate::scene::Rgb;
use glam::{DVec2, DVec3};

/// The largest fraction of the power leaving (any point of) `source` that can reach `receiver`:
/// `(r_R / (D - r_S))^2`, or 1 when the spheres are too close for the bound.
pub(super) fn transfer_fraction_bound(source: &Sphere, receiver: &Sphere) -> f64 {
    let d = source.centre.distance(receiver.centre) - source.radius;
    if d <= receiver.radius {
        1.0
    } else {
        (receiver.radius / d).powi(2)
    }
}

/// How far apart, in sums of the two spheres' radii, a receiver's centre must be from the
/// shooter's for [`point_form_factor`].
pub(super) const POINT_ESTIMATE_RADII: f64 = 4.0;

/// The form factor from `receiver`'s centre to `shooter`'s domain taken as a point source of its
/// area, `A cos_s cos_r / (pi d^2)` (0 when either faces away), when the centres are at least
/// [`POINT_ESTIMATE_RADII`] times the sum of the radii apart; `None` nearer. Its relative error
/// is of the order of `(r / d)^2`: `point_estimate_is_close_to_the_polygon_form_factor` pins it
/// within 5 % of the exact form factor (at grazing angles, of 0.3 times the head-on one). A cost
/// and reflection estimate (`unoccluded.rs`), one evaluation instead of a polygon's contour
/// integral at five points.
pub(super) fn point_form_factor(
    shooter: &ElementRoot,
    s: &Sphere,
    receiver: &ElementRoot,
    r: &Sphere,
) -> Option<f64> {
    let d = r.centre - s.centre;
    let len = d.length();
    if len < POINT_ESTIMATE_RADII * (s.radius + r.radius) {
        return None;
    }
    let cos_s = shooter.normal.dot(d) / len;
    let cos_r = -receiver.normal.dot(d) / len;
    if cos_s <= 0.0 || cos_r <= 0.0 {
        return Some(0.0);
    }
    Some(shooter.area_m2 * cos_s * cos_r / (std::f64::consts::PI * len * len))
}

/// Where a far link to `root` is evaluated: its centre, or the centre's stand-in on the face
/// of an extended root. The same every shot: computed once per root (`shooting.rs`, for `pass.rs`).
pub(super) fn link_point(root: &ElementRoot) -> DVec3 {
    let st = match root.shape {
        Shape::Triangle => DVec2::splat(1.0 / 3.0),
        Shape::Parallelogram => DVec2::splat(0.5),
    };
    visibility_point(root, &super::basis::ChildMap::IDENTITY, st)
}

/// The irradiance one far link delivers to `root` at its [`link_point`] `x`, one shadow ray
/// deciding its visibility (`ElementSource::far_irradiance_at`; read from `verdict`, the
/// shooter's table and the receiver's index, when an earlier shot traced it); `None` when `x`
/// receives nothing from the source.
pub(super) fn far_irradiance(
    source: &ElementSource,
    root: &ElementRoot,
    x: DVec3,
    verdict: Option<(&VerdictTable, usize)>,
) -> Option<Rgb> {
    let ignore = source.ignored_faces(root.face.0);
    source.far_irradiance_at(x, root.normal, ignore, verdict)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::solver::basis::{Basis, MAX_FUNCTIONS};
    use crate::solver::element::tests::parallelogram_root;
    use crate::solver::source::Rays;
    use crate::solver::visibility::Visibility;

    /// `ElementSource::power_bound` against the radiosity's largest magnitude on a fine grid of
    /// the element times its area, for random coefficients at every order on both native shapes:
    /// never below it, and within four times it (a sum of magnitudes, not loose beyond that); with
    /// one non-constant function beside the mean, within 5 % of the larger of its two signs'
    /// (each function's own bound, not one margin for all: the former `6 x` fails this).
    #[test]
    fn power_bound_holds_over_the_face() {
        use crate::solver::element_source::tests::shot_of_first_root;
        use crate::solver::element_source::SourceElement;
        use crate::solver::hierarchy::Hierarchy;
        use crate::solver::refine::Shot;
        use crate::solver::rules::{Bases, Rules};
        use crate::solver::visibility::Visibility;
        let mut rnd = crate::shuffle::uniform_sequence(31);
        let visibility = Visibility::new(Vec::new(), 30.0);
        for shape in [Shape::Triangle, Shape::Parallelogram] {
            for order in 1..=3 {
                let (bases, rules) = (Bases::new(order), Rules::new(order));
                let basis = Basis::new(shape, order);
                let n = basis.len();
                let mut root = parallelogram_root(DVec3::ZERO, DVec3::X * 2.0, DVec3::Y);
                if shape == Shape::Triangle {
                    root.shape = Shape::Triangle;
                    root.area_m2 *= 0.5;
                    root.face_area_m2 *= 0.5;
                }
                let roots = [root];
                let hierarchy = Hierarchy::new(n);
                let singles = 2 * (n - 1);
                // A single function's first sign's largest power (its lobes may differ in size).
                let mut first_sign = 0.0f64;
                for k in 0..50 + singles {
                    let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
                    let (weight, tight) = if k < 50 {
                        for c in coeffs.iter_mut().take(n) {
                            *c = [rnd() - 0.3, rnd() - 0.5, 2.0 * rnd() - 1.0];
                        }
                        ([rnd(), rnd(), rnd()], 4.0)
                    } else {
                        let (a, sign) = (1 + (k - 50) / 2, if k % 2 == 0 { 1.0 } else { -1.0 });
                        coeffs[0] = [0.5; 3];
                        coeffs[a] = [sign; 3];
                        ([1.0; 3], 0.0)
                    };
                    let element = SourceElement::root(&roots[0], coeffs, n, None, None);
                    let shot = shot_of_first_root(
                        &roots,
                        (&bases, &rules),
                        &visibility,
                        &hierarchy,
                        false,
                    );
                    let Some(source) = shot.source(&element, weight) else {
                        continue;
                    };
                    let mut phi = [0.0; MAX_FUNCTIONS];
                    let mut largest = 0.0f64;
                    for i in 0..=60 {
                        for j in 0..=60 {
                            if shape == Shape::Triangle && i + j > 60 {
                                continue;
                            }
                            basis.eval(DVec2::new(i as f64, j as f64) / 60.0, &mut phi[..n]);
                            let b: f64 = (0..3)
                                .map(|ch| {
                                    let v: f64 = (0..n).map(|a| coeffs[a][ch] * phi[a]).sum();
                                    weight[ch] * v.abs()
                                })
                                .sum();
                            largest = largest.max(b);
                        }
                    }
                    let sent = largest * roots[0].face_area_m2;
                    let bound = source.power_bound();
                    assert!(
                        sent <= bound * (1.0 + 1e-12),
                        "{shape:?} M{order}: {sent} > {bound}"
                    );
                    if k < 50 {
                        assert!(
                            bound <= tight * sent,
                            "{shape:?} M{order}: {bound} loose for {sent}"
                        );
                    } else if k % 2 == 0 {
                        first_sign = sent;
                    } else {
                        let larger = sent.max(first_sign);
                        assert!(
                            bound <= 1.05 * larger,
                            "{shape:?} M{order} function {}: {bound} loose for {larger}",
                            1 + (k - 50) / 2
                        );
                    }
                }
            }
        }
    }

    /// The bound against a brute-force estimate: the largest solid-angle fraction
    /// `cos-weighted` of a small receiver disc from points of the source never exceeds it.
    #[test]
    fn far_field_bound_holds_for_random_pairs() {
        let mut rnd = crate::shuffle::uniform_sequence(12345);
        for _ in 0..2000 {
            let s = Sphere {
                centre: DVec3::new(rnd(), rnd(), rnd()) * 10.0,
                radius: 0.1 + rnd(),
            };
            let r = Sphere {
                centre: DVec3::new(rnd(), rnd(), rnd()) * 10.0,
                radius: 0.1 + rnd(),
            };
            let bound = transfer_fraction_bound(&s, &r);
            // Point-to-sphere: from a point y at distance L of a sphere of radius r, a
            // Lambertian emitter aimed straight at it sends (r / L)^2 of its power into it.
            for _ in 0..20 {
                let dir = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize_or_zero();
                let y = s.centre + dir * s.radius * rnd();
                let l = y.distance(r.centre);
                let exact = if l <= r.radius {
                    1.0
                } else {
                    (r.radius / l).powi(2)
                };
                assert!(exact <= bound + 1e-12, "{exact} > {bound}");
            }
        }
    }

    /// A 1 m square source facing up (face 0) and a receiver 20 m above it facing down (face 1),
    /// in a scene open (`blocked` false) or with a 0.2 m square at half height over the source's
    /// centre, which blocks the centre ray and not the rule's outer points: `f` gets the source
    /// as the receiver sees it (M2, direct), the receiver's root and the visibility.
    pub(in crate::solver) fn square_under_square<R>(
        blocked: bool,
        f: impl FnOnce(&ElementSource, &ElementRoot, &Visibility) -> R,
    ) -> R {
        let c = DVec3::new(0.5, 0.5, 10.0);
        let half = DVec3::new(0.1, 0.1, 0.0);
        square_under_square_blocked_by(blocked.then_some((c - half, c + half)), f)
    }

    /// [`square_under_square`] with a blocker of its own: the horizontal rectangle between the
    /// two corners `(low, high)` (the same height), or nothing.
    pub(in crate::solver) fn square_under_square_blocked_by<R>(
        blocker: Option<(DVec3, DVec3)>,
        f: impl FnOnce(&ElementSource, &ElementRoot, &Visibility) -> R,
    ) -> R {
        use crate::solver::element_source::tests::shot_of_first_root;
        use crate::solver::element_source::SourceElement;
        use crate::solver::hierarchy::Hierarchy;
        use crate::solver::refine::Shot;
        use crate::solver::rules::{Bases, Rules};
        let mut source = parallelogram_root(DVec3::ZERO, DVec3::X, DVec3::Y);
        source.exitance = [2.0, 1.0, 0.5];
        let mut receiver = parallelogram_root(DVec3::new(0.0, 0.0, 20.0), DVec3::Y, DVec3::X);
        receiver.face = crate::domain::FaceId(1);
        let roots = [source, receiver];
        let (bases, rules) = (Bases::new(2), Rules::new(2));
        let hierarchy = Hierarchy::new(bases.of(Shape::Parallelogram).len());
        let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
        coeffs[0] = roots[0].exitance;
        let n = bases.of(Shape::Parallelogram).len();
        let element = SourceElement::root(&roots[0], coeffs, n, None, None);
        let visibility = match blocker {
            Some((lo, hi)) => {
                debug_assert_eq!(lo.z, hi.z, "a horizontal rectangle");
                let (a, b) = (lo, DVec3::new(hi.x, lo.y, lo.z));
                let (d, e) = (hi, DVec3::new(lo.x, hi.y, lo.z));
                Visibility::new([([a, b, d], 7), ([a, d, e], 7)], 30.0)
            }
            None => Visibility::new(Vec::new(), 30.0),
        };
        let shot = shot_of_first_root(&roots, (&bases, &rules), &visibility, &hierarchy, true);
        let source = shot.source(&element, [1.0; 3]).expect("an emitting source");
        f(&source, &roots[1], &visibility)
    }

    /// A far link traces one shadow ray, to the source's centre: when it passes, the link takes
    /// what the source's whole rule delivers with every point visible (the same numbers); when
    /// it is blocked, nothing.
    #[test]
    fn a_far_link_takes_the_whole_source_on_one_ray() {
        let at = |blocked: bool| {
            square_under_square(blocked, |source, receiver, visibility| {
                let ignore = source.ignored_faces(1);
                let x = DVec3::new(0.5, 0.5, 20.0);
                let whole = source
                    .irradiance_at(x, receiver.normal, ignore, Rays::Trace, None)
                    .map(|p| p.e);
                let before = visibility.rays_traced();
                let far = far_irradiance(source, receiver, link_point(receiver), None);
                (whole, far, visibility.rays_traced() - before)
            })
        };
        let (whole, far, rays) = at(false);
        assert_eq!(rays, 1);
        assert_eq!(far, whole);
        assert!(far.is_some_and(|e| e[0] > 0.0), "{far:?}");
        let (whole, far, rays) = at(true);
        assert_eq!(rays, 1);
        assert_eq!(far, Some([0.0; 3]));
        assert!(
            whole.is_some_and(|e| e[0] > 0.0),
            "the outer points see the source: {whole:?}"
        );
    }

    /// With the shooter's table of verdicts (`far_verdicts.rs`), a far link traces its ray the
    /// first time only: the second takes the same light, blocked or not, with no ray; a pair
    /// known blocked takes nothing without evaluating its form factor.
    #[test]
    fn a_far_link_reads_its_verdict_back_from_the_shooters_table() {
        use crate::solver::far_verdicts::FarVerdicts;
        for blocked in [false, true] {
            square_under_square(blocked, |source, receiver, visibility| {
                let mut verdicts = FarVerdicts::new(2, usize::MAX);
                verdicts.reserve(0);
                let table = verdicts.table(0).expect("a table within the budget");
                let x = link_point(receiver);
                let untabled = far_irradiance(source, receiver, x, None);
                let mut rays = Vec::new();
                let mut far = Vec::new();
                for _ in 0..2 {
                    let before = visibility.rays_traced();
                    far.push(far_irradiance(source, receiver, x, Some((table, 1))));
                    rays.push(visibility.rays_traced() - before);
                }
                assert_eq!(rays, [1, 0], "blocked {blocked}");
                assert_eq!(far, [untabled, untabled], "blocked {blocked}");
                assert_eq!(untabled.is_some_and(|e| e[0] > 0.0), !blocked);
                // A pair known blocked is answered before its form factor is evaluated: asked
                // at a point behind the source's plane (`None`: its form factor is 0), the
                // table's verdict stands. In a solve the point is the pair's own, whose form
                // factor was positive when its ray was traced.
                let behind = DVec3::new(0.5, 0.5, -5.0);
                assert_eq!(far_irradiance(source, receiver, behind, None), None);
                let known = far_irradiance(source, receiver, behind, Some((table, 1)));
                assert_eq!(known, blocked.then_some([0.0; 3]), "blocked {blocked}");
            });
        }
    }

    /// The point estimate against the exact form factor at the receiver's centre, for random
    /// pairs of parallelograms at least `POINT_ESTIMATE_RADII` sums of radii apart: within 5 %
    /// of it, or of 0.3 times the head-on value `A / (pi d^2)` where it is smaller (grazing
    /// angles); `None` nearer.
    #[test]
    fn point_estimate_is_close_to_the_polygon_form_factor() {
        let mut rnd = crate::shuffle::uniform_sequence(777);
        let mut v = || DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
        let (mut checked, mut near) = (0, 0);
        for _ in 0..4000 {
            let a = parallelogram_root(v() * 20.0, v() * 2.0, v() * 2.0);
            let b = parallelogram_root(v() * 20.0, v() * 2.0, v() * 2.0);
            let (sa, sb) = (Sphere::of_root(&a), Sphere::of_root(&b));
            let Some(estimate) = point_form_factor(&a, &sa, &b, &sb) else {
                near += 1;
                continue;
            };
            let exact = if a.normal.dot(sb.centre - sa.centre) > 0.0 {
                point_polygon_form_factor(sb.centre, b.normal, &a.corners())
            } else {
                0.0
            };
            let scale = a.area_m2 / (std::f64::consts::PI * sa.centre.distance_squared(sb.centre));
            assert!(
                (estimate - exact).abs() <= 0.05 * exact.max(0.3 * scale),
                "estimate {estimate} against {exact} (head-on {scale})"
            );
            checked += 1;
        }
        assert!(checked > 1000 && near > 100, "{checked} far, {near} near");
    }
}
