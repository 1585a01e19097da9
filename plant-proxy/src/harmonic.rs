//! # A harmonic of the sample index
//!
//! The discrete-time signals of chapter 4 are sums of cosines of the step index `k`,
//! not of time: the two- and four-harmonic commands of §4.5.1
//!
//! ```text
//! r_k = cos(k) + cos(k/8),     r_k = cos(k) + cos(k/2) + cos(k/4) + cos(k/8),
//! ```
//!
//! and the input disturbance of Example 3 (§4.7), a single harmonic at 0.35 rad per step.
//! A [`Harmonic`] is one term `A cos(ω k + φ)` with `ω` in rad per step (`ω = 2π f T`
//! for a frequency `f` in Hz at the sample period `T`); [`sum_at`] adds terms in their
//! order, starting from zero, so a sum is reproducible bit for bit.
//!
//! `ω k` is evaluated as `ω · (k as f64)`: exact in `k` up to `2^53` and rounded once, so
//! the phase error stays at a few ulp of `ω k`.

/// The highest frequency of a harmonic, rad per step: π, the Nyquist frequency (a higher
/// one is the same sequence as a lower one, aliased).
pub const MAX_FREQUENCY_RAD_STEP: f64 = std::f64::consts::PI;

/// One term `amplitude · cos(omega · k + phase)` of the step index `k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// Amplitude `A`.
    pub amplitude: f64,
    /// Frequency `ω`, rad per step, in `[0, π]`.
    pub omega: f64,
    /// Phase `φ` at `k = 0`, rad.
    pub phase: f64,
}

impl Harmonic {
    /// A unit-amplitude, zero-phase term `cos(omega · k)`.
    pub fn unit(omega: f64) -> Self {
        Self {
            amplitude: 1.0,
            omega,
            phase: 0.0,
        }
    }

    /// Its value `A cos(ω k + φ)` at step `k`.
    pub fn at(&self, k: u64) -> f64 {
        self.amplitude * (self.omega * k as f64 + self.phase).cos()
    }

    /// True when every field is finite and `0 ≤ ω ≤ π` ([`MAX_FREQUENCY_RAD_STEP`]).
    pub fn is_valid(&self) -> bool {
        self.amplitude.is_finite()
            && self.phase.is_finite()
            && (0.0..=MAX_FREQUENCY_RAD_STEP).contains(&self.omega)
    }
}

/// `Σ_i A_i cos(ω_i k + φ_i)`, summed in the order of `terms` from `0.0` (0 when empty).
pub fn sum_at(terms: &[Harmonic], k: u64) -> f64 {
    terms.iter().fold(0.0, |acc, h| acc + h.at(k))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_harmonic_is_its_formula() {
        let h = Harmonic {
            amplitude: 2.5,
            omega: 0.35,
            phase: -0.4,
        };
        for k in [0u64, 1, 2, 17, 1000, 123_456_789] {
            assert_eq!(h.at(k), 2.5 * (0.35 * k as f64 - 0.4).cos());
        }
        assert_eq!(Harmonic::unit(1.0).at(3), 3f64.cos());
        assert_eq!(sum_at(&[], 5), 0.0);
        let two = [Harmonic::unit(1.0), Harmonic::unit(0.125)];
        assert_eq!(sum_at(&two, 9), 9f64.cos() + (9.0f64 / 8.0).cos());
    }

    #[test]
    fn validity_bounds_the_frequency_to_nyquist() {
        assert!(Harmonic::unit(0.0).is_valid());
        assert!(Harmonic::unit(std::f64::consts::PI).is_valid());
        assert!(!Harmonic::unit(3.2).is_valid());
        assert!(!Harmonic::unit(-0.1).is_valid());
        assert!(!Harmonic::unit(f64::NAN).is_valid());
        let mut h = Harmonic::unit(0.5);
        h.amplitude = f64::INFINITY;
        assert!(!h.is_valid());
    }
}
