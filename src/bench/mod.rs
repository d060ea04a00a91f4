//! Benchmarks run from the command line (`wavrad bench ...`): `sweep` (issue 19), the
//! speed-accuracy sweep over tolerance x order x domain mode and its chart (`chart`).
//!
//! Invariants: a benchmark measures the solver through its public entry points (here, each solve a
//! `wavrad solve` process) and never changes a solution; it sits above `reference` and `job` and
//! below `cli` (`tests/architecture.rs`).

pub mod chart;
pub mod sweep;
