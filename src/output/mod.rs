//! Outputs of a solve: the lightmap atlas (EXR pages), result.json and convergence.csv, and the
//! `faces --json` document. Reads the solution; never changes it.
//!
//! Texel conventions (CONTRACT): texel `(i, j)` of a root's rectangle covers `s` in `[i/w, (i+1)/w]`
//! and `t` in `[j/h, (j+1)/h]` (rows from the top of the image); its value is the solution at the
//! texel centre (clamped into the element, so gutters and texels outside a triangle repeat the
//! nearest face value and bilinear filtering never bleeds black); alpha is the texel's coverage.

pub mod atlas;
pub mod probes;

use crate::domain::{ElementRoot, Shape};
use crate::faces::FaceSet;
use crate::job::JobParams;
use crate::pipeline::Prepared;
use crate::scene::Scene;
use crate::solver::{Progress, Solution};
use atlas::{default_density, Atlas, GUTTER};
use glam::DVec2;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::io::Write;
use std::path::Path;

/// Output settings that are not solver parameters.
#[derive(Debug, Clone, Default)]
pub struct OutputOptions {
    pub texels_per_meter: Option<f64>,
    pub exr_float: bool,
}

/// A temporary name beside `path`, unique per process and call (so concurrent writers never share one).
fn temporary_path(path: &Path) -> std::path::PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// Makes a rename in `path`'s directory durable (fsync of the directory; a no-op where unsupported).
fn sync_parent(path: &Path) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = std::fs::File::open(dir) {
            d.sync_all()?;
        }
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically: temporary file, fsync, rename, fsync of the directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = temporary_path(path);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)?;
        sync_parent(path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
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

/// Fraction of the texel `[s0,s1] x [t0,t1]` inside the reference shape.
fn texel_coverage(shape: Shape, s0: f64, s1: f64, t0: f64, t1: f64) -> f64 {
    let clamp01 = |a: f64| a.clamp(0.0, 1.0);
    let area = (s1 - s0) * (t1 - t0);
    match shape {
        Shape::Parallelogram => {
            ((clamp01(s1) - clamp01(s0)) * (clamp01(t1) - clamp01(t0)) / area).clamp(0.0, 1.0)
        }
        Shape::Triangle => {
            // Clip the texel square by s >= 0, t >= 0, s + t <= 1 and take the polygon's area.
            let mut poly = vec![
                DVec2::new(s0, t0),
                DVec2::new(s1, t0),
                DVec2::new(s1, t1),
                DVec2::new(s0, t1),
            ];
            for (n, c) in [
                (DVec2::new(1.0, 0.0), 0.0),
                (DVec2::new(0.0, 1.0), 0.0),
                (DVec2::new(-1.0, -1.0), -1.0),
            ] {
                let mut out = Vec::with_capacity(poly.len() + 1);
                for i in 0..poly.len() {
                    let a = poly[i];
                    let b = poly[(i + 1) % poly.len()];
                    let (da, db) = (n.dot(a) - c, n.dot(b) - c);
                    if da >= 0.0 {
                        out.push(a);
                    }
                    if (da >= 0.0) != (db >= 0.0) {
                        out.push(a + (b - a) * (da / (da - db)));
                    }
                }
                poly = out;
                if poly.is_empty() {
                    return 0.0;
                }
            }
            let mut a2 = 0.0;
            for i in 0..poly.len() {
                a2 += poly[i].perp_dot(poly[(i + 1) % poly.len()]);
            }
            (0.5 * a2.abs() / area).clamp(0.0, 1.0)
        }
    }
}

/// The closest point of the reference shape to `st`.
fn clamp_to_shape(shape: Shape, st: DVec2) -> DVec2 {
    let c = st.clamp(DVec2::ZERO, DVec2::ONE);
    match shape {
        Shape::Parallelogram => c,
        Shape::Triangle => {
            if c.x + c.y <= 1.0 {
                c
            } else {
                // Project onto s + t = 1 within the segment.
                let d = 0.5 * (c.x + c.y - 1.0);
                DVec2::new(c.x - d, c.y - d).clamp(DVec2::ZERO, DVec2::ONE)
            }
        }
    }
}

/// RGBA texels of every atlas page, row-major from the top.
pub fn render_pages(solution: &Solution, atlas: &Atlas) -> Vec<Vec<[f32; 4]>> {
    let mut pages: Vec<Vec<[f32; 4]>> = atlas
        .pages
        .iter()
        .map(|p| vec![[0.0; 4]; (p.width * p.height) as usize])
        .collect();
    // Evaluate each root's block (rectangle plus gutter) in parallel, then copy.
    let blocks: Vec<(usize, Vec<[f32; 4]>)> = (0..solution.roots.len())
        .into_par_iter()
        .map(|i| {
            let r = atlas.rects[i];
            let shape = solution.roots[i].shape;
            let (bw, bh) = (r.w + 2 * GUTTER, r.h + 2 * GUTTER);
            let mut block = Vec::with_capacity((bw * bh) as usize);
            for by in 0..bh {
                for bx in 0..bw {
                    let (ti, tj) = (bx as f64 - GUTTER as f64, by as f64 - GUTTER as f64);
                    let (s0, s1) = (ti / r.w as f64, (ti + 1.0) / r.w as f64);
                    let (t0, t1) = (tj / r.h as f64, (tj + 1.0) / r.h as f64);
                    let centre = DVec2::new(0.5 * (s0 + s1), 0.5 * (t0 + t1));
                    let v = solution.value_at(i, clamp_to_shape(shape, centre));
                    let a = texel_coverage(shape, s0, s1, t0, t1);
                    block.push([v[0] as f32, v[1] as f32, v[2] as f32, a as f32]);
                }
            }
            (i, block)
        })
        .collect();
    for (i, block) in blocks {
        let r = atlas.rects[i];
        let page = &mut pages[r.page as usize];
        let width = atlas.pages[r.page as usize].width;
        let bw = r.w + 2 * GUTTER;
        for (k, texel) in block.into_iter().enumerate() {
            let (bx, by) = (k as u32 % bw, k as u32 / bw);
            let (x, y) = (r.x - GUTTER + bx, r.y - GUTTER + by);
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

fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    texels: &[[f32; 4]],
    float: bool,
) -> std::io::Result<()> {
    let tmp = temporary_path(path);
    let w = width as usize;
    let result = if float {
        exr::prelude::write_rgba_file(&tmp, w, height as usize, |x, y| {
            let t = texels[y * w + x];
            (t[0], t[1], t[2], t[3])
        })
    } else {
        exr::prelude::write_rgba_file(&tmp, w, height as usize, |x, y| {
            let t = texels[y * w + x];
            let h = half::f16::from_f32;
            (h(t[0]), h(t[1]), h(t[2]), h(t[3]))
        })
    };
    result.map_err(|e| std::io::Error::other(e.to_string()))?;
    std::fs::File::open(&tmp)?.sync_all()?;
    std::fs::rename(&tmp, path)?;
    sync_parent(path)
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

/// `preview.png`: the first atlas page, exposed by [`preview_scale`], sRGB-encoded, uncovered texels dimmed.
pub fn preview_png(texels: &[[f32; 4]], width: u32, height: u32) -> std::io::Result<Vec<u8>> {
    let scale = preview_scale(texels);
    let srgb = |x: f32| {
        let x = (x * scale).clamp(0.0, 1.0);
        let e = if x <= 0.0031308 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        };
        (e * 255.0 + 0.5) as u8
    };
    let mut data = Vec::with_capacity(texels.len() * 3);
    for t in texels {
        let dim = if t[3] > 0.0 { 1.0 } else { 0.25 };
        data.extend([srgb(t[0] * dim), srgb(t[1] * dim), srgb(t[2] * dim)]);
    }
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(&data).map_err(std::io::Error::other)?;
    }
    Ok(out)
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

fn frame_json(root: &ElementRoot) -> Value {
    json!({"origin": v3(root.frame.origin), "u": v3(root.frame.u), "v": v3(root.frame.v)})
}

/// Writes every output of a solve to `dir` and returns the result.json document.
pub fn write_outputs(
    dir: &Path,
    scene: &Scene,
    prepared: &Prepared,
    solution: &Solution,
    params: &JobParams,
    options: &OutputOptions,
) -> std::io::Result<Value> {
    let density = options
        .texels_per_meter
        .unwrap_or_else(|| default_density(&solution.roots));
    let atlas = Atlas::pack(&solution.roots, density);
    let pages = render_pages(solution, &atlas);
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
            &dir.join("preview.png"),
            &preview_png(texels, page.width, page.height)?,
        )?;
    }
    let faces: Vec<Value> = solution
        .roots
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let face = &prepared.faces.faces[r.face.0 as usize];
            let rect = atlas.rects[i];
            json!({
                "id": r.face.0, "side": r.side.as_str(), "material": r.material, "area": face.area_m2,
                "frame": frame_json(r), "kind": face.kind.as_str(),
                "mean_radiance": solution.mean_value(i),
                "atlas": {"page": rect.page, "x": rect.x, "y": rect.y, "w": rect.w, "h": rect.h},
            })
        })
        .collect();
    let stats = &solution.stats;
    let mut warnings = scene.warnings.clone();
    if params.domain == crate::job::DomainMode::Extended {
        warnings.push(
            "extended domains are not built yet: every face is a native triangle in this version"
                .into(),
        );
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
            "emitters": solution.roots.iter().filter(|r| r.exitance.iter().any(|&e| e > 0.0)).count(),
            "lights": scene.lights.len(),
            "area": prepared.faces.faces.iter().map(|f| f.area_m2).sum::<f64>(),
        },
        "params": serde_json::to_value(params).unwrap_or(Value::Null),
        "warnings": warnings,
        "stats": {
            "seconds": stats.seconds, "iterations": stats.iterations, "elements": stats.elements,
            "links": stats.links, "unshot_ratio": stats.unshot_ratio,
            "emitted_power": stats.emitted_power, "peak_memory_bytes": peak_memory_bytes(),
            "stop_reason": stats.stop_reason.map(|s| s.as_str()).unwrap_or("converged"),
            "rays": stats.rays, "refinement_capped": stats.refinement_capped,
            "texels_per_meter": atlas.texels_per_meter,
        },
        "faces": faces,
        "atlas": {"pages": page_json},
    });
    let text = serde_json::to_vec_pretty(&result).map_err(std::io::Error::other)?;
    write_atomic(&dir.join("result.json"), &text)?;
    Ok(result)
}

/// The `faces --json` document.
pub fn faces_json(faces: &FaceSet, roots: &[ElementRoot]) -> Value {
    let list: Vec<Value> = faces
        .faces
        .iter()
        .map(|f| {
            let root = roots.iter().find(|r| r.face == f.id && r.side == crate::domain::Side::Front);
            let domain = root.map(|r| {
                let area = match r.shape {
                    Shape::Triangle => 0.5 * r.frame.cross().length(),
                    Shape::Parallelogram => r.frame.cross().length(),
                };
                json!({"origin": v3(r.frame.origin), "u": v3(r.frame.u), "v": v3(r.frame.v), "area": area})
            });
            json!({
                "id": f.id.0, "material": f.material, "double_sided": f.double_sided, "kind": f.kind.as_str(),
                "area": f.area_m2, "holes": f.holes.len(),
                "vertices": f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>(),
                "triangles": f.triangles.len(), "normal": v3(f.normal), "domain": domain,
            })
        })
        .collect();
    json!({"triangles_in": faces.triangles_in, "degenerate_dropped": faces.degenerate_dropped,
        "faces_out": faces.faces.len(), "faces": list})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_texel_coverage_matches_geometry() {
        // A texel straddling the hypotenuse symmetrically is half covered.
        let c = texel_coverage(Shape::Triangle, 0.45, 0.55, 0.45, 0.55);
        assert!((c - 0.5).abs() < 1e-12, "{c}");
        assert_eq!(texel_coverage(Shape::Triangle, 0.1, 0.2, 0.1, 0.2), 1.0);
        assert_eq!(texel_coverage(Shape::Triangle, 0.8, 0.9, 0.8, 0.9), 0.0);
        assert_eq!(
            texel_coverage(Shape::Parallelogram, -0.1, 0.0, 0.2, 0.3),
            0.0
        );
        // Summed over a grid, coverage integrates the triangle's area (half the square).
        let n = 37;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let (s0, t0) = (i as f64 / n as f64, j as f64 / n as f64);
                sum += texel_coverage(
                    Shape::Triangle,
                    s0,
                    s0 + 1.0 / n as f64,
                    t0,
                    t0 + 1.0 / n as f64,
                );
            }
        }
        assert!((sum / (n * n) as f64 - 0.5).abs() < 1e-12);
    }

    #[test]
    fn clamp_to_shape_lands_inside() {
        let p = clamp_to_shape(Shape::Triangle, DVec2::new(0.9, 0.7));
        assert!(p.x + p.y <= 1.0 + 1e-12 && p.x >= 0.0 && p.y >= 0.0);
        assert!((p - DVec2::new(0.6, 0.4)).length() < 1e-12);
    }
}
