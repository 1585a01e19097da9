//! Dereverberated transfer functions (DTFs), section 3.2 of the dissertation.
//!
//! A DTF `Ĝ_d(z)` is a low-order, asymptotically stable model that follows the magnitude
//! and phase trend of a lightly damped structure `G_d(z)` and ignores its resonances and
//! anti-resonances. Two constructions are implemented, both channel by channel (SISO):
//!
//! ## Complex windowed average, §3.2.1
//!
//! The response is smoothed by a complex windowed average of half-width `Δ` (rad/sample):
//!
//! ```text
//!                       1           θ_hi
//! Ḡ_d(e^{jθ}) = ─────────────────── ∫  G_d(e^{jν}) dν,   θ_lo = max(0, θ − Δ),      (3.40)
//!                θ_hi − θ_lo        θ_lo                  θ_hi = min(π, θ + Δ).
//! ```
//!
//! (The dissertation names the upper end `θ_min` and the lower end `θ_max`; the window is
//! the same.) [`windowed_average`] integrates a response given on a grid with the trapezoid
//! rule on its piecewise-linear interpolant (window ends interpolated linearly) and refuses
//! a grid with fewer than [`MIN_POINTS_PER_WINDOW`] points in some window;
//! [`windowed_average_of`] evaluates a model densely inside each window (composite Simpson)
//! for an average that is exact to quadrature accuracy.
//!
//! `Ĝ_d` is then fitted to `Ḡ_d` with a fixed order and asymptotic stability enforced. The
//! dissertation uses "Algorithm 1 of \[65\] except that the order is fixed"; that reference is
//! not available here, so [`fit`] does the following instead, on the real-coefficient model
//! `Ĝ(z) = (b_0 z^m + … + b_m)/(z^n + a_1 z^{n−1} + … + a_n)`:
//!
//! 1. Sanathanan–Koerner (SK) iterations: with `A_{(l)}` the denominator of iteration `l`
//!    (`A_{(0)} = 1`, so the first iteration is Levy's equation-error fit), solve the linear
//!    least-squares problem
//!    `min Σ_k w_k |B(z_k) − Ḡ_k A(z_k)|² / |A_{(l)}(z_k)|²`, `z_k = e^{jθ_k}`,
//!    for the `m + 1 + n` real coefficients by stacking real and imaginary parts
//!    ([`SK_ITERATIONS`] iterations, or a caller's count with [`fit_iterations`]);
//! 2. stability: every pole with `|p| > 1` is reflected to `1/p̄` (same magnitude
//!    response up to a constant, phase changed), and a pole left within `10⁻⁶` of the unit
//!    circle is pulled in to radius [`MAX_FIT_POLE_RADIUS`];
//! 3. with that denominator fixed, the numerator is re-solved by linear least squares on
//!    the output error `Σ w_k |B(z_k)/A(z_k) − Ḡ_k|²`.
//!
//! The default weights `w_k` are the trapezoid weights of the grid, so the cost
//! approximates `∫ |B/A − Ḡ|² dθ`.
//!
//! [`averaged_dtfs`] does both steps for every channel of an [`Frf`] (MIMO: channel by
//! channel, as in the dissertation).
//!
//! ## Optimization, §3.2.2
//!
//! ```text
//!  min_{k, a, b, n̂, m̂} ∫_0^π |G_d(e^{jθ}) − Ĝ_d(e^{jθ})|² d(log θ)                 (3.44)
//!  subject to  Ĝ_d(z) = k Π_{i=1}^{m̂} (z + b_i) / Π_{i=1}^{n̂} (z + a_i),            (3.45)
//!              m̂ ≤ n̂ ≤ n̂_max,                                                     (3.46)
//!              Ĝ_d asymptotically stable,                                          (3.47)
//! ```
//!
//! with real `a_i`, `b_i`. [`optimize`] discretizes (3.44) on a logarithmic grid
//! `θ_lo … π` with trapezoid weights in `log θ` ([`log_weights`]); the integral diverges at
//! `θ → 0` only through the grid's lower end, and that end changes the result: the default
//! [`DEFAULT_THETA_LO`] `= 2·10⁻³ π` (0.1 Hz at `T_s = 0.01` s) reproduces (3.48) to three
//! digits, `10⁻³ π` gives a pole 0.002 closer to the origin and a gain 1 % lower (see
//! [`example_3_41`]). Stability is structural: `a_i = ρ tanh(s_i)`, and likewise
//! `b_i = ρ tanh(t_i)`, with `ρ =` [`MAX_ROOT`], so poles and zeros are real and strictly
//! inside the unit circle (the zeros are kept minimum phase as well). For given `a`, `b`
//! the gain `k` minimizes the weighted cost in closed form,
//! `k = Σ w_k Re(φ̄_k G_k) / Σ w_k |φ_k|²` with `φ = Π(z + b)/Π(z + a)`, and the remaining
//! `n̂ + m̂` parameters are minimized by the Nelder–Mead simplex method of the `argmin`
//! crate. [`optimize_with`] documents the search and its defaults ([`OptimizeOptions`]):
//!
//! - the search evaluates (3.44) on the grid lumped into ≤ [`DEFAULT_COST_CELLS`] cells of
//!   equal width in `log θ` (weighted mean response per cell: every bin still counts), and
//!   each structure's best point is polished on the full grid, where all costs are reported;
//! - orders `n̂ = 1, 2, …` in turn, order `n̂ + 1` warm-started from the order-`n̂`
//!   solutions plus a new pole or a cancelling pole–zero pair (continuation) and from two
//!   spread-out cold starts, the runs of one order in parallel (rayon);
//! - parsimony: a structure with more parameters must lower the relative cost by
//!   [`DEFAULT_MIN_GAIN`] (2 %) of the incumbent's to win, and the first order that does not
//!   is the last one tried;
//! - real poles (and zeros) closer than [`DEFAULT_MIN_SEPARATION`] (0.05) are penalized: the
//!   real-root constraint is often active and otherwise piles several poles onto nearly one
//!   point (a near-repeated, ill-conditioned cluster).
//!
//! The search is local (one start per structure, from the clustered poles), not an
//! exhaustive multi-start search, so its cost can lie a few percent above the best
//! optimum; every structure tried is returned with its relative cost and the number of cost evaluations
//! ([`optimize_all`], [`Candidate`]).
//! [`optimized_dtfs`] does it for every channel of an [`Frf`].

use super::{C64, Frf, eval_tf};
use nalgebra::{DMatrix, DVector};
use plant_proxy::lti::{LtiError, Tf, eigenvalues};
use std::f64::consts::PI;

#[cfg(test)]
mod tests;

/// Fewest grid points a window of (3.40) must hold for [`windowed_average`].
pub const MIN_POINTS_PER_WINDOW: usize = 8;

/// Number of Sanathanan–Koerner iterations of [`fit`].
pub const SK_ITERATIONS: usize = 30;

/// Largest pole radius [`fit`] leaves (poles closer to the unit circle are pulled in).
pub const MAX_FIT_POLE_RADIUS: f64 = 1.0 - 1e-6;

/// Bound `ρ` on `|a_i|`, `|b_i|` in [`optimize`]: `a_i = ρ tanh(s_i)`.
pub const MAX_ROOT: f64 = 0.999;

/// Default lower end of the logarithmic grid of [`optimize`], rad/sample (`2·10⁻³ π`).
pub const DEFAULT_THETA_LO: f64 = 2e-3 * PI;

/// Default number of points of the logarithmic grid of [`optimize`].
pub const DEFAULT_LOG_POINTS: usize = 1000;

/// A discrete SISO transfer function `num(z)/den(z)`, descending powers of `z`, `den`
/// monic, `num` without leading zeros (`[0.0]` when zero) and of degree ≤ that of `den`.
#[derive(Debug, Clone, PartialEq)]
pub struct Dtf {
    /// Numerator coefficients, descending powers.
    pub num: Vec<f64>,
    /// Denominator coefficients, descending powers, `den[0] = 1`.
    pub den: Vec<f64>,
}

/// A DTF that cannot be designed or analysed, naming the step (`what`) and the bad input.
#[derive(Debug, thiserror::Error)]
pub enum DtfError {
    /// A transfer function, realization or eigenvalue problem of `plant_proxy::lti`.
    #[error(transparent)]
    Lti(#[from] LtiError),
    /// A frequency grid that cannot be made.
    #[error(transparent)]
    Grid(#[from] super::GridError),
    /// Roots of the zero polynomial.
    #[error("the zero polynomial has no roots")]
    ZeroPolynomial,
    /// A window half-width outside `(0, π]`.
    #[error("window half-width Δ = {0} rad/sample must be in (0, π]")]
    Delta(f64),
    /// Log weights on a grid from 0.
    #[error("log weights: the grid must start above θ = 0")]
    LogFromZero,
    /// The least-squares solve failed (nalgebra's message).
    #[error("least squares: {0}")]
    LeastSquares(String),
    /// A step's input is not usable.
    #[error("{what}: {problem}")]
    Input {
        /// The step (`DTF fit`, `windowed average`, …).
        what: &'static str,
        /// What is wrong.
        problem: Problem,
    },
    /// A step failed for another reason.
    #[error("{what}: {source}")]
    In {
        /// The step.
        what: &'static str,
        /// Why.
        #[source]
        source: Box<DtfError>,
    },
    /// One channel of a multi-channel design failed.
    #[error("channel {channel}: {source}")]
    Channel {
        /// The channel (channel-major).
        channel: usize,
        /// Why.
        #[source]
        source: Box<DtfError>,
    },
    /// The optimization's Nelder–Mead failed.
    #[error("Nelder–Mead: {0}")]
    NelderMead(String),
    /// The optimization's Nelder–Mead returned no point.
    #[error("Nelder–Mead returned no point")]
    NoPoint,
}

impl DtfError {
    /// This error, in channel `channel`.
    pub fn in_channel(self, channel: usize) -> Self {
        DtfError::Channel {
            channel,
            source: Box::new(self),
        }
    }
}

message_from!(DtfError);

/// What is wrong with the input of a step of the DTF design.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    /// Fewer than 2 grid points.
    #[error("the grid needs at least 2 points, got {0}")]
    GridPoints(usize),
    /// A grid point outside `[0, π]`.
    #[error("θ[{k}] = {theta} is not within [0, π]")]
    OutOfRange {
        /// Its index.
        k: usize,
        /// Its value.
        theta: f64,
    },
    /// The grid does not increase at `k`.
    #[error("the grid must increase strictly (θ[{k}] = {at} ≥ θ[{}] = {next})", k + 1)]
    NotIncreasing {
        /// The index.
        k: usize,
        /// `θ[k]`.
        at: f64,
        /// `θ[k + 1]`.
        next: f64,
    },
    /// Not one response value per frequency.
    #[error("{values} response values for {frequencies} frequencies")]
    ResponseLength {
        /// The values.
        values: usize,
        /// The frequencies.
        frequencies: usize,
    },
    /// A NaN or infinite response value.
    #[error("the response at θ = {0} is not finite")]
    NotFinite(f64),
    /// A window reaches beyond the grid.
    #[error(
        "the window [{:.6}, {:.6}] rad/sample at θ = {theta:.6} reaches beyond the grid \
         [{:.6}, {:.6}]; give the response from 0 to π",
        window.0, window.1, grid.0, grid.1
    )]
    Beyond {
        /// The window.
        window: (f64, f64),
        /// Its centre.
        theta: f64,
        /// The grid's ends.
        grid: (f64, f64),
    },
    /// Too few grid points in a window.
    #[error(
        "only {inside} grid points in the window [{:.6}, {:.6}] at θ = {theta:.6} (Δ = {delta} \
         rad/sample); at least {MIN_POINTS_PER_WINDOW} are needed: use a grid finer than \
         {:.3e} rad/sample",
        window.0, window.1, delta / (MIN_POINTS_PER_WINDOW - 1) as f64
    )]
    Sparse {
        /// The points inside.
        inside: usize,
        /// The window.
        window: (f64, f64),
        /// Its centre.
        theta: f64,
        /// Its half-width.
        delta: f64,
    },
    /// More zeros than poles.
    #[error("{zeros} zeros exceed {poles} poles (the DTF must be proper)")]
    Improper {
        /// The zeros.
        zeros: usize,
        /// The poles.
        poles: usize,
    },
    /// Fewer equations than coefficients.
    #[error(
        "{frequencies} frequencies give {} equations for {unknowns} coefficients",
        2 * frequencies
    )]
    Equations {
        /// The frequencies.
        frequencies: usize,
        /// The coefficients.
        unknowns: usize,
    },
    /// Weights of the wrong number or sign.
    #[error("weights must be {0} finite, nonnegative numbers")]
    Weights(usize),
    /// `n̂_max = 0`.
    #[error("n̂_max must be at least 1")]
    NoOrder,
    /// Negative optimization options (their debug form).
    #[error("min_gain and min_separation must be nonnegative, got {0}")]
    Options(String),
    /// A zero response.
    #[error("the response is zero")]
    ZeroResponse,
    /// No structure satisfies the zero count (its debug form).
    #[error("no structure with n̂ ≤ {n_max} satisfies {zeros}")]
    NoStructure {
        /// The largest order.
        n_max: usize,
        /// The zero count.
        zeros: String,
    },
}

impl Dtf {
    /// A normalized transfer function: the denominator is made monic, leading zeros of the
    /// numerator dropped; an error for a zero leading denominator coefficient, a non-finite
    /// coefficient or an improper ratio.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self, DtfError> {
        let tf = Tf::new(num, den)?;
        let a0 = tf.den()[0];
        Ok(Self {
            num: tf.num().iter().map(|b| b / a0).collect(),
            den: tf.den().iter().map(|a| a / a0).collect(),
        })
    }

    /// Channel `(output, input)` of a discrete state-space model (e.g. a ZOH
    /// discretization), through [`plant_proxy::lti::StateSpace::channel_tf`].
    pub fn from_state_space(
        ss: &plant_proxy::lti::StateSpace,
        output: usize,
        input: usize,
    ) -> Result<Self, DtfError> {
        let (num, den) = ss.channel_tf(output, input)?;
        Self::new(num, den)
    }

    /// `Ĝ(e^{jθ})`.
    pub fn eval(&self, theta: f64) -> C64 {
        eval_tf(&self.num, &self.den, C64::from_polar(1.0, theta))
    }

    /// The response on the grid `theta` (rad/sample).
    pub fn response(&self, theta: &[f64]) -> Vec<C64> {
        theta.iter().map(|&t| self.eval(t)).collect()
    }

    /// The response on `theta` as a one-channel [`Frf`] at sample period `ts`.
    pub fn frf(&self, theta: &[f64], ts: f64) -> Frf {
        Frf {
            ts,
            theta: theta.to_vec(),
            n_outputs: 1,
            n_inputs: 1,
            response: vec![self.response(theta)],
        }
    }

    /// The order `n` (degree of the denominator).
    pub fn order(&self) -> usize {
        self.den.len() - 1
    }

    /// The relative degree `n − deg num` (the delay of the first nonzero Markov parameter).
    pub fn relative_degree(&self) -> usize {
        self.order() - (self.num.len() - 1)
    }

    /// The poles (roots of `den`, eigenvalues of its companion matrix).
    pub fn poles(&self) -> Result<Vec<C64>, DtfError> {
        roots(&self.den)
    }

    /// The zeros (roots of `num`); none for a constant or zero numerator.
    pub fn zeros(&self) -> Result<Vec<C64>, DtfError> {
        if self.num.iter().all(|&b| b == 0.0) {
            return Ok(Vec::new());
        }
        roots(&self.num)
    }

    /// The largest pole magnitude (0 for a constant).
    pub fn spectral_radius(&self) -> Result<f64, DtfError> {
        Ok(self.poles()?.iter().fold(0.0_f64, |a, p| a.max(p.norm())))
    }

    /// True when every pole is strictly inside the unit circle.
    pub fn is_stable(&self) -> Result<bool, DtfError> {
        Ok(self.spectral_radius()? < 1.0)
    }

    /// The static gain `Ĝ(1)`.
    pub fn dc_gain(&self) -> f64 {
        self.eval(0.0).re
    }
}

/// Roots of a polynomial in descending powers (leading zeros ignored).
fn roots(coeffs: &[f64]) -> Result<Vec<C64>, DtfError> {
    let first = coeffs
        .iter()
        .position(|&c| c != 0.0)
        .ok_or(DtfError::ZeroPolynomial)?;
    let c = &coeffs[first..];
    let n = c.len() - 1;
    if n == 0 {
        return Ok(Vec::new());
    }
    let comp = DMatrix::from_fn(n, n, |r, k| {
        if r == 0 {
            -c[k + 1] / c[0]
        } else if r == k + 1 {
            1.0
        } else {
            0.0
        }
    });
    Ok(eigenvalues(&comp)?)
}

/// `Π (z − r_i)` for complex roots in conjugate pairs (real part of the expansion).
fn poly_from_roots(r: &[C64]) -> Vec<f64> {
    plant_proxy::lti::poly_from_roots(r)
}

/// A grid must be finite, strictly increasing and within `[0, π]`.
fn check_grid(theta: &[f64], what: &'static str) -> Result<(), DtfError> {
    let bad = |problem| DtfError::Input { what, problem };
    if theta.len() < 2 {
        return Err(bad(Problem::GridPoints(theta.len())));
    }
    if let Some(k) = theta
        .iter()
        .position(|t| !(t.is_finite() && (0.0..=PI + 1e-12).contains(t)))
    {
        return Err(bad(Problem::OutOfRange { k, theta: theta[k] }));
    }
    if let Some(k) = theta.windows(2).position(|w| w[1] <= w[0]) {
        return Err(bad(Problem::NotIncreasing {
            k,
            at: theta[k],
            next: theta[k + 1],
        }));
    }
    Ok(())
}

fn check_response(theta: &[f64], g: &[C64], what: &'static str) -> Result<(), DtfError> {
    let bad = |problem| DtfError::Input { what, problem };
    if g.len() != theta.len() {
        return Err(bad(Problem::ResponseLength {
            values: g.len(),
            frequencies: theta.len(),
        }));
    }
    if let Some(k) = g
        .iter()
        .position(|v| !(v.re.is_finite() && v.im.is_finite()))
    {
        return Err(bad(Problem::NotFinite(theta[k])));
    }
    Ok(())
}

/// The window `[max(0, θ − Δ), min(π, θ + Δ)]` of (3.40).
fn window(theta: f64, delta: f64) -> (f64, f64) {
    ((theta - delta).max(0.0), (theta + delta).min(PI))
}

fn check_delta(delta: f64) -> Result<(), DtfError> {
    if delta.is_finite() && delta > 0.0 && delta <= PI {
        Ok(())
    } else {
        Err(DtfError::Delta(delta))
    }
}

/// `∫_lo^hi` of the piecewise-linear interpolant of `g` on `theta` (`lo`, `hi` inside the
/// grid).
fn integrate_linear(theta: &[f64], g: &[C64], lo: f64, hi: f64) -> C64 {
    let interp = |i: usize, t: f64| {
        let s = (t - theta[i]) / (theta[i + 1] - theta[i]);
        g[i] * (1.0 - s) + g[i + 1] * s
    };
    let last = theta.len() - 2;
    let mut i = theta
        .partition_point(|&t| t <= lo)
        .saturating_sub(1)
        .min(last);
    let mut sum = C64::new(0.0, 0.0);
    while i <= last && theta[i] < hi {
        let a = theta[i].max(lo);
        let b = theta[i + 1].min(hi);
        if b > a {
            sum += (interp(i, a) + interp(i, b)) * (0.5 * (b - a));
        }
        i += 1;
    }
    sum
}

/// The complex windowed average (3.40) of the response `g` given on the grid `theta`
/// (rad/sample, increasing, within `[0, π]`), window half-width `delta` rad/sample, at every
/// grid point. Trapezoid rule on the piecewise-linear interpolant, window ends interpolated.
///
/// Errors: a grid that does not cover some window `[max(0, θ − Δ), min(π, θ + Δ)]` (so a
/// grid meant for averaging must run from 0 to π, or the windows be clipped by the caller),
/// or one with fewer than [`MIN_POINTS_PER_WINDOW`] points in some window.
pub fn windowed_average(theta: &[f64], g: &[C64], delta: f64) -> Result<Vec<C64>, DtfError> {
    let what = "windowed average";
    check_grid(theta, what)?;
    check_response(theta, g, what)?;
    check_delta(delta)?;
    let (first, last) = (theta[0], theta[theta.len() - 1]);
    let tol = 1e-9;
    theta
        .iter()
        .map(|&t| {
            let (lo, hi) = window(t, delta);
            if lo < first - tol || hi > last + tol {
                return Err(DtfError::Input {
                    what,
                    problem: Problem::Beyond {
                        window: (lo, hi),
                        theta: t,
                        grid: (first, last),
                    },
                });
            }
            let (lo, hi) = (lo.max(first), hi.min(last));
            let inside = theta
                .iter()
                .filter(|&&v| v >= lo - tol && v <= hi + tol)
                .count();
            if inside < MIN_POINTS_PER_WINDOW {
                return Err(DtfError::Input {
                    what,
                    problem: Problem::Sparse {
                        inside,
                        window: (lo, hi),
                        theta: t,
                        delta,
                    },
                });
            }
            Ok(integrate_linear(theta, g, lo, hi) / (hi - lo))
        })
        .collect()
}

/// The complex windowed average (3.40) of a response function `f(ν)` (`ν` in rad/sample,
/// e.g. `|ν| model.eval(ν)`) at every point of `theta`, each window integrated by the
/// composite Simpson rule on `intervals` equal sub-intervals (rounded up to an even number,
/// at least 2). Simpson's error is `O(h⁴ f⁗)`: a lightly damped mode of half-power width
/// `2ζθ_n` needs `h` well below it.
pub fn windowed_average_of(
    f: impl Fn(f64) -> C64,
    theta: &[f64],
    delta: f64,
    intervals: usize,
) -> Result<Vec<C64>, DtfError> {
    check_grid(theta, "windowed average")?;
    check_delta(delta)?;
    let n = intervals.max(2).next_multiple_of(2);
    Ok(theta
        .iter()
        .map(|&t| {
            let (lo, hi) = window(t, delta);
            let h = (hi - lo) / n as f64;
            let mut sum = f(lo) + f(hi);
            for i in 1..n {
                let c = if i % 2 == 1 { 4.0 } else { 2.0 };
                sum += f(lo + h * i as f64) * c;
            }
            sum * (h / 3.0) / (hi - lo)
        })
        .collect())
}

/// Trapezoid weights of a grid: `w_k ≈ ∫` over the half-intervals around `x_k`.
fn trapezoid_weights(x: &[f64]) -> Vec<f64> {
    let mut w = vec![0.0; x.len()];
    for k in 0..x.len() - 1 {
        let h = 0.5 * (x[k + 1] - x[k]);
        w[k] += h;
        w[k + 1] += h;
    }
    w
}

/// Trapezoid weights in `log θ` of a grid with `θ_0 > 0`: `Σ w_k f(θ_k) ≈ ∫ f d(log θ)`,
/// the discretization of (3.44).
pub fn log_weights(theta: &[f64]) -> Result<Vec<f64>, DtfError> {
    check_grid(theta, "log weights")?;
    if theta[0] <= 0.0 {
        return Err(DtfError::LogFromZero);
    }
    let lt: Vec<f64> = theta.iter().map(|t| t.ln()).collect();
    Ok(trapezoid_weights(&lt))
}

/// The default grid of [`optimize`]: [`DEFAULT_LOG_POINTS`] points logarithmically spaced
/// from [`DEFAULT_THETA_LO`] to π.
pub fn default_log_grid() -> Vec<f64> {
    super::grid(DEFAULT_THETA_LO, PI, DEFAULT_LOG_POINTS, true)
        .expect("the default grid constants are valid")
}

/// Weighted linear least squares `min ‖diag(√w)(A x − b)‖` with column scaling, by SVD.
fn weighted_ls(a: DMatrix<f64>, b: DVector<f64>) -> Result<DVector<f64>, DtfError> {
    let mut a = a;
    let scale: Vec<f64> = a
        .column_iter()
        .map(|c| {
            let n = c.norm();
            if n > 0.0 { n } else { 1.0 }
        })
        .collect();
    for (j, s) in scale.iter().enumerate() {
        a.column_mut(j).unscale_mut(*s);
    }
    let x = a
        .svd(true, true)
        .solve(&b, 1e-14)
        .map_err(|e| DtfError::LeastSquares(e.to_string()))?;
    Ok(DVector::from_iterator(
        x.len(),
        x.iter().zip(&scale).map(|(v, s)| v / s),
    ))
}

/// Fits `Ĝ(z) = (b_0 z^m + … + b_m)/(z^n + a_1 z^{n−1} + … + a_n)` (relative degree
/// `n − m`) to `target` on `theta`, stable: [`SK_ITERATIONS`] Sanathanan–Koerner iterations,
/// unstable poles reflected, numerator re-solved (see the module docs). `weights` default to
/// the trapezoid weights of the grid. Errors: `m > n`, too few points, bad grid or weights.
pub fn fit(
    theta: &[f64],
    target: &[C64],
    weights: Option<&[f64]>,
    n: usize,
    m: usize,
) -> Result<Dtf, DtfError> {
    fit_iterations(theta, target, weights, n, m, SK_ITERATIONS)
}

/// [`fit`] with `iterations` Sanathanan–Koerner iterations (1 is Levy's equation-error fit;
/// 0 keeps the denominator `z^n` and only fits the numerator).
pub fn fit_iterations(
    theta: &[f64],
    target: &[C64],
    weights: Option<&[f64]>,
    n: usize,
    m: usize,
    iterations: usize,
) -> Result<Dtf, DtfError> {
    let what = "DTF fit";
    let bad = |problem| DtfError::Input { what, problem };
    check_grid(theta, what)?;
    check_response(theta, target, what)?;
    if m > n {
        return Err(bad(Problem::Improper { zeros: m, poles: n }));
    }
    let unknowns = m + 1 + n;
    if 2 * theta.len() < unknowns {
        return Err(bad(Problem::Equations {
            frequencies: theta.len(),
            unknowns,
        }));
    }
    let w: Vec<f64> = match weights {
        Some(w) => {
            if w.len() != theta.len() || w.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(bad(Problem::Weights(theta.len())));
            }
            w.to_vec()
        }
        None => trapezoid_weights(theta),
    };
    let sw: Vec<f64> = w.iter().map(|v| v.sqrt()).collect();
    let z: Vec<C64> = theta.iter().map(|&t| C64::from_polar(1.0, t)).collect();
    let nk = theta.len();
    let mut den = vec![0.0; n + 1];
    den[0] = 1.0;
    for _ in 0..iterations {
        let mut a = DMatrix::zeros(2 * nk, unknowns);
        let mut b = DVector::zeros(2 * nk);
        for k in 0..nk {
            let scale = sw[k] / super::horner(&den, z[k]);
            let mut row = Vec::with_capacity(unknowns);
            for i in 0..=m {
                row.push(z[k].powu((m - i) as u32) * scale);
            }
            for i in 1..=n {
                row.push(-target[k] * z[k].powu((n - i) as u32) * scale);
            }
            for (j, v) in row.iter().enumerate() {
                a[(k, j)] = v.re;
                a[(nk + k, j)] = v.im;
            }
            let r = target[k] * z[k].powu(n as u32) * scale;
            b[k] = r.re;
            b[nk + k] = r.im;
        }
        let x = weighted_ls(a, b)?;
        for i in 1..=n {
            den[i] = x[m + i];
        }
    }
    // Stability: reflect, then keep off the unit circle.
    if n > 0 {
        let poles: Vec<C64> = roots(&den)?
            .into_iter()
            .map(|p| {
                let p = if p.norm() > 1.0 { p.conj().inv() } else { p };
                if p.norm() > MAX_FIT_POLE_RADIUS {
                    p * (MAX_FIT_POLE_RADIUS / p.norm())
                } else {
                    p
                }
            })
            .collect();
        den = poly_from_roots(&poles);
    }
    // Numerator for the fixed denominator (output error, linear in b).
    let mut a = DMatrix::zeros(2 * nk, m + 1);
    let mut b = DVector::zeros(2 * nk);
    for k in 0..nk {
        let scale = sw[k] / super::horner(&den, z[k]);
        for i in 0..=m {
            let v = z[k].powu((m - i) as u32) * scale;
            a[(k, i)] = v.re;
            a[(nk + k, i)] = v.im;
        }
        b[k] = sw[k] * target[k].re;
        b[nk + k] = sw[k] * target[k].im;
    }
    let num = weighted_ls(a, b)?;
    let mut num: Vec<f64> = num.iter().copied().collect();
    if num.iter().all(|&v| v == 0.0) {
        num = vec![0.0];
    }
    Dtf::new(num, den)
}

/// The relative weighted RMS error `√(Σ w |Ĝ − G|² / Σ w |G|²)` with trapezoid weights in
/// `θ` (the measure [`fit`] minimizes, normalized).
pub fn linear_fit_error(theta: &[f64], g: &[C64], dtf: &Dtf) -> Result<f64, DtfError> {
    check_grid(theta, "fit error")?;
    check_response(theta, g, "fit error")?;
    let w = trapezoid_weights(theta);
    let (mut e, mut n) = (0.0, 0.0);
    for (k, &t) in theta.iter().enumerate() {
        e += w[k] * (g[k] - dtf.eval(t)).norm_sqr();
        n += w[k] * g[k].norm_sqr();
    }
    Ok((e / n).sqrt())
}

/// The windowed-average DTF of every channel of `frf` (MIMO: channel by channel, §3.2.1):
/// (3.40) with half-width `delta` rad/sample on the FRF's own grid ([`windowed_average`],
/// so the grid must run from 0 to π), then [`fit`] with `n` poles and `m` zeros.
/// Channel-major, like [`Frf::response`].
pub fn averaged_dtfs(frf: &Frf, delta: f64, n: usize, m: usize) -> Result<Vec<Dtf>, DtfError> {
    frf.response
        .iter()
        .enumerate()
        .map(|(c, g)| {
            windowed_average(&frf.theta, g, delta)
                .and_then(|avg| fit(&frf.theta, &avg, None, n, m))
                .map_err(|e| e.in_channel(c))
        })
        .collect()
}

/// The optimization DTF (3.44)–(3.47) of every channel of `frf` (channel by channel,
/// §3.2.2), on the FRF's grid without its points at `θ = 0` (where `log θ` is undefined);
/// the grid should be logarithmic (e.g. [`default_log_grid`]) for the trapezoid weights in
/// `log θ` to approximate (3.44) well. Channel-major.
pub fn optimized_dtfs(frf: &Frf, n_max: usize, zeros: ZeroCount) -> Result<Vec<Dtf>, DtfError> {
    let keep: Vec<usize> = (0..frf.theta.len())
        .filter(|&k| frf.theta[k] > 0.0)
        .collect();
    let theta: Vec<f64> = keep.iter().map(|&k| frf.theta[k]).collect();
    frf.response
        .iter()
        .enumerate()
        .map(|(c, g)| {
            let g: Vec<C64> = keep.iter().map(|&k| g[k]).collect();
            optimize(&theta, &g, n_max, zeros).map_err(|e| e.in_channel(c))
        })
        .collect()
}

mod example;
mod optimization;
pub use example::{
    EXAMPLE_LINEAR_POINTS, EXAMPLE_WINDOW_INTERVALS, Example341, example_3_41, format_poly,
    format_roots,
};
pub use optimization::{
    COST_GAIN_FLOOR, Candidate, DEFAULT_COST_CELLS, DEFAULT_MAX_ITERS_PER_PARAMETER,
    DEFAULT_MIN_GAIN, DEFAULT_MIN_SEPARATION, OptimizeOptions, Optimized, POLISH_SD_TOLERANCE,
    SEARCH_SD_TOLERANCE, ZeroCount, log_cost, optimize, optimize_all, optimize_with,
};
