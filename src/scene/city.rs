//! The city generator for the scaling benchmark (issue 17) and tests: N copies of one lit building
//! as glTF node instances under one sky panel covering them all.
//!
//! Owns [`city_glb`] and the layout it uses ([`city_grid`], [`CITY_PITCH_WIDTHS`]). Compiled only
//! for unit tests and the `test-support` feature, like `gltf_writer.rs`.
//!
//! Invariants of a city built from a building GLB (pinned by the tests below):
//! - the building's meshes are stored once; every building is a tree of nodes referencing them,
//!   under one instance node carrying only a translation, so the city has N times the building's
//!   triangles (the emissive meshes aside) and its glTF stays the size of one building;
//! - buildings sit on a grid `ceil(sqrt N)` wide in x and as many rows in z as needed, centre to
//!   centre [`CITY_PITCH_WIDTHS`] times the building's footprint width (the larger of its x and z
//!   extents), the grid centred where the building stood; glTF's y is up;
//! - the original sky panel nodes (nodes whose mesh emits) are dropped and one panel replaces them:
//!   the original panel's own triangles, material and winding, its corners moved out in x and z
//!   by half the grid's extent, so it overhangs the city as the original overhung one building, at
//!   the same height, with the same emission and facing.

use super::{load_scene, ExternalFiles, Triangle};
use glam::DVec3;
use serde_json::{json, Value};
use std::collections::BTreeSet;

/// Centre-to-centre distance between neighbouring buildings, in building footprint widths.
pub const CITY_PITCH_WIDTHS: f64 = 1.25;

/// Columns (along x) and rows (along z) of the grid of `n` buildings: `ceil(sqrt n)` columns,
/// as many rows as needed (at least one of each).
pub fn city_grid(n: usize) -> (usize, usize) {
    let mut cols = (n as f64).sqrt().ceil() as usize;
    while cols * cols < n {
        cols += 1;
    }
    let cols = cols.max(1);
    (cols, n.div_ceil(cols).max(1))
}

/// A GLB's JSON document and binary chunk.
fn parse_glb(bytes: &[u8]) -> Result<(Value, Vec<u8>), String> {
    let u32_at = |i: usize| -> Result<usize, String> {
        bytes
            .get(i..i + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            .ok_or_else(|| "truncated GLB".to_string())
    };
    if bytes.get(0..4) != Some(b"glTF") {
        return Err("not a GLB (no glTF magic)".into());
    }
    let json_len = u32_at(12)?;
    if bytes.get(16..20) != Some(b"JSON") {
        return Err("the GLB's first chunk is not JSON".into());
    }
    let json_bytes = bytes
        .get(20..20 + json_len)
        .ok_or("the GLB's JSON chunk is truncated")?;
    let json: Value = serde_json::from_slice(json_bytes).map_err(|e| format!("GLB JSON: {e}"))?;
    let bin_at = 20 + json_len;
    let bin = if bin_at + 8 <= bytes.len() {
        let len = u32_at(bin_at)?;
        if bytes.get(bin_at + 4..bin_at + 8) != Some(b"BIN\0") {
            return Err("the GLB's second chunk is not BIN".into());
        }
        bytes
            .get(bin_at + 8..bin_at + 8 + len)
            .ok_or("the GLB's BIN chunk is truncated")?
            .to_vec()
    } else {
        Vec::new()
    };
    Ok((json, bin))
}

/// Appends `bytes` to the binary chunk (4-byte aligned) as a new buffer view; returns its index.
fn push_view(json: &mut Value, bin: &mut Vec<u8>, bytes: &[u8], target: u32) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let view =
        json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(), "target": target});
    bin.extend_from_slice(bytes);
    push(json, "bufferViews", view)
}

/// Pushes `value` onto the top-level array `key` (created when missing); returns its index.
fn push(json: &mut Value, key: &str, value: Value) -> usize {
    if !json[key].is_array() {
        json[key] = json!([]);
    }
    let array = json[key].as_array_mut().expect("an array");
    array.push(value);
    array.len() - 1
}

/// Copies the node tree under `index` into `out`, leaving out the sky panel's nodes; returns the
/// copy's index, `None` for a panel node.
fn copy_tree(
    index: usize,
    nodes: &[Value],
    panel_meshes: &BTreeSet<u32>,
    depth: usize,
    out: &mut Vec<Value>,
) -> Result<Option<usize>, String> {
    let node = nodes
        .get(index)
        .ok_or_else(|| format!("node {index} does not exist"))?;
    if depth > nodes.len() {
        return Err("the node graph has a cycle".into());
    }
    let is_panel = node["mesh"]
        .as_u64()
        .is_some_and(|m| panel_meshes.contains(&(m as u32)));
    if is_panel {
        if node["children"].as_array().is_some_and(|c| !c.is_empty()) {
            return Err(format!("sky panel node {index} has children"));
        }
        return Ok(None);
    }
    let mut copy = node.clone();
    if let Some(children) = node["children"].as_array() {
        let mut kept = Vec::new();
        for c in children {
            let c = c.as_u64().ok_or("a node child is not an index")? as usize;
            if let Some(k) = copy_tree(c, nodes, panel_meshes, depth + 1, out)? {
                kept.push(k);
            }
        }
        copy["children"] = json!(kept);
    }
    out.push(copy);
    Ok(Some(out.len() - 1))
}

/// A GLB of `n` copies of the building in `building_glb` (a GLB whose only emissive meshes are its
/// sky panel, such as `scenes/kenney_building_small_c/kenney_building_small_c_lit.glb`) on a grid,
/// under one sky panel covering the city (the module header gives the layout). `n = 1` gives the
/// building and its panel as they were. Errors name what the input lacks (no panel, a mesh mixing
/// emissive and non-emissive primitives, external buffers, skins or animations).
pub fn city_glb(building_glb: &[u8], n: usize) -> Result<Vec<u8>, String> {
    if n == 0 {
        return Err("a city has at least one building".into());
    }
    let scene = load_scene(building_glb, &ExternalFiles::Refuse, usize::MAX)
        .map_err(|e| format!("the building does not load: {e}"))?;
    let (mut json, mut bin) = parse_glb(building_glb)?;
    for key in ["skins", "animations"] {
        if json[key].as_array().is_some_and(|a| !a.is_empty()) {
            return Err(format!("the building has {key}: not supported"));
        }
    }
    let buffers = json["buffers"].as_array().map_or(0, Vec::len);
    if buffers != 1 || json["buffers"][0].get("uri").is_some() {
        return Err("the building must keep all its data in the GLB's BIN chunk".into());
    }

    // Split the triangles (world space) into the panel's and the building's, by mesh.
    let emits = |t: &Triangle| scene.material(t).is_emissive();
    let panel_meshes: BTreeSet<u32> = scene
        .triangles
        .iter()
        .filter(|t| emits(t))
        .map(|t| t.source.mesh)
        .collect();
    if panel_meshes.is_empty() {
        return Err("the building has no emissive sky panel".into());
    }
    let building: Vec<&Triangle> = scene.triangles.iter().filter(|t| !emits(t)).collect();
    if let Some(t) = building
        .iter()
        .find(|t| panel_meshes.contains(&t.source.mesh))
    {
        return Err(format!(
            "mesh {} mixes emissive and non-emissive primitives",
            t.source.mesh
        ));
    }
    if building.is_empty() {
        return Err("the building has no non-emissive triangles".into());
    }
    let mut bmin = DVec3::splat(f64::INFINITY);
    let mut bmax = DVec3::splat(f64::NEG_INFINITY);
    for v in building.iter().flat_map(|t| t.vertices) {
        bmin = bmin.min(v);
        bmax = bmax.max(v);
    }
    let centre = 0.5 * (bmin + bmax);
    let width = (bmax.x - bmin.x).max(bmax.z - bmin.z);
    let pitch = CITY_PITCH_WIDTHS * width;
    let (cols, rows) = city_grid(n);
    let half = DVec3::new(
        0.5 * (cols - 1) as f64 * pitch,
        0.0,
        0.5 * (rows - 1) as f64 * pitch,
    );

    // The building's node trees, without the panel, once per building under a translated node.
    let nodes: Vec<Value> = json["nodes"].as_array().cloned().unwrap_or_default();
    let scene_index = json["scene"].as_u64().unwrap_or(0) as usize;
    let roots: Vec<usize> = json["scenes"][scene_index]["nodes"]
        .as_array()
        .ok_or("the building's scene lists no nodes")?
        .iter()
        .map(|v| {
            v.as_u64()
                .map(|i| i as usize)
                .ok_or("a scene node is not an index")
        })
        .collect::<Result<_, _>>()?;
    let mut out_nodes = Vec::new();
    let mut instances = Vec::new();
    for k in 0..n {
        let (i, j) = (k % cols, k / cols);
        let mut children = Vec::new();
        for &r in &roots {
            if let Some(c) = copy_tree(r, &nodes, &panel_meshes, 0, &mut out_nodes)? {
                children.push(c);
            }
        }
        let t = [i as f64 * pitch - half.x, 0.0, j as f64 * pitch - half.z];
        out_nodes
            .push(json!({"name": format!("building_{k}"), "translation": t, "children": children}));
        instances.push(out_nodes.len() - 1);
    }

    // One panel: the original panel's triangles, each primitive with its own material, corners
    // moved out by half the grid's extent (a corner on the building's centre line stays).
    let stretch = |p: f64, c: f64, h: f64| {
        if p > c {
            p + h
        } else if p < c {
            p - h
        } else {
            p
        }
    };
    let mut groups: Vec<((u32, u32), Vec<DVec3>)> = Vec::new();
    for t in scene.triangles.iter().filter(|t| emits(t)) {
        let key = (t.source.mesh, t.source.primitive);
        let at = match groups.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                groups.push((key, Vec::new()));
                groups.len() - 1
            }
        };
        groups[at].1.extend(t.vertices.iter().map(|v| {
            DVec3::new(
                stretch(v.x, centre.x, half.x),
                v.y,
                stretch(v.z, centre.z, half.z),
            )
        }));
    }
    let mut primitives = Vec::new();
    for ((mesh, primitive), vertices) in groups {
        let material = json["meshes"][mesh as usize]["primitives"][primitive as usize]["material"]
            .as_u64()
            .ok_or("the sky panel's primitive has no material")?;
        let mut pos = Vec::with_capacity(vertices.len() * 12);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for v in &vertices {
            for (a, x) in [v.x, v.y, v.z].into_iter().enumerate() {
                let x = x as f32;
                lo[a] = lo[a].min(x);
                hi[a] = hi[a].max(x);
                pos.extend_from_slice(&x.to_le_bytes());
            }
        }
        let idx: Vec<u8> = (0..vertices.len() as u32)
            .flat_map(u32::to_le_bytes)
            .collect();
        let pos_view = push_view(&mut json, &mut bin, &pos, 34962);
        let idx_view = push_view(&mut json, &mut bin, &idx, 34963);
        let pos_acc = push(
            &mut json,
            "accessors",
            json!({"bufferView": pos_view, "componentType": 5126, "count": vertices.len(),
                "type": "VEC3", "min": lo, "max": hi}),
        );
        let idx_acc = push(
            &mut json,
            "accessors",
            json!({"bufferView": idx_view, "componentType": 5125, "count": vertices.len(),
                "type": "SCALAR"}),
        );
        primitives.push(
            json!({"attributes": {"POSITION": pos_acc}, "indices": idx_acc,
            "mode": 4, "material": material}),
        );
    }
    let panel_mesh = push(
        &mut json,
        "meshes",
        json!({"name": "city_sky_panel", "primitives": primitives}),
    );
    out_nodes.push(json!({"name": "city_sky_panel", "mesh": panel_mesh}));
    instances.push(out_nodes.len() - 1);

    json["nodes"] = json!(out_nodes);
    json["scenes"] = json!([{"name": format!("city of {n} buildings"), "nodes": instances}]);
    json["scene"] = json!(0);
    json["extras"] = json!({"city": {
        "buildings": n, "columns": cols, "rows": rows, "pitch_m": pitch,
        "note": "generated by wavrad::scene::city::city_glb: node instances of one building under one sky panel"
    }});
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    json["buffers"][0]["byteLength"] = json!(bin.len());
    Ok(super::gltf_writer::glb_from_parts(&json, &bin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn building() -> Vec<u8> {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/kenney_building_small_c/kenney_building_small_c_lit.glb"
        );
        std::fs::read(path).expect("the Kenney sample")
    }

    fn load(bytes: &[u8]) -> Scene {
        load_scene(bytes, &ExternalFiles::Refuse, usize::MAX).expect("loads")
    }

    /// Bounds of the emissive (`true`) or other triangles.
    fn bounds(scene: &Scene, emissive: bool) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in scene
            .triangles
            .iter()
            .filter(|t| scene.material(t).is_emissive() == emissive)
        {
            for v in t.vertices {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        (lo, hi)
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn the_grid_is_ceil_sqrt_n_wide() {
        assert_eq!(city_grid(1), (1, 1));
        assert_eq!(city_grid(3), (2, 2));
        assert_eq!(city_grid(4), (2, 2));
        assert_eq!(city_grid(5), (3, 2));
        assert_eq!(city_grid(16), (4, 4));
        assert_eq!(city_grid(64), (8, 8));
    }

    #[test]
    fn a_city_of_four_has_four_buildings_and_one_panel_over_them_all() {
        let one = load(&building());
        let panel_tris = one.emissive_triangle_count();
        assert_eq!(panel_tris, 2, "the sample's sky panel is one quad");
        let building_tris = one.triangles.len() - panel_tris;
        let (blo, bhi) = bounds(&one, false);
        let (plo, phi) = bounds(&one, true);
        let pitch = CITY_PITCH_WIDTHS * (bhi.x - blo.x).max(bhi.z - blo.z);

        let glb = city_glb(&building(), 4).expect("a city");
        let city = load(&glb);
        assert_eq!(city.triangles.len(), 4 * building_tris + panel_tris);
        // One emitter: the panel's two triangles, one material, coplanar, facing as before.
        let emissive: Vec<&Triangle> = city
            .triangles
            .iter()
            .filter(|t| city.material(t).is_emissive())
            .collect();
        assert_eq!(emissive.len(), panel_tris);
        assert!(emissive.iter().all(|t| t.material == emissive[0].material));
        let original_normal = one
            .triangles
            .iter()
            .find(|t| one.material(t).is_emissive())
            .unwrap()
            .cross()
            .normalize();
        for t in &emissive {
            assert!(t.cross().normalize().dot(original_normal) > 1.0 - 1e-9);
        }
        let panel_area: f64 = emissive.iter().map(|t| t.area()).sum();
        // Buildings: a 2 x 2 grid, `pitch` apart, centred where the building stood.
        let h = DVec3::new(0.5 * pitch, 0.0, 0.5 * pitch);
        let (clo, chi) = bounds(&city, false);
        assert!(close(clo, blo - h) && close(chi, bhi + h), "{clo} {chi}");
        // The panel overhangs the city as it overhung the building, at the same height.
        let (qlo, qhi) = bounds(&city, true);
        assert!(close(qlo, plo - h) && close(qhi, phi + h), "{qlo} {qhi}");
        let expected_area = (qhi.x - qlo.x) * (qhi.z - qlo.z);
        assert!((panel_area - expected_area).abs() < 1e-6 * expected_area);
        assert!(close(city.bounds.min, blo.min(plo) - h));
        // Each building's meshes are stored once: the city's GLB is barely larger.
        assert!(glb.len() < building().len() + 4096, "{}", glb.len());
    }

    #[test]
    fn a_city_of_one_is_the_building_under_its_own_panel() {
        let one = load(&building());
        let city = load(&city_glb(&building(), 1).unwrap());
        assert_eq!(city.triangles.len(), one.triangles.len());
        assert!(close(city.bounds.min, one.bounds.min) && close(city.bounds.max, one.bounds.max));
        assert_eq!(
            city.emissive_triangle_count(),
            one.emissive_triangle_count()
        );
    }

    #[test]
    fn an_uneven_city_fills_its_grid_row_by_row_under_one_panel() {
        let one = load(&building());
        let b = one.triangles.len() - one.emissive_triangle_count();
        let city = load(&city_glb(&building(), 5).unwrap());
        assert_eq!(city.triangles.len(), 5 * b + 2);
        let (blo, bhi) = bounds(&one, false);
        let (clo, chi) = bounds(&city, false);
        let pitch = CITY_PITCH_WIDTHS * (bhi.x - blo.x).max(bhi.z - blo.z);
        // Three columns, two rows.
        assert!(((chi.x - clo.x) - (bhi.x - blo.x) - 2.0 * pitch).abs() < 1e-5);
        assert!(((chi.z - clo.z) - (bhi.z - blo.z) - pitch).abs() < 1e-5);
    }

    #[test]
    fn a_building_without_a_sky_panel_is_refused() {
        let mut b = crate::scene::gltf_writer::SceneBuilder::new();
        let m = b.material([0.5; 3], [0.0; 3], false);
        b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Z, 1);
        let err = city_glb(&b.to_glb(), 4).unwrap_err();
        assert!(err.contains("no emissive sky panel"), "{err}");
        assert!(city_glb(&building(), 0).is_err());
    }
}
