//! Lightmap atlas: one rectangle per surface (face side), proportional to its frame's `|u| x |v|` at
//! the texel density (or the minimal `MINIMAL_RECT` square for a surface whose texels nobody
//! needs resolved), each inside a *cell*: the rectangle, its gutter of `gutter` texels on every
//! side, rounded up to the atlas *block*. Cells are packed into pages by `etagere`'s shelf
//! allocator, tallest first on horizontal shelves or widest first on vertical ones, from two first
//! page sizes, whichever takes fewer page texels.
//!
//! The mip rule (why the default gutter is 4 and the block 8): a mip chain of `n` levels (0 to
//! `n - 1`) built by 2 x 2 box filtering averages, at level `k`, aligned blocks of `2^k x 2^k`
//! texels, and bilinear filtering at level `k` reads the level-`k` texel under the sample point and
//! its neighbour towards the point, i.e. whole blocks reaching up to `2^(k-1)` texels (one texel at
//! level 0) past the texel holding the point. So when every cell starts on a multiple of `2^k`, has
//! a side that is a multiple of `2^k`, and its rectangle keeps `max(1, 2^(k-1))` texels of gutter,
//! sampling any point of a rectangle at levels `0..=k` (bilinear or trilinear) reads only texels
//! of its own cell. Hence the block is `max(4, 2^(1 + floor(log2 gutter)))` and a gutter `g >= 1`
//! keeps `2 + floor(log2 g)` mip levels apart ([`mip_levels_for_gutter`]): the default gutter 4
//! gives block 8 and 4 levels (0 to 3); gutter 1 gives block 4 and 2 levels. The block is never
//! below 4, so block compression (4 x 4 texel blocks) never mixes two cells either. Every texel of
//! a cell outside its face (gutter, rounding, the part of the frame outside the face) holds the
//! face's value at the nearest point (`output::render_surface`), so what a sample mixes is the face's
//! own values. Pinned by `tests/atlas.rs` (`a_four_level_mip_chain_never_mixes_two_surfaces`,
//! with its control `a_one_texel_gutter_mixes_surfaces_at_the_third_level`) and the unit test
//! `every_rectangle_point_reads_only_its_cell_at_every_safe_level`.
//!
//! Invariants (checked by [`Atlas::assert_well_formed`], pinned by
//! `random_requests_pack_well_formed_on_every_setting`): cells lie inside their page and never
//! overlap; cell corners and sides are multiples of the block; rectangles sit `gutter` texels
//! inside their cell; page sides are multiples of the block (so of 4), powers of two with
//! `pow2`, and at most `max_page_size`; more pages are opened when one is full. Same requests and
//! settings give the same atlas (`packing_is_deterministic`).

use etagere::{size2, AllocatorOptions, AtlasAllocator};

/// Default largest page side, in texels.
pub const DEFAULT_MAX_PAGE_SIZE: u32 = 4096;
/// Smallest `max_page_size` accepted.
pub const MIN_MAX_PAGE_SIZE: u32 = 256;
/// Largest `max_page_size` accepted.
pub const MAX_MAX_PAGE_SIZE: u32 = 16384;
/// Largest rectangle side, in texels (a huge face is sampled more coarsely rather than overflowing).
pub const MAX_RECT_SIZE: u32 = 1024;
/// Default gutter: four mip levels kept apart (see the module header).
pub const DEFAULT_GUTTER: u32 = 4;
/// Largest gutter accepted (block 64: seven mip levels).
pub const MAX_GUTTER: u32 = 32;
/// Side of the rectangle of a surface nobody needs resolved (at most its natural size).
pub const MINIMAL_RECT: u32 = 4;
/// Texels aimed for in all when the job does not set the density.
pub const DEFAULT_TEXEL_BUDGET: f64 = 1_048_576.0;
/// Cells placed on one page at most: `etagere` indexes its items with `u16`, and a page of small
/// cells could exceed that (each allocation adds at most one item and one shelf).
const MAX_CELLS_PER_PAGE: usize = 16_000;

/// How the atlas is laid out (CLI `--gutter`, `--atlas-max-size`, `--atlas-pow2`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AtlasSettings {
    /// Texels of gutter on every side of each rectangle.
    pub gutter: u32,
    /// Largest page side, a multiple of 4 in `[MIN_MAX_PAGE_SIZE, MAX_MAX_PAGE_SIZE]`.
    pub max_page_size: u32,
    /// Page sides are powers of two (at most the largest power of two within `max_page_size`).
    pub pow2: bool,
}

impl Default for AtlasSettings {
    fn default() -> Self {
        AtlasSettings {
            gutter: DEFAULT_GUTTER,
            max_page_size: DEFAULT_MAX_PAGE_SIZE,
            pow2: false,
        }
    }
}

impl AtlasSettings {
    /// Checks the settings; the error names the parameter (HTTP names) and the accepted range.
    pub fn validate(&self) -> Result<(), String> {
        if self.gutter > MAX_GUTTER {
            return Err(format!(
                "gutter must be in [0, {MAX_GUTTER}] texels (got {})",
                self.gutter
            ));
        }
        let m = self.max_page_size;
        if !(MIN_MAX_PAGE_SIZE..=MAX_MAX_PAGE_SIZE).contains(&m) || !m.is_multiple_of(4) {
            return Err(format!(
                "atlas_max_size must be a multiple of 4 in [{MIN_MAX_PAGE_SIZE}, \
                 {MAX_MAX_PAGE_SIZE}] texels (got {m})"
            ));
        }
        Ok(())
    }

    /// The alignment of cells and page sides: see [`block_for_gutter`].
    pub fn block(&self) -> u32 {
        block_for_gutter(self.gutter)
    }

    /// The largest page side these settings allow: a multiple of the block, or a power of two.
    pub fn page_limit(&self) -> u32 {
        let m = self.max_page_size.max(MIN_MAX_PAGE_SIZE);
        if self.pow2 {
            1 << (31 - m.leading_zeros())
        } else {
            m / self.block() * self.block()
        }
    }
}

/// Cell alignment for a gutter: `max(4, 2^(1 + floor(log2 gutter)))` (4 for no gutter).
pub fn block_for_gutter(gutter: u32) -> u32 {
    if gutter == 0 {
        4
    } else {
        (2u32 << (31 - gutter.leading_zeros())).max(4)
    }
}

/// Mip levels (0 to n - 1) whose bilinear samples of a rectangle read only its own cell: `2 +
/// floor(log2 gutter)`, 0 without a gutter (level 0 already reads half a texel outside).
pub fn mip_levels_for_gutter(gutter: u32) -> u32 {
    if gutter == 0 {
        0
    } else {
        2 + (31 - gutter.leading_zeros())
    }
}

/// What one surface asks of the atlas.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectRequest {
    /// The frame's `|u|` and `|v|`, metres.
    pub width_m: f64,
    pub height_m: f64,
    /// Nobody needs the surface resolved: it gets at most `MINIMAL_RECT` texels a side.
    pub minimal: bool,
}

/// A root's place in the atlas (the face texels, gutter excluded).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AtlasRect {
    pub page: u32,
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

/// A rectangle's cell: the rectangle, its gutter and the rounding to the block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cell {
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
    /// One per request, in request order.
    pub rects: Vec<AtlasRect>,
    pub pages: Vec<Page>,
    pub settings: AtlasSettings,
}

/// The density that spends about [`DEFAULT_TEXEL_BUDGET`] texels on the surfaces that are resolved
/// (minimal ones aside).
pub fn default_density(requests: &[RectRequest]) -> f64 {
    let area: f64 = requests
        .iter()
        .filter(|r| !r.minimal)
        .map(|r| r.width_m * r.height_m)
        .sum();
    if area > 0.0 && area.is_finite() {
        (DEFAULT_TEXEL_BUDGET / area).sqrt()
    } else {
        1.0
    }
}

fn round_up(x: u32, to: u32) -> u32 {
    x.div_ceil(to) * to
}

impl Atlas {
    /// Packs one rectangle per request at `texels_per_meter`. Settings out of range are clamped
    /// into it (validate them first to refuse them).
    pub fn pack(
        requests: &[RectRequest],
        texels_per_meter: f64,
        settings: &AtlasSettings,
    ) -> Atlas {
        let settings = AtlasSettings {
            gutter: settings.gutter.min(MAX_GUTTER),
            max_page_size: settings
                .max_page_size
                .clamp(MIN_MAX_PAGE_SIZE, MAX_MAX_PAGE_SIZE),
            pow2: settings.pow2,
        };
        let (g, block, limit) = (settings.gutter, settings.block(), settings.page_limit());
        let max_rect = MAX_RECT_SIZE.min(limit - 2 * g);
        let size = |len: f64| ((len * texels_per_meter).ceil() as u32).clamp(1, max_rect);
        let sizes: Vec<(u32, u32)> = requests
            .iter()
            .map(|r| {
                let (w, h) = (size(r.width_m), size(r.height_m));
                if r.minimal {
                    (w.min(MINIMAL_RECT), h.min(MINIMAL_RECT))
                } else {
                    (w, h)
                }
            })
            .collect();
        let cells: Vec<(u32, u32)> = sizes
            .iter()
            .map(|&(w, h)| (round_up(w + 2 * g, block), round_up(h + 2 * g, block)))
            .collect();
        let (places, pages) = pack_cells(&cells, &settings);
        let rects = places
            .iter()
            .zip(&sizes)
            .map(|(&(page, x, y), &(w, h))| AtlasRect {
                page,
                x: x + g,
                y: y + g,
                w,
                h,
            })
            .collect();
        let atlas = Atlas {
            texels_per_meter,
            rects,
            pages,
            settings,
        };
        debug_assert!(atlas.check().is_ok(), "{:?}", atlas.check());
        atlas
    }

    /// The cell of rectangle `i`.
    pub fn cell(&self, i: usize) -> Cell {
        let r = self.rects[i];
        let (g, block) = (self.settings.gutter, self.settings.block());
        Cell {
            x: r.x - g,
            y: r.y - g,
            w: round_up(r.w + 2 * g, block),
            h: round_up(r.h + 2 * g, block),
        }
    }

    /// Rectangle texels (gutters excluded) over page texels.
    pub fn efficiency(&self) -> f64 {
        let used: u64 = self.rects.iter().map(|r| r.w as u64 * r.h as u64).sum();
        let total: u64 = self
            .pages
            .iter()
            .map(|p| p.width as u64 * p.height as u64)
            .sum();
        if total > 0 {
            used as f64 / total as f64
        } else {
            0.0
        }
    }

    fn check(&self) -> Result<(), String> {
        let (g, block) = (self.settings.gutter, self.settings.block());
        let limit = self.settings.page_limit();
        for p in &self.pages {
            if p.width == 0 || p.height == 0 || p.width > limit || p.height > limit {
                return Err(format!("page {p:?} empty or above {limit}"));
            }
            if !p.width.is_multiple_of(block) || !p.height.is_multiple_of(block) {
                return Err(format!("page {p:?} not a multiple of the block {block}"));
            }
            if self.settings.pow2 && !(p.width.is_power_of_two() && p.height.is_power_of_two()) {
                return Err(format!("page {p:?} not a power of two"));
            }
        }
        // Occupancy in blocks, per page: cells are whole blocks, so this finds every overlap.
        let mut occupied: Vec<Vec<bool>> = self
            .pages
            .iter()
            .map(|p| vec![false; ((p.width / block) * (p.height / block)) as usize])
            .collect();
        for (i, r) in self.rects.iter().enumerate() {
            let p = self
                .pages
                .get(r.page as usize)
                .ok_or(format!("rect {i} on a missing page"))?;
            if r.x < g || r.y < g || r.w == 0 || r.h == 0 {
                return Err(format!("rect {i} {r:?} has no room for its gutter"));
            }
            let c = self.cell(i);
            if !c.x.is_multiple_of(block) || !c.y.is_multiple_of(block) {
                return Err(format!("cell {i} {c:?} not aligned to {block}"));
            }
            if c.x + c.w > p.width || c.y + c.h > p.height {
                return Err(format!("cell {i} {c:?} leaves page {p:?}"));
            }
            let row = p.width / block;
            for by in c.y / block..(c.y + c.h) / block {
                for bx in c.x / block..(c.x + c.w) / block {
                    let k = (by * row + bx) as usize;
                    if std::mem::replace(&mut occupied[r.page as usize][k], true) {
                        return Err(format!(
                            "cell {i} {c:?} overlaps another on page {}",
                            r.page
                        ));
                    }
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

/// `(page, x, y)` per cell, and the pages.
type Packing = (Vec<(u32, u32, u32)>, Vec<Page>);

/// Places cells on pages with horizontal shelves (tallest first) and with vertical ones (widest
/// first), each from a first page 10 % larger than the area grown by quarters and from one just the
/// area grown by sixteenths, and keeps the packing with the fewest page texels (the first of the
/// candidates on a tie).
fn pack_cells(cells: &[(u32, u32)], settings: &AtlasSettings) -> Packing {
    let texels =
        |p: &Packing| -> u64 { p.1.iter().map(|p| p.width as u64 * p.height as u64).sum() };
    let mut best: Option<(u64, Packing)> = None;
    for (slack, growth) in [(1.1, 4), (1.0, 16)] {
        for vertical in [false, true] {
            let packing = pack_cells_on_shelves(cells, settings, vertical, slack, growth);
            let t = texels(&packing);
            if best.as_ref().is_none_or(|(b, _)| t < *b) {
                best = Some((t, packing));
            }
        }
    }
    best.map(|(_, p)| p).unwrap_or_default()
}

/// Places cells (sides multiples of the block, at most the page limit) on pages. Tallest cells
/// first (ties: wider first, then index; widths and heights swapped with `vertical` shelves). Each
/// page is first tried as a square of `slack` times the area left, grown (by 2 with `pow2`, else
/// by `1 / growth`) until everything fits or it reaches the limit, then cut to what it holds.
fn pack_cells_on_shelves(
    cells: &[(u32, u32)],
    settings: &AtlasSettings,
    vertical: bool,
    slack: f64,
    growth: u32,
) -> Packing {
    let (block, limit) = (settings.block(), settings.page_limit());
    let fit = |side: u32| -> u32 {
        let side = side.max(block);
        if settings.pow2 {
            side.next_power_of_two().min(limit)
        } else {
            round_up(side, block).min(limit)
        }
    };
    let mut order: Vec<usize> = (0..cells.len()).collect();
    order.sort_by_key(|&i| {
        let (w, h) = cells[i];
        let (along, across) = if vertical { (h, w) } else { (w, h) };
        (std::cmp::Reverse(across), std::cmp::Reverse(along), i)
    });
    let mut places = vec![(0u32, 0u32, 0u32); cells.len()];
    let mut pages = Vec::new();
    let mut remaining = order;
    while !remaining.is_empty() {
        let area: f64 = remaining
            .iter()
            .map(|&i| cells[i].0 as f64 * cells[i].1 as f64)
            .sum();
        let largest = remaining
            .iter()
            .map(|&i| cells[i].0.max(cells[i].1))
            .max()
            .unwrap_or(block);
        let mut side = fit(((area * slack).sqrt().ceil() as u32).max(largest));
        let (placed, rest) = loop {
            let (placed, rest) = fill_page(side, &remaining, cells, block, vertical);
            if rest.is_empty() || side >= limit {
                break (placed, rest);
            }
            side = if settings.pow2 {
                fit(side * 2)
            } else {
                fit(side + (side / growth).max(block))
            };
        };
        let page = pages.len() as u32;
        let (mut width, mut height) = (block, block);
        if placed.is_empty() {
            // Cannot happen (a cell fits an empty page at the limit); never loop forever.
            let i = remaining[0];
            places[i] = (page, 0, 0);
            width = cells[i].0;
            height = cells[i].1;
            remaining.remove(0);
        } else {
            for &(i, x, y) in &placed {
                places[i] = (page, x, y);
                width = width.max(x + cells[i].0);
                height = height.max(y + cells[i].1);
            }
            remaining = rest;
        }
        if settings.pow2 {
            width = width.next_power_of_two();
            height = height.next_power_of_two();
        }
        pages.push(Page { width, height });
    }
    (places, pages)
}

/// Allocates `order`'s cells, in order, on one `side x side` page: the placed `(cell, x, y)` and
/// the cells left over (in order).
fn fill_page(
    side: u32,
    order: &[usize],
    cells: &[(u32, u32)],
    block: u32,
    vertical: bool,
) -> (Vec<(usize, u32, u32)>, Vec<usize>) {
    let to_i32 = |v: u32| i32::try_from(v).unwrap_or(i32::MAX);
    let options = AllocatorOptions {
        alignment: size2(to_i32(block), to_i32(block)),
        vertical_shelves: vertical,
        ..AllocatorOptions::default()
    };
    let mut allocator = AtlasAllocator::with_options(size2(to_i32(side), to_i32(side)), &options);
    let mut placed = Vec::new();
    let mut rest = Vec::new();
    for &i in order {
        let (w, h) = cells[i];
        let allocation = if placed.len() < MAX_CELLS_PER_PAGE {
            allocator.allocate(size2(to_i32(w), to_i32(h)))
        } else {
            None
        };
        let at = allocation.and_then(|a| {
            let (x, y) = (a.rectangle.min.x, a.rectangle.min.y);
            Some((u32::try_from(x).ok()?, u32::try_from(y).ok()?))
        });
        match at {
            Some((x, y)) => placed.push((i, x, y)),
            None => rest.push(i),
        }
    }
    (placed, rest)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random requests: mostly small faces, a few large ones, some minimal.
    fn requests(n: usize, seed: u64) -> Vec<RectRequest> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as f64 / (1u64 << 31) as f64
        };
        (0..n)
            .map(|_| {
                let big = next() < 0.05;
                let scale = if big { 8.0 } else { 1.0 };
                RectRequest {
                    width_m: 0.05 + next() * scale,
                    height_m: 0.05 + next() * scale,
                    minimal: next() < 0.1,
                }
            })
            .collect()
    }

    #[test]
    fn block_and_levels_follow_the_gutter() {
        let cases = [
            (0, 4, 0),
            (1, 4, 2),
            (2, 4, 3),
            (3, 4, 3),
            (4, 8, 4),
            (8, 16, 5),
        ];
        for (g, block, levels) in cases {
            assert_eq!(block_for_gutter(g), block, "gutter {g}");
            assert_eq!(mip_levels_for_gutter(g), levels, "gutter {g}");
        }
        assert_eq!(AtlasSettings::default().block(), 8);
        assert_eq!(mip_levels_for_gutter(DEFAULT_GUTTER), 4);
    }

    #[test]
    fn settings_are_validated_with_the_parameter_named() {
        assert!(AtlasSettings::default().validate().is_ok());
        let bad = |gutter, max_page_size| {
            AtlasSettings {
                gutter,
                max_page_size,
                pow2: false,
            }
            .validate()
            .unwrap_err()
        };
        assert!(bad(33, 4096).contains("gutter"));
        assert!(bad(4, 4098).contains("atlas_max_size"));
        assert!(bad(4, 4095).contains("multiple of 4"));
        assert!(bad(4, 128).contains("atlas_max_size"));
        assert!(bad(4, 32768).contains("atlas_max_size"));
    }

    #[test]
    fn random_requests_pack_well_formed_on_every_setting() {
        let reqs = requests(600, 7);
        for gutter in [0, 1, 2, 4, 8] {
            for pow2 in [false, true] {
                for max_page_size in [256, 1000, 4096] {
                    let settings = AtlasSettings {
                        gutter,
                        max_page_size,
                        pow2,
                    };
                    let atlas = Atlas::pack(&reqs, 40.0, &settings);
                    atlas.assert_well_formed();
                    assert_eq!(atlas.rects.len(), reqs.len());
                    for p in &atlas.pages {
                        assert!(
                            p.width.is_multiple_of(4) && p.height.is_multiple_of(4),
                            "{p:?}"
                        );
                        assert!(p.width <= max_page_size && p.height <= max_page_size);
                        if pow2 {
                            assert!(p.width.is_power_of_two() && p.height.is_power_of_two());
                        }
                    }
                    if max_page_size == 256 {
                        assert!(atlas.pages.len() > 3, "{} pages", atlas.pages.len());
                    }
                    if max_page_size == 4096 {
                        assert_eq!(atlas.pages.len(), 1);
                    }
                    for (r, q) in atlas.rects.iter().zip(&reqs) {
                        if q.minimal {
                            assert!(r.w <= MINIMAL_RECT && r.h <= MINIMAL_RECT, "{r:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_minimal_surface_gets_the_minimal_rectangle() {
        let lamp = RectRequest {
            width_m: 2.0,
            height_m: 2.0,
            minimal: true,
        };
        let wall = RectRequest {
            minimal: false,
            ..lamp
        };
        let atlas = Atlas::pack(&[lamp, wall], 100.0, &AtlasSettings::default());
        let (l, w) = (atlas.rects[0], atlas.rects[1]);
        assert_eq!((l.w, l.h), (MINIMAL_RECT, MINIMAL_RECT));
        assert_eq!((w.w, w.h), (200, 200));
        // Its cell: 4 + 2 x 4 texels of gutter, rounded up to the block of 8.
        assert_eq!((atlas.cell(0).w, atlas.cell(0).h), (16, 16));
        // The default density spends the budget on the wall only.
        let d = default_density(&[lamp, wall]);
        assert!((d - (DEFAULT_TEXEL_BUDGET / 4.0).sqrt()).abs() < 1e-9);
    }

    #[test]
    fn packing_is_deterministic() {
        let reqs = requests(400, 11);
        let settings = AtlasSettings {
            max_page_size: 512,
            ..AtlasSettings::default()
        };
        let a = Atlas::pack(&reqs, 30.0, &settings);
        let b = Atlas::pack(&reqs, 30.0, &settings);
        assert_eq!(a.rects, b.rects);
        assert_eq!(a.pages, b.pages);
    }

    /// The texels a bilinear sample at `(px, py)` reads at mip level `k` (a 2^k block-aligned
    /// chain), as level-0 texel ranges `[x0, x1) x [y0, y1)`.
    fn bilinear_footprint(px: f64, py: f64, k: u32) -> (i64, i64, i64, i64) {
        let b = 1i64 << k;
        // Level-k texel coordinates of the point: bilinear reads floor(c - 0.5) and, unless the
        // point sits on that texel's centre (weight zero), the next one.
        let axis = |p: f64| {
            let c = p / b as f64 - 0.5;
            let i = c.floor() as i64;
            let last = if c > i as f64 { i + 1 } else { i };
            (i * b, (last + 1) * b)
        };
        let ((x0, x1), (y0, y1)) = (axis(px), axis(py));
        (x0, x1, y0, y1)
    }

    /// Sample points of a rectangle: its corners, edge midpoints and texel centres near its edges.
    fn sample_points(r: &AtlasRect) -> Vec<(f64, f64)> {
        let (x0, y0) = (r.x as f64, r.y as f64);
        let (x1, y1) = (x0 + r.w as f64, y0 + r.h as f64);
        let xs = [x0, x0 + 0.5, (x0 + x1) / 2.0, x1 - 0.5, x1];
        let ys = [y0, y0 + 0.5, (y0 + y1) / 2.0, y1 - 0.5, y1];
        xs.iter()
            .flat_map(|&x| ys.iter().map(move |&y| (x, y)))
            .collect()
    }

    /// The mip rule of the module header, checked on packed atlases: for each gutter, at every
    /// level it promises, every sample of a rectangle reads texels of its own cell only; one level
    /// more reads outside some cell (so the rule is tight, and a one-texel gutter fails level 2).
    #[test]
    fn every_rectangle_point_reads_only_its_cell_at_every_safe_level() {
        let reqs = requests(300, 3);
        for gutter in [1, 2, 4, 8] {
            let settings = AtlasSettings {
                gutter,
                ..AtlasSettings::default()
            };
            let atlas = Atlas::pack(&reqs, 40.0, &settings);
            let levels = mip_levels_for_gutter(gutter);
            let mut leaks_one_level_more = false;
            for (i, r) in atlas.rects.iter().enumerate() {
                let c = atlas.cell(i);
                let inside = |f: (i64, i64, i64, i64)| {
                    f.0 >= c.x as i64
                        && f.1 <= (c.x + c.w) as i64
                        && f.2 >= c.y as i64
                        && f.3 <= (c.y + c.h) as i64
                };
                for (px, py) in sample_points(r) {
                    for k in 0..levels {
                        let f = bilinear_footprint(px, py, k);
                        assert!(inside(f), "gutter {gutter} level {k} rect {r:?} at ({px},{py}) reads {f:?} outside {c:?}");
                    }
                    leaks_one_level_more |= !inside(bilinear_footprint(px, py, levels));
                }
            }
            assert!(
                leaks_one_level_more,
                "gutter {gutter}: level {levels} also safe?"
            );
        }
    }
}
