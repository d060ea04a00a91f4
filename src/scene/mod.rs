//! Scene: what a glTF file holds, in world space and validated.
//!
//! Owns the triangles (world frame, metres, `f64`), the materials (rho, L_e, sides) and the
//! punctual lights. Everything past this module takes a [`Scene`], never raw glTF.
//!
//! Invariants of a [`Scene`] built by [`load_scene`]:
//! - every vertex coordinate is finite; every triangle's material index is valid;
//! - a triangle's vertices are in counter-clockwise order about its front normal in world space
//!   (node transforms with a negative determinant have been compensated);
//! - `rho` is clamped to `[0, 1]`, `emission` (L_e) is finite and non-negative.
//!
//! Degenerate (zero-area) triangles are kept here; the face builder drops and counts them.

mod buffers;
/// `city_glb`, N instances of one lit building under one sky panel, for the scaling benchmark and
/// tests: compiled like `gltf_writer` (unit tests and the `test-support` feature).
#[cfg(any(test, feature = "test-support"))]
pub mod city;
mod error;
mod gltf_import;
mod gltf_textures;
/// `SceneBuilder`, a small GLB writer for tests: compiled for the crate's own unit tests and, with
/// the `test-support` feature (which the integration tests turn on), for `tests/` and `benches/`.
#[cfg(any(test, feature = "test-support"))]
pub mod gltf_writer;
mod texture;

pub use error::{Problem, SceneError};
pub use gltf_import::{load_scene, load_scene_from_path, primitive_triangles, ExternalFiles};
pub use texture::{srgb_to_linear, Texture, TextureSlot, UvTransform, Wrap};

/// Every `.gltf` and `.glb` file under `dir`, sorted, skipping `original/` folders (untouched
/// upstream files, not scenes); empty when `dir` is absent. For the tests and benchmarks that
/// sweep `../shared/scenes`.
#[cfg(any(test, feature = "test-support"))]
pub fn scene_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "original") {
                    walk(&p, out);
                }
            } else if p.extension().is_some_and(|x| x == "gltf" || x == "glb") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, &mut out);
    out.sort();
    out
}

use glam::{DVec2, DVec3};
use std::sync::Arc;

/// Linear RGB triple (per colour channel quantities: rho, L_e, radiosity...).
pub type Rgb = [f64; 3];

/// A surface material as the solver sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// glTF material name (or `material_N`).
    pub name: String,
    /// Reflectance factor, `baseColorFactor.rgb` clamped to `[0, 1]`; the reflectance is this
    /// times the base colour texture's linear value when there is one.
    pub rho: Rgb,
    /// Emitted radiance factor L_e = `emissiveFactor * emissiveStrength`; times the emissive
    /// texture's linear value when there is one.
    pub emission: Rgb,
    /// Two radiosity sides (glTF `doubleSided`).
    pub double_sided: bool,
    /// `baseColorTexture`.
    pub base_color_texture: Option<TextureSlot>,
    /// `emissiveTexture`.
    pub emissive_texture: Option<TextureSlot>,
}

impl Material {
    /// The default glTF material: white, single-sided, not emissive.
    pub fn gltf_default() -> Self {
        Material {
            name: "default".into(),
            rho: [1.0; 3],
            emission: [0.0; 3],
            double_sided: false,
            base_color_texture: None,
            emissive_texture: None,
        }
    }

    /// True when reflectance or emission comes from a texture.
    pub fn has_texture(&self) -> bool {
        self.base_color_texture.is_some() || self.emissive_texture.is_some()
    }

    /// True when the material emits on any channel.
    pub fn is_emissive(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }
}

/// One world-space triangle, counter-clockwise about its front normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    pub vertices: [DVec3; 3],
    pub material: u32,
    /// Where it came from: mesh index, primitive index, triangle index within the primitive.
    pub source: TriangleSource,
}

/// The place of a triangle in the glTF file, for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriangleSource {
    pub mesh: u32,
    pub primitive: u32,
    pub triangle: u32,
}

impl Triangle {
    /// A triangle of `material` with the place `index` of the first mesh's first primitive: a
    /// scene built in code (tests, generated twins) has no other place to name.
    pub fn numbered(vertices: [DVec3; 3], material: u32, index: u32) -> Triangle {
        Triangle {
            vertices,
            material,
            source: TriangleSource {
                mesh: 0,
                primitive: 0,
                triangle: index,
            },
        }
    }

    /// Unnormalised normal: `(b - a) x (c - a)`, length twice the area.
    pub fn cross(&self) -> DVec3 {
        let [a, b, c] = self.vertices;
        (b - a).cross(c - a)
    }

    pub fn area(&self) -> f64 {
        0.5 * self.cross().length()
    }
}

/// A `KHR_lights_punctual` light, in world space.
#[derive(Debug, Clone, PartialEq)]
pub struct PunctualLight {
    pub name: String,
    pub kind: LightKind,
    /// `color * intensity`: candela (W/sr) for point and spot, lux (W/m^2) for directional.
    pub intensity: Rgb,
}

#[derive(Debug, Clone, PartialEq)]
pub enum LightKind {
    Point {
        position: DVec3,
    },
    Spot {
        position: DVec3,
        /// Unit direction the spot points to.
        direction: DVec3,
        inner_cone_angle: f64,
        outer_cone_angle: f64,
    },
    /// Light travelling along `direction` (unit).
    Directional {
        direction: DVec3,
    },
}

/// A perspective camera in world space: a glTF camera node's (`-Z` of the node is `forward`, `+Y`
/// is `up`), read by the importer; the preview renders from it (`output::preview`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub position: DVec3,
    /// Unit direction the camera looks along.
    pub forward: DVec3,
    /// Unit up direction, orthogonal to `forward`.
    pub up: DVec3,
    /// Vertical field of view, radians, in `(0, pi)`.
    pub yfov: f64,
    /// Width over height of the image, when the file gives it (positive and finite).
    pub aspect: Option<f64>,
    /// Distance of the near plane, metres (0 when the file's is not positive).
    pub znear: f64,
}

/// Axis-aligned bounds of the scene's vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub min: DVec3,
    pub max: DVec3,
}

impl Bounds {
    pub fn empty() -> Self {
        Bounds {
            min: DVec3::splat(f64::INFINITY),
            max: DVec3::splat(f64::NEG_INFINITY),
        }
    }
    pub fn extend(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn diagonal(&self) -> f64 {
        if self.min.x > self.max.x {
            return 0.0;
        }
        (self.max - self.min).length()
    }
}

/// The texture coordinates of one triangle's corners (in its vertex order), as its material's
/// textures read them: the `TEXCOORD_n` set each names, its `KHR_texture_transform` applied.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TriangleTexcoords {
    pub base_color: [DVec2; 3],
    pub emissive: [DVec2; 3],
}

/// A validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub lights: Vec<PunctualLight>,
    pub bounds: Bounds,
    /// Things the user should know that did not stop the import (ignored lines, textures...).
    pub warnings: Vec<String>,
    /// Decoded textures, indexed by [`TextureSlot::texture`].
    pub textures: Vec<Arc<Texture>>,
    /// Per triangle (same index), its texture coordinates; empty when no material has a texture.
    pub texcoords: Vec<TriangleTexcoords>,
    /// The file's first perspective camera (lowest node index in the scene), if any.
    pub camera: Option<Camera>,
    /// The glTF file the scene was read from (`None` for scenes built in code): what the baked
    /// scene (`output::baked_scene`) rewrites.
    pub source: Option<Arc<GltfSource>>,
}

/// The input glTF as the importer read it: its JSON as written (unknown extensions kept), the
/// parsed document, its buffers, the encoded bytes of each image (`None` where unreadable), and
/// the mesh instances the triangles came from.
///
/// Invariant: `instances` are in the order their triangles were pushed, each owning the
/// contiguous range `triangles` of [`Scene::triangles`]; the triangles of one instance are those
/// of its mesh's triangle primitives, in primitive order, triangle `k` of a primitive being
/// [`primitive_triangles`]`[k]`.
#[derive(Clone)]
pub struct GltfSource {
    pub json: serde_json::Value,
    pub document: gltf::Document,
    pub buffers: Vec<Vec<u8>>,
    pub images: Vec<Option<Vec<u8>>>,
    pub instances: Vec<MeshInstance>,
}

impl std::fmt::Debug for GltfSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GltfSource")
            .field("buffers", &self.buffers.len())
            .field("images", &self.images.len())
            .field("instances", &self.instances)
            .finish()
    }
}

/// One node that places a mesh in the scene (a mesh used by several nodes has one per node).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshInstance {
    pub node: u32,
    pub mesh: u32,
    /// The node's world matrix (local to world), column-major.
    pub world: glam::DMat4,
    /// The world matrix mirrors (negative determinant): the importer swapped corners 1 and 2.
    pub mirrored: bool,
    /// Its triangles in [`Scene::triangles`].
    pub triangles: std::ops::Range<usize>,
}

impl Scene {
    /// A scene of triangles of glTF's default material, numbered in order, no lights or camera.
    pub fn of_triangles(tris: &[[DVec3; 3]]) -> Scene {
        let triangles = (0u32..)
            .zip(tris)
            .map(|(i, &v)| Triangle::numbered(v, 0, i))
            .collect();
        Scene::new(triangles, vec![Material::gltf_default()], vec![], vec![])
    }

    /// Builds a scene from parts, computing bounds. Used by tests and by the importer.
    pub fn new(
        triangles: Vec<Triangle>,
        materials: Vec<Material>,
        lights: Vec<PunctualLight>,
        warnings: Vec<String>,
    ) -> Self {
        let mut bounds = Bounds::empty();
        for t in &triangles {
            for v in t.vertices {
                bounds.extend(v);
            }
        }
        Scene {
            triangles,
            materials,
            lights,
            bounds,
            warnings,
            textures: Vec::new(),
            texcoords: Vec::new(),
            source: None,
            camera: None,
        }
    }

    /// The scene with the camera the file gives.
    pub fn with_camera(mut self, camera: Option<Camera>) -> Self {
        self.camera = camera;
        self
    }

    /// The scene with textures and per-triangle texture coordinates (`texcoords` empty, or one
    /// per triangle).
    pub fn with_textures(
        mut self,
        textures: Vec<Arc<Texture>>,
        texcoords: Vec<TriangleTexcoords>,
    ) -> Self {
        debug_assert!(texcoords.is_empty() || texcoords.len() == self.triangles.len());
        self.textures = textures;
        self.texcoords = texcoords;
        self
    }

    /// The length of the bounding-box diagonal: the scale every geometric tolerance is relative to.
    pub fn diagonal(&self) -> f64 {
        self.bounds.diagonal()
    }

    pub fn material(&self, t: &Triangle) -> &Material {
        &self.materials[t.material as usize]
    }

    /// Number of triangles whose material emits.
    pub fn emissive_triangle_count(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| self.material(t).is_emissive())
            .count()
    }
}
