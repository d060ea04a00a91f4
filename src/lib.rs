//! wavrad: wavelet radiosity on arbitrary planar surfaces (Holzschuch, Cuny, Alonso, EGWR 2000),
//! baking diffuse lightmaps for glTF scenes.
//!
//! Modules in data-flow order; each depends only on those before it (`tests/architecture.rs`
//! enforces the order, see ARCHITECTURE.md): `scene` -> `faces` -> `domain` -> `solver` ->
//! `pipeline` -> `output` -> `job` -> `service`, `bench` -> `cli`; `reference` measures solutions
//! against Monte Carlo references and CIE cases (tests and benches); `bench` holds the benchmarks
//! the CLI runs (`wavrad bench visibility`, `wavrad bench sweep`); `shuffle` (the deterministic shuffle several stages
//! share) and `fsutil` (atomic writes) are utilities any layer may use.

// Numerical kernels index several parallel arrays (basis functions x colour channels) in one loop;
// iterator chains would hide the formulas.
#![allow(clippy::needless_range_loop)]

pub mod bench;
pub mod cli;
pub mod domain;
pub mod faces;
pub(crate) mod fsutil;
pub mod job;
pub mod output;
pub mod pipeline;
pub mod reference;
pub mod scene;
pub mod service;
pub(crate) mod shuffle;
pub mod solver;
