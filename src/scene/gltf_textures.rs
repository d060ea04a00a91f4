//! The textures of a glTF import: which images the materials use (base colour and emissive; others,
//! such as normal maps, are not read), the scene's texel budget ([`MAX_SCENE_TEXELS`], checked on
//! the images' headers before anything is decoded, each header read once), parallel decoding, a
//! material's [`TextureSlot`] (`TEXCOORD_n`, `KHR_texture_transform`) and a primitive's texture
//! coordinates. Invariant: a texture a material names is either decoded or reported as a
//! [`Problem`] naming its image; a `TEXCOORD_n` a texture needs is read or reported, never dropped.

use super::buffers::{read_uri, ExternalFiles};
use super::error::Problem;
use super::texture::{ImageHeader, Texture, TextureSlot, UvTransform, Wrap};
use glam::DVec2;
use rayon::prelude::*;

/// Most texels all of a scene's base colour and emissive textures may hold together (a limit on
/// the memory an upload can claim: 12 bytes a texel once decoded).
pub const MAX_SCENE_TEXELS: u64 = 1 << 26;

fn wrap_of(mode: gltf::texture::WrappingMode) -> Wrap {
    use gltf::texture::WrappingMode as M;
    match mode {
        M::Repeat => Wrap::Repeat,
        M::MirroredRepeat => Wrap::MirroredRepeat,
        M::ClampToEdge => Wrap::ClampToEdge,
    }
}

/// A texture before decoding: its index, its place for messages, its wrap modes, its bytes and
/// header (or why they could not be read).
type EncodedTexture = (
    usize,
    String,
    [Wrap; 2],
    Result<(Vec<u8>, ImageHeader), String>,
);

/// Decodes every texture a material uses as its base colour or emissive texture (others, such as
/// normal maps, are not read). Returns the decoded textures and, per glTF texture index, its
/// index among them. An image that cannot be read or decoded is a problem naming it.
pub(super) fn read_textures(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    external: &ExternalFiles,
    problems: &mut Vec<Problem>,
) -> (Vec<std::sync::Arc<Texture>>, Vec<Option<u32>>) {
    let mut used = vec![false; document.textures().len()];
    for m in document.materials() {
        let infos = [
            m.pbr_metallic_roughness().base_color_texture(),
            m.emissive_texture(),
        ];
        for info in infos.into_iter().flatten() {
            used[info.texture().index()] = true;
        }
    }
    // The encoded images first, with their declared sizes: the scene's total is bounded before
    // anything is decoded.
    let mut total_texels = 0u64;
    let sources: Vec<EncodedTexture> = document
        .textures()
        .filter(|t| used[t.index()])
        .map(|t| {
            let image = t.source();
            let place = match image.name() {
                Some(n) => format!("image {} ('{n}')", image.index()),
                None => format!("image {}", image.index()),
            };
            let sampler = t.sampler();
            let wrap = [wrap_of(sampler.wrap_s()), wrap_of(sampler.wrap_t())];
            let encoded = match image.source() {
                gltf::image::Source::View { view, .. } => buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
                    .map(<[u8]>::to_vec)
                    .ok_or_else(|| "its bufferView runs past its buffer".to_string()),
                gltf::image::Source::Uri { uri, .. } => read_uri(uri, external),
            }
            .and_then(|bytes| {
                let header = ImageHeader::read(&bytes)?;
                total_texels += header.texels();
                Ok((bytes, header))
            });
            (t.index(), place, wrap, encoded)
        })
        .collect();
    if total_texels > MAX_SCENE_TEXELS {
        problems.push(Problem {
            place: "textures".into(),
            message: format!(
                "the base colour and emissive textures hold {total_texels} texels in all, more than the {MAX_SCENE_TEXELS} accepted: scale them down"
            ),
        });
        return (Vec::new(), vec![None; used.len()]);
    }
    let decoded: Vec<(usize, Result<Texture, Problem>)> = sources
        .into_par_iter()
        .map(|(index, place, wrap, encoded)| {
            let texture = encoded
                .and_then(|(bytes, header)| {
                    Texture::decode_with_header(&bytes, header, &place, wrap)
                })
                .map_err(|message| Problem {
                    place: format!("{place} (texture {index})"),
                    message,
                });
            (index, texture)
        })
        .collect();
    let mut textures = Vec::new();
    let mut texture_of = vec![None; used.len()];
    for (index, result) in decoded {
        match result {
            Ok(t) => {
                texture_of[index] = Some(textures.len() as u32);
                textures.push(std::sync::Arc::new(t));
            }
            Err(p) => problems.push(p),
        }
    }
    (textures, texture_of)
}

pub(super) fn texture_slot(
    info: &gltf::texture::Info,
    texture_of: &[Option<u32>],
) -> Option<TextureSlot> {
    let texture = texture_of.get(info.texture().index()).copied().flatten()?;
    let (tex_coord, transform) = match info.texture_transform() {
        Some(t) => (
            t.tex_coord().unwrap_or(info.tex_coord()),
            UvTransform {
                offset: DVec2::from(t.offset().map(f64::from)),
                rotation: f64::from(t.rotation()),
                scale: DVec2::from(t.scale().map(f64::from)),
            },
        ),
        None => (info.tex_coord(), UvTransform::IDENTITY),
    };
    Some(TextureSlot {
        texture,
        tex_coord,
        transform,
    })
}

/// Per texture slot (base colour, emissive) of a primitive's material, the texture coordinates of
/// each vertex with the slot's transform applied (empty for a slot without a texture). A
/// `TEXCOORD_n` a texture needs that the primitive lacks, or whose count or values are wrong, is
/// a problem (`None`): a texture is never silently dropped.
pub(super) fn read_uv_sets(
    primitive: &gltf::Primitive,
    buffers: &[Vec<u8>],
    place: &str,
    slots: [Option<TextureSlot>; 2],
    vertices: usize,
    problems: &mut Vec<Problem>,
) -> Option<[Vec<DVec2>; 2]> {
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
    let mut sets: [Vec<DVec2>; 2] = Default::default();
    let names = ["baseColorTexture", "emissiveTexture"];
    for (k, slot) in slots.iter().enumerate() {
        let Some(slot) = slot else { continue };
        let set = slot.tex_coord;
        let Some(read) = reader.read_tex_coords(set) else {
            problems.push(Problem {
                place: place.to_owned(),
                message: format!(
                    "its material's {} reads TEXCOORD_{set}, which the primitive lacks (or its accessor runs past its buffer)",
                    names[k]
                ),
            });
            return None;
        };
        let uvs: Vec<DVec2> = read
            .into_f32()
            .map(|[u, v]| slot.transform.apply(DVec2::new(f64::from(u), f64::from(v))))
            .collect();
        if uvs.len() != vertices || uvs.iter().any(|p| !p.is_finite()) {
            problems.push(Problem {
                place: place.to_owned(),
                message: format!(
                    "TEXCOORD_{set} has {} values for {vertices} vertices, or a NaN/infinite one",
                    uvs.len()
                ),
            });
            return None;
        }
        sets[k] = uvs;
    }
    Some(sets)
}
