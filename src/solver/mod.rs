//! The solver: hierarchical multi-wavelet radiosity by progressive shooting.
//!
//! Owns the element hierarchies of every root, the transfer of light between elements (quadrature
//! with the exact point-to-polygon form factor for the constant part, visibility by rays), the
//! refinement oracle and the shooting loop. It does no I/O and knows neither glTF nor HTTP.
//!
//! Shooting (docs/design.md section 5.1): emitters first shoot their emission (the "direct"
//! shots, recorded apart so `--indirect-only` can leave them out); then the root with the most
//! unshot power shoots, in a pass with roots of at least half its power that face none of the
//! pass's others, until `unshot_ratio = unshot power / direct power received <= target`. Links
//! are not cached: each transfer is recomputed when its source shoots again (memory stays
//! proportional to elements); only what depends on geometry alone, what their shadow rays said
//! and a near link's form factors, is kept between a root's shots, each within a fixed budget:
//! a far link's verdict per pair of roots, two bits each (`far_verdicts.rs`,
//! [`FAR_VERDICT_BYTES`]), and a near link's ray masks and its points' form factors per pair of
//! source element and receiver node (`near_verdicts.rs`, [`NEAR_VERDICT_BYTES`]). Receivers of
//! one pass are processed in parallel (rayon); the shooters are read-only during it, and refined
//! only virtually (sub-elements computed by push, not stored).

pub(crate) mod basis;
pub(crate) mod cover;
mod element;
mod element_source;
mod eta;
mod far_field;
mod far_verdicts;
mod forecast_inputs;
mod front_map;
pub(crate) mod hierarchy;
mod indirect_forecast;
pub mod kernel;
pub(crate) mod lights;
mod near_verdicts;
pub(crate) mod node_reflectance;
mod node_sums;
mod oracle;
mod pass;
mod progress;
pub(crate) mod quadrature;
mod refine;
mod rules;
mod shooting;
mod shot_record;
mod solution;
mod source;
mod striped_count;
mod transfer;
mod unoccluded;
pub(crate) mod visibility;

pub use shooting::solve;
pub use solution::Solution;

use crate::scene::Rgb;

/// What lightmaps and probes hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// `L = B / pi`, emission included.
    Radiance,
    /// `H / pi`, emission not included.
    Irradiance,
}

/// Default refinement tolerance: a transfer is refined while its estimated error exceeds this
/// fraction of the scene's emitted power. Chosen against the Monte Carlo references
/// (`tests/reference.rs`, README): at M2, 2e-6 takes the Red Eclipse level from 5.6 % (1e-5) to
/// 2.85 % and the Kenney building from 5.9 % to 3.5 %, at 2-4x the time; 1e-6 gains little more
/// on the building (3.2 %) for twice the time again (measured with the node-sum check after
/// direct shots only; after every shot, the default gives 2.64 % and 3.29 %).
pub const DEFAULT_TOLERANCE: f64 = 2e-6;
/// Deepest subdivision of an element (4^depth sub-elements at most).
pub const MAX_DEPTH: u8 = 9;
/// Elements are not split below this edge length, relative to the scene diagonal.
pub const MIN_EDGE_REL: f64 = 1e-3;
/// In a direct shot, a receiver node whose links' sum deviates from its projection by more than
/// this fraction of the sum's brightest point is judged against a threshold down to
/// [`DIRECT_DETAIL_TIGHTENING`] times lower (`node_sums.rs`): sharp shadow limits are refined
/// where they fall, without a lower tolerance everywhere.
pub const DETAIL_REL: f64 = 0.01;
/// How much lower than the tolerance's threshold the detail of direct light may be refined to.
pub const DIRECT_DETAIL_TIGHTENING: f64 = 4.0;
/// What the far links' shadow-ray verdicts may take by default (`far_verdicts.rs`): two bits per
/// pair of shooter and receiver roots, so a level of 40 000 roots keeps the tables of some 26 000
/// shooters; beyond it a shooter traces its far links every shot. Counted in
/// `job::estimated_memory_bytes`.
pub const FAR_VERDICT_BYTES: usize = 256 << 20;
/// What the near links' kept shadow-ray verdicts may take by default (`near_verdicts.rs`): one
/// entry per link a receiver root took from an indirect shot (its points' form factors and ray
/// masks: 8 bytes a point, 16 where some point's rays disagree among themselves); beyond it
/// links trace every shot. Counted in `job::estimated_memory_bytes`.
pub const NEAR_VERDICT_BYTES: usize = 1 << 30;
/// Safety limit on shots (a closed scene of rho = 1 never converges).
pub const DEFAULT_MAX_ITERATIONS: u64 = 1_000_000;
/// Stack of each thread of a pool that solves: a thread waiting for a stolen piece of a direct
/// shot's evaluations (`refine.rs`, `transfer_all`) may run other receivers' recursions on top of
/// its own (rayon's work stealing), so it needs more than a thread's default 2 MiB (reserved,
/// not committed, until used).
pub const SOLVER_STACK_BYTES: usize = 64 << 20;

/// Solver settings (the solver options of docs/contract.md that reach the solver).
#[derive(Debug, Clone)]
pub struct SolverParams {
    pub order: usize,
    pub target_unshot: f64,
    pub tolerance: f64,
    pub max_seconds: Option<f64>,
    pub quantity: Quantity,
    pub indirect_only: bool,
    pub max_iterations: u64,
    /// After each shot, judge every receiver node on the sum of the links it gathered and
    /// refine where that sum is not represented within the tolerance (`refine_by_node_sums`).
    /// On by default; off gives the per-link oracle alone (`tests/solver.rs` compares both).
    pub node_sums: bool,
    /// Bytes the far links' shadow-ray verdicts may keep between a root's shots
    /// (`far_verdicts.rs`); 0 traces every far link's ray every shot (the same solve, more rays).
    pub far_verdict_bytes: usize,
    /// Bytes the near links' shadow-ray verdicts may keep between a root's shots
    /// (`near_verdicts.rs`); 0 traces every near link's rays every shot (the same solve, more
    /// rays).
    pub near_verdict_bytes: usize,
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            order: 2,
            target_unshot: 1e-3,
            tolerance: DEFAULT_TOLERANCE,
            max_seconds: None,
            quantity: Quantity::Radiance,
            indirect_only: false,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            node_sums: true,
            far_verdict_bytes: FAR_VERDICT_BYTES,
            near_verdict_bytes: NEAR_VERDICT_BYTES,
        }
    }
}

/// Why the shooting loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    Converged,
    TimeBudget,
    Cancelled,
    IterationLimit,
}

impl StopReason {
    pub fn as_str(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::TimeBudget => "time_budget",
            StopReason::Cancelled => "cancelled",
            StopReason::IterationLimit => "iteration_limit",
        }
    }
}

/// Progress of the solve (feeds the CLI bar, convergence.csv and the HTTP progress object).
///
/// Reported after every pass of shots (those reports, one row per shot of the pass, are the
/// solution's `convergence`) and, during a pass that lasts longer than [`REPORT_INTERVAL`],
/// every `REPORT_INTERVAL` from within it (`tests/progress.rs`,
/// `progress_moves_within_a_long_shot`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Shots finished (lights' shots included).
    pub iterations: u64,
    /// Unshot power / emitted power after the last finished shot (1 before the first).
    pub unshot_ratio: f64,
    /// Leaf elements after the last finished shot.
    pub elements: u64,
    /// Links accepted so far, far links included (counted during shots too).
    pub links: u64,
    /// Seconds of solving so far.
    pub seconds: f64,
    /// Receiver roots the pass in progress has finished, of `shot_receivers`.
    pub shot_receivers_done: u64,
    /// Receiver roots the pass in progress visits (those facing any of its shooters); 0 between
    /// passes.
    pub shot_receivers: u64,
    /// Estimated seconds until the solve ends: the target reached, or the time budget spent
    /// (`eta::EtaEstimator`); `None` until it can be estimated.
    pub eta_seconds: Option<f64>,
}

/// How often a long shot reports its progress from within.
pub const REPORT_INTERVAL: std::time::Duration = std::time::Duration::from_millis(500);

/// Counters of rare numerical fallbacks and work done.
#[derive(Debug, Clone, Default)]
pub struct SolveStats {
    pub iterations: u64,
    pub links: u64,
    pub elements: u64,
    pub rays: u64,
    pub seconds: f64,
    pub unshot_ratio: f64,
    pub emitted_power: Rgb,
    pub stop_reason: Option<StopReason>,
    /// Transfers accepted above tolerance because neither side could be split further.
    pub refinement_capped: u64,
    /// Receiver points where no source quadrature point lay in front of the receiver (touching
    /// elements) and the rule could not be carried onto the source's part in front (a partly
    /// covered source, or no front point exchanging light): the exact form factor times the
    /// visible fraction stood in for the quadrature.
    pub touching_fallbacks: u64,
    /// Receiver nodes that gave links back to their children after a shot, because the
    /// sum of their links was not represented within the tolerance (`SolverParams::node_sums`).
    pub node_sum_splits: u64,
    /// Bytes the element hierarchies hold at the end of the solve (node entries, the coefficient
    /// arrays `h`, `hd`, `u`, `dh` and the side tables, as allocated: `Hierarchy::bytes`), per
    /// element (leaf).
    pub bytes_per_element: f64,
    /// The node-sum check's per-link entries at their largest in one receiver's record during
    /// one shot (source path, deviation and coefficients, as allocated), per link that record
    /// held then; 0 when no link was recorded. Links are kept only within a shot, and what they
    /// delivered at points is kept per node (`shot_record.rs`).
    pub bytes_per_link: f64,
}

/// The sum of a colour's channels (the scalar that powers and errors are compared by).
fn mean_rgb_sum(c: Rgb) -> f64 {
    c[0] + c[1] + c[2]
}
