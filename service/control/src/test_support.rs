//! Helpers shared by the unit tests of the math kernels (compiled for tests only).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// A seeded source of uniform and standard normal numbers for reproducible tests.
pub struct Gauss(ChaCha8Rng);

impl Gauss {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(ChaCha8Rng::seed_from_u64(seed))
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        self.0.sample(StandardNormal)
    }
    /// `len` standard normal numbers.
    pub fn vec(&mut self, len: usize) -> Vec<f64> {
        (0..len).map(|_| self.normal()).collect()
    }
}
