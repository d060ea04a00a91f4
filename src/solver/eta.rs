//! The estimate of the seconds left in a solve, which the CLI and the service both show.
//!
//! Owns [`EtaEstimator`], fed by the reporter (`progress.rs`) with the clock, each shot's
//! [`ShotPlan`] and the unshot ratio after it; and the cost model it assumes (its doc). The
//! indirect shots' evidence and the model read off it live in `history.rs`.
//!
//! Invariants: an estimate is never negative, is capped by what is left of the time budget, and
//! is 0 once the target is reached; nothing before the first report (`tests::eta_*`).

use super::indirect_forecast::CostCurve;
use history::{IndirectHistory, WINDOW_NATS};

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

/// A shot about to start, for the ETA: its kind, the power it sends, and how much of that is
/// expected back as unshot power (what the receivers would reflect of it with no occluder).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ShotPlan {
    pub kind: ShotKind,
    /// Power sent, W (mean of the channels).
    pub power: f64,
    /// Power expected back as unshot radiosity, W (an over-estimate where the shooter is
    /// occluded).
    pub returns: f64,
}

/// The largest share of the power shot that is taken to come back unshot, bounce after bounce
/// (a closed room of reflectance 0.95): bounds the geometric series of the model.
const MAX_RETURN: f64 = 0.95;
/// Indirect shots finished, and nats shed ([`WINDOW_NATS`]), before their history alone is used
/// (before it, the prior less the seconds since counts too, when there was a direct phase).
const MIN_SHOTS: usize = 2;
/// The share of the foreseen indirect cost (`indirect_forecast.rs`) the indirect shots must
/// have spent before their seconds weigh as much as the prior's in the price of what is left.
const CURVE_TRUST: f64 = 0.3;
/// Rays the direct phase must have traced before its seconds per ray price the foreseen cost
/// (the first rays of a shot come with its set-up, and would make the first reports jump).
const MIN_PRICED_RAYS: f64 = 1e4;

/// Estimates the seconds left in a solve from what the solver knows: the clock, the shot in
/// progress (its plan, its seconds so far, the fraction of its cost done and what its receivers
/// done got against what was expected of them), the seconds and power of the light and direct
/// shots, and the indirect shots since (their seconds and the unshot ratio after them).
///
/// The model (`tests::eta_*` pin it on synthetic solves): a shot's seconds grow with the power
/// it sends (its links with the power its receivers get over the threshold, under soft shadows),
/// and the power the shots send falls with the unshot power.
/// - A shot in progress ends after `s (1 - f) / f` more seconds, `s` its seconds so far and `f`
///   the fraction of its cost done (`s` again while nothing is); a receiver's cost is weighed
///   as `1 +` a power below 1 of what it would receive with no occluder over the threshold
///   (`pass.rs`, `receiver_cost_weight`).
/// - While lights and emitters shoot (the first shot of a sky panel can be most of a solve), the
///   shots of their kind still queued are taken to be like this one, and what follows is the
///   *prior*: the indirect phase's foreseen cost (`indirect_forecast.rs`, in rays) at the
///   direct phase's seconds per ray (`eta_prior_counts_the_cost_of_a_large_scene`). With
///   nothing foreseen, the direct phase's seconds per W times the power the indirect shots will
///   send, `(U - U_target) / (1 - k)`: `U` what the phase leaves unshot (the plans' `returns`
///   scaled by what the receivers done so far got of theirs, until it is done; then the real
///   one), and `k = U / P`, `P` the power it sent, the share taken to come back at every bounce
///   (at most [`MAX_RETURN`]); under a sky a fraction of the direct phase, in a closed room a
///   multiple (`tests::eta_prior_*`).
/// - Then, along the foreseen cost curve: the cost from the nats shed so far to the target, at
///   a price per ray that starts at the prior's and moves to the indirect shots' own (their
///   seconds over the cost of the nats they shed), weighing as much as the prior's once that
///   cost is [`CURVE_TRUST`] of the whole. The curve's shape carries the price to the target: seconds per nat that rise as
///   the power spreads over more roots (`eta_follows_a_cost_per_nat_that_rises_as_foreseen`).
/// - With nothing foreseen, the indirect shots are the evidence: with `u` the nats of unshot
///   ratio shed since the
///   direct phase, the seconds per nat are those of the last [`WINDOW_NATS`] of the history
///   (taken at its middle), falling like `exp(-beta u)`, `beta` the slope of ln seconds per nat
///   against `u` over the history, shrunk towards a prior decay as far as its steps scatter
///   (0.35 before three steps; `history.rs`), within [0, 1]: 0 is a ratio falling
///   exponentially in time, 1 seconds per nat falling like the unshot power. Not the shots'
///   seconds against their power: under a sky later shots are cheaper but each sheds fewer
///   nats, the unshot power being spread over more roots, and their seconds per nat hold
///   (`eta_follows_cheaper_shots_that_shed_fewer_nats`). Until the history spans the window (and
///   [`MIN_SHOTS`]), the prior less the seconds since, the evidence weighing in as the window
///   fills. The seconds left are the
///   integral down to the target, less the seconds of the shot in progress (at least its rest).
/// - A shot's rest: `s (1 - f) / f` more seconds, `s` its seconds so far, `f` the share of its
///   cost done or of its receivers done, whichever leaves more.
/// - Capped by what is left of the time budget, 0 once the target is reached.
#[derive(Debug, Clone)]
pub(super) struct EtaEstimator {
    target_ln: f64,
    max_seconds: Option<f64>,
    /// ln of the unshot ratio after the last finished shot (its running minimum since the base
    /// last changed); `None` before the first report.
    y: Option<f64>,
    /// What the ratio is taken against at the last report, W.
    base: f64,
    /// When the last shot finished.
    t_last: f64,
    /// The light and direct shots finished: their seconds, power sent and returns.
    direct: Phase,
    /// The shot in progress: when it began, and its plan.
    shot: Option<(f64, ShotPlan)>,
    /// For the shot in progress, what its receivers done got of what was expected of them.
    seen: Option<f64>,
    /// For the shot in progress, the share of its receivers done.
    receivers_done: f64,
    /// The indirect shots since the last direct shot.
    history: IndirectHistory,
    /// The indirect phase's cost foreseen (`indirect_forecast.rs`; empty until foreseen).
    foreseen: CostCurve,
    /// Rays traced by the solve at the last count, and at the start of the shot in progress.
    rays: u64,
    shot_rays: u64,
}

/// Seconds, power sent, returns (W) and rays traced of light and direct shots.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Phase {
    seconds: f64,
    power: f64,
    returns: f64,
    rays: f64,
}

impl Phase {
    /// The phase with `times` more shots of `seconds`, `power` W sent, `returns` W back and
    /// `rays` traced.
    fn add(self, seconds: f64, power: f64, returns: f64, rays: f64, times: f64) -> Phase {
        Phase {
            seconds: self.seconds + seconds * times,
            power: self.power + power * times,
            returns: self.returns + returns * times,
            rays: self.rays + rays * times,
        }
    }

    /// The phase's seconds per ray; none before it traced [`MIN_PRICED_RAYS`].
    fn seconds_per_ray(&self) -> Option<f64> {
        (self.rays >= MIN_PRICED_RAYS).then(|| self.seconds / self.rays)
    }

    /// Seconds of a cost of `rays` rays, at the phase's seconds per ray; 0 before it is priced.
    fn cost_seconds(&self, rays: f64) -> f64 {
        self.seconds_per_ray().map_or(0.0, |s| rays * s)
    }

    /// Seconds of the indirect shots after this phase, `unshot` W left unshot by it, `target` W
    /// the unshot power to reach (the model's prior).
    fn prior(&self, unshot: f64, target: f64) -> Option<f64> {
        if self.seconds <= 0.0 || self.power <= 0.0 {
            return None;
        }
        let back = (unshot / self.power).clamp(0.0, MAX_RETURN);
        Some(self.seconds / self.power * (unshot - target).max(0.0) / (1.0 - back))
    }
}

impl EtaEstimator {
    pub(super) fn new(target: f64, max_seconds: Option<f64>) -> Self {
        EtaEstimator {
            target_ln: target.ln(),
            max_seconds,
            y: None,
            base: 0.0,
            t_last: 0.0,
            direct: Phase::default(),
            shot: None,
            seen: None,
            receivers_done: 0.0,
            history: IndirectHistory::default(),
            foreseen: CostCurve::default(),
            rays: 0,
            shot_rays: 0,
        }
    }

    /// The solve has traced `rays` rays so far (the count never decreases).
    pub(super) fn rays_traced(&mut self, rays: u64) {
        self.rays = self.rays.max(rays);
    }

    /// The indirect phase is foreseen to cost `cost`: its seconds are the prior (the power's
    /// only while it prices nothing), and its shape carries the indirect shots' seconds to the
    /// target.
    pub(super) fn indirect_cost_foreseen(&mut self, cost: CostCurve) {
        self.foreseen = cost;
    }

    /// The first report: the unshot ratio `ratio` of `base` W at `now`, before any shot of the
    /// loop.
    pub(super) fn solve_started(&mut self, now: f64, ratio: f64, base: f64) {
        self.t_last = now;
        self.y = Some(ln_ratio(ratio));
        self.base = base;
    }

    pub(super) fn shot_started(&mut self, now: f64, plan: ShotPlan) {
        self.shot = Some((now, plan));
        self.seen = None;
        self.receivers_done = 0.0;
        self.shot_rays = self.rays;
    }

    /// The receivers of the shot in progress done so far got `ratio` times the returns expected
    /// of them.
    pub(super) fn returns_seen(&mut self, ratio: f64) {
        self.seen = ratio.is_finite().then_some(ratio.max(0.0));
    }

    /// The shot in progress has done `share` of its receivers.
    pub(super) fn receivers_done(&mut self, share: f64) {
        if share.is_finite() {
            self.receivers_done = share.clamp(0.0, 1.0);
        }
    }

    /// The shot in progress ended at `now`, leaving `ratio` of `base` W unshot.
    pub(super) fn shot_finished(&mut self, now: f64, ratio: f64, base: f64) {
        let y = ln_ratio(ratio);
        // A new base (the direct phase ended) starts a new running minimum.
        let before = if base == self.base {
            self.y.unwrap_or(y)
        } else {
            y
        };
        let y = y.min(before);
        match self.shot.take() {
            Some((start, plan)) if plan.kind != ShotKind::Indirect => {
                let returns = plan.returns * self.seen.unwrap_or(1.0);
                let rays = self.rays_of_shot();
                self.direct = self.direct.add(now - start, plan.power, returns, rays, 1.0);
                self.history.clear();
            }
            Some(_) => self.history.shot_finished(self.t_last, before, now, y),
            None => {}
        }
        self.seen = None;
        self.t_last = now;
        self.y = Some(y);
        self.base = base;
    }

    /// Seconds left at `now`, `fraction` of the cost of the shot in progress done.
    pub(super) fn estimate(&self, now: f64, fraction: f64) -> Option<f64> {
        let y = self.y?;
        let budget = self.max_seconds.map(|m| (m - now).max(0.0));
        let left = (y - self.target_ln).max(0.0);
        let eta = match self.shot {
            None if left <= 0.0 => Some(0.0),
            None => self.after_direct(left),
            Some((start, plan)) => {
                let seconds = (now - start).max(0.0);
                // The larger of what the cost done and the receivers done say is left: the
                // weights follow the power received, and a sky's most exposed receivers are
                // not its slowest (`eta_of_a_direct_shot_in_progress`).
                let rest = rest_of_shot(seconds, fraction).max(if self.receivers_done > 0.0 {
                    rest_of_shot(seconds, self.receivers_done)
                } else {
                    0.0
                });
                match plan.kind {
                    ShotKind::Light { left: queued } | ShotKind::Direct { left: queued } => {
                        let shot = seconds + rest;
                        let returns = plan.returns * self.seen.unwrap_or(1.0);
                        let phase =
                            self.direct
                                .add(shot, plan.power, returns, 0.0, 1.0 + queued as f64);
                        // What the phase leaves unshot is not known before it ends: the
                        // returns stand for it (the target is far below).
                        let by_power = phase.prior(phase.returns, 0.0).unwrap_or(0.0);
                        // Seconds per ray so far, this shot's included.
                        let so_far = self.direct.add(seconds, 0.0, 0.0, self.rays_of_shot(), 1.0);
                        let by_cost = so_far.cost_seconds(self.foreseen.total());
                        let after = if by_cost > 0.0 { by_cost } else { by_power };
                        Some(rest + queued as f64 * shot + after)
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
        let Some((elapsed, span)) = self.history.span() else {
            return self.direct_prior(self.y?);
        };
        if !self.foreseen.is_empty() {
            return self.along_the_curve(elapsed, span, left);
        }
        let model = self.history.model(left);
        let enough_shots = self.history.shots() >= MIN_SHOTS;
        // Until the history fills its window it says little (the first shots, of the most
        // concentrated power, shed nats fastest): at least what the direct phase suggested.
        let Some(prior) = self.direct_prior(self.history.y_start()) else {
            return if enough_shots { model } else { None };
        };
        // The evidence weighs in as the window fills.
        let w = (span / WINDOW_NATS).clamp(0.0, 1.0);
        if enough_shots && w >= 1.0 {
            return model;
        }
        let rest = (prior - elapsed).max(0.0);
        match model {
            Some(m) if enough_shots => Some((1.0 - w) * rest + w * m),
            _ => Some(rest),
        }
    }

    /// Seconds left along the foreseen cost curve, the indirect shots having shed `span` nats in
    /// `elapsed` seconds and `left` nats to go: the curve's cost from here to the target at a
    /// price per ray that starts at the prior's and moves to what the shots so far paid as
    /// their share of the curve grows ([`CURVE_TRUST`]).
    fn along_the_curve(&self, elapsed: f64, span: f64, left: f64) -> Option<f64> {
        let prior = || self.direct_prior(self.history.y_start());
        let curve = &self.foreseen;
        let whole = curve.at(span + left);
        if whole <= 0.0 {
            return prior().map(|p| (p - elapsed).max(0.0));
        }
        let done = curve.at(span);
        // The prior's price: the direct phase's per ray; when it priced no ray, the power
        // prior spread over the curve; with neither, the shots' own price alone.
        let prior_price = self
            .direct
            .seconds_per_ray()
            .or_else(|| prior().map(|p| p / whole));
        let trust = if prior_price.is_some() {
            CURVE_TRUST * whole
        } else {
            0.0
        };
        if trust + done <= 0.0 {
            return None;
        }
        let price = (prior_price.unwrap_or(0.0) * trust + elapsed) / (trust + done);
        Some(price * (whole - done))
    }

    /// Rays traced since the shot in progress (or the last one) began.
    fn rays_of_shot(&self) -> f64 {
        self.rays.saturating_sub(self.shot_rays) as f64
    }

    /// The prior from the end of the direct phase, which left ln ratio `y` of the base unshot:
    /// the foreseen cost to the target at the phase's seconds per ray; the phase's seconds per
    /// W times the power left to send when nothing is foreseen (or nothing priced yet).
    fn direct_prior(&self, y: f64) -> Option<f64> {
        let nats = (y - self.target_ln).max(0.0);
        let by_cost = self.direct.cost_seconds(self.foreseen.at(nats));
        if by_cost > 0.0 {
            return Some(by_cost);
        }
        let unshot = y.exp() * self.base;
        self.direct.prior(unshot, self.target_ln.exp() * self.base)
    }
}

/// Seconds left in a shot `seconds` old with `fraction` of its cost done.
fn rest_of_shot(seconds: f64, fraction: f64) -> f64 {
    if fraction > 0.0 {
        seconds * (1.0 - fraction.min(1.0)) / fraction
    } else {
        seconds
    }
}

/// ln of an unshot ratio (a ratio of 0, nothing emitted, is as good as any target).
fn ln_ratio(ratio: f64) -> f64 {
    ratio.max(1e-300).ln()
}

mod history;
#[cfg(test)]
mod tests;
