//! Scene import on good and bad files: every bad file is refused with a message naming the place,
//! never a panic; the CLI maps refusals to exit code 2.

use glam::DVec3;
use serde_json::{json, Value};
use wavrad::scene::gltf_writer::{glb_from_parts, SceneBuilder};
use wavrad::scene::{load_scene, ExternalFiles, SceneError};

mod common;
use common::cli::wavrad;

const LIMIT: usize = 1_000_000;

fn one_quad_glb() -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [1.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    b.to_glb()
}

/// Splits a GLB into its JSON document and binary chunk.
fn glb_parts(glb: &[u8]) -> (Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = if glb.len() > 20 + json_len {
        glb[28 + json_len..].to_vec()
    } else {
        Vec::new()
    };
    (doc, bin)
}

fn message(e: &SceneError) -> String {
    e.to_string()
}

#[test]
fn a_good_glb_loads_with_its_materials() {
    let scene = load_scene(&one_quad_glb(), &ExternalFiles::Refuse, LIMIT).expect("loads");
    assert_eq!(scene.triangles.len(), 2);
    assert_eq!(scene.materials[0].rho, [0.5; 3]);
    assert_eq!(scene.materials[0].emission, [1.0; 3]);
    // Front normal is u x v = +z.
    assert!(scene.triangles[0].cross().normalize().dot(DVec3::Z) > 0.999);
}

#[test]
fn truncated_glb_is_refused_with_a_reason() {
    let glb = one_quad_glb();
    for cut in [0, 5, 12, 19, glb.len() / 2, glb.len() - 1] {
        let err = load_scene(&glb[..cut], &ExternalFiles::Refuse, LIMIT).unwrap_err();
        assert!(
            matches!(err, SceneError::Unreadable(_)),
            "cut at {cut}: {err:?}"
        );
        assert!(!message(&err).is_empty());
    }
}

#[test]
fn wrong_magic_and_garbage_are_refused() {
    for bytes in [
        &b"glTX\x02\x00\x00\x00"[..],
        b"hello world",
        b"{not json",
        b"\x00\x01\x02",
    ] {
        let err = load_scene(bytes, &ExternalFiles::Refuse, LIMIT).unwrap_err();
        assert!(matches!(err, SceneError::Unreadable(_)), "{err:?}");
    }
}

#[test]
fn index_out_of_range_names_the_primitive() {
    let (doc, mut bin) = glb_parts(&one_quad_glb());
    // The index buffer follows 4 positions (48 bytes); make the third index 99.
    bin[48 + 8..48 + 12].copy_from_slice(&99u32.to_le_bytes());
    let err = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).unwrap_err();
    let m = message(&err);
    assert!(matches!(err, SceneError::Invalid(_)), "{err:?}");
    assert!(
        m.contains("mesh 0 primitive 0 triangle 0") && m.contains("index 99 is out of range"),
        "{m}"
    );
}

#[test]
fn nan_positions_are_refused_and_every_bad_primitive_is_reported() {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [1.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    b.quad(m, DVec3::Z, DVec3::X, DVec3::Y, 1);
    let (doc, mut bin) = glb_parts(&b.to_glb());
    let nan = f32::NAN.to_le_bytes();
    // First vertex of mesh 0 (offset 0) and of mesh 1 (after 48 + 24 bytes of mesh 0).
    bin[0..4].copy_from_slice(&nan);
    bin[72 + 4..72 + 8].copy_from_slice(&nan);
    let err = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).unwrap_err();
    let m = message(&err);
    // Vertex 0 of each quad is shared by both its triangles: four problems, each at its triangle.
    let mut places: Vec<&str> = match &err {
        SceneError::Invalid(problems) => problems.iter().map(|p| p.place.as_str()).collect(),
        other => panic!("expected Invalid, got {other:?}"),
    };
    places.sort();
    assert_eq!(
        places,
        [
            "mesh 0 primitive 0 triangle 0",
            "mesh 0 primitive 0 triangle 1",
            "mesh 1 primitive 0 triangle 0",
            "mesh 1 primitive 0 triangle 1"
        ],
        "{m}"
    );
    assert!(m.contains("vertex 0 has a NaN"), "{m}");
}

#[test]
fn many_bad_triangles_are_listed_up_to_a_cap_then_counted() {
    // 40 quads in one mesh would be 40 meshes with SceneBuilder; instead corrupt a long index buffer.
    let (mut doc, mut bin) = glb_parts(&one_quad_glb());
    // Replace the 6 indices by 120 (40 triangles), every one out of range.
    let index_offset = 48;
    bin.truncate(index_offset);
    for _ in 0..120 {
        bin.extend_from_slice(&7u32.to_le_bytes());
    }
    let index_view = doc["accessors"][1]["bufferView"].as_u64().unwrap() as usize;
    doc["bufferViews"][index_view]["byteLength"] = json!(480);
    doc["accessors"][1]["count"] = json!(120);
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    let err = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).unwrap_err();
    let m = message(&err);
    let SceneError::Invalid(problems) = &err else {
        panic!("expected Invalid, got {err:?}");
    };
    assert_eq!(problems.len(), 17, "{m}");
    assert_eq!(problems[15].place, "mesh 0 primitive 0 triangle 15");
    assert!(
        problems[16].message.starts_with("24 more triangle(s)"),
        "{m}"
    );
}

#[test]
fn cyclic_node_graph_is_refused_not_followed() {
    let (mut doc, bin) = glb_parts(&one_quad_glb());
    doc["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
    doc["scenes"] = json!([{"nodes": [0]}]);
    let err = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT);
    let err = err.expect_err("a cycle must be refused");
    assert!(message(&err).contains("node"), "{}", message(&err));
}

#[test]
fn lying_buffer_length_is_refused() {
    let (mut doc, bin) = glb_parts(&one_quad_glb());
    doc["buffers"][0]["byteLength"] = json!(1_000_000);
    let err = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).unwrap_err();
    assert!(!message(&err).is_empty());
}

#[test]
fn mirrored_node_transform_keeps_the_front_side() {
    let (mut doc, bin) = glb_parts(&one_quad_glb());
    doc["nodes"][0]["scale"] = json!([-1.0, 1.0, 1.0]);
    let scene = load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).unwrap();
    // Mirroring x keeps the quad's normal at +z; the winding is compensated.
    for t in &scene.triangles {
        assert!(
            t.cross().normalize().dot(DVec3::Z) > 0.999,
            "{:?}",
            t.cross()
        );
        assert!(t.vertices.iter().all(|v| v.x <= 0.0));
    }
}

#[test]
fn data_uri_gltf_loads_and_external_uris_are_refused_over_http() {
    use base64::Engine;
    let (mut doc, bin) = glb_parts(&one_quad_glb());
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    doc["buffers"][0]["uri"] = json!(uri);
    let text = serde_json::to_vec(&doc).unwrap();
    let scene =
        load_scene(&text, &ExternalFiles::Refuse, LIMIT).expect("self-contained glTF loads");
    assert_eq!(scene.triangles.len(), 2);
    doc["buffers"][0]["uri"] = json!("scene.bin");
    let err = load_scene(
        &serde_json::to_vec(&doc).unwrap(),
        &ExternalFiles::Refuse,
        LIMIT,
    )
    .unwrap_err();
    assert!(message(&err).contains("scene.bin"), "{}", message(&err));
    // A data URI whose payload is shorter than the buffer says it is.
    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,AAAA");
    let err = load_scene(
        &serde_json::to_vec(&doc).unwrap(),
        &ExternalFiles::Refuse,
        LIMIT,
    )
    .unwrap_err();
    assert!(message(&err).contains("buffer 0"), "{}", message(&err));
}

#[test]
fn triangle_limit_is_enforced() {
    let err = load_scene(&one_quad_glb(), &ExternalFiles::Refuse, 1).unwrap_err();
    assert!(
        matches!(err, SceneError::Unsolvable(_)) && message(&err).contains("limit"),
        "{err:?}"
    );
}

#[test]
fn the_shared_sample_gltf_with_external_bin_loads() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/cornell_box/cornell_box.gltf");
    let scene = wavrad::scene::load_scene_from_path(&path, LIMIT).expect("bundled sample loads");
    assert_eq!(scene.triangles.len(), 32);
    assert_eq!(scene.emissive_triangle_count(), 2);
}

#[test]
fn cli_exits_2_with_a_one_line_reason_on_bad_input() {
    let dir = std::env::temp_dir().join(format!("wavrad-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("truncated.glb");
    let glb = one_quad_glb();
    std::fs::write(&bad, &glb[..glb.len() / 2]).unwrap();
    let out = wavrad(&[
        "solve",
        bad.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("truncated"), "{stderr}");
    assert!(out.stdout.is_empty(), "stdout must stay clean on errors");
    // Bad option: exit 2 as well.
    let out = wavrad(&["solve", bad.to_str().unwrap(), "--out", "x", "--order", "7"]);
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cli_solve_writes_the_contract_outputs() {
    let dir = std::env::temp_dir().join(format!("wavrad-cli-ok-{}", std::process::id()));
    let scene = dir.join("box.glb");
    std::fs::create_dir_all(&dir).unwrap();
    let mut b = SceneBuilder::new();
    let w = b.material([0.5; 3], [0.0; 3], false);
    let e = b.material([0.5; 3], [1.0; 3], false);
    b.inward_box([w, w, w, e, w, w], DVec3::ZERO, DVec3::ONE, 1);
    std::fs::write(&scene, b.to_glb()).unwrap();
    let out_dir = dir.join("out");
    let out = wavrad(&[
        "solve",
        scene.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--order",
        "1",
        "--json",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value = serde_json::from_slice(&out.stdout).expect("one JSON summary on stdout");
    assert_eq!(summary["stats"]["stop_reason"], "converged");
    let result: Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["scene"]["triangles"], 12);
    // The box's 12 triangles merge into 6 parallelogram faces, one radiosity side each.
    let faces = result["faces"].as_array().unwrap();
    assert_eq!(faces.len(), 6);
    assert!(faces.iter().all(|f| f["kind"] == "parallelogram"));
    assert_eq!(result["scene"]["faces"], 6);
    assert!(result["stats"]["peak_memory_bytes"].as_u64().unwrap() > 0);
    // Counters of every fallback; a box has no extended face.
    for counter in [
        "refinement_capped",
        "touching_fallbacks",
        "node_sum_splits",
        "extended_faces",
        "extended_faces_on_domain",
        "extended_faces_tessellated",
    ] {
        assert!(result["stats"][counter].is_u64(), "{counter}");
    }
    assert_eq!(result["stats"]["extended_faces"], 0);
    // What the solve's memory grows with (docs/contract.md): both measured on every solve.
    for figure in ["bytes_per_element", "bytes_per_link"] {
        let bytes = result["stats"][figure].as_f64().unwrap_or(f64::NAN);
        assert!(bytes > 0.0, "{figure}: {bytes}");
    }
    let csv = std::fs::read_to_string(out_dir.join("convergence.csv")).unwrap();
    assert!(csv.starts_with("seconds,unshot_ratio,elements,links\n") && csv.lines().count() > 2);
    // The EXR reads back with the atlas size result.json states, and coverage alpha in [0, 1].
    let image = exr::prelude::read_first_rgba_layer_from_file(
        out_dir.join("lightmap.exr"),
        |res, _| (res.width(), vec![[0f32; 4]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b, a];
        },
    )
    .expect("lightmap.exr reads back");
    let size = image.layer_data.size;
    assert_eq!(
        size.width() as u64,
        result["atlas"]["pages"][0]["width"].as_u64().unwrap()
    );
    assert_eq!(
        size.height() as u64,
        result["atlas"]["pages"][0]["height"].as_u64().unwrap()
    );
    let (_, texels) = &image.layer_data.channel_data.pixels;
    assert!(texels
        .iter()
        .all(|t| t.iter().all(|c| c.is_finite() && *c >= 0.0) && t[3] <= 1.0));
    assert!(texels.iter().any(|t| t[3] == 1.0) && texels.iter().any(|t| t[0] > 0.0));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Fuzzing regressions (tests/data/malformed/fuzz_*): each is refused with a reason of its own,
/// not by the importer's panic guard ("the glTF parser failed").
#[test]
fn fuzz_crashes_are_refused_with_a_reason() {
    let cases = [
        (
            "fuzz_position_accessor_out_of_range.gltf",
            "accessor index out of bounds",
        ),
        ("fuzz_accessor_count_zero.glb", "count must be at least 1"),
        (
            "fuzz_position_accessor_vec2.gltf",
            "POSITION: must be a VEC3 accessor of FLOAT",
        ),
        ("float_indices.gltf", "indices: must be a SCALAR accessor"),
        (
            "position_accessor_vec4_u8.gltf",
            "POSITION: must be a VEC3 accessor of FLOAT",
        ),
    ];
    for (file, expected) in cases {
        let path = format!("{}/tests/data/malformed/{file}", env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(&path).unwrap();
        let e = load_scene(&bytes, &ExternalFiles::Refuse, 1000).unwrap_err();
        let m = message(&e);
        assert!(m.contains(expected), "{file}: {m}");
        assert!(!m.contains("parser failed"), "{file}: {m}");
    }
}

/// The glTF's first perspective camera is read in world space (node `-Z` forward, `+Y` up, parent
/// transforms applied); an orthographic camera on a later node does not replace it; a file
/// without one has none (the preview then frames the scene).
#[test]
fn the_importer_reads_the_first_perspective_camera_in_world_space() {
    use wavrad::scene::Camera;
    let forward = DVec3::new(-1.0, -0.5, -1.0).normalize();
    let up = (DVec3::Y - forward * forward.y).normalize();
    let camera = Camera {
        position: DVec3::new(1.0, 2.0, 3.0),
        forward,
        up,
        yfov: 0.7,
        aspect: Some(1.5),
        znear: 0.05,
    };
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [1.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    b.camera(camera);
    let glb = b.to_glb();
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-5;
    let scene = load_scene(&glb, &ExternalFiles::Refuse, LIMIT).expect("loads");
    let read = scene.camera.expect("the camera is read");
    assert!(close(read.position, camera.position), "{read:?}");
    assert!(
        close(read.forward, forward) && close(read.up, up),
        "{read:?}"
    );
    assert!((read.yfov - 0.7).abs() < 1e-6 && (read.aspect.unwrap() - 1.5).abs() < 1e-6);
    assert!((read.znear - 0.05).abs() < 1e-6);

    // The camera node under a parent that moves it and scales it by 2; an orthographic camera on
    // a node of a higher index.
    let (mut doc, bin) = glb_parts(&glb);
    let nodes = doc["nodes"].as_array().unwrap().len();
    let camera_node = nodes - 1;
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"translation": [10.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [camera_node]}));
    doc["cameras"].as_array_mut().unwrap().push(
        json!({"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}),
    );
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"camera": 1, "translation": [0.0, 0.0, 9.0]}));
    let roots: Vec<usize> = (0..camera_node).chain([nodes, nodes + 1]).collect();
    doc["scenes"][0]["nodes"] = json!(roots);
    let scene =
        load_scene(&glb_from_parts(&doc, &bin), &ExternalFiles::Refuse, LIMIT).expect("loads");
    let read = scene.camera.expect("the perspective camera is read");
    assert!(close(read.position, DVec3::new(12.0, 4.0, 6.0)), "{read:?}");
    assert!(
        close(read.forward, forward) && close(read.up, up),
        "{read:?}"
    );

    // Without a camera: none.
    let scene = load_scene(&one_quad_glb(), &ExternalFiles::Refuse, LIMIT).expect("loads");
    assert_eq!(scene.camera, None);
}
