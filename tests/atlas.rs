//! The lightmap atlas for engines (issue 18): rendered pages keep every face's mip chain to its own
//! values (no black or neighbour bleed at 4 levels with the default gutter; a one-texel gutter
//! fails, which is what the test would catch), a rho = 0 emitter gets the minimal rectangle and
//! its constant radiance, result.json states the atlas, and the packing efficiency of `etagere`
//! against the shelf packer it replaced on the sample scenes and `../shared/scenes` (printed).

use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use wavrad::domain::{build_domains, DomainMode};
use wavrad::faces::merge_planar_faces;
use wavrad::output::{
    mip_levels_for_gutter, plan_atlas, render_pages, write_outputs, Atlas, AtlasSettings,
    OutputOptions,
};
use wavrad::pipeline::{bake, Prepared};
use wavrad::scene::gltf_writer::SceneBuilder;
use wavrad::scene::{load_scene, load_scene_from_path, ExternalFiles, Scene};
use wavrad::solver::{Solution, SolverParams};

/// A box of walls of different reflectances, a small rho = 0 lamp under its ceiling, and floating
/// quads of several sizes: many faces of contrasting values, packed side by side.
fn contrast_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let walls: Vec<u32> = [0.9, 0.2, 0.6, 0.4, 0.8, 0.3]
        .iter()
        .map(|&r| b.material([r, r * 0.5, 0.1], [0.0; 3], false))
        .collect();
    let lamp = b.material([0.0; 3], [4.0, 4.0, 4.0], false);
    b.inward_box(
        [walls[0], walls[1], walls[2], walls[3], walls[4], walls[5]],
        DVec3::ZERO,
        DVec3::ONE,
        1,
    );
    // The lamp faces down (u x v = -z), just under the ceiling.
    b.quad(
        lamp,
        DVec3::new(0.35, 0.35, 0.98),
        DVec3::Y * 0.3,
        DVec3::X * 0.3,
        1,
    );
    for k in 0..5 {
        let s = 0.08 + 0.06 * k as f64;
        let m = walls[k % walls.len()];
        b.quad(
            m,
            DVec3::new(0.05 + 0.18 * k as f64, 0.1, 0.1 + 0.12 * k as f64),
            DVec3::X * s,
            DVec3::Y * s,
            1,
        );
    }
    load_scene(&b.to_glb(), &ExternalFiles::Refuse, 1_000_000).expect("scene")
}

fn solve(scene: &Scene) -> (Prepared, Solution) {
    let params = SolverParams {
        order: 2,
        target_unshot: 0.02,
        tolerance: 1e-4,
        ..SolverParams::default()
    };
    bake(
        scene,
        DomainMode::Extended,
        params,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .expect("bake")
}

/// One 2 x 2 box-filter step of an RGB page (sides even).
fn downsample(texels: &[[f32; 3]], width: usize, height: usize) -> Vec<[f32; 3]> {
    let (w2, h2) = (width / 2, height / 2);
    let mut out = vec![[0.0f32; 3]; w2 * h2];
    for y in 0..h2 {
        for x in 0..w2 {
            for c in 0..3 {
                let s = texels[2 * y * width + 2 * x][c]
                    + texels[2 * y * width + 2 * x + 1][c]
                    + texels[(2 * y + 1) * width + 2 * x][c]
                    + texels[(2 * y + 1) * width + 2 * x + 1][c];
                out[y * w2 + x][c] = s / 4.0;
            }
        }
    }
    out
}

/// Bilinear sample (clamped to the edge) of mip level `k` at level-0 point `(px, py)`.
fn bilinear(level: &[[f32; 3]], width: usize, height: usize, k: u32, px: f64, py: f64) -> [f64; 3] {
    let b = (1u32 << k) as f64;
    let (cx, cy) = (px / b - 0.5, py / b - 0.5);
    let (x0, y0) = (cx.floor(), cy.floor());
    let (fx, fy) = (cx - x0, cy - y0);
    let at = |x: f64, y: f64| {
        let xi = (x.max(0.0) as usize).min(width - 1);
        let yi = (y.max(0.0) as usize).min(height - 1);
        level[yi * width + xi]
    };
    let mut v = [0.0; 3];
    for (dx, dy, wgt) in [
        (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
        (1.0, 0.0, fx * (1.0 - fy)),
        (0.0, 1.0, (1.0 - fx) * fy),
        (1.0, 1.0, fx * fy),
    ] {
        let t = at(x0 + dx, y0 + dy);
        for c in 0..3 {
            v[c] += wgt * t[c] as f64;
        }
    }
    v
}

/// Samples of the 4-level mip chain (levels 0 to 3) at every texel centre and corner of every
/// rectangle that fall outside the range of its own cell's values: `(surface, level, value,
/// range)` of the first few, and their count.
fn mip_leaks(atlas: &Atlas, pages: &[Vec<[f32; 4]>]) -> (usize, Vec<String>) {
    let mut chains = Vec::new();
    for (texels, page) in pages.iter().zip(&atlas.pages) {
        // A page whose sides are not multiples of 8 (block 4) is padded with black.
        let (pw, ph) = (page.width as usize, page.height as usize);
        let (mut w, mut h) = (pw.div_ceil(8) * 8, ph.div_ceil(8) * 8);
        let mut level0 = vec![[0.0f32; 3]; w * h];
        for y in 0..ph {
            for x in 0..pw {
                let t = texels[y * pw + x];
                level0[y * w + x] = [t[0], t[1], t[2]];
            }
        }
        let mut levels = vec![(level0, w, h)];
        for _ in 0..3 {
            let next = downsample(&levels.last().expect("level").0, w, h);
            w /= 2;
            h /= 2;
            levels.push((next, w, h));
        }
        chains.push(levels);
    }
    let (mut count, mut first) = (0, Vec::new());
    for (i, r) in atlas.rects.iter().enumerate() {
        let c = atlas.cell(i);
        let page = &pages[r.page as usize];
        let width = atlas.pages[r.page as usize].width as usize;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for y in c.y..c.y + c.h {
            for x in c.x..c.x + c.w {
                let t = page[y as usize * width + x as usize];
                for ch in 0..3 {
                    lo[ch] = lo[ch].min(t[ch] as f64);
                    hi[ch] = hi[ch].max(t[ch] as f64);
                }
            }
        }
        let chain = &chains[r.page as usize];
        let mut points = Vec::new();
        for j in 0..=2 * r.h {
            for i2 in 0..=2 * r.w {
                points.push((r.x as f64 + i2 as f64 / 2.0, r.y as f64 + j as f64 / 2.0));
            }
        }
        for k in 0..4u32 {
            let (level, lw, lh) = &chain[k as usize];
            for &(px, py) in &points {
                let v = bilinear(level, *lw, *lh, k, px, py);
                let out = (0..3).any(|ch| {
                    let eps = 1e-5 * hi[ch].abs().max(1e-6);
                    v[ch] < lo[ch] - eps || v[ch] > hi[ch] + eps
                });
                if out {
                    count += 1;
                    if first.len() < 5 {
                        first.push(format!(
                            "surface {i} level {k} at ({px}, {py}): {v:?} outside {lo:?}..{hi:?}"
                        ));
                    }
                }
            }
        }
    }
    (count, first)
}

fn options(settings: AtlasSettings) -> OutputOptions {
    OutputOptions {
        texels_per_meter: Some(48.0),
        atlas: settings,
        ..OutputOptions::default()
    }
}

/// With the default gutter (4, block 8), every bilinear sample of a face's rectangle at mip levels
/// 0 to 3 of its box-filtered page lies within the range of its own cell's values: no neighbour
/// and no empty page texel (black) is ever mixed in.
#[test]
fn a_four_level_mip_chain_never_mixes_two_surfaces() {
    let scene = contrast_scene();
    let (prepared, solution) = solve(&scene);
    let settings = AtlasSettings::default();
    assert_eq!(mip_levels_for_gutter(settings.gutter), 4);
    let atlas = plan_atlas(
        &scene,
        &prepared.faces,
        &prepared.surfaces,
        &options(settings),
    );
    atlas.assert_well_formed();
    assert!(atlas.rects.len() >= 12, "{} surfaces", atlas.rects.len());
    let pages = render_pages(&solution, &prepared.surfaces, &atlas);
    let (count, first) = mip_leaks(&atlas, &pages);
    assert_eq!(count, 0, "{first:#?}");
}

/// The control: the layout this atlas replaced (a one-texel gutter; block 4, the smallest) mixes
/// neighbours or black into faces by level 3, and the check above sees it.
#[test]
fn a_one_texel_gutter_mixes_surfaces_at_the_third_level() {
    let scene = contrast_scene();
    let (prepared, solution) = solve(&scene);
    let settings = AtlasSettings {
        gutter: 1,
        ..AtlasSettings::default()
    };
    let atlas = plan_atlas(
        &scene,
        &prepared.faces,
        &prepared.surfaces,
        &options(settings),
    );
    atlas.assert_well_formed();
    let pages = render_pages(&solution, &prepared.surfaces, &atlas);
    let (count, first) = mip_leaks(&atlas, &pages);
    assert!(count > 0, "a one-texel gutter kept 4 mip levels apart?");
    println!("one-texel gutter: {count} leaking samples, e.g. {first:#?}");
}

/// The rho = 0 lamp gets at most 4 x 4 texels, all holding its emission (radiance L_e = 4), and
/// result.json's `atlas` states gutter, block, mip levels, efficiency and minimal rectangles.
#[test]
fn a_rho_zero_emitter_gets_the_minimal_rectangle_and_result_json_states_the_atlas() {
    let scene = contrast_scene();
    let (prepared, solution) = solve(&scene);
    let dir = std::env::temp_dir().join(format!("wavrad-atlas-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let opts = options(AtlasSettings {
        pow2: true,
        ..AtlasSettings::default()
    });
    let result = write_outputs(&dir, &scene, &prepared, &solution, &opts).expect("outputs");
    let atlas = plan_atlas(&scene, &prepared.faces, &prepared.surfaces, &opts);
    let lamp_material = scene
        .materials
        .iter()
        .position(|m| m.rho == [0.0; 3])
        .expect("lamp material") as u32;
    let pages = render_pages(&solution, &prepared.surfaces, &atlas);
    let mut lamps = 0;
    for (i, (s, r)) in prepared.surfaces.iter().zip(&atlas.rects).enumerate() {
        let face = &prepared.faces.faces[s.face.0 as usize];
        let json_rect = &result["faces"][i]["atlas"];
        assert_eq!(json_rect["w"], r.w);
        assert_eq!(json_rect["x"], r.x);
        if face.material != lamp_material {
            let natural = |len: f64| (len * 48.0).ceil() as u32;
            assert_eq!(
                (r.w, r.h),
                (natural(s.frame.u.length()), natural(s.frame.v.length()))
            );
            continue;
        }
        lamps += 1;
        assert!(r.w <= 4 && r.h <= 4, "lamp rect {r:?}");
        let c = atlas.cell(i);
        let width = atlas.pages[r.page as usize].width;
        for y in c.y..c.y + c.h {
            for x in c.x..c.x + c.w {
                let t = pages[r.page as usize][(y * width + x) as usize];
                for ch in 0..3 {
                    assert!((t[ch] - 4.0).abs() < 1e-3, "lamp texel {t:?}");
                }
            }
        }
    }
    assert_eq!(lamps, 1);
    let a = &result["atlas"];
    assert_eq!(a["gutter"], 4);
    assert_eq!(a["block"], 8);
    assert_eq!(a["mip_levels"], 4);
    assert_eq!(a["minimal_rects"], 1);
    let efficiency = a["efficiency"].as_f64().expect("efficiency");
    assert!((efficiency - atlas.efficiency()).abs() < 1e-12);
    assert!(efficiency > 0.0 && efficiency < 1.0);
    for p in a["pages"].as_array().expect("pages") {
        let (w, h) = (p["width"].as_u64().unwrap(), p["height"].as_u64().unwrap());
        assert!(w.is_power_of_two() && h.is_power_of_two(), "{p}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A small page limit opens more pages, each within the limit; rendering fills every one.
#[test]
fn a_small_page_limit_spreads_the_atlas_over_pages() {
    let scene = contrast_scene();
    let (prepared, solution) = solve(&scene);
    let mut opts = options(AtlasSettings {
        max_page_size: 256,
        ..AtlasSettings::default()
    });
    opts.texels_per_meter = Some(200.0);
    let atlas = plan_atlas(&scene, &prepared.faces, &prepared.surfaces, &opts);
    atlas.assert_well_formed();
    assert!(atlas.pages.len() >= 4, "{} pages", atlas.pages.len());
    for p in &atlas.pages {
        assert!(
            p.width <= 256
                && p.height <= 256
                && p.width.is_multiple_of(4)
                && p.height.is_multiple_of(4)
        );
    }
    let pages = render_pages(&solution, &prepared.surfaces, &atlas);
    assert_eq!(pages.len(), atlas.pages.len());
    let (count, first) = mip_leaks(&atlas, &pages);
    assert_eq!(count, 0, "{first:#?}");
}

/// The shelf packer this atlas replaced (tallest first, shelves across a page about 15 % wider
/// than the square root of the area, a power of two), on the same cells: (pages, efficiency).
fn shelf_baseline(atlas: &Atlas) -> (usize, f64) {
    let limit = atlas.settings.page_limit();
    let block = atlas.settings.block();
    let cells: Vec<(u32, u32)> = (0..atlas.rects.len())
        .map(|i| (atlas.cell(i).w, atlas.cell(i).h))
        .collect();
    let pages = shelf_pack(&cells, limit);
    let used: f64 = atlas.rects.iter().map(|r| r.w as f64 * r.h as f64).sum();
    let area: f64 = pages
        .iter()
        .map(|&(w, h)| w.div_ceil(block) as f64 * h.div_ceil(block) as f64 * (block * block) as f64)
        .sum();
    (pages.len(), used / area)
}

/// The old shelf packer on `cells`: the pages `(width, height)`.
fn shelf_pack(cells: &[(u32, u32)], limit: u32) -> Vec<(u32, u32)> {
    let total: f64 = cells.iter().map(|&(w, h)| w as f64 * h as f64).sum();
    let widest = cells.iter().map(|c| c.0).max().unwrap_or(1);
    let page_width = ((total.sqrt() * 1.15).ceil() as u32)
        .next_power_of_two()
        .clamp(widest, limit);
    let mut order: Vec<usize> = (0..cells.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(cells[i].1), i));
    let mut pages: Vec<(u32, u32)> = Vec::new();
    let (mut x, mut y, mut shelf_h, mut used_w) = (0u32, 0u32, 0u32, 0u32);
    for i in order {
        let (w, h) = cells[i];
        if x + w > page_width {
            y += shelf_h;
            x = 0;
            shelf_h = 0;
        }
        if y + h > limit {
            pages.push((used_w, y));
            (x, y, shelf_h, used_w) = (0, 0, 0, 0);
        }
        x += w;
        used_w = used_w.max(x);
        shelf_h = shelf_h.max(h);
    }
    pages.push((used_w, y + shelf_h));
    pages
}

fn scene_paths() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = wavrad::scene::scene_files(&root.join("scenes"));
    let shared = root.join("../shared/scenes");
    if shared.is_dir() {
        paths.extend(wavrad::scene::scene_files(&shared));
    } else {
        println!("SKIP ../shared/scenes: absent (a fresh clone has no ../shared)");
    }
    paths
}

/// The layout this atlas replaced, at the same rectangle sizes: one-texel gutter, no block, the
/// shelf packer: its efficiency.
fn todays_layout(atlas: &Atlas) -> f64 {
    let limit = atlas.settings.page_limit();
    let cells: Vec<(u32, u32)> = atlas.rects.iter().map(|r| (r.w + 2, r.h + 2)).collect();
    let pages = shelf_pack(&cells, limit);
    let used: f64 = atlas.rects.iter().map(|r| r.w as f64 * r.h as f64).sum();
    used / pages.iter().map(|&(w, h)| w as f64 * h as f64).sum::<f64>()
}

/// Packing efficiency (face texels over page texels) of the atlas against the shelf packer it
/// replaced, on the same cells, and of the layout it replaced (`today`: one-texel gutter, no block),
/// for the sample scenes and `../shared/scenes`; `cells` is the share of page texels in cells.
/// Every atlas is well formed; `etagere` packs at least 90 % as densely as the shelf packer. On
/// levels of many small faces the 4-level gutter dominates: a face of a few texels takes a cell
/// of 16 x 16.
#[test]
fn packing_efficiency_against_the_shelf_packer() {
    println!(
        "{:<36} {:>9} {:>8} {:>7} {:>6} {:>8} {:>6} {:>8} {:>6} {:>7} {:>8}",
        "scene",
        "triangles",
        "surfaces",
        "minimal",
        "pages",
        "etagere",
        "cells",
        "shelf",
        "pages",
        "today",
        "gutter_1"
    );
    for path in scene_paths() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let scene = match load_scene_from_path(&path, 5_000_000) {
            Ok(s) => s,
            Err(e) => panic!("{name}: {e}"),
        };
        let faces = merge_planar_faces(&scene);
        let surfaces = build_domains(&scene, &faces, DomainMode::Extended).surfaces;
        let opts = OutputOptions::default();
        let atlas = plan_atlas(&scene, &faces, &surfaces, &opts);
        atlas.assert_well_formed();
        let minimal = surfaces
            .iter()
            .filter(|s| wavrad::output::needs_no_resolution(&scene, &faces, s))
            .count();
        let (shelf_pages, shelf) = shelf_baseline(&atlas);
        let gutter_1 = plan_atlas(
            &scene,
            &faces,
            &surfaces,
            &OutputOptions {
                atlas: AtlasSettings {
                    gutter: 1,
                    ..AtlasSettings::default()
                },
                ..OutputOptions::default()
            },
        );
        gutter_1.assert_well_formed();
        let cell_texels: f64 = (0..atlas.rects.len())
            .map(|i| atlas.cell(i).w as f64 * atlas.cell(i).h as f64)
            .sum();
        let page_texels: f64 = atlas
            .pages
            .iter()
            .map(|p| p.width as f64 * p.height as f64)
            .sum();
        println!(
            "{name:<36} {:>9} {:>8} {:>7} {:>6} {:>8.3} {:>6.3} {:>8.3} {:>6} {:>7.3} {:>8.3}",
            scene.triangles.len(),
            surfaces.len(),
            minimal,
            atlas.pages.len(),
            atlas.efficiency(),
            cell_texels / page_texels,
            shelf,
            shelf_pages,
            todays_layout(&atlas),
            gutter_1.efficiency()
        );
        assert!(
            atlas.efficiency() >= 0.9 * shelf,
            "{name}: etagere {} against shelf {shelf}",
            atlas.efficiency()
        );
    }
}
