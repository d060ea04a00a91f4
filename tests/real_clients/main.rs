//! Checks driven by real clients: the Khronos glTF-Validator on baked scenes (`gltf_validator`) and
//! headless Chromium on the dashboard (`dashboard`). Without the clients they skip with a printed
//! reason; `.ci/run` installs them and runs this target with `WAVRAD_REQUIRE_CLIENTS=1`.

#[path = "../common/mod.rs"]
mod common;

mod dashboard;
mod gltf_validator;
