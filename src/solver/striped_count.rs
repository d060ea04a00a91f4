//! A count the pool's threads add to at once without writing one shared cache line: one padded
//! atomic per thread of the pool (and one for threads outside it), summed when read. Every ray
//! packet and every far link of a solve adds to its counts: one shared atomic would be a cache
//! line the cores take from each other at each add (docs/performance-notes.md, "Far links known
//! blocked").
//!
//! Invariants: once the threads that added are joined, [`StripedCount::get`] is exactly every
//! `add` less every `sub` (each stripe wraps, so a stripe may go below zero while the sum does
//! not); a reading taken while they run is a sum of stripes read one after the other, which
//! may miss operations in flight on some of them (an `add` on one stripe missed and its `sub`
//! on another seen): it never reads below zero.

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

    /// Adds `n` to the count.
    pub fn add(&self, n: u64) {
        self.stripe().fetch_add(n, Ordering::Relaxed);
    }

    /// Takes `n` from the count (what was added, on this thread or another).
    pub fn sub(&self, n: u64) {
        self.stripe().fetch_sub(n, Ordering::Relaxed);
    }

    /// The count: the stripes' wrapping sum, 0 where a reading during the adds would be below
    /// zero (see the module header).
    pub fn get(&self) -> u64 {
        let sum = self
            .stripes
            .iter()
            .fold(0u64, |sum, s| sum.wrapping_add(s.0.load(Ordering::Relaxed)));
        u64::try_from(sum as i64).unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Adds and subtractions from the pool's threads and from outside it sum exactly, a
    /// subtraction made on another thread than the adds included; a pool larger than the
    /// count's stripes shares them; each stripe has its cache lines to itself; a reading that
    /// catches a subtraction before its add is 0.
    #[test]
    fn adds_from_every_thread_sum_exactly() {
        assert_eq!(std::mem::align_of::<Stripe>(), 128);
        assert_eq!(std::mem::size_of::<Stripe>(), 128);
        let early = StripedCount::new();
        early.sub(3);
        assert_eq!(early.get(), 0);
        early.add(5);
        assert_eq!(early.get(), 2);
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
