//! The HTTP service over a real socket (port 0), what a submission's body may be: GLB, glTF JSON
//! and multipart uploads whose parts carry the external buffers and images by name; bad and
//! malformed scenes are refused with a 4xx that says why, and the server keeps working.

use base64::Engine;
use glam::DVec3;
use reqwest::StatusCode;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Duration;
use wavrad::scene::gltf_writer::{glb_from_parts, SceneBuilder};
use wavrad::service::ServiceConfig;

mod common;
use common::scenes::{one_triangle_gltf, small_scene, TRIANGLE};
use common::service::{
    client, data_dir, error_of, expect_error, get, get_ok, list_jobs, multipart, start, submit,
    submit_ok, wait_for,
};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_scenes_are_refused_and_the_server_keeps_working() {
    let mut config = ServiceConfig::new(data_dir("http-bad"));
    config.max_triangles = 12;
    let base = start(config).await;
    let client = client();

    // A GLB cut in half.
    let glb = small_scene(0.5);
    let truncated = glb[..glb.len() / 2].to_vec();
    let response = submit(&client, &base, "order=1", "model/gltf-binary", truncated).await;
    expect_error(
        response,
        StatusCode::UNPROCESSABLE_ENTITY,
        "unreadable_scene",
    )
    .await;

    // glTF JSON whose index buffer points past the vertices.
    let (mut root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 5]);
    root["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    let body = serde_json::to_vec(&root).unwrap();
    let response = submit(&client, &base, "order=1", "model/gltf+json", body).await;
    let error = expect_error(response, StatusCode::UNPROCESSABLE_ENTITY, "invalid_scene").await;
    assert!(
        error["message"].as_str().unwrap().contains("out of range"),
        "{error}"
    );

    // A GLB with a NaN vertex position.
    let mut nan = TRIANGLE;
    nan[1][1] = f32::NAN;
    let (root, bin) = one_triangle_gltf(nan, [0, 1, 2]);
    let response = submit(
        &client,
        &base,
        "",
        "model/gltf-binary",
        glb_from_parts(&root, &bin),
    )
    .await;
    let error = expect_error(response, StatusCode::UNPROCESSABLE_ENTITY, "invalid_scene").await;
    assert!(
        error["message"].as_str().unwrap().contains("NaN"),
        "{error}"
    );

    // Over --max-triangles (12 here).
    let mut b = SceneBuilder::new();
    let lamp = b.material([0.5; 3], [1.0; 3], false);
    b.inward_box([lamp; 6], DVec3::ZERO, DVec3::ONE, 2);
    let response = submit(&client, &base, "", "model/gltf-binary", b.to_glb()).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        error["message"].as_str().unwrap().contains("max-triangles"),
        "{error}"
    );

    // The same triangle without the NaN is fine (so it was the NaN that was refused).
    let (root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    let ok = submit(
        &client,
        &base,
        "order=1",
        "model/gltf-binary",
        glb_from_parts(&root, &bin),
    )
    .await;
    assert_eq!(ok.status(), StatusCode::ACCEPTED);

    // Nothing refused was stored or listed.
    let list = list_jobs(&client, &base).await;
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1);

    let health = get(&client, format!("{base}/healthz")).await;
    assert_eq!(health.status(), StatusCode::OK);
    let job = submit_ok(&client, &base, "order=1", small_scene(0.5)).await;
    wait_for(
        &client,
        &base,
        job["id"].as_str().unwrap(),
        "succeeded",
        Duration::from_secs(60),
    )
    .await;
}

/// Every file of `tests/data/malformed/` (written by its `make.py`: truncated, wrong magic, huge
/// counts, cyclic node graphs, NaN, missing buffers, data URIs lying about their size, ...) is
/// refused with a 4xx and a message, and the server keeps serving.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_files_get_4xx_and_the_server_stays_up() {
    let base = start(ServiceConfig::new(data_dir("http-malformed"))).await;
    let client = client();
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/malformed"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e != "py"))
        .collect();
    files.sort();
    assert!(files.len() >= 25, "the corpus is there: {}", files.len());
    // Each hostile shape the service must refuse, by category (issue 6), in both containers
    // where it applies.
    let categories: [(&str, &[&str]); 8] = [
        (
            "truncated",
            &[
                "truncated.glb",
                "truncated_header.glb",
                "truncated.gltf",
                "empty.glb",
            ],
        ),
        ("wrong magic", &["wrong_magic.glb", "wrong_version.glb"]),
        (
            "huge counts",
            &[
                "huge_accessor_count.gltf",
                "huge_accessor_count.glb",
                "huge_buffer_byte_length.gltf",
                "huge_chunk_count.glb",
                "length_lies.glb",
                "json_chunk_length_lies.glb",
            ],
        ),
        (
            "cyclic node graphs",
            &[
                "cyclic_nodes.gltf",
                "cyclic_nodes.glb",
                "self_child_node.gltf",
                "shared_children_nodes.gltf",
            ],
        ),
        (
            "NaN",
            &[
                "nan_positions.gltf",
                "nan_positions.glb",
                "nan_emission.gltf",
                "inf_positions.gltf",
                "inf_emission.gltf",
                "inf_emission_strength.gltf",
                "inf_light_intensity.gltf",
                "huge_translation.gltf",
            ],
        ),
        (
            "missing buffers",
            &[
                "missing_buffer.gltf",
                "no_buffers.gltf",
                "buffer_without_uri.gltf",
                "missing_bin_chunk.glb",
                "bin_chunk_shorter_than_buffer.glb",
            ],
        ),
        (
            "data URIs lying about their size",
            &[
                "data_uri_shorter_than_declared.gltf",
                "data_uri_longer_than_declared.gltf",
            ],
        ),
        (
            "fuzz crashes",
            &[
                "fuzz_accessor_count_zero.glb",
                "fuzz_position_accessor_out_of_range.gltf",
                "fuzz_position_accessor_vec2.gltf",
                "float_indices.gltf",
                "position_accessor_vec4_u8.gltf",
            ],
        ),
    ];
    for (category, names) in categories {
        for name in names {
            assert!(
                files.iter().any(|f| f.ends_with(name)),
                "{category}: {name} is in the corpus"
            );
        }
    }
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let content_type = match path.extension().and_then(|e| e.to_str()) {
            Some("gltf") => "model/gltf+json",
            _ => "model/gltf-binary",
        };
        let bytes = std::fs::read(&path).unwrap();
        let response = submit(&client, &base, "order=1", content_type, bytes).await;
        let status = response.status();
        assert!(status.is_client_error(), "{name}: {status}");
        let body: Value = response
            .json()
            .await
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let message = body["error"]["message"].as_str().unwrap_or("");
        assert!(message.len() > 10, "{name}: {body}");
        assert!(body["error"]["code"].is_string(), "{name}: {body}");
        println!("{name}: {status} {}: {message}", body["error"]["code"]);
        let health = get(&client, format!("{base}/healthz")).await;
        assert_eq!(health.status(), StatusCode::OK, "after {name}");
    }
    let list = list_jobs(&client, &base).await;
    assert_eq!(list, json!({"jobs": []}), "no job was created");
}

/// A .gltf with an external buffer is solved when the buffer is uploaded as a part named by its
/// URI; without it, or without a `scene` part, the upload is refused with what to fix.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_multipart_upload_resolves_external_files_by_name() {
    let base = start(ServiceConfig::new(data_dir("http-multipart"))).await;
    let client = client();
    let (mut root, bin) = one_triangle_gltf(TRIANGLE, [0, 1, 2]);
    root["buffers"][0]["uri"] = json!("geometry/tri.bin");
    let gltf = serde_json::to_vec(&root).unwrap();

    let (content_type, body) = multipart(&[
        ("scene", "tri.gltf", "model/gltf+json", &gltf),
        (
            "geometry/tri.bin",
            "tri.bin",
            "application/octet-stream",
            &bin,
        ),
    ]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    let done = wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    assert_eq!(done["state"], "succeeded");

    let (content_type, body) = multipart(&[("scene", "tri.gltf", "model/gltf+json", &gltf)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        error["message"]
            .as_str()
            .unwrap()
            .contains("geometry/tri.bin"),
        "{error}"
    );

    let (content_type, body) =
        multipart(&[("tri.bin", "tri.bin", "application/octet-stream", &bin)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    let error = expect_error(response, StatusCode::BAD_REQUEST, "bad_multipart").await;
    assert!(error["message"].as_str().unwrap().contains("'scene'"));
}

/// A job carries its scene's name: the `name` parameter, else the file name of a multipart
/// upload's `scene` part (without its folder), else none; a bad `name` is a 400 that says why.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_carries_the_name_of_its_scene() {
    let base = start(ServiceConfig::new(data_dir("http-names"))).await;
    let client = client();
    let glb = small_scene(0.5);

    let named = submit_ok(
        &client,
        &base,
        "order=1&name=Caf%C3%A9%20room.glb",
        glb.clone(),
    )
    .await;
    assert_eq!(named["name"], "Café room.glb");
    let unnamed = submit_ok(&client, &base, "order=1", glb.clone()).await;
    assert!(unnamed.get("name").is_none(), "{unnamed}");

    let (content_type, body) =
        multipart(&[("scene", "uploads/box.glb", "model/gltf-binary", &glb)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let from_file: Value = response.json().await.unwrap();
    assert_eq!(from_file["name"], "box.glb");
    let (content_type, body) =
        multipart(&[("scene", "uploads/box.glb", "model/gltf-binary", &glb)]);
    let response = submit(&client, &base, "name=mine", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let overridden: Value = response.json().await.unwrap();
    assert_eq!(
        overridden["name"], "mine",
        "the parameter wins over the file name"
    );

    let too_long = format!("name={}", "x".repeat(201));
    for (query, says) in [
        ("name=", "1 to 200"),
        (too_long.as_str(), "1 to 200"),
        ("name=a%0Ab", "control"),
        ("name=a&name=b", "twice"),
    ] {
        let response = submit(&client, &base, query, "model/gltf-binary", glb.clone()).await;
        let error = expect_error(response, StatusCode::BAD_REQUEST, "bad_parameters").await;
        assert!(
            error["message"].as_str().unwrap().contains(says),
            "{query}: {error}"
        );
    }
    let id = named["id"].as_str().unwrap();
    let listed = list_jobs(&client, &base).await;
    let entry = listed["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|j| j["id"] == id)
        .expect("the named job is listed")
        .clone();
    assert_eq!(entry["name"], "Café room.glb");
    let done = wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    assert_eq!(done["name"], "Café room.glb");
}

/// Over HTTP a texture's image is a named part of a multipart upload (never a file of the
/// server's): the job solves with it; a missing part, an image that cannot be decoded and glTF 1.0
/// are 422s that name what to fix.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_carries_its_images_as_named_parts() {
    let base = start(ServiceConfig::new(data_dir("http-textures"))).await;
    let client = client();
    let upload = |parts: &[(&str, &[u8])]| {
        let parts: Vec<(&str, &str, &str, &[u8])> = parts
            .iter()
            .map(|&(name, bytes)| (name, name, "application/octet-stream", bytes))
            .collect();
        multipart(&parts)
    };
    let (gltf, bin, png) = common::gltf::glowing_quad_gltf("2.0");
    let (content_type, body) = upload(&[("scene", &gltf), ("scene.bin", &bin), ("glow.png", &png)]);
    let response = submit(&client, &base, "order=1", &content_type, body).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    wait_for(&client, &base, id, "succeeded", Duration::from_secs(60)).await;
    let result = get_ok(&client, format!("{base}/v1/jobs/{id}/result")).await;
    let mean = result["faces"][0]["mean_radiance"][0].as_f64().unwrap();
    let glow = common::gltf::glow();
    assert!(
        (mean - glow).abs() < 1e-6,
        "emission {mean}, texture {glow}"
    );

    let (old, _, _) = common::gltf::glowing_quad_gltf("1.0");
    let not_png: &[u8] = b"GIF89a, not a PNG";
    // (parts, what the message names)
    type Refusal<'a> = (Vec<(&'a str, &'a [u8])>, &'a str);
    let refusals: [Refusal; 3] = [
        (vec![("scene", &gltf), ("scene.bin", &bin)], "glow.png"),
        (
            vec![("scene", &gltf), ("scene.bin", &bin), ("glow.png", not_png)],
            "image 0",
        ),
        (
            vec![("scene", &old), ("scene.bin", &bin), ("glow.png", &png)],
            "asset.version",
        ),
    ];
    for (parts, needle) in refusals {
        let (content_type, body) = upload(&parts);
        let response = submit(&client, &base, "order=1", &content_type, body).await;
        let error = error_of(response, StatusCode::UNPROCESSABLE_ENTITY).await;
        let message = error["message"].as_str().unwrap_or_default();
        assert!(message.contains(needle), "{needle}: {error}");
    }
}
