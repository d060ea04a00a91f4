//! Editing GLBs for tests (`Glb`: JSON and binary chunk, views, textures, UVs) and the palette
//! images and glowing quad the texture tests share. Encodes images as the importer decodes them:
//! linear values written as sRGB bytes.

use glam::DVec3;
use serde_json::{json, Value};
use wavrad::scene::gltf_writer::{glb_from_parts, SceneBuilder};

/// A GLB taken apart for editing: its JSON and its binary chunk.
pub struct Glb {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Glb {
    pub fn parse(bytes: &[u8]) -> Glb {
        let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap()) as usize;
        let json_len = u32_at(12);
        let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        let bin = if bin_at + 8 <= bytes.len() {
            bytes[bin_at + 8..bin_at + 8 + u32_at(bin_at)].to_vec()
        } else {
            Vec::new()
        };
        Glb { json, bin }
    }

    pub fn glb_bytes(&mut self) -> Vec<u8> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.json["buffers"] = json!([{"byteLength": self.bin.len()}]);
        glb_from_parts(&self.json, &self.bin)
    }

    pub fn push_array(&mut self, key: &str, value: Value) -> usize {
        if self.json.get(key).is_none() {
            self.json[key] = json!([]);
        }
        let array = self.json[key].as_array_mut().unwrap();
        array.push(value);
        array.len() - 1
    }

    pub fn push_view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.push_array(
            "bufferViews",
            json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}),
        )
    }

    /// Adds an image (embedded in a buffer view) and a texture of it; returns the texture index.
    pub fn add_texture(&mut self, bytes: &[u8], mime: &str, sampler: Option<Value>) -> usize {
        let view = self.push_view(bytes);
        let image = self.push_array("images", json!({"bufferView": view, "mimeType": mime}));
        let mut texture = json!({"source": image});
        if let Some(s) = sampler {
            texture["sampler"] = json!(self.push_array("samplers", s));
        }
        self.push_array("textures", texture)
    }

    /// The POSITION values of mesh `m`'s first primitive (tightly packed float VEC3).
    pub fn positions(&self, m: usize) -> Vec<[f32; 3]> {
        let a = &self.json["accessors"][self.json["meshes"][m]["primitives"][0]["attributes"]
            ["POSITION"]
            .as_u64()
            .unwrap() as usize];
        let view = &self.json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        assert!(view
            .get("byteStride")
            .is_none_or(|s| s.as_u64() == Some(12)));
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let count = a["count"].as_u64().unwrap() as usize;
        (0..count)
            .map(|i| {
                let f = |k: usize| {
                    let at = start + 12 * i + 4 * k;
                    f32::from_le_bytes(self.bin[at..at + 4].try_into().unwrap())
                };
                [f(0), f(1), f(2)]
            })
            .collect()
    }

    /// Gives mesh `m`'s first primitive a `TEXCOORD_0` computed from each vertex's position.
    pub fn set_uvs(&mut self, m: usize, uv: impl Fn([f32; 3]) -> [f32; 2]) {
        let values: Vec<[f32; 2]> = self.positions(m).into_iter().map(uv).collect();
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()))
            .collect();
        let view = self.push_view(&bytes);
        let accessor = self.push_array(
            "accessors",
            json!({"bufferView": view, "componentType": 5126, "count": values.len(), "type": "VEC2"}),
        );
        self.json["meshes"][m]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(accessor);
    }
}

pub fn linear_to_srgb_byte(c: f64) -> u8 {
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Cells of this many texels per side in the palette textures (a JPEG macroblock: its chroma is
/// subsampled 2x, so smaller cells would share their colour with a neighbour).
pub const CELL: u32 = 16;

/// A row of uniform cells holding `colours` (linear, encoded as sRGB bytes).
pub fn palette_image(colours: &[[f64; 3]], format: image::ImageFormat) -> Vec<u8> {
    let width = CELL * colours.len() as u32;
    let img = image::RgbImage::from_fn(width, CELL, |x, _| {
        image::Rgb(colours[(x / CELL) as usize].map(linear_to_srgb_byte))
    });
    let mut bytes = Vec::new();
    let mut cursor = std::io::Cursor::new(&mut bytes);
    match format {
        image::ImageFormat::Jpeg => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut cursor, 95)
                .encode_image(&img)
                .unwrap();
        }
        _ => img.write_to(&mut cursor, format).unwrap(),
    }
    bytes
}

/// An emitting unit quad whose emission comes from an external PNG (`glow.png`, one texel of
/// linear 0.5 as sRGB 188) times `emissiveFactor` 1, its buffer external too (`scene.bin`): the
/// glTF JSON, the buffer and the image. `version` is written as `asset.version`.
pub fn glowing_quad_gltf(version: &str) -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    let mut b = SceneBuilder::new();
    let m = b.material([0.0; 3], [1.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    let mut glb = Glb::parse(&b.to_glb());
    glb.set_uvs(0, |p| [p[0], p[1]]);
    glb.push_array("images", json!({"uri": "glow.png"}));
    let t = glb.push_array("textures", json!({"source": 0}));
    glb.json["materials"][0]["emissiveTexture"] = json!({"index": t});
    glb.json["asset"]["version"] = json!(version);
    let _ = glb.glb_bytes();
    glb.json["buffers"][0]["uri"] = json!("scene.bin");
    let png = palette_image(&[[0.5; 3]], image::ImageFormat::Png);
    (serde_json::to_vec(&glb.json).unwrap(), glb.bin.clone(), png)
}

/// The emitted radiance sRGB byte 188 decodes to.
pub fn glow() -> f64 {
    wavrad::scene::srgb_to_linear(188.0 / 255.0)
}
