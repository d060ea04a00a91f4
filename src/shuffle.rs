//! A deterministic shuffle: Fisher-Yates driven by SplitMix64 from a fixed seed, so that whatever
//! is built from a shuffled order (the trapezoidal map's segment insertion, the order in which
//! `visibility::bounding_planes` tries the scene's points) is reproducible run to run.
//!
//! Owns [`shuffle`] and its generator [`SplitMix64`] (the domain's property tests draw their
//! polygons from it too), and for the numerical tests a sequence of uniform numbers
//! (`uniform_sequence`). Invariant: the same seed and length give the same permutation, the same
//! seed the same sequence.

/// SplitMix64: a tiny, good-enough generator for a shuffle.
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (n > 0), by multiply-shift.
    fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next()) * n as u128) >> 64) as usize
    }
}

/// Uniform numbers in `[0, 1)` from a fixed seed (a 64-bit linear congruential generator, its
/// top 53 bits): the numerical tests' random points and coefficients.
#[cfg(test)]
pub(crate) fn uniform_sequence(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Permutes `items` in place, the permutation fixed by `seed`.
pub fn shuffle<T>(items: &mut [T], seed: u64) {
    let mut rng = SplitMix64::new(seed);
    for i in (1..items.len()).rev() {
        items.swap(i, rng.below(i + 1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seed_gives_one_permutation_of_the_items() {
        let mut a: Vec<u32> = (0..100).collect();
        let mut b = a.clone();
        shuffle(&mut a, 7);
        shuffle(&mut b, 7);
        assert_eq!(a, b, "same seed, same order");
        assert_ne!(a, (0..100).collect::<Vec<_>>(), "shuffled");
        let mut sorted = a.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..100).collect::<Vec<_>>(), "a permutation");
    }
}
