//! `wavrad bench`: measurements from the command line, for `benches/README.md`, the README's
//! chart and `docs/performance-notes.md`: [`sweep`] (issue 19: the speed-accuracy sweep over
//! tolerance x order x domain mode) and its [`chart`]; [`visibility`] (segment occlusion through
//! the solver's own BVH, against a brute-force count and an outside ray tracer).
//!
//! Invariants: a benchmark measures the code a solve runs (each sweep solve a `wavrad solve`
//! process; the visibility bench builds its BVH with the pipeline's own function) and never
//! changes a solution; machine output is one JSON line (visibility) or files (sweep). It sits
//! above `reference`, `pipeline` and `job` and below `cli` (`tests/architecture.rs`).

pub mod chart;
pub mod sweep;
pub mod sweep_report;
pub mod visibility;
