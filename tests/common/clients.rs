//! Real clients the checks drive: Node.js tools installed under `tests/js/node_modules` (the
//! Khronos glTF-Validator, `playwright-core`, three.js) and Debian's Chromium.
//!
//! In a plain `cargo test` a missing tool makes the test print why it skipped and return; `.ci/run`
//! installs them and sets `WAVRAD_REQUIRE_CLIENTS=1`, which turns a skip into a failure.

use std::path::{Path, PathBuf};

/// `tests/js`, where `package.json` names the Node.js tools.
pub fn js_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/js")
}

/// True when `.ci/run` asked for every client to be present.
pub fn required() -> bool {
    std::env::var_os("WAVRAD_REQUIRE_CLIENTS").is_some_and(|v| v == "1")
}

/// Skips the calling test with `reason` (printed), or fails it when clients are required.
pub fn skip(test: &str, reason: &str) {
    if required() {
        panic!("{test}: {reason} (WAVRAD_REQUIRE_CLIENTS=1: .ci/run installs it)");
    }
    eprintln!("SKIPPED {test}: {reason}; `.ci/run` installs it (or `cd tests/js && npm ci`)");
}

/// `node` on the PATH.
pub fn node() -> Option<PathBuf> {
    which("node")
}

/// An installed npm package's directory under `tests/js/node_modules`.
pub fn npm_package(name: &str) -> Option<PathBuf> {
    let dir = js_dir().join("node_modules").join(name);
    dir.join("package.json").is_file().then_some(dir)
}

/// Debian's Chromium (`WAVRAD_CHROMIUM` overrides the path).
pub fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("WAVRAD_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    which("chromium").or_else(|| which("chromium-browser"))
}

fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|p| p.is_file())
}
