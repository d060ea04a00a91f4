//! Progress that moves: the solver reports from within a long shot (receivers done, at least
//! once a second, on the caller's thread, with an ETA), only the reports between shots are
//! convergence rows, and `wavrad solve` logs a `progress` event a benchmark can parse. The
//! service's side is in `tests/http_observe.rs`.

use serde_json::Value;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use wavrad::domain::DomainMode;
use wavrad::pipeline::bake;
use wavrad::scene::{load_scene, ExternalFiles};
use wavrad::solver::{Progress, SolverParams, StopReason, REPORT_INTERVAL};

mod common;
use common::cli::wavrad;
use common::scenes::{cluttered_scene, long_first_shot};

/// A first shot that lasts seconds (a lamp wall onto a cluttered room at a fine tolerance):
/// while it runs, `observe` is called from the caller's thread at least once a second with the
/// receivers done moving and no shot finished; the solve is cancelled from `observe` once that
/// is seen. The convergence rows are the reports between shots only.
#[test]
fn progress_moves_within_a_long_shot() {
    let scene = load_scene(&long_first_shot(), &ExternalFiles::Refuse, 1_000_000).unwrap();
    let (params, _) = long_first_shot_params();
    let cancel = AtomicBool::new(false);
    let caller = std::thread::current().id();
    let start = Instant::now();
    let mut reports: Vec<(Duration, Progress)> = Vec::new();
    let (_, solution) = bake(&scene, DomainMode::Extended, params, &cancel, &mut |p| {
        assert_eq!(
            std::thread::current().id(),
            caller,
            "observe stays on the caller's thread"
        );
        reports.push((start.elapsed(), *p));
        let within: Vec<u64> = reports
            .iter()
            .filter(|r| r.1.shot_receivers > 0)
            .map(|r| r.1.shot_receivers_done)
            .collect();
        // Seen moving (or given up on: the assertions below then fail).
        if within.len() >= 3 && within.last() > within.first() || within.len() >= 120 {
            cancel.store(true, Ordering::Relaxed);
        }
    })
    .unwrap();
    let within: Vec<&(Duration, Progress)> =
        reports.iter().filter(|r| r.1.shot_receivers > 0).collect();
    for r in &reports {
        println!(
            "{:>6.2} s  shot {} ({}/{})  eta {:?}",
            r.0.as_secs_f64(),
            r.1.iterations,
            r.1.shot_receivers_done,
            r.1.shot_receivers,
            r.1.eta_seconds
        );
    }
    assert!(within.len() >= 3, "reports from within the first shot");
    assert!(
        within.iter().all(|r| r.1.iterations == 0),
        "all within the first shot"
    );
    let receivers = within[0].1.shot_receivers;
    assert!(within.iter().all(|r| r.1.shot_receivers == receivers));
    let done: Vec<u64> = within.iter().map(|r| r.1.shot_receivers_done).collect();
    assert!(done.windows(2).all(|w| w[0] <= w[1]), "{done:?}");
    assert!(done.last() > done.first(), "receivers done move: {done:?}");
    assert!(done.iter().all(|&d| d <= receivers));
    // At least once a second (every REPORT_INTERVAL, with room for a loaded machine).
    for w in reports.windows(2) {
        let gap = w[1].0 - w[0].0;
        assert!(gap < Duration::from_secs(1), "{gap:?}");
        if w[0].1.shot_receivers > 0 && w[1].1.shot_receivers > 0 {
            assert!(
                gap >= REPORT_INTERVAL / 2,
                "no faster than REPORT_INTERVAL: {gap:?}"
            );
        }
    }
    assert!(
        within
            .iter()
            .all(|r| r.1.eta_seconds.is_some_and(|e| e > 0.0)),
        "an ETA during the first shot"
    );
    assert!(!solution.convergence.is_empty());
    assert!(
        solution.convergence.iter().all(|p| p.shot_receivers == 0),
        "convergence rows are the reports between shots"
    );
}

/// A time budget that ends within a long shot stops the solve there (receivers not yet reached
/// are left out), not at the end of the shot. The budget is set to a time the first run saw the
/// first shot running at; the second run must then end with no shot finished.
#[test]
fn the_time_budget_stops_within_a_long_shot() {
    let scene = load_scene(&long_first_shot(), &ExternalFiles::Refuse, 1_000_000).unwrap();
    let (params, _) = long_first_shot_params();
    let cancel = AtomicBool::new(false);
    let mut inside = None;
    bake(
        &scene,
        DomainMode::Extended,
        params.clone(),
        &cancel,
        &mut |p| {
            if p.shot_receivers > 0 && p.iterations == 0 && inside.is_none() {
                inside = Some(p.seconds);
                cancel.store(true, Ordering::Relaxed);
            }
        },
    )
    .unwrap();
    let inside = inside.expect("a report from within the first shot");
    let budget = SolverParams {
        max_seconds: Some(inside),
        ..params
    };
    let cancel = AtomicBool::new(false);
    let mut last = None;
    let (_, solution) = bake(&scene, DomainMode::Extended, budget, &cancel, &mut |p| {
        last = Some(*p);
    })
    .unwrap();
    let stats = &solution.stats;
    println!(
        "budget {inside:.2} s: stopped after {:.2} s, {} shot(s), last report {last:?}",
        stats.seconds, stats.iterations
    );
    assert_eq!(stats.stop_reason, Some(StopReason::TimeBudget));
    assert_eq!(stats.iterations, 0, "the first shot was not finished");
    assert!(
        solution
            .convergence
            .last()
            .is_some_and(|p| p.unshot_ratio >= 0.999),
        "the shooter keeps its unshot power when its shot is cut short"
    );
}

/// The job parameters (for the service) and solver parameters of [`long_first_shot`].
fn long_first_shot_params() -> (SolverParams, &'static str) {
    let params = SolverParams {
        order: 1,
        tolerance: 3e-8,
        ..SolverParams::default()
    };
    (params, "order=1&tolerance=3e-8")
}

/// `wavrad solve` without a terminal (and with `--log-format json`) logs a `progress` event at
/// most once a second with the fields a benchmark parses.
#[test]
fn solve_logs_progress_events() {
    let dir = std::env::temp_dir().join(format!("wavrad-progress-log-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("room.glb");
    std::fs::write(&scene, cluttered_scene(5)).unwrap();
    let out = dir.join("out");
    let output = wavrad(&[
        "--log-format",
        "json",
        "solve",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--order",
        "1",
        "--max-seconds",
        "3",
    ]);
    assert!(output.status.success(), "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let events: Vec<Value> = stderr
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["fields"]["message"] == "progress")
        .collect();
    assert!(events.len() >= 2, "{stderr}");
    for e in &events {
        let f = &e["fields"];
        assert_eq!(e["level"], "INFO");
        for key in [
            "seconds",
            "shots",
            "unshot_ratio",
            "shot_receivers_done",
            "shot_receivers",
        ] {
            assert!(f[key].is_number(), "{key} in {e}");
        }
        assert!(f["eta_seconds"].is_number() || f.get("eta_seconds").is_none());
    }
    assert!(
        events
            .iter()
            .any(|e| e["fields"]["eta_seconds"].is_number()),
        "{stderr}"
    );
    let seconds: Vec<f64> = events
        .iter()
        .map(|e| e["fields"]["seconds"].as_f64().unwrap())
        .collect();
    assert!(
        seconds.windows(2).all(|w| w[1] - w[0] >= 0.9),
        "at most once a second: {seconds:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
