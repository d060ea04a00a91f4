//! Checks driven by real clients: the Khronos glTF-Validator on baked scenes (`gltf_validator`),
//! headless Chromium on the dashboard (`dashboard`) and on its 3-D view of a bake (`viewer`);
//! cluster mode against a temporary PostgreSQL and SeaweedFS with `wavrad` replicas (`cluster`).
//! Without the clients they skip with a printed reason; `.ci/run` installs them and runs this
//! target with `WAVRAD_REQUIRE_CLIENTS=1`.

#[path = "../common/mod.rs"]
mod common;

mod cluster;
mod dashboard;
mod gltf_validator;
mod viewer;
