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
/// does not). A cost and reflection estimate for the ETA, not a transfer: it runs for every
/// receiver of every shot, so it allocates only where the contour integral clips.
pub(super) fn unoccluded_received(ctx: &ShotContext, shooter: usize, power: f64, ri: usize) -> f64 {
    let (sroot, receiver) = (&ctx.roots[shooter], &ctx.roots[ri]);
    let (s, r) = (&ctx.spheres[shooter], &ctx.spheres[ri]);
    let ff = far_field::point_form_factor(sroot, s, receiver, r).unwrap_or_else(|| {
        let polygon = sroot.corners();
        let corners = receiver.corners();
        let points = corners.iter().copied().chain(std::iter::once(r.centre));
        let n = corners.len() as f64 + 1.0;
        points
            .filter(|p| sroot.normal.dot(*p - polygon[0]) > 0.0)
            .map(|p| point_polygon_form_factor(p, receiver.normal, &polygon))
            .sum::<f64>()
            / n
    });
    power / sroot.area_m2 * ff.min(1.0) * receiver.face_area_m2
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
}
