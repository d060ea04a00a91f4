//! The world geometry of one element of a root: its [`Patch`] (origin, edges, area), the points
//! that receive and cast rays for it (`visibility_point`, `receiving_point`: off an extended face,
//! the closest point on the face), and the [`Emitter`] whose exact form factor it has (its own
//! polygon, or the face inside a partly covered element, as world rings) and a bound on it that
//! needs no contour integral ([`FormFactorBound`]).
//!
//! Invariant: an extended root's points always receive and see through their stand-ins on the
//! face (`V'(Q,P) = V(Q,P')`), in visibility and kernel alike, so the extension is continuous
//! across the face's border.

use super::basis::ChildMap;
use super::cover::{node_box, NodeCover};
use super::kernel;
use crate::domain::{Corners, ElementRoot, ElementStatus, Frame, Shape};
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// The world point that stands in for root point `map(st)` in visibility queries: the point itself
/// on a native root or on the face; else its closest point on the face (`V'(Q,P) = V(Q,P')`).
pub(super) fn visibility_point(root: &ElementRoot, map: &ChildMap, st: DVec2) -> DVec3 {
    let p = map.apply(st);
    match &root.mask {
        Some(mask) => root.frame.point(mask.closest_point(p)),
        None => root.frame.point(p),
    }
}

/// Where quadrature point `k` (at `st`) of receiver element `patch` of `root` receives light: the
/// point itself, or, off an extended face, its stand-in (`cover.visibility_point`, the closest
/// point on the face), in visibility and kernel alike. The extension is then continuous across the
/// face's border: with the kernel at the point itself, a wall standing on the border inside the
/// domain is seen from behind on one side of it and from the front on the other, and elements
/// straddling the border average the two.
pub(super) fn receiving_point(
    root: &ElementRoot,
    patch: &Patch,
    cover: Option<&NodeCover>,
    k: usize,
    st: DVec2,
) -> DVec3 {
    match cover {
        Some(c) => root.frame.point(c.visibility_point[k]),
        None => patch.point(st),
    }
}

/// A sphere around a set of points: centred on their mean, through the farthest.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sphere {
    pub centre: DVec3,
    pub radius: f64,
}

impl Sphere {
    pub fn around(points: &[DVec3]) -> Self {
        debug_assert!(!points.is_empty());
        let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
        let radius = points
            .iter()
            .map(|c| c.distance(centre))
            .fold(0.0, f64::max);
        Sphere { centre, radius }
    }

    /// The sphere around a root's corners (its whole domain for an extended root).
    pub fn of_root(root: &ElementRoot) -> Self {
        Self::around(&root.corners())
    }
}

/// What a source element emits from: its own shape, or the face inside it; on its front side only.
pub(super) struct Emitter {
    shape: EmitterShape,
    /// The element's corners and their bounding sphere (a partly covered element's face lies
    /// inside them).
    corners: Corners,
    sphere: Sphere,
    /// A point of the source's plane and its unit normal (the emitting side).
    origin: DVec3,
    normal: DVec3,
}

enum EmitterShape {
    /// The element's own polygon.
    Polygon,
    Rings(Arc<FaceRings>),
}

/// The face inside a partly covered element, as world-space rings (see `FaceMask::clip`).
pub(super) type FaceRings = Vec<Vec<DVec3>>;

/// The face rings of element `map` of `root` when the element is partly covered (computed once per
/// source element, not per transfer: clipping is O(n) in the face's edges).
pub(super) fn partial_face_rings(
    root: &ElementRoot,
    map: &ChildMap,
    cover: Option<&NodeCover>,
) -> Option<Arc<FaceRings>> {
    match (&root.mask, cover) {
        (Some(mask), Some(c)) if c.status == ElementStatus::Partial => {
            Some(world_rings(root, &mask.clip(node_box(map))))
        }
        _ => None,
    }
}

/// Rings in `root`'s `(s,t)` as world-space rings.
pub(super) fn world_rings(root: &ElementRoot, rings: &[Vec<DVec2>]) -> Arc<FaceRings> {
    Arc::new(
        rings
            .iter()
            .map(|r| r.iter().map(|p| root.frame.point(*p)).collect())
            .collect(),
    )
}

impl Emitter {
    pub(super) fn new(root: &ElementRoot, patch: &Patch, rings: Option<&Arc<FaceRings>>) -> Self {
        let shape = match rings {
            Some(r) => EmitterShape::Rings(r.clone()),
            None => EmitterShape::Polygon,
        };
        let corners = patch.corners(root.shape);
        let sphere = Sphere::around(&corners);
        Emitter {
            shape,
            corners,
            sphere,
            origin: patch.origin,
            normal: root.normal,
        }
    }

    /// Exact unoccluded form factor from a differential area at `x` (normal `n`): zero behind the
    /// source's plane, which a one-sided emitter does not light (a receiver element, or an
    /// extended domain, may reach behind a source it otherwise faces).
    pub(super) fn form_factor(&self, x: DVec3, n: DVec3) -> f64 {
        if self.normal.dot(x - self.origin) <= 0.0 {
            return 0.0;
        }
        match &self.shape {
            EmitterShape::Polygon => kernel::point_polygon_form_factor(x, n, &self.corners),
            EmitterShape::Rings(r) => kernel::point_rings_form_factor(x, n, r),
        }
    }

    /// Is `x` (normal `n`) in front of the source's plane, at least `radii` times the radius of
    /// the element's corners' sphere from its centre, with every corner in front of `x`'s tangent
    /// plane? The kernel is then smooth over the element, and its rule's sum within
    /// [`kernel::rule_suffices_radii`]'s promise of the element's own form factor.
    pub(super) fn far_in_front(&self, x: DVec3, n: DVec3, radii: f64) -> bool {
        self.normal.dot(x - self.origin) > 0.0
            && x.distance_squared(self.sphere.centre) >= (radii * self.sphere.radius).powi(2)
            && self.corners.iter().all(|c| n.dot(*c - x) >= 0.0)
    }

    /// Does the source's quadrature rule give the form factor at `x` (normal `n`) as closely as
    /// [`kernel::rule_suffices_radii`] promises? When [`Emitter::far_in_front`] (where the
    /// tangent plane cuts the source, only the exact contour integral is right). Never for the
    /// face inside a partly covered element: its rule is weighted by coverage, and the exact
    /// form factor is what corrects it (a far link, whose whole transfer is within the
    /// threshold, takes the rule's sum there too: `ElementSource::far_irradiance_at`).
    pub(super) fn rule_suffices(&self, x: DVec3, n: DVec3, radii: f64) -> bool {
        matches!(self.shape, EmitterShape::Polygon) && self.far_in_front(x, n, radii)
    }
}

/// An upper bound on the unoccluded form factor ([`Emitter::form_factor`]) from a differential
/// area to any part of one patch (the whole patch, or the face inside it), from the patch's
/// plane, its corners' sphere and its area alone: no contour integral. The kernel
/// `cos_x cos_p / (pi r^2)` at a patch point `p` is `(n . (p - x)) h / (pi r^4)`, `h` the
/// height of `x` over the plane, with `r` at least the distance `d` from `x` to the sphere and
/// `n . (p - x)` at most `n . (c - x) + radius`. Pinned by
/// `tests::the_form_factor_bound_is_never_below_the_form_factor`.
pub(super) struct FormFactorBound {
    normal: DVec3,
    origin: DVec3,
    sphere: Sphere,
    area: f64,
}

impl FormFactorBound {
    pub(super) fn new(root: &ElementRoot, patch: &Patch) -> Self {
        FormFactorBound {
            normal: root.normal,
            origin: patch.origin,
            sphere: Sphere::around(&patch.corners(root.shape)),
            area: patch.area,
        }
    }

    /// The bound at `x` (normal `n`): 0 behind the plane (as the form factor), infinite where
    /// `x` lies in the sphere.
    pub(super) fn at(&self, x: DVec3, n: DVec3) -> f64 {
        let height = self.normal.dot(x - self.origin);
        if height <= 0.0 {
            return 0.0;
        }
        let d = x.distance(self.sphere.centre) - self.sphere.radius;
        if d <= 0.0 {
            return f64::INFINITY;
        }
        let facing = (n.dot(self.sphere.centre - x) + self.sphere.radius).max(0.0);
        self.area * height * facing / (std::f64::consts::PI * d.powi(4))
    }
}

/// World geometry of a sub-element given its map in the root's reference coordinates.
#[derive(Debug, Clone, Copy)]
pub(super) struct Patch {
    pub(super) origin: DVec3,
    pub(super) u: DVec3,
    pub(super) v: DVec3,
    pub(super) area: f64,
}

impl Patch {
    pub(super) fn new(root: &ElementRoot, map: &ChildMap) -> Self {
        let f = &root.frame;
        let origin = f.point(map.o);
        let u = f.u * map.e1.x + f.v * map.e1.y;
        let v = f.u * map.e2.x + f.v * map.e2.y;
        let full = u.cross(v).length();
        let area = match root.shape {
            Shape::Triangle => 0.5 * full,
            Shape::Parallelogram => full,
        };
        Patch { origin, u, v, area }
    }
    pub(super) fn point(&self, st: DVec2) -> DVec3 {
        self.origin + self.u * st.x + self.v * st.y
    }
    pub(super) fn corners(&self, shape: Shape) -> Corners {
        let (origin, u, v) = (self.origin, self.u, self.v);
        Frame { origin, u, v }.corners(shape)
    }
    pub(super) fn min_edge(&self) -> f64 {
        self.u.length().min(self.v.length())
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::domain::{FaceId, Side};

    /// A native parallelogram at `origin` with sides `u` and `v` (facing `u x v`), face 0,
    /// reflectance 0.5, not emitting.
    pub(in crate::solver) fn parallelogram_root(origin: DVec3, u: DVec3, v: DVec3) -> ElementRoot {
        let cross = u.cross(v);
        ElementRoot {
            face: FaceId(0),
            side: Side::Front,
            shape: Shape::Parallelogram,
            frame: Frame { origin, u, v },
            normal: cross.normalize(),
            area_m2: cross.length(),
            face_area_m2: cross.length(),
            mask: None,
            material: 0,
            rho: [0.5; 3],
            exitance: [0.0; 3],
            reflectance: None,
        }
    }

    /// The bound is at or above the exact form factor wherever it is finite, on whole patches and
    /// on the face inside a partly covered one, at random points near and far (in front of the
    /// patch and behind it) with random normals; and finite beyond the patch's sphere.
    #[test]
    fn the_form_factor_bound_is_never_below_the_form_factor() {
        let mut rnd = crate::shuffle::uniform_sequence(23);
        let mut compared = 0;
        for case in 0..400 {
            let v =
                |rnd: &mut dyn FnMut() -> f64| DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            let (u, w) = (v(&mut rnd) * 3.0, v(&mut rnd) * 3.0);
            let mut root = parallelogram_root(v(&mut rnd), u, w);
            if case % 2 == 1 {
                root.shape = Shape::Triangle;
            }
            let map = ChildMap::IDENTITY;
            let patch = Patch::new(&root, &map);
            // Every fourth case, a small triangle of the patch (9 % of it) as rings.
            let rings = (case % 4 == 2).then(|| {
                let ring = [
                    DVec2::new(0.1, 0.1),
                    DVec2::new(0.6, 0.2),
                    DVec2::new(0.3, 0.5),
                ];
                world_rings(&root, &[ring.to_vec()])
            });
            let emitter = Emitter::new(&root, &patch, rings.as_ref());
            let bound = FormFactorBound::new(&root, &patch);
            for _ in 0..20 {
                let scale = [0.5, 2.0, 10.0, 50.0][(rnd() * 4.0) as usize];
                let x = patch.origin + v(&mut rnd) * scale;
                let n = v(&mut rnd).normalize();
                let (f, b) = (emitter.form_factor(x, n), bound.at(x, n));
                assert!(b >= f * (1.0 - 1e-9), "bound {b} under {f} at {x} {n}");
                if x.distance(bound.sphere.centre) > bound.sphere.radius {
                    assert!(b.is_finite());
                }
                compared += usize::from(b.is_finite() && f > 0.0);
            }
        }
        assert!(compared > 1000, "{compared}");
    }

    /// A native unit square in the plane z = 0, facing +z.
    fn unit_square() -> ElementRoot {
        parallelogram_root(DVec3::ZERO, DVec3::X, DVec3::Y)
    }

    /// The rule stands in for the contour integral only far enough (in radii of the corners'
    /// sphere, `sqrt(1/2)` here), in front of the source, with the whole source in front of the
    /// receiving point's tangent plane; never for a face given as rings, which is far in front
    /// by the same test (a far link takes the rule's sum there).
    #[test]
    fn the_rule_stands_in_only_far_in_front_and_never_for_rings() {
        let root = unit_square();
        let patch = Patch::new(&root, &ChildMap::IDENTITY);
        let emitter = Emitter::new(&root, &patch, None);
        let (above, down) = (|z: f64| DVec3::new(0.5, 0.5, z), -DVec3::Z);
        let radius = 0.5f64.sqrt();
        assert!(emitter.rule_suffices(above(4.0 * radius + 1e-9), down, 4.0));
        assert!(!emitter.rule_suffices(above(4.0 * radius - 1e-9), down, 4.0));
        // Behind the source's plane.
        assert!(!emitter.rule_suffices(above(-10.0), DVec3::Z, 4.0));
        // Tilted so that the corners at x = 0 fall behind the point's tangent plane.
        let tilted = DVec3::new(1.0, 0.0, -0.01).normalize();
        assert!(!emitter.rule_suffices(above(10.0), tilted, 4.0));
        // The same square as a ring: the exact form factor at any distance.
        let corners = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        let rings = world_rings(&root, &[corners.to_vec()]);
        let ringed = Emitter::new(&root, &patch, Some(&rings));
        assert!(!ringed.rule_suffices(above(1e3), down, 4.0));
        // Though as far in front (what a far link asks), by the element's own corners.
        assert!(ringed.far_in_front(above(4.0 * radius + 1e-9), down, 4.0));
        assert!(!ringed.far_in_front(above(4.0 * radius - 1e-9), down, 4.0));
        assert!(!ringed.far_in_front(above(10.0), tilted, 4.0));
        // Both give the same exact form factor.
        let x = above(3.0);
        assert!((ringed.form_factor(x, down) - emitter.form_factor(x, down)).abs() < 1e-15);
    }
}
