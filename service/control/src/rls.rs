//! Recursive least squares with variable-rate forgetting (RLS-VRF), dissertation §2.1.
//!
//! The estimate `θ_k ∈ ℝⁿ` of `y_k = φ_k θ` (2.1), `φ_k ∈ ℝ^{p×n}`, `y_k ∈ ℝ^p`, is updated
//! by (2.12)–(2.14):
//!
//! ```text
//! e_k     = y_k − φ_k θ_k                                   (2.7)
//! L_k     = β_k P_k                                         (2.14)
//! P_{k+1} = L_k − L_k φ_kᵀ (I_p + φ_k L_k φ_kᵀ)⁻¹ φ_k L_k   (2.13)
//! θ_{k+1} = θ_k + P_{k+1} φ_kᵀ e_k                          (2.12)
//! ```
//!
//! with `β_k = 1/λ_k` from a [`ForgettingRule`]
//! (constant, or Algorithm 1 / (5.1)–(5.7)). With `β_k ≡ 1/λ` this is (2.8)–(2.9), and with
//! `λ = 1` the minimizer of (2.6), i.e. the regularized batch solution (2.5) with
//! `R_θ = P_0⁻¹`.
//!
//! # The fast kernel ([`Rls`])
//!
//! With `G = P_k φᵀ` (n×p), `S = I_p + β φ G = C Cᵀ` (Cholesky, p×p) and
//! `W = β G C⁻ᵀ` (n×p), (2.12)–(2.13) become
//!
//! ```text
//! P_{k+1} = β P_k − W Wᵀ,        θ_{k+1} = θ_k + W (C⁻¹ e_k),
//! ```
//!
//! because `P_{k+1} φᵀ = L φᵀ (I + φ L φᵀ)⁻¹ = β G S⁻¹` and `β² G S⁻¹ Gᵀ = W Wᵀ`. For
//! `p = 1` the "factorization" is a scalar square root; no matrix inverse is formed for
//! any `p`, no `n×n` temporary exists and nothing is allocated (every buffer is sized in
//! [`Rls::new`]).
//!
//! **Deferred rank-p update.** Step `k` does not apply `P_{k+1} = β_k P_k − W_k W_kᵀ`; it
//! keeps `W_k` and `β_k`, and step `k + 1` applies them in the same sweep over `P` that
//! computes `G_{k+1} = P_{k+1} φ_{k+1}ᵀ`: each stored entry is read once, updated, written
//! once and used at once (one read and one write of `P` per step instead of two reads and
//! a write). Entry `(i, j)` is computed as `(…(β P_ij − W_j0 W_i0) − …) − W_j,p−1 W_i,p−1`
//! and stored once for both `(i, j)` and `(j, i)`, so `P` stays **exactly** symmetric in
//! floating point. What `P` the user sees is unaffected: [`Rls::covariance`] applies the
//! pending update on the fly (bit-for-bit as the next sweep will), [`Rls::trace_p`] is
//! `tr(P_{k+1})` summed from its diagonal computed in step `k` (`O(n p)`, again
//! bit-for-bit the stored values), and [`Rls::reset`] discards the pending update.
//!
//! # Guard
//!
//! A step is rejected and the state reset to `θ_0, P_0` (and the forgetting windows
//! emptied) when the input `φ_k` or `y_k` is non-finite, the innovation matrix `S` is not
//! positive definite, or the new `θ` is non-finite, or the new `P` has a non-finite or
//! non-positive diagonal entry or `tr(P) > trace_limit`. The event is reported in
//! [`RlsStep::reset`] and counted by [`Rls::resets`]; NaN never enters `θ`.
//!
//! Timing of the checks: `θ_{k+1}` and the diagonal and trace of `P_{k+1}` are checked in
//! step `k` itself. The off-diagonal entries of `P_{k+1}` only exist once the deferred
//! update is applied, in the sweep of step `k + 1`, which checks every entry it writes;
//! a non-finite one (possible only by overflow of a finite computation, since `W_k`, `β_k`
//! and the diagonal were finite) rejects step `k + 1`: the state is reset before `P_{k+1}`
//! is used for anything, the data of step `k + 1` is discarded, and the reset is reported
//! by that step. [`Rls::covariance`] called in between would show the bad entry.
//!
//! # Performance
//!
//! Only the upper triangle of `P` is stored, row-packed (`n(n+1)/2` doubles: 361 KB at
//! `n = 300`, which fits a 1 MB L2 with room for the controller).
//! The sweep (submodule `simd`, `O(n² p)`: `1 + 3p` multiply-adds per stored entry)
//! is the only part that is not `O(n p)`. With AVX2 and FMA (detected at run time) it runs
//! as explicit intrinsics for `p ≤ 4`, two packed rows per pass (each vector of `W`, `φ`
//! and `G` loaded serves both rows) and with the `β` multiplication skipped when `β = 1`
//! (exact); otherwise as plain loops that the compiler vectorizes.
//! `cargo bench -p latency-bench --bench rls` measures it against [`TextbookRls`]
//! (results: `docs/results/latency-bench.md` and the benchmark's own output).
//!
//! [`TextbookRls`] writes the same equations literally (allocating, with an explicit
//! inverse) and serves as the test oracle and benchmark baseline.

use nalgebra::{DMatrix, DVector};

use crate::ParamError;
use crate::forgetting::{Forgetting, ForgettingRule, cholesky_in_place};
use crate::linalg::{axpy, dot};

mod shared;
mod simd;

pub use shared::SharedRls;

/// Configuration of an RLS estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct RlsConfig {
    /// Number of parameters `n` (length of `θ`).
    pub n: usize,
    /// Number of outputs `p` (rows of `φ_k`).
    pub p: usize,
    /// Initial estimate `θ_0` (length `n`), also the reset value.
    pub theta0: Vec<f64>,
    /// Initial covariance `P_0 = p0 · I` (`p0 > 0`), also the reset value.
    pub p0: f64,
    /// How `λ_k = 1/β_k` is chosen.
    pub rule: ForgettingRule,
    /// `tr(P)` beyond this value (or a non-finite `θ`/`P`) resets to `θ_0, P_0`; must
    /// exceed `tr(P_0) = n · p0` (may be `+∞`).
    pub trace_limit: f64,
}

impl RlsConfig {
    /// The trace limit when a configuration gives none is this many times
    /// `tr P_0 = n · p0`, as for the RLS inside RCAC and PCAC
    /// ([`crate::RcacParams::TRACE_LIMIT_FACTOR`]).
    pub const TRACE_LIMIT_FACTOR: f64 = 1e6;

    /// The configuration for `n` parameters, `p` outputs and `P_0 = p0 · I`, with
    /// `θ_0 = 0`, no forgetting ([`ForgettingRule::DEFAULT`]) and the trace limit
    /// [`Self::TRACE_LIMIT_FACTOR`] `· n · p0`; change them with the struct update syntax
    /// and check the result with [`RlsConfig::checked`].
    pub fn new(n: usize, p: usize, p0: f64) -> Self {
        Self {
            n,
            p,
            theta0: vec![0.0; n],
            p0,
            rule: ForgettingRule::DEFAULT,
            trace_limit: Self::TRACE_LIMIT_FACTOR * n as f64 * p0,
        }
    }

    /// The configuration, checked.
    ///
    /// # Errors
    ///
    /// The first refused field: `"n"` (`n = 0` or `p = 0`), `"theta0"` (not `n` finite
    /// values), `"p0"` (not positive and finite), `"trace-limit"` (not above
    /// `tr P_0 = n · p0`), or the forgetting rule's field ([`ForgettingRule::validate`]).
    pub fn checked(self) -> Result<Self, ParamError> {
        self.check()?;
        self.rule.validate(self.p)?;
        Ok(self)
    }

    /// The checks of [`RlsConfig::checked`] but the forgetting rule's.
    fn check(&self) -> Result<(), ParamError> {
        if self.n == 0 || self.p == 0 {
            return Err(ParamError::new(
                "n",
                format!("n = {} and p = {} must be positive", self.n, self.p),
            ));
        }
        if self.theta0.len() != self.n {
            return Err(ParamError::new(
                "theta0",
                format!(
                    "theta0 has length {}, expected n = {}",
                    self.theta0.len(),
                    self.n
                ),
            ));
        }
        if self.theta0.iter().any(|x| !x.is_finite()) {
            return Err(ParamError::new("theta0", "theta0 must be finite"));
        }
        if !(self.p0 > 0.0 && self.p0.is_finite()) {
            return Err(ParamError::new(
                "p0",
                format!("p0 = {} must be positive and finite", self.p0),
            ));
        }
        let trace0 = self.n as f64 * self.p0;
        if self.trace_limit.is_nan() || self.trace_limit <= trace0 {
            return Err(ParamError::new(
                "trace-limit",
                format!(
                    "trace_limit = {} must exceed tr(P0) = {}",
                    self.trace_limit, trace0
                ),
            ));
        }
        Ok(())
    }

    /// [`RlsConfig::check`] as the constructors report it (`"rls: "` and the message).
    fn validate(&self) -> Result<(), String> {
        self.check().map_err(|e| format!("rls: {}", e.message))
    }
}

/// What one update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsStep {
    /// The forgetting factor `λ_k = 1/β_k` used in this step.
    pub lambda: f64,
    /// Euclidean norm of the prior error `e_k` (`+∞` when the input was non-finite).
    pub error_norm: f64,
    /// `true` when the guard reset `θ, P` to `θ_0, P_0` in this step.
    pub reset: bool,
}

impl RlsStep {
    /// An update that passed the guard.
    fn accepted(lambda: f64, error_norm: f64) -> Self {
        Self {
            lambda,
            error_norm,
            reset: false,
        }
    }

    /// An update whose guard reset the estimator.
    fn guard_reset(lambda: f64, error_norm: f64) -> Self {
        Self {
            lambda,
            error_norm,
            reset: true,
        }
    }
}

/// True when every entry of the regressor and the measurement is finite; otherwise the
/// step is refused and the estimator reset, before anything is computed.
fn data_finite(regressor: &[f64], y: &[f64]) -> bool {
    regressor.iter().chain(y).all(|x| x.is_finite())
}

/// The prior errors `e_l = y_l − ŷ_l` (2.7), `ŷ_l = prediction(l)`, written into `err`;
/// returns `(‖e‖, ‖y‖²)` for the forgetting rule.
#[inline(always)]
fn prior_errors(y: &[f64], err: &mut [f64], prediction: impl Fn(usize) -> f64) -> (f64, f64) {
    let (mut e2, mut y2) = (0.0, 0.0);
    for (l, (e_out, &yl)) in err.iter_mut().zip(y).enumerate() {
        let e = yl - prediction(l);
        *e_out = e;
        e2 += e * e;
        y2 += yl * yl;
    }
    (e2.sqrt(), y2)
}

/// The guard after an update: the new covariance's entries finite (`entries_finite`),
/// the estimate finite, its smallest diagonal entry positive and its trace within the
/// limit. When it fails the estimator is reset to `θ_0, P_0`.
fn guard_passes(
    theta: &[f64],
    entries_finite: bool,
    min_diag: f64,
    trace: f64,
    trace_limit: f64,
) -> bool {
    entries_finite && theta.iter().all(|x| x.is_finite()) && min_diag > 0.0 && trace <= trace_limit
}

/// The allocation-free RLS-VRF estimator (2.12)–(2.14).
#[derive(Debug, Clone)]
pub struct Rls {
    n: usize,
    p: usize,
    theta0: Vec<f64>,
    p0: f64,
    trace_limit: f64,
    forgetting: Forgetting,
    theta: Vec<f64>,
    /// Upper triangle of the stored matrix `Q` (`P_{k−1}`, or `P_0` after a reset),
    /// row-packed: row `i` (`Q[i, i..n]`, diagonal first) at `[i n − i(i−1)/2 ..][.. n − i]`;
    /// `n(n+1)/2` entries, symmetric by construction. The current covariance is
    /// `P_k = β_pend Q − W_pend W_pendᵀ` (the deferred update, see the module docs).
    cov: Vec<f64>,
    /// `W` of the previous step (n×p, column `l` at `[l n .. (l+1) n]`), not yet applied
    /// to `cov` (zeros after construction and reset).
    w_pend: Vec<f64>,
    /// `β` of the previous step, not yet applied to `cov` (1 after construction and reset).
    beta_pend: f64,
    /// `tr(P_k)`, the sum of the diagonal of `P_k` exactly as the next sweep will store it.
    trace: f64,
    /// Prior error `e_k` of the last update.
    err: Vec<f64>,
    /// `G = P φᵀ`, then `W = β G C⁻ᵀ`; column `l` at `[l n .. (l+1) n]`.
    g: Vec<f64>,
    /// `S = I + β φ G`, then its Cholesky factor (p×p row-major).
    s: Vec<f64>,
    /// `C⁻¹ e`.
    z: Vec<f64>,
    resets: u64,
    /// The compiled form of the `O(n² p)` kernels (detected once, in [`Rls::new`]).
    level: simd::Level,
}

impl Rls {
    /// Builds the estimator with `θ = θ_0`, `P = p0 · I`, allocating every buffer.
    ///
    /// # Errors
    ///
    /// Invalid dimensions, `θ_0` length, `p0`, `trace_limit`, or forgetting rule.
    pub fn new(cfg: &RlsConfig) -> Result<Self, String> {
        cfg.validate()?;
        let (n, p) = (cfg.n, cfg.p);
        Ok(Self {
            n,
            p,
            theta0: cfg.theta0.clone(),
            p0: cfg.p0,
            trace_limit: cfg.trace_limit,
            forgetting: Forgetting::new(&cfg.rule, p)?,
            theta: cfg.theta0.clone(),
            cov: packed_identity(n, cfg.p0),
            trace: n as f64 * cfg.p0,
            err: vec![0.0; p],
            g: vec![0.0; n * p],
            s: vec![0.0; p * p],
            z: vec![0.0; p],
            resets: 0,
            w_pend: vec![0.0; n * p],
            beta_pend: 1.0,
            level: simd::Level::detect(),
        })
    }

    /// One update with regressor `φ_k` (p×n, row-major, length `p·n`) and measurement
    /// `y_k` (length `p`), (2.12)–(2.14): `e_k = y_k − φ_k θ_k`, `β_k` from the rule,
    /// `L_k = β_k P_k`, `P_{k+1} = L_k − L_k φᵀ (I_p + φ L_k φᵀ)⁻¹ φ L_k`,
    /// `θ_{k+1} = θ_k + P_{k+1} φᵀ e_k`, computed as described in the module docs: one
    /// sweep over `P` applies the deferred `P_k = β_{k−1} P_{k−1} − W_{k−1} W_{k−1}ᵀ` and
    /// forms `G = P_k φ_kᵀ`; the rank-p update to `P_{k+1}` is deferred to the next call
    /// (its diagonal and trace are computed and checked now).
    ///
    /// Never allocates. `P` stays exactly symmetric. A non-finite input or a guarded
    /// blow-up resets `θ, P` to `θ_0, P_0`, sets [`RlsStep::reset`] and increments
    /// [`Rls::resets`] (an off-diagonal overflow of `P_{k+1}` is caught by the next call,
    /// see "Guard" in the module docs).
    ///
    /// # Panics
    ///
    /// Only on a caller bug: wrong slice lengths.
    pub fn update(&mut self, phi: &[f64], y: &[f64]) -> RlsStep {
        let (n, p) = (self.n, self.p);
        assert_eq!(phi.len(), n * p, "rls: phi must have length p·n");
        assert_eq!(y.len(), p, "rls: y must have length p");
        if !data_finite(phi, y) {
            self.err.fill(0.0);
            return self.fail(1.0, f64::INFINITY);
        }

        // e_k = y_k − φ_k θ_k (2.7).
        let theta = &self.theta;
        let (error_norm, y2) =
            prior_errors(y, &mut self.err, |l| dot(&phi[l * n..(l + 1) * n], theta));
        let beta = self.forgetting.beta_scaled(&self.err, y2);
        let lambda = 1.0 / beta;

        // P_k = β_{k−1} P_{k−1} − W_{k−1} W_{k−1}ᵀ (the deferred update of the previous
        // step) and G = P_k φᵀ, in one sweep over the packed upper triangle of P. The sweep
        // also checks every new entry: a non-finite off-diagonal entry of P_k (its diagonal
        // was checked in the previous step) is caught here.
        let pending = simd::Pending {
            w: &self.w_pend,
            beta: self.beta_pend,
            n,
            p,
        };
        let finite = simd::fused_pass(self.level, &mut self.cov, pending, phi, &mut self.g);
        if !finite {
            return self.fail(lambda, error_norm);
        }

        // S = I + β φ G (symmetric: lower triangle computed, then mirrored).
        for l in 0..p {
            for m in 0..=l {
                let v = beta * dot(&phi[l * n..(l + 1) * n], &self.g[m * n..(m + 1) * n]);
                let v = if l == m { 1.0 + v } else { v };
                self.s[l * p + m] = v;
                self.s[m * p + l] = v;
            }
        }
        if !cholesky_in_place(&mut self.s, p) {
            return self.fail(lambda, error_norm);
        }

        // W = β G C⁻ᵀ, column by column in place (C W_rowᵀ = β G_rowᵀ for every row).
        for l in 0..p {
            let (done, rest) = self.g.split_at_mut(l * n);
            let wl = &mut rest[..n];
            let inv = 1.0 / self.s[l * p + l];
            for v in wl.iter_mut() {
                *v *= beta;
            }
            for k in 0..l {
                axpy(-self.s[l * p + k], &done[k * n..(k + 1) * n], wl);
            }
            for v in wl.iter_mut() {
                *v *= inv;
            }
        }
        // z = C⁻¹ e (forward substitution).
        for l in 0..p {
            let mut v = self.err[l];
            for k in 0..l {
                v -= self.s[l * p + k] * self.z[k];
            }
            self.z[l] = v / self.s[l * p + l];
        }

        // θ_{k+1} = θ_k + W z.
        for l in 0..p {
            axpy(self.z[l], &self.g[l * n..(l + 1) * n], &mut self.theta);
        }

        // P_{k+1} = β P_k − W Wᵀ is deferred to the next sweep; its diagonal (O(n p)) is
        // computed now, exactly as the sweep will store it, for the guard and tr(P).
        let (trace, min_diag, diag_ok) = simd::next_diag(
            self.level,
            &self.cov,
            simd::Pending {
                w: &self.g,
                beta,
                n,
                p,
            },
        );
        if !guard_passes(&self.theta, diag_ok, min_diag, trace, self.trace_limit) {
            return self.fail(lambda, error_norm);
        }
        std::mem::swap(&mut self.g, &mut self.w_pend);
        self.beta_pend = beta;
        self.trace = trace;
        RlsStep::accepted(lambda, error_norm)
    }

    fn fail(&mut self, lambda: f64, error_norm: f64) -> RlsStep {
        self.resets += 1;
        self.reset();
        RlsStep::guard_reset(lambda, error_norm)
    }

    /// The current estimate `θ_k` (length `n`).
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// `tr(P_k)`.
    pub fn trace_p(&self) -> f64 {
        self.trace
    }

    /// The covariance `P_k` (n×n, exactly symmetric), expanded from the packed triangle
    /// kept internally with the deferred update `β P − W Wᵀ` of the last step applied on
    /// the fly (bit-for-bit as the next update will apply it). Allocates: meant for tests
    /// and inspection, not the hot path.
    pub fn covariance(&self) -> DMatrix<f64> {
        let pending = simd::Pending {
            w: &self.w_pend,
            beta: self.beta_pend,
            n: self.n,
            p: self.p,
        };
        applied_covariance(self.level, &self.cov, pending)
    }

    /// The prior error `e_k = y_k − φ_k θ_k` of the last update (zeros after a rejected
    /// non-finite input).
    pub fn prior_error(&self) -> &[f64] {
        &self.err
    }

    /// Number of guard resets since construction (explicit [`Rls::reset`] calls are not
    /// counted).
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// Visits what the estimator learned as the blocks of a checkpoint
    /// ([`crate::learned`]): `theta` (θ_k), `Q` (the packed triangle), `W` (the deferred
    /// update) and `beta-trace` (`[β, tr P_k]`), with `P_k = β Q − W Wᵀ`. Does not allocate.
    pub fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        visit("theta", &self.theta);
        visit("Q", &self.cov);
        visit("W", &self.w_pend);
        visit("beta-trace", &[self.beta_pend, self.trace]);
    }

    /// Takes back the blocks of [`Rls::learned`] and empties the forgetting windows (they
    /// belong to the data history); the estimator then continues exactly as the saved one
    /// would have. Allocates (it checks that `P_k` is positive definite).
    ///
    /// # Errors
    ///
    /// A missing, mis-sized or non-finite block, a covariance that is not positive
    /// definite or whose trace the guard would refuse; the estimator is then at `θ_0`, `P_0`.
    pub fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let n = self.n;
        let theta = saved.block("theta", n)?;
        let q = saved.block("Q", n * (n + 1) / 2)?;
        let w = saved.block("W", n * self.p)?;
        let bt = saved.block("beta-trace", 2)?;
        self.theta.copy_from_slice(theta);
        self.cov.copy_from_slice(q);
        self.w_pend.copy_from_slice(w);
        self.beta_pend = bt[0];
        self.trace = bt[1];
        self.forgetting.reset();
        self.err.fill(0.0);
        let checked = if bt[0] > 0.0 {
            crate::learned::check_covariance(&self.covariance(), self.trace, self.trace_limit)
        } else {
            Err(format!("β = {:e} is not positive", bt[0]))
        };
        if checked.is_err() {
            self.reset();
        }
        checked
    }

    /// Empties the forgetting windows (the data history) and keeps `θ_k` and `P_k`, for a
    /// new data stream ([`crate::learned`]). Does not allocate.
    pub fn restart_data(&mut self) {
        self.forgetting.reset();
        self.err.fill(0.0);
    }

    /// Resets `θ = θ_0`, `P = P_0` and empties the forgetting windows. Does not allocate.
    pub fn reset(&mut self) {
        self.theta.copy_from_slice(&self.theta0);
        fill_packed_identity(&mut self.cov, self.n, self.p0);
        self.w_pend.fill(0.0);
        self.beta_pend = 1.0;
        self.trace = self.n as f64 * self.p0;
        self.forgetting.reset();
    }
}

/// `β Q − W Wᵀ` as a full symmetric matrix, for the row-packed upper triangle `Q` and a
/// deferred update (`pending`), entry by entry exactly as the next sweep will store it.
/// Allocates: for inspection, tests and checkpoints.
fn applied_covariance(
    level: simd::Level,
    packed: &[f64],
    pending: simd::Pending<'_>,
) -> DMatrix<f64> {
    let simd::Pending { w, beta, n, p } = pending;
    let mut m = DMatrix::zeros(n, n);
    let mut off = 0;
    for i in 0..n {
        for (t, &v) in packed[off..off + n - i].iter().enumerate() {
            let j = i + t;
            let v = if level.fma() {
                simd::entry::<true>(beta, v, w, n, p, i, j)
            } else {
                simd::entry::<false>(beta, v, w, n, p, i, j)
            };
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
        off += n - i;
    }
    m
}

/// `p0 · I` as a row-packed upper triangle (`n(n+1)/2` entries).
fn packed_identity(n: usize, p0: f64) -> Vec<f64> {
    let mut v = vec![0.0; n * (n + 1) / 2];
    fill_packed_identity(&mut v, n, p0);
    v
}

/// Overwrites the row-packed upper triangle `pk` with `p0 · I`. Does not allocate.
fn fill_packed_identity(pk: &mut [f64], n: usize, p0: f64) {
    pk.fill(0.0);
    let mut off = 0;
    for i in 0..n {
        pk[off] = p0;
        off += n - i;
    }
}

/// `a · b + c`: a fused multiply-add (one rounding) when `FMA` (only instantiated inside
/// functions compiled with the `fma` target feature, or off the hot path), else a multiply
/// then an add.
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// The RLS-VRF equations (2.12)–(2.14) written literally with nalgebra (allocating, with
/// an explicit `p×p` inverse): the oracle for tests and the benchmark baseline.
#[derive(Debug, Clone)]
pub struct TextbookRls {
    n: usize,
    p: usize,
    theta0: DVector<f64>,
    p0: f64,
    trace_limit: f64,
    forgetting: Forgetting,
    theta: DVector<f64>,
    cov: DMatrix<f64>,
}

impl TextbookRls {
    /// Builds the estimator with `θ = θ_0`, `P = p0 · I`.
    ///
    /// # Errors
    ///
    /// The same validation as [`Rls::new`].
    pub fn new(cfg: &RlsConfig) -> Result<Self, String> {
        cfg.validate()?;
        Ok(Self {
            n: cfg.n,
            p: cfg.p,
            theta0: DVector::from_column_slice(&cfg.theta0),
            p0: cfg.p0,
            trace_limit: cfg.trace_limit,
            forgetting: Forgetting::new(&cfg.rule, cfg.p)?,
            theta: DVector::from_column_slice(&cfg.theta0),
            cov: DMatrix::from_diagonal_element(cfg.n, cfg.n, cfg.p0),
        })
    }

    /// One update (2.12)–(2.14) with `φ_k` (p×n row-major) and `y_k` (length `p`).
    pub fn update(&mut self, phi: &[f64], y: &[f64]) -> RlsStep {
        let (n, p) = (self.n, self.p);
        let phi = DMatrix::from_row_slice(p, n, phi);
        let y = DVector::from_column_slice(y);
        let e = &y - &phi * &self.theta;
        let beta = self.forgetting.beta_scaled(e.as_slice(), y.norm_squared());
        let l = &self.cov * beta;
        let s = DMatrix::<f64>::identity(p, p) + &phi * &l * phi.transpose();
        let reset = match s.try_inverse() {
            Some(s_inv) => {
                let lpt = &l * phi.transpose();
                self.cov = &l - &lpt * s_inv * &phi * &l;
                self.theta = &self.theta + &self.cov * phi.transpose() * &e;
                let bad = self
                    .cov
                    .iter()
                    .chain(self.theta.iter())
                    .any(|x| !x.is_finite());
                bad || self.cov.trace() > self.trace_limit
            }
            None => true,
        };
        if reset {
            self.theta = self.theta0.clone();
            self.cov = DMatrix::from_diagonal_element(n, n, self.p0);
            self.forgetting.reset();
        }
        RlsStep {
            lambda: 1.0 / beta,
            error_norm: e.norm(),
            reset,
        }
    }

    /// The current estimate `θ_k`.
    pub fn theta(&self) -> &[f64] {
        self.theta.as_slice()
    }

    /// `tr(P_k)`.
    pub fn trace_p(&self) -> f64 {
        self.cov.trace()
    }

    /// The covariance `P_k`.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.cov
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_support::{Gauss, f_test, proposition_5_2_1_rules};

    fn cfg(n: usize, p: usize, p0: f64, rule: ForgettingRule) -> RlsConfig {
        RlsConfig {
            rule,
            trace_limit: f64::INFINITY,
            ..RlsConfig::new(n, p, p0)
        }
    }

    #[test]
    fn the_configuration_starts_at_the_defaults_and_names_a_refused_field() {
        let c = RlsConfig::new(4, 2, 10.0);
        assert_eq!(
            (c.theta0.clone(), c.rule.clone()),
            (vec![0.0; 4], ForgettingRule::DEFAULT)
        );
        assert_eq!(c.trace_limit, 1e6 * 4.0 * 10.0);
        assert_eq!(c.checked().map(|c| c.n), Ok(4));
        let field = |c: RlsConfig| c.checked().unwrap_err().field;
        assert_eq!(field(RlsConfig::new(0, 1, 1.0)), "n");
        assert_eq!(field(RlsConfig::new(2, 1, -1.0)), "p0");
        let tight = RlsConfig {
            trace_limit: 2.0,
            ..RlsConfig::new(2, 1, 1.0)
        };
        assert_eq!(field(tight), "trace-limit");
        let forgetting = RlsConfig {
            rule: ForgettingRule::Constant { lambda: 0.0 },
            ..RlsConfig::new(2, 1, 1.0)
        };
        assert_eq!(field(forgetting), "forgetting.lambda");
        assert_eq!(
            Rls::new(&RlsConfig::new(0, 1, 1.0)).unwrap_err(),
            "rls: n = 0 and p = 1 must be positive"
        );
    }

    fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
        let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
        let den: f64 = b.iter().map(|y| y * y).sum::<f64>();
        (num / den.max(f64::MIN_POSITIVE)).sqrt()
    }

    fn is_exactly_symmetric(m: &DMatrix<f64>) -> bool {
        (0..m.nrows()).all(|i| (0..i).all(|j| m[(i, j)] == m[(j, i)]))
    }

    /// y = φ θ* + noise with a random φ (p×n) per step.
    fn sample(g: &mut Gauss, theta: &[f64], p: usize, noise: f64) -> (Vec<f64>, Vec<f64>) {
        let n = theta.len();
        let phi = g.vec(p * n);
        let y = (0..p)
            .map(|l| dot(&phi[l * n..(l + 1) * n], theta) + noise * g.normal())
            .collect();
        (phi, y)
    }

    #[test]
    fn with_lambda_one_and_large_p0_the_estimate_equals_batch_least_squares() {
        for (n, p) in [(6, 1), (8, 2), (5, 3)] {
            let p0 = 1e8;
            let mut rls =
                Rls::new(&cfg(n, p, p0, ForgettingRule::Constant { lambda: 1.0 })).unwrap();
            let mut g = Gauss::new(42 + n as u64);
            let truth = g.vec(n);
            let mut ata = DMatrix::<f64>::identity(n, n) / p0; // R_θ = P0⁻¹ (2.5)
            let mut aty = DVector::<f64>::zeros(n);
            for _ in 0..200 {
                let (phi, y) = sample(&mut g, &truth, p, 0.1);
                let pm = DMatrix::from_row_slice(p, n, &phi);
                ata += pm.transpose() * &pm;
                aty += pm.transpose() * DVector::from_column_slice(&y);
                assert!(!rls.update(&phi, &y).reset);
            }
            let batch = ata.cholesky().unwrap().solve(&aty); // (2.5)
            let d = rel_diff(rls.theta(), batch.as_slice());
            assert!(d < 1e-6, "(n, p) = ({n}, {p}): relative difference {d}");
            assert!(is_exactly_symmetric(&rls.covariance()));
        }
    }

    #[test]
    fn constant_lambda_matches_the_recursion_2_8_and_2_9() {
        for (n, p) in [(7, 1), (9, 2), (6, 3)] {
            let lambda = 0.97;
            let mut rls = Rls::new(&cfg(n, p, 10.0, ForgettingRule::Constant { lambda })).unwrap();
            let mut th = DVector::<f64>::zeros(n);
            let mut pk = DMatrix::<f64>::identity(n, n) * 10.0;
            let mut g = Gauss::new(5 + p as u64);
            let truth = g.vec(n);
            for _ in 0..1000 {
                let (phi, y) = sample(&mut g, &truth, p, 0.05);
                let f = DMatrix::from_row_slice(p, n, &phi);
                let e = DVector::from_column_slice(&y) - &f * &th;
                let inner = (DMatrix::<f64>::identity(p, p) * lambda + &f * &pk * f.transpose())
                    .try_inverse()
                    .unwrap();
                let k = &pk * f.transpose() * &inner;
                th += &k * &e; // (2.8)
                pk = (&pk - &k * &f * &pk) / lambda; // (2.9)
                rls.update(&phi, &y);
            }
            let d = rel_diff(rls.theta(), th.as_slice());
            assert!(d < 1e-10, "(n, p) = ({n}, {p}): theta differs by {d}");
            let dp = rel_diff(rls.covariance().as_slice(), pk.as_slice());
            assert!(dp < 1e-9, "(n, p) = ({n}, {p}): P differs by {dp}");
        }
    }

    #[test]
    fn multi_output_noiseless_identification_recovers_the_parameters() {
        for p in [2, 3] {
            let n = 10;
            let rule = f_test(10, 80, 1.0, 0.001);
            let mut rls = Rls::new(&cfg(n, p, 1e4, rule)).unwrap();
            let mut g = Gauss::new(77 + p as u64);
            let truth = g.vec(n);
            let mut last = None;
            for _ in 0..500 {
                let (phi, y) = sample(&mut g, &truth, p, 0.0);
                let st = rls.update(&phi, &y);
                assert!(!st.reset);
                last = Some(st);
            }
            let d = rel_diff(rls.theta(), &truth);
            assert!(d < 1e-6, "p = {p}: {d}");
            assert!(last.unwrap().error_norm < 1e-5);
            assert_eq!(rls.prior_error().len(), p);
        }
    }

    fn compare_fast_and_textbook(n: usize, p: usize, steps: usize, rule: ForgettingRule) {
        let c = cfg(n, p, 10.0, rule);
        let mut fast = Rls::new(&c).unwrap();
        let mut book = TextbookRls::new(&c).unwrap();
        let mut g = Gauss::new(1234 + n as u64);
        let mut truth = g.vec(n);
        let mut forgot = 0;
        for k in 0..steps {
            if k == steps / 2 {
                truth = g.vec(n);
            }
            let (phi, y) = sample(&mut g, &truth, p, 0.1);
            let a = fast.update(&phi, &y);
            let b = book.update(&phi, &y);
            assert!(!a.reset && !b.reset);
            assert!(
                (a.lambda - b.lambda).abs() < 1e-12,
                "k = {k}: {a:?} vs {b:?}"
            );
            forgot += usize::from(a.lambda < 1.0);
        }
        let d = rel_diff(fast.theta(), book.theta());
        assert!(d < 1e-10, "(n, p) = ({n}, {p}): theta differs by {d}");
        let dp = rel_diff(fast.covariance().as_slice(), book.covariance().as_slice());
        assert!(dp < 1e-10, "(n, p) = ({n}, {p}): P differs by {dp}");
        assert!((fast.trace_p() - book.trace_p()).abs() <= 1e-10 * book.trace_p());
        assert!(is_exactly_symmetric(&fast.covariance()));
        assert!(forgot > 0, "the comparison must exercise forgetting");
    }

    #[test]
    fn fast_kernel_agrees_with_textbook_for_35_parameters_and_5_outputs() {
        compare_fast_and_textbook(35, 5, 4000, f_test(10, 80, 0.3, 0.01));
        compare_fast_and_textbook(35, 5, 3000, ForgettingRule::Constant { lambda: 0.999 });
        compare_fast_and_textbook(20, 8, 2000, f_test(10, 80, 0.3, 0.01));
    }

    #[test]
    fn fast_kernel_agrees_with_textbook_for_300_parameters_and_3_outputs() {
        compare_fast_and_textbook(300, 3, 2000, f_test(10, 80, 0.3, 0.01));
    }

    /// The packed triangle as stored (the sweep's output), in the order of
    /// [`Rls::covariance`]'s upper triangle.
    fn stored_upper(rls: &Rls) -> Vec<f64> {
        rls.cov.clone()
    }

    fn upper_packed(m: &DMatrix<f64>) -> Vec<f64> {
        let n = m.nrows();
        (0..n)
            .flat_map(|i| (i..n).map(move |j| (i, j)))
            .map(|ij| m[ij])
            .collect()
    }

    #[test]
    fn deferred_update_is_seen_bit_for_bit_and_both_kernel_forms_agree() {
        for (n, p) in [(37, 1), (38, 2), (41, 3), (40, 4), (21, 6), (1, 1), (2, 3)] {
            for rule in [
                ForgettingRule::Constant { lambda: 0.995 },
                f_test(10, 80, 0.3, 0.01),
            ] {
                let c = cfg(n, p, 10.0, rule);
                let mut fast = Rls::new(&c).unwrap();
                let mut portable = Rls::new(&c).unwrap();
                portable.level = simd::Level::Portable;
                let mut g = Gauss::new(99 + (n * p) as u64);
                let truth = g.vec(n);
                for k in 0..600 {
                    let (phi, y) = sample(&mut g, &truth, p, 0.1);
                    for rls in [&mut fast, &mut portable] {
                        // What the accessors show before the step is exactly what the
                        // step's sweep stores (the diagonal, hence tr P, included).
                        let shown = rls.covariance();
                        let trace = rls.trace_p();
                        assert!(!rls.update(&phi, &y).reset);
                        let stored = stored_upper(rls);
                        assert!(
                            upper_packed(&shown) == stored,
                            "(n, p) = ({n}, {p}), k = {k}: covariance() ≠ stored P"
                        );
                        let diag_sum = (0..n).fold(0.0, |s, i| s + shown[(i, i)]);
                        assert_eq!(diag_sum, trace, "(n, p) = ({n}, {p}), k = {k}");
                    }
                }
                let d = rel_diff(fast.theta(), portable.theta());
                assert!(d < 1e-12, "(n, p) = ({n}, {p}): theta differs by {d}");
                let (a, b) = (fast.covariance(), portable.covariance());
                let dp = rel_diff(a.as_slice(), b.as_slice());
                assert!(dp < 1e-12, "(n, p) = ({n}, {p}): P differs by {dp}");
                assert!(is_exactly_symmetric(&a) && is_exactly_symmetric(&b));
            }
        }
    }

    #[test]
    fn an_off_diagonal_overflow_of_the_deferred_update_is_caught_by_the_next_sweep() {
        for level in [simd::Level::detect(), simd::Level::Portable] {
            for p in [1, 3] {
                let n = 6;
                let mut c = cfg(n, p, 1.0, ForgettingRule::Constant { lambda: 1.0 });
                c.theta0 = vec![0.25; n];
                let mut rls = Rls::new(&c).unwrap();
                rls.level = level;
                // A state whose pending update has a finite, positive diagonal but an
                // off-diagonal entry that overflows: β P_01 = 4 · 1e308 = ∞.
                rls.cov[1] = 1e308;
                rls.beta_pend = 4.0;
                let mut g = Gauss::new(3);
                let phi = g.vec(n * p);
                // The sweep itself reports it (S would also fail to factor, as ∞·0 = NaN).
                let mut pk = rls.cov.clone();
                let mut gg = vec![0.0; n * p];
                let pending = simd::Pending {
                    w: &rls.w_pend,
                    beta: rls.beta_pend,
                    n,
                    p,
                };
                assert!(!simd::fused_pass(level, &mut pk, pending, &phi, &mut gg));
                let st = rls.update(&phi, &vec![1.0; p]);
                assert!(st.reset, "level {level:?}, p = {p}: {st:?}");
                assert_eq!(rls.resets(), 1);
                assert_eq!(rls.theta(), &c.theta0[..]);
                assert_eq!(rls.trace_p(), n as f64);
                assert!(rls.covariance().iter().all(|x| x.is_finite()));
                assert!(!rls.update(&phi, &vec![1.0; p]).reset);
                assert!(rls.theta().iter().all(|x| x.is_finite()));
            }
        }
    }

    #[test]
    fn non_finite_input_resets_and_is_reported_without_propagating_nan() {
        let n = 4;
        let rule = f_test(5, 30, 1.0, 0.01);
        let mut c = cfg(n, 1, 10.0, rule);
        c.theta0 = vec![0.5; n];
        let mut rls = Rls::new(&c).unwrap();
        let mut g = Gauss::new(9);
        let truth = g.vec(n);
        for _ in 0..100 {
            let (phi, y) = sample(&mut g, &truth, 1, 0.01);
            rls.update(&phi, &y);
        }
        let st = rls.update(&[1.0, f64::NAN, 0.0, 0.0], &[1.0]);
        assert!(st.reset);
        assert_eq!(rls.resets(), 1);
        assert_eq!(rls.theta(), &c.theta0[..]);
        assert_eq!(rls.trace_p(), 40.0);
        let st = rls.update(&[1.0, 0.0, 0.0, 0.0], &[f64::INFINITY]);
        assert!(st.reset);
        assert_eq!(rls.resets(), 2);
        for _ in 0..100 {
            let (phi, y) = sample(&mut g, &truth, 1, 0.01);
            assert!(!rls.update(&phi, &y).reset);
            assert!(rls.theta().iter().all(|x| x.is_finite()));
            assert!(rls.prior_error().iter().all(|x| x.is_finite()));
        }
    }

    #[test]
    fn blow_up_of_the_covariance_resets_and_is_reported() {
        let n = 3;
        let mut c = cfg(n, 1, 1.0, ForgettingRule::Constant { lambda: 0.5 });
        c.trace_limit = 1e6;
        let mut rls = Rls::new(&c).unwrap();
        // No excitation with heavy forgetting: P grows like 2^k until the trace limit.
        let mut resets = 0;
        for _ in 0..100 {
            let st = rls.update(&[0.0; 3], &[0.0]);
            resets += usize::from(st.reset);
            assert!(rls.trace_p() <= 1e6);
        }
        assert!(resets >= 4);
        assert_eq!(rls.resets(), resets as u64);
        // Huge data: overflow is caught, never stored.
        let mut c = cfg(n, 1, 1.0, ForgettingRule::Constant { lambda: 1.0 });
        c.trace_limit = 1e6;
        let mut rls = Rls::new(&c).unwrap();
        let st = rls.update(&[1e200, 1e200, 1e200], &[1e300]);
        assert!(st.reset, "{st:?}");
        assert!(rls.theta().iter().all(|x| x.is_finite()));
        assert!(rls.covariance().iter().all(|x| x.is_finite()));
        let st = rls.update(&[1.0, 2.0, 3.0], &[1.0]);
        assert!(!st.reset);
    }

    #[test]
    fn invalid_configurations_are_rejected() {
        let ok = cfg(3, 1, 1.0, ForgettingRule::Constant { lambda: 1.0 });
        assert!(Rls::new(&ok).is_ok());
        let mut c = ok.clone();
        c.theta0 = vec![0.0; 2];
        assert!(Rls::new(&c).is_err());
        let mut c = ok.clone();
        c.p0 = 0.0;
        assert!(Rls::new(&c).is_err());
        let mut c = ok.clone();
        c.trace_limit = 3.0;
        assert!(Rls::new(&c).is_err());
        let mut c = ok;
        c.rule = ForgettingRule::Constant { lambda: 0.0 };
        assert!(TextbookRls::new(&c).is_err());
    }

    /// The mass-spring-damper of §5.3, (5.8), with φ_k = [y_{k−1} y_{k−2} u_k u_{k−1} u_{k−2}].
    fn msd_run(
        rule: ForgettingRule,
        noise: f64,
        change_at: usize,
        steps: usize,
        seed: u64,
    ) -> (Rls, Vec<RlsStep>, [f64; 5]) {
        let before = [1.64, -0.8187, 0.0, 0.4606, 0.4307];
        let after = [0.3116, -0.998, 0.0, 0.4218, 0.4215];
        let mut rls = Rls::new(&cfg(5, 1, 100.0, rule)).unwrap();
        let mut g = Gauss::new(seed);
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        let mut out = Vec::with_capacity(steps);
        let mut th = before;
        for k in 0..steps {
            th = if k < change_at { before } else { after };
            let u = g.normal();
            let phi = [y1, y2, u, u1, u2];
            let y_true = dot(&phi, &th);
            let y = y_true + noise * g.normal();
            out.push(rls.update(&phi, &[y]));
            (y2, y1, u2, u1) = (y1, y_true, u1, u);
        }
        (rls, out, th)
    }

    #[test]
    fn f_test_forgets_after_an_abrupt_parameter_change() {
        let rule = f_test(10, 80, 1.0, 0.001);
        let (rls, steps, truth) = msd_run(rule, 0.01, 200, 300, 17);
        let before = steps[..200].iter().filter(|s| s.lambda < 1.0).count();
        let after = steps[200..230].iter().filter(|s| s.lambda < 1.0).count();
        assert!(before <= 2, "forgot {before} times before the change");
        assert!(after >= 3, "forgot only {after} times after the change");
        let d = rel_diff(rls.theta(), &truth);
        assert!(d < 0.05, "not re-converged: {d}");
        // Without forgetting the estimate is still far off 100 steps after the change.
        let (slow, _, _) = msd_run(ForgettingRule::Constant { lambda: 1.0 }, 0.01, 200, 300, 17);
        assert!(rel_diff(slow.theta(), &truth) > 2.0 * d);
    }

    #[test]
    fn f_test_rarely_forgets_on_a_stationary_noisy_problem() {
        let rule = f_test(10, 80, 1.0, 0.001);
        let (rls, steps, truth) = msd_run(rule, 0.1, usize::MAX, 20_000, 23);
        let forgot = steps.iter().filter(|s| s.lambda < 1.0).count();
        let frac = forgot as f64 / steps.len() as f64;
        assert!(frac < 0.01, "fraction of steps with β > 1: {frac}");
        assert!(rel_diff(rls.theta(), &truth) < 0.05);
        assert_eq!(rls.resets(), 0);
    }

    #[test]
    fn noiseless_converged_data_causes_no_spurious_forgetting() {
        // Noiseless data: the prior errors decay (the P_0 regularization is forgotten) until
        // they reach the roundoff level ≲ 1e-10 ‖y‖; from then on the variances are
        // "numerical zero" and there must be no forgetting even at a loose α = 0.1.
        let rule = f_test(10, 80, 1.0, 0.1);
        let (rls, steps, truth) = msd_run(rule, 0.0, usize::MAX, 6000, 31);
        let last_big = steps.iter().rposition(|s| s.error_norm > 1e-9).unwrap();
        assert!(
            last_big < 3000,
            "errors never reached numerical zero ({last_big})"
        );
        let late = steps[last_big + 82..]
            .iter()
            .filter(|s| s.lambda < 1.0)
            .count();
        assert_eq!(late, 0);
        assert!(rel_diff(rls.theta(), &truth) < 1e-9);

        // Exact initial estimate: every error is roundoff from the first step.
        for p in [1, 3] {
            let n = 12;
            let mut g = Gauss::new(8 + p as u64);
            let truth = g.vec(n);
            let mut c = cfg(n, p, 100.0, f_test(10, 80, 1.0, 0.1));
            c.theta0 = truth.clone();
            let mut rls = Rls::new(&c).unwrap();
            for _ in 0..3000 {
                let (phi, y) = sample(&mut g, &truth, p, 0.0);
                let st = rls.update(&phi, &y);
                assert_eq!(st.lambda, 1.0, "p = {p}: {st:?}");
            }
        }
    }

    #[test]
    fn proposition_5_2_1_holds_inside_rls() {
        let (a, b) = proposition_5_2_1_rules(10, 80, 0.5);
        let (_, sa, _) = msd_run(a, 0.05, 1000, 3000, 3);
        let (_, sb, _) = msd_run(b, 0.05, 1000, 3000, 3);
        let mut forgot = 0;
        for (x, y) in sa.iter().zip(&sb) {
            assert!((x.lambda - y.lambda).abs() < 1e-9);
            forgot += usize::from(x.lambda < 1.0);
        }
        assert!(forgot > 100);
    }
}
