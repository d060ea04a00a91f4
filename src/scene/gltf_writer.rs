//! A small GLB writer: builds a glTF 2.0 binary from world-space triangles and materials.
//!
//! Used by tests to make hand-built scenes (and by fuzzing seeds); it writes exactly the subset the
//! importer reads: one mesh per material group, `POSITION` + `indices`, materials with
//! `baseColorFactor`, `emissiveFactor`, `KHR_materials_emissive_strength`, `doubleSided`,
//! optionally `KHR_lights_punctual` lights, and optionally one perspective camera.

use super::{Camera, LightKind, Material, PunctualLight};
use glam::DVec3;
use serde_json::{json, Value};

/// A scene under construction: quads and triangles added in world space.
#[derive(Debug, Default, Clone)]
pub struct SceneBuilder {
    materials: Vec<Material>,
    /// Per mesh: material index, positions, indices.
    meshes: Vec<(u32, Vec<[f32; 3]>, Vec<u32>)>,
    lights: Vec<PunctualLight>,
    camera: Option<Camera>,
}

impl SceneBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a material; returns its index.
    pub fn material(&mut self, rho: [f64; 3], emission: [f64; 3], double_sided: bool) -> u32 {
        self.materials.push(Material {
            name: format!("material_{}", self.materials.len()),
            rho,
            emission,
            double_sided,
            base_color_texture: None,
            emissive_texture: None,
        });
        (self.materials.len() - 1) as u32
    }

    /// Adds a triangle list (counter-clockwise about the front normal) as one mesh.
    pub fn mesh(&mut self, material: u32, positions: &[DVec3], indices: &[u32]) -> &mut Self {
        self.meshes.push((
            material,
            positions
                .iter()
                .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                .collect(),
            indices.to_vec(),
        ));
        self
    }

    /// Adds the parallelogram `origin + s*u + t*v`, front normal `u x v`, split in `n x n` quads.
    pub fn quad(&mut self, material: u32, origin: DVec3, u: DVec3, v: DVec3, n: u32) -> &mut Self {
        let n = n.max(1);
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions.push(origin + u * (i as f64 / n as f64) + v * (j as f64 / n as f64));
            }
        }
        let mut indices = Vec::new();
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                indices.extend([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        self.mesh(material, &positions, &indices)
    }

    /// Adds the six faces of the box `[min, max]`, front normals pointing inward, `n x n` quads each.
    pub fn inward_box(&mut self, materials: [u32; 6], min: DVec3, max: DVec3, n: u32) -> &mut Self {
        let d = max - min;
        let (x, y, z) = (DVec3::X * d.x, DVec3::Y * d.y, DVec3::Z * d.z);
        // Order: -x, +x, -y, +y, -z, +z walls; u x v points into the box.
        self.quad(materials[0], min, y, z, n);
        self.quad(materials[1], min + x, z, y, n);
        self.quad(materials[2], min, z, x, n);
        self.quad(materials[3], min + y, x, z, n);
        self.quad(materials[4], min, x, y, n);
        self.quad(materials[5], min + z, y, x, n)
    }

    pub fn light(&mut self, light: PunctualLight) -> &mut Self {
        self.lights.push(light);
        self
    }

    /// Adds a perspective camera node (written after the meshes and lights).
    pub fn camera(&mut self, camera: Camera) -> &mut Self {
        self.camera = Some(camera);
        self
    }

    /// Writes the GLB bytes.
    pub fn to_glb(&self) -> Vec<u8> {
        let mut bin: Vec<u8> = Vec::new();
        let mut accessors = Vec::new();
        let mut views = Vec::new();
        let mut meshes = Vec::new();
        let mut nodes = Vec::new();
        for (material, positions, indices) in &self.meshes {
            let mut min = [f32::INFINITY; 3];
            let mut max = [f32::NEG_INFINITY; 3];
            let pos_offset = bin.len();
            for p in positions {
                for k in 0..3 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                    bin.extend_from_slice(&p[k].to_le_bytes());
                }
            }
            views.push(
                json!({"buffer": 0, "byteOffset": pos_offset, "byteLength": positions.len() * 12}),
            );
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126,
                "count": positions.len(), "type": "VEC3", "min": min, "max": max}));
            let idx_offset = bin.len();
            for i in indices {
                bin.extend_from_slice(&i.to_le_bytes());
            }
            views.push(
                json!({"buffer": 0, "byteOffset": idx_offset, "byteLength": indices.len() * 4}),
            );
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5125,
                "count": indices.len(), "type": "SCALAR"}));
            meshes.push(
                json!({"primitives": [{"attributes": {"POSITION": accessors.len() - 2},
                "indices": accessors.len() - 1, "material": material}]}),
            );
            nodes.push(json!({"mesh": meshes.len() - 1}));
        }
        let mut light_json = Vec::new();
        for l in &self.lights {
            let max = l.intensity.iter().cloned().fold(0.0f64, f64::max);
            let color = if max > 0.0 {
                l.intensity.map(|c| c / max)
            } else {
                [1.0; 3]
            };
            let (kind, translation, dir) = match &l.kind {
                LightKind::Point { position } => {
                    (json!({"type": "point"}), *position, DVec3::NEG_Z)
                }
                LightKind::Spot {
                    position,
                    direction,
                    inner_cone_angle,
                    outer_cone_angle,
                } => (
                    json!({"type": "spot", "spot": {"innerConeAngle": inner_cone_angle, "outerConeAngle": outer_cone_angle}}),
                    *position,
                    *direction,
                ),
                LightKind::Directional { direction } => {
                    (json!({"type": "directional"}), DVec3::ZERO, *direction)
                }
            };
            let mut lj = kind;
            lj["color"] = json!(color);
            lj["intensity"] = json!(max);
            light_json.push(lj);
            // Rotation taking -Z to `dir`.
            let q = glam::DQuat::from_rotation_arc(DVec3::NEG_Z, dir.normalize());
            nodes.push(
                json!({"translation": [translation.x, translation.y, translation.z],
                "rotation": [q.x, q.y, q.z, q.w],
                "extensions": {"KHR_lights_punctual": {"light": light_json.len() - 1}}}),
            );
        }
        let mut cameras = Vec::new();
        if let Some(c) = &self.camera {
            let mut perspective = json!({"yfov": c.yfov, "znear": c.znear.max(1e-6)});
            if let Some(aspect) = c.aspect {
                perspective["aspectRatio"] = json!(aspect);
            }
            cameras.push(json!({"type": "perspective", "perspective": perspective}));
            // The node's axes: +X right, +Y up, +Z behind the camera.
            let back = -c.forward.normalize();
            let right = c.up.cross(back).normalize();
            let up = back.cross(right);
            let q = glam::DQuat::from_mat3(&glam::DMat3::from_cols(right, up, back));
            let t = c.position;
            nodes.push(
                json!({"translation": [t.x, t.y, t.z], "rotation": [q.x, q.y, q.z, q.w],
                "camera": 0}),
            );
        }
        let materials: Vec<Value> = self
            .materials
            .iter()
            .map(|m| {
                let max_e = m.emission.iter().cloned().fold(0.0f64, f64::max);
                let (factor, strength) = if max_e > 1.0 {
                    (m.emission.map(|e| e / max_e), max_e)
                } else {
                    (m.emission, 1.0)
                };
                let mut mj = json!({"name": m.name,
                    "pbrMetallicRoughness": {"baseColorFactor": [m.rho[0], m.rho[1], m.rho[2], 1.0],
                        "metallicFactor": 0.0, "roughnessFactor": 1.0},
                    "emissiveFactor": factor, "doubleSided": m.double_sided});
                if strength != 1.0 {
                    mj["extensions"] =
                        json!({"KHR_materials_emissive_strength": {"emissiveStrength": strength}});
                }
                mj
            })
            .collect();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let mut root = json!({
            "asset": {"version": "2.0", "generator": "wavrad SceneBuilder"},
            "scene": 0,
            "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
            "nodes": nodes, "meshes": meshes, "materials": materials,
            "accessors": accessors, "bufferViews": views,
            "buffers": [{"byteLength": bin.len()}],
            "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_lights_punctual"],
        });
        if !cameras.is_empty() {
            root["cameras"] = json!(cameras);
        }
        if !light_json.is_empty() {
            root["extensions"] = json!({"KHR_lights_punctual": {"lights": light_json}});
        }
        glb_from_parts(&root, &bin)
    }
}

/// Packs a JSON document and a binary chunk into GLB bytes (chunks padded to 4 bytes).
pub fn glb_from_parts(root: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json_bytes = serde_json::to_vec(root).unwrap_or_default();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}
