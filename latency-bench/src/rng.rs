//! A seeded pseudo-random generator for the bench's test matrices and signals.
//!
//! A 64-bit linear congruential generator (multiplier and increment of Knuth's MMIX) whose
//! output is the high half of the state passed through a xorshift, as in PCG's output
//! function, so that the low-quality low bits of an LCG never show. The bench only needs
//! reproducible, roughly uniform numbers: the matrices it builds are the same on every run
//! and every machine, so step costs are comparable across runs.

/// The generator; see the module docs.
#[derive(Debug, Clone)]
pub struct Lcg {
    state: u64,
}

impl Lcg {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        let mut g = Self {
            state: seed ^ 0x9E37_79B9_7F4A_7C15,
        };
        g.next_u32();
        g
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        self.state = self
            .state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let x = self.state;
        let xorshifted = (((x >> 18) ^ x) >> 27) as u32;
        let rot = (x >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A number uniform in `[-1, 1)`.
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32()) << 21;
        let lo = u64::from(self.next_u32() >> 11);
        let unit = (hi | lo) as f64 / (1u64 << 53) as f64; // [0, 1)
        2.0 * unit - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_numbers_and_they_look_uniform() {
        let mut a = Lcg::new(7);
        let mut b = Lcg::new(7);
        let xs: Vec<f64> = (0..10_000).map(|_| a.uniform()).collect();
        assert!(xs.iter().all(|x| (-1.0..1.0).contains(x)));
        assert_eq!(xs[..5], (0..5).map(|_| b.uniform()).collect::<Vec<_>>()[..]);
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.03, "{mean}");
        assert!((var - 1.0 / 3.0).abs() < 0.02, "{var}");
        assert_ne!(Lcg::new(8).uniform(), Lcg::new(7).uniform());
    }
}
