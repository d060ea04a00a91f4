//! Progress of a solve while it runs: reports from within a shot, and the ETA.
//!
//! Owns [`with_reports`], which runs a shot's parallel loop over its receivers on the rayon pool
//! while the calling thread (the one `observe` belongs to: it never leaves it) reports the count
//! of receivers done every [`REPORT_INTERVAL`]; and [`EtaEstimator`], the estimate of the seconds
//! left that the CLI and the service both show.
//!
//! Invariants: the loop counts one per receiver root (no per-ray atomics); a report never
//! blocks the loop; a shot shorter than `REPORT_INTERVAL` makes no report from within (the
//! reports between shots are the solver's), so small scenes report exactly as before.

use super::{Progress, SolverParams, REPORT_INTERVAL};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How long the calling thread, when it is a thread of the pool, lets the other threads take the
/// loop before it runs the loop itself (they are all busy elsewhere).
const START_GRACE: Duration = Duration::from_millis(20);

/// Runs `work` (a parallel loop that adds one to the counter it is given per receiver done) and,
/// while it runs, calls `report(done)` on the calling thread every [`REPORT_INTERVAL`].
///
/// The loop runs on the rayon pool of the calling thread (the global pool from a thread outside
/// any pool), which the calling thread leaves to it while it waits; a thread that is the only one
/// of its pool runs the loop itself without reports, and so does one whose pool leaves the loop
/// untaken for [`START_GRACE`] (never a deadlock). A panic in `work` ends the wait and is
/// propagated (`tests::a_panic_in_the_loop_reaches_the_caller`).
pub(super) fn with_reports<W>(work: W, report: &mut dyn FnMut(u64))
where
    W: FnOnce(&AtomicU64) + Send,
{
    let done = AtomicU64::new(0);
    if rayon::current_thread_index().is_some() && rayon::current_num_threads() < 2 {
        work(&done);
        return;
    }
    let started = AtomicBool::new(false);
    // Dropped when `work` returns or unwinds: the waiting thread sees the channel close.
    let (finished, wait) = mpsc::channel::<()>();
    rayon::in_place_scope(|scope| {
        let (done, started) = (&done, &started);
        scope.spawn(move |_| {
            let _finished = finished;
            started.store(true, Ordering::Release);
            work(done);
        });
        let begin = Instant::now();
        let mut next_report = begin + REPORT_INTERVAL;
        let mut next_check = begin + START_GRACE;
        loop {
            let waiting = !started.load(Ordering::Acquire);
            let wake = if waiting {
                next_report.min(next_check)
            } else {
                next_report
            };
            match wait.recv_timeout(wake.saturating_duration_since(Instant::now())) {
                Ok(()) | Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {}
            }
            let now = Instant::now();
            if waiting && now >= next_check && !started.load(Ordering::Acquire) {
                // Every other thread of the pool is busy: run pending work here (the loop, or
                // what keeps the others from it) rather than wait for nothing.
                rayon::yield_now();
                next_check = Instant::now() + START_GRACE;
                continue;
            }
            if now >= next_report {
                report(done.load(Ordering::Relaxed));
                next_report = (next_report + REPORT_INTERVAL).max(now + REPORT_INTERVAL / 2);
            }
        }
    });
}

/// What a shot shoots, for the ETA: how many shots of its kind are left after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ShotKind {
    /// A punctual light (they shoot first).
    Light { left: usize },
    /// An emitter's emission (direct shots follow the lights).
    Direct { left: usize },
    /// Unshot radiosity, until the target.
    Indirect,
}

/// Makes the solver's [`Progress`] reports: after every shot and from within long shots, each
/// with its ETA; calls `observe` (on the solver's thread only).
pub(super) struct Reporter<'a> {
    start: Instant,
    observe: &'a mut dyn FnMut(&Progress),
    links: &'a AtomicU64,
    eta: EtaEstimator,
    /// The last report after a shot (before any: the start).
    last: Progress,
    shot_running: bool,
}

impl<'a> Reporter<'a> {
    pub(super) fn new(
        start: Instant,
        observe: &'a mut dyn FnMut(&Progress),
        links: &'a AtomicU64,
        params: &SolverParams,
        roots: usize,
    ) -> Self {
        Reporter {
            start,
            observe,
            links,
            eta: EtaEstimator::new(params.target_unshot, params.max_seconds),
            last: Progress {
                iterations: 0,
                unshot_ratio: 1.0,
                elements: roots as u64,
                links: 0,
                seconds: 0.0,
                shot_receivers_done: 0,
                shot_receivers: 0,
                eta_seconds: None,
            },
            shot_running: false,
        }
    }

    fn seconds(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// A shot of `kind` begins, after `iterations` shots.
    pub(super) fn shot_started(&mut self, iterations: u64, kind: ShotKind) {
        let now = self.seconds();
        self.last.iterations = iterations;
        self.eta.shot_started(now, kind);
        self.shot_running = true;
    }

    /// Within the shot: `done` of its `receivers` are finished.
    pub(super) fn within_shot(&mut self, done: u64, receivers: u64) {
        let seconds = self.seconds();
        let fraction = if receivers > 0 {
            done as f64 / receivers as f64
        } else {
            0.0
        };
        let progress = Progress {
            links: self.links.load(Ordering::Relaxed),
            seconds,
            shot_receivers_done: done,
            shot_receivers: receivers,
            eta_seconds: self.eta.estimate(seconds, fraction),
            ..self.last
        };
        (self.observe)(&progress);
    }

    /// Between shots: `iterations` shots are done, leaving `ratio` unshot over `elements` leaves.
    /// Returns the report (a row of the solution's convergence).
    pub(super) fn after_shot(&mut self, iterations: u64, ratio: f64, elements: u64) -> Progress {
        let seconds = self.seconds();
        if self.shot_running {
            self.eta.shot_finished(seconds, ratio);
            self.shot_running = false;
        } else {
            self.eta.solve_started(seconds, ratio);
        }
        self.last = Progress {
            iterations,
            unshot_ratio: ratio,
            elements,
            links: self.links.load(Ordering::Relaxed),
            seconds,
            shot_receivers_done: 0,
            shot_receivers: 0,
            eta_seconds: self.eta.estimate(seconds, 0.0),
        };
        (self.observe)(&self.last);
        self.last
    }
}

/// While lights and emitters shoot, what follows is expected to take this multiple of their
/// seconds (no history of the ratio to go by yet): a middle value, since under a sky panel what
/// follows its shot is a fraction of it, and in a closed room lit by a small lamp a multiple.
const AFTER_DIRECT: f64 = 0.7;
/// Indirect shots finished before their history is used (before it: the prior above, when
/// there was a direct phase, else no estimate).
const MIN_SHOTS: usize = 2;
/// Indirect shots finished before the curvature `alpha` is measured (before it: 0, the mean
/// seconds per nat of the history).
const ALPHA_SHOTS: usize = 8;
/// Nats the history must span before the curvature `alpha` is measured.
const ALPHA_SPAN: f64 = 1.0;
/// The curvature is fitted on the seconds per nat of the last this many nats of the history...
const FIT_NATS: f64 = 3.0;
/// ... cut into this many bins (a bin's seconds per nat read on the cumulative curve, so one
/// slow or instant shot does not swing it).
const FIT_BINS: usize = 8;
/// A fitted curvature is kept in full when it is well beyond its standard error, and shrunk
/// towards 0 when not: `alpha^3 / (alpha^2 + SIGNIFICANCE se^2)` (4: two standard errors).
const SIGNIFICANCE: f64 = 4.0;
/// Bounds of `alpha`: -1 is a ratio falling like 1/t.
const ALPHA_RANGE: (f64, f64) = (-1.0, 1.5);
/// Nats of progress below which a shot updates the last point of the history instead of adding
/// one (bounds the history by the nats from the start to the target, not by the shots).
const HISTORY_STEP: f64 = 1e-3;

/// Estimates the seconds left in a solve from what the solver knows: the clock, the shot in
/// progress (its kind, its seconds so far and the fraction of its receivers done), the seconds
/// the light and direct shots took, and the history of the unshot ratio against time since.
///
/// The model (`tests::eta_*` pin it on synthetic solves):
/// - a shot in progress ends after `s (1 - f) / f` more seconds, `s` its seconds so far and `f`
///   the fraction of its receivers done (`s` again while none is);
/// - while lights and emitters shoot (the first shot of a sky panel can be most of a solve), the
///   shots of their kind still queued take as long as this one, and what follows takes
///   [`AFTER_DIRECT`] times the seconds of all of them;
/// - then, with `u` the nats of unshot ratio shed since the direct shots, the seconds per nat are
///   `g(u) = g_now exp(-alpha (u - u_now))`: `alpha = 0` is a ratio falling exponentially in
///   time, `alpha = -1` one falling like 1/t, `alpha > 0` one falling faster and faster as the
///   shots' power (and with it their refinement) falls. `alpha` is fitted on the last
///   [`FIT_NATS`] of the history and kept only as far as it stands out of its noise
///   ([`SIGNIFICANCE`]); before [`ALPHA_SHOTS`] shots and [`ALPHA_SPAN`] nats it is 0 (and
///   before [`MIN_SHOTS`], what the direct phase suggested counts too). The seconds left are the
///   integral of `g` down to the target, less the seconds of the shot in progress (at least
///   what its receivers say is left of it);
/// - capped by what is left of the time budget, 0 once the target is reached.
#[derive(Debug, Clone)]
pub(super) struct EtaEstimator {
    target_ln: f64,
    max_seconds: Option<f64>,
    /// ln of the unshot ratio after the last finished shot (its running minimum); `None` before
    /// the first report.
    y: Option<f64>,
    /// When the last shot finished.
    t_last: f64,
    /// Seconds of the light and direct shots finished.
    direct_seconds: f64,
    /// The shot in progress: when it began, and its kind.
    shot: Option<(f64, ShotKind)>,
    /// Since the last direct shot: (seconds, nats shed since then), the first point at its end;
    /// the nats never decrease.
    history: Vec<(f64, f64)>,
    /// ln of the unshot ratio at the first point of `history`.
    y_phase: f64,
    /// Indirect shots finished.
    indirect_shots: usize,
}

impl EtaEstimator {
    pub(super) fn new(target: f64, max_seconds: Option<f64>) -> Self {
        EtaEstimator {
            target_ln: target.ln(),
            max_seconds,
            y: None,
            t_last: 0.0,
            direct_seconds: 0.0,
            shot: None,
            history: Vec::new(),
            y_phase: 0.0,
            indirect_shots: 0,
        }
    }

    /// The first report: the unshot ratio `ratio` at `now`, before any shot of the loop.
    pub(super) fn solve_started(&mut self, now: f64, ratio: f64) {
        self.t_last = now;
        self.y = Some(ln_ratio(ratio));
    }

    pub(super) fn shot_started(&mut self, now: f64, kind: ShotKind) {
        self.shot = Some((now, kind));
    }

    /// The shot in progress ended at `now`, leaving `ratio` unshot.
    pub(super) fn shot_finished(&mut self, now: f64, ratio: f64) {
        let y = ln_ratio(ratio);
        let before = self.y.unwrap_or(y);
        let y = y.min(before);
        match self.shot.take() {
            Some((start, ShotKind::Light { .. } | ShotKind::Direct { .. })) => {
                self.direct_seconds += now - start;
                self.history.clear();
                self.indirect_shots = 0;
            }
            Some((_, ShotKind::Indirect)) => {
                if self.history.is_empty() {
                    self.history.push((self.t_last, 0.0));
                    self.y_phase = before;
                }
                let u = self.y_phase - y;
                let n = self.history.len();
                if n >= 2 && u - self.history[n - 2].1 < HISTORY_STEP {
                    self.history[n - 1] = (now, u);
                } else {
                    self.history.push((now, u));
                }
                self.indirect_shots += 1;
            }
            None => {}
        }
        self.t_last = now;
        self.y = Some(y);
    }

    /// Seconds left at `now`, `fraction` of the receivers of the shot in progress done.
    pub(super) fn estimate(&self, now: f64, fraction: f64) -> Option<f64> {
        let y = self.y?;
        let budget = self.max_seconds.map(|m| (m - now).max(0.0));
        let left = (y - self.target_ln).max(0.0);
        let eta = match self.shot {
            None if left <= 0.0 => Some(0.0),
            None => self.after_direct(left),
            Some((start, kind)) => {
                let seconds = (now - start).max(0.0);
                let rest = rest_of_shot(seconds, fraction);
                match kind {
                    ShotKind::Light { left: queued } | ShotKind::Direct { left: queued } => {
                        let shot = seconds + rest;
                        let queued = queued as f64 * shot;
                        let direct = self.direct_seconds + shot + queued;
                        Some(rest + queued + AFTER_DIRECT * direct)
                    }
                    ShotKind::Indirect => self
                        .after_direct(left)
                        .map(|after| (after - seconds).max(rest)),
                }
            }
        };
        match (eta, budget) {
            (Some(e), Some(b)) => Some(e.min(b)),
            (e, b) => e.or(b),
        }
    }

    /// Seconds from the last finished shot to the target, `left` nats away, after the direct
    /// shots.
    fn after_direct(&self, left: f64) -> Option<f64> {
        let prior = (self.direct_seconds > 0.0).then_some(AFTER_DIRECT * self.direct_seconds);
        let (Some(&(t0, _)), Some(&(tn, span))) = (self.history.first(), self.history.last())
        else {
            return prior;
        };
        let mean = (span > 0.0 && tn > t0).then(|| (tn - t0) / span);
        if self.indirect_shots < MIN_SHOTS {
            // One shot says little: at least what the direct phase suggested.
            let rest = prior? - (tn - t0);
            return Some(rest.max(mean.map_or(0.0, |g| g * left)));
        }
        let g_mean = mean?;
        if self.indirect_shots < ALPHA_SHOTS || span < ALPHA_SPAN {
            return Some(g_mean * left);
        }
        let fit = span.min(FIT_NATS);
        let u0 = span - fit;
        let g_window = (tn - self.time_at(u0)) / fit;
        if g_window.is_nan() || g_window <= 0.0 {
            return Some(g_mean * left);
        }
        let Some((alpha, u_mid)) = self.curvature(u0, fit) else {
            return Some(g_window * left);
        };
        // The window's mean holds at its middle.
        let g_now = g_window * (-alpha * (span - u_mid)).exp();
        Some(g_now * nats_integral(alpha, left))
    }

    /// The curvature `alpha` of ln(seconds per nat) against nats over `[u0, u0 + fit]` (least
    /// squares over [`FIT_BINS`] bins, shrunk by its standard error), and the window's mean nats;
    /// `None` when too few bins took any time.
    fn curvature(&self, u0: f64, fit: f64) -> Option<(f64, f64)> {
        let b = fit / FIT_BINS as f64;
        let mut points = [(0.0, 0.0); FIT_BINS];
        let mut n = 0;
        for j in 0..FIT_BINS {
            let ua = u0 + j as f64 * b;
            let g = (self.time_at(ua + b) - self.time_at(ua)) / b;
            if g > 0.0 {
                points[n] = (ua + b / 2.0, g.ln());
                n += 1;
            }
        }
        if n < 4 {
            return None;
        }
        let points = &points[..n];
        let nf = n as f64;
        let (mx, my) = points
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0 / nf, b + p.1 / nf));
        let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
        let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let slope = sxy / sxx;
        let rss: f64 = points
            .iter()
            .map(|p| (p.1 - my - slope * (p.0 - mx)).powi(2))
            .sum();
        let se2 = rss / (nf - 2.0) / sxx;
        let measured = -slope;
        let alpha = measured.powi(3) / (measured * measured + SIGNIFICANCE * se2);
        let alpha = if alpha.is_finite() { alpha } else { 0.0 };
        Some((alpha.clamp(ALPHA_RANGE.0, ALPHA_RANGE.1), u0 + fit / 2.0))
    }

    /// Seconds at which the history had shed `u` nats (linear between its points).
    fn time_at(&self, u: f64) -> f64 {
        let h = &self.history;
        let i = h.partition_point(|p| p.1 < u);
        if i == 0 {
            return h[0].0;
        }
        if i >= h.len() {
            return h[h.len() - 1].0;
        }
        let (ta, ua) = h[i - 1];
        let (tb, ub) = h[i];
        ta + (tb - ta) * (u - ua) / (ub - ua)
    }
}

/// Seconds left in a shot `seconds` old with `fraction` of its receivers done.
fn rest_of_shot(seconds: f64, fraction: f64) -> f64 {
    if fraction > 0.0 {
        seconds * (1.0 - fraction.min(1.0)) / fraction
    } else {
        seconds
    }
}

/// `integral_0^x exp(-alpha v) dv`.
fn nats_integral(alpha: f64, x: f64) -> f64 {
    if alpha.abs() < 1e-9 {
        x
    } else {
        -(-alpha * x).exp_m1() / alpha
    }
}

/// ln of an unshot ratio (a ratio of 0, nothing emitted, is as good as any target).
fn ln_ratio(ratio: f64) -> f64 {
    ratio.max(1e-300).ln()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// A loop of `n` receivers of `each` each, counted as `shoot` counts them.
    fn slow_loop(n: u64, each: Duration) -> impl FnOnce(&AtomicU64) + Send {
        move |done: &AtomicU64| {
            (0..n).into_par_iter().for_each(|_| {
                std::thread::sleep(each);
                done.fetch_add(1, Ordering::Relaxed);
            });
        }
    }

    /// Receivers done one after the other (a loop that lasts `n * each` on any number of cores).
    fn serial_loop(n: u64, each: Duration) -> impl FnOnce(&AtomicU64) + Send {
        move |done: &AtomicU64| {
            for _ in 0..n {
                std::thread::sleep(each);
                done.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    #[test]
    fn a_long_loop_reports_its_count_from_the_calling_thread() {
        let caller = std::thread::current().id();
        let mut reports = Vec::new();
        let t = Instant::now();
        with_reports(serial_loop(40, Duration::from_millis(30)), &mut |d| {
            assert_eq!(std::thread::current().id(), caller);
            reports.push((t.elapsed(), d));
        });
        assert!(reports.len() >= 2, "{reports:?}");
        assert!(reports.windows(2).all(|w| w[0].1 < w[1].1), "{reports:?}");
        assert!(reports.iter().all(|r| r.1 <= 40));
        let gaps = reports.windows(2).map(|w| w[1].0 - w[0].0);
        assert!(
            gaps.into_iter().all(|g| g >= REPORT_INTERVAL / 2),
            "{reports:?}"
        );
    }

    #[test]
    fn a_short_loop_makes_no_report() {
        let mut reports = 0;
        with_reports(slow_loop(4, Duration::ZERO), &mut |_| reports += 1);
        assert_eq!(reports, 0);
    }

    /// On a thread of a pool of one, or of a pool whose other threads are all busy, the loop
    /// still runs (on the calling thread).
    #[test]
    fn the_loop_runs_when_no_other_thread_can_take_it() {
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let counted = one.install(|| {
            let mut n = 0;
            with_reports(slow_loop(8, Duration::from_millis(1)), &mut |_| {});
            with_reports(|d| n = d.fetch_add(1, Ordering::Relaxed) + 1, &mut |_| {});
            n
        });
        assert_eq!(counted, 1);
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let (release, blocked) = mpsc::channel::<()>();
        let ran = AtomicU64::new(0);
        two.in_place_scope(|s| {
            // One thread of two waits for the loop on the other to end.
            s.spawn(move |_| {
                let _ = blocked.recv();
            });
            std::thread::sleep(Duration::from_millis(50));
            two.install(|| {
                with_reports(
                    |_| {
                        ran.fetch_add(1, Ordering::Relaxed);
                    },
                    &mut |_| {},
                )
            });
            drop(release);
        });
        assert_eq!(ran.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn a_panic_in_the_loop_reaches_the_caller() {
        let result = std::panic::catch_unwind(|| {
            with_reports(|_| panic!("in a receiver"), &mut |_| {});
        });
        assert!(result.is_err());
    }

    /// Feeds `e` a solve: one direct shot of `direct` seconds whose receivers finish at an even
    /// rate, leaving ratio `r1`, then indirect shots each shedding `step` nats in the seconds
    /// `g(u) * step` (`u` the nats shed before it) until the target 1e-3; returns every
    /// (seconds, eta) reported, the in-shot ones every half second, and the total seconds.
    fn synthetic_solve(
        direct: f64,
        r1: f64,
        step: f64,
        g: impl Fn(f64) -> f64,
    ) -> (Vec<(f64, Option<f64>)>, f64) {
        let mut e = EtaEstimator::new(1e-3, None);
        let mut out = Vec::new();
        e.solve_started(0.0, 1.0);
        out.push((0.0, e.estimate(0.0, 0.0)));
        e.shot_started(0.0, ShotKind::Direct { left: 0 });
        let mut t = 0.5;
        while t < direct {
            out.push((t, e.estimate(t, t / direct)));
            t += 0.5;
        }
        let mut t = direct;
        e.shot_finished(t, r1);
        out.push((t, e.estimate(t, 0.0)));
        let (mut y, mut u) = (r1.ln(), 0.0);
        while y > 1e-3f64.ln() {
            e.shot_started(t, ShotKind::Indirect);
            let dt = g(u) * step;
            let mut s = 0.5;
            while s < dt {
                out.push((t + s, e.estimate(t + s, s / dt)));
                s += 0.5;
            }
            t += dt;
            y -= step;
            u += step;
            e.shot_finished(t, y.exp());
            out.push((t, e.estimate(t, 0.0)));
        }
        (out, t)
    }

    /// The worst ratios (lowest, highest) of the ETA to the seconds really left, over the
    /// reports from `from` of the solve on, while more than 2 % of it is left.
    fn worst_ratios(reports: &[(f64, Option<f64>)], total: f64, from: f64) -> (f64, f64) {
        let mut worst = (f64::INFINITY, 0.0f64);
        for &(t, eta) in reports {
            let left = total - t;
            if t >= from * total && left >= 0.02 * total {
                let q = eta.expect("an estimate after the first shot") / left;
                worst = (worst.0.min(q), worst.1.max(q));
            }
        }
        worst
    }

    fn within_twice(worst: (f64, f64)) -> bool {
        worst.0 >= 0.5 && worst.1 <= 2.0
    }

    /// A first (direct) shot of 60 % of the solve whose receivers finish evenly, then a ratio
    /// falling exponentially: the ETA is within a factor 2 of the seconds left from a fifth of
    /// the solve on (the rule), and closer once the decay is under way.
    #[test]
    fn eta_holds_on_a_long_direct_shot_then_an_exponential_decay() {
        let (reports, total) = synthetic_solve(60.0, 0.3, 0.02, |_| 7.0);
        assert!((total - 100.0).abs() < 1.0, "{total}");
        let worst = worst_ratios(&reports, total, 0.2);
        assert!(within_twice(worst), "{worst:?}");
        let late = worst_ratios(&reports, total, 0.7);
        assert!(late.0 > 0.85 && late.1 < 1.15, "{late:?}");
    }

    /// A ratio falling exponentially for 2 nats, then like 1/t (each nat taking e times longer
    /// than the one before): the turn cannot be foreseen, but once the fit window has seen it
    /// (by 70 % of this solve) the ETA is within a factor 2 again.
    #[test]
    fn eta_follows_a_decay_that_turns_to_one_over_t() {
        let g = |u: f64| {
            if u < 2.0 {
                4.0
            } else {
                4.0 / 3.0 * ((u - 2.0).exp() + 2.0)
            }
        };
        let (reports, total) = synthetic_solve(60.0, 0.3, 0.02, g);
        let late = worst_ratios(&reports, total, 0.7);
        assert!(within_twice(late), "{late:?}");
        let at_the_turn = worst_ratios(&reports, total, 0.5);
        assert!(
            at_the_turn.0 < 0.5,
            "the turn is a surprise: {at_the_turn:?}"
        );
    }

    /// A ratio falling faster and faster (each shot cheaper as the power shot falls, as on the
    /// Cornell box): taken for exponential at first (an over-estimate), then fitted.
    #[test]
    fn eta_follows_a_decay_that_speeds_up() {
        let (reports, total) = synthetic_solve(20.0, 0.4, 0.02, |u| 12.0 * (-0.8 * u).exp());
        let late = worst_ratios(&reports, total, 0.85);
        assert!(within_twice(late), "{late:?}");
        let early = worst_ratios(&reports, total, 0.6);
        assert!(early.1 > 2.0 && early.0 >= 0.5, "{early:?}");
    }

    /// During a direct shot: the rest of the shot from its receivers done (its seconds so far
    /// again while none is), the direct shots still queued as long as this one, then
    /// `AFTER_DIRECT` times the direct phase; capped by the time budget.
    #[test]
    fn eta_of_a_direct_shot_in_progress() {
        let mut e = EtaEstimator::new(1e-3, None);
        assert_eq!(
            e.estimate(0.0, 0.0),
            None,
            "nothing known before the first report"
        );
        e.solve_started(0.0, 1.0);
        e.shot_started(0.0, ShotKind::Direct { left: 1 });
        let close = |a: Option<f64>, b: f64| (a.unwrap() - b).abs() < 1e-9;
        // A quarter done in 10 s: 30 s more, a second shot of 40 s, then 0.7 x 80 s.
        assert!(close(
            e.estimate(10.0, 0.25),
            30.0 + 40.0 + AFTER_DIRECT * 80.0
        ));
        assert!(close(
            e.estimate(10.0, 0.0),
            10.0 + 20.0 + AFTER_DIRECT * 40.0
        ));
        e.shot_finished(40.0, 0.5);
        e.shot_started(40.0, ShotKind::Direct { left: 0 });
        assert!(close(e.estimate(50.0, 0.5), 10.0 + AFTER_DIRECT * 60.0));
        e.shot_finished(60.0, 0.3);
        assert!(close(e.estimate(60.0, 0.0), AFTER_DIRECT * 60.0));
        // One indirect shot: at least the rest of that prior, or its own pace if slower.
        e.shot_started(60.0, ShotKind::Indirect);
        e.shot_finished(62.0, 0.3 * (-0.1f64).exp());
        let left = (0.3f64.ln() - 0.1 - 1e-3f64.ln()) * 20.0;
        assert!(close(
            e.estimate(62.0, 0.0),
            left.max(AFTER_DIRECT * 60.0 - 2.0)
        ));
        let mut capped = EtaEstimator::new(1e-3, Some(50.0));
        capped.solve_started(0.0, 1.0);
        capped.shot_started(0.0, ShotKind::Direct { left: 0 });
        assert_eq!(capped.estimate(10.0, 0.25), Some(40.0));
    }

    /// Moved from the service (which now shows the solver's ETA): a ratio falling exactly
    /// exponentially gives the exact seconds left; the budget caps it; no estimate from one
    /// shot, or from a ratio that does not fall; 0 once the target is reached.
    #[test]
    fn eta_follows_an_exponential_decay() {
        let estimate = |points: &[(f64, f64)], target: f64, max_seconds: Option<f64>| {
            let mut e = EtaEstimator::new(target, max_seconds);
            let (t0, y0) = points[0];
            e.solve_started(t0, y0.exp());
            for &(t, y) in &points[1..] {
                e.shot_started(t, ShotKind::Indirect);
                e.shot_finished(t, y.exp());
            }
            e.estimate(points[points.len() - 1].0, 0.0)
        };
        // ratio = exp(-t): from ln r = -2 at t = 2 to ln(1e-3) = -6.9 takes 4.9 s more.
        let points: Vec<(f64, f64)> = (0..=4)
            .map(|i| (i as f64 * 0.5, -(i as f64) * 0.5))
            .collect();
        let eta = estimate(&points, 1e-3, None).unwrap();
        assert!((eta - (1e3f64.ln() - 2.0)).abs() < 1e-9, "{eta}");
        assert_eq!(estimate(&points, 1e-3, Some(3.0)), Some(1.0));
        assert_eq!(estimate(&points[..2], 1e-3, None), None);
        let flat = [(0.0, -1.0), (1.0, -1.0), (2.0, -1.0)];
        assert_eq!(estimate(&flat, 1e-3, None), None);
        assert_eq!(estimate(&[(1.0, -8.0)], 1e-3, None), Some(0.0));
    }
}
