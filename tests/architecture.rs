//! Checks on the code's shape (ARCHITECTURE.md): every source file opens with a `//!` header, and
//! dependencies point one way along the data flow (the solver knows no glTF, HTTP, serde or tokio).

use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn every_source_file_has_a_module_header() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    assert!(files.len() > 10);
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        assert!(
            text.starts_with("//!"),
            "{} must open with a //! header saying what it owns",
            f.display()
        );
    }
}

#[test]
fn dependencies_point_along_the_data_flow() {
    // (module directory or file, names it must not mention)
    let rules: &[(&str, &[&str])] = &[
        (
            "scene",
            &[
                "crate::faces",
                "crate::domain",
                "crate::solver",
                "crate::output",
                "crate::service",
                "crate::cli",
                "crate::job",
            ],
        ),
        (
            "faces",
            &[
                "crate::domain",
                "crate::solver",
                "crate::output",
                "crate::service",
                "gltf::",
            ],
        ),
        (
            "domain",
            &["crate::solver", "crate::output", "crate::service", "gltf::"],
        ),
        (
            "solver",
            &[
                "crate::scene::load",
                "crate::faces",
                "crate::output",
                "crate::service",
                "crate::job",
                "gltf::",
                "serde",
                "tokio",
                "axum",
            ],
        ),
        ("output", &["crate::service", "tokio", "axum"]),
    ];
    for (module, forbidden) in rules {
        let path = src().join(module);
        let mut files = Vec::new();
        if path.is_dir() {
            rust_files(&path, &mut files);
        } else {
            files.push(path);
        }
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for word in *forbidden {
                assert!(
                    !text.contains(word),
                    "{} mentions {word}: dependencies must point along the data flow",
                    f.display()
                );
            }
        }
    }
}
