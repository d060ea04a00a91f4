//! What `wavrad bench sweep` reports (`sweep.rs` runs the solves): a solve's [`Row`], its CSV and
//! table lines, the chart's data per scene ([`scene_plot`]), the time to reach an error
//! ([`time_to_reach`]) and the extended-to-tessellated [`Ratio`] ([`mode_ratio`]), the closing
//! [`summary`].
//!
//! Invariants: a capped row (stopped before converging) is in the CSV but in no curve and no
//! ratio; a ratio is taken at the tightest error both modes reach, on each curve's lower
//! envelope. Pinned by this file's unit tests and `tests/bench_sweep.rs`.

use super::chart::{Curve, ScenePlot};
use super::sweep::{MODES, ORDERS};
use std::fmt::Write as _;

/// One solve of the sweep.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub order: usize,
    pub domain: String,
    pub tolerance: f64,
    /// The solve alone (result.json `stats.seconds`).
    pub seconds: f64,
    /// The whole process: loading, preparation, solve and export.
    pub wall_seconds: f64,
    /// The process's CPU time (user + system, all threads; [`super::sweep::children_cpu_seconds`]); `NaN` when
    /// unknown (a run of an older sweep read back by `--resume`).
    pub cpu_seconds: f64,
    pub shots: u64,
    pub elements: u64,
    pub links: u64,
    pub peak_memory_bytes: u64,
    pub rays: u64,
    pub unshot_ratio: f64,
    pub stop_reason: String,
    pub extended_faces: u64,
    /// `NaN` when a probe found no surface.
    pub nrms: f64,
    pub worst: f64,
    pub worst_label: String,
    /// `(seconds, unshot_ratio)` per shot, from convergence.csv.
    pub convergence: Vec<(f64, f64)>,
}

impl Row {
    /// Stopped by the per-solve cap.
    pub fn capped(&self) -> bool {
        self.stop_reason != "converged"
    }
}

/// The extended-to-tessellated time ratio of one scene and order at the tightest error both
/// modes reach.
#[derive(Debug, Clone, PartialEq)]
pub struct Ratio {
    pub scene: String,
    pub order: usize,
    pub extended_faces: u64,
    pub error: f64,
    pub extended_seconds: f64,
    pub tessellated_seconds: f64,
}

impl Ratio {
    pub fn ratio(&self) -> f64 {
        self.extended_seconds / self.tessellated_seconds
    }
}

/// What a sweep did.
#[derive(Debug, Clone, Default)]
pub struct Report {
    pub rows: Vec<Row>,
    pub left_out: Vec<String>,
    pub ratios: Vec<Ratio>,
    /// The sweep's wall seconds, from its start to its chart.
    pub wall_seconds: f64,
    /// The CPU seconds of the sweep's own process and of every solve in `rows` (those read back
    /// by `--resume` too): what the grid takes at most on an idle machine
    /// ([`super::sweep::children_cpu_seconds`]).
    pub cpu_seconds: f64,
    /// Rows whose CPU time is unknown (read back from an older sweep), left out of `cpu_seconds`.
    pub cpu_unknown: usize,
}

/// The CSV columns, in order.
pub const CSV_HEADER: &str = "scene,order,domain,tolerance,seconds,wall_seconds,shots,elements,links,peak_memory_bytes,rays,unshot_ratio,stop_reason,extended_faces,nrms,worst_point,worst_label,cpu_seconds";

/// The time a curve of `(seconds, error)` points first reaches `error`, interpolated linearly in
/// log-log between the two solves around it, on the curve's lower envelope (the best error reached
/// by each time); the first solve's time when it is already there; `None` when it never is.
pub fn time_to_reach(points: &[(f64, f64)], error: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|&(t, e)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<(f64, f64)> = None;
    for (t, e) in pts {
        match best {
            None if e <= error => return Some(t),
            None => best = Some((t, e)),
            Some((t0, e0)) if e <= error => {
                let f = (error.ln() - e0.ln()) / (e.ln() - e0.ln());
                return Some((t0.ln() + f * (t.ln() - t0.ln())).exp());
            }
            Some((_, e0)) if e < e0 => best = Some((t, e)),
            Some(_) => {}
        }
    }
    None
}

/// The ratio of extended to tessellated time to reach the tightest error both curves reach
/// (`(seconds, error)` points each); `None` when either is empty.
pub fn mode_ratio(extended: &[(f64, f64)], tessellated: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let min = |c: &[(f64, f64)]| {
        c.iter()
            .map(|p| p.1)
            .filter(|e| e.is_finite() && *e > 0.0)
            .fold(f64::INFINITY, f64::min)
    };
    let error = min(extended).max(min(tessellated));
    if !error.is_finite() {
        return None;
    }
    Some((
        error,
        time_to_reach(extended, error)?,
        time_to_reach(tessellated, error)?,
    ))
}

/// The data set a SCENE argument names.
/// One CSV line (no newline).
pub fn csv_line(r: &Row) -> String {
    format!(
        "{},{},{},{:e},{:.4},{:.3},{},{},{},{},{},{:e},{},{},{:.6},{:.6},{},{:.3}",
        r.scene,
        r.order,
        r.domain,
        r.tolerance,
        r.seconds,
        r.wall_seconds,
        r.shots,
        r.elements,
        r.links,
        r.peak_memory_bytes,
        r.rays,
        r.unshot_ratio,
        r.stop_reason,
        r.extended_faces,
        r.nrms,
        r.worst,
        r.worst_label.replace(',', ";"),
        r.cpu_seconds,
    )
}

/// The table line printed as each solve finishes.
pub fn table_line(r: &Row) -> String {
    format!(
        "{:<28} M{} {:<11} {:>7.0e} {:>8.2} s {:>8} el {:>6} MB  nrms {:>6.2} %  worst {:>6.2} % ({}){}",
        r.scene,
        r.order,
        r.domain,
        r.tolerance,
        r.seconds,
        r.elements,
        r.peak_memory_bytes / 1_000_000,
        r.nrms * 100.0,
        r.worst * 100.0,
        r.worst_label,
        if r.capped() {
            format!("  [{}]", r.stop_reason)
        } else {
            String::new()
        }
    )
}

fn curve_label(order: usize, domain: &str) -> String {
    format!("M{order} {domain}")
}

/// The tolerance of a scene's convergence panel: the one nearest the solver's default (in log)
/// among those that the most modes solved within the cap, at order 2 when it ran (else the lowest
/// order run).
fn convergence_pick(rows: &[&Row]) -> Option<(usize, f64)> {
    let order = if rows.iter().any(|r| r.order == 2) {
        2
    } else {
        rows.iter().map(|r| r.order).min()?
    };
    let default = crate::solver::DEFAULT_TOLERANCE.ln();
    let modes = |t: f64| {
        rows.iter()
            .filter(|r| r.order == order && r.tolerance == t && !r.capped())
            .count()
    };
    let most = rows.iter().map(|r| modes(r.tolerance)).max()?;
    rows.iter()
        .filter(|r| r.order == order && !r.capped() && !r.convergence.is_empty())
        .filter(|r| modes(r.tolerance) == most)
        .map(|r| r.tolerance)
        .min_by(|a, b| {
            (a.ln() - default)
                .abs()
                .total_cmp(&(b.ln() - default).abs())
        })
        .map(|t| (order, t))
}

/// The chart's data for one scene.
pub(super) fn scene_plot(name: &str, rows: &[&Row]) -> ScenePlot {
    let mut error = Vec::new();
    for order in ORDERS {
        for domain in MODES {
            let points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.order == order && r.domain == domain && !r.capped())
                .map(|r| (r.seconds, r.nrms * 100.0))
                .collect();
            if !points.is_empty() {
                error.push(Curve {
                    label: curve_label(order, domain),
                    order,
                    extended: domain == "extended",
                    points,
                });
            }
        }
    }
    let (mut convergence, mut convergence_tolerance) = (Vec::new(), f64::NAN);
    if let Some((order, tolerance)) = convergence_pick(rows) {
        convergence_tolerance = tolerance;
        for r in rows
            .iter()
            .filter(|r| r.order == order && r.tolerance == tolerance)
        {
            convergence.push(Curve {
                label: curve_label(order, &r.domain),
                order,
                extended: r.domain == "extended",
                points: r.convergence.clone(),
            });
        }
    }
    ScenePlot {
        name: name.to_string(),
        error,
        convergence,
        convergence_tolerance,
    }
}

pub(super) fn ratios_of(name: &str, rows: &[&Row]) -> Vec<Ratio> {
    let curve = |order: usize, domain: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| r.order == order && r.domain == domain && !r.capped())
            .map(|r| (r.seconds, r.nrms))
            .collect()
    };
    let extended_faces = rows.iter().map(|r| r.extended_faces).max().unwrap_or(0);
    ORDERS
        .iter()
        .filter_map(|&order| {
            let (error, extended_seconds, tessellated_seconds) =
                mode_ratio(&curve(order, "extended"), &curve(order, "tessellated"))?;
            Some(Ratio {
                scene: name.to_string(),
                order,
                extended_faces,
                error,
                extended_seconds,
                tessellated_seconds,
            })
        })
        .collect()
}

/// The closing summary: the ratios and what was left out.
pub fn summary(report: &Report) -> String {
    let mut s = format!(
        "sweep: {} solves, {:.0} s wall, {:.0} s CPU (the sweep's process and its solves; on an \
         idle machine the sweep takes at most its CPU time){}\n",
        report.rows.len(),
        report.wall_seconds,
        report.cpu_seconds,
        if report.cpu_unknown > 0 {
            format!("; CPU time unknown for {} solves", report.cpu_unknown)
        } else {
            String::new()
        }
    );
    for r in &report.ratios {
        let _ = writeln!(
            s,
            "{} M{}: extended / tessellated time to {:.2} % nrms = {:.2} s / {:.2} s = {:.2}{}",
            r.scene,
            r.order,
            r.error * 100.0,
            r.extended_seconds,
            r.tessellated_seconds,
            r.ratio(),
            if r.extended_faces == 0 {
                " (no extended face: both modes solve the same roots)"
            } else {
                ""
            }
        );
    }
    if report.left_out.is_empty() {
        s += "left out: nothing\n";
    } else {
        s += "left out:\n";
        for l in &report.left_out {
            let _ = writeln!(s, "  {l}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_to_reach_interpolates_in_log_log_on_the_lower_envelope() {
        // Error 10 % at 1 s, 1 % at 100 s: 1e-1.5 is reached half way in log time, at 10 s.
        let t = time_to_reach(&[(1.0, 0.1), (100.0, 0.01)], 0.1f64.powf(1.5)).expect("reached");
        assert!((t - 10.0).abs() < 1e-9, "{t}");
        // Already reached by the first solve.
        assert_eq!(time_to_reach(&[(2.0, 0.01), (5.0, 0.001)], 0.05), Some(2.0));
        // Never reached.
        assert_eq!(time_to_reach(&[(2.0, 0.01), (5.0, 0.02)], 0.005), None);
        // A worse later solve does not set the envelope: interpolation starts from the best one.
        let t = time_to_reach(&[(1.0, 0.1), (2.0, 0.2), (100.0, 0.001)], 0.01).expect("reached");
        assert!((t - 10.0).abs() < 1e-9, "{t}");
    }

    #[test]
    fn mode_ratio_is_taken_at_the_tightest_error_both_reach() {
        let extended = [(1.0, 0.1), (10.0, 0.01)];
        let tessellated = [(2.0, 0.1), (20.0, 0.02)];
        let (error, te, tt) = mode_ratio(&extended, &tessellated).expect("both reach 2 %");
        assert_eq!(error, 0.02);
        assert!((tt - 20.0).abs() < 1e-9, "{tt}");
        assert!(te < 10.0 && te > 1.0);
        assert_eq!(mode_ratio(&extended, &[]), None);
    }
}
