//! The extended domain of a face (paper section 3, docs/design.md section 4): its minimal-area
//! enclosing parallelogram as a frame `x(s,t) = origin + s*u + t*v`, `(s,t)` in `[0,1]^2`, and the
//! face as a polygon with holes in `(s, t)` with its trapezoidal map.
//!
//! Owns the questions the solver asks of an extended face: [`ExtendedDomain::contains`] (closed
//! face: the boundary is inside, see the trapezoidal map's convention), [`ExtendedDomain::coverage`]
//! of an `(s,t)` box (element status and the quadrature weights' alpha),
//! [`ExtendedDomain::closest_point_on_face`] (the extended visibility `V'(Q,P) = V(Q,P')`, distance
//! measured in world space), and [`ExtendedDomain::segment_hits_face`] (the face as an occluder:
//! plane crossing, parallelogram bounds, trapezoidal map).
//!
//! Invariants: `frame.u x frame.v` points along `normal` (unit) with length the domain's area, so
//! rings keep their orientation in `(s, t)`: `rings[0]` is the outer ring, counter-clockwise, the
//! others are holes, clockwise; every ring vertex lies in `[0,1]^2` (clamped there from a rounding error outside);
//! no ring repeats a vertex consecutively and none is degenerate (all vertices collinear: such
//! rings are dropped, so a face of collinear points is empty). When the rings break the
//! trapezoidal map's contract (crossing after rounding), point location falls back to an exact
//! winding-number test over the rings (O(n) a query; [`ExtendedDomain::uses_trapezoidal_map`]
//! reports it). This is the front side's domain: a back side's frame swaps `u` and `v`, so its
//! `(s, t)` is this domain's `(t, s)`. Units: metres and square metres in world space.

/// Exact point location by winding number (Sunday's crossing rule with exact orientation), the
/// boundary first; inside means a non-zero winding number; a repeated vertex is no edge (as in
/// the trapezoidal map). The face geometry's test, shared with the face validator.
pub use crate::faces::geom::locate_by_winding;

use super::coverage::{box_coverage, Coverage, StBox};
use super::parallelogram::min_area_parallelogram;
use super::predicates::{orient, signed_area};
use super::trapezoidal_map::{Location, MapError, TrapezoidalMap};
use super::{plane_coordinates, Frame};
use glam::{DVec2, DVec3};

/// An intersection point this far outside `[0,1]^2` still reaches the point-location test.
const BOUNDS_MARGIN: f64 = 1e-12;

/// Why an extended domain could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DomainError {
    #[error("a face vertex or the normal is not finite")]
    NonFinite,
    #[error("the face normal is zero")]
    ZeroNormal,
}

/// How `contains` is answered.
#[derive(Debug, Clone)]
enum PointLocator {
    Map(TrapezoidalMap),
    /// The rings broke the map's contract: exact winding numbers over the rings.
    Rings(MapError),
}

/// A face's extended domain.
#[derive(Debug, Clone)]
pub struct ExtendedDomain {
    /// `origin + s*u + t*v`, world space; `u x v` along `normal`.
    pub frame: Frame,
    /// Unit front normal of the face.
    pub normal: DVec3,
    rings: Vec<Vec<DVec2>>,
    locator: PointLocator,
    /// `[u.u, u.v, v.v]`: world distances from `(s, t)` differences.
    gram: [f64; 3],
}

impl ExtendedDomain {
    /// The domain of the face with rings `outer` and `holes` (world space, in the plane through
    /// them with the given front normal; the outer ring is made counter-clockwise and holes
    /// clockwise about it).
    pub fn new(outer: &[DVec3], holes: &[Vec<DVec3>], normal: DVec3) -> Result<Self, DomainError> {
        let all_finite = normal.is_finite()
            && outer
                .iter()
                .chain(holes.iter().flatten())
                .all(|p| p.is_finite());
        if !all_finite {
            return Err(DomainError::NonFinite);
        }
        let normal_len = normal.length();
        if normal_len <= 0.0 || !normal_len.is_finite() {
            return Err(DomainError::ZeroNormal);
        }
        let normal = normal / normal_len;
        // An orthonormal basis (e1, e2) of the plane with e1 x e2 = normal.
        let e1 = longest_edge_direction(outer, normal)
            .unwrap_or_else(|| normal.any_orthonormal_vector());
        let e2 = normal.cross(e1);
        let base = outer.first().copied().unwrap_or(DVec3::ZERO);
        let to_plane = |p: &DVec3| DVec2::new((*p - base).dot(e1), (*p - base).dot(e2));
        let outer2: Vec<DVec2> = outer.iter().map(to_plane).collect();
        let holes2: Vec<Vec<DVec2>> = holes
            .iter()
            .map(|h| h.iter().map(to_plane).collect())
            .collect();
        // Hole vertices join the hull's input: a valid face's holes are inside its outer ring
        // (no change), and an invalid one's still get coordinates in [0,1]^2.
        let all: Vec<DVec2> = outer2
            .iter()
            .chain(holes2.iter().flatten())
            .copied()
            .collect();
        let para = min_area_parallelogram(&all);
        let frame = Frame {
            origin: base + e1 * para.origin.x + e2 * para.origin.y,
            u: e1 * para.u.x + e2 * para.u.y,
            v: e1 * para.v.x + e2 * para.v.y,
        };
        // Vertices on the parallelogram's sides come out a rounding error outside [0,1] (relative
        // to the domain's width: large for slivers), and are clamped onto it.
        let to_st = |p: DVec2| para.coordinates(p).clamp(DVec2::ZERO, DVec2::ONE);
        let mut rings = Vec::with_capacity(1 + holes.len());
        if let Some(ring) = clean_ring(outer2.iter().map(|p| to_st(*p)), true) {
            rings.push(ring);
            for hole in &holes2 {
                if let Some(ring) = clean_ring(hole.iter().map(|p| to_st(*p)), false) {
                    rings.push(ring);
                }
            }
        }
        debug_assert!(rings.iter().all(|r| r.len() >= 3));
        debug_assert!(
            frame.cross().dot(normal) >= 0.0,
            "u x v must not oppose the normal"
        );
        let locator = match TrapezoidalMap::new(&rings) {
            Ok(map) => PointLocator::Map(map),
            Err(e) => PointLocator::Rings(e),
        };
        Ok(ExtendedDomain {
            frame,
            normal,
            rings,
            locator,
            gram: [
                frame.u.dot(frame.u),
                frame.u.dot(frame.v),
                frame.v.dot(frame.v),
            ],
        })
    }

    /// The domain of a polygon with holes given in a plane's own 2D coordinates (the plane z = 0,
    /// normal +z): for tests, benchmarks and hand-made faces.
    pub fn from_plane_polygon(outer: &[DVec2], holes: &[Vec<DVec2>]) -> Result<Self, DomainError> {
        let lift = |r: &[DVec2]| r.iter().map(|p| p.extend(0.0)).collect::<Vec<DVec3>>();
        let holes: Vec<Vec<DVec3>> = holes.iter().map(|h| lift(h)).collect();
        Self::new(&lift(outer), &holes, DVec3::Z)
    }

    /// The face's rings in `(s, t)`: outer counter-clockwise first, then holes clockwise.
    pub fn rings(&self) -> &[Vec<DVec2>] {
        &self.rings
    }

    /// The world point of domain coordinates `st`.
    pub fn world_point(&self, st: DVec2) -> DVec3 {
        self.frame.point(st)
    }

    /// Domain coordinates of the world point `x` projected onto the plane.
    pub fn coordinates(&self, x: DVec3) -> DVec2 {
        plane_coordinates(&self.frame, x)
    }

    /// Area of the parallelogram, m^2.
    pub fn domain_area_m2(&self) -> f64 {
        self.frame.cross().length()
    }

    /// Area of the face from its rings, m^2.
    pub fn face_area_m2(&self) -> f64 {
        let st_area: f64 = self.rings.iter().map(|r| signed_area(r)).sum();
        st_area.max(0.0) * self.domain_area_m2()
    }

    /// Face area over domain area, in `[0, 1]`.
    pub fn fill_ratio(&self) -> f64 {
        let st_area: f64 = self.rings.iter().map(|r| signed_area(r)).sum();
        st_area.clamp(0.0, 1.0)
    }

    /// False when point location fell back to the rings (their map could not be built).
    pub fn uses_trapezoidal_map(&self) -> bool {
        matches!(self.locator, PointLocator::Map(_))
    }

    /// Why the map could not be built, if it could not.
    pub fn map_error(&self) -> Option<MapError> {
        match self.locator {
            PointLocator::Map(_) => None,
            PointLocator::Rings(e) => Some(e),
        }
    }

    /// Where `st` lies relative to the face.
    pub fn locate(&self, st: DVec2) -> Location {
        match &self.locator {
            PointLocator::Map(map) => map.locate(st),
            PointLocator::Rings(_) => locate_by_winding(&self.rings, st),
        }
    }

    /// The closed face contains `st` (inside or on its boundary).
    pub fn contains(&self, st: DVec2) -> bool {
        self.locate(st) != Location::Outside
    }

    /// The face inside the `(s,t)` box `b`: its area (in `(s,t)` units, multiply by
    /// [`Self::domain_area_m2`] for m^2) and the element status.
    pub fn coverage(&self, b: StBox) -> Coverage {
        box_coverage(&self.rings, b, |p| self.contains(p))
    }

    /// The point of the face closest to `st` in world distance (`st` itself when the face contains
    /// it), as domain coordinates: the `P'` of the extended visibility. An empty face returns
    /// `st`. O(n) for a point outside the face.
    pub fn closest_point_on_face(&self, st: DVec2) -> DVec2 {
        self.closest_point_inset(st, 0.0)
    }

    /// As [`Self::closest_point_on_face`], but a point outside the face is brought `inset` metres
    /// inside it, off the boundary (along the inward normals of the edges at the closest point):
    /// a visibility ray must not start on the line where another surface meets the face, where
    /// the ray's first hit would be too close to count. Falls back to the boundary point when the
    /// inset point is not in the face (a sliver narrower than the inset).
    pub fn closest_point_inset(&self, st: DVec2, inset: f64) -> DVec2 {
        if !st.is_finite() || self.contains(st) {
            return st;
        }
        let [uu, uv, vv] = self.gram;
        let dot =
            |a: DVec2, b: DVec2| uu * a.x * b.x + uv * (a.x * b.y + a.y * b.x) + vv * a.y * b.y;
        let mut best = st;
        let mut best_d2 = f64::INFINITY;
        // (ring, edge, lambda) of the closest point.
        let mut at = (0, 0, 0.0);
        for (ri, ring) in self.rings.iter().enumerate() {
            let n = ring.len();
            for i in 0..n {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                let ab = b - a;
                let len2 = dot(ab, ab);
                let lambda = if len2 > 0.0 {
                    (dot(st - a, ab) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let c = a + ab * lambda;
                let d2 = dot(st - c, st - c);
                if d2 < best_d2 {
                    best_d2 = d2;
                    best = c;
                    at = (ri, i, lambda);
                }
            }
        }
        if inset <= 0.0 || !best_d2.is_finite() {
            return best;
        }
        // Inward normals (interior on the left of every ring edge) of the closest edge, and of the
        // edge sharing the vertex when the closest point is a vertex.
        let (ri, i, lambda) = at;
        let ring = &self.rings[ri];
        let n = ring.len();
        // Unit inward normal (world) of edge `e`.
        let inward = |e: usize| -> DVec3 {
            let (a, b) = (ring[e % n], ring[(e + 1) % n]);
            let d = self.frame.u * (b - a).x + self.frame.v * (b - a).y;
            self.normal.cross(d).normalize_or_zero()
        };
        let to_st = |world: DVec3| {
            plane_coordinates(
                &Frame {
                    origin: DVec3::ZERO,
                    ..self.frame
                },
                world,
            )
        };
        let n1 = inward(i);
        // At a vertex (start of edge `i` when `start`): along the sum of the two edges' normals,
        // scaled so the point is `inset` from both edges' lines (an acute corner needs more than
        // the sum), at most 20 insets.
        let corner = |start: bool| -> DVec3 {
            let n2 = if start {
                inward(i + n - 1)
            } else {
                inward(i + 1)
            };
            let sum = n1 + n2;
            let along = sum.dot(n1);
            if along > 0.05 {
                sum * (inset / along)
            } else {
                sum.normalize_or_zero() * inset
            }
        };
        let inside = |p: DVec2| p.is_finite() && self.contains(p);
        // Within 20 insets of a vertex, step in from the vertex: the edge's own normal would come
        // too close to the other edge of an acute corner (or leave the face across it).
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        let world_len = (self.frame.u * (b - a).x + self.frame.v * (b - a).y).length();
        let near_start = lambda * world_len < 20.0 * inset;
        let near_end = (1.0 - lambda) * world_len < 20.0 * inset;
        if near_start || near_end {
            let start = near_start && (!near_end || lambda < 0.5);
            let vertex = if start { a } else { b };
            let from_vertex = vertex + to_st(corner(start));
            if inside(from_vertex) {
                return from_vertex;
            }
        }
        let first = n1 * inset;
        let moved = best + to_st(first);
        if inside(moved) {
            return moved;
        }
        // Shorter steps; the boundary point if nothing is inside.
        let mut step = first;
        for _ in 0..8 {
            step *= 0.5;
            let p = best + to_st(step);
            if inside(p) {
                return p;
            }
        }
        best
    }

    /// The open segment `a -> b` (world space) passes through the face: its endpoints lie strictly
    /// on opposite sides of the face's plane, and the crossing point is in the closed face. A
    /// segment in the plane or ending on it does not hit.
    pub fn segment_hits_face(&self, a: DVec3, b: DVec3) -> bool {
        let da = self.normal.dot(a - self.frame.origin);
        let db = self.normal.dot(b - self.frame.origin);
        if !((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            return false;
        }
        let x = a + (b - a) * (da / (da - db));
        let st = self.coordinates(x);
        let in_bounds = |c: f64| (-BOUNDS_MARGIN..=1.0 + BOUNDS_MARGIN).contains(&c);
        in_bounds(st.x) && in_bounds(st.y) && self.contains(st)
    }
}

/// The unit direction of the longest edge of `ring` projected into the plane of `normal`.
fn longest_edge_direction(ring: &[DVec3], normal: DVec3) -> Option<DVec3> {
    let n = ring.len();
    let mut best: Option<(f64, DVec3)> = None;
    for i in 0..n {
        let d = ring[(i + 1) % n] - ring[i];
        let d = d - normal * normal.dot(d);
        let len = d.length();
        if len > 0.0 && best.is_none_or(|(l, _)| len > l) {
            best = Some((len, d / len));
        }
    }
    best.map(|(_, d)| d)
}

/// The ring without consecutive repeated vertices, oriented counter-clockwise (`outer`) or
/// clockwise; `None` when it has fewer than three distinct vertices or they are all collinear.
fn clean_ring(points: impl Iterator<Item = DVec2>, outer: bool) -> Option<Vec<DVec2>> {
    let mut ring: Vec<DVec2> = Vec::new();
    for p in points {
        if ring.last() != Some(&p) {
            ring.push(p);
        }
    }
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    if ring.len() < 3 {
        return None;
    }
    let (a, b) = (ring[0], ring[1]);
    if ring.iter().all(|&c| orient(a, b, c) == 0.0) {
        return None;
    }
    if (signed_area(&ring) > 0.0) != outer {
        ring.reverse();
    }
    Some(ring)
}
