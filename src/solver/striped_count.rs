//! A count the pool's threads add to at once without writing one shared cache line: one padded
//! atomic per thread of the pool (and one for threads outside it), summed when read. A solve
//! counts every ray and link; one shared atomic per far link was a line both cores took in turn
//! (docs/performance-notes.md, "Far links known blocked").
//!
//! Invariant: [`StripedCount::get`] is the sum of every `add` less every `sub` made before it
//! (wrapping, so a stripe may go below zero while the sum does not); a reading taken while
//! threads add may miss adds in flight, as a single atomic's would.

use std::sync::atomic::{AtomicU64, Ordering};

/// One thread's part of a [`StripedCount`], alone on its cache lines.
#[derive(Debug, Default)]
#[repr(align(128))]
struct Stripe(AtomicU64);

/// A count added to from many threads (see the module header).
#[derive(Debug)]
pub(crate) struct StripedCount {
    stripes: Box<[Stripe]>,
}

impl Default for StripedCount {
    fn default() -> Self {
        Self::new()
    }
}

impl StripedCount {
    /// Zero, with a stripe for each thread of the current rayon pool and one for the others.
    pub fn new() -> Self {
        StripedCount {
            stripes: (0..=rayon::current_num_threads())
                .map(|_| Stripe::default())
                .collect(),
        }
    }

    /// The calling thread's stripe: its index in the rayon pool it runs in, past the one for
    /// threads outside any pool (wrapped for a larger pool than the one the count was made in).
    fn stripe(&self) -> &AtomicU64 {
        let i = rayon::current_thread_index().map_or(0, |i| i + 1);
        &self.stripes[i % self.stripes.len()].0
    }

    pub fn add(&self, n: u64) {
        self.stripe().fetch_add(n, Ordering::Relaxed);
    }

    pub fn sub(&self, n: u64) {
        self.stripe().fetch_sub(n, Ordering::Relaxed);
    }

    pub fn get(&self) -> u64 {
        self.stripes
            .iter()
            .fold(0u64, |sum, s| sum.wrapping_add(s.0.load(Ordering::Relaxed)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Adds and subtractions from the pool's threads and from outside it sum exactly, a
    /// subtraction made on another thread than the adds included; and a pool larger than the
    /// count's stripes shares them.
    #[test]
    fn adds_from_every_thread_sum_exactly() {
        let count = StripedCount::new();
        (0..10_000u64)
            .into_par_iter()
            .for_each(|i| count.add(i % 7));
        let expected: u64 = (0..10_000u64).map(|i| i % 7).sum();
        assert_eq!(count.get(), expected);
        count.sub(expected - 5);
        assert_eq!(count.get(), 5);
        let wide = rayon::ThreadPoolBuilder::new()
            .num_threads(count.stripes.len() + 3)
            .build()
            .expect("a pool");
        wide.install(|| (0..1000).into_par_iter().for_each(|_| count.add(2)));
        assert_eq!(count.get(), 2005);
    }
}
