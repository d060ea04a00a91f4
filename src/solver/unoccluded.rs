//! What one root could send another with no occluder: whether they face each other at all, and
//! the power one would receive of what the other sends. A shot's plan asks it of every root
//! (`pass.rs`), and so does the indirect forecast (`forecast_inputs.rs`): it allocates only where
//! the shooter crosses a receiving point's tangent plane (the contour integral's clipping).
//!
//! Invariant: a pass visits only the receivers that face one of its shooters, and two roots that
//! do not face each other exchange no light, so a pass may take such roots together.

use super::element::Sphere;
use super::far_field;
use super::kernel::point_polygon_form_factor;
use super::refine::ShotContext;
use crate::domain::ElementRoot;
use glam::DVec3;

/// The power root `ri` would get from root `shooter` sending `power` W evenly over its domain
/// with no occluder: its face area times a form factor to the shooter's domain. A far receiver
/// takes the point estimate at its centre (`far_field::point_form_factor`); a near one the form
/// factor averaged over its centre and corners (one of them may see the shooter when the centre
/// does not), or at its centre alone when it takes the shot as one far link (`far_link`: the
/// most it can receive is within the oracle's threshold, and where the two bounding spheres
/// are apart so is the centre's estimate, every point of the shooter lying at least as far from
/// it as from the receiver's sphere). A cost and reflection estimate for the ETA, not a
/// transfer: it runs for every receiver of every shot, so it allocates only where the contour
/// integral clips.
pub(super) fn unoccluded_received(
    ctx: &ShotContext,
    shooter: usize,
    power: f64,
    ri: usize,
    far_link: bool,
) -> f64 {
    let (sroot, receiver) = (&ctx.roots[shooter], &ctx.roots[ri]);
    let (s, r) = (&ctx.spheres[shooter], &ctx.spheres[ri]);
    let ff = far_field::point_form_factor(sroot, s, receiver, r)
        .unwrap_or_else(|| near_form_factor(sroot, receiver, r.centre, far_link));
    power / sroot.area_m2 * ff.min(1.0) * receiver.face_area_m2
}

/// The form factor from `receiver` to `shooter`'s domain with no occluder: at `centre` alone
/// (`centre_only`), else averaged over the receiver's corners and `centre` (summed in that
/// order, as the plan always did); 0 at a point behind the shooter's plane.
fn near_form_factor(
    shooter: &ElementRoot,
    receiver: &ElementRoot,
    centre: DVec3,
    centre_only: bool,
) -> f64 {
    let polygon = shooter.corners();
    let at = |p: DVec3| {
        if shooter.normal.dot(p - polygon[0]) > 0.0 {
            point_polygon_form_factor(p, receiver.normal, &polygon)
        } else {
            0.0
        }
    };
    if centre_only {
        return at(centre);
    }
    let corners = receiver.corners();
    let n = corners.len() as f64 + 1.0;
    (corners.iter().map(|&p| at(p)).sum::<f64>() + at(centre)) / n
}

/// Can any point of `a` (front side) see any point of `b` (front side)? Some corner of each lies
/// in front of the other's plane (by more than `eps`). `sa` and `sb` are the roots' bounding
/// spheres (`Sphere::of_root`): a root whose sphere lies wholly behind the other's plane has no
/// corner in front of it, which decides most pairs before any corner is computed (the plan asks
/// for every root of every shot). `tests::the_spheres_decide_as_the_corners_do`.
pub(super) fn faces_each_other(
    a: &ElementRoot,
    sa: &Sphere,
    b: &ElementRoot,
    sb: &Sphere,
    eps: f64,
) -> bool {
    let behind = |n: DVec3, o: DVec3, s: &Sphere| n.dot(s.centre - o) + s.radius < 0.0;
    if behind(a.normal, a.frame.origin, sb) || behind(b.normal, b.frame.origin, sa) {
        return false;
    }
    faces_each_other_by_corners(a, b, eps)
}

/// [`faces_each_other`] from the corners alone.
fn faces_each_other_by_corners(a: &ElementRoot, b: &ElementRoot, eps: f64) -> bool {
    let ca = a.corners();
    let cb = b.corners();
    let b_in_front_of_a = cb.iter().any(|p| a.normal.dot(*p - ca[0]) > eps);
    let a_in_front_of_b = ca.iter().any(|p| b.normal.dot(*p - cb[0]) > eps);
    b_in_front_of_a && a_in_front_of_b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::Shape;
    use crate::solver::element::tests::parallelogram_root;

    /// The sphere test decides as the corners do, for random pairs of parallelograms and
    /// triangles in every orientation, many of them touching or crossing.
    #[test]
    fn the_spheres_decide_as_the_corners_do() {
        let mut rnd = crate::shuffle::uniform_sequence(77);
        let mut vector = |scale: f64| DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * scale;
        let (mut facing, mut apart, mut by_spheres) = (0, 0, 0);
        for i in 0..20_000 {
            let mut root = |shape| {
                let mut r = parallelogram_root(vector(4.0), vector(2.0), vector(2.0));
                r.shape = shape;
                r
            };
            let shapes = [Shape::Parallelogram, Shape::Triangle];
            let (a, b) = (root(shapes[i % 2]), root(shapes[i / 2 % 2]));
            let (sa, sb) = (Sphere::of_root(&a), Sphere::of_root(&b));
            let eps = 1e-9;
            let expected = faces_each_other_by_corners(&a, &b, eps);
            let behind = |n: DVec3, o: DVec3, s: &Sphere| n.dot(s.centre - o) + s.radius < 0.0;
            if behind(a.normal, a.frame.origin, &sb) || behind(b.normal, b.frame.origin, &sa) {
                by_spheres += 1;
            }
            assert_eq!(
                faces_each_other(&a, &sa, &b, &sb, eps),
                expected,
                "pair {i}"
            );
            if expected {
                facing += 1;
            } else {
                apart += 1;
            }
        }
        assert!(
            facing > 2_000 && apart > 2_000,
            "{facing} facing, {apart} not"
        );
        assert!(
            by_spheres > 1_000,
            "{by_spheres} pairs decided by the spheres"
        );
    }

    /// [`near_form_factor`]: a far link's receiver is estimated by the form factor at its centre
    /// alone; any other by the mean over its corners and centre, a point behind the shooter's
    /// plane counting 0. A 4 m square shooter on the floor and receivers facing it from 0.5 to 3 m
    /// above, 2 cm to 1 m wide: the centre alone is within 1 % of the mean where the receiver is
    /// under a tenth of its height across, and the two differ for the largest ones (the
    /// estimate changes where it should).
    #[test]
    fn a_far_link_receiver_is_estimated_at_its_centre() {
        let shooter = parallelogram_root(DVec3::ZERO, DVec3::X * 4.0, DVec3::Y * 4.0);
        let polygon = shooter.corners();
        let mut rnd = crate::shuffle::uniform_sequence(17);
        let mut apart = 0;
        for i in 0..2000 {
            let size = [0.02, 0.1, 0.3, 1.0][i % 4];
            let height = 0.5 + 2.5 * rnd();
            let corner = DVec3::new(6.0 * rnd() - 1.0, 6.0 * rnd() - 1.0, height);
            // Facing down onto the shooter (u x v along -z).
            let receiver = parallelogram_root(corner, DVec3::Y * size, DVec3::X * size);
            let centre = Sphere::of_root(&receiver).centre;
            let at_centre = point_polygon_form_factor(centre, receiver.normal, &polygon);
            assert_eq!(
                near_form_factor(&shooter, &receiver, centre, true),
                at_centre
            );
            let corners = receiver.corners();
            let mean = (corners
                .iter()
                .map(|&p| point_polygon_form_factor(p, receiver.normal, &polygon))
                .sum::<f64>()
                + at_centre)
                / 5.0;
            let five = near_form_factor(&shooter, &receiver, centre, false);
            assert!((five - mean).abs() <= 1e-12 * mean, "{five} against {mean}");
            if size < 0.1 * height {
                assert!(
                    (at_centre - mean).abs() <= 0.01 * mean,
                    "{size} m at {height} m: {at_centre} against {mean}"
                );
            }
            if (at_centre - mean).abs() > 0.05 * mean {
                apart += 1;
            }
        }
        assert!(
            apart > 20,
            "{apart} large receivers where the two estimates differ"
        );
        // A corner behind the shooter's plane counts 0 in the mean.
        let straddling = parallelogram_root(DVec3::new(1.0, 1.0, -0.5), DVec3::Z, DVec3::X);
        let centre = Sphere::of_root(&straddling).centre;
        let front: f64 = straddling
            .corners()
            .iter()
            .chain([centre].iter())
            .filter(|p| p.z > 0.0)
            .map(|&p| point_polygon_form_factor(p, straddling.normal, &polygon))
            .sum();
        let five = near_form_factor(&shooter, &straddling, centre, false);
        assert!((five - front / 5.0).abs() <= 1e-12 * front.max(1e-300));
    }
}
