//! Fuzz target: the scene import path the service runs on every upload (container checks, glTF
//! parsing, buffers, node graph, primitives) and the solvability check. Any panic is a crash,
//! even one `load_scene`'s own `catch_unwind` would turn into an error: libFuzzer's panic hook
//! aborts first.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::collections::HashMap;
use wavrad::scene::{load_scene, ExternalFiles};

fuzz_target!(|data: &[u8]| {
    // As over HTTP: external URIs refused.
    if let Ok(scene) = load_scene(data, &ExternalFiles::Refuse, 100_000) {
        let _ = wavrad::pipeline::check_solvable(&scene);
    }
    // As a multipart upload with one named part, so URI resolution by name is exercised too.
    let mut parts = HashMap::new();
    parts.insert("a.bin".to_string(), data.get(..64).unwrap_or(data).to_vec());
    let _ = load_scene(data, &ExternalFiles::Named(parts), 100_000);
});
