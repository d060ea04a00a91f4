//! The estimate of the seconds left in a solve, which the CLI and the service both show.
//!
//! Owns [`EtaEstimator`], fed by the reporter (`progress.rs`) with the clock, each shot's
//! [`ShotPlan`] and the unshot ratio after it; and the cost model it assumes (its doc).
//!
//! Invariants: an estimate is never negative, is capped by what is left of the time budget, and
//! is 0 once the target is reached; nothing before the first report (`tests::eta_*`).

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
/// The shots per nat are counted over the last this many nats of the history.
const WINDOW_NATS: f64 = 1.0;
/// The share of the prior's seconds that must pass before the indirect shots' evidence replaces
/// its far-field part (their first nats, the hot spots of the direct light draining, are the
/// fastest of the phase).
const PRIOR_TRUST: f64 = 0.25;
/// Steps of the history, and nats they span, before its decay is fitted ([`EtaEstimator::decay`]).
const MIN_DECAY_STEPS: usize = 3;
const MIN_DECAY_SPAN: f64 = 0.05;
/// Nats of progress below which a shot updates the last point of the history instead of adding
/// one (bounds the history by the nats from the start to the target, not by the shots).
const HISTORY_STEP: f64 = 1e-3;
/// What one far-field receiver visit of an indirect shot costs, in rays of the direct phase (its
/// seconds over the rays it traced, so the machine and its load are the phase's): a visit is one
/// ray, one exact form factor, a constant added to the receiver's tree and its unshot power
/// recomputed, besides the shot's share of checks (docs/performance-notes.md, "The ETA's
/// prior counts the far field").
const FAR_VISIT_RAYS: f64 = 20.0;
/// Rays the direct phase must have traced before its seconds per ray price the far-field visits
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
///   as `1 +` what it would receive with no occluder over the threshold (`shooting.rs`).
/// - While lights and emitters shoot (the first shot of a sky panel can be most of a solve), the
///   shots of their kind still queued are taken to be like this one, and what follows is the
///   *prior*: the direct phase's seconds per W sent, times the power the indirect shots will
///   send, `(U - U_target) / (1 - k)`: `U` what the phase leaves unshot (the plans' `returns`
///   scaled by what the receivers done so far got of theirs, until it is done; then the real
///   one), and `k = U / P`, `P` the power it sent, the share taken to come back at every bounce
///   (at most [`MAX_RETURN`]). Under a sky most of the power leaves, `k` is small and the prior a
///   fraction of the direct phase; in a closed room it is a multiple (`tests::eta_prior_*`).
///   To that the prior adds the far-field visits the indirect phase is foreseen to make
///   (`indirect_forecast.rs`: one per root a shot reaches in its far field, whatever the power:
///   the term that grows like the roots squared), [`FAR_VISIT_RAYS`] each at the direct phase's
///   seconds per ray (`eta_prior_counts_the_far_field_of_a_large_scene`).
/// - Then the indirect shots are the evidence: with `u` the nats of unshot ratio shed since the
///   direct phase, the seconds per nat are those of the last [`WINDOW_NATS`] of the history
///   (taken at its middle), falling like `exp(-beta u)`, `beta` the slope of ln seconds per nat
///   against `u` over the history ([`EtaEstimator::decay`]), within [0, 1]: 0 is a ratio falling
///   exponentially in time, 1 seconds per nat falling like the unshot power. Not the shots'
///   seconds against their power: under a sky later shots are cheaper but each sheds fewer
///   nats, the unshot power being spread over more roots, and their seconds per nat hold
///   (`eta_follows_cheaper_shots_that_shed_fewer_nats`). Until the history spans the window (and
///   [`MIN_SHOTS`]), the prior less the seconds since, the evidence weighing in as the window
///   fills. The seconds left are the
///   integral down to the target, less the seconds of the shot in progress (at least what its
///   cost done says is left of it).
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
    /// Since the last direct shot: (seconds, nats shed since then, indirect shots), the first
    /// point at its end; the nats never decrease.
    history: Vec<(f64, f64, f64)>,
    /// ln of the unshot ratio at the first point of `history`.
    y_phase: f64,
    /// Indirect shots finished.
    indirect_shots: usize,
    /// The far-field receiver visits the indirect phase is foreseen to make
    /// (`indirect_forecast.rs`; 0 until foreseen).
    far_visits: f64,
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

    /// Seconds of `visits` far-field receiver visits, at the phase's seconds per ray
    /// ([`FAR_VISIT_RAYS`] each); 0 before it traced [`MIN_PRICED_RAYS`].
    fn far_seconds(&self, visits: f64) -> f64 {
        if self.rays >= MIN_PRICED_RAYS {
            visits * FAR_VISIT_RAYS * self.seconds / self.rays
        } else {
            0.0
        }
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
            history: Vec::new(),
            y_phase: 0.0,
            indirect_shots: 0,
            far_visits: 0.0,
            rays: 0,
            shot_rays: 0,
        }
    }

    /// The solve has traced `rays` rays so far (the count never decreases).
    pub(super) fn rays_traced(&mut self, rays: u64) {
        self.rays = self.rays.max(rays);
    }

    /// The indirect phase is foreseen to make `visits` far-field receiver visits: their seconds
    /// join the prior.
    pub(super) fn far_visits_foreseen(&mut self, visits: f64) {
        if visits.is_finite() {
            self.far_visits = visits.max(0.0);
        }
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
        self.shot_rays = self.rays;
    }

    /// The receivers of the shot in progress done so far got `ratio` times the returns expected
    /// of them.
    pub(super) fn returns_seen(&mut self, ratio: f64) {
        self.seen = ratio.is_finite().then_some(ratio.max(0.0));
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
                self.indirect_shots = 0;
            }
            Some(_) => {
                if self.history.is_empty() {
                    self.history.push((self.t_last, 0.0, 0.0));
                    self.y_phase = before;
                }
                self.indirect_shots += 1;
                let u = self.y_phase - y;
                let n = self.history.len();
                let point = (now, u, self.indirect_shots as f64);
                if n >= 2 && u - self.history[n - 2].1 < HISTORY_STEP {
                    self.history[n - 1] = point;
                } else {
                    self.history.push(point);
                }
            }
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
                let rest = rest_of_shot(seconds, fraction);
                match plan.kind {
                    ShotKind::Light { left: queued } | ShotKind::Direct { left: queued } => {
                        let shot = seconds + rest;
                        let returns = plan.returns * self.seen.unwrap_or(1.0);
                        let phase =
                            self.direct
                                .add(shot, plan.power, returns, 0.0, 1.0 + queued as f64);
                        // What the phase leaves unshot is not known before it ends: the
                        // returns stand for it (the target is far below).
                        let after = phase.prior(phase.returns, 0.0);
                        // Seconds per ray so far, this shot's included.
                        let so_far = self.direct.add(seconds, 0.0, 0.0, self.rays_of_shot(), 1.0);
                        let far = so_far.far_seconds(self.far_visits);
                        Some(rest + queued as f64 * shot + after.unwrap_or(0.0) + far)
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
        let (Some(&(t0, _, _)), Some(&(tn, span, _))) = (self.history.first(), self.history.last())
        else {
            return self.direct_prior(self.y?);
        };
        let model = self.indirect_model(left);
        let enough_shots = self.indirect_shots >= MIN_SHOTS;
        // Until the history fills its window it says little (the first shots, of the most
        // concentrated power, shed nats fastest): at least what the direct phase suggested.
        let Some((prior, far)) = self.direct_prior_parts(self.y_phase) else {
            return if enough_shots { model } else { None };
        };
        let elapsed = tn - t0;
        // The evidence weighs in as the window fills; the far-field part of the prior (foreseen
        // shot by shot, not taken from the power) only as the prior's seconds pass.
        let by_nats = (span / WINDOW_NATS).clamp(0.0, 1.0);
        let (by_time, far_share) = if prior > 0.0 {
            let by_time = (elapsed / (PRIOR_TRUST * prior)).clamp(0.0, 1.0);
            (by_time, (far / prior).clamp(0.0, 1.0))
        } else {
            (1.0, 0.0)
        };
        let w = (1.0 - far_share) * by_nats + far_share * by_nats.min(by_time);
        if enough_shots && w >= 1.0 {
            return model;
        }
        let rest = (prior - elapsed).max(0.0);
        match model {
            Some(m) if enough_shots => Some((1.0 - w) * rest + w * m),
            _ => Some(rest),
        }
    }

    /// Rays traced since the shot in progress (or the last one) began.
    fn rays_of_shot(&self) -> f64 {
        self.rays.saturating_sub(self.shot_rays) as f64
    }

    /// The prior from the end of the direct phase, which left ln ratio `y` of the base unshot.
    fn direct_prior(&self, y: f64) -> Option<f64> {
        self.direct_prior_parts(y).map(|(prior, _)| prior)
    }

    /// [`EtaEstimator::direct_prior`] and its far-field part.
    fn direct_prior_parts(&self, y: f64) -> Option<(f64, f64)> {
        let unshot = y.exp() * self.base;
        let power = self
            .direct
            .prior(unshot, self.target_ln.exp() * self.base)?;
        let far = self.direct.far_seconds(self.far_visits);
        Some((power + far, far))
    }

    /// The model on the indirect shots' evidence, `left` nats from the target: the seconds per
    /// nat of the last [`WINDOW_NATS`] of the history (taken at its middle), falling like
    /// `exp(-beta u)` from there, `beta` the [`EtaEstimator::decay`] of the history.
    fn indirect_model(&self, left: f64) -> Option<f64> {
        let &(tn, span, _) = self.history.last()?;
        if span <= 0.0 {
            return None;
        }
        let window = span.min(WINDOW_NATS);
        let g_window = (tn - self.time_at(span - window)) / window;
        if g_window.is_nan() || g_window <= 0.0 {
            return None;
        }
        let beta = self.decay();
        let g_now = g_window * (-beta * window / 2.0).exp();
        Some(g_now * nats_integral(beta, left))
    }

    /// How fast the seconds per nat fall with the nats shed: minus the slope of `ln(dt / du)`
    /// against `u` over the history's steps (least squares, each step weighted by its `du`),
    /// within [0, 1]; 0 until [`MIN_DECAY_STEPS`] steps span [`MIN_DECAY_SPAN`] nats
    /// (`the_decay_is_fitted_on_the_seconds_per_nat`).
    fn decay(&self) -> f64 {
        let steps = || {
            self.history.windows(2).filter_map(|w| {
                let ((ta, ua, _), (tb, ub, _)) = (w[0], w[1]);
                let (dt, du) = (tb - ta, ub - ua);
                (dt > 0.0 && du > 0.0).then(|| (0.5 * (ua + ub), (dt / du).ln(), du))
            })
        };
        let (mut n, mut w, mut wx, mut wy) = (0usize, 0.0, 0.0, 0.0);
        for (x, y, dw) in steps() {
            n += 1;
            w += dw;
            wx += dw * x;
            wy += dw * y;
        }
        if n < MIN_DECAY_STEPS || w < MIN_DECAY_SPAN {
            return 0.0;
        }
        let (mx, my) = (wx / w, wy / w);
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for (x, y, dw) in steps() {
            sxx += dw * (x - mx) * (x - mx);
            sxy += dw * (x - mx) * (y - my);
        }
        if sxx <= 1e-12 * w {
            return 0.0;
        }
        (-sxy / sxx).clamp(0.0, 1.0)
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
        let (ta, ua, _) = h[i - 1];
        let (tb, ub, _) = h[i];
        ta + (tb - ta) * (u - ua) / (ub - ua)
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

/// `integral_0^x exp(-beta v) dv`.
fn nats_integral(beta: f64, x: f64) -> f64 {
    if beta.abs() < 1e-9 {
        x
    } else {
        -(-beta * x).exp_m1() / beta
    }
}

/// ln of an unshot ratio (a ratio of 0, nothing emitted, is as good as any target).
fn ln_ratio(ratio: f64) -> f64 {
    ratio.max(1e-300).ln()
}

#[cfg(test)]
mod tests;
