//! What the indirect phase will cost, foreseen from where the unshot power is before it starts:
//! the shots it will take, and their cost against the nats of unshot power they shed (the
//! [`CostCurve`] the ETA, `eta.rs`, prices and follows).
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
//! the sample sizes whatever the scene, its other work is one sort of the roots (`tests::*`); the
//! cost curve starts at (0, 0) and neither coordinate decreases along it.

/// Roots the model is simulated on, at most.
const MAX_SAMPLE: usize = 2048;
/// Of those, the roots of most unshot power, taken at weight 1 (power held by a few roots is
/// never left out of the strata).
const TOP_ROOTS: usize = 512;
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
/// The largest share of a shot taken to come back (a closed room of reflectance 0.95).
const MAX_BACK: f64 = 0.95;

/// Receivers each sampled shooter's facing count is taken over, at most (scaled to the whole).
const MAX_FACING_RECEIVERS: usize = 1024;
/// What an indirect shot costs, in rays of the direct phase (its seconds over the rays it
/// traced), [`shot_cost`]: [`RAYS_PER_RECEIVER`] per receiver the shooter faces (its plan, its
/// far links), [`RAYS_PER_POWER`] times the square root of its power over the threshold and
/// [`RAYS_PER_POWER_LINEAR`] times that power itself (the links refined near it, which grow
/// faster than the square root for a powerful shot); the law is pinned by
/// `the_cost_curve_counts_receivers_faced_and_power`. The constants are fitted on the scaling
/// benchmark's six scenes so that the ETA stays within 2 of the time left on each
/// (docs/performance-notes.md, "The ETA's price of a powerful shot"; a change in what an
/// indirect shot or a direct ray costs moves them): the ETA corrects the level as the indirect
/// shots come, the curve's shape is what it relies on.
const RAYS_PER_RECEIVER: f64 = 3.7;
const RAYS_PER_POWER: f64 = 4000.0;
const RAYS_PER_POWER_LINEAR: f64 = 100.0;
/// Nats between the points of the cost curve, at least.
const CURVE_STEP: f64 = 0.01;

/// The indirect phase foreseen: the shots it will take, and what they cost against the nats
/// of unshot power they shed.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct IndirectForecast {
    pub shots: f64,
    pub cost: CostCurve,
}

/// The cost of the indirect phase foreseen, in rays of the direct phase, against the nats of
/// unshot power shed from its start: increasing in both, from (0, 0).
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct CostCurve {
    /// (nats shed, cost to shed them).
    points: Vec<(f64, f64)>,
}

/// The roots as the forecast sees them.
pub(super) struct ForecastInput<'a> {
    /// Unshot power per root, W (mean of the channels).
    pub unshot: &'a [f64],
    /// Where reflected light lands, per root (any scale; face area times reflectance).
    pub share: &'a [f64],
    /// The unshot power to reach, W.
    pub target: f64,
    /// The power a link may leave unrepresented, W (prices a shot's near links).
    pub threshold: f64,
}

/// A root of the sample and how many roots it stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sampled {
    root: usize,
    weight: f64,
}

/// The indirect phase foreseen from `input`, `back(s, r)` the share of 1 W sent by root `s` that
/// root `r` sends back (its reflectance times what it would receive with no occluder; `None`
/// when they do not face each other), `faces(s, r)` whether a shot of `s` visits `r`.
pub(super) fn forecast(
    input: &ForecastInput,
    back: &dyn Fn(usize, usize) -> Option<f64>,
    faces: &dyn Fn(usize, usize) -> bool,
) -> IndirectForecast {
    let n = input.unshot.len();
    let total: f64 = input.unshot.iter().sum();
    if n == 0 || total <= input.target || !total.is_finite() {
        return IndirectForecast::default();
    }
    // The roots that hold or can receive power, by unshot power, largest first.
    let mut order: Vec<usize> = (0..n)
        .filter(|&i| input.unshot[i] > 0.0 || input.share[i] > 0.0)
        .collect();
    order.sort_by(|&a, &b| input.unshot[b].total_cmp(&input.unshot[a]));
    let back = back_share(input.unshot, &order, back);
    let sample = weighted_sample(&order);
    let u: Vec<f64> = sample.iter().map(|s| input.unshot[s.root]).collect();
    let share: Vec<f64> = sample.iter().map(|s| input.share[s.root]).collect();
    let weight: Vec<f64> = sample.iter().map(|s| s.weight).collect();
    let sample_total: f64 = u.iter().zip(&weight).map(|(u, w)| u * w).sum();
    let target = input.target * sample_total / total;
    let simulated = shot_powers(&u, &share, &weight, back, target);
    let shots: f64 = simulated.iter().map(|s| weight[s.entry]).sum();
    debug_assert!(shots.is_finite() && shots >= 0.0);
    let facing = facing_counts(n, &sample, faces);
    let cost = cost_curve(&simulated, &weight, &facing, sample_total, input.threshold);
    IndirectForecast { shots, cost }
}

/// Receivers each sampled root's shot visits: its facing count over at most
/// [`MAX_FACING_RECEIVERS`] receivers (a fixed shuffle), scaled to the `n` roots.
fn facing_counts(n: usize, sample: &[Sampled], faces: &dyn Fn(usize, usize) -> bool) -> Vec<f64> {
    let receivers = receiver_sample(n, MAX_FACING_RECEIVERS);
    let scale = n as f64 / receivers.len().max(1) as f64;
    sample
        .iter()
        .map(|s| {
            let k = receivers
                .iter()
                .filter(|&&r| r != s.root && faces(s.root, r))
                .count();
            k as f64 * scale
        })
        .collect()
}

/// The cost curve of the model's shots `simulated`, each costing [`shot_cost`] per root it
/// stands for (its power over `threshold`); the nats shed after each from `total` W.
fn cost_curve(
    simulated: &[SimulatedShot],
    weight: &[f64],
    facing: &[f64],
    total: f64,
    threshold: f64,
) -> CostCurve {
    let mut points = vec![(0.0, 0.0)];
    let mut cost = 0.0;
    for (j, s) in simulated.iter().enumerate() {
        let (k, p) = (s.entry, s.power);
        cost += weight[k] * shot_cost(facing[k], p / threshold);
        let nats = (total / s.left.max(total * 1e-300)).ln();
        let last = points.last().map_or(0.0, |&(u, _)| u);
        if nats >= last + CURVE_STEP || j + 1 == simulated.len() {
            points.push((nats.max(last), cost));
        }
    }
    CostCurve::new(points)
}

/// What a shot costs, in rays of the direct phase: `facing` receivers faced, a power of
/// `power` thresholds sent (the constants' doc; `the_cost_curve_counts_receivers_faced_and_power`).
fn shot_cost(facing: f64, power: f64) -> f64 {
    RAYS_PER_RECEIVER * facing + RAYS_PER_POWER * power.sqrt() + RAYS_PER_POWER_LINEAR * power
}

impl CostCurve {
    /// The curve through `points` (nats shed, cost), from (0, 0), neither decreasing.
    pub(super) fn new(points: Vec<(f64, f64)>) -> Self {
        debug_assert!(points.first() == Some(&(0.0, 0.0)));
        debug_assert!(points
            .windows(2)
            .all(|w| w[1].0 >= w[0].0 && w[1].1 >= w[0].1));
        CostCurve { points }
    }

    /// Cost to shed `nats` from the start: linear between the points, and past the last one at
    /// the mean cost per nat of its last nat (the model stops at its own target, which the solve
    /// may pass later).
    pub(super) fn at(&self, nats: f64) -> f64 {
        let p = &self.points;
        let Some(&(u_end, c_end)) = p.last() else {
            return 0.0;
        };
        if nats >= u_end {
            // The mean cost per nat over the last nat (or the whole curve, when shorter).
            let u0 = (u_end - 1.0).max(0.0);
            let slope = if u_end > u0 {
                (c_end - self.at(u0)) / (u_end - u0)
            } else {
                0.0
            };
            return c_end + slope * (nats - u_end);
        }
        let i = p.partition_point(|&(u, _)| u < nats.max(0.0));
        if i == 0 {
            return p[0].1;
        }
        let ((u0, c0), (u1, c1)) = (p[i - 1], p[i]);
        if u1 > u0 {
            c0 + (c1 - c0) * (nats - u0) / (u1 - u0)
        } else {
            c1
        }
    }

    /// Cost of the whole curve (to the model's own target).
    pub(super) fn total(&self) -> f64 {
        self.points.last().map_or(0.0, |&(_, c)| c)
    }

    /// Whether nothing is foreseen.
    pub(super) fn is_empty(&self) -> bool {
        self.points.len() < 2
    }
}

/// The share of a shot's power that comes back as unshot power: over [`BACK_SHOOTERS`] shooters
/// taken in strata of the unshot power (`order`, the roots by power, largest first), what at
/// most [`MAX_BACK_RECEIVERS`] receivers (a fixed shuffle, scaled to the whole) reflect of 1 W
/// (at most [`MAX_BACK`]).
fn back_share(unshot: &[f64], order: &[usize], back: &dyn Fn(usize, usize) -> Option<f64>) -> f64 {
    let n = unshot.len();
    let shooters = strata_by_power(unshot, order, BACK_SHOOTERS);
    if shooters.is_empty() {
        return 0.0;
    }
    let receivers = receiver_sample(n, MAX_BACK_RECEIVERS);
    let scale = n as f64 / receivers.len() as f64;
    let sum: f64 = shooters
        .iter()
        .map(|&s| {
            receivers
                .iter()
                .filter(|&&r| r != s)
                .filter_map(|&r| back(s, r))
                .sum::<f64>()
        })
        .sum();
    (scale * sum / shooters.len() as f64).clamp(0.0, MAX_BACK)
}

/// One of the model's shots.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SimulatedShot {
    /// The sampled entry that shoots.
    entry: usize,
    /// The power it sends, per root it stands for.
    power: f64,
    /// The unshot power the model holds after the shot (its returns counted).
    left: f64,
}

/// The model's shots, in order, from unshot powers `u` per root, entry `i` standing for
/// `weight[i]` roots alike (shooting it shoots them all), with `back` of every shot returning
/// over the roots in proportion to `share`, until the unshot power is at most `target`.
fn shot_powers(
    u: &[f64],
    share: &[f64],
    weight: &[f64],
    back: f64,
    target: f64,
) -> Vec<SimulatedShot> {
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
        shots.push(SimulatedShot {
            entry: i,
            power: p,
            left: total,
        });
    }
    shots
}

/// At most [`MAX_SAMPLE`] of the roots `order` (by unshot power, largest first): every one when
/// there are no more; else the first [`TOP_ROOTS`] at weight 1, and one root per stratum of the
/// others, standing for its stratum.
fn weighted_sample(order: &[usize]) -> Vec<Sampled> {
    let one = |&root: &usize| Sampled { root, weight: 1.0 };
    if order.len() <= MAX_SAMPLE {
        return order.iter().map(one).collect();
    }
    let (top, rest) = order.split_at(TOP_ROOTS);
    let k = MAX_SAMPLE - TOP_ROOTS;
    let step = rest.len() as f64 / k as f64;
    let strata = (0..k).map(|j| Sampled {
        root: rest[((j as f64 + 0.5) * step) as usize],
        weight: step,
    });
    top.iter().map(one).chain(strata).collect()
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

/// At most `m` of the roots `order` (by unshot power, largest first), one at the middle of each
/// of `m` equal strata of the total unshot power.
fn strata_by_power(unshot: &[f64], order: &[usize], m: usize) -> Vec<usize> {
    let lit = order.partition_point(|&i| unshot[i] > 0.0);
    let total: f64 = order[..lit].iter().map(|&i| unshot[i]).sum();
    let mut picked = Vec::new();
    let mut acc = 0.0;
    for &i in &order[..lit] {
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
        let (entries, powers): (Vec<usize>, Vec<f64>) =
            shots.iter().map(|s| (s.entry, s.power)).unzip();
        assert_eq!((entries, powers), (vec![1, 3, 2], vec![5.0, 4.0, 3.0]));
        let left: Vec<f64> = shots.iter().map(|s| s.left).collect();
        assert_eq!(left, vec![10.0, 6.0, 3.0]);
        assert!(shot_powers(&u, &[1.0; 5], &[1.0; 5], 0.0, 15.0).is_empty());
    }

    /// One root that gets back half of what it sends: it shoots until `0.5^k` is within the
    /// target, `k = ceil(ln(target) / ln(0.5))`, each shot half the last.
    #[test]
    fn what_comes_back_is_shot_again() {
        let shots = shot_powers(&[1.0], &[1.0], &[1.0], 0.5, 0.01);
        let k = (0.01f64.ln() / 0.5f64.ln()).ceil() as usize;
        assert_eq!(shots.len(), k);
        for (j, s) in shots.iter().enumerate() {
            assert_eq!(s.entry, 0);
            assert!((s.power - 0.5f64.powi(j as i32)).abs() < 1e-12);
            assert!((s.left - 0.5f64.powi(j as i32 + 1)).abs() < 1e-12);
        }
    }

    /// An entry of weight 2 shoots as two alike roots of weight 1 do: with nothing back, the same
    /// powers, each of its shots standing for two of theirs; with returns, about as many shots
    /// (its two roots shoot at once, so the second does not shoot the first's returns at once).
    #[test]
    fn a_weighted_entry_shoots_as_the_roots_it_stands_for() {
        let count =
            |shots: &[SimulatedShot], w: &[f64]| -> f64 { shots.iter().map(|s| w[s.entry]).sum() };
        let (u, share) = ([3.0, 1.0], [1.0, 2.0]);
        let (spelled_u, spelled_share) = ([3.0, 3.0, 1.0], [1.0, 1.0, 2.0]);
        let weighted = shot_powers(&u, &share, &[2.0, 1.0], 0.0, 1.5);
        assert_eq!(weighted.len(), 1);
        // Two roots of 3 W shot, 1 W left: the power left counts the entry's weight.
        let first = weighted[0];
        assert_eq!((first.entry, first.power, first.left), (0, 3.0, 1.0));
        let spelled = shot_powers(&spelled_u, &spelled_share, &[1.0; 3], 0.0, 1.5);
        let powers: Vec<f64> = spelled.iter().map(|s| s.power).collect();
        assert_eq!(powers, vec![3.0, 3.0]);
        let weighted = shot_powers(&u, &share, &[2.0, 1.0], 0.6, 1e-3);
        let spelled = shot_powers(&spelled_u, &spelled_share, &[1.0; 3], 0.6, 1e-3);
        let ratio = count(&weighted, &[2.0, 1.0]) / spelled.len() as f64;
        assert!((ratio - 1.0).abs() < 0.1, "{weighted:?} {spelled:?}");
    }

    /// `copies` copies of five roots, each root facing the other roots of its copy (a tenth of
    /// every shot coming back from each), then `black` roots that neither hold nor take light;
    /// returns the forecast and the exchanges asked for.
    fn copies(copies: usize, black: usize) -> (IndirectForecast, usize) {
        let set = [5.0, 4.0, 3.0, 2.0, 1.0];
        let lit = 5 * copies;
        let n = lit + black;
        let unshot: Vec<f64> = (0..n)
            .map(|i| if i < lit { set[i % 5] } else { 0.0 })
            .collect();
        let share: Vec<f64> = (0..n).map(|i| if i < lit { 1.0 } else { 0.0 }).collect();
        let input = ForecastInput {
            unshot: &unshot,
            share: &share,
            target: 1e-3 * 15.0 * copies as f64,
            threshold: 1e-6,
        };
        let calls = Cell::new(0);
        let f = forecast(
            &input,
            &|s, r| {
                calls.set(calls.get() + 1);
                (s < lit && r < lit && s / 5 == r / 5).then_some(0.1)
            },
            &|s, r| s < lit && r < lit && s / 5 == r / 5,
        );
        (f, calls.get())
    }

    /// A scene within the sample is simulated exactly: every root at weight 1, `back` the four
    /// other roots of the copy reflecting a tenth each.
    #[test]
    fn a_small_scene_is_simulated_exactly() {
        let (f, _) = copies(1, 0);
        let u = [5.0, 4.0, 3.0, 2.0, 1.0];
        let exact = shot_powers(&u, &[1.0; 5], &[1.0; 5], 0.4, 15e-3);
        assert!(exact.len() > 5);
        assert_eq!(f.shots, exact.len() as f64);
    }

    /// A scene of many copies of a set takes about as many times the shots of the set (not
    /// exactly: what comes back spreads over every copy), and past the sample sizes the forecast
    /// asks for a bounded number of exchanges while its sample stands for the whole: 4 000 copies
    /// against ten times the exact simulation of 400.
    #[test]
    fn a_sample_stands_for_a_large_scene() {
        let (one, _) = copies(1, 0);
        let (ten, _) = copies(10, 0);
        let ratio = ten.shots / (10.0 * one.shots);
        assert!((ratio - 1.0).abs() < 0.15, "{ten:?} {one:?}");
        let (exact, _) = copies(400, 0);
        let (many, calls) = copies(4000, 0);
        let ratio = many.shots / (10.0 * exact.shots);
        assert!((ratio - 1.0).abs() < 0.1, "{many:?} {exact:?}");
        assert!(calls <= BACK_SHOOTERS * MAX_BACK_RECEIVERS, "{calls}");
    }

    /// Roots with no power that take no light change nothing: they are never sampled to stand
    /// for the others (400 copies, alone and among as many black roots as lit ones).
    #[test]
    fn black_roots_do_not_count() {
        let (alone, _) = copies(400, 0);
        let (among, _) = copies(400, 2000);
        let ratio = among.shots / alone.shots;
        assert!((ratio - 1.0).abs() < 0.05, "{among:?} {alone:?}");
    }

    /// All the power in a few roots of a large scene (one lit corner): they are shot, however
    /// few against the strata.
    #[test]
    fn power_held_by_a_few_roots_is_foreseen() {
        let n = 20_000;
        let unshot: Vec<f64> = (0..n).map(|i| if i < 3 { 1.0 } else { 0.0 }).collect();
        let share = vec![1.0; n];
        let input = ForecastInput {
            unshot: &unshot,
            share: &share,
            target: 0.5,
            threshold: 1e-3,
        };
        let f = forecast(&input, &|_, _| None, &|_, _| false);
        assert_eq!(f.shots, 3.0, "{f:?}");
    }

    /// The strata of the power: the root at the middle of each equal share of it (a root
    /// holding several shares is picked for each), black roots never.
    #[test]
    fn strata_split_the_power_evenly() {
        let unshot = [0.0, 6.0, 1.0, 1.0, 1.0, 1.0, 0.0];
        let order = [1, 2, 3, 4, 5, 0, 6];
        assert_eq!(strata_by_power(&unshot, &order, 2), vec![1, 3]);
        assert_eq!(strata_by_power(&unshot, &order, 4), vec![1, 1, 2, 4]);
        assert!(strata_by_power(&[0.0; 3], &[0, 1, 2], 4).is_empty());
    }

    /// The cost curve of a small scene against its shots counted by hand: each shot costs
    /// [`RAYS_PER_RECEIVER`] per receiver it faces (four: the other roots of its copy),
    /// [`RAYS_PER_POWER`] times the square root of its power over the threshold and
    /// [`RAYS_PER_POWER_LINEAR`] times that power; the nats are those of the unshot power the
    /// shots leave, a share `back` of each coming back.
    #[test]
    fn the_cost_curve_counts_receivers_faced_and_power() {
        let (f, _) = copies(1, 0);
        let u = [5.0, 4.0, 3.0, 2.0, 1.0];
        let exact = shot_powers(&u, &[1.0; 5], &[1.0; 5], 0.4, 15e-3);
        let threshold = 1e-6;
        let (mut left, mut cost) = (15.0, 0.0);
        for s in &exact {
            let p = s.power;
            let power = p / threshold;
            cost += RAYS_PER_RECEIVER * 4.0
                + RAYS_PER_POWER * power.sqrt()
                + RAYS_PER_POWER_LINEAR * power;
            left -= 0.6 * p;
            let nats = (15.0f64 / left).ln();
            let at = f.cost.at(nats);
            assert!((at - cost).abs() <= 1e-9 * cost, "{at} {cost}");
        }
        assert!((f.cost.total() - cost).abs() <= 1e-9 * cost);
    }

    /// Between its points the curve is linear; past the last it goes on at the cost per nat of
    /// its last nat; before the first it is 0.
    #[test]
    fn the_cost_curve_interpolates_and_extends() {
        let c = CostCurve::new(vec![(0.0, 0.0), (1.0, 10.0), (2.0, 30.0), (3.0, 40.0)]);
        assert_eq!(c.at(-1.0), 0.0);
        assert_eq!(c.at(0.5), 5.0);
        assert_eq!(c.at(1.5), 20.0);
        assert_eq!(c.at(3.0), 40.0);
        assert_eq!(c.at(4.0), 50.0);
        assert_eq!(c.total(), 40.0);
        // One long step: the last nat is within it.
        let long = CostCurve::new(vec![(0.0, 0.0), (2.5, 100.0)]);
        assert_eq!(long.at(3.0), 120.0);
        assert!(CostCurve::default().is_empty());
        assert_eq!(CostCurve::default().at(1.0), 0.0);
    }

    /// Nothing to shoot, or already within the target: nothing foreseen.
    #[test]
    fn nothing_to_shoot_foresees_nothing() {
        let input = ForecastInput {
            unshot: &[0.5, 0.5],
            share: &[1.0, 1.0],
            target: 1.0,
            threshold: 1e-3,
        };
        let back = |_: usize, _: usize| None;
        let faces = |_: usize, _: usize| true;
        assert_eq!(forecast(&input, &back, &faces), IndirectForecast::default());
        let empty = ForecastInput {
            unshot: &[],
            share: &[],
            target: 0.0,
            threshold: 1e-3,
        };
        assert_eq!(forecast(&empty, &back, &faces), IndirectForecast::default());
    }
}
