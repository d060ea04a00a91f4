//! Benchmark: what textures cost before the solve. The largest lit scene of `../shared/scenes/`
//! (the Sauerbraten level, 70 000 triangles) is given a tiled texture (a 64 x 64 checker, planar
//! texture coordinates in 0.5 m tiles, on every non-emissive material), so every face's
//! reflectance varies and every root reads a reflectance map; it prints import + `prepare` (faces,
//! domains, maps, visibility) against the untextured scene, best of three, and the peak memory.
//!
//! Run: `cargo bench --bench textures` (prints SKIP when `../shared` is absent).

use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;
use wavrad::domain::DomainMode;
use wavrad::scene::{load_scene, ExternalFiles};

const RUNS: usize = 3;

/// Appends `bytes` to the binary chunk as a new buffer view; returns its index.
fn push_view(json: &mut Value, bin: &mut Vec<u8>, bytes: &[u8]) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(bytes);
    let views = json["bufferViews"].as_array_mut().expect("bufferViews");
    views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
    views.len() - 1
}

/// The GLB with a tiled checker on every non-emissive material and `TEXCOORD_0` from positions.
fn textured_twin(bytes: &[u8]) -> Vec<u8> {
    let u32_at =
        |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes")) as usize;
    let json_len = u32_at(12);
    let mut json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).expect("JSON chunk");
    let bin_at = 20 + json_len;
    let mut bin = bytes[bin_at + 8..bin_at + 8 + u32_at(bin_at)].to_vec();
    let checker = image::RgbImage::from_fn(64, 64, |x, y| {
        if (x / 8 + y / 8) % 2 == 0 {
            image::Rgb([200, 180, 160])
        } else {
            image::Rgb([90, 80, 70])
        }
    });
    let mut png = Vec::new();
    checker
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("PNG encodes");
    let view = push_view(&mut json, &mut bin, &png);
    json["images"] = json!([{"bufferView": view, "mimeType": "image/png"}]);
    json["textures"] = json!([{"source": 0}]);
    let meshes = json["meshes"].as_array().map_or(0, Vec::len);
    for m in 0..meshes {
        let primitives = json["meshes"][m]["primitives"]
            .as_array()
            .map_or(0, Vec::len);
        for p in 0..primitives {
            let a = json["meshes"][m]["primitives"][p]["attributes"]["POSITION"]
                .as_u64()
                .expect("POSITION") as usize;
            let accessor = json["accessors"][a].clone();
            let view =
                &json["bufferViews"][accessor["bufferView"].as_u64().expect("view") as usize];
            let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
                + accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
            let stride = view["byteStride"].as_u64().unwrap_or(12) as usize;
            let count = accessor["count"].as_u64().expect("count") as usize;
            let mut uv = Vec::with_capacity(8 * count);
            for i in 0..count {
                let f = |k: usize| {
                    let at = start + stride * i + 4 * k;
                    f32::from_le_bytes(bin[at..at + 4].try_into().expect("4 bytes"))
                };
                for c in [(f(0) + f(2)) * 2.0, f(1) * 2.0] {
                    uv.extend_from_slice(&c.to_le_bytes());
                }
            }
            let view = push_view(&mut json, &mut bin, &uv);
            let accessors = json["accessors"].as_array_mut().expect("accessors");
            accessors.push(
                json!({"bufferView": view, "componentType": 5126, "count": count, "type": "VEC2"}),
            );
            let index = accessors.len() - 1;
            json["meshes"][m]["primitives"][p]["attributes"]["TEXCOORD_0"] = json!(index);
        }
    }
    for material in json["materials"].as_array_mut().into_iter().flatten() {
        let emissive = material["emissiveFactor"]
            .as_array()
            .is_some_and(|e| e.iter().any(|x| x.as_f64().unwrap_or(0.0) > 0.0));
        if !emissive {
            material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
        }
    }
    json["buffers"] = json!([{"byteLength": bin.len()}]);
    wavrad::scene::gltf_writer::glb_from_parts(&json, &bin)
}

/// Best of `RUNS` import + prepare: seconds, roots, roots with a reflectance map.
fn measure(glb: &[u8]) -> (f64, usize, usize) {
    let mut best = (f64::INFINITY, 0, 0);
    for _ in 0..RUNS {
        let start = Instant::now();
        let scene = load_scene(glb, &ExternalFiles::Refuse, 10_000_000).expect("scene loads");
        let prepared = wavrad::pipeline::prepare(&scene, DomainMode::Extended);
        let seconds = start.elapsed().as_secs_f64();
        let maps = prepared
            .roots
            .iter()
            .filter(|r| r.reflectance.is_some())
            .count();
        if seconds < best.0 {
            best = (seconds, prepared.roots.len(), maps);
        }
    }
    best
}

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/scenes/sauerbraten_zdm2/sauerbraten_zdm2_lit.glb");
    let Ok(bytes) = std::fs::read(&path) else {
        println!(
            "SKIP: {} is absent (a fresh clone has no ../shared)",
            path.display()
        );
        return;
    };
    let (plain_s, roots, _) = measure(&bytes);
    println!("untextured: import + prepare {plain_s:.2} s, {roots} roots");
    let (textured_s, roots, maps) = measure(&textured_twin(&bytes));
    println!(
        "tiled checker: import + prepare {textured_s:.2} s ({:.1}x), {roots} roots, {maps} with a reflectance map",
        textured_s / plain_s
    );
    if let Ok(status) = std::fs::read_to_string("/proc/self/status") {
        for line in status.lines().filter(|l| l.starts_with("VmHWM")) {
            println!("peak memory: {}", line.trim_start_matches("VmHWM:").trim());
        }
    }
}
