//! The baked scene, `scene.glb`: the input glTF rewritten so that an engine shows the lightmap.
//!
//! Owns the rewrite (docs/contract.md, "scene.glb"): nodes, hierarchy, materials, textures,
//! samplers, cameras and lights are kept from the input's JSON as written; each mesh instance (a
//! node placing a mesh) gets its own mesh, whose primitives hold the *pieces* the faces were cut
//! into (`FaceSet::piece_source`, `Face::triangulation`), written in the mesh's local space by
//! interpolating the source triangle's vertex attributes with the piece corner's barycentrics,
//! one primitive per input primitive and atlas page, vertices split per face side, plus
//! `TEXCOORD_1` into the atlas: `((x + s w) / W, (y + t h) / H)` for the point `(s, t)` of the
//! side's frame (the EXR's texel convention). A double-sided face is written twice, the back copy
//! with reversed winding, negated normals and its own `TEXCOORD_1`; its material becomes
//! single-sided. Each material used gets the `MOZ_lightmap` extension naming its page's texture
//! (cloned per page); each page is one embedded PNG named like its EXR without `.exr`.
//!
//! Invariants (pinned by `tests/baked_scene.rs` and `tests/real_clients/gltf_validator.rs`):
//! every written primitive has `TEXCOORD_1`; an input `TEXCOORD_n` with `n >= 1` is written as
//! `TEXCOORD_{n+1}` and every `texCoord >= 1` in the materials moves with it; the PNG holds
//! irradiance, `linear(texel) x intensity = H`, sRGB-encoded. Pieces in no face (degenerate,
//! overlapped away), points, lines, skins, morph targets and animations are left out.

use super::atlas::{Atlas, AtlasRect};
use super::{encode_rgb_png, page_file_name, srgb8};
use crate::domain::{plane_coordinates, Side, Surface};
use crate::faces::FaceSet;
use crate::scene::{primitive_triangles, GltfSource, Scene};
use glam::{DVec2, DVec3};
use serde_json::{json, Map, Value};
use std::collections::{BTreeMap, HashMap};

/// The glTF extension that attaches a lightmap to a material (Mozilla Hubs; three.js loaders).
pub const LIGHTMAP_EXTENSION: &str = "MOZ_lightmap";

/// The share of covered texels whose irradiance the PNG holds without clipping: `intensity` is
/// this percentile of their largest channel (`lightmap_intensity`).
pub const INTENSITY_PERCENTILE: f64 = 0.995;

/// The name of atlas page `n`'s image in the baked scene: its EXR file's name without `.exr`.
pub fn lightmap_image_name(n: usize) -> String {
    page_file_name(n).trim_end_matches(".exr").to_string()
}

/// The `intensity` of the baked scene's lightmaps: the [`INTENSITY_PERCENTILE`] of the largest
/// channel of every covered irradiance texel (all pages), 1 when the scene is dark.
pub fn lightmap_intensity(irradiance_pages: &[Vec<[f32; 4]>]) -> f64 {
    let mut peaks: Vec<f32> = irradiance_pages
        .iter()
        .flatten()
        .filter(|t| t[3] > 0.0)
        .map(|t| t[0].max(t[1]).max(t[2]))
        .filter(|x| x.is_finite())
        .collect();
    if peaks.is_empty() {
        return 1.0;
    }
    let k = ((peaks.len() - 1) as f64 * INTENSITY_PERCENTILE) as usize;
    let (_, p, _) = peaks.select_nth_unstable_by(k, f32::total_cmp);
    if *p > 0.0 {
        f64::from(*p)
    } else {
        1.0
    }
}

/// One lightmap page as an 8-bit sRGB PNG: each texel `H / intensity` (irradiance texels in).
pub fn lightmap_png(
    irradiance: &[[f32; 4]],
    width: u32,
    height: u32,
    intensity: f64,
) -> std::io::Result<Vec<u8>> {
    let mut data = Vec::with_capacity(irradiance.len() * 3);
    for t in irradiance {
        data.extend([0, 1, 2].map(|c| srgb8((f64::from(t[c]) / intensity) as f32)));
    }
    encode_rgb_png(&data, width, height)
}

/// What [`baked_scene_glb`] needs of the solve besides the input glTF.
pub struct BakeInputs<'a> {
    pub scene: &'a Scene,
    pub faces: &'a FaceSet,
    pub surfaces: &'a [Surface],
    pub atlas: &'a Atlas,
    /// One PNG per atlas page ([`lightmap_png`]).
    pub pages_png: &'a [Vec<u8>],
    pub intensity: f64,
}

/// The binary chunk being built, with its buffer views and accessors.
#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

impl Bin {
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.data.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// A FLOAT accessor of `values` (`components` per element), with min and max when asked.
    fn floats(&mut self, values: &[f32], components: usize, kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        let mut a = json!({"bufferView": view, "componentType": 5126,
            "count": values.len() / components, "type": kind});
        if bounds {
            let mut min = vec![f32::INFINITY; components];
            let mut max = vec![f32::NEG_INFINITY; components];
            for e in values.chunks_exact(components) {
                for c in 0..components {
                    min[c] = min[c].min(e[c]);
                    max[c] = max[c].max(e[c]);
                }
            }
            a["min"] = json!(min.iter().map(|&x| f64::from(x)).collect::<Vec<_>>());
            a["max"] = json!(max.iter().map(|&x| f64::from(x)).collect::<Vec<_>>());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.accessors
            .push(json!({"bufferView": view, "componentType": 5125,
            "count": indices.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

/// The vertex attributes of one input primitive, read as floats (missing or unreadable: empty).
struct Attributes {
    positions: Vec<DVec3>,
    normals: Vec<[f32; 3]>,
    tangents: Vec<[f32; 4]>,
    /// `(set, values)` per `TEXCOORD_n`.
    uvs: Vec<(u32, Vec<[f32; 2]>)>,
    /// `(set, RGBA)` per `COLOR_n`.
    colors: Vec<(u32, Vec<[f32; 4]>)>,
}

impl Attributes {
    fn read(primitive: &gltf::Primitive, buffers: &[Vec<u8>]) -> Attributes {
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let positions: Vec<DVec3> = reader
            .read_positions()
            .map(|p| p.map(|p| DVec3::from(p.map(f64::from))).collect())
            .unwrap_or_default();
        let n = positions.len();
        let full = |len: usize| len == n;
        let normals: Vec<[f32; 3]> = reader
            .read_normals()
            .map(Iterator::collect)
            .filter(|v: &Vec<_>| full(v.len()))
            .unwrap_or_default();
        let tangents: Vec<[f32; 4]> = reader
            .read_tangents()
            .map(Iterator::collect)
            .filter(|v: &Vec<_>| full(v.len()))
            .unwrap_or_default();
        let mut uvs = Vec::new();
        let mut colors = Vec::new();
        for (semantic, _) in primitive.attributes() {
            match semantic {
                gltf::Semantic::TexCoords(set) => {
                    if let Some(v) = reader.read_tex_coords(set) {
                        let v: Vec<[f32; 2]> = v.into_f32().collect();
                        if full(v.len()) {
                            uvs.push((set, v));
                        }
                    }
                }
                gltf::Semantic::Colors(set) => {
                    if let Some(v) = reader.read_colors(set) {
                        let v: Vec<[f32; 4]> = v.into_rgba_f32().collect();
                        if full(v.len()) {
                            colors.push((set, v));
                        }
                    }
                }
                _ => {}
            }
        }
        uvs.sort_by_key(|u| u.0);
        colors.sort_by_key(|c| c.0);
        Attributes {
            positions,
            normals,
            tangents,
            uvs,
            colors,
        }
    }

    /// Floats per written vertex: position, normal, tangent, each UV set, each colour, TEXCOORD_1.
    fn stride(&self) -> usize {
        3 + 3 * usize::from(!self.normals.is_empty())
            + 4 * usize::from(!self.tangents.is_empty())
            + 2 * self.uvs.len()
            + 4 * self.colors.len()
            + 2
    }

    /// The written vertex at barycentrics `b` of the input triangle `idx`, for side `back`, with
    /// lightmap coordinates `uv1`.
    fn vertex(&self, idx: [usize; 3], b: [f64; 3], back: bool, uv1: DVec2, out: &mut Vec<f32>) {
        let mix = |get: &dyn Fn(usize) -> f64| -> f64 { (0..3).map(|k| b[k] * get(idx[k])).sum() };
        let p = DVec3::new(
            mix(&|i| self.positions.get(i).map_or(0.0, |p| p.x)),
            mix(&|i| self.positions.get(i).map_or(0.0, |p| p.y)),
            mix(&|i| self.positions.get(i).map_or(0.0, |p| p.z)),
        );
        out.extend([p.x as f32, p.y as f32, p.z as f32]);
        let sign = if back { -1.0 } else { 1.0 };
        if !self.normals.is_empty() {
            let n = DVec3::new(
                mix(&|i| self.normals.get(i).map_or(0.0, |n| f64::from(n[0]))),
                mix(&|i| self.normals.get(i).map_or(0.0, |n| f64::from(n[1]))),
                mix(&|i| self.normals.get(i).map_or(0.0, |n| f64::from(n[2]))),
            )
            .normalize_or(DVec3::Z)
                * sign;
            out.extend([n.x as f32, n.y as f32, n.z as f32]);
        }
        if !self.tangents.is_empty() {
            let t = DVec3::new(
                mix(&|i| self.tangents.get(i).map_or(0.0, |t| f64::from(t[0]))),
                mix(&|i| self.tangents.get(i).map_or(0.0, |t| f64::from(t[1]))),
                mix(&|i| self.tangents.get(i).map_or(0.0, |t| f64::from(t[2]))),
            )
            .normalize_or(DVec3::X);
            let w = mix(&|i| self.tangents.get(i).map_or(1.0, |t| f64::from(t[3])));
            // The bitangent (n x t) w keeps its direction when the back copy negates n.
            let w = if w < 0.0 { -sign } else { sign };
            out.extend([t.x as f32, t.y as f32, t.z as f32, w as f32]);
        }
        for (_, uv) in &self.uvs {
            for c in 0..2 {
                out.push(mix(&|i| uv.get(i).map_or(0.0, |v| f64::from(v[c]))) as f32);
            }
        }
        for (_, colour) in &self.colors {
            for c in 0..4 {
                let x = mix(&|i| colour.get(i).map_or(1.0, |v| f64::from(v[c])));
                out.push(x.clamp(0.0, 1.0) as f32);
            }
        }
        out.extend([uv1.x as f32, uv1.y as f32]);
    }
}

/// The vertices and triangles of one written primitive (one input primitive on one page).
#[derive(Default)]
struct PrimitiveBuilder {
    vertices: Vec<f32>,
    indices: Vec<u32>,
    lookup: HashMap<Vec<u32>, u32>,
}

impl PrimitiveBuilder {
    fn push(&mut self, vertex: &[f32]) {
        let key: Vec<u32> = vertex.iter().map(|x| x.to_bits()).collect();
        let next = self.lookup.len() as u32;
        let i = *self.lookup.entry(key).or_insert_with(|| {
            self.vertices.extend_from_slice(vertex);
            next
        });
        self.indices.push(i);
    }
}

/// Barycentric coordinates of `p` in the triangle `w` (projected onto its plane).
fn barycentric(p: DVec3, w: [DVec3; 3]) -> [f64; 3] {
    let (e0, e1, e2) = (w[1] - w[0], w[2] - w[0], p - w[0]);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (e2.dot(e0), e2.dot(e1));
    let det = d00 * d11 - d01 * d01;
    if det.abs() <= f64::MIN_POSITIVE {
        return [1.0, 0.0, 0.0];
    }
    let b1 = (d11 * d20 - d01 * d21) / det;
    let b2 = (d00 * d21 - d01 * d20) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// `TEXCOORD_1` of world point `x` on a side with this frame and rectangle on a `W x H` page.
pub fn lightmap_uv(surface: &Surface, rect: AtlasRect, page: (u32, u32), x: DVec3) -> DVec2 {
    let st = plane_coordinates(&surface.frame, x).clamp(DVec2::ZERO, DVec2::ONE);
    DVec2::new(
        (f64::from(rect.x) + st.x * f64::from(rect.w)) / f64::from(page.0),
        (f64::from(rect.y) + st.y * f64::from(rect.h)) / f64::from(page.1),
    )
}

/// The MIME type of an encoded image, from its magic bytes, else as declared.
fn mime_type(bytes: &[u8], declared: Option<&str>) -> String {
    if bytes.starts_with(b"\x89PNG") {
        "image/png".into()
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        "image/jpeg".into()
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        "image/webp".into()
    } else if bytes.starts_with(b"\xABKTX 20") {
        "image/ktx2".into()
    } else {
        declared.unwrap_or("image/png").to_string()
    }
}

/// A 1 x 1 white PNG standing in for an input image that could not be read.
fn placeholder_png() -> Vec<u8> {
    encode_rgb_png(&[255, 255, 255], 1, 1).unwrap_or_default()
}

/// Adds one to every `texCoord >= 1` in `v` (texture infos and `KHR_texture_transform`).
fn shift_tex_coords(v: &mut Value) {
    match v {
        Value::Object(map) => {
            for (k, x) in map.iter_mut() {
                if k == "texCoord" {
                    if let Some(n) = x.as_u64().filter(|&n| n >= 1) {
                        *x = json!(n + 1);
                    }
                } else {
                    shift_tex_coords(x);
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(shift_tex_coords),
        _ => {}
    }
}

/// The baked scene as GLB bytes, or `None` when the scene was not read from a glTF file.
pub fn baked_scene_glb(inputs: &BakeInputs) -> Option<Vec<u8>> {
    let source = inputs.scene.source.as_deref()?;
    Some(write_glb(&rewrite(source, inputs)))
}

/// The JSON and binary chunk of the baked scene.
fn rewrite(source: &GltfSource, inputs: &BakeInputs) -> (Value, Vec<u8>) {
    let BakeInputs {
        scene,
        faces,
        surfaces,
        atlas,
        pages_png,
        intensity,
    } = *inputs;
    let document = &source.document;
    let mut root = match &source.json {
        Value::Object(m) => m.clone(),
        _ => Map::new(),
    };
    for key in [
        "buffers",
        "bufferViews",
        "accessors",
        "meshes",
        "animations",
        "skins",
    ] {
        root.remove(key);
    }
    let mut bin = Bin::default();

    // Input images, embedded in order (texture indices stay valid).
    let mut images: Vec<Value> = match root.remove("images") {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    for (i, image) in images.iter_mut().enumerate() {
        let bytes = source
            .images
            .get(i)
            .cloned()
            .flatten()
            .unwrap_or_else(placeholder_png);
        let declared = image.get("mimeType").and_then(Value::as_str);
        let mime = mime_type(&bytes, declared);
        let view = bin.view(&bytes, None);
        let mut out = Map::new();
        for key in ["name", "extras", "extensions"] {
            if let Some(x) = image.get(key) {
                out.insert(key.into(), x.clone());
            }
        }
        out.insert("bufferView".into(), json!(view));
        out.insert("mimeType".into(), json!(mime));
        *image = Value::Object(out);
    }
    // One image, texture (linear filtering, clamped) per lightmap page.
    let mut samplers: Vec<Value> = match root.remove("samplers") {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    samplers.push(json!({"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}));
    let lightmap_sampler = samplers.len() - 1;
    let mut textures: Vec<Value> = match root.remove("textures") {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    let mut page_texture = Vec::new();
    for (n, png) in pages_png.iter().enumerate() {
        let view = bin.view(png, None);
        images.push(
            json!({"name": lightmap_image_name(n), "mimeType": "image/png", "bufferView": view}),
        );
        textures.push(
            json!({"name": lightmap_image_name(n), "source": images.len() - 1,
            "sampler": lightmap_sampler}),
        );
        page_texture.push(textures.len() - 1);
    }

    // Texture coordinate sets 1 and up move up by one: TEXCOORD_1 is the lightmap's.
    let shift = document.meshes().flat_map(|m| m.primitives()).any(|p| {
        p.attributes()
            .any(|(s, _)| matches!(s, gltf::Semantic::TexCoords(n) if n >= 1))
    });
    let mut materials: Vec<Value> = match root.remove("materials") {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    if shift {
        materials.iter_mut().for_each(shift_tex_coords);
    }
    let shifted = materials.clone();
    let mut material_of: HashMap<(Option<usize>, u32), usize> = HashMap::new();
    let mut first_page: HashMap<usize, u32> = HashMap::new();
    let mut material_for = |material: Option<usize>, page: u32| -> usize {
        if let Some(&m) = material_of.get(&(material, page)) {
            return m;
        }
        let lightmap = json!({"index": page_texture.get(page as usize).copied().unwrap_or(0),
            "texCoord": 1, "intensity": intensity});
        let index = match material.filter(|&m| m < shifted.len()) {
            Some(m) if !first_page.contains_key(&m) => {
                first_page.insert(m, page);
                m
            }
            Some(m) => {
                let mut clone = shifted[m].clone();
                let name = clone
                    .get("name")
                    .and_then(Value::as_str)
                    .map_or(format!("material_{m}"), str::to_owned);
                clone["name"] = json!(format!("{name} ({})", lightmap_image_name(page as usize)));
                materials.push(clone);
                materials.len() - 1
            }
            None => {
                // The glTF default material as the solver reads it: white and diffuse.
                materials.push(
                    json!({"name": format!("default ({})", lightmap_image_name(page as usize)),
                    "pbrMetallicRoughness": {"metallicFactor": 0.0}}),
                );
                materials.len() - 1
            }
        };
        if let Some(Value::Object(m)) = materials.get_mut(index) {
            // Both sides are written as faces of their own.
            m.remove("doubleSided");
            let ext = m
                .entry("extensions")
                .or_insert_with(|| json!({}))
                .as_object_mut();
            if let Some(ext) = ext {
                ext.insert(LIGHTMAP_EXTENSION.into(), lightmap.clone());
            } else {
                m.insert("extensions".into(), json!({ LIGHTMAP_EXTENSION: lightmap }));
            }
        }
        material_of.insert((material, page), index);
        index
    };

    // Pieces: per piece its face and place in the face; per scene triangle its pieces.
    let mut piece_place: Vec<Option<(usize, usize)>> = vec![None; faces.piece_source.len()];
    for (f, face) in faces.faces.iter().enumerate() {
        for (k, &p) in face.triangles.iter().enumerate() {
            if let Some(slot) = piece_place.get_mut(p as usize) {
                *slot = Some((f, k));
            }
        }
    }
    let mut pieces_of: Vec<Vec<u32>> = vec![Vec::new(); scene.triangles.len()];
    for (p, &t) in faces.piece_source.iter().enumerate() {
        if let Some(list) = pieces_of.get_mut(t as usize) {
            list.push(p as u32);
        }
    }
    let mut surface_of: HashMap<(u32, bool), usize> = HashMap::new();
    for (i, s) in surfaces.iter().enumerate() {
        surface_of.insert((s.face.0, s.side == Side::Back), i);
    }

    let mesh_json = source.json.get("meshes").cloned().unwrap_or(Value::Null);
    let mut meshes = Vec::new();
    let mut node_mesh: HashMap<u32, usize> = HashMap::new();
    for instance in &source.instances {
        let Some(mesh) = document.meshes().nth(instance.mesh as usize) else {
            continue;
        };
        let mut next_triangle = instance.triangles.start;
        let mut primitives = Vec::new();
        for primitive in mesh.primitives() {
            let attributes = Attributes::read(&primitive, &source.buffers);
            let Some(triangles) =
                primitive_triangles(&primitive, &source.buffers, attributes.positions.len())
            else {
                continue;
            };
            let first = next_triangle;
            next_triangle += triangles.len();
            let mut pages: BTreeMap<u32, PrimitiveBuilder> = BTreeMap::new();
            let mut vertex = Vec::with_capacity(attributes.stride());
            for (k, idx) in triangles.iter().enumerate() {
                let idx = idx.map(|i| i as usize);
                let world = idx.map(|i| {
                    instance
                        .world
                        .transform_point3(attributes.positions.get(i).copied().unwrap_or_default())
                });
                let winding = (world[1] - world[0]).cross(world[2] - world[0]);
                for &p in pieces_of.get(first + k).map_or(&[][..], Vec::as_slice) {
                    let Some((f, pos)) = piece_place.get(p as usize).copied().flatten() else {
                        continue;
                    };
                    let face = &faces.faces[f];
                    let Some(&corners) = face.triangulation.get(pos) else {
                        continue;
                    };
                    // Corners in the input triangle's winding (the importer reversed mirrored ones).
                    let mut corners = corners;
                    if winding.dot(face.normal) < 0.0 {
                        corners.swap(1, 2);
                    }
                    for back in [false, true] {
                        let Some(&s) = surface_of.get(&(face.id.0, back)) else {
                            continue;
                        };
                        let (Some(surface), Some(&rect)) = (surfaces.get(s), atlas.rects.get(s))
                        else {
                            continue;
                        };
                        let Some(page) = atlas.pages.get(rect.page as usize) else {
                            continue;
                        };
                        let builder = pages.entry(rect.page).or_default();
                        let order = if back { [0, 2, 1] } else { [0, 1, 2] };
                        for c in order.map(|c| corners[c]) {
                            vertex.clear();
                            let uv1 = lightmap_uv(surface, rect, (page.width, page.height), c);
                            attributes.vertex(idx, barycentric(c, world), back, uv1, &mut vertex);
                            builder.push(&vertex);
                        }
                    }
                }
            }
            let input = mesh_json
                .get(mesh.index())
                .and_then(|m| m.get("primitives"))
                .and_then(|p| p.get(primitive.index()));
            for (page, builder) in pages {
                if builder.indices.is_empty() {
                    continue;
                }
                let stride = attributes.stride();
                let column = |start: usize, width: usize| -> Vec<f32> {
                    builder
                        .vertices
                        .chunks_exact(stride)
                        .flat_map(|v| v[start..start + width].iter().copied())
                        .collect()
                };
                let mut attrs = Map::new();
                let mut at = 0;
                attrs.insert(
                    "POSITION".into(),
                    json!(bin.floats(&column(at, 3), 3, "VEC3", true)),
                );
                at += 3;
                if !attributes.normals.is_empty() {
                    attrs.insert(
                        "NORMAL".into(),
                        json!(bin.floats(&column(at, 3), 3, "VEC3", false)),
                    );
                    at += 3;
                }
                if !attributes.tangents.is_empty() {
                    attrs.insert(
                        "TANGENT".into(),
                        json!(bin.floats(&column(at, 4), 4, "VEC4", false)),
                    );
                    at += 4;
                }
                for (set, _) in &attributes.uvs {
                    let set = if shift && *set >= 1 { set + 1 } else { *set };
                    let a = bin.floats(&column(at, 2), 2, "VEC2", false);
                    attrs.insert(format!("TEXCOORD_{set}"), json!(a));
                    at += 2;
                }
                for (set, _) in &attributes.colors {
                    let a = bin.floats(&column(at, 4), 4, "VEC4", false);
                    attrs.insert(format!("COLOR_{set}"), json!(a));
                    at += 4;
                }
                let lightmap_uv = bin.floats(&column(at, 2), 2, "VEC2", false);
                attrs.insert("TEXCOORD_1".into(), json!(lightmap_uv));
                // Sets are numbered from 0 without gaps: a primitive without TEXCOORD_0 shares
                // the lightmap's accessor (no texture of its material reads set 0).
                attrs
                    .entry("TEXCOORD_0")
                    .or_insert_with(|| json!(lightmap_uv));
                let indices = bin.indices(&builder.indices);
                let material = material_for(primitive.material().index(), page);
                let mut out =
                    json!({"attributes": attrs, "indices": indices, "material": material});
                if let Some(extras) = input.and_then(|p| p.get("extras")) {
                    out["extras"] = extras.clone();
                }
                primitives.push(out);
            }
        }
        if primitives.is_empty() {
            continue;
        }
        let mut out = json!({"primitives": primitives});
        if let Some(m) = mesh_json.get(mesh.index()) {
            for key in ["name", "extras"] {
                if let Some(x) = m.get(key) {
                    out[key] = x.clone();
                }
            }
        }
        meshes.push(out);
        node_mesh.insert(instance.node, meshes.len() - 1);
    }

    if let Some(Value::Array(nodes)) = root.get_mut("nodes") {
        for (i, node) in nodes.iter_mut().enumerate() {
            if let Value::Object(node) = node {
                node.remove("skin");
                node.remove("weights");
                match node_mesh.get(&(i as u32)) {
                    Some(&m) => node.insert("mesh".into(), json!(m)),
                    None => node.remove("mesh"),
                };
            }
        }
    }
    let mut used: Vec<Value> = match root.remove("extensionsUsed") {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    if !used.iter().any(|e| e == LIGHTMAP_EXTENSION) {
        used.push(json!(LIGHTMAP_EXTENSION));
    }
    root.insert("extensionsUsed".into(), Value::Array(used));
    let put = |root: &mut Map<String, Value>, key: &str, list: Vec<Value>| {
        if !list.is_empty() {
            root.insert(key.into(), Value::Array(list));
        }
    };
    put(&mut root, "images", images);
    put(&mut root, "samplers", samplers);
    put(&mut root, "textures", textures);
    put(&mut root, "materials", materials);
    put(&mut root, "meshes", meshes);
    put(&mut root, "accessors", std::mem::take(&mut bin.accessors));
    put(&mut root, "bufferViews", std::mem::take(&mut bin.views));
    while !bin.data.len().is_multiple_of(4) {
        bin.data.push(0);
    }
    root.insert("buffers".into(), json!([{"byteLength": bin.data.len()}]));
    if let Some(Value::Object(asset)) = root.get_mut("asset") {
        asset.insert(
            "generator".into(),
            json!(concat!("wavrad ", env!("CARGO_PKG_VERSION"))),
        );
    }
    (Value::Object(root), bin.data)
}

/// The GLB container: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
fn write_glb((json, bin): &(Value, Vec<u8>)) -> Vec<u8> {
    let mut text = serde_json::to_vec(json).unwrap_or_default();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentrics_reproduce_the_point() {
        let w = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 1.0),
            DVec3::new(0.0, 3.0, 0.0),
        ];
        let b = [0.2, 0.5, 0.3];
        let p = w[0] * b[0] + w[1] * b[1] + w[2] * b[2];
        let got = barycentric(p, w);
        for k in 0..3 {
            assert!((got[k] - b[k]).abs() < 1e-12, "{got:?}");
        }
    }

    #[test]
    fn texcoords_from_one_up_move_up_by_one() {
        let mut m = json!({"occlusionTexture": {"index": 0, "texCoord": 1},
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 1, "texCoord": 0,
                "extensions": {"KHR_texture_transform": {"texCoord": 2}}}}});
        shift_tex_coords(&mut m);
        assert_eq!(m["occlusionTexture"]["texCoord"], 2);
        assert_eq!(m["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"], 0);
        assert_eq!(
            m["pbrMetallicRoughness"]["baseColorTexture"]["extensions"]["KHR_texture_transform"]
                ["texCoord"],
            3
        );
    }

    #[test]
    fn srgb_encoding_matches_the_standard_curve() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(0.5), 188);
        assert_eq!(srgb8(2.0), 255);
    }
}
