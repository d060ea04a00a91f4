//! The lightmap's EXR pages: RGBA texels (f32, or f16 for half pages) written atomically with
//! the exr crate's fast lossless encoding and the tiles in increasing order, so two bakes of one
//! solution are the same bytes (`tests::exr_pages_keep_their_tile_order`).

use crate::fsutil::write_atomic_with;
use std::path::Path;

/// How the lightmap pages are encoded: the crate's fast lossless default (RLE, 64 x 64 tiles),
/// the tiles in increasing order. Its default leaves the order to the threads that compress
/// them, so two bakes of one solution differed byte for byte
/// (`tests::exr_pages_keep_their_tile_order`).
const EXR_ENCODING: exr::prelude::Encoding = exr::prelude::Encoding {
    line_order: exr::prelude::LineOrder::Increasing,
    ..exr::prelude::Encoding::FAST_LOSSLESS
};

pub(super) fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    texels: &[[f32; 4]],
    float: bool,
) -> std::io::Result<()> {
    use exr::prelude::{Image, IntoSample, SpecificChannels, Vec2, WritableImage};
    let size = (width as usize, height as usize);
    // Every texel's channels as `sample` makes them (f32, or f16 for half pages).
    fn encode<S: IntoSample>(
        tmp: &Path,
        size: (usize, usize),
        texels: &[[f32; 4]],
        sample: impl Fn(f32) -> S + Sync,
    ) -> exr::error::UnitResult {
        let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
            let t = texels[y * size.0 + x];
            (sample(t[0]), sample(t[1]), sample(t[2]), sample(t[3]))
        });
        Image::from_encoded_channels(size, EXR_ENCODING, channels)
            .write()
            .to_file(tmp)
    }
    write_atomic_with(path, |tmp| {
        let result = if float {
            encode(tmp, size, texels, |c| c)
        } else {
            encode(tmp, size, texels, half::f16::from_f32)
        };
        result.map_err(|e| std::io::Error::other(e.to_string()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A page written twice is the same bytes, its tiles in increasing order (the crate's
    /// default order is whatever its compressing threads finish first), and reads back.
    #[test]
    fn exr_pages_keep_their_tile_order() {
        let dir = std::env::temp_dir().join(format!("wavrad-exr-order-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let (w, h) = (300u32, 200u32);
        let texels: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [
                    (x * 0.37).sin().abs(),
                    (y * 0.11).cos().abs(),
                    x * y * 1e-4,
                    1.0,
                ]
            })
            .collect();
        for float in [false, true] {
            let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
            write_exr(&a, w, h, &texels, float).expect("write a");
            write_exr(&b, w, h, &texels, float).expect("write b");
            let meta = exr::meta::MetaData::read_from_file(&a, false).expect("exr header");
            assert_eq!(
                meta.headers[0].line_order,
                exr::prelude::LineOrder::Increasing
            );
            let bytes = |p: &Path| std::fs::read(p).expect("read back");
            assert_eq!(bytes(&a), bytes(&b), "float {float}");
            let read = exr::prelude::read_first_rgba_layer_from_file(
                &a,
                |size, _| vec![[0.0f32; 4]; size.width() * size.height()],
                move |px: &mut Vec<[f32; 4]>, p, (r, g, b, al): (f32, f32, f32, f32)| {
                    px[p.y() * w as usize + p.x()] = [r, g, b, al];
                },
            )
            .expect("read exr");
            let back = &read.layer_data.channel_data.pixels;
            let tol = if float { 0.0 } else { 1e-3 };
            for (got, want) in back.iter().zip(&texels) {
                for c in 0..4 {
                    assert!((got[c] - want[c]).abs() <= tol * want[c].abs().max(1.0));
                }
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
