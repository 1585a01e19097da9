//! # The command `r_k` the plant publishes
//!
//! Each measurement carries the command channels `r` (`n_r` of them) next to `y` and `z`.
//! The plant side produces them; a DAQ process that plays the plant supplies its own `r`
//! the same way. A scenario gives them in the `[plant]` table (`plant.command`) as either
//!
//! - **a constant vector** (`command = [..]`, `n_r = plant.commands` entries, the default
//!   being `n_r` zeros): [`Command::Constant`], the behaviour of every scenario before the
//!   generated commands; or
//! - **a generated signal** (`[plant.command]`, one channel, `n_r = 1`) of the step index
//!   `k`, as the examples of chapter 4 use (§4.5–4.7):
//!   - [`Command::Step`]: `r_k = A` for `k ≥ k_0`, `0` before (the unit step command of
//!     Examples 1–3 is `A = 1`, `k_0 = 0`);
//!   - [`Command::Harmonics`]: `r_k = Σ_i a_i cos(ω_i k + φ_i)` ([`crate::harmonic`]), with
//!     the presets [`TWO_HARMONIC`] (`r_k = cos(k) + cos(k/8)`) and [`FOUR_HARMONIC`]
//!     (`r_k = cos(k) + cos(k/2) + cos(k/4) + cos(k/8)`) of §4.5.1–4.6.2.
//!
//! `r_k` is a function of `k` alone, published with `y_k` and `z_k` at sample `k`
//! ([`crate::sim::PlantSim::sample`]).

use crate::harmonic::{Harmonic, sum_at};

/// The frequencies, rad per step, of the two-harmonic command `r_k = cos(k) + cos(k/8)`.
pub const TWO_HARMONIC: [f64; 2] = [1.0, 0.125];

/// The frequencies, rad per step, of the four-harmonic command
/// `r_k = cos(k) + cos(k/2) + cos(k/4) + cos(k/8)`.
pub const FOUR_HARMONIC: [f64; 4] = [1.0, 0.5, 0.25, 0.125];

/// The command channels `r` (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `n_r` channels held at these values (`n_r` may be 0).
    Constant(Vec<f64>),
    /// One channel: `amplitude` from step `start` on, 0 before.
    Step {
        /// Amplitude `A`.
        amplitude: f64,
        /// First step `k_0` at which `r_k = A`.
        start: u64,
    },
    /// One channel: `Σ_i a_i cos(ω_i k + φ_i)`, summed in order.
    Harmonics(Vec<Harmonic>),
}

impl Default for Command {
    /// No command channel.
    fn default() -> Self {
        Command::Constant(Vec::new())
    }
}

impl Command {
    /// The unit-amplitude, zero-phase harmonics at the frequencies `omegas` (rad per step),
    /// e.g. [`TWO_HARMONIC`] or [`FOUR_HARMONIC`].
    pub fn harmonics_at(omegas: &[f64]) -> Self {
        Command::Harmonics(omegas.iter().map(|&w| Harmonic::unit(w)).collect())
    }

    /// The number of channels `n_r`.
    pub fn n_r(&self) -> usize {
        match self {
            Command::Constant(v) => v.len(),
            Command::Step { .. } | Command::Harmonics(_) => 1,
        }
    }

    /// The value of the single channel of a generated command at step `k` (for a constant
    /// one, its first channel, 0 when it has none).
    pub fn value(&self, k: u64) -> f64 {
        match self {
            Command::Constant(v) => v.first().copied().unwrap_or(0.0),
            Command::Step { amplitude, start } => {
                if k >= *start {
                    *amplitude
                } else {
                    0.0
                }
            }
            Command::Harmonics(h) => sum_at(h, k),
        }
    }

    /// Writes `r_k` into `r`, which has [`Command::n_r`] entries. Does not allocate.
    pub fn write(&self, k: u64, r: &mut [f64]) {
        match self {
            Command::Constant(v) => r.copy_from_slice(v),
            _ => r[0] = self.value(k),
        }
    }

    /// True when every value is finite and every harmonic valid ([`Harmonic::is_valid`]).
    pub fn is_valid(&self) -> bool {
        match self {
            Command::Constant(v) => v.iter().all(|x| x.is_finite()),
            Command::Step { amplitude, .. } => amplitude.is_finite(),
            Command::Harmonics(h) => !h.is_empty() && h.iter().all(Harmonic::is_valid),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn r(c: &Command, k: u64) -> f64 {
        let mut out = vec![f64::NAN; c.n_r()];
        c.write(k, &mut out);
        out[0]
    }

    #[test]
    fn a_step_is_zero_before_its_start_and_its_amplitude_from_it() {
        let c = Command::Step {
            amplitude: 1.5,
            start: 3,
        };
        assert_eq!(c.n_r(), 1);
        let got: Vec<f64> = (0..6).map(|k| r(&c, k)).collect();
        assert_eq!(got, [0.0, 0.0, 0.0, 1.5, 1.5, 1.5]);
        let unit = Command::Step {
            amplitude: 1.0,
            start: 0,
        };
        assert!((0..200).all(|k| r(&unit, k) == 1.0));
    }

    #[test]
    fn the_two_and_four_harmonic_commands_are_the_chapters_formulas() {
        let two = Command::harmonics_at(&TWO_HARMONIC);
        let four = Command::harmonics_at(&FOUR_HARMONIC);
        for k in 0..1000u64 {
            let kf = k as f64;
            assert_eq!(r(&two, k), kf.cos() + (kf / 8.0).cos(), "k = {k}");
            let expected = kf.cos() + (kf / 2.0).cos() + (kf / 4.0).cos() + (kf / 8.0).cos();
            assert_eq!(r(&four, k), expected, "k = {k}");
        }
        assert_eq!(r(&two, 0), 2.0);
        assert_eq!(r(&four, 0), 4.0);
    }

    #[test]
    fn explicit_harmonics_carry_amplitude_and_phase() {
        let c = Command::Harmonics(vec![
            Harmonic {
                amplitude: 2.0,
                omega: 0.3,
                phase: 0.5,
            },
            Harmonic {
                amplitude: -1.0,
                omega: 0.0,
                phase: 0.0,
            },
        ]);
        for k in [0u64, 1, 10, 99] {
            assert_eq!(r(&c, k), 2.0 * (0.3 * k as f64 + 0.5).cos() - 1.0);
        }
    }

    #[test]
    fn a_constant_command_is_held() {
        let c = Command::Constant(vec![1.0, -1.0]);
        assert_eq!(c.n_r(), 2);
        let mut out = [0.0; 2];
        for k in [0, 7, 1_000_000] {
            c.write(k, &mut out);
            assert_eq!(out, [1.0, -1.0]);
        }
        assert_eq!(Command::default().n_r(), 0);
    }

    #[test]
    fn validity() {
        assert!(Command::harmonics_at(&FOUR_HARMONIC).is_valid());
        assert!(!Command::Harmonics(Vec::new()).is_valid());
        assert!(!Command::harmonics_at(&[4.0]).is_valid());
        assert!(!Command::Constant(vec![f64::NAN]).is_valid());
        assert!(
            !Command::Step {
                amplitude: f64::INFINITY,
                start: 0
            }
            .is_valid()
        );
    }
}
