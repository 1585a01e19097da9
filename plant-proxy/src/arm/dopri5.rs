//! # Dormand–Prince 5(4) with dense output and event location, allocation-free
//!
//! The explicit Runge–Kutta pair of Dormand and Prince (seven stages, first same as last)
//! for `ẋ = f(t, x)`, `x ∈ ℝᴺ` held in nalgebra's fixed-size [`SVector`]:
//!
//! ```text
//! k_i = f(t + c_i h, x + h Σ_{j<i} a_ij k_j),   x⁺ = x + h Σ b_i k_i   (b = a_7·, order 5)
//! err = h Σ e_i k_i                                                 (5th − embedded 4th order)
//! ```
//!
//! with the standard tableau (`c = [0, 1/5, 3/10, 4/5, 8/9, 1, 1]`; the coefficients are in
//! the source). A step is accepted when the scaled RMS norm
//!
//! ```text
//! ‖err‖ = sqrt( (1/N) Σ_j ( err_j / (atol + rtol · max(|x_j|, |x⁺_j|)) )² ) ≤ 1,
//! ```
//!
//! and the next step is `h · min(10, max(0.2, 0.9 ‖err‖^{−(0.2 − 0.75 β)} ‖err_prev‖^{β}))`
//! (the PI control of Hairer, Nørsett and Wanner, β = 0.04; after a rejection the step only
//! shrinks). The PI term keeps the step near the stability boundary without chattering when
//! the problem is stiff, as the regularized Coulomb friction of (7.29) makes the contact
//! phase (`∂F_f/∂ẋ = −μ F_c / 10⁻⁴`).
//!
//! ## Dense output and events
//!
//! Every accepted step keeps the continuous extension of order 4,
//!
//! ```text
//! x(t + θh) = r_1 + θ (r_2 + (1−θ) (r_3 + θ (r_4 + (1−θ) r_5))),   θ ∈ [0, 1],
//! r_1 = x, r_2 = x⁺ − x, r_3 = h k_1 − r_2, r_4 = r_2 − h k_7 − r_3, r_5 = h Σ d_i k_i,
//! ```
//!
//! from which [`Dopri5::integrate`] locates the first zero of a switching function `g(t, x)`
//! in the step: the integration of a segment runs while `g ≥ 0` and stops at the first
//! accepted step after which `g < 0`; the crossing is then bracketed on the dense output by
//! the Illinois variant of regula falsi (bisection after a stalled side) until the bracket
//! `[t_lo, t_hi]` is shorter than the time tolerance, and the integration stops at `t_hi`,
//! where `g < 0` holds strictly. The caller then changes the right-hand side (the contact
//! state of the arm) and starts a new segment from there, so the step into a discontinuity
//! of `f` is resolved, not sampled.
//!
//! ## Bounds
//!
//! An interval shorter than `64 ε max(|t|, 10⁻³)` (what is left after an event or a phase
//! change that falls just before the end) is stepped over with the state unchanged.
//! Every step attempt (accepted or rejected) counts against a budget the caller passes in
//! (the plant's maximum number of steps per sample); when it runs out, or the step size
//! falls below the resolution of `t`, or `f` cannot be evaluated (returns `None`, e.g. a
//! mass matrix that is not positive definite, or a non-finite value), the integration stops
//! with an [`IntegrationError`] instead of looping. Nothing allocates; nothing panics.

use nalgebra::SVector;
use std::fmt;

/// A right-hand side `ẋ = f(t, x)`.
pub trait OdeSystem<const N: usize> {
    /// `f(t, x)`, or `None` when it cannot be evaluated at this state.
    fn rhs(&self, t: f64, x: &SVector<f64, N>) -> Option<SVector<f64, N>>;
}

/// The integrator's tolerances and bound (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// Relative tolerance `rtol`.
    pub rtol: f64,
    /// Absolute tolerance `atol` (in the units of each state component).
    pub atol: f64,
    /// Time tolerance of the located events: the length of the final bracket, s.
    pub event_time: f64,
}

/// Why an integration stopped before its end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IntegrationError {
    /// The budget of step attempts ran out (the problem needs more steps than allowed).
    StepBudget {
        /// The time reached.
        t: f64,
        /// The step size in use.
        h: f64,
    },
    /// The step size fell below what `t` can resolve.
    StepTooSmall {
        /// The time reached.
        t: f64,
    },
    /// The right-hand side could not be evaluated (or gave a non-finite value).
    Rhs {
        /// The time of the failed evaluation.
        t: f64,
    },
}

impl fmt::Display for IntegrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IntegrationError::StepBudget { t, h } => write!(
                f,
                "the step budget ran out at t = {t} s (step {h:e} s): raise \
                 plant.integrator.max-steps-per-sample or loosen the tolerances"
            ),
            IntegrationError::StepTooSmall { t } => {
                write!(f, "the step size underflowed at t = {t} s")
            }
            IntegrationError::Rhs { t } => write!(
                f,
                "the equations of motion could not be evaluated at t = {t} s (a mass matrix \
                 that is not positive definite or a non-finite state)"
            ),
        }
    }
}

impl std::error::Error for IntegrationError {}

/// How a call of [`Dopri5::integrate`] ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stop {
    /// The end time was reached.
    End,
    /// The switching function became negative: the state is at `t_hi` (returned in place),
    /// the first time of the final bracket where `g < 0`.
    Event {
        /// The last time of the bracket where `g ≥ 0`.
        t_lo: f64,
    },
}

/// Counters of the work done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps.
    pub accepted: u64,
    /// Rejected steps.
    pub rejected: u64,
    /// Evaluations of the right-hand side.
    pub evaluations: u64,
    /// Located events.
    pub events: u64,
}

// The Dormand–Prince tableau.
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;
// Error coefficients: b (5th order) − b̂ (embedded 4th order).
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output.
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

const SAFETY: f64 = 0.9;
const BETA: f64 = 0.04;
const EXPO: f64 = 0.2 - BETA * 0.75;
const MIN_FACTOR: f64 = 0.2;
const MAX_FACTOR: f64 = 10.0;
/// The most iterations of the root bracketing (each halves the bracket at worst every
/// other iteration): far more than `log2(step / event_time)` needs.
const MAX_ROOT_ITERATIONS: usize = 200;

/// The integrator: tolerances, the step size carried from call to call, the PI
/// controller's memory, the dense output of the last step and the counters.
#[derive(Debug, Clone)]
pub struct Dopri5<const N: usize> {
    tol: Tolerances,
    /// The proposed next step (carried across calls).
    h: f64,
    /// The largest step.
    h_max: f64,
    err_prev: f64,
    /// Dense output `r_1 … r_5` of the last accepted step, over `[t_old, t_old + h_old]`.
    dense: [SVector<f64, N>; 5],
    t_old: f64,
    h_old: f64,
    stats: Stats,
}

impl<const N: usize> Dopri5<N> {
    /// An integrator with tolerances `tol`, first step `h0` and largest step `h_max` (s).
    pub fn new(tol: Tolerances, h0: f64, h_max: f64) -> Self {
        Self {
            tol,
            h: h0.min(h_max),
            h_max,
            err_prev: 1e-4,
            dense: [SVector::zeros(); 5],
            t_old: 0.0,
            h_old: 0.0,
            stats: Stats::default(),
        }
    }

    /// The tolerances.
    pub fn tolerances(&self) -> &Tolerances {
        &self.tol
    }

    /// The counters since construction (or the last [`Dopri5::reset`]).
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// The step size the next call starts with.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Back to the first step `h0`, counters cleared.
    pub fn reset(&mut self, h0: f64) {
        self.h = h0.min(self.h_max);
        self.err_prev = 1e-4;
        self.stats = Stats::default();
    }

    /// The dense output of the last accepted step at `t` in it.
    fn interpolate(&self, t: f64) -> SVector<f64, N> {
        let th = if self.h_old > 0.0 {
            ((t - self.t_old) / self.h_old).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let th1 = 1.0 - th;
        let [r1, r2, r3, r4, r5] = &self.dense;
        r1 + (r2 + (r3 + (r4 + r5 * th1) * th) * th1) * th
    }

    /// Integrates `sys` from `(*t, *x)` to `t_end`, or to the first crossing of `g` below
    /// zero (module documentation); `*t`, `*x` are updated in place. Each step attempt
    /// takes one from `budget`.
    pub fn integrate<S, G>(
        &mut self,
        sys: &S,
        t: &mut f64,
        x: &mut SVector<f64, N>,
        t_end: f64,
        g: G,
        budget: &mut u64,
    ) -> Result<Stop, IntegrationError>
    where
        S: OdeSystem<N>,
        G: Fn(f64, &SVector<f64, N>) -> f64,
    {
        if self.negligible(*t, t_end) {
            *t = t_end.max(*t);
            return Ok(Stop::End);
        }
        let mut k1 = self.eval(sys, *t, x)?;
        while *t < t_end {
            let remaining = t_end - *t;
            if self.negligible(*t, t_end) {
                // What is left is below the resolution of t (an event or a phase change
                // just before t_end): x does not change over it.
                *t = t_end;
                break;
            }
            // Step onto t_end when it is within reach (and do not leave a sliver).
            let mut h = self.h.min(self.h_max);
            let last = h >= remaining * (1.0 - 1e-12) || remaining - h < 1e-3 * h;
            if last {
                h = remaining;
            }
            if *budget == 0 {
                return Err(IntegrationError::StepBudget { t: *t, h });
            }
            *budget -= 1;
            if h <= 8.0 * f64::EPSILON * t.abs().max(1e-3) {
                return Err(IntegrationError::StepTooSmall { t: *t });
            }
            let (x_new, k7, err_vec, ks) = self.stages(sys, *t, x, &k1, h)?;
            let err = self.error_norm(x, &x_new, &err_vec);
            if !err.is_finite() {
                self.stats.rejected += 1;
                self.h = h * MIN_FACTOR;
                continue;
            }
            let fac11 = err.powf(EXPO);
            if err <= 1.0 {
                // Accept: dense output, then advance.
                let t_new = if last { t_end } else { *t + h };
                let ydiff = x_new - *x;
                let bspl = k1 * h - ydiff;
                let [_, _, k3, k4, k5, k6] = ks;
                self.dense = [
                    *x,
                    ydiff,
                    bspl,
                    ydiff - k7 * h - bspl,
                    (k1 * D1 + k3 * D3 + k4 * D4 + k5 * D5 + k6 * D6 + k7 * D7) * h,
                ];
                self.t_old = *t;
                self.h_old = h;
                self.stats.accepted += 1;
                let fac = (fac11 / self.err_prev.powf(BETA) / SAFETY)
                    .clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR);
                let h_next = h / fac;
                self.err_prev = err.max(1e-4);
                // A step cut short to land on t_end says nothing about the next one.
                self.h = if last { h_next.max(self.h) } else { h_next };
                if g(t_new, &x_new) < 0.0 {
                    return self.locate(*t, t_new, t, x, &g);
                }
                *t = t_new;
                *x = x_new;
                k1 = k7;
            } else {
                self.stats.rejected += 1;
                self.h = h / (fac11 / SAFETY).min(1.0 / MIN_FACTOR);
            }
        }
        Ok(Stop::End)
    }

    /// True when `[t, t_end]` is shorter than what a step can resolve at `t`.
    fn negligible(&self, t: f64, t_end: f64) -> bool {
        t_end - t <= 64.0 * f64::EPSILON * t.abs().max(1e-3)
    }

    fn eval<S: OdeSystem<N>>(
        &mut self,
        sys: &S,
        t: f64,
        x: &SVector<f64, N>,
    ) -> Result<SVector<f64, N>, IntegrationError> {
        self.stats.evaluations += 1;
        match sys.rhs(t, x) {
            Some(v) if v.iter().all(|e| e.is_finite()) => Ok(v),
            _ => Err(IntegrationError::Rhs { t }),
        }
    }

    /// The six new stages of one step: `(x⁺, k_7, h Σ e_i k_i, [k_1 … k_6])`.
    #[allow(clippy::type_complexity)]
    fn stages<S: OdeSystem<N>>(
        &mut self,
        sys: &S,
        t: f64,
        x: &SVector<f64, N>,
        k1: &SVector<f64, N>,
        h: f64,
    ) -> Result<
        (
            SVector<f64, N>,
            SVector<f64, N>,
            SVector<f64, N>,
            [SVector<f64, N>; 6],
        ),
        IntegrationError,
    > {
        let k2 = self.eval(sys, t + C2 * h, &(x + k1 * (A21 * h)))?;
        let k3 = self.eval(sys, t + C3 * h, &(x + (k1 * A31 + k2 * A32) * h))?;
        let k4 = self.eval(sys, t + C4 * h, &(x + (k1 * A41 + k2 * A42 + k3 * A43) * h))?;
        let k5 = self.eval(
            sys,
            t + C5 * h,
            &(x + (k1 * A51 + k2 * A52 + k3 * A53 + k4 * A54) * h),
        )?;
        let k6 = self.eval(
            sys,
            t + h,
            &(x + (k1 * A61 + k2 * A62 + k3 * A63 + k4 * A64 + k5 * A65) * h),
        )?;
        let x_new = x + (k1 * A71 + k3 * A73 + k4 * A74 + k5 * A75 + k6 * A76) * h;
        let k7 = self.eval(sys, t + h, &x_new)?;
        let err = (k1 * E1 + k3 * E3 + k4 * E4 + k5 * E5 + k6 * E6 + k7 * E7) * h;
        Ok((x_new, k7, err, [*k1, k2, k3, k4, k5, k6]))
    }

    fn error_norm(&self, x: &SVector<f64, N>, x_new: &SVector<f64, N>, e: &SVector<f64, N>) -> f64 {
        let mut sum = 0.0;
        for j in 0..N {
            let sk = self.tol.atol + self.tol.rtol * x[j].abs().max(x_new[j].abs());
            let r = e[j] / sk;
            sum += r * r;
        }
        (sum / N as f64).sqrt()
    }

    /// Brackets the first zero of `g` in the last step `[t0, t1]` (`g(t0) ≥ 0 > g(t1)`) and
    /// leaves `(*t, *x)` at the bracket's right end.
    fn locate<G>(
        &mut self,
        t0: f64,
        t1: f64,
        t: &mut f64,
        x: &mut SVector<f64, N>,
        g: &G,
    ) -> Result<Stop, IntegrationError>
    where
        G: Fn(f64, &SVector<f64, N>) -> f64,
    {
        let (mut a, mut b) = (t0, t1);
        let mut ga = g(a, &self.interpolate(a)).max(0.0);
        let mut gb = g(b, &self.interpolate(b));
        let mut side = 0i8;
        for _ in 0..MAX_ROOT_ITERATIONS {
            if b - a <= self.tol.event_time {
                break;
            }
            // Regula falsi with the Illinois halving; bisection when it would not move.
            let mut m = if ga - gb > 0.0 {
                b - gb * (b - a) / (gb - ga)
            } else {
                0.5 * (a + b)
            };
            let span = b - a;
            if !(m > a + 0.01 * span.min(self.tol.event_time) && m < b) {
                m = 0.5 * (a + b);
            }
            let gm = g(m, &self.interpolate(m));
            if gm < 0.0 {
                b = m;
                gb = gm;
                if side == -1 {
                    ga *= 0.5;
                }
                side = -1;
            } else {
                a = m;
                ga = gm;
                if side == 1 {
                    gb *= 0.5;
                }
                side = 1;
            }
        }
        *t = b;
        *x = self.interpolate(b);
        self.stats.events += 1;
        Ok(Stop::Event { t_lo: a })
    }
}
