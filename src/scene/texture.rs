//! Textures: base-colour and emissive images decoded to linear RGB, the sampler's wrap modes, and
//! a material's texture slot (which `TEXCOORD_n` set, which `KHR_texture_transform`).
//!
//! Owns [`Texture`] (decode, bilinear [`Texture::sample`]), [`ImageHeader`] (format and size,
//! read once before decoding), [`Wrap`], [`TextureSlot`] and [`UvTransform`]. Invariants: texels
//! are linear (glTF stores both colour textures in sRGB, decoded here with the exact sRGB transfer
//! function), finite and in `[0, 1]`; a texture has at least one texel; sampling never panics,
//! whatever the coordinates (NaN included: it reads texel 0). Alpha is ignored (surfaces are
//! opaque to light). Pinned by the unit tests below: sRGB values, wrap modes against hand-computed
//! texel indices, bilinear weights, the transform's order.

use super::Rgb;
use glam::DVec2;

/// How texture coordinates outside `[0, 1]` are mapped back (glTF sampler `wrapS` / `wrapT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// Most texels [`Texture::uniform_over`] reads for one box.
pub const MAX_UNIFORM_CHECK: i64 = 4096;

impl Wrap {
    /// Texel-space coordinate `v` of a row of `n` texels brought near the texture (the same texel
    /// after wrapping), so converting it to an integer cannot saturate.
    fn reduce(self, v: f64, n: i64) -> f64 {
        match self {
            Wrap::ClampToEdge => v.clamp(-1.0, n as f64),
            // Both periods divide 2n.
            Wrap::Repeat | Wrap::MirroredRepeat if v.abs() >= 1e9 => v.rem_euclid((2 * n) as f64),
            Wrap::Repeat | Wrap::MirroredRepeat => v,
        }
    }

    /// The texel index for integer index `i` of a row of `n` texels.
    fn index(self, i: i64, n: i64) -> usize {
        let k = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let period = i.rem_euclid(2 * n);
                if period < n {
                    period
                } else {
                    2 * n - 1 - period
                }
            }
        };
        k as usize
    }
}

/// A decoded texture in linear RGB.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    /// The glTF image's name, or `image N`, for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major, first row at `v = 0` (the image's top, as glTF defines).
    pub texels: Vec<[f32; 3]>,
    /// Wrap along `u` (S) and `v` (T).
    pub wrap: [Wrap; 2],
    /// The colour of every texel, when they are all the same (a solid texture, tiled or not).
    pub single_colour: Option<[f32; 3]>,
}

/// sRGB-encoded value in `[0, 1]` to linear (IEC 61966-2-1).
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Largest texture accepted (texels: 4096 x 4096), checked on the image's header before it is
/// decoded, so a small file claiming a huge image cannot exhaust memory.
pub const MAX_TEXELS: u64 = 1 << 24;

/// The format of an image's bytes: PNG or JPEG, else why not.
fn format_of(bytes: &[u8]) -> Result<image::ImageFormat, String> {
    let format = image::guess_format(bytes)
        .map_err(|_| "is neither a PNG nor a JPEG image (unrecognised bytes)".to_string())?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(format!(
            "is a {format:?} image: only PNG and JPEG are supported"
        ));
    }
    Ok(format)
}

/// What an image's header declares, read without decoding it: its format (PNG or JPEG) and size.
/// Read once per image: the importer bounds the scene's texels with it, then decodes by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageHeader {
    format: image::ImageFormat,
    pub width: u32,
    pub height: u32,
}

impl ImageHeader {
    /// Reads the header of a PNG or JPEG image, else says why it cannot be read.
    pub fn read(bytes: &[u8]) -> Result<ImageHeader, String> {
        let format = format_of(bytes)?;
        let (width, height) = image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
            .into_dimensions()
            .map_err(|e| format!("cannot be decoded: {e}"))?;
        Ok(ImageHeader {
            format,
            width,
            height,
        })
    }

    /// Texels the header declares.
    pub fn texels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }
}

/// sRGB-encoded colour samples (RGB triples, each sample in `0..=max`) to linear texels, through a
/// table of every sample value: 8-bit images with `max = 255`, 16-bit ones with `65535` (they keep
/// their precision).
fn linear_texels<S: Copy + Into<u16>>(samples: &[S], max: S) -> Vec<[f32; 3]> {
    let max: u16 = max.into();
    let lut: Vec<f32> = (0..=max)
        .map(|v| srgb_to_linear(f64::from(v) / f64::from(max)) as f32)
        .collect();
    samples
        .chunks_exact(3)
        .map(|p| {
            [p[0], p[1], p[2]].map(|c| {
                let c: u16 = c.into();
                lut[usize::from(c)]
            })
        })
        .collect()
}

impl Texture {
    /// Decodes a PNG or JPEG image whose colour channels are sRGB-encoded.
    pub fn decode(bytes: &[u8], name: &str, wrap: [Wrap; 2]) -> Result<Texture, String> {
        Texture::decode_with_header(bytes, ImageHeader::read(bytes)?, name, wrap)
    }

    /// [`Texture::decode`] of an image whose header was read already.
    pub fn decode_with_header(
        bytes: &[u8],
        header: ImageHeader,
        name: &str,
        wrap: [Wrap; 2],
    ) -> Result<Texture, String> {
        let ImageHeader {
            format,
            width,
            height,
        } = header;
        if width == 0 || height == 0 || header.texels() > MAX_TEXELS {
            return Err(format!(
                "is {width} x {height} texels: empty, or more than the {MAX_TEXELS} accepted"
            ));
        }
        let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(width);
        limits.max_image_height = Some(height);
        // RGBA16, the largest decoded form, plus the decoder's own buffers.
        limits.max_alloc = Some(header.texels() * 8 + (16 << 20));
        reader.limits(limits);
        let decoded = reader
            .decode()
            .map_err(|e| format!("cannot be decoded: {e}"))?;
        if (decoded.width(), decoded.height()) != (width, height) {
            return Err("decodes to other dimensions than its header declares".into());
        }
        // 16-bit images keep their precision; everything else goes through 8 bits.
        let texels = if matches!(
            decoded.color(),
            image::ColorType::Rgb16
                | image::ColorType::Rgba16
                | image::ColorType::L16
                | image::ColorType::La16
        ) {
            linear_texels(decoded.to_rgb16().as_raw(), u16::MAX)
        } else {
            linear_texels(decoded.to_rgb8().as_raw(), u8::MAX)
        };
        Ok(Texture::from_texels(name, width, height, texels, wrap))
    }

    /// A texture of linear texels (row-major, `width * height` of them).
    pub fn from_texels(
        name: &str,
        width: u32,
        height: u32,
        texels: Vec<[f32; 3]>,
        wrap: [Wrap; 2],
    ) -> Texture {
        debug_assert_eq!(texels.len(), width as usize * height as usize);
        let single_colour = texels
            .first()
            .copied()
            .filter(|first| texels.iter().all(|t| t == first));
        Texture {
            name: name.to_owned(),
            width,
            height,
            texels,
            wrap,
            single_colour,
        }
    }

    fn texel(&self, x: usize, y: usize) -> [f32; 3] {
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear sample at texture coordinates `uv` (texel centres at `(i + 0.5) / width`), the
    /// sampler's wrap modes applied to the texel indices.
    pub fn sample(&self, uv: DVec2) -> Rgb {
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let x = if uv.x.is_finite() {
            uv.x * w as f64 - 0.5
        } else {
            0.0
        };
        let y = if uv.y.is_finite() {
            uv.y * h as f64 - 0.5
        } else {
            0.0
        };
        let (x, y) = (self.wrap[0].reduce(x, w), self.wrap[1].reduce(y, h));
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xs = [self.wrap[0].index(x0, w), self.wrap[0].index(x0 + 1, w)];
        let ys = [self.wrap[1].index(y0, h), self.wrap[1].index(y0 + 1, h)];
        let mut out = [0.0; 3];
        for (j, &yy) in ys.iter().enumerate() {
            let wy = if j == 0 { 1.0 - fy } else { fy };
            for (i, &xx) in xs.iter().enumerate() {
                let wx = if i == 0 { 1.0 - fx } else { fx };
                let t = self.texel(xx, yy);
                for c in 0..3 {
                    out[c] += wx * wy * f64::from(t[c]);
                }
            }
        }
        out
    }

    /// The colour every bilinear sample in the box `[lo, hi]` of texture coordinates reads, when
    /// they all read the same one (every texel the box reaches holds it). `None` when they differ,
    /// and for boxes reaching more than [`MAX_UNIFORM_CHECK`] texels of a texture of several
    /// colours (not checked: the caller treats the box as varying).
    pub fn uniform_over(&self, lo: DVec2, hi: DVec2) -> Option<[f32; 3]> {
        if let Some(c) = self.single_colour {
            return Some(c);
        }
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let far = |v: f64| !v.is_finite() || v.abs() > 1e9;
        if far(lo.x) || far(lo.y) || far(hi.x) || far(hi.y) {
            return None;
        }
        let x0 = (lo.x * w as f64 - 0.5).floor() as i64;
        let x1 = (hi.x * w as f64 - 0.5).floor() as i64 + 1;
        let y0 = (lo.y * h as f64 - 0.5).floor() as i64;
        let y1 = (hi.y * h as f64 - 0.5).floor() as i64 + 1;
        if (x1 - x0 + 1) * (y1 - y0 + 1) > MAX_UNIFORM_CHECK {
            return None;
        }
        let first = self.texel(self.wrap[0].index(x0, w), self.wrap[1].index(y0, h));
        for y in y0..=y1 {
            let yy = self.wrap[1].index(y, h);
            for x in x0..=x1 {
                if self.texel(self.wrap[0].index(x, w), yy) != first {
                    return None;
                }
            }
        }
        Some(first)
    }
}

/// `KHR_texture_transform`: `uv' = offset + R(rotation) (scale * uv)`, applied to the texture
/// coordinates as they are read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    pub offset: DVec2,
    pub rotation: f64,
    pub scale: DVec2,
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform {
        offset: DVec2::ZERO,
        rotation: 0.0,
        scale: DVec2::ONE,
    };

    pub fn apply(&self, uv: DVec2) -> DVec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        // The extension's matrix: rows (cos, sin) and (-sin, cos).
        self.offset + DVec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y)
    }
}

/// A material's use of a texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureSlot {
    /// Index into `Scene::textures`.
    pub texture: u32,
    /// The `TEXCOORD_n` set (after the transform's own `texCoord` override).
    pub tex_coord: u32,
    pub transform: UvTransform,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tex(w: u32, h: u32, values: &[f32], wrap: Wrap) -> Texture {
        Texture::from_texels(
            "t",
            w,
            h,
            values.iter().map(|&v| [v, v, v]).collect(),
            [wrap; 2],
        )
    }

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-12);
        // 0.5 sRGB is 0.21404 linear; 0.04 is on the linear segment.
        assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-7);
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-15);
    }

    #[test]
    fn wrap_modes_map_indices_as_the_spec_says() {
        assert_eq!(Wrap::Repeat.index(-1, 4), 3);
        assert_eq!(Wrap::Repeat.index(5, 4), 1);
        assert_eq!(Wrap::ClampToEdge.index(-3, 4), 0);
        assert_eq!(Wrap::ClampToEdge.index(9, 4), 3);
        // Mirrored: 0 1 2 3 | 3 2 1 0 | 0 1 ...
        let mirrored: Vec<usize> = (-2..10).map(|i| Wrap::MirroredRepeat.index(i, 4)).collect();
        assert_eq!(mirrored, vec![1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0, 1]);
    }

    #[test]
    fn bilinear_sampling_interpolates_between_texel_centres() {
        let t = tex(2, 1, &[0.0, 1.0], Wrap::ClampToEdge);
        // Texel centres at u = 0.25 and 0.75.
        assert!((t.sample(DVec2::new(0.25, 0.5))[0]).abs() < 1e-12);
        assert!((t.sample(DVec2::new(0.75, 0.5))[0] - 1.0).abs() < 1e-12);
        assert!((t.sample(DVec2::new(0.5, 0.5))[0] - 0.5).abs() < 1e-12);
        assert!((t.sample(DVec2::new(0.375, 0.5))[0] - 0.25).abs() < 1e-12);
        // Clamped beyond the edges, repeated otherwise (u = 1.0 is halfway back to texel 0).
        assert!((t.sample(DVec2::new(1.0, 0.5))[0] - 1.0).abs() < 1e-12);
        let r = tex(2, 1, &[0.0, 1.0], Wrap::Repeat);
        assert!((r.sample(DVec2::new(1.0, 0.5))[0] - 0.5).abs() < 1e-12);
        assert!((r.sample(DVec2::new(-0.75, 0.5))[0]).abs() < 1e-12);
        // Never panics on wild coordinates, and far ones keep their period: 2^40 + 0.25 is 0.25.
        let _ = r.sample(DVec2::new(f64::NAN, 1e300));
        let _ = t.sample(DVec2::new(-1e18, f64::INFINITY));
        let far = r.sample(DVec2::new(1_099_511_627_776.25, 0.5))[0];
        assert!(
            (far - r.sample(DVec2::new(0.25, 0.5))[0]).abs() < 1e-3,
            "{far}"
        );
        let m = tex(2, 1, &[0.0, 1.0], Wrap::MirroredRepeat);
        let far = m.sample(DVec2::new(1_099_511_627_776.25, 0.5))[0];
        assert!(
            (far - m.sample(DVec2::new(0.25, 0.5))[0]).abs() < 1e-3,
            "{far}"
        );
        assert_eq!(t.sample(DVec2::new(-1e300, 0.5))[0], 0.0);
        assert_eq!(t.sample(DVec2::new(1e300, 0.5))[0], 1.0);
    }

    #[test]
    fn uniform_over_sees_every_texel_a_sample_can_reach() {
        let t = tex(4, 1, &[0.2, 0.2, 0.2, 0.8], Wrap::ClampToEdge);
        assert_eq!(
            t.uniform_over(DVec2::new(0.1, 0.0), DVec2::new(0.3, 1.0)),
            Some([0.2; 3])
        );
        // u = 0.6 is past texel 2's centre: it blends with texel 3.
        assert_eq!(
            t.uniform_over(DVec2::new(0.1, 0.0), DVec2::new(0.65, 1.0)),
            None
        );
    }

    #[test]
    fn the_transform_scales_then_rotates_then_offsets() {
        let tr = UvTransform {
            offset: DVec2::new(0.5, 0.0),
            rotation: std::f64::consts::FRAC_PI_2,
            scale: DVec2::new(2.0, 1.0),
        };
        // (1, 0) -> scale (2, 0) -> rotate: (cos*2 + 0, -sin*2) = (0, -2) -> offset (0.5, -2).
        let p = tr.apply(DVec2::new(1.0, 0.0));
        assert!((p - DVec2::new(0.5, -2.0)).length() < 1e-12);
        assert_eq!(
            UvTransform::IDENTITY.apply(DVec2::new(0.3, 0.7)),
            DVec2::new(0.3, 0.7)
        );
    }

    #[test]
    fn decode_reads_png_as_srgb_and_refuses_garbage() {
        let mut bytes = Vec::new();
        let img = image::RgbImage::from_raw(1, 1, vec![128, 0, 255]).unwrap();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
        let t = Texture::decode(&bytes, "p", [Wrap::Repeat; 2]).unwrap();
        assert!((f64::from(t.texels[0][0]) - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert_eq!(t.texels[0][1], 0.0);
        assert_eq!(t.texels[0][2], 1.0);
        assert!(Texture::decode(b"not an image", "g", [Wrap::Repeat; 2]).is_err());
        assert!(Texture::decode(&bytes[..bytes.len() / 2], "h", [Wrap::Repeat; 2]).is_err());
    }
}
