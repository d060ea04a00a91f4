//! `/metrics`: Prometheus text exposition (format 0.0.4), every series named `wavrad_*`. Counters
//! live here as atomics, updated when a solve ends; gauges are read from the job board at scrape
//! time. Hand-written: the format is small and this keeps a dependency out.

use super::jobs::JobState;
use super::AppState;
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counters of solves that ended in this process.
#[derive(Debug, Default)]
pub struct Metrics {
    solve_micros: AtomicU64,
    solves: AtomicU64,
    shots: AtomicU64,
    rays: AtomicU64,
    elements: AtomicU64,
}

impl Metrics {
    /// Records a solve that ended (any outcome).
    pub fn record_solve(&self, seconds: f64, shots: u64, rays: u64, elements: u64) {
        let micros = (seconds.max(0.0) * 1e6).round();
        if micros.is_finite() {
            self.solve_micros
                .fetch_add(micros as u64, Ordering::Relaxed);
        }
        self.solves.fetch_add(1, Ordering::Relaxed);
        self.shots.fetch_add(shots, Ordering::Relaxed);
        self.rays.fetch_add(rays, Ordering::Relaxed);
        self.elements.fetch_add(elements, Ordering::Relaxed);
    }
}

/// The exposition text.
pub fn render(state: &AppState) -> String {
    let m = state.metrics();
    let mut out = String::with_capacity(2048);
    let mut series = |name: &str, kind: &str, help: &str, samples: &[(&str, f64)]| {
        let _ = writeln!(out, "# HELP {name} {help}");
        let _ = writeln!(out, "# TYPE {name} {kind}");
        for (labels, value) in samples {
            let _ = writeln!(out, "{name}{labels} {value}");
        }
    };
    let counts = state.jobs().count_by_state();
    let by_state: Vec<(String, f64)> = counts
        .iter()
        .map(|(s, n)| (format!("{{state=\"{}\"}}", s.as_str()), *n as f64))
        .collect();
    let by_state: Vec<(&str, f64)> = by_state.iter().map(|(l, v)| (l.as_str(), *v)).collect();
    series(
        "wavrad_jobs",
        "gauge",
        "Jobs this service knows, by state.",
        &by_state,
    );
    series(
        "wavrad_queue_depth",
        "gauge",
        "Jobs waiting for a runner.",
        &[("", state.jobs().queued() as f64)],
    );
    series(
        "wavrad_queue_capacity",
        "gauge",
        "Jobs that may wait (--max-queued); one more is refused with 429.",
        &[("", state.jobs().max_queued() as f64)],
    );
    let running: Vec<_> = state
        .jobs()
        .list()
        .into_iter()
        .filter(|j| j.state() == JobState::Running)
        .collect();
    let live_elements: u64 = running.iter().map(|j| j.status().progress.elements).sum();
    let live_shots: u64 = running.iter().map(|j| j.status().progress.iterations).sum();
    series(
        "wavrad_running_elements",
        "gauge",
        "Elements of the solves running now.",
        &[("", live_elements as f64)],
    );
    series(
        "wavrad_running_shots",
        "gauge",
        "Shots done so far by the solves running now.",
        &[("", live_shots as f64)],
    );
    series(
        "wavrad_solves_total",
        "counter",
        "Solves that ended (succeeded, cancelled, stopped or failed in the solver).",
        &[("", m.solves.load(Ordering::Relaxed) as f64)],
    );
    series(
        "wavrad_solve_seconds_total",
        "counter",
        "Seconds spent solving, over the solves that ended.",
        &[("", m.solve_micros.load(Ordering::Relaxed) as f64 / 1e6)],
    );
    series(
        "wavrad_shots_total",
        "counter",
        "Shots (iterations) of the solves that ended.",
        &[("", m.shots.load(Ordering::Relaxed) as f64)],
    );
    series(
        "wavrad_elements_total",
        "counter",
        "Elements at the end of the solves that ended.",
        &[("", m.elements.load(Ordering::Relaxed) as f64)],
    );
    series(
        "wavrad_rays_total",
        "counter",
        "Visibility rays traced by the solves that succeeded.",
        &[("", m.rays.load(Ordering::Relaxed) as f64)],
    );
    if let Some(cluster) = state.cluster() {
        // Per replica: what this replica did; the job gauges above count this replica's
        // board, which stays empty in cluster mode (the jobs are in the database).
        let c = &cluster.counters;
        series(
            "wavrad_cluster_claims_total",
            "counter",
            "Jobs this replica claimed from the database (each claim is an attempt).",
            &[("", c.claims.load(Ordering::Relaxed) as f64)],
        );
        series(
            "wavrad_cluster_lost_leases_total",
            "counter",
            "Attempts of this replica fenced out by a newer attempt (outputs discarded).",
            &[("", c.lost_leases.load(Ordering::Relaxed) as f64)],
        );
        series(
            "wavrad_cluster_cancels_total",
            "counter",
            "Cancel requests this replica's heartbeat turned into a stop.",
            &[("", c.cancels_seen.load(Ordering::Relaxed) as f64)],
        );
        series(
            "wavrad_cluster_running",
            "gauge",
            "Solves running on this replica now.",
            &[("", state.active_solves() as f64)],
        );
    }
    out
}
