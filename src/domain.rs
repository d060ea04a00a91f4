//! Domains: one element root per radiosity side of each face, with the frame the solver's basis
//! functions and the lightmap live on.
//!
//! A root's frame maps reference coordinates `(s, t)` to world space: `x(s,t) = origin + s*u + t*v`.
//! For a [`Shape::Parallelogram`] `(s,t)` ranges over `[0,1]^2`; for a [`Shape::Triangle`] over
//! `s, t >= 0, s + t <= 1`. Invariant: `u x v` points along the side's normal (the back side of a
//! double-sided face swaps `u` and `v`), so every root emits and receives on the side `u x v` faces.
//! Extended domains (a parallelogram with a face mask) come with the extended-domains issue.

use crate::faces::{Face, FaceId, FaceKind, FaceSet};
use crate::scene::{Rgb, Scene};
use glam::{DVec2, DVec3};

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
    /// Area of the element (of its shape in world space), m^2.
    pub area_m2: f64,
    pub material: u32,
    pub rho: Rgb,
    /// Emitted radiosity E = pi * L_e on this side, W/m^2.
    pub exitance: Rgb,
}

impl ElementRoot {
    /// World-space corners of the root's shape (3 or 4).
    pub fn corners(&self) -> Vec<DVec3> {
        let f = &self.frame;
        match self.shape {
            Shape::Triangle => vec![f.origin, f.origin + f.u, f.origin + f.v],
            Shape::Parallelogram => vec![
                f.origin,
                f.origin + f.u,
                f.origin + f.u + f.v,
                f.origin + f.v,
            ],
        }
    }
}

fn frame_of(face: &Face) -> (Shape, Frame) {
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
        // Parallelograms (and, until extended domains exist, anything else with 4 corners).
        _ => {
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
    }
}

/// Builds the element roots: one per face side, front before back, in face id order.
pub fn build_roots(scene: &Scene, faces: &FaceSet) -> Vec<ElementRoot> {
    let mut roots = Vec::with_capacity(faces.faces.len());
    for face in &faces.faces {
        let material = &scene.materials[face.material as usize];
        let (shape, frame) = frame_of(face);
        let area = match shape {
            Shape::Triangle => 0.5 * frame.cross().length(),
            Shape::Parallelogram => frame.cross().length(),
        };
        let exitance = material.emission.map(|e| std::f64::consts::PI * e);
        roots.push(ElementRoot {
            face: face.id,
            side: Side::Front,
            shape,
            frame,
            normal: face.normal,
            area_m2: area,
            material: face.material,
            rho: material.rho,
            exitance,
        });
        if face.double_sided {
            let back = Frame {
                origin: frame.origin,
                u: frame.v,
                v: frame.u,
            };
            roots.push(ElementRoot {
                face: face.id,
                side: Side::Back,
                shape,
                frame: back,
                normal: -face.normal,
                area_m2: area,
                material: face.material,
                rho: material.rho,
                exitance,
            });
        }
    }
    roots
}
