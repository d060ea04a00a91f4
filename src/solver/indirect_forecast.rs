//! What the indirect phase will cost, foreseen from where the unshot power is before it starts:
//! the shots it will take and the far-field receiver visits they will make (the ETA's prior,
//! `eta.rs`).
//!
//! Owns [`forecast`] and the model it runs ([`shot_powers`]): progressive shooting of the root
//! with the most unshot power, each shot sending all of it and `back` of it coming back, spread
//! over the roots in proportion to their `share` (face area times reflectance), until the unshot
//! power falls to the target. Large scenes are simulated on a weighted sample of the roots that
//! hold or can receive power: the most powerful at weight 1, one root per stratum of the rest
//! standing for its stratum (a scene of `k` copies of a set of roots takes `k` times the shots of
//! the set).
//!
//! Invariants: the forecast is finite and non-negative and needs no randomness (strata of the
//! roots sorted by power, receivers by a fixed shuffle); the exchanges it asks for are bounded by
//! the sample sizes whatever the scene, its other work is a sort of the roots (`tests::*`).

/// Roots the model is simulated on, at most.
const MAX_SAMPLE: usize = 2048;
/// Of those, the roots of most unshot power, taken at weight 1 (power held by a few roots is
/// never left out of the strata).
const TOP_ROOTS: usize = 512;
/// Receivers each sampled shooter's visits are counted over, at most (scaled to the whole).
const MAX_RECEIVERS: usize = 256;
/// Receivers the share that comes back is summed over, at most (scaled to the whole; exact up to
/// this many roots).
const MAX_BACK_RECEIVERS: usize = 16384;
/// Shooters the share of a shot that comes back is measured on.
const BACK_SHOOTERS: usize = 24;
/// Fixes the receivers sampled.
const RECEIVER_SEED: u64 = 17;
/// Simulated shots per sampled root, at most (a closed room of reflectance 0.95 takes about 60
/// per root from 1 down to 1e-3).
const MAX_SHOTS_PER_ROOT: usize = 200;

/// The indirect phase foreseen: its shots and the receivers they visit in the far field (one ray
/// and one constant each: their cost does not grow with the power shot).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct IndirectForecast {
    pub shots: f64,
    pub far_visits: f64,
}

/// How shooter `s` and receiver `r` exchange light, when they face each other: the share of 1 W
/// sent by `s` that `r` sends back (its reflectance times what it would receive with no
/// occluder), and the bound on the share of what `s` sends that `r` can receive (which decides
/// whether `r` is in the shot's far field, `far_field.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Exchange {
    pub back: f64,
    pub transfer_bound: f64,
}

/// The roots as the forecast sees them.
pub(super) struct ForecastInput<'a> {
    /// Unshot power per root, W (mean of the channels).
    pub unshot: &'a [f64],
    /// Where reflected light lands, per root (any scale; face area times reflectance).
    pub share: &'a [f64],
    /// Per root, the power bound of a shot per W of it (an extended domain's area over its face's).
    pub bound_per_watt: &'a [f64],
    /// The unshot power to reach, W.
    pub target: f64,
    /// A receiver is in a shot's far field when the shot's power bound times its transfer bound is
    /// at most this, W.
    pub threshold: f64,
}

/// A root of the sample and how many roots it stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sampled {
    root: usize,
    weight: f64,
}

/// The indirect phase foreseen from `input`, `exchange(s, r)` telling how roots `s` and `r`
/// exchange light (`None` when they do not face each other).
pub(super) fn forecast(
    input: &ForecastInput,
    exchange: &dyn Fn(usize, usize) -> Option<Exchange>,
) -> IndirectForecast {
    let n = input.unshot.len();
    let total: f64 = input.unshot.iter().sum();
    if n == 0 || total <= input.target || !total.is_finite() {
        return IndirectForecast::default();
    }
    let back = {
        let receivers = receiver_sample(n, MAX_BACK_RECEIVERS);
        let scale = n as f64 / receivers.len() as f64;
        back_share(input.unshot, &receivers, scale, exchange)
    };
    let receivers = receiver_sample(n, MAX_RECEIVERS);
    let scale_receivers = n as f64 / receivers.len() as f64;
    let sample = weighted_sample(input.unshot, input.share);
    // Per sampled root, the transfer bounds of the receivers it faces (largest first).
    let bounds: Vec<Vec<f64>> = sample
        .iter()
        .map(|s| {
            let mut b: Vec<f64> = receivers
                .iter()
                .filter(|&&r| r != s.root)
                .filter_map(|&r| exchange(s.root, r))
                .map(|e| e.transfer_bound)
                .collect();
            b.sort_by(|x, y| y.total_cmp(x));
            b
        })
        .collect();
    let u: Vec<f64> = sample.iter().map(|s| input.unshot[s.root]).collect();
    let share: Vec<f64> = sample.iter().map(|s| input.share[s.root]).collect();
    let weight: Vec<f64> = sample.iter().map(|s| s.weight).collect();
    let sample_total: f64 = u.iter().zip(&weight).map(|(u, w)| u * w).sum();
    let target = input.target * sample_total / total;
    let mut out = IndirectForecast::default();
    for (k, power) in shot_powers(&u, &share, &weight, back, target) {
        let b = &bounds[k];
        let bound = power * input.bound_per_watt[sample[k].root];
        // Receivers whose transfer bound lets through more than the threshold are refined.
        let near = if bound > 0.0 {
            b.partition_point(|&t| t * bound > input.threshold)
        } else {
            0
        };
        out.shots += weight[k];
        out.far_visits += weight[k] * scale_receivers * (b.len() - near) as f64;
    }
    debug_assert!(out.shots.is_finite() && out.far_visits >= 0.0);
    out
}

/// The share of a shot's power that comes back as unshot power: over [`BACK_SHOOTERS`] shooters
/// taken in strata of the unshot power, what the sampled `receivers` (each standing for `scale`
/// roots) reflect of 1 W (at most 0.95).
fn back_share(
    unshot: &[f64],
    receivers: &[usize],
    scale: f64,
    exchange: &dyn Fn(usize, usize) -> Option<Exchange>,
) -> f64 {
    let shooters = strata_by_power(unshot, BACK_SHOOTERS);
    if shooters.is_empty() {
        return 0.0;
    }
    let sum: f64 = shooters
        .iter()
        .map(|&s| {
            receivers
                .iter()
                .filter(|&&r| r != s)
                .filter_map(|&r| exchange(s, r))
                .map(|e| e.back)
                .sum::<f64>()
        })
        .sum();
    (scale * sum / shooters.len() as f64).clamp(0.0, 0.95)
}

/// The model's shots: (sampled root, power sent per root it stands for) of each, in order, from
/// unshot powers `u` per root, entry `i` standing for `weight[i]` roots alike (shooting it shoots
/// them all), with `back` of every shot returning over the roots in proportion to `share`, until
/// the unshot power is at most `target`.
pub(super) fn shot_powers(
    u: &[f64],
    share: &[f64],
    weight: &[f64],
    back: f64,
    target: f64,
) -> Vec<(usize, f64)> {
    debug_assert!(u.len() == share.len() && u.len() == weight.len());
    let mut u = u.to_vec();
    // Where a W of returns lands, per root of each entry.
    let share_sum: f64 = share.iter().zip(weight).map(|(s, w)| s * w).sum();
    let weight_sum: f64 = weight.iter().sum();
    let share: Vec<f64> = if share_sum > 0.0 {
        share.iter().map(|s| s / share_sum).collect()
    } else {
        vec![1.0 / weight_sum.max(1.0); u.len()]
    };
    let mut total: f64 = u.iter().zip(weight).map(|(u, w)| u * w).sum();
    let mut shots = Vec::new();
    while total > target && shots.len() < MAX_SHOTS_PER_ROOT * u.len() {
        let Some((i, p)) = u
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        if p <= 0.0 {
            break;
        }
        u[i] = 0.0;
        let returned = back * p * weight[i];
        for (uj, sj) in u.iter_mut().zip(&share) {
            *uj += returned * sj;
        }
        total = u.iter().zip(weight).map(|(u, w)| u * w).sum();
        shots.push((i, p));
    }
    shots
}

/// The roots that hold or can receive power, at most [`MAX_SAMPLE`] of them: every one when
/// there are no more; else the [`TOP_ROOTS`] of most unshot power at weight 1, and one root per
/// stratum of the others sorted by power (largest first), standing for its stratum.
fn weighted_sample(unshot: &[f64], share: &[f64]) -> Vec<Sampled> {
    let mut order: Vec<usize> = (0..unshot.len())
        .filter(|&i| unshot[i] > 0.0 || share[i] > 0.0)
        .collect();
    let one = |root| Sampled { root, weight: 1.0 };
    if order.len() <= MAX_SAMPLE {
        return order.into_iter().map(one).collect();
    }
    order.sort_by(|&a, &b| unshot[b].total_cmp(&unshot[a]));
    let (top, rest) = order.split_at(TOP_ROOTS);
    let k = MAX_SAMPLE - TOP_ROOTS;
    let step = rest.len() as f64 / k as f64;
    let strata = (0..k).map(|j| Sampled {
        root: rest[((j as f64 + 0.5) * step) as usize],
        weight: step,
    });
    top.iter().copied().map(one).chain(strata).collect()
}

/// At most `m` indices of `0..n`, drawn by a fixed shuffle (evenly spaced ones would alias with
/// a scene's own period: a city's buildings are its roots in blocks).
fn receiver_sample(n: usize, m: usize) -> Vec<usize> {
    let mut all: Vec<usize> = (0..n).collect();
    if n > m {
        crate::shuffle::shuffle(&mut all, RECEIVER_SEED);
        all.truncate(m);
    }
    all
}

/// At most `m` roots, one at the middle of each of `m` equal strata of the total unshot power
/// (the roots sorted by power, largest first).
fn strata_by_power(unshot: &[f64], m: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..unshot.len()).filter(|&i| unshot[i] > 0.0).collect();
    order.sort_by(|&a, &b| unshot[b].total_cmp(&unshot[a]));
    let total: f64 = order.iter().map(|&i| unshot[i]).sum();
    let mut picked = Vec::new();
    let mut acc = 0.0;
    for &i in &order {
        acc += unshot[i];
        while picked.len() < m && acc >= (picked.len() as f64 + 0.5) / m as f64 * total {
            picked.push(i);
        }
    }
    picked
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// Nothing comes back: the shots are the roots in decreasing order of power until what is
    /// left is within the target.
    #[test]
    fn with_nothing_back_the_largest_roots_shoot_once() {
        let u = [1.0, 5.0, 3.0, 4.0, 2.0];
        let shots = shot_powers(&u, &[1.0; 5], &[1.0; 5], 0.0, 3.5);
        assert_eq!(shots, vec![(1, 5.0), (3, 4.0), (2, 3.0)]);
        assert!(shot_powers(&u, &[1.0; 5], &[1.0; 5], 0.0, 15.0).is_empty());
    }

    /// One root that gets back half of what it sends: it shoots until `0.5^k` is within the
    /// target, `k = ceil(ln(target) / ln(0.5))`, each shot half the last.
    #[test]
    fn what_comes_back_is_shot_again() {
        let shots = shot_powers(&[1.0], &[1.0], &[1.0], 0.5, 0.01);
        let k = (0.01f64.ln() / 0.5f64.ln()).ceil() as usize;
        assert_eq!(shots.len(), k);
        for (j, &(i, p)) in shots.iter().enumerate() {
            assert_eq!(i, 0);
            assert!((p - 0.5f64.powi(j as i32)).abs() < 1e-12);
        }
    }

    /// An entry of weight 2 shoots as two alike roots of weight 1 do: with nothing back, the same
    /// powers, each of its shots standing for two of theirs; with returns, about as many shots
    /// (its two roots shoot at once, so the second does not shoot the first's returns at once).
    #[test]
    fn a_weighted_entry_shoots_as_the_roots_it_stands_for() {
        let count =
            |shots: &[(usize, f64)], w: &[f64]| -> f64 { shots.iter().map(|&(i, _)| w[i]).sum() };
        let (u, share) = ([3.0, 1.0], [1.0, 2.0]);
        let (spelled_u, spelled_share) = ([3.0, 3.0, 1.0], [1.0, 1.0, 2.0]);
        let weighted = shot_powers(&u, &share, &[2.0, 1.0], 0.0, 1.5);
        assert_eq!(weighted, vec![(0, 3.0)]);
        let spelled = shot_powers(&spelled_u, &spelled_share, &[1.0; 3], 0.0, 1.5);
        let powers: Vec<f64> = spelled.iter().map(|&(_, p)| p).collect();
        assert_eq!(powers, vec![3.0, 3.0]);
        let weighted = shot_powers(&u, &share, &[2.0, 1.0], 0.6, 1e-3);
        let spelled = shot_powers(&spelled_u, &spelled_share, &[1.0; 3], 0.6, 1e-3);
        let ratio = count(&weighted, &[2.0, 1.0]) / spelled.len() as f64;
        assert!((ratio - 1.0).abs() < 0.1, "{weighted:?} {spelled:?}");
    }

    /// `copies` copies of five roots, each root facing the other roots of its copy (transfer
    /// bound `bound`, a tenth of every shot coming back from each), then `black` roots that
    /// neither hold nor take light; returns the forecast and the exchanges asked for.
    fn copies(
        copies: usize,
        black: usize,
        bound: f64,
        threshold: f64,
    ) -> (IndirectForecast, usize) {
        let set = [5.0, 4.0, 3.0, 2.0, 1.0];
        let lit = 5 * copies;
        let n = lit + black;
        let unshot: Vec<f64> = (0..n)
            .map(|i| if i < lit { set[i % 5] } else { 0.0 })
            .collect();
        let share: Vec<f64> = (0..n).map(|i| if i < lit { 1.0 } else { 0.0 }).collect();
        let bound_per_watt = vec![1.0; n];
        let input = ForecastInput {
            unshot: &unshot,
            share: &share,
            bound_per_watt: &bound_per_watt,
            target: 1e-3 * 15.0 * copies as f64,
            threshold,
        };
        let calls = Cell::new(0);
        let f = forecast(&input, &|s, r| {
            calls.set(calls.get() + 1);
            (s < lit && r < lit && s / 5 == r / 5).then_some(Exchange {
                back: 0.1,
                transfer_bound: bound,
            })
        });
        (f, calls.get())
    }

    /// Every receiver of the shooter's copy is visited by every shot, in the far field when the
    /// shot's bound times its transfer bound is within the threshold, else refined (not counted).
    #[test]
    fn far_visits_are_the_shots_times_the_far_receivers() {
        let (all_far, _) = copies(1, 0, 1e-9, 1.0);
        assert!(all_far.shots > 5.0);
        assert!((all_far.far_visits - 4.0 * all_far.shots).abs() < 1e-9);
        let (all_near, _) = copies(1, 0, 1.0, 1e-12);
        assert!(all_near.shots > 5.0);
        assert_eq!(all_near.far_visits, 0.0);
    }

    /// A scene of many copies of a set takes about as many times the shots of the set (not
    /// exactly: what comes back spreads over every copy), and past the sample sizes the forecast
    /// asks for a bounded number of exchanges while its sample stands for the whole: 4 000 copies
    /// against ten times the exact simulation of 400.
    #[test]
    fn a_sample_stands_for_a_large_scene() {
        let (one, _) = copies(1, 0, 1e-9, 1.0);
        let (ten, _) = copies(10, 0, 1e-9, 1.0);
        let ratio = ten.shots / (10.0 * one.shots);
        assert!((ratio - 1.0).abs() < 0.15, "{ten:?} {one:?}");
        let (exact, _) = copies(400, 0, 1e-9, 1.0);
        let (many, calls) = copies(4000, 0, 1e-9, 1.0);
        let ratio = many.shots / (10.0 * exact.shots);
        assert!((ratio - 1.0).abs() < 0.1, "{many:?} {exact:?}");
        let ratio = many.far_visits / (10.0 * exact.far_visits);
        assert!((ratio - 1.0).abs() < 0.2, "{many:?} {exact:?}");
        assert!(
            calls <= MAX_SAMPLE * MAX_RECEIVERS + BACK_SHOOTERS * MAX_BACK_RECEIVERS,
            "{calls}"
        );
    }

    /// Roots with no power that take no light change nothing: they are never sampled to stand
    /// for the others (400 copies, alone and among as many black roots as lit ones).
    #[test]
    fn black_roots_do_not_count() {
        let (alone, _) = copies(400, 0, 1e-9, 1.0);
        let (among, _) = copies(400, 2000, 1e-9, 1.0);
        let ratio = among.shots / alone.shots;
        assert!((ratio - 1.0).abs() < 0.05, "{among:?} {alone:?}");
        let ratio = among.far_visits / alone.far_visits;
        assert!((ratio - 1.0).abs() < 0.3, "{among:?} {alone:?}");
    }

    /// All the power in a few roots of a large scene (one lit corner): they are shot, however
    /// few against the strata.
    #[test]
    fn power_held_by_a_few_roots_is_foreseen() {
        let n = 20_000;
        let unshot: Vec<f64> = (0..n).map(|i| if i < 3 { 1.0 } else { 0.0 }).collect();
        let share = vec![1.0; n];
        let bound_per_watt = vec![1.0; n];
        let input = ForecastInput {
            unshot: &unshot,
            share: &share,
            bound_per_watt: &bound_per_watt,
            target: 0.5,
            threshold: 1.0,
        };
        let f = forecast(&input, &|_, _| None);
        assert_eq!(f.shots, 3.0, "{f:?}");
    }

    /// Nothing to shoot, or already within the target: nothing foreseen.
    #[test]
    fn nothing_to_shoot_foresees_nothing() {
        let input = ForecastInput {
            unshot: &[0.5, 0.5],
            share: &[1.0, 1.0],
            bound_per_watt: &[1.0, 1.0],
            target: 1.0,
            threshold: 1.0,
        };
        let exchange = |_: usize, _: usize| None;
        assert_eq!(forecast(&input, &exchange), IndirectForecast::default());
        let empty = ForecastInput {
            unshot: &[],
            share: &[],
            bound_per_watt: &[],
            target: 0.0,
            threshold: 1.0,
        };
        assert_eq!(forecast(&empty, &exchange), IndirectForecast::default());
    }
}
