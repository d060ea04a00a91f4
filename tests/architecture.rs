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

/// The crate's modules in data-flow order: a module may use those of lower rank (and its own),
/// never one of equal or higher rank. `shuffle` and `fsutil` are leaf utilities anyone may use.
const LAYERS: &[(&str, u32)] = &[
    ("shuffle", 0),
    ("fsutil", 0),
    ("scene", 1),
    ("faces", 2),
    ("domain", 3),
    ("solver", 4),
    ("pipeline", 5),
    ("output", 6),
    ("reference", 7),
    ("job", 7),
    ("service", 8),
    ("bench", 8),
    ("cli", 9),
];

/// How many modules below the crate root the file `path` is (`src/job.rs` and
/// `src/output/mod.rs` 1, `src/output/probes.rs` 2).
fn module_depth(path: &Path) -> usize {
    let rel = path.strip_prefix(src()).expect("a file under src");
    let parts = rel.components().count();
    if rel.file_stem().is_some_and(|s| s == "mod") {
        parts - 1
    } else {
        parts
    }
}

fn rank(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, r)| r)
}

fn identifier(text: &str) -> String {
    text.chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

/// The first segments of the paths after `prefix` at the start of `text`: one name for
/// `job::X`, every name for a group `{job::X, solver::{Y, Z}}`.
fn first_segments(text: &str) -> Vec<String> {
    let text = text.trim_start();
    let Some(group) = text.strip_prefix('{') else {
        return vec![identifier(text)];
    };
    let (mut names, mut depth, mut expect_name) = (Vec::new(), 1, true);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 1 => break,
            '}' => depth -= 1,
            ',' if depth == 1 => expect_name = true,
            c if expect_name && depth == 1 && !c.is_whitespace() => {
                names.push(identifier(&group[i..]));
                expect_name = false;
            }
            _ => {}
        }
    }
    names
}

/// The crate modules that `text`, a file `depth` modules below the crate root in module
/// `module`, names through `crate::...` (single or grouped) or through a `super::` chain that
/// climbs to the crate root, and that run back up the data flow or sideways into a module of the
/// same rank. (A chain that stops below the root names a sibling, which is not checked.)
fn imports_against_the_flow(module: &str, depth: usize, text: &str) -> Vec<String> {
    let own = rank(module).expect("module listed in LAYERS");
    let mut names = Vec::new();
    for (at, _) in text.match_indices("crate::") {
        names.extend(first_segments(&text[at + "crate::".len()..]));
    }
    let mut rest = text;
    while let Some(at) = rest.find("super::") {
        // A whole chain, counted once: skip a `super::` that continues one.
        let before = &rest[..at];
        let mut chain = 0;
        let mut after = &rest[at..];
        while let Some(next) = after.strip_prefix("super::") {
            chain += 1;
            after = next;
        }
        if !before.ends_with("super::") && chain >= depth {
            names.extend(
                first_segments(after)
                    .into_iter()
                    .filter(|n| rank(n).is_some()),
            );
        }
        rest = after;
    }
    let mut out = Vec::new();
    for name in names {
        if name == module || name == "self" {
            continue;
        }
        // An unknown name is an error too: a new module must take its place in LAYERS.
        let allowed = rank(&name).is_some_and(|r| r < own || (r == 0 && own > 0));
        if !allowed && !out.contains(&name) {
            out.push(name);
        }
    }
    out
}

#[test]
fn the_layer_check_catches_an_import_that_runs_back_up() {
    let check = imports_against_the_flow;
    assert_eq!(
        check(
            "output",
            1,
            "use crate::job::JobParams;\nuse crate::solver::Solution;"
        ),
        ["job"]
    );
    assert_eq!(
        check("solver", 2, "let x = crate::pipeline::prepare(s);"),
        ["pipeline"]
    );
    assert_eq!(
        check(
            "job",
            1,
            "use crate::reference::x; use crate::fsutil::write_atomic;"
        ),
        ["reference"]
    );
    // Grouped imports: every group member is checked.
    assert_eq!(
        check(
            "output",
            2,
            "use crate::{\n    scene::Scene,\n    service::{a, b},\n};"
        ),
        ["service"]
    );
    // `super::` chains that climb to the crate root are crate paths.
    assert_eq!(check("output", 1, "use super::job::JobParams;"), ["job"]);
    assert_eq!(
        check("service", 3, "use super::super::super::cli::Cli;"),
        ["cli"]
    );
    assert_eq!(
        check("output", 2, "use super::super::{job::X, scene::Y};"),
        ["job"]
    );
    // Downward imports and siblings below the root pass.
    assert!(check(
        "service",
        1,
        "use crate::job::JobParams; use crate::{scene::Scene, solver::Solution};"
    )
    .is_empty());
    assert!(check(
        "service",
        3,
        "use super::super::jobs::Job; use super::outputs::get_file;"
    )
    .is_empty());
}

#[test]
fn every_module_of_the_crate_has_a_layer() {
    for entry in std::fs::read_dir(src()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if name == "lib" || name == "main" {
            continue;
        }
        assert!(
            rank(&name).is_some(),
            "src/{name} has no place in tests/architecture.rs LAYERS"
        );
    }
}

#[test]
fn crate_modules_depend_only_on_earlier_layers() {
    for &(module, _) in LAYERS {
        let dir = src().join(module);
        let mut files = Vec::new();
        if dir.is_dir() {
            rust_files(&dir, &mut files);
        } else {
            files.push(dir.with_extension("rs"));
        }
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            let wrong = imports_against_the_flow(module, module_depth(&f), &text);
            assert!(
                wrong.is_empty(),
                "{} uses {wrong:?}: a module may only use modules before it in the data flow",
                f.display()
            );
        }
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
        ("output", &["tokio", "axum"]),
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

/// The documents the code cites live in the repository (`docs/`): no source file, README or
/// ARCHITECTURE.md line points at design pages outside it.
#[test]
fn citations_point_into_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files.push(root.join("README.md"));
    files.push(root.join("ARCHITECTURE.md"));
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        for (n, line) in text.lines().enumerate() {
            for cited in [
                "shared/design",
                "DESIGN.md",
                "CONTRACT.md",
                "STYLE.md",
                "CONTRACT ",
            ] {
                assert!(
                    !line.contains(cited),
                    "{}:{}: cites {cited}; cite docs/contract.md or docs/design.md",
                    f.display(),
                    n + 1
                );
            }
        }
    }
    for doc in ["docs/contract.md", "docs/design.md"] {
        assert!(root.join(doc).is_file(), "{doc} is cited and must exist");
    }
}
