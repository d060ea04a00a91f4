//! Progress of a solve while it runs: reports after every shot and from within a shot.
//!
//! Owns [`with_reports`], which runs a shot's parallel loop over its receivers on the rayon pool
//! while the calling thread (the one `observe` belongs to: it never leaves it) reports the
//! receivers done, and their share of the shot's estimated cost, every [`REPORT_INTERVAL`]; and
//! the [`Reporter`], which makes the solver's [`Progress`] reports with the ETA (`eta.rs`).
//!
//! Invariants: the loop counts once per piece of receiver roots (no per-ray atomics); a report
//! never blocks the loop; a shot shorter than `REPORT_INTERVAL` makes no report from within (the
//! reports between shots are the solver's), so small scenes report exactly as before.

use super::eta::{EtaEstimator, ShotPlan};
use super::indirect_forecast::IndirectForecast;
use super::striped_count::StripedCount;
use super::visibility::Visibility;
use super::{Progress, SolverParams, REPORT_INTERVAL};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How long the calling thread, when it is a thread of the pool, lets the other threads take the
/// loop before it runs the loop itself (they are all busy elsewhere).
const START_GRACE: Duration = Duration::from_millis(20);

/// What a shot's loop has done: receivers, their cost units, and the unshot power they got
/// against what was expected of them (both in the units of [`CostUnits`] for the expected
/// total), all counted by [`ShotCounter::add`] (a piece of the loop at once) or
/// [`ShotCounter::finished`] (one receiver).
#[derive(Debug, Default)]
pub(super) struct ShotCounter {
    receivers: AtomicU64,
    units: AtomicU64,
    expected: AtomicU64,
    returned: AtomicU64,
}

/// A reading of a [`ShotCounter`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct ShotCounts {
    pub receivers: u64,
    pub units: u64,
    pub expected: u64,
    pub returned: u64,
}

impl ShotCounts {
    /// Counts one receiver done: `units` of the cost, `expected` and `returned` units of
    /// returns (wrapping, as the counter's atomics add).
    pub(super) fn receiver(&mut self, units: u64, expected: u64, returned: u64) {
        self.receivers += 1;
        self.units = self.units.wrapping_add(units);
        self.expected = self.expected.wrapping_add(expected);
        self.returned = self.returned.wrapping_add(returned);
    }
}

impl ShotCounter {
    /// One receiver is done: `units` of the cost, `expected` and `returned` units of returns.
    pub(super) fn finished(&self, units: u64, expected: u64, returned: u64) {
        let mut one = ShotCounts::default();
        one.receiver(units, expected, returned);
        self.add(one);
    }

    /// Receivers done together (a loop's piece adds its receivers once: the counter is one
    /// cache line every thread writes).
    pub(super) fn add(&self, done: ShotCounts) {
        self.receivers.fetch_add(done.receivers, Ordering::Relaxed);
        self.units.fetch_add(done.units, Ordering::Relaxed);
        self.expected.fetch_add(done.expected, Ordering::Relaxed);
        self.returned.fetch_add(done.returned, Ordering::Relaxed);
    }

    fn load(&self) -> ShotCounts {
        ShotCounts {
            receivers: self.receivers.load(Ordering::Relaxed),
            units: self.units.load(Ordering::Relaxed),
            expected: self.expected.load(Ordering::Relaxed),
            returned: self.returned.load(Ordering::Relaxed),
        }
    }
}

/// Receivers' cost weights (any positive scale) turned into integer units that add up to about
/// [`CostUnits::TOTAL`], so a loop can count them in one atomic.
#[derive(Debug, Clone, Copy)]
pub(super) struct CostUnits {
    scale: f64,
}

impl CostUnits {
    const TOTAL: f64 = (1u64 << 40) as f64;

    /// Units for weights that add up to `sum`.
    pub(super) fn new(sum: f64) -> Self {
        let scale = if sum > 0.0 && sum.is_finite() {
            Self::TOTAL / sum
        } else {
            0.0
        };
        CostUnits { scale }
    }

    pub(super) fn of(&self, weight: f64) -> u64 {
        (weight.max(0.0) * self.scale).round() as u64
    }

    /// The fraction of the shot `units` stand for.
    fn fraction(units: u64) -> f64 {
        (units as f64 / Self::TOTAL).min(1.0)
    }
}

/// Runs `work` (a parallel loop that counts its receivers done with [`ShotCounter::add`] or
/// [`ShotCounter::finished`])
/// and, while it runs, calls `report` with its counts on the calling thread every
/// [`REPORT_INTERVAL`].
///
/// The loop runs on the rayon pool of the calling thread (the global pool from a thread outside
/// any pool), which the calling thread leaves to it while it waits; a thread that is the only one
/// of its pool runs the loop itself without reports, and so does one whose pool leaves the loop
/// untaken for [`START_GRACE`] (never a deadlock). A panic in `work` ends the wait and is
/// propagated (`tests::a_panic_in_the_loop_reaches_the_caller`).
pub(super) fn with_reports<W>(work: W, report: &mut dyn FnMut(ShotCounts))
where
    W: FnOnce(&ShotCounter) + Send,
{
    let done = ShotCounter::default();
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
                report(done.load());
                next_report = (next_report + REPORT_INTERVAL).max(now + REPORT_INTERVAL / 2);
            }
        }
    });
}

/// Makes the solver's [`Progress`] reports: after every shot and from within long shots, each
/// with its ETA; calls `observe` (on the solver's thread only).
pub(super) struct Reporter<'a> {
    start: Instant,
    observe: &'a mut dyn FnMut(&Progress),
    links: &'a StripedCount,
    /// Counts the rays traced (the ETA's measure of the machine's speed).
    visibility: &'a Visibility,
    eta: EtaEstimator,
    /// The last report after a shot (before any: the start).
    last: Progress,
    shot_running: bool,
    foreseen: bool,
}

impl<'a> Reporter<'a> {
    pub(super) fn new(
        start: Instant,
        observe: &'a mut dyn FnMut(&Progress),
        links: &'a StripedCount,
        visibility: &'a Visibility,
        params: &SolverParams,
        roots: usize,
    ) -> Self {
        Reporter {
            start,
            observe,
            links,
            visibility,
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
            foreseen: false,
        }
    }

    /// Seconds since the start, the rays traced so far counted into the ETA.
    fn seconds(&mut self) -> f64 {
        self.eta.rays_traced(self.visibility.rays_traced());
        self.start.elapsed().as_secs_f64()
    }

    /// The indirect phase foreseen (`indirect_forecast.rs`).
    pub(super) fn indirect_foreseen(&mut self, forecast: IndirectForecast) {
        tracing::debug!(
            shots = forecast.shots,
            cost = forecast.cost.total(),
            rays = self.visibility.rays_traced(),
            seconds = self.start.elapsed().as_secs_f64(),
            "indirect phase foreseen"
        );
        self.eta.indirect_cost_foreseen(forecast.cost);
        self.foreseen = true;
    }

    /// Whether the indirect phase has been foreseen.
    pub(super) fn has_forecast(&self) -> bool {
        self.foreseen
    }

    /// A shot of `plan` begins, after `iterations` shots.
    pub(super) fn shot_started(&mut self, iterations: u64, plan: ShotPlan) {
        let now = self.seconds();
        self.last.iterations = iterations;
        self.eta.shot_started(now, plan);
        self.shot_running = true;
    }

    /// Within the shot of `receivers` receivers: what its loop counted.
    pub(super) fn within_shot(&mut self, counts: ShotCounts, receivers: u64) {
        let seconds = self.seconds();
        if counts.expected > 0 {
            self.eta
                .returns_seen(counts.returned as f64 / counts.expected as f64);
        }
        if receivers > 0 {
            self.eta
                .receivers_done(counts.receivers as f64 / receivers as f64);
        }
        let progress = Progress {
            links: self.links.get(),
            seconds,
            shot_receivers_done: counts.receivers,
            shot_receivers: receivers,
            eta_seconds: self
                .eta
                .estimate(seconds, CostUnits::fraction(counts.units)),
            ..self.last
        };
        (self.observe)(&progress);
    }

    /// Between shots: `iterations` shots are done, leaving `ratio` unshot of `base` W over
    /// `elements` leaves. Returns the report (a row of the solution's convergence).
    pub(super) fn after_shot(
        &mut self,
        iterations: u64,
        ratio: f64,
        base: f64,
        elements: u64,
    ) -> Progress {
        let seconds = self.seconds();
        if self.shot_running {
            self.eta.shot_finished(seconds, ratio, base);
            self.shot_running = false;
        } else {
            self.eta.solve_started(seconds, ratio, base);
        }
        self.last = Progress {
            iterations,
            unshot_ratio: ratio,
            elements,
            links: self.links.get(),
            seconds,
            shot_receivers_done: 0,
            shot_receivers: 0,
            eta_seconds: self.eta.estimate(seconds, 0.0),
        };
        (self.observe)(&self.last);
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// A loop of `n` receivers of `each` each, counted as `shoot` counts them: a piece of the
    /// loop (two receivers here) adds its receivers at once.
    fn slow_loop(n: u64, each: Duration) -> impl FnOnce(&ShotCounter) + Send {
        move |done: &ShotCounter| {
            (0..n.div_ceil(2)).into_par_iter().for_each(|piece| {
                let receivers = (n - 2 * piece).min(2);
                std::thread::sleep(each * receivers as u32);
                done.add(ShotCounts {
                    receivers,
                    units: receivers,
                    ..ShotCounts::default()
                });
            });
        }
    }

    /// Pieces added at once sum as their receivers one by one would, field by field.
    #[test]
    fn pieces_add_up_as_their_receivers() {
        let (pieces, one_by_one) = (ShotCounter::default(), ShotCounter::default());
        let receivers: Vec<(u64, u64, u64)> = (0..37).map(|i| (i * 3, i % 5, i * i)).collect();
        for chunk in receivers.chunks(8) {
            let mut sum = ShotCounts::default();
            for &(u, e, r) in chunk {
                sum.receiver(u, e, r);
                one_by_one.finished(u, e, r);
            }
            pieces.add(sum);
        }
        assert_eq!(pieces.load(), one_by_one.load());
        assert_eq!(pieces.load().receivers, 37);
    }

    /// Receivers done one after the other (a loop that lasts `n * each` on any number of cores).
    fn serial_loop(n: u64, each: Duration) -> impl FnOnce(&ShotCounter) + Send {
        move |done: &ShotCounter| {
            for _ in 0..n {
                std::thread::sleep(each);
                done.finished(1, 0, 0);
            }
        }
    }

    #[test]
    fn a_long_loop_reports_its_count_from_the_calling_thread() {
        let caller = std::thread::current().id();
        let mut reports = Vec::new();
        let t = Instant::now();
        with_reports(serial_loop(40, Duration::from_millis(30)), &mut |c| {
            assert_eq!(std::thread::current().id(), caller);
            assert_eq!(c.units, c.receivers);
            reports.push((t.elapsed(), c.receivers));
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
        let mut counted = 0;
        with_reports(
            |d: &ShotCounter| {
                slow_loop(5, Duration::ZERO)(d);
                counted = d.load().receivers;
            },
            &mut |_| reports += 1,
        );
        assert_eq!((reports, counted), (0, 5));
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
            with_reports(
                |d| {
                    d.finished(1, 0, 0);
                    n = d.load().receivers;
                },
                &mut |_| {},
            );
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

    /// Cost units add up to the fraction of the weights done.
    #[test]
    fn cost_units_count_the_fraction_of_the_weights() {
        let weights = [1.0, 3.0, 1e5, 0.5];
        let units = CostUnits::new(weights.iter().sum());
        let done: u64 = weights[..2].iter().map(|&w| units.of(w)).sum();
        let want = 4.0 / weights.iter().sum::<f64>();
        assert!((CostUnits::fraction(done) - want).abs() < 1e-9);
        let all: u64 = weights.iter().map(|&w| units.of(w)).sum();
        assert!((CostUnits::fraction(all) - 1.0).abs() < 1e-9);
        assert_eq!(CostUnits::new(0.0).of(1.0), 0);
    }
}
