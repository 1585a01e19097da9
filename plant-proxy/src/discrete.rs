//! # Discrete-time transfer-function plants, run by their difference equation
//!
//! Chapter 4 states its plants per step, in the backward shift `q⁻¹`:
//!
//! ```text
//! D(q⁻¹) y_k = N(q⁻¹) u_k,     D(q⁻¹) = a_0 + a_1 q⁻¹ + … + a_n q⁻ⁿ,
//!                              N(q⁻¹) = b_0 + b_1 q⁻¹ + … + b_m q⁻ᵐ,
//! ```
//!
//! (e.g. (4.83) and (4.88), [`crate::mrac_examples`]). A [`DiscreteTf`] holds the
//! coefficients as given in the file (`[plant.discrete] num = [b_0, …, b_m]`,
//! `den = [a_0, …, a_n]`), divided by `a_0` once at load time (exact when `a_0 = 1`), and
//! [`DifferenceEquation`] runs the plant at the scenario's sample rate with no
//! discretization at all: one step of the plant is one sample,
//!
//! ```text
//! y_k = Σ_{j=1..m} b_j u_{k−j} − Σ_{i=1..n} a_i y_{k−i}
//! ```
//!
//! evaluated in exactly this order (the `u` terms by increasing `j`, then the `y` terms by
//! increasing `i`, accumulated from `0.0`), so an independent recursion written the same
//! way reproduces it bit for bit. The plant starts at rest: every `u_{k}` and `y_{k}` with
//! `k < 0` is zero.
//!
//! **No direct feedthrough: `b_0 = 0`.** `y_k` is published before the service answers
//! with `u_k` (the measurement convention of [`crate::sim`]), so `y_k` cannot depend on
//! `u_k`; the chapter's plants have `b_0 = 0` (relative degree ≥ 1). A further pure delay
//! is either leading zeros of `num` or `plant.input-delays = [d]` (`q^{-d}` on the input).
//!
//! The state of the recursion is the non-minimal
//! `x_k = [y_{k−1}, …, y_{k−n}, u_{k−1}, …, u_{k−m}]` (`n + m` entries,
//! [`DiscreteTf::n_states`]). As a function of `z` the plant is
//! `G(z) = (b_0 z^N + … + b_m z^{N−m}) / (a_0 z^N + … + a_n z^{N−n})`, `N = max(n, m)`
//! ([`DiscreteTf::descending`]), whose poles and zeros [`DiscreteTf::poles`] and
//! [`DiscreteTf::zeros`] compute.
//!
//! [`DiscretePlant`] adds what drives it: the input disturbance of Example 3 (§4.7),
//! `d_k = Σ A cos(ω k + φ)` ([`crate::harmonic`]) added to the applied input,
//! `u_k ← u_k + d_k`. The performance variable is the output itself, `z_k = y_k`: the
//! service computes the model-following error `e_k = y_k − y_{m,k}` against its own
//! reference model ((4.4), (4.84), metric (4.85)).

use crate::harmonic::Harmonic;
use crate::lti::{LtiError, eigenvalues};
use nalgebra::{Complex, DMatrix};
use std::fmt;

/// The largest number of coefficients of `num` or `den` (the recursion keeps
/// `n + m` past values).
pub const MAX_COEFFICIENTS: usize = 501;

/// Why the coefficients of a discrete transfer function were refused.
#[derive(Debug, Clone, PartialEq)]
pub enum DiscreteTfError {
    /// `den` has no coefficient.
    EmptyDenominator,
    /// `den[0]` is zero (or not a usable divisor).
    ZeroLeadingDenominator,
    /// `num` has no coefficient.
    EmptyNumerator,
    /// `num[0]` is not zero: a direct feedthrough, which the measurement convention
    /// cannot simulate.
    DirectFeedthrough(f64),
    /// A coefficient is NaN or infinite.
    NonFinite {
        /// `"num"` or `"den"`.
        which: &'static str,
        /// Its index.
        index: usize,
    },
    /// Too many coefficients ([`MAX_COEFFICIENTS`]).
    TooLong {
        /// `"num"` or `"den"`.
        which: &'static str,
        /// How many were given.
        len: usize,
    },
    /// A coefficient divided by `den[0]` is no longer finite.
    Overflow,
}

impl DiscreteTfError {
    /// The key the error is about: `"num"` or `"den"`, with an index when there is one
    /// (`"den[2]"`).
    pub fn key(&self) -> String {
        match self {
            DiscreteTfError::EmptyDenominator
            | DiscreteTfError::ZeroLeadingDenominator
            | DiscreteTfError::Overflow => "den".into(),
            DiscreteTfError::EmptyNumerator | DiscreteTfError::DirectFeedthrough(_) => "num".into(),
            DiscreteTfError::NonFinite { which, index } => format!("{which}[{index}]"),
            DiscreteTfError::TooLong { which, .. } => (*which).into(),
        }
    }
}

impl fmt::Display for DiscreteTfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DiscreteTfError::EmptyDenominator => {
                write!(f, "is empty: give [a_0, a_1, …] with a_0 ≠ 0")
            }
            DiscreteTfError::ZeroLeadingDenominator => {
                write!(f, "the leading coefficient a_0 (of q^0) is zero")
            }
            DiscreteTfError::EmptyNumerator => write!(f, "is empty: give [0.0, b_1, …]"),
            DiscreteTfError::DirectFeedthrough(b0) => write!(
                f,
                "b_0 = {b0}: the coefficient of q^0 must be 0 (y_k is published before u_k \
                 arrives, so the plant cannot feed u_k through; start with 0.0 for the \
                 one-step delay)"
            ),
            DiscreteTfError::NonFinite { .. } => write!(f, "is not finite"),
            DiscreteTfError::TooLong { len, .. } => {
                write!(f, "has {len} coefficients, at most {MAX_COEFFICIENTS}")
            }
            DiscreteTfError::Overflow => write!(
                f,
                "dividing by the leading coefficient a_0 makes a coefficient overflow"
            ),
        }
    }
}

impl std::error::Error for DiscreteTfError {}

/// A discrete transfer function `N(q⁻¹)/D(q⁻¹)` with `b_0 = 0`, normalized so that
/// `a_0 = 1` (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteTf {
    num: Vec<f64>,
    den: Vec<f64>,
}

impl DiscreteTf {
    /// Validates `num = [b_0, …, b_m]` and `den = [a_0, …, a_n]` (ascending powers of `q⁻¹`)
    /// and divides both by `a_0`.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self, DiscreteTfError> {
        for (which, v) in [("num", &num), ("den", &den)] {
            if v.len() > MAX_COEFFICIENTS {
                return Err(DiscreteTfError::TooLong {
                    which,
                    len: v.len(),
                });
            }
            if let Some(index) = v.iter().position(|x| !x.is_finite()) {
                return Err(DiscreteTfError::NonFinite { which, index });
            }
        }
        let a0 = *den.first().ok_or(DiscreteTfError::EmptyDenominator)?;
        if a0 == 0.0 {
            return Err(DiscreteTfError::ZeroLeadingDenominator);
        }
        let b0 = *num.first().ok_or(DiscreteTfError::EmptyNumerator)?;
        if b0 != 0.0 {
            return Err(DiscreteTfError::DirectFeedthrough(b0));
        }
        let scale = |v: Vec<f64>| -> Vec<f64> {
            if a0 == 1.0 {
                v
            } else {
                v.into_iter().map(|x| x / a0).collect()
            }
        };
        let (num, den) = (scale(num), scale(den));
        if num.iter().chain(&den).any(|x| !x.is_finite()) {
            return Err(DiscreteTfError::Overflow);
        }
        Ok(Self { num, den })
    }

    /// `[b_0 = 0, b_1, …, b_m]` (divided by the given `a_0`).
    pub fn num(&self) -> &[f64] {
        &self.num
    }

    /// `[1, a_1, …, a_n]`.
    pub fn den(&self) -> &[f64] {
        &self.den
    }

    /// `n`, the degree of `D(q⁻¹)`: the number of past outputs in the recursion.
    pub fn n(&self) -> usize {
        self.den.len() - 1
    }

    /// `m`, the degree of `N(q⁻¹)`: the number of past inputs in the recursion.
    pub fn m(&self) -> usize {
        self.num.len() - 1
    }

    /// `n + m`: the length of the recursion's state `[y_{k−1}, …, y_{k−n}, u_{k−1}, …]`.
    pub fn n_states(&self) -> usize {
        self.n() + self.m()
    }

    /// `G(z)` in descending powers of `z`: `(numerator, denominator)`, both padded to
    /// `N + 1 = max(n, m) + 1` coefficients, then the numerator's leading zeros dropped
    /// (`[0.0]` for the zero plant).
    pub fn descending(&self) -> (Vec<f64>, Vec<f64>) {
        let big_n = self.n().max(self.m());
        let pad = |v: &[f64]| {
            let mut p = v.to_vec();
            p.resize(big_n + 1, 0.0);
            p
        };
        let num = pad(&self.num);
        let num = match num.iter().position(|&b| b != 0.0) {
            Some(i) => num[i..].to_vec(),
            None => vec![0.0],
        };
        (num, pad(&self.den))
    }

    /// The poles of `G(z)`: the roots of the descending denominator (`N` of them).
    pub fn poles(&self) -> Result<Vec<Complex<f64>>, LtiError> {
        roots(&self.descending().1)
    }

    /// The zeros of `G(z)`: the roots of the descending numerator (none for the zero plant).
    pub fn zeros(&self) -> Result<Vec<Complex<f64>>, LtiError> {
        let num = self.descending().0;
        if num.iter().all(|&b| b == 0.0) {
            return Ok(Vec::new());
        }
        roots(&num)
    }
}

/// The roots of `c_0 pᵈ + c_1 pᵈ⁻¹ + … + c_d` (`c_0 ≠ 0`), as the eigenvalues of its
/// companion matrix.
pub fn roots(c: &[f64]) -> Result<Vec<Complex<f64>>, LtiError> {
    let d = c.len().saturating_sub(1);
    if d == 0 {
        return Ok(Vec::new());
    }
    let mut m = DMatrix::zeros(d, d);
    for j in 0..d {
        m[(0, j)] = -c[j + 1] / c[0];
    }
    for i in 1..d {
        m[(i, i - 1)] = 1.0;
    }
    eigenvalues(&m)
}

/// The exact recursion of a [`DiscreteTf`] (see the module documentation). Allocates only
/// in [`DifferenceEquation::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct DifferenceEquation {
    tf: DiscreteTf,
    /// `[y_{k−1}, …, y_{k−n}, u_{k−1}, …, u_{k−m}]`.
    state: Vec<f64>,
    /// `y_k`.
    y: f64,
}

impl DifferenceEquation {
    /// The plant `tf` at rest at `k = 0` (`y_0 = 0`).
    pub fn new(tf: DiscreteTf) -> Self {
        let state = vec![0.0; tf.n_states()];
        Self { tf, state, y: 0.0 }
    }

    /// The transfer function it runs.
    pub fn tf(&self) -> &DiscreteTf {
        &self.tf
    }

    /// The output `y_k` at the current step.
    pub fn output(&self) -> f64 {
        self.y
    }

    /// The state `[y_{k−1}, …, y_{k−n}, u_{k−1}, …, u_{k−m}]`.
    pub fn state(&self) -> &[f64] {
        &self.state
    }

    /// Applies `u_k` and steps to `k + 1`:
    /// `y_{k+1} = Σ_{j=1..m} b_j u_{k+1−j} − Σ_{i=1..n} a_i y_{k+1−i}`. Does not allocate.
    pub fn step(&mut self, u: f64) {
        let n = self.tf.n();
        let (ys, us) = self.state.split_at_mut(n);
        if n > 0 {
            ys.rotate_right(1);
            ys[0] = self.y;
        }
        if !us.is_empty() {
            us.rotate_right(1);
            us[0] = u;
        }
        let mut acc = 0.0;
        for (b, u_past) in self.tf.num[1..].iter().zip(us.iter()) {
            acc += b * u_past;
        }
        for (a, y_past) in self.tf.den[1..].iter().zip(ys.iter()) {
            acc -= a * y_past;
        }
        self.y = acc;
    }

    /// Back to rest at `k = 0`. Does not allocate.
    pub fn reset(&mut self) {
        self.state.fill(0.0);
        self.y = 0.0;
    }
}

/// A discrete-time plant of a scenario (`kind = "discrete"` or `"mrac-example"`): one
/// input `u`, one output `y`, `z = y`, no disturbance input `w`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscretePlant {
    /// `N(q⁻¹)/D(q⁻¹)`.
    pub tf: DiscreteTf,
    /// The input disturbance `d_k = Σ A cos(ω k + φ)` added to the applied input
    /// (`[plant.input-disturbance]`; empty: none).
    pub input_disturbance: Vec<Harmonic>,
    /// The chapter's example and its `(ρ, ν)` when the plant was built by
    /// [`crate::mrac_examples`].
    pub example: Option<crate::mrac_examples::ExampleParams>,
}

#[cfg(test)]
mod tests;
