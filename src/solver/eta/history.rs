//! The indirect shots' evidence for the ETA: when each shot since the direct phase ended
//! finished and the nats of unshot ratio shed by then, and the seconds to the target read off them.
//!
//! Owns [`IndirectHistory`]. Invariants: its points' seconds and nats never decrease, the first at
//! the direct phase's end; a point is added only when the nats moved by [`HISTORY_STEP`], so its
//! length is bounded by the nats from the start to the target, not by the shots
//! (`tests::the_history_grows_with_the_nats_not_the_shots`).

/// The seconds per nat are counted over the last this many nats of the history.
pub(super) const WINDOW_NATS: f64 = 1.0;
/// Steps of the history, and nats they span, before its decay is fitted
/// ([`IndirectHistory::decay`]).
const MIN_DECAY_STEPS: usize = 3;
const MIN_DECAY_SPAN: f64 = 0.05;
/// The decay taken before the history says otherwise ([`IndirectHistory::decay`]): the seconds
/// per nat halving every two nats. Fitted on half-nat bins of whole indirect phases, the scaling
/// ladder's cities give 0 to 0.35, the Red Eclipse level 0.27, the Kenney building 0.4 and the
/// Cornell box 0.8 (docs/performance-notes.md, "The ETA's decay prior").
const DECAY_PRIOR: f64 = 0.35;
/// How far from [`DECAY_PRIOR`] a history's decay is taken to be, a priori.
const DECAY_PRIOR_SD: f64 = 0.1;
/// Nats of progress below which a shot updates the last point of the history instead of adding
/// one.
const HISTORY_STEP: f64 = 1e-3;

/// The indirect shots since the direct phase ended.
#[derive(Debug, Clone, Default)]
pub(super) struct IndirectHistory {
    /// (seconds, nats shed since the first point); empty before the first indirect shot ends.
    points: Vec<(f64, f64)>,
    /// ln of the unshot ratio at the first point.
    y_start: f64,
    /// Indirect shots finished.
    shots: usize,
}

impl IndirectHistory {
    /// A direct shot ended: the indirect phase starts again after it.
    pub(super) fn clear(&mut self) {
        self.points.clear();
        self.shots = 0;
    }

    /// An indirect shot ended at `now` leaving ln ratio `y` (never above `before`); the shot
    /// before it ended at `t_last` leaving ln ratio `before`.
    pub(super) fn shot_finished(&mut self, t_last: f64, before: f64, now: f64, y: f64) {
        debug_assert!(y <= before);
        if self.points.is_empty() {
            self.points.push((t_last, 0.0));
            self.y_start = before;
        }
        self.shots += 1;
        let u = self.y_start - y;
        let n = self.points.len();
        if n >= 2 && u - self.points[n - 2].1 < HISTORY_STEP {
            self.points[n - 1] = (now, u);
        } else {
            self.points.push((now, u));
        }
    }

    /// Indirect shots finished.
    pub(super) fn shots(&self) -> usize {
        self.shots
    }

    /// ln of the unshot ratio at the direct phase's end (when the first point was taken).
    pub(super) fn y_start(&self) -> f64 {
        self.y_start
    }

    /// The seconds and the nats the history spans; `None` before its first shot.
    pub(super) fn span(&self) -> Option<(f64, f64)> {
        let (&(t0, _), &(tn, un)) = (self.points.first()?, self.points.last()?);
        Some((tn - t0, un))
    }

    /// Seconds from the last point to the target, `left` nats away: the seconds per nat of the
    /// last [`WINDOW_NATS`] of the history (taken at its middle), falling like `exp(-beta u)`
    /// from there, `beta` the [`IndirectHistory::decay`].
    pub(super) fn model(&self, left: f64) -> Option<f64> {
        let &(tn, span) = self.points.last()?;
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
    /// shrunk towards [`DECAY_PRIOR`] as far as the steps scatter about their line, within
    /// [0, 1]; [`DECAY_PRIOR`] until [`MIN_DECAY_STEPS`] steps span [`MIN_DECAY_SPAN`] nats.
    ///
    /// The shrinkage is the posterior mean of the slope under a normal prior
    /// `N(DECAY_PRIOR, DECAY_PRIOR_SD^2)`, the noise read off the residuals: steps that lie on
    /// a line give its slope, whatever the prior (`tests::the_decay_is_fitted_on_the_seconds_per_nat`);
    /// a few scattered shots, whose first nats are shed fastest, do not make a falling cost look
    /// flat (`tests::a_scattered_history_keeps_the_decay_of_the_prior`).
    fn decay(&self) -> f64 {
        let steps = || {
            self.points.windows(2).filter_map(|w| {
                let ((ta, ua), (tb, ub)) = (w[0], w[1]);
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
            return DECAY_PRIOR;
        }
        let (mx, my) = (wx / w, wy / w);
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for (x, y, dw) in steps() {
            sxx += dw * (x - mx) * (x - mx);
            sxy += dw * (x - mx) * (y - my);
        }
        if sxx <= 1e-12 * w {
            return DECAY_PRIOR;
        }
        let fitted = -sxy / sxx;
        // The noise of a step of unit weight (the slope's variance is that over sxx).
        let residuals: f64 = steps()
            .map(|(x, y, dw)| dw * ((y - my) + fitted * (x - mx)).powi(2))
            .sum();
        let noise = residuals / (n - 2) as f64;
        let k = noise / (DECAY_PRIOR_SD * DECAY_PRIOR_SD);
        ((sxx * fitted + k * DECAY_PRIOR) / (sxx + k)).clamp(0.0, 1.0)
    }

    /// Seconds at which the history had shed `u` nats (linear between its points).
    fn time_at(&self, u: f64) -> f64 {
        let h = &self.points;
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

/// `integral_0^x exp(-beta v) dv`.
fn nats_integral(beta: f64, x: f64) -> f64 {
    if beta.abs() < 1e-9 {
        x
    } else {
        -(-beta * x).exp_m1() / beta
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The decay is minus the slope of ln seconds per nat against the nats shed, within [0, 1],
    /// and the prior's until three steps: seconds per nat halving every nat (on its line) is
    /// ln 2; growing is 0.
    #[test]
    fn the_decay_is_fitted_on_the_seconds_per_nat() {
        let fitted = |points: &[(f64, f64)]| {
            let h = IndirectHistory {
                points: points.to_vec(),
                ..IndirectHistory::default()
            };
            h.decay()
        };
        // Seconds per nat 2^-u: t(u) = (1 - 2^-u) / ln 2.
        let halving: Vec<(f64, f64)> = (0..=40)
            .map(|i| {
                let u = i as f64 * 0.1;
                ((1.0 - 0.5f64.powf(u)) / 2f64.ln(), u)
            })
            .collect();
        let beta = fitted(&halving);
        assert!((beta - 2f64.ln()).abs() < 1e-3, "{beta}");
        assert_eq!(fitted(&halving[..3]), DECAY_PRIOR, "two steps are too few");
        let steady: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, i as f64 * 0.3)).collect();
        assert!(fitted(&steady).abs() < 1e-12);
        let slowing: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, (i as f64).sqrt())).collect();
        assert_eq!(fitted(&slowing), 0.0);
    }

    /// A history whose seconds per nat fall like the prior's decay but scatter about it, its
    /// first half nat shed four times faster (the most concentrated power shot first, as on
    /// the Red Eclipse level): the plain least-squares slope is below 0.1, the shrunk
    /// decay stays near the prior's; the same steps on their line give their own slope.
    #[test]
    fn a_scattered_history_keeps_the_decay_of_the_prior() {
        let rate = |i: usize, u: f64| {
            let scatter = if u < 0.5 {
                0.25
            } else if i.is_multiple_of(2) {
                2.0
            } else {
                0.5
            };
            (-DECAY_PRIOR * u).exp() * scatter
        };
        let history = |rate: &dyn Fn(usize, f64) -> f64| {
            let (mut t, mut points) = (0.0, vec![(0.0, 0.0)]);
            for i in 0..30 {
                let (u, du) = (i as f64 * 0.1, 0.1);
                t += rate(i, u + 0.5 * du) * du;
                points.push((t, u + du));
            }
            IndirectHistory {
                points,
                ..IndirectHistory::default()
            }
        };
        let scattered = history(&rate);
        // The plain slope of ln(dt / du) against u, every step of equal weight.
        let steps: Vec<(f64, f64)> = scattered
            .points
            .windows(2)
            .map(|w| (0.5 * (w[0].1 + w[1].1), ((w[1].0 - w[0].0) / 0.1f64).ln()))
            .collect();
        let n = steps.len() as f64;
        let (mx, my) = steps
            .iter()
            .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
        let sxy: f64 = steps.iter().map(|&(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = steps.iter().map(|&(x, _)| (x - mx) * (x - mx)).sum();
        let plain = -sxy / sxx;
        assert!(plain < 0.1, "plain slope {plain}");
        let beta = scattered.decay();
        assert!(
            (beta - DECAY_PRIOR).abs() < 0.15 && beta > plain + 0.15,
            "{beta} against {plain}"
        );
        // On its line, a decay of 0.8 is fitted as 0.8.
        let clean = history(&|_, u| (-0.8 * u).exp());
        assert!((clean.decay() - 0.8).abs() < 1e-3, "{}", clean.decay());
    }

    /// Shots that shed less than [`HISTORY_STEP`] each move the last point instead of adding
    /// one: 10 000 shots over 2 nats leave about 2 / step points, and the span is exact.
    #[test]
    fn the_history_grows_with_the_nats_not_the_shots() {
        let mut h = IndirectHistory::default();
        let (shots, nats) = (10_000, 2.0);
        let mut y = -1.0;
        for k in 0..shots {
            let next = y - nats / shots as f64;
            h.shot_finished(k as f64, y, k as f64 + 1.0, next);
            y = next;
        }
        assert_eq!(h.shots(), shots);
        assert!(
            h.points.len() <= (nats / HISTORY_STEP) as usize + 2,
            "{}",
            h.points.len()
        );
        let (seconds, span) = h.span().expect("shots recorded");
        assert_eq!(seconds, shots as f64);
        assert!((span - nats).abs() < 1e-9);
        assert_eq!(h.y_start(), -1.0);
    }

    /// `integral_0^x exp(-beta v) dv` against its closed form and its limit at beta 0.
    #[test]
    fn nats_integral_is_the_exponential_integral() {
        assert_eq!(nats_integral(0.0, 3.0), 3.0);
        let (b, x) = (0.7f64, 2.5f64);
        assert!((nats_integral(b, x) - (1.0 - (-b * x).exp()) / b).abs() < 1e-12);
    }
}
