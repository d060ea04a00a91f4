//! Lightmap atlas: one rectangle per surface (face side) (proportional to its frame's `|u| x |v|` at the
//! texel density), each surrounded by a gutter, packed on shelves into pages.
//!
//! Invariants (checked by [`Atlas::assert_well_formed`]): rectangles with their gutters lie inside
//! their page and never overlap; every page is at most `MAX_PAGE_SIZE` texels on a side.

use crate::domain::Frame;

/// Largest page side, in texels.
pub const MAX_PAGE_SIZE: u32 = 4096;
/// Largest rectangle side, in texels (a huge face is sampled more coarsely rather than overflowing).
pub const MAX_RECT_SIZE: u32 = 1024;
/// Texels of gutter on every side of a rectangle (filled from the face's edge, never black).
pub const GUTTER: u32 = 1;
/// Texels aimed for in all when the job does not set the density.
pub const DEFAULT_TEXEL_BUDGET: f64 = 1_048_576.0;

/// A root's place in the atlas (the face texels, gutter excluded).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AtlasRect {
    pub page: u32,
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Page {
    pub width: u32,
    pub height: u32,
}

#[derive(Debug, Clone)]
pub struct Atlas {
    pub texels_per_meter: f64,
    pub rects: Vec<AtlasRect>,
    pub pages: Vec<Page>,
}

/// The density that spends about [`DEFAULT_TEXEL_BUDGET`] texels on the scene's frames.
pub fn default_density(frames: &[Frame]) -> f64 {
    let area: f64 = frames.iter().map(|f| f.u.length() * f.v.length()).sum();
    if area > 0.0 {
        (DEFAULT_TEXEL_BUDGET / area).sqrt()
    } else {
        1.0
    }
}

impl Atlas {
    /// Packs one rectangle per frame at `texels_per_meter`.
    pub fn pack(frames: &[Frame], texels_per_meter: f64) -> Atlas {
        let size = |len: f64| ((len * texels_per_meter).ceil() as u32).clamp(1, MAX_RECT_SIZE);
        let sizes: Vec<(u32, u32)> = frames
            .iter()
            .map(|f| (size(f.u.length()), size(f.v.length())))
            .collect();
        let total: f64 = sizes
            .iter()
            .map(|&(w, h)| ((w + 2 * GUTTER) * (h + 2 * GUTTER)) as f64)
            .sum();
        let widest = sizes.iter().map(|s| s.0 + 2 * GUTTER).max().unwrap_or(1);
        let page_width = ((total.sqrt() * 1.15).ceil() as u32)
            .next_power_of_two()
            .clamp(widest, MAX_PAGE_SIZE);
        // Shelf packing, tallest first; ties by index for determinism.
        let mut order: Vec<usize> = (0..frames.len()).collect();
        order.sort_by_key(|&i| (std::cmp::Reverse(sizes[i].1), i));
        let mut rects = vec![
            AtlasRect {
                page: 0,
                x: 0,
                y: 0,
                w: 0,
                h: 0
            };
            frames.len()
        ];
        let mut pages = Vec::new();
        let (mut page, mut x, mut y, mut shelf_h, mut used_w) = (0u32, 0u32, 0u32, 0u32, 0u32);
        for i in order {
            let (w, h) = sizes[i];
            let (gw, gh) = (w + 2 * GUTTER, h + 2 * GUTTER);
            if x + gw > page_width {
                y += shelf_h;
                x = 0;
                shelf_h = 0;
            }
            if y + gh > MAX_PAGE_SIZE {
                pages.push(Page {
                    width: used_w.max(1),
                    height: y.max(1),
                });
                page += 1;
                x = 0;
                y = 0;
                shelf_h = 0;
                used_w = 0;
            }
            rects[i] = AtlasRect {
                page,
                x: x + GUTTER,
                y: y + GUTTER,
                w,
                h,
            };
            x += gw;
            used_w = used_w.max(x);
            shelf_h = shelf_h.max(gh);
        }
        pages.push(Page {
            width: used_w.max(1),
            height: (y + shelf_h).max(1),
        });
        let atlas = Atlas {
            texels_per_meter,
            rects,
            pages,
        };
        debug_assert!(atlas.check().is_ok());
        atlas
    }

    fn check(&self) -> Result<(), String> {
        for (i, r) in self.rects.iter().enumerate() {
            let p = self
                .pages
                .get(r.page as usize)
                .ok_or(format!("rect {i} on a missing page"))?;
            if r.x < GUTTER
                || r.y < GUTTER
                || r.x + r.w + GUTTER > p.width
                || r.y + r.h + GUTTER > p.height
            {
                return Err(format!("rect {i} {r:?} leaves page {p:?}"));
            }
            if p.width > MAX_PAGE_SIZE || p.height > MAX_PAGE_SIZE {
                return Err(format!("page {p:?} too large"));
            }
        }
        // Overlap check by sweeping pairs on each page (fine for tests and debug builds).
        for (i, a) in self.rects.iter().enumerate() {
            for b in &self.rects[i + 1..] {
                if a.page == b.page
                    && a.x < b.x + b.w + 2 * GUTTER
                    && b.x < a.x + a.w + 2 * GUTTER
                    && a.y < b.y + b.h + 2 * GUTTER
                    && b.y < a.y + a.h + 2 * GUTTER
                {
                    return Err(format!("rects {a:?} and {b:?} overlap"));
                }
            }
        }
        Ok(())
    }

    /// Panics with the first violated invariant.
    pub fn assert_well_formed(&self) {
        if let Err(e) = self.check() {
            panic!("atlas not well formed: {e}");
        }
    }
}
