//! Domains: the element roots of every face side (what the solver's bases live on) and the
//! surfaces (one per face side: the frame its lightmap rectangle lives on, and its roots).
//!
//! A triangle or parallelogram face is one native root; any other ("extended") face gets an
//! [`ExtendedDomain`]: its minimal-area enclosing parallelogram, which frames its lightmap, with
//! the face as a polygon with holes in `(s, t)`. In [`DomainMode::Extended`] such a face is one
//! parallelogram root per side on that domain, carrying a [`FaceMask`] (the face inside it); in
//! [`DomainMode::Tessellated`] (the paper's baseline, and the fallback for a face whose domain
//! could not be built) it is one triangle root per triangle of its triangulation. Domains are kept
//! in [`Domains::extended`] either way.
//!
//! A root's frame maps reference coordinates `(s, t)` to world space: `x(s,t) = origin + s*u + t*v`.
//! For a [`Shape::Parallelogram`] `(s,t)` ranges over `[0,1]^2`; for a [`Shape::Triangle`] over
//! `s, t >= 0, s + t <= 1`. Invariant: `u x v` points along the side's normal (the back side of a
//! double-sided face swaps `u` and `v`), so every root emits and receives on the side `u x v` faces.
//!
//! Submodules (the extended-domain geometry, docs/design.md section 4): [`predicates`] (exact
//! orientation, lexicographic order), [`hull`] (convex hull), [`parallelogram`] (minimal-area
//! enclosing parallelogram), [`trapezoidal_map`] (point location), [`coverage`] (face area in a
//! box, element status), [`extended`] ([`ExtendedDomain`]: frame, rings, map and the queries the
//! solver asks). None of them knows faces, scenes or the solver except `extended` (which takes
//! plain rings) and this file.

pub(crate) mod coverage;
pub(crate) mod extended;
pub(crate) mod hull;
pub(crate) mod mask;
pub(crate) mod parallelogram;
pub(crate) mod predicates;
pub(crate) mod reflectance;
pub(crate) mod trapezoidal_map;

#[cfg(test)]
mod tests;

pub use coverage::{Coverage, ElementStatus, StBox};
pub use extended::{DomainError, ExtendedDomain};
pub use mask::FaceMask;
pub use reflectance::{FaceTexture, ReflectanceMap};
pub use trapezoidal_map::{Location, MapError, TrapezoidalMap};

pub use crate::faces::FaceId;
use crate::faces::{Face, FaceKind, FaceSet};
use crate::scene::{Rgb, Scene};
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// The reference shape of an element (and of each of its sub-elements).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    Triangle,
    Parallelogram,
}

/// Which radiosity side of a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Front,
    Back,
}

impl Side {
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Front => "front",
            Side::Back => "back",
        }
    }
}

/// An affine frame `origin + s*u + t*v` in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub origin: DVec3,
    pub u: DVec3,
    pub v: DVec3,
}

impl Frame {
    /// World-space corners of `shape` on this frame (3 or 4), without allocating.
    pub fn corners(&self, shape: Shape) -> Corners {
        let (o, u, v) = (self.origin, self.u, self.v);
        match shape {
            Shape::Triangle => Corners {
                points: [o, o + u, o + v, o],
                len: 3,
            },
            Shape::Parallelogram => Corners {
                points: [o, o + u, o + u + v, o + v],
                len: 4,
            },
        }
    }

    pub fn point(&self, st: DVec2) -> DVec3 {
        self.origin + self.u * st.x + self.v * st.y
    }
    /// `u x v`, of length the parallelogram's area.
    pub fn cross(&self) -> DVec3 {
        self.u.cross(self.v)
    }
}

/// The root of one side's element hierarchy.
#[derive(Debug, Clone)]
pub struct ElementRoot {
    pub face: FaceId,
    pub side: Side,
    pub shape: Shape,
    pub frame: Frame,
    /// Unit normal of this side.
    pub normal: DVec3,
    /// Area of the element (of its shape in world space), m^2: for an extended root, the domain's.
    pub area_m2: f64,
    /// Area of the face this root carries, m^2: `area_m2` for a native root, the face's own
    /// area for an extended one (what emits, and what powers and means are counted over).
    pub face_area_m2: f64,
    /// An extended root (a parallelogram domain larger than its face): the face inside it.
    /// `None` for native triangles and parallelograms, which their element fills.
    pub mask: Option<FaceMask>,
    pub material: u32,
    /// Reflectance: the material's, or for a textured face its mean over the root's face.
    pub rho: Rgb,
    /// Emitted radiosity E = pi * L_e on this side, W/m^2 (for a textured emitter, its mean over
    /// the root's face).
    pub exitance: Rgb,
    /// A face whose reflectance varies (a texture of several colours): its values over the root.
    /// `None` when `rho` holds everywhere.
    pub reflectance: Option<Arc<ReflectanceMap>>,
}

impl ElementRoot {
    /// World-space corners of the root's shape (3 or 4), without allocating: the solver asks
    /// for them for every root in every shot.
    pub fn corners(&self) -> Corners {
        self.frame.corners(self.shape)
    }
}

/// A root's corners in order (3 for a triangle, 4 for a parallelogram); derefs to the slice.
#[derive(Debug, Clone, Copy)]
pub struct Corners {
    points: [DVec3; 4],
    len: usize,
}

impl std::ops::Deref for Corners {
    type Target = [DVec3];
    fn deref(&self) -> &[DVec3] {
        &self.points[..self.len]
    }
}

impl ElementRoot {
    /// Locates world point `x` on this root: its reference coordinates clamped into the shape (for
    /// an extended root, into the face), the distance of `x` from the root's plane, and the
    /// in-plane distance from the shape (from the face).
    pub fn locate(&self, x: DVec3) -> (DVec2, f64, f64) {
        let f = &self.frame;
        let plane_distance = self.normal.dot(x - f.origin);
        let st = plane_coordinates(f, x - self.normal * plane_distance);
        let inside = match &self.mask {
            Some(mask) if st.is_finite() => mask.closest_point(st),
            _ => clamp_to_shape(self.shape, st),
        };
        let outside = (f.point(inside) - f.point(st)).length();
        (inside, plane_distance.abs(), outside)
    }
}

/// Coordinates `(s, t)` of the in-plane point `x` in `frame` (least squares for points off the plane).
pub fn plane_coordinates(f: &Frame, x: DVec3) -> DVec2 {
    let q = x - f.origin;
    let (uu, uv, vv) = (f.u.dot(f.u), f.u.dot(f.v), f.v.dot(f.v));
    let (qu, qv) = (q.dot(f.u), q.dot(f.v));
    let det = uu * vv - uv * uv;
    DVec2::new((qu * vv - qv * uv) / det, (qv * uu - qu * uv) / det)
}

/// The closest point of the reference shape to `st`.
pub fn clamp_to_shape(shape: Shape, st: DVec2) -> DVec2 {
    let c = st.clamp(DVec2::ZERO, DVec2::ONE);
    match shape {
        Shape::Parallelogram => c,
        Shape::Triangle => {
            if c.x + c.y <= 1.0 {
                c
            } else {
                // Project onto s + t = 1 within the segment.
                let d = 0.5 * (c.x + c.y - 1.0);
                DVec2::new(c.x - d, c.y - d).clamp(DVec2::ZERO, DVec2::ONE)
            }
        }
    }
}

/// How faces that are neither triangles nor parallelograms are represented.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DomainMode {
    /// The paper's extended domains: one parallelogram root per side of every extended face,
    /// with the face as its [`FaceMask`].
    #[default]
    Extended,
    /// The paper's baseline: every such face is split into its triangles.
    Tessellated,
}

/// One radiosity side of a face as outputs see it: its frame (the lightmap rectangle's parameter
/// square) and the element roots that carry its radiosity (contiguous in [`Domains::roots`]).
#[derive(Debug, Clone)]
pub struct Surface {
    pub face: FaceId,
    pub side: Side,
    pub kind: FaceKind,
    /// Shape of the frame: a triangle face uses the part `s + t <= 1` of its rectangle.
    pub shape: Shape,
    pub frame: Frame,
    /// The face's own area (not the frame's), m^2.
    pub area_m2: f64,
    pub roots: std::ops::Range<usize>,
}

impl Surface {
    /// Area of the frame's shape (the domain), m^2.
    pub fn domain_area_m2(&self) -> f64 {
        match self.shape {
            Shape::Triangle => 0.5 * self.frame.cross().length(),
            Shape::Parallelogram => self.frame.cross().length(),
        }
    }

    /// The face's area over its domain's (1 for native triangles and parallelograms up to
    /// rounding; 0 for a domain of zero area).
    pub fn fill_ratio(&self) -> f64 {
        let domain = self.domain_area_m2();
        if domain > 0.0 {
            self.area_m2 / domain
        } else {
            0.0
        }
    }
}

/// Element roots and the surfaces they make up.
#[derive(Debug, Clone, Default)]
pub struct Domains {
    pub roots: Vec<ElementRoot>,
    pub surfaces: Vec<Surface>,
    /// Per face id: the extended domain of an extended face (its front side's frame), `None` for
    /// triangles and parallelograms (and for an extended face whose rings are not finite).
    pub extended: Vec<Option<Arc<ExtendedDomain>>>,
}

/// A rectangle in the face's plane enclosing its outer ring, aligned with its longest edge, with
/// `u x v` along `normal`: the frame of an extended face whose domain cannot be built (non-finite
/// rings, which validated faces never have).
fn enclosing_rectangle(outer: &[DVec3], normal: DVec3) -> Frame {
    let mut e1 = DVec3::X;
    let mut longest = -1.0;
    for i in 0..outer.len() {
        let d = outer[(i + 1) % outer.len()] - outer[i];
        if d.length() > longest {
            longest = d.length();
            e1 = d / d.length();
        }
    }
    let e2 = normal.cross(e1);
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in outer {
        let q = DVec2::new((*p - outer[0]).dot(e1), (*p - outer[0]).dot(e2));
        lo = lo.min(q);
        hi = hi.max(q);
    }
    Frame {
        origin: outer[0] + e1 * lo.x + e2 * lo.y,
        u: e1 * (hi.x - lo.x),
        v: e2 * (hi.y - lo.y),
    }
}

/// The face's own frame and shape (before any side flip); `domain` is the extended face's domain.
fn face_frame(face: &Face, domain: Option<&ExtendedDomain>) -> (Shape, Frame) {
    match face.kind {
        FaceKind::Triangle => {
            let [a, b, c] = [face.outer[0], face.outer[1], face.outer[2]];
            (
                Shape::Triangle,
                Frame {
                    origin: a,
                    u: b - a,
                    v: c - a,
                },
            )
        }
        FaceKind::Parallelogram => {
            let a = face.outer[0];
            (
                Shape::Parallelogram,
                Frame {
                    origin: a,
                    u: face.outer[1] - a,
                    v: face.outer[3] - a,
                },
            )
        }
        FaceKind::Extended => (
            Shape::Parallelogram,
            match domain {
                Some(d) => d.frame,
                None => enclosing_rectangle(&face.outer, face.normal),
            },
        ),
    }
}

/// The frame of a root of the given side: the back side swaps `u` and `v` so `u x v` keeps facing
/// the side's normal.
fn sided(frame: Frame, side: Side) -> Frame {
    match side {
        Side::Front => frame,
        Side::Back => Frame {
            origin: frame.origin,
            u: frame.v,
            v: frame.u,
        },
    }
}

/// Builds the element roots and surfaces: per face side (front before back, in face id order),
/// one native root for a triangle or parallelogram face, else one triangle root per triangle of
/// the face's triangulation; every extended face's surface is framed by its extended domain's
/// parallelogram, and the domain is kept in [`Domains::extended`].
pub fn build_domains(scene: &Scene, faces: &FaceSet, mode: DomainMode) -> Domains {
    let mut domains = Domains::default();
    let inset = mask::VISIBILITY_INSET_REL * scene.diagonal();
    // Roots of faces whose reflectance varies, with their face's texture.
    let mut varying: Vec<(usize, Arc<FaceTexture>)> = Vec::new();
    for face in &faces.faces {
        let material = &scene.materials[face.material as usize];
        let texture = FaceTexture::new(scene, faces, face);
        // A texture of one colour over the whole face is exact as constants.
        let (rho, emission) = match texture.as_ref().and_then(FaceTexture::uniform) {
            Some(values) => values,
            None => (material.rho, material.emission),
        };
        let texture = texture.filter(|t| t.uniform().is_none()).map(Arc::new);
        let extended = match face.kind {
            FaceKind::Extended => ExtendedDomain::new(&face.outer, &face.holes, face.normal)
                .ok()
                .map(Arc::new),
            FaceKind::Triangle | FaceKind::Parallelogram => None,
        };
        let (shape, frame) = face_frame(face, extended.as_deref());
        // In extended mode an extended face is one root on its domain.
        let masked = extended
            .clone()
            .filter(|d| mode == DomainMode::Extended && d.face_area_m2() > 0.0);
        domains.extended.push(extended);
        let sides: &[Side] = if face.double_sided {
            &[Side::Front, Side::Back]
        } else {
            &[Side::Front]
        };
        for &side in sides {
            let normal = if side == Side::Front {
                face.normal
            } else {
                -face.normal
            };
            let first = domains.roots.len();
            let mut push_root = |shape: Shape, frame: Frame, mask: Option<FaceMask>| {
                let frame = sided(frame, side);
                let area = match shape {
                    Shape::Triangle => 0.5 * frame.cross().length(),
                    Shape::Parallelogram => frame.cross().length(),
                };
                // An extended root's face area from its rings (what the mask's coverage
                // integrates to), so powers and means agree with coverage.
                let face_area = mask.as_ref().map_or(area, |m| m.domain().face_area_m2());
                if let Some(t) = &texture {
                    // Its map is read after every root is built, in parallel.
                    varying.push((domains.roots.len(), t.clone()));
                }
                let exitance = emission.map(|e| std::f64::consts::PI * e);
                domains.roots.push(ElementRoot {
                    face: face.id,
                    side,
                    shape,
                    frame,
                    normal,
                    area_m2: area,
                    face_area_m2: face_area,
                    mask,
                    material: face.material,
                    rho,
                    exitance,
                    reflectance: None,
                });
            };
            match (face.kind, &masked) {
                (FaceKind::Triangle | FaceKind::Parallelogram, _) => push_root(shape, frame, None),
                (FaceKind::Extended, Some(domain)) => push_root(
                    shape,
                    frame,
                    Some(FaceMask::new(domain.clone(), side == Side::Back, inset)),
                ),
                (FaceKind::Extended, None) => {
                    for [a, b, c] in &face.triangulation {
                        push_root(
                            Shape::Triangle,
                            Frame {
                                origin: *a,
                                u: *b - *a,
                                v: *c - *a,
                            },
                            None,
                        );
                    }
                }
            }
            domains.surfaces.push(Surface {
                face: face.id,
                side,
                kind: face.kind,
                shape,
                frame: sided(frame, side),
                area_m2: face.area_m2,
                roots: first..domains.roots.len(),
            });
        }
    }
    read_reflectance_maps(&mut domains.roots, varying, scene.diagonal());
    domains
}

/// A reflectance raster's cells are at least this fraction of the scene's diagonal: finer detail
/// of a texture does not move the light, and a tiled texture would otherwise give every small
/// face of a level a full raster.
pub const RASTER_CELL_REL: f64 = 1.0 / 512.0;

/// Reads the reflectance maps of the roots whose face's texture varies (in parallel), and sets
/// their `rho` and `exitance` to the maps' means.
fn read_reflectance_maps(
    roots: &mut [ElementRoot],
    varying: Vec<(usize, Arc<FaceTexture>)>,
    diagonal: f64,
) {
    use rayon::prelude::*;
    let maps: Vec<(usize, Option<(ReflectanceMap, Rgb)>)> = varying
        .into_par_iter()
        .map(|(i, texture)| {
            let r = &roots[i];
            let extent = r.frame.u.length().max(r.frame.v.length());
            let max_cells = (extent / (RASTER_CELL_REL * diagonal)).ceil();
            let map = ReflectanceMap::new(texture, &r.frame, max_cells, |st| {
                match (&r.mask, r.shape) {
                    (Some(m), _) => m.contains(st),
                    (None, Shape::Triangle) => st.x + st.y <= 1.0,
                    (None, Shape::Parallelogram) => true,
                }
            });
            (i, map)
        })
        .collect();
    for (i, map) in maps {
        if let Some((map, emission)) = map {
            let r = &mut roots[i];
            r.rho = map.mean;
            r.exitance = emission.map(|e| std::f64::consts::PI * e);
            r.reflectance = Some(Arc::new(map));
        }
    }
}
