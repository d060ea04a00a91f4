//! Faces: the planar surfaces the solver sees, built from the scene's triangles.
//!
//! This first version makes one face per non-degenerate triangle (planar-face merging, rings with
//! holes and the parallelogram test come with the planar-faces issue). The types already carry what
//! merged faces need: an outer ring, hole rings and the triangles a face came from.
//!
//! Invariants: face ids are `0..faces.len()`, in order; `outer` is counter-clockwise about `normal`
//! (unit); `area` is the sum of the areas of `triangles`; degenerate triangles are in no face.

use crate::scene::Scene;
use glam::DVec3;

/// Index of a face in [`FaceSet::faces`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FaceId(pub u32);

/// How the solver represents a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaceKind {
    Triangle,
    Parallelogram,
    Extended,
}

impl FaceKind {
    pub fn as_str(self) -> &'static str {
        match self {
            FaceKind::Triangle => "triangle",
            FaceKind::Parallelogram => "parallelogram",
            FaceKind::Extended => "extended",
        }
    }
}

/// A planar face: one material, one plane, an outer ring and holes.
#[derive(Debug, Clone)]
pub struct Face {
    pub id: FaceId,
    pub material: u32,
    pub double_sided: bool,
    pub kind: FaceKind,
    /// Unit front normal (counter-clockwise winding).
    pub normal: DVec3,
    /// Area in m^2: the sum of the areas of the triangles it came from.
    pub area_m2: f64,
    /// Outer ring, counter-clockwise about `normal`.
    pub outer: Vec<DVec3>,
    /// Hole rings, clockwise about `normal`.
    pub holes: Vec<Vec<DVec3>>,
    /// Indices into `Scene::triangles` of the triangles merged into this face.
    pub triangles: Vec<u32>,
}

/// The faces of a scene with the import counts.
#[derive(Debug, Clone)]
pub struct FaceSet {
    pub faces: Vec<Face>,
    pub triangles_in: usize,
    pub degenerate_dropped: usize,
    /// For each scene triangle, the face it belongs to (`None` when dropped as degenerate).
    pub face_of_triangle: Vec<Option<FaceId>>,
}

/// A triangle whose area is below this fraction of the squared scene diagonal is degenerate.
pub const DEGENERATE_AREA_REL: f64 = 1e-14;

/// Builds the faces of a scene (one per non-degenerate triangle in this version).
pub fn build_faces(scene: &Scene) -> FaceSet {
    let diag = scene.diagonal();
    let min_area = DEGENERATE_AREA_REL * diag * diag;
    let mut faces = Vec::new();
    let mut face_of_triangle = vec![None; scene.triangles.len()];
    let mut dropped = 0;
    for (i, t) in scene.triangles.iter().enumerate() {
        let cross = t.cross();
        let area = 0.5 * cross.length();
        if area.is_nan() || area <= min_area {
            dropped += 1;
            continue;
        }
        let id = FaceId(faces.len() as u32);
        face_of_triangle[i] = Some(id);
        faces.push(Face {
            id,
            material: t.material,
            double_sided: scene.material(t).double_sided,
            kind: FaceKind::Triangle,
            normal: cross / cross.length(),
            area_m2: area,
            outer: t.vertices.to_vec(),
            holes: Vec::new(),
            triangles: vec![i as u32],
        });
    }
    FaceSet {
        faces,
        triangles_in: scene.triangles.len(),
        degenerate_dropped: dropped,
        face_of_triangle,
    }
}
