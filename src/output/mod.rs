//! Outputs of a solve: the lightmap atlas (EXR pages, `atlas.png`), `preview.png` (a picture of
//! the lit scene, `preview.rs`), result.json and convergence.csv, and the `faces --json` document. Reads the solution; never changes it.
//!
//! Texel conventions (docs/contract.md): texel `(i, j)` of a root's rectangle covers `s` in `[i/w, (i+1)/w]`
//! and `t` in `[j/h, (j+1)/h]` (rows from the top of the image); its value is the solution at the
//! texel centre (clamped into the element, so gutters and texels outside a triangle repeat the
//! nearest face value and bilinear filtering never bleeds black); alpha is the texel's coverage.
//! Every texel of a rectangle's cell (gutter and block rounding included, `atlas.rs`) is
//! rendered that way, so mip levels the gutter keeps apart mix only the face's own values
//! (`tests/atlas.rs`).

pub(crate) mod atlas;
pub mod baked_scene;
mod lightmap_exr;
pub mod preview;
pub mod probes;
pub(crate) mod solution_file;

use crate::domain::{clamp_to_shape, plane_coordinates, DomainMode, Frame, Side, StBox, Surface};
use crate::faces::FaceSet;
use crate::fsutil::write_atomic;
use crate::pipeline::Prepared;
use crate::scene::Scene;
use crate::solver::{Progress, Solution};
pub use atlas::{
    block_for_gutter, default_density, mip_levels_for_gutter, Atlas, AtlasRect, AtlasSettings,
    Cell, Page, RectRequest,
};
use glam::DVec2;
use lightmap_exr::write_exr;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::Path;

/// What the outputs need besides the solution: atlas settings, the domain mode the roots were
/// built with, and the job's parameters as result.json echoes them.
#[derive(Debug, Clone, Default)]
pub struct OutputOptions {
    /// Lightmap density; `None` picks one from the scene's size ([`atlas::default_density`]).
    pub texels_per_meter: Option<f64>,
    /// Gutter, page size limit and power-of-two pages.
    pub atlas: AtlasSettings,
    /// 32-bit float EXR pages instead of half floats.
    pub exr_float: bool,
    /// The mode the roots were built with (result.json counts extended faces that fell back).
    pub domain: DomainMode,
    /// result.json's `params`, written as given.
    pub params: Value,
}

/// The process's peak resident memory (VmHWM) in bytes, 0 where unknown.
pub fn peak_memory_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<u64>().ok())
        })
        .map(|kb| kb * 1024)
        .unwrap_or(0)
}

fn v3(v: glam::DVec3) -> Value {
    json!([v.x, v.y, v.z])
}

/// Area of the axis-aligned box `[x0,x1] x [y0,y1]` inside the convex polygon `poly` (either
/// orientation), by clipping the box with each edge's half-plane (Sutherland-Hodgman).
fn box_in_convex_area(x0: f64, x1: f64, y0: f64, y1: f64, poly: &[DVec2]) -> f64 {
    let mut signed = 0.0;
    for i in 0..poly.len() {
        signed += poly[i].perp_dot(poly[(i + 1) % poly.len()]);
    }
    let orientation = signed.signum();
    let mut cur = vec![
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ];
    for i in 0..poly.len() {
        let a = poly[i];
        let e = poly[(i + 1) % poly.len()] - a;
        // Inside: on the left of the edge for a counter-clockwise polygon.
        let side = |p: DVec2| orientation * e.perp_dot(p - a);
        let mut next = Vec::with_capacity(cur.len() + 1);
        for k in 0..cur.len() {
            let (p, q) = (cur[k], cur[(k + 1) % cur.len()]);
            let (dp, dq) = (side(p), side(q));
            if dp >= 0.0 {
                next.push(p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                next.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
        cur = next;
        if cur.len() < 3 {
            return 0.0;
        }
    }
    let mut a2 = 0.0;
    for i in 0..cur.len() {
        a2 += cur[i].perp_dot(cur[(i + 1) % cur.len()]);
    }
    0.5 * a2.abs()
}

fn point_in_convex(p: DVec2, poly: &[DVec2]) -> bool {
    let mut sign = 0.0;
    for i in 0..poly.len() {
        let d = (poly[(i + 1) % poly.len()] - poly[i]).perp_dot(p - poly[i]);
        if d != 0.0 {
            if sign != 0.0 && d.signum() != sign {
                return false;
            }
            sign = d.signum();
        }
    }
    true
}

/// What a rendered texel holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TexelValue {
    /// The job's quantity (the EXR pages): radiance, or irradiance / pi.
    Requested,
    /// The irradiance H itself, whatever the job's quantity (the baked scene's PNG pages).
    Irradiance,
}

/// The texel value at world point `x` on root `i` (clamped into the root), never negative.
fn value_on_root(solution: &Solution, i: usize, x: glam::DVec3, what: TexelValue) -> [f64; 3] {
    let root = &solution.roots[i];
    let st = clamp_to_shape(root.shape, plane_coordinates(&root.frame, x));
    match what {
        TexelValue::Requested => solution.value_at(i, st),
        TexelValue::Irradiance => solution.irradiance_at(i, st).map(|h| h.max(0.0)),
    }
}

/// RGBA texels of one surface's cell (its rectangle, gutter and block rounding), row-major from
/// the top.
fn render_surface(
    solution: &Solution,
    surface: &Surface,
    rect: AtlasRect,
    cell: Cell,
    what: TexelValue,
) -> Vec<[f32; 4]> {
    // The rectangle's corner inside the cell.
    let (gx, gy) = ((rect.x - cell.x) as f64, (rect.y - cell.y) as f64);
    let (bw, bh) = (cell.w as usize, cell.h as usize);
    let (w, h) = (rect.w as f64, rect.h as f64);
    let mut coverage = vec![0.0f64; bw * bh];
    let mut value: Vec<Option<[f64; 3]>> = vec![None; bw * bh];
    let frame = &surface.frame;
    // Texel-space point (x, y) of the block <-> frame coordinates (s, t).
    let to_texel = |st: DVec2| DVec2::new(st.x * w + gx, st.y * h + gy);
    let to_world = |p: DVec2| frame.point(DVec2::new((p.x - gx) / w, (p.y - gy) / h));
    let mut corners = Vec::with_capacity(4);
    for i in surface.roots.clone() {
        let root = &solution.roots[i];
        corners.clear();
        corners.extend(
            root.corners()
                .iter()
                .map(|c| to_texel(plane_coordinates(frame, *c))),
        );
        let lo = corners
            .iter()
            .fold(DVec2::splat(f64::INFINITY), |m, c| m.min(*c));
        let hi = corners
            .iter()
            .fold(DVec2::splat(f64::NEG_INFINITY), |m, c| m.max(*c));
        let (x0, x1) = (
            (lo.x.floor().max(0.0)) as usize,
            (hi.x.ceil().max(0.0) as usize).min(bw),
        );
        let (y0, y1) = (
            (lo.y.floor().max(0.0)) as usize,
            (hi.y.ceil().max(0.0) as usize).min(bh),
        );
        for y in y0..y1 {
            for x in x0..x1 {
                let (fx, fy) = (x as f64, y as f64);
                let a = match &root.mask {
                    // An extended root: the face inside the texel, not the domain.
                    Some(mask) => {
                        let texel = StBox::new(
                            DVec2::new((fx - gx) / w, (fy - gy) / h),
                            DVec2::new((fx + 1.0 - gx) / w, (fy + 1.0 - gy) / h),
                        );
                        mask.coverage(texel).fraction(&texel)
                    }
                    None => box_in_convex_area(fx, fx + 1.0, fy, fy + 1.0, &corners),
                };
                if a <= 0.0 {
                    continue;
                }
                let k = y * bw + x;
                coverage[k] += a;
                let centre = DVec2::new(fx + 0.5, fy + 0.5);
                if value[k].is_none() && point_in_convex(centre, &corners) {
                    value[k] = Some(value_on_root(solution, i, to_world(centre), what));
                }
            }
        }
    }
    // Texels whose centre lies on no root (gutter, rounding, outside the face): the nearest
    // root's value.
    let mut out = Vec::with_capacity(bw * bh);
    for k in 0..bw * bh {
        let v = value[k].unwrap_or_else(|| {
            let x = to_world(DVec2::new((k % bw) as f64 + 0.5, (k / bw) as f64 + 0.5));
            let nearest = surface.roots.clone().min_by(|&a, &b| {
                let da = solution.roots[a].locate(x);
                let db = solution.roots[b].locate(x);
                (da.1 + da.2).total_cmp(&(db.1 + db.2))
            });
            nearest
                .map(|i| value_on_root(solution, i, x, what))
                .unwrap_or([0.0; 3])
        });
        let a = coverage[k].clamp(0.0, 1.0);
        out.push([v[0] as f32, v[1] as f32, v[2] as f32, a as f32]);
    }
    out
}

/// RGBA texels of every atlas page, row-major from the top: the job's quantity.
pub fn render_pages(
    solution: &Solution,
    surfaces: &[Surface],
    atlas: &Atlas,
) -> Vec<Vec<[f32; 4]>> {
    render_pages_of(solution, surfaces, atlas, TexelValue::Requested)
}

/// [`render_pages`] with the texels holding `what` (same coverage, clamping and gutters).
pub fn render_pages_of(
    solution: &Solution,
    surfaces: &[Surface],
    atlas: &Atlas,
    what: TexelValue,
) -> Vec<Vec<[f32; 4]>> {
    let mut pages: Vec<Vec<[f32; 4]>> = atlas
        .pages
        .iter()
        .map(|p| vec![[0.0; 4]; (p.width * p.height) as usize])
        .collect();
    let blocks: Vec<Vec<[f32; 4]>> = surfaces
        .par_iter()
        .zip(atlas.rects.par_iter())
        .enumerate()
        .map(|(i, (surface, rect))| render_surface(solution, surface, *rect, atlas.cell(i), what))
        .collect();
    for (i, (block, r)) in blocks.into_iter().zip(&atlas.rects).enumerate() {
        let page = &mut pages[r.page as usize];
        let width = atlas.pages[r.page as usize].width;
        let c = atlas.cell(i);
        for (k, texel) in block.into_iter().enumerate() {
            let (bx, by) = (k as u32 % c.w, k as u32 / c.w);
            let (x, y) = (c.x + bx, c.y + by);
            page[(y * width + x) as usize] = texel;
        }
    }
    pages
}

/// File name of atlas page `n`.
pub fn page_file_name(n: usize) -> String {
    if n == 0 {
        "lightmap.exr".to_string()
    } else {
        format!("lightmap-{n}.exr")
    }
}

/// Exposure of the preview: the 99th percentile of covered texel luminance maps to 0.9.
fn preview_scale(texels: &[[f32; 4]]) -> f32 {
    let mut lum: Vec<f32> = texels
        .iter()
        .filter(|t| t[3] > 0.0)
        .map(|t| 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2])
        .filter(|l| l.is_finite())
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    let k = ((lum.len() - 1) as f64 * 0.99) as usize;
    let (_, p99, _) = lum.select_nth_unstable_by(k, f32::total_cmp);
    if *p99 > 0.0 {
        0.9 / *p99
    } else {
        1.0
    }
}

/// sRGB encoding of a linear value, clamped to `[0, 1]`, as an 8-bit value (the PNG pictures and
/// the baked scene's lightmap pages).
pub fn srgb8(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let e = if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0 + 0.5) as u8
}

/// An 8-bit RGB PNG of `data` (row-major from the top, three bytes a pixel), marked sRGB: every
/// PNG wavrad writes holds sRGB-encoded values.
pub(crate) fn encode_rgb_png(data: &[u8], width: u32, height: u32) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(data).map_err(std::io::Error::other)?;
    }
    Ok(out)
}

/// `atlas.png`: the first atlas page, exposed by [`preview_scale`], sRGB-encoded, uncovered texels dimmed.
pub fn atlas_png(texels: &[[f32; 4]], width: u32, height: u32) -> std::io::Result<Vec<u8>> {
    let scale = preview_scale(texels);
    let mut data = Vec::with_capacity(texels.len() * 3);
    for t in texels {
        let dim = if t[3] > 0.0 { 1.0 } else { 0.25 };
        data.extend([0, 1, 2].map(|c| srgb8(t[c] * dim * scale)));
    }
    encode_rgb_png(&data, width, height)
}

/// `convergence.csv`: one row per shot.
pub fn convergence_csv(rows: &[Progress]) -> String {
    let mut s = String::from("seconds,unshot_ratio,elements,links\n");
    for r in rows {
        s.push_str(&format!(
            "{:.6},{:.9e},{},{}\n",
            r.seconds, r.unshot_ratio, r.elements, r.links
        ));
    }
    s
}

fn frame_json(frame: &Frame) -> Value {
    json!({"origin": v3(frame.origin), "u": v3(frame.u), "v": v3(frame.v)})
}

/// Area-weighted mean of the requested quantity over a surface's roots.
fn surface_mean(solution: &Solution, surface: &Surface) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut area = 0.0;
    for i in surface.roots.clone() {
        let a = solution.roots[i].face_area_m2;
        let m = solution.mean_value(i);
        for c in 0..3 {
            sum[c] += a * m[c];
        }
        area += a;
    }
    if area > 0.0 {
        sum.map(|x| x / area)
    } else {
        sum
    }
}

/// Whether a surface's texels need no resolution: its material reflects nothing (rho = 0), so
/// its radiance is its emission, uniform without an emissive texture (and an engine multiplies
/// its irradiance by a zero albedo). Such a surface gets the minimal rectangle (`atlas.rs`).
pub fn needs_no_resolution(scene: &Scene, faces: &FaceSet, surface: &Surface) -> bool {
    let Some(face) = faces.faces.get(surface.face.0 as usize) else {
        return false;
    };
    let Some(m) = scene.materials.get(face.material as usize) else {
        return false;
    };
    m.rho == [0.0; 3] && (m.emissive_texture.is_none() || !m.is_emissive())
}

/// The atlas of a solve's surfaces (one rectangle per entry of `surfaces`, `Prepared::surfaces`,
/// in order): the one `write_outputs` renders, for any other output that maps into it.
pub fn plan_atlas(
    scene: &Scene,
    faces: &FaceSet,
    surfaces: &[Surface],
    options: &OutputOptions,
) -> Atlas {
    let requests: Vec<RectRequest> = surfaces
        .iter()
        .map(|s| RectRequest {
            width_m: s.frame.u.length(),
            height_m: s.frame.v.length(),
            minimal: needs_no_resolution(scene, faces, s),
        })
        .collect();
    let density = options
        .texels_per_meter
        .unwrap_or_else(|| default_density(&requests));
    Atlas::pack(&requests, density, &options.atlas)
}

/// Writes every output of a solve to `dir` and returns the result.json document.
pub fn write_outputs(
    dir: &Path,
    scene: &Scene,
    prepared: &Prepared,
    solution: &Solution,
    options: &OutputOptions,
) -> std::io::Result<Value> {
    let atlas = plan_atlas(scene, &prepared.faces, &prepared.surfaces, options);
    let pages = render_pages(solution, &prepared.surfaces, &atlas);
    let mut page_json = Vec::new();
    for (n, (texels, page)) in pages.iter().zip(&atlas.pages).enumerate() {
        let name = page_file_name(n);
        write_exr(
            &dir.join(&name),
            page.width,
            page.height,
            texels,
            options.exr_float,
        )?;
        page_json.push(json!({"file": name, "width": page.width, "height": page.height}));
    }
    write_atomic(
        &dir.join("convergence.csv"),
        convergence_csv(&solution.convergence).as_bytes(),
    )?;
    if let (Some(texels), Some(page)) = (pages.first(), atlas.pages.first()) {
        write_atomic(
            &dir.join("atlas.png"),
            &atlas_png(texels, page.width, page.height)?,
        )?;
    }
    write_atomic(
        &dir.join("preview.png"),
        &preview::preview_png(scene, prepared, solution)?,
    )?;
    let faces: Vec<Value> = prepared
        .surfaces
        .iter()
        .zip(&atlas.rects)
        .map(|(surface, rect)| {
            let face = &prepared.faces.faces[surface.face.0 as usize];
            json!({
                "id": surface.face.0, "side": surface.side.as_str(), "material": face.material,
                "area": surface.area_m2, "frame": frame_json(&surface.frame), "kind": surface.kind.as_str(),
                "mean_radiance": surface_mean(solution, surface),
                "atlas": {"page": rect.page, "x": rect.x, "y": rect.y, "w": rect.w, "h": rect.h},
            })
        })
        .collect();
    let stats = &solution.stats;
    let mut warnings = scene.warnings.clone();
    warnings.extend(prepared.faces.warnings.iter().cloned());
    // Extended faces solved on their domain, and those that fell back to their triangles.
    let extended_faces = prepared
        .faces
        .faces
        .iter()
        .filter(|f| f.kind == crate::faces::FaceKind::Extended)
        .count();
    let mut masked_faces: Vec<u32> = solution
        .roots
        .iter()
        .filter(|r| r.mask.is_some())
        .map(|r| r.face.0)
        .collect();
    masked_faces.dedup();
    let extended_tessellated = if options.domain == DomainMode::Extended {
        extended_faces - masked_faces.len().min(extended_faces)
    } else {
        0
    };
    if extended_tessellated > 0 {
        warnings.push(format!(
            "{extended_tessellated} extended face(s) were solved as triangles: their domain could not be built"
        ));
    }
    if stats.refinement_capped > 0 {
        warnings.push(format!(
            "{} transfer(s) stayed above the tolerance because elements reached the minimum size or depth",
            stats.refinement_capped
        ));
    }
    let result = json!({
        "scene": {
            "triangles": scene.triangles.len(), "faces": prepared.faces.faces.len(),
            "emitters": prepared.faces.faces.iter().filter(|f| scene.materials[f.material as usize].is_emissive()).count(),
            "lights": scene.lights.len(),
            "area": prepared.faces.faces.iter().map(|f| f.area_m2).sum::<f64>(),
        },
        "params": options.params.clone(),
        "warnings": warnings,
        "stats": {
            "seconds": stats.seconds, "iterations": stats.iterations, "elements": stats.elements,
            "links": stats.links, "unshot_ratio": stats.unshot_ratio,
            "emitted_power": stats.emitted_power, "peak_memory_bytes": peak_memory_bytes(),
            "stop_reason": stats.stop_reason.map(|s| s.as_str()).unwrap_or("converged"),
            "rays": stats.rays, "refinement_capped": stats.refinement_capped,
            "touching_fallbacks": stats.touching_fallbacks,
            "node_sum_splits": stats.node_sum_splits,
            "bytes_per_element": stats.bytes_per_element, "bytes_per_link": stats.bytes_per_link,
            "extended_faces": extended_faces, "extended_faces_on_domain": masked_faces.len(),
            "extended_faces_tessellated": extended_tessellated,
            "duplicates_dropped": prepared.faces.duplicates_dropped,
            "overlaps_cut": prepared.faces.overlaps_cut,
            "back_to_back_kept": prepared.faces.back_to_back_kept,
            "texels_per_meter": atlas.texels_per_meter,
        },
        "faces": faces,
        "atlas": {
            "pages": page_json, "gutter": atlas.settings.gutter, "block": atlas.settings.block(),
            "mip_levels": mip_levels_for_gutter(atlas.settings.gutter),
            "efficiency": atlas.efficiency(),
            "minimal_rects": prepared.surfaces.iter().filter(|s| needs_no_resolution(scene, &prepared.faces, s)).count(),
        },
    });
    let mut result = result;
    if let Some(baked) = write_baked_scene(dir, scene, prepared, solution, &atlas)? {
        result["baked_scene"] = baked;
    }
    let text = serde_json::to_vec_pretty(&result).map_err(std::io::Error::other)?;
    write_atomic(&dir.join("result.json"), &text)?;
    Ok(result)
}

/// File name of the baked scene in a job's outputs.
pub const BAKED_SCENE_FILE: &str = "scene.glb";

/// Writes `scene.glb` ([`baked_scene`]) when the scene was read from a glTF file: the atlas
/// pages rendered again holding irradiance, as PNGs scaled by one `intensity`. Returns
/// result.json's `baked_scene` object (`{"file", "intensity"}`).
fn write_baked_scene(
    dir: &Path,
    scene: &Scene,
    prepared: &Prepared,
    solution: &Solution,
    atlas: &Atlas,
) -> std::io::Result<Option<Value>> {
    if scene.source.is_none() {
        return Ok(None);
    }
    let irradiance = render_pages_of(solution, &prepared.surfaces, atlas, TexelValue::Irradiance);
    let intensity = baked_scene::lightmap_intensity(&irradiance);
    let pages_png = irradiance
        .iter()
        .zip(&atlas.pages)
        .map(|(texels, page)| baked_scene::lightmap_png(texels, page.width, page.height, intensity))
        .collect::<std::io::Result<Vec<_>>>()?;
    let inputs = baked_scene::BakeInputs {
        scene,
        faces: &prepared.faces,
        surfaces: &prepared.surfaces,
        atlas,
        pages_png: &pages_png,
        intensity,
    };
    let Some(glb) = baked_scene::baked_scene_glb(&inputs) else {
        return Ok(None);
    };
    write_atomic(&dir.join(BAKED_SCENE_FILE), &glb)?;
    Ok(Some(
        json!({"file": BAKED_SCENE_FILE, "intensity": intensity}),
    ))
}

/// The `faces --json` document.
pub fn faces_json(faces: &FaceSet, surfaces: &[Surface]) -> Value {
    let list: Vec<Value> = faces
        .faces
        .iter()
        .map(|f| {
            let surface = surfaces.iter().find(|s| s.face == f.id && s.side == Side::Front);
            let domain = surface.map(|s| {
                json!({"origin": v3(s.frame.origin), "u": v3(s.frame.u), "v": v3(s.frame.v),
                    "area": s.domain_area_m2(), "fill_ratio": s.fill_ratio()})
            });
            json!({
                "id": f.id.0, "material": f.material, "double_sided": f.double_sided, "kind": f.kind.as_str(),
                "area": f.area_m2, "holes": f.holes.len(),
                "vertices": f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>(),
                "triangles": faces.source_triangle_count(f), "normal": v3(f.normal), "domain": domain,
            })
        })
        .collect();
    json!({"triangles_in": faces.triangles_in, "degenerate_dropped": faces.degenerate_dropped,
        "triangles_cut_at_contacts": faces.triangles_cut,
        "duplicates_dropped": faces.duplicates_dropped, "overlaps_cut": faces.overlaps_cut,
        "back_to_back_kept": faces.back_to_back_kept,
        "faces_out": faces.faces.len(), "faces": list})
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_triangle() -> Vec<DVec2> {
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0),
        ]
    }

    #[test]
    fn box_coverage_of_a_triangle_matches_geometry() {
        let tri = unit_triangle();
        // A box straddling the hypotenuse symmetrically is half covered.
        assert!((box_in_convex_area(0.45, 0.55, 0.45, 0.55, &tri) / 0.01 - 0.5).abs() < 1e-12);
        assert!((box_in_convex_area(0.1, 0.2, 0.1, 0.2, &tri) / 0.01 - 1.0).abs() < 1e-12);
        assert_eq!(box_in_convex_area(0.8, 0.9, 0.8, 0.9, &tri), 0.0);
        // Either orientation.
        let mut rev = tri.clone();
        rev.reverse();
        assert!((box_in_convex_area(0.45, 0.55, 0.45, 0.55, &rev) / 0.01 - 0.5).abs() < 1e-12);
        // Summed over a grid, coverage integrates the triangle's area.
        let n = 37;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let (s0, t0) = (i as f64 / n as f64, j as f64 / n as f64);
                sum += box_in_convex_area(s0, s0 + 1.0 / n as f64, t0, t0 + 1.0 / n as f64, &tri);
            }
        }
        assert!((sum - 0.5).abs() < 1e-12);
    }

    /// `faces --json` adds `domain.fill_ratio`: an L of three unit squares fills three quarters of
    /// its minimal enclosing parallelogram (the 2 x 2 square); a square fills all of its own.
    #[test]
    fn faces_json_reports_fill_ratios() {
        use crate::scene::{Material, Scene, Triangle, TriangleSource};
        let p = |x: f64, y: f64, z: f64| glam::DVec3::new(x, y, z);
        let quads = [
            // The L in z = 0: [0,1]x[0,1], [1,2]x[0,1], [0,1]x[1,2].
            [
                p(0.0, 0.0, 0.0),
                p(1.0, 0.0, 0.0),
                p(1.0, 1.0, 0.0),
                p(0.0, 1.0, 0.0),
            ],
            [
                p(1.0, 0.0, 0.0),
                p(2.0, 0.0, 0.0),
                p(2.0, 1.0, 0.0),
                p(1.0, 1.0, 0.0),
            ],
            [
                p(0.0, 1.0, 0.0),
                p(1.0, 1.0, 0.0),
                p(1.0, 2.0, 0.0),
                p(0.0, 2.0, 0.0),
            ],
            // A square in the plane z = 5.
            [
                p(0.0, 0.0, 5.0),
                p(1.0, 0.0, 5.0),
                p(1.0, 1.0, 5.0),
                p(0.0, 1.0, 5.0),
            ],
        ];
        let mut triangles = Vec::new();
        for q in quads {
            for v in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                triangles.push(Triangle {
                    vertices: v,
                    material: 0,
                    source: TriangleSource {
                        mesh: 0,
                        primitive: 0,
                        triangle: triangles.len() as u32,
                    },
                });
            }
        }
        let scene = Scene::new(triangles, vec![Material::gltf_default()], vec![], vec![]);
        let faces = crate::faces::merge_planar_faces(&scene);
        let domains =
            crate::domain::build_domains(&scene, &faces, crate::domain::DomainMode::Extended);
        let doc = faces_json(&faces, &domains.surfaces);
        let list = doc["faces"].as_array().expect("faces");
        assert_eq!(list.len(), 2);
        let mut fills: Vec<(String, f64)> = list
            .iter()
            .map(|f| {
                let fill = f["domain"]["fill_ratio"].as_f64().expect("fill_ratio");
                let area = f["area"].as_f64().expect("area");
                let domain_area = f["domain"]["area"].as_f64().expect("domain area");
                assert!((fill - area / domain_area).abs() < 1e-12);
                (f["kind"].as_str().expect("kind").to_string(), fill)
            })
            .collect();
        fills.sort_by(|a, b| a.0.cmp(&b.0));
        assert_eq!(fills[0].0, "extended");
        assert!((fills[0].1 - 0.75).abs() < 1e-12, "L fill {}", fills[0].1);
        assert_eq!(fills[1].0, "parallelogram");
        assert!((fills[1].1 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn point_in_convex_either_orientation() {
        let tri = unit_triangle();
        assert!(point_in_convex(DVec2::new(0.2, 0.2), &tri));
        assert!(!point_in_convex(DVec2::new(0.6, 0.6), &tri));
        let mut rev = tri;
        rev.reverse();
        assert!(point_in_convex(DVec2::new(0.2, 0.2), &rev));
    }
}
