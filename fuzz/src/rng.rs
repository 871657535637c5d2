//! The random source of the generators: one ChaCha8 stream per case, so any case can be
//! regenerated from `(seed, case index)` alone.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

/// The seeded generator of a run; [`Streams::case`] gives case `i` its own stream.
#[derive(Clone)]
pub(crate) struct Streams(ChaCha8Rng);

impl Streams {
    /// The streams of seed `seed`.
    pub(crate) fn new(seed: u64) -> Streams {
        Streams(ChaCha8Rng::seed_from_u64(seed))
    }

    /// The random source of case `case` (stream number `case` of the seed's key).
    pub(crate) fn case(&self, case: u64) -> Gen {
        let mut rng = self.0.clone();
        rng.set_stream(case);
        Gen(rng)
    }
}

/// Random choices for one case.
pub(crate) struct Gen(ChaCha8Rng);

impl Gen {
    /// 64 random bits.
    pub(crate) fn u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// 32 random bits.
    pub(crate) fn u32(&mut self) -> u32 {
        self.0.next_u32()
    }

    /// Uniform in `0..n` (`n > 0`; the modulo bias is irrelevant here).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        debug_assert!(n > 0);
        (self.u64() % n as u64) as usize
    }

    /// Uniform in `lo..=hi`.
    pub(crate) fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi - lo + 1)
    }

    /// True with probability `num / den`.
    pub(crate) fn chance(&mut self, num: u32, den: u32) -> bool {
        self.u32() % den < num
    }

    /// One element of a non-empty slice.
    pub(crate) fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }

    /// An index into `weights`, drawn with those weights (not all zero).
    pub(crate) fn weighted(&mut self, weights: &[u32]) -> usize {
        self.weighted_index(weights.iter().copied())
    }

    /// The first item of an entry of `table` drawn with the entry's weight, the second item
    /// (the same draw as [`Gen::weighted`] of the weights).
    pub(crate) fn pick_weighted<T: Copy>(&mut self, table: &[(T, u32)]) -> T {
        table[self.weighted_index(table.iter().map(|(_, w)| *w))].0
    }

    fn weighted_index(&mut self, weights: impl Iterator<Item = u32> + Clone) -> usize {
        let total: u32 = weights.clone().sum();
        let mut x = self.u32() % total;
        let mut last = 0;
        for (i, w) in weights.enumerate() {
            if x < w {
                return i;
            }
            x -= w;
            last = i;
        }
        last
    }

    /// `n` random bytes.
    pub(crate) fn bytes(&mut self, n: usize) -> Vec<u8> {
        let mut v = vec![0u8; n];
        self.0.fill_bytes(&mut v);
        v
    }

    /// The number of mutations of one case: 1 to 8, fewer more often (half the cases draw
    /// from 1–2, the rest uniformly from 1–8).
    pub(crate) fn mutation_count(&mut self) -> usize {
        if self.chance(1, 2) {
            self.range(1, 2)
        } else {
            self.range(1, 8)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_reproducible_and_independent() {
        let s = Streams::new(7);
        let a: Vec<u64> = (0..4).map(|_| s.case(3).u64()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(s.case(3).u64(), s.case(4).u64());
        assert_ne!(Streams::new(8).case(3).u64(), s.case(3).u64());
    }
}
