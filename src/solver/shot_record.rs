//! What one shot's links delivered to each node of one receiver, kept until the shot is over so
//! that each node can be judged on the sum of its links (see `ShotContext::refine_by_node_sums`).
//!
//! Owns [`ShotRecord`]: per node, each link's source, its irradiance at the node's rule points
//! then check points, and its coefficients (the projection on the node's basis), with their sums.
//! Invariant: a node's sums are the sums of its recorded links, point by point and coefficient by
//! coefficient; every link of a node has as many point values as the node's sum.

use super::basis::MAX_FUNCTIONS;
use crate::scene::Rgb;
use std::collections::BTreeMap;

/// The links one receiver gathered during a shot, per node.
pub(super) struct ShotRecord<S> {
    /// In node order: the check takes nodes parents first (see `refine_by_node_sums`).
    pub nodes: BTreeMap<usize, NodeSum<S>>,
}

impl<S> Default for ShotRecord<S> {
    fn default() -> Self {
        ShotRecord {
            nodes: BTreeMap::new(),
        }
    }
}

/// One node's links from one shot and their sums.
pub(super) struct NodeSum<S> {
    /// Irradiance at the node's rule points, then at its check points.
    pub e: Vec<Rgb>,
    /// The node's coefficients from these links.
    pub dh: [Rgb; MAX_FUNCTIONS],
    pub links: Vec<RecordedLink<S>>,
}

/// One gathered link: what it delivered, and its source, to send it again.
pub(super) struct RecordedLink<S> {
    pub source: S,
    pub e: Vec<Rgb>,
    pub dh: [Rgb; MAX_FUNCTIONS],
}

fn add_rgb(acc: &mut [Rgb], x: &[Rgb]) {
    for (a, x) in acc.iter_mut().zip(x) {
        for ch in 0..3 {
            a[ch] += x[ch];
        }
    }
}

impl<S> ShotRecord<S> {
    /// Records a link gathered at node `b`.
    pub fn add(&mut self, b: usize, e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS], source: S) {
        let sum = self.nodes.entry(b).or_insert_with(|| NodeSum {
            e: vec![[0.0; 3]; e.len()],
            dh: [[0.0; 3]; MAX_FUNCTIONS],
            links: Vec::new(),
        });
        debug_assert_eq!(sum.e.len(), e.len(), "one node, one set of points");
        add_rgb(&mut sum.e, e);
        add_rgb(&mut sum.dh, dh);
        sum.links.push(RecordedLink {
            source,
            e: e.to_vec(),
            dh: *dh,
        });
    }
}

impl<S> NodeSum<S> {
    /// When the sum's `deviation` (the oracle's error of a set of point values against a
    /// projection) exceeds `allowed`, the links that must go to the node's children: every link
    /// whose own deviation exceeds its share `allowed / n`. The links kept then sum to a
    /// deviation within `allowed`, since the deviation of a sum is at most the sum of the
    /// deviations. `None` when the sum passes.
    pub fn links_to_resend(
        self,
        allowed: f64,
        deviation: impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> f64,
    ) -> Option<Vec<RecordedLink<S>>> {
        if deviation(&self.e, &self.dh) <= allowed {
            return None;
        }
        let share = allowed / self.links.len() as f64;
        let resend: Vec<RecordedLink<S>> = self
            .links
            .into_iter()
            .filter(|l| deviation(&l.e, &l.dh) > share)
            .collect();
        // Empty only by rounding (the sum's deviation is at most the links' sum): nothing to do.
        (!resend.is_empty()).then_some(resend)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle's deviation for a constant basis: the largest |value - coefficient| (channel 0).
    fn constant_deviation(e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS]) -> f64 {
        e.iter()
            .map(|v| (v[0] - dh[0][0]).abs())
            .fold(0.0, f64::max)
    }

    fn link(values: &[f64]) -> (Vec<Rgb>, [Rgb; MAX_FUNCTIONS]) {
        let e: Vec<Rgb> = values.iter().map(|&v| [v, 0.0, 0.0]).collect();
        let mut dh = [[0.0; 3]; MAX_FUNCTIONS];
        dh[0][0] = values.iter().sum::<f64>() / values.len() as f64;
        (e, dh)
    }

    #[test]
    fn sums_are_the_sums_of_the_links() {
        let mut r = ShotRecord::default();
        for (i, v) in [[1.0, 2.0], [0.5, 0.0], [3.0, 3.0]].iter().enumerate() {
            let (e, dh) = link(v);
            r.add(7, &e, &dh, i);
        }
        let s = &r.nodes[&7];
        assert_eq!(s.links.len(), 3);
        assert_eq!(s.e, vec![[4.5, 0.0, 0.0], [5.0, 0.0, 0.0]]);
        assert!((s.dh[0][0] - (1.5 + 0.25 + 3.0)).abs() < 1e-12);
    }

    #[test]
    fn links_that_each_pass_can_fail_together_and_the_kept_ones_pass() {
        // Ten links, each a step of 0.1 across the node: each deviates by 0.05, the sum by 0.5.
        let mut r = ShotRecord::default();
        for i in 0..10 {
            let (e, dh) = link(&[0.1, 0.0]);
            r.add(0, &e, &dh, i);
        }
        // One smooth link stays whatever the budget.
        let (e, dh) = link(&[1.0, 1.0]);
        r.add(0, &e, &dh, 10);
        let sum = r.nodes.remove(&0).expect("recorded");
        let allowed = 0.2;
        assert!(sum
            .links
            .iter()
            .all(|l| constant_deviation(&l.e, &l.dh) <= allowed));
        let resend = sum
            .links_to_resend(allowed, constant_deviation)
            .expect("the sum fails");
        let sent: Vec<usize> = resend.iter().map(|l| l.source).collect();
        assert_eq!(sent, (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn a_passing_sum_keeps_its_links() {
        let mut r = ShotRecord::default();
        for i in 0..3 {
            let (e, dh) = link(&[0.1, 0.0]);
            r.add(0, &e, &dh, i);
        }
        let sum = r.nodes.remove(&0).expect("recorded");
        assert!(sum.links_to_resend(0.2, constant_deviation).is_none());
    }

    #[test]
    fn what_stays_is_within_the_budget() {
        // Links of random steps: whatever is kept sums to a deviation within the budget.
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200 {
            let mut r = ShotRecord::default();
            let n = 2 + (next() * 20.0) as usize;
            for i in 0..n {
                let (e, dh) = link(&[next(), next() * 0.1, next() * 0.01]);
                r.add(0, &e, &dh, i);
            }
            let sum = r.nodes.remove(&0).expect("recorded");
            let allowed = next() * 2.0;
            let all: Vec<(Vec<Rgb>, [Rgb; MAX_FUNCTIONS], usize)> = sum
                .links
                .iter()
                .map(|l| (l.e.clone(), l.dh, l.source))
                .collect();
            let resend: Vec<usize> = sum
                .links_to_resend(allowed, constant_deviation)
                .map(|v| v.into_iter().map(|l| l.source).collect())
                .unwrap_or_default();
            let mut kept = ShotRecord::default();
            for (e, dh, i) in all.into_iter().filter(|l| !resend.contains(&l.2)) {
                kept.add(0, &e, &dh, i);
            }
            if let Some(k) = kept.nodes.get(&0) {
                assert!(constant_deviation(&k.e, &k.dh) <= allowed + 1e-12);
            }
        }
    }
}
