//! wavrad: wavelet radiosity on arbitrary planar surfaces (Holzschuch, Cuny, Alonso, EGWR 2000),
//! baking diffuse lightmaps for glTF scenes.
//!
//! Modules in data-flow order; each depends only on those before it (see ARCHITECTURE.md):
//! `scene` -> `faces` -> `domain` -> `solver` -> `output` -> `service` / `cli`.

pub mod cli;
pub mod domain;
pub mod faces;
pub mod job;
pub mod output;
pub mod pipeline;
pub mod scene;
pub mod service;
pub mod solver;
