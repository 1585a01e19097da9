//! # The plants of chapter 4's examples, from the pole radius and angle `(ρ, ν)`
//!
//! Examples 1 and 3 (§4.5, §4.7) use the minimum-phase plant (4.83), Example 2 (§4.6)
//! the nonminimum-phase plant (4.88):
//!
//! ```text
//! (4.83)  N(q⁻¹)/D(q⁻¹) = (q⁻¹ − 0.5 q⁻²) / ((1 − ρ e^{jν} q⁻¹)(1 − ρ e^{−jν} q⁻¹))
//! (4.88)  N(q⁻¹)/D(q⁻¹) = (q⁻¹ − 1.5 q⁻²) / ((1 − ρ e^{jν} q⁻¹)(1 − ρ e^{−jν} q⁻¹))
//! ```
//!
//! so that, with real coefficients,
//!
//! ```text
//! N(q⁻¹) = [0, 1, −c],   c = 0.5 (4.83) or 1.5 (4.88): one zero at z = c,
//! D(q⁻¹) = [1, −2ρ cos ν, ρ²]:                       poles at z = ρ e^{±jν}.
//! ```
//!
//! The chapter sweeps `(ρ, ν)` for its figures (Figures 4.2a–4.14a) and shows the
//! responses at `ρ = 0.5`, `ν = π/4`. A scenario builds them with
//! `kind = "mrac-example"` and `[plant.mrac-example] example = 1 | 2, rho, nu`; `ρ` must
//! be in `(0, 1)` (an asymptotically stable plant, the chapter's range) and `ν` in
//! `[0, π]` (the angle of the upper pole; `ν = 0` or `π` gives a double real pole). The
//! difference equation is then run exactly ([`crate::discrete`]). Example 3 is (4.83)
//! with the input disturbance at 0.35 rad/step (`[plant.input-disturbance]`); the
//! reference models (4.84)/(4.89) are the service's, not the plant's.

use crate::discrete::{DiscreteTf, DiscreteTfError};
use std::f64::consts::PI;
use std::fmt;

/// The frequency of Example 3's input disturbance, rad per step (§4.7).
pub const EXAMPLE_3_DISTURBANCE_RAD_STEP: f64 = 0.35;

/// Which plant of chapter 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MracExample {
    /// `example = 1`: the minimum-phase plant (4.83), zero at 0.5 (Examples 1 and 3).
    MinimumPhase,
    /// `example = 2`: the nonminimum-phase plant (4.88), zero at 1.5 (Example 2).
    NonminimumPhase,
}

impl MracExample {
    /// The example for `example = n` in the file (1 or 2).
    pub fn from_number(n: i64) -> Option<Self> {
        match n {
            1 => Some(MracExample::MinimumPhase),
            2 => Some(MracExample::NonminimumPhase),
            _ => None,
        }
    }

    /// Its number in the file: 1 or 2.
    pub fn number(self) -> u8 {
        match self {
            MracExample::MinimumPhase => 1,
            MracExample::NonminimumPhase => 2,
        }
    }

    /// The dissertation's equation: `"(4.83)"` or `"(4.88)"`.
    pub fn equation(self) -> &'static str {
        match self {
            MracExample::MinimumPhase => "(4.83)",
            MracExample::NonminimumPhase => "(4.88)",
        }
    }

    /// The plant's zero `c` (`N(q⁻¹) = q⁻¹ − c q⁻²`): 0.5 or 1.5.
    pub fn zero(self) -> f64 {
        match self {
            MracExample::MinimumPhase => 0.5,
            MracExample::NonminimumPhase => 1.5,
        }
    }

    /// The plant (4.83) or (4.88) with poles at `ρ e^{±jν}`.
    pub fn plant(self, rho: f64, nu: f64) -> Result<DiscreteTf, MracExampleError> {
        if !(rho.is_finite() && rho > 0.0 && rho < 1.0) {
            return Err(MracExampleError::Rho(rho));
        }
        if !(nu.is_finite() && (0.0..=PI).contains(&nu)) {
            return Err(MracExampleError::Nu(nu));
        }
        DiscreteTf::new(
            vec![0.0, 1.0, -self.zero()],
            pole_polynomial(rho, nu).to_vec(),
        )
        .map_err(MracExampleError::Tf)
    }
}

/// `(1 − ρ e^{jν} q⁻¹)(1 − ρ e^{−jν} q⁻¹) = 1 − 2ρ cos ν q⁻¹ + ρ² q⁻²`, ascending powers.
pub fn pole_polynomial(rho: f64, nu: f64) -> [f64; 3] {
    [1.0, -2.0 * rho * nu.cos(), rho * rho]
}

/// The example and the `(ρ, ν)` a plant was built from (reported by `describe`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExampleParams {
    /// (4.83) or (4.88).
    pub example: MracExample,
    /// Pole radius `ρ`.
    pub rho: f64,
    /// Pole angle `ν`, rad.
    pub nu: f64,
}

/// Why `(ρ, ν)` were refused.
#[derive(Debug, Clone, PartialEq)]
pub enum MracExampleError {
    /// `ρ` is not in `(0, 1)` or not finite.
    Rho(f64),
    /// `ν` is not in `[0, π]` or not finite.
    Nu(f64),
    /// The coefficients were refused (cannot happen for valid `(ρ, ν)`).
    Tf(DiscreteTfError),
}

impl fmt::Display for MracExampleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MracExampleError::Rho(r) => write!(
                f,
                "{r} is not a pole radius in (0, 1) (the plant must be asymptotically stable)"
            ),
            MracExampleError::Nu(v) => {
                write!(f, "{v} is not a pole angle in [0, π] rad")
            }
            MracExampleError::Tf(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for MracExampleError {}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Complex;

    fn close(a: Complex<f64>, b: Complex<f64>) -> bool {
        (a - b).norm() < 1e-12
    }

    /// Every expected root matches one found root, and there are as many of each.
    fn same_roots(found: &[Complex<f64>], expected: &[Complex<f64>]) {
        assert_eq!(found.len(), expected.len(), "{found:?} vs {expected:?}");
        for e in expected {
            assert!(
                found.iter().any(|f| close(*f, *e)),
                "{e} not among {found:?}"
            );
        }
    }

    #[test]
    fn the_poles_are_at_rho_e_to_the_plus_minus_j_nu_and_the_zero_is_the_chapters() {
        let cases = [
            (0.5, PI / 4.0),
            (0.9, 0.3),
            (0.2, 2.5),
            (0.99, PI / 2.0),
            (0.7, 1e-3),
        ];
        for example in [MracExample::MinimumPhase, MracExample::NonminimumPhase] {
            for (rho, nu) in cases {
                let g = example.plant(rho, nu).unwrap();
                let pole = Complex::from_polar(rho, nu);
                same_roots(&g.poles().unwrap(), &[pole, pole.conj()]);
                same_roots(&g.zeros().unwrap(), &[Complex::new(example.zero(), 0.0)]);
                assert_eq!(g.num(), &[0.0, 1.0, -example.zero()]);
            }
        }
        assert_eq!(MracExample::MinimumPhase.zero(), 0.5);
        assert_eq!(MracExample::NonminimumPhase.zero(), 1.5);
    }

    #[test]
    fn the_denominator_is_the_product_of_the_two_first_order_factors() {
        // (1 − p q⁻¹)(1 − p̄ q⁻¹) expanded with complex arithmetic.
        let (rho, nu) = (0.5, PI / 4.0);
        let p = Complex::from_polar(rho, nu);
        let g = MracExample::MinimumPhase.plant(rho, nu).unwrap();
        let expected = [1.0, (-p - p.conj()).re, (p * p.conj()).re];
        for (a, e) in g.den().iter().zip(expected) {
            assert!((a - e).abs() < 1e-15, "{:?} vs {expected:?}", g.den());
        }
        // At (0.5, π/4): 1 − 0.7071… q⁻¹ + 0.25 q⁻².
        assert!((g.den()[1] + 0.5 * 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(g.den()[2], 0.25);
    }

    #[test]
    fn bad_rho_or_nu_are_refused() {
        let ex = MracExample::MinimumPhase;
        for rho in [0.0, 1.0, -0.5, 1.5, f64::NAN, f64::INFINITY] {
            assert!(
                matches!(ex.plant(rho, 0.5), Err(MracExampleError::Rho(_))),
                "{rho}"
            );
        }
        for nu in [-0.1, 3.2, f64::NAN, f64::NEG_INFINITY] {
            assert!(
                matches!(ex.plant(0.5, nu), Err(MracExampleError::Nu(_))),
                "{nu}"
            );
        }
        assert!(ex.plant(0.5, 0.0).is_ok());
        assert!(ex.plant(0.5, PI).is_ok());
        assert_eq!(MracExample::from_number(3), None);
        assert_eq!(MracExample::from_number(2).unwrap().number(), 2);
        assert_eq!(MracExample::from_number(1).unwrap().equation(), "(4.83)");
    }
}
