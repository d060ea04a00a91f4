//! `wavrad bench`: measurements of the solver's parts from the command line, for
//! `benches/README.md` and `docs/performance-notes.md`.
//!
//! Owns [`visibility`] (segment occlusion through the solver's own BVH, against a brute-force
//! count and an outside ray tracer). Invariants: a benchmark measures the code a solve runs (it
//! builds its structures with the pipeline's own functions), and its machine output is one JSON
//! line on stdout.

pub mod visibility;
