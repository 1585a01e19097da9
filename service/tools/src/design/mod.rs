//! # design: offline tools that turn a model or measured data into an RCAC target model
//!
//! The path of section 3.2 of the dissertation, from a plant to the target model `G_f` of
//! (2.19) that RCAC's configuration reads:
//!
//! ```text
//!  scenario model ──► model FRF G_d(e^{jθ}) ─┐
//!                     (model.rs)             ├─► complex windowed average (3.40) ─► fit ─┐
//!  CSV log (u, y) ──► Welch H1 FRF, coherence┤   (dtf.rs)                               ├─► G_f = β Ĝ_d z^{-d}
//!                     and delays (welch.rs)  └─► log-frequency optimization (3.44)–(3.47)┘    (target.rs, (3.49))
//!  model ─────────► Markov parameters H_i, FIR target model (3.39) (markov.rs)
//! ```
//!
//! Beside that path, the robust gain of the sampling arm (7.39)–(7.41): the semidefinite
//! program (`sdp.rs`, `robust_gain.rs`, with the other objectives of
//! `robust_gain_objective.rs`, under the crate feature `sdp`, which links BLAS and
//! LAPACK) and its file ([`robust_gain_file`], always built, so the committed gain is
//! checked by the default tests).
//!
//! Everything here runs offline (it allocates freely); nothing is called from the RT loop.
//!
//! ## Conventions
//!
//! - Frequencies are normalized, `θ = ω T_s ∈ [0, π]` rad/sample; [`Frf::ts`] converts.
//! - A discrete transfer function is written in `z` with coefficients in descending powers,
//!   `G(z) = (b_0 z^m + … + b_m)/(z^n + a_1 z^{n−1} + … + a_n)`, as in (3.42).
//! - A response matrix has one entry per `(output, input)` channel, stored channel-major:
//!   channel `c = output · n_inputs + input`.

#![allow(clippy::needless_range_loop)]

pub mod csvlog;
pub mod dtf;
pub mod frf_file;
pub mod markov;
pub mod model;
pub mod plots;
#[cfg(feature = "sdp")]
pub mod robust_gain;
pub mod robust_gain_file;
#[cfg(feature = "sdp")]
pub mod robust_gain_objective;
#[cfg(feature = "sdp")]
pub mod sdp;
pub mod target_response;
pub mod welch;

use nalgebra::{Complex, DMatrix};

/// A complex number of `f64`, the element of every response here.
pub type C64 = Complex<f64>;

/// A frequency response: `G(e^{jθ_k})` of every `(output, input)` channel on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Frf {
    /// Sample period `T_s`, s (`ω = θ / T_s`).
    pub ts: f64,
    /// Grid `θ_k` in rad/sample, increasing, within `[0, π]`.
    pub theta: Vec<f64>,
    /// Number of outputs.
    pub n_outputs: usize,
    /// Number of inputs.
    pub n_inputs: usize,
    /// `response[c][k]`: channel `c = output · n_inputs + input` at `theta[k]`.
    pub response: Vec<Vec<C64>>,
}

impl Frf {
    /// The response of an `n_outputs × n_inputs` system at sample period `ts` on the grid
    /// `theta`, from its `(output, input)` matrix `at(θ_k)` at each grid point.
    pub fn from_fn(
        ts: f64,
        theta: &[f64],
        (n_outputs, n_inputs): (usize, usize),
        mut at: impl FnMut(f64) -> DMatrix<C64>,
    ) -> Frf {
        let never = |e: std::convert::Infallible| match e {};
        Self::try_from_fn(ts, theta, (n_outputs, n_inputs), |th| Ok(at(th))).unwrap_or_else(never)
    }

    /// [`Frf::from_fn`] with an `at` that can fail; its first error is returned.
    pub fn try_from_fn<E>(
        ts: f64,
        theta: &[f64],
        (n_outputs, n_inputs): (usize, usize),
        mut at: impl FnMut(f64) -> Result<DMatrix<C64>, E>,
    ) -> Result<Frf, E> {
        let mut response = vec![Vec::with_capacity(theta.len()); n_outputs * n_inputs];
        for &th in theta {
            let g = at(th)?;
            for o in 0..n_outputs {
                for i in 0..n_inputs {
                    response[o * n_inputs + i].push(g[(o, i)]);
                }
            }
        }
        Ok(Frf {
            ts,
            theta: theta.to_vec(),
            n_outputs,
            n_inputs,
            response,
        })
    }

    /// The response of channel `(output, input)`.
    pub fn channel(&self, output: usize, input: usize) -> &[C64] {
        &self.response[output * self.n_inputs + input]
    }

    /// The grid in rad/s.
    pub fn omega(&self) -> Vec<f64> {
        self.theta.iter().map(|t| t / self.ts).collect()
    }

    /// The grid in Hz.
    pub fn hz(&self) -> Vec<f64> {
        self.theta
            .iter()
            .map(|t| t / (2.0 * std::f64::consts::PI * self.ts))
            .collect()
    }
}

/// A frequency grid that cannot be made, naming the bad value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The ends are not `0 ≤ low < high ≤ π`.
    #[error("frequency grid [{low}, {high}] rad/sample must satisfy 0 ≤ low < high ≤ π")]
    Range {
        /// The lower end.
        low: f64,
        /// The upper end.
        high: f64,
    },
    /// Fewer than 2 points.
    #[error("frequency grid needs at least 2 points, got {0}")]
    Points(usize),
    /// A logarithmic grid from 0.
    #[error("a logarithmic frequency grid needs a lower end above 0")]
    LogFromZero,
}

message_from!(GridError);

/// A grid of `points` frequencies over `[θ_lo, θ_hi]` rad/sample, linear or logarithmic
/// (a logarithmic grid needs `θ_lo > 0`). Errors name the bad value.
pub fn grid(theta_lo: f64, theta_hi: f64, points: usize, log: bool) -> Result<Vec<f64>, GridError> {
    let pi = std::f64::consts::PI;
    if !(theta_lo.is_finite()
        && theta_hi.is_finite()
        && 0.0 <= theta_lo
        && theta_lo < theta_hi
        && theta_hi <= pi)
    {
        return Err(GridError::Range {
            low: theta_lo,
            high: theta_hi,
        });
    }
    if points < 2 {
        return Err(GridError::Points(points));
    }
    if log && theta_lo <= 0.0 {
        return Err(GridError::LogFromZero);
    }
    let last = (points - 1) as f64;
    Ok((0..points)
        .map(|i| {
            let s = i as f64 / last;
            if log {
                theta_lo * (theta_hi / theta_lo).powf(s)
            } else {
                theta_lo + (theta_hi - theta_lo) * s
            }
        })
        .collect())
}

/// Evaluates `num(z)/den(z)` (descending powers) at `z`.
pub fn eval_tf(num: &[f64], den: &[f64], z: C64) -> C64 {
    horner(num, z) / horner(den, z)
}

/// `c_0 z^{n} + … + c_n` at `z` (Horner's scheme).
pub fn horner(coeffs: &[f64], z: C64) -> C64 {
    coeffs
        .iter()
        .fold(C64::new(0.0, 0.0), |acc, &c| acc * z + C64::new(c, 0.0))
}
