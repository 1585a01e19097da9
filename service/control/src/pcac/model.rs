//! PCAC's input–output model (2.24) and its online identification by RLS with
//! variable-rate forgetting (2.25)–(2.35); its realization (2.36)–(2.46) is in
//! [`crate::bocf`].
//!
//! # Coefficients and regressor
//!
//! `p` outputs, `m` inputs, order `n̂ ≥ 1`, `N = n̂(p+m)` regressors per output. The
//! coefficient matrix `Θ̃ = [F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂] ∈ ℝ^{p×N}` has `θ = vec Θ̃` (2.27),
//! column-stacked, so `θ[c p + r] = Θ̃[r, c]`; `F̂_i` occupies columns `(i−1)p .. ip`,
//! `Ĝ_i` columns `n̂p + (i−1)m .. n̂p + im`. With the row
//! `ψ_k = [−y_{k−1}ᵀ … −y_{k−n̂}ᵀ u_{k−1}ᵀ … u_{k−n̂}ᵀ] ∈ ℝ^{1×N}` the regressor (2.28) is
//! `φ_k = ψ_k ⊗ I_p` and `φ_k θ = (ψ_k ⊗ I_p) vec Θ̃ = Θ̃ ψ_kᵀ`, so
//! `z_k = y_k − Θ̃ ψ_kᵀ` (2.26)/(2.29).
//!
//! # The Kronecker reduction of RLS (2.30)–(2.32)
//!
//! Suppose `P_k = P̃_k ⊗ I_p` (true for `P_0 = p0 I_{Np} = (p0 I_N) ⊗ I_p`). With
//! `g_k = P̃_k ψ_kᵀ ∈ ℝ^N` and `s_k = ψ_k g_k`, by `(A ⊗ B)(C ⊗ D) = AC ⊗ BD`:
//!
//! ```text
//! L_k φ_kᵀ          = β_k (P̃_k ψ_kᵀ ⊗ I_p)      = β_k g_k ⊗ I_p
//! φ_k L_k φ_kᵀ      = β_k (ψ_k P̃_k ψ_kᵀ) ⊗ I_p  = β_k s_k I_p
//! P_{k+1} (2.31)    = [β_k P̃_k − β_k² g_k g_kᵀ / (1 + β_k s_k)] ⊗ I_p  =: P̃_{k+1} ⊗ I_p
//! P_{k+1} φ_kᵀ z_k  = (P̃_{k+1} ψ_kᵀ) ⊗ z_k = vec(z_k ψ_k P̃_{k+1}),
//! P̃_{k+1} ψ_kᵀ     = β_k g_k / (1 + β_k s_k)
//! ```
//!
//! (`β_k = 1/λ_k`), hence by induction `P_k = P̃_k ⊗ I_p` for all `k`, and (2.32) is
//!
//! ```text
//! Θ̃_{k+1} = Θ̃_k + z_k (β_k / (1 + β_k s_k)) g_kᵀ :
//! ```
//!
//! the `p` rows of `Θ̃` are `p` right-hand sides of one scalar-row RLS on `ψ_k` that share
//! `P̃_k` (`N×N`) and `β_k`. `β_k` itself depends on all outputs: the forgetting rule (the
//! F-test (2.33)–(2.35) with the Lawley–Hotelling form for `p > 1`) receives the whole
//! `p`-dimensional `z_k`, exactly as in the full RLS. The guard compares
//! `tr P_{k+1} = p · tr P̃_{k+1}` with the trace limit, so both forms reset at the same
//! steps. For the truss (`n̂ = 25, p = 4, m = 2`) this is `N = 150` instead of
//! `Np = 600`: a `150×150` covariance (11 325 packed entries, 89 KB) instead of a
//! `600×600` one (1.4 MB), `O(N²)` per step instead of the kernel's `O((Np)² p)`.
//! The ignored test `pcac_id_timing` (`cargo test --release -p control --lib
//! pcac_id_timing -- --ignored --nocapture`) times both forms.
//!
//! [`IdKernel::Shared`] is this reduced form ([`SharedRls`], since
//! [`Rls`] estimates a vector `θ` only and cannot share one covariance between right-hand
//! sides); [`IdKernel::Full`] runs [`Rls`] on the full rows `ψ_k ⊗ I_p` (`n = Np`
//! parameters, `p` rows) and is the reference: the tests check both give the same
//! estimates, forgetting factors and covariances (`P = P̃ ⊗ I_p`).
//!
//! # The data the realization uses
//!
//! The block observable canonical realization (2.36)–(2.42), its Markov parameters and
//! free response (2.43)–(2.46) are [`crate::bocf`]'s; [`IoModel::realization`] hands it the
//! current coefficients and the model is its [`DataWindow`]. At step `k`, after
//! [`IoModel::update`] with `y_k` and `u_{k−1}`, the coefficients are `θ_{k+1}` (computed
//! from `z_k`, i.e. from `y_k`, `y_{k−1} … y_{k−n̂}` and `u_{k−1} … u_{k−n̂}`), and the
//! state estimate (2.38)–(2.39) uses these coefficients and the stored
//!
//! ```text
//! x̂_k:  y_k, y_{k−1}, …, y_{k−n̂+1}   and   u_{k−1}, …, u_{k−n̂+1}
//! ```
//!
//! (`y_{k−n̂}` and `u_{k−n̂}` enter `θ_{k+1}` but not `x̂_k`), so that
//! `Ĉ x_{1|k} = Ĉ (Â_k x̂_k + B̂_k u_k)` is the one-step prediction of (2.24) for `y_{k+1}`
//! with the coefficients `θ_{k+1}` ([`IoModel::predict_one_step`]).
//!
//! # Real time
//!
//! Every buffer is sized in [`IoModel::new`]; [`IoModel::update`], [`IoModel::observe`] and
//! [`IoModel::realization`] never allocate and never panic: slices of the wrong length are
//! refused with a [`DimError`] (a `Copy` value, no allocation).

#![allow(clippy::needless_range_loop)] // index-heavy block algebra, as in `design`

use crate::bocf::{DataWindow, IdentifiedModel, Realization, check};
/// The realization's types, here so that `pcac::model` paths keep naming them.
pub use crate::bocf::{DimError, HorizonPrediction};
use crate::forgetting::ForgettingRule;
use crate::rls::{Rls, RlsConfig, RlsStep, SharedRls};

/// Which RLS form identifies the coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IdKernel {
    /// The Kronecker-reduced form: one `N×N` covariance `P̃` shared by the `p` outputs
    /// (`N = n̂(p+m)`), see the module docs. The default.
    #[default]
    Shared,
    /// The crate's [`Rls`] on the full rows `φ_k = ψ_k ⊗ I_p` (`n̂p(p+m)` parameters, `p`
    /// rows): the reference.
    Full,
}

/// Parameters of an [`IoModel`].
#[derive(Debug, Clone, PartialEq)]
pub struct IoModelParams {
    /// Model order `n̂ ≥ 1` (the data window of (2.24)).
    pub n_hat: usize,
    /// Number of outputs `p ≥ 1`.
    pub p: usize,
    /// Number of inputs `m ≥ 1`.
    pub m: usize,
    /// `θ_0` in the order of (2.27) (`θ = vec[F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]`, length
    /// `n̂p(p+m)`), also the reset value; empty means `θ_0 = 0`.
    pub theta0: Vec<f64>,
    /// `P_0 = p0 · I` (`p0 > 0`, finite), also the reset value.
    pub p0: f64,
    /// The forgetting rule, e.g. the F-test (2.33)–(2.35).
    pub rule: ForgettingRule,
    /// `tr P_k` (of the full `n̂p(p+m)`-square covariance) beyond this resets `θ, P` to
    /// `θ_0, P_0`; must exceed `tr P_0 = n̂p(p+m) p0` (may be `+∞`).
    pub trace_limit: f64,
    /// Which RLS form to run.
    pub kernel: IdKernel,
}

/// A pre-sized history of vectors of length `dim`; `back(0)` is the newest.
#[derive(Debug, Clone)]
pub(super) struct Ring {
    dim: usize,
    cap: usize,
    data: Vec<f64>,
    /// Slot of the newest entry.
    head: usize,
}

impl Ring {
    pub(super) fn new(dim: usize, cap: usize) -> Self {
        Self {
            dim,
            cap,
            data: vec![0.0; dim * cap],
            head: 0,
        }
    }

    pub(super) fn push(&mut self, v: &[f64]) {
        self.head = if self.head + 1 == self.cap {
            0
        } else {
            self.head + 1
        };
        let d = self.dim;
        self.data[self.head * d..(self.head + 1) * d].copy_from_slice(v);
    }

    /// The entry `j` pushes ago (`j < cap`).
    pub(super) fn back(&self, j: usize) -> &[f64] {
        let idx = (self.head + self.cap - j) % self.cap;
        &self.data[idx * self.dim..(idx + 1) * self.dim]
    }

    /// Every entry back to zero.
    pub(super) fn clear(&mut self) {
        self.data.fill(0.0);
    }
}

#[derive(Debug, Clone)]
enum Kernel {
    Shared(Box<SharedRls>),
    Full {
        rls: Box<Rls>,
        /// The full regressor `ψ_k ⊗ I_p` (p × Np row-major).
        phi: Vec<f64>,
    },
}

/// The input–output model (2.24) with its online identification; its realization is
/// [`IoModel::realization`].
///
/// # Call order per sample `k`
///
/// 1. `y_k` is measured. The input `u_{k−1}` applied over the period ending at sample `k`
///    is known (in PCAC it was decided at step `k − 2` as `u_{1|k−2}` and held from sample
///    `k − 1` to `k`;
///    use the input the plant actually applied when it is reported).
/// 2. [`IoModel::update`]`(y_k, u_{k−1})`: stores `u_{k−1}`, forms
///    `ψ_k = [−y_{k−1}ᵀ … −y_{k−n̂}ᵀ u_{k−1}ᵀ … u_{k−n̂}ᵀ]`, runs RLS with `z_k` to get
///    `θ_{k+1}`, then stores `y_k`. ([`IoModel::observe`] stores both without identifying.)
/// 3. The realization at step `k` with `θ_{k+1}` ([`IoModel::realization`], see
///    [`crate::bocf`]): [`Realization::fill_state`] with this model as the data window
///    (`x̂_k` from `y_k … y_{k−n̂+1}`, `u_{k−1} … u_{k−n̂+1}`), [`Realization::fill_a`],
///    [`Realization::fill_b`]; [`Realization::one_step_state`] gives
///    `x_{1|k} = Â x̂_k + B̂ u_k` with `u_k`, the input already decided for this period
///    (`u_{1|k−1}`); [`Realization::markov`] and [`Realization::free_response`] give
///    `T̂_{k,ℓ}` and `Γ̂_{k,ℓ} x_{1|k}` for (2.43) ([`HorizonPrediction`] computes them
///    together).
/// 4. MPC computes `U_{1|k,ℓ}`; `u_{1|k}` is the next input, `u_{k+1}`, and becomes the
///    `u` argument of step `k + 2`'s update.
///
/// Before the first samples the histories are zero (`y_{−i} = 0`, `u_{−i} = 0`).
#[derive(Debug, Clone)]
pub struct IoModel {
    n_hat: usize,
    p: usize,
    m: usize,
    /// `N = n̂(p+m)`.
    nr: usize,
    kernel: Kernel,
    /// `Θ̃ = [F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]`, p×N row-major (the current `θ_{k+1}`).
    coef: Vec<f64>,
    /// `y_k, y_{k−1}, …` (capacity n̂).
    ys: Ring,
    /// `u_{k−1}, u_{k−2}, …` (capacity n̂).
    us: Ring,
    /// `ψ_k` of the last update.
    psi: Vec<f64>,
    /// `z_k` of the last update.
    err: Vec<f64>,
    last: RlsStep,
    samples: u64,
}

impl IoModel {
    /// Builds the model with `θ = θ_0`, `P = p0 I`, zero histories, allocating every buffer.
    ///
    /// # Errors
    ///
    /// A message naming the parameter: `n̂`, `p` or `m` zero, `θ_0` of the wrong length or
    /// non-finite, `p0` not positive and finite, `trace_limit ≤ tr P_0`, or an invalid
    /// forgetting rule (e.g. F-test with `τ_d ≤ p + 3`).
    pub fn new(params: &IoModelParams) -> Result<Self, String> {
        let IoModelParams { n_hat, p, m, .. } = *params;
        if n_hat == 0 {
            return Err("pcac model: the order n_hat must be at least 1".into());
        }
        if p == 0 || m == 0 {
            return Err(format!(
                "pcac model: p = {p} outputs and m = {m} inputs must both be at least 1"
            ));
        }
        let nr = n_hat * (p + m);
        let ntheta = nr * p;
        let theta0 = if params.theta0.is_empty() {
            vec![0.0; ntheta]
        } else if params.theta0.len() != ntheta {
            return Err(format!(
                "pcac model: theta0 has length {}, expected n_hat·p·(p+m) = {ntheta}",
                params.theta0.len()
            ));
        } else {
            params.theta0.clone()
        };
        if theta0.iter().any(|x| !x.is_finite()) {
            return Err("pcac model: theta0 must be finite".into());
        }
        if !(params.p0 > 0.0 && params.p0.is_finite()) {
            return Err(format!(
                "pcac model: p0 = {} must be positive and finite",
                params.p0
            ));
        }
        let trace0 = ntheta as f64 * params.p0;
        if params.trace_limit.is_nan() || params.trace_limit <= trace0 {
            return Err(format!(
                "pcac model: trace_limit = {} must exceed tr(P0) = {trace0}",
                params.trace_limit
            ));
        }
        // Θ̃ row-major from vec Θ̃.
        let mut coef = vec![0.0; ntheta];
        for c in 0..nr {
            for r in 0..p {
                coef[r * nr + c] = theta0[c * p + r];
            }
        }
        let kernel = match params.kernel {
            IdKernel::Shared => Kernel::Shared(Box::new(
                SharedRls::new(
                    nr,
                    p,
                    coef.clone(),
                    params.p0,
                    &params.rule,
                    params.trace_limit,
                )
                .map_err(|e| format!("pcac model: {e}"))?,
            )),
            IdKernel::Full => Kernel::Full {
                rls: Box::new(
                    Rls::new(&RlsConfig {
                        n: ntheta,
                        p,
                        theta0,
                        p0: params.p0,
                        rule: params.rule.clone(),
                        trace_limit: params.trace_limit,
                    })
                    .map_err(|e| format!("pcac model: {e}"))?,
                ),
                phi: vec![0.0; p * ntheta],
            },
        };
        Ok(Self {
            n_hat,
            p,
            m,
            nr,
            kernel,
            coef,
            ys: Ring::new(p, n_hat),
            us: Ring::new(m, n_hat),
            psi: vec![0.0; nr],
            err: vec![0.0; p],
            last: RlsStep {
                lambda: 1.0,
                error_norm: 0.0,
                reset: false,
            },
            samples: 0,
        })
    }

    /// Model order `n̂`.
    pub fn n_hat(&self) -> usize {
        self.realization().n_hat()
    }

    /// Number of outputs `p`.
    pub fn p(&self) -> usize {
        self.realization().p()
    }

    /// Number of inputs `m`.
    pub fn m(&self) -> usize {
        self.realization().m()
    }

    /// State dimension `n̂p` of the realization.
    pub fn state_dim(&self) -> usize {
        self.realization().state_dim()
    }

    /// Which RLS form runs.
    pub fn kernel(&self) -> IdKernel {
        match self.kernel {
            Kernel::Shared(_) => IdKernel::Shared,
            Kernel::Full { .. } => IdKernel::Full,
        }
    }

    /// Identification step `k` (see the call order on [`IoModel`]): stores `u_{k−1}`
    /// (`u_prev`, length `m`), forms `ψ_k`, updates `θ_k → θ_{k+1}` by (2.30)–(2.32) with
    /// the forgetting factor of the configured rule fed with `z_k` (2.26), then stores
    /// `y_k` (`y`, length `p`). Never allocates.
    ///
    /// Non-finite data make the RLS guard reset `θ, P` to `θ_0, P_0` (reported in
    /// [`RlsStep::reset`]); the values are stored in the histories as given, so the caller
    /// should substitute finite ones (e.g. hold the last) if it wants identification to
    /// resume at once.
    ///
    /// # Errors
    ///
    /// [`DimError`] for a slice of the wrong length; nothing is changed then.
    pub fn update(&mut self, y: &[f64], u_prev: &[f64]) -> Result<RlsStep, DimError> {
        check("y", y.len(), self.p)?;
        check("u_prev", u_prev.len(), self.m)?;
        self.us.push(u_prev);
        let (n_hat, p, m, nr) = (self.n_hat, self.p, self.m, self.nr);
        for i in 0..n_hat {
            for (d, s) in self.psi[i * p..(i + 1) * p].iter_mut().zip(self.ys.back(i)) {
                *d = -s;
            }
            let off = n_hat * p + i * m;
            self.psi[off..off + m].copy_from_slice(self.us.back(i));
        }
        let step = match &mut self.kernel {
            Kernel::Shared(k) => {
                let st = k.update(&self.psi, y);
                self.coef.copy_from_slice(k.theta());
                self.err.copy_from_slice(k.prior_error());
                st
            }
            Kernel::Full { rls, phi } => {
                // φ_k = ψ_k ⊗ I_p: row r has ψ_c at column c p + r.
                phi.fill(0.0);
                let ntheta = nr * p;
                for r in 0..p {
                    for c in 0..nr {
                        phi[r * ntheta + c * p + r] = self.psi[c];
                    }
                }
                let st = rls.update(phi, y);
                let th = rls.theta();
                for c in 0..nr {
                    for r in 0..p {
                        self.coef[r * nr + c] = th[c * p + r];
                    }
                }
                self.err.copy_from_slice(rls.prior_error());
                st
            }
        };
        self.ys.push(y);
        self.samples += 1;
        self.last = step;
        Ok(step)
    }

    /// Stores `u_{k−1}` and `y_k` like [`IoModel::update`] without identifying (for a
    /// sample that must not update the estimate). Never allocates.
    ///
    /// # Errors
    ///
    /// [`DimError`] for a slice of the wrong length; nothing is changed then.
    pub fn observe(&mut self, y: &[f64], u_prev: &[f64]) -> Result<(), DimError> {
        check("y", y.len(), self.p)?;
        check("u_prev", u_prev.len(), self.m)?;
        self.us.push(u_prev);
        self.ys.push(y);
        self.samples += 1;
        Ok(())
    }

    /// Returns to `θ_0`, `P_0`, zero histories and the forgetting rule's initial state,
    /// without allocating (the reset counter is kept).
    pub fn reset(&mut self) {
        match &mut self.kernel {
            Kernel::Shared(k) => k.reset(),
            Kernel::Full { rls, .. } => rls.reset(),
        }
        self.take_coefficients();
        self.restart_data();
    }

    /// Copies the estimator's `θ` into `Θ̃` (p×N row-major).
    fn take_coefficients(&mut self) {
        let (p, nr) = (self.p, self.nr);
        match &self.kernel {
            Kernel::Shared(k) => self.coef.copy_from_slice(k.theta()),
            Kernel::Full { rls, .. } => {
                let th = rls.theta();
                for c in 0..nr {
                    for r in 0..p {
                        self.coef[r * nr + c] = th[c * p + r];
                    }
                }
            }
        }
    }

    /// Visits the identification's learned blocks ([`crate::learned`]): those of
    /// [`SharedRls::learned`] or of [`Rls::learned`]. Does not allocate.
    pub fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        match &self.kernel {
            Kernel::Shared(k) => k.learned(visit),
            Kernel::Full { rls, .. } => rls.learned(visit),
        }
    }

    /// Takes back the blocks of [`IoModel::learned`] (the histories stay as they are).
    ///
    /// # Errors
    ///
    /// As the estimator's `restore_learned`; the model is then back at `θ_0`, `P_0`.
    pub fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let restored = match &mut self.kernel {
            Kernel::Shared(k) => k.restore_learned(saved),
            Kernel::Full { rls, .. } => rls.restore_learned(saved),
        };
        self.take_coefficients();
        restored
    }

    /// Zero histories `y`, `u`, `ψ`, the prior error and the forgetting windows, keeping
    /// `θ` and `P` (a new data stream, [`crate::learned`]). Does not allocate.
    pub fn restart_data(&mut self) {
        match &mut self.kernel {
            Kernel::Shared(k) => k.restart_data(),
            Kernel::Full { rls, .. } => rls.restart_data(),
        }
        self.restart_histories();
    }

    /// Zero histories `y`, `u`, `ψ` and the prior error, keeping `θ`, `P` **and the
    /// forgetting rule's windows**: a new phase of the same experiment after a gap in the
    /// data (the sampling arm's next contact, chapter 7), in which the windows still hold
    /// the prior errors of the last phase, so that a model that no longer fits is seen at
    /// once (the F-test compares the new errors with the old ones and forgets,
    /// §7.3.3). The histories start again from zeros: the caller must not identify before
    /// `n̂` samples have refilled them ([`IoModel::observe`] them). Does not allocate.
    pub fn restart_histories(&mut self) {
        self.ys.clear();
        self.us.clear();
        self.psi.fill(0.0);
        self.err.fill(0.0);
        self.last = RlsStep {
            lambda: 1.0,
            error_norm: 0.0,
            reset: false,
        };
        self.samples = 0;
    }

    /// The newest stored output `y_k` (zeros before the first sample).
    pub fn last_y(&self) -> &[f64] {
        self.ys.back(0)
    }

    /// `Θ̃ = [F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]` (p × n̂(p+m), row-major): the current estimate
    /// `θ_{k+1}` after step `k`.
    pub fn coefficients(&self) -> &[f64] {
        &self.coef
    }

    /// Writes `θ = vec Θ̃` in the order of (2.27) into `out` (length `n̂p(p+m)`).
    ///
    /// # Errors
    ///
    /// [`DimError`] for the wrong length.
    pub fn theta_vec(&self, out: &mut [f64]) -> Result<(), DimError> {
        check("theta", out.len(), self.nr * self.p)?;
        for c in 0..self.nr {
            for r in 0..self.p {
                out[c * self.p + r] = self.coef[r * self.nr + c];
            }
        }
        Ok(())
    }

    /// Entry `(r, s)` of `F̂_i` (`1 ≤ i ≤ n̂`, `r, s < p`), as [`Realization::f`].
    #[inline]
    pub fn f(&self, i: usize, r: usize, s: usize) -> f64 {
        self.realization().f(i, r, s)
    }

    /// Entry `(r, s)` of `Ĝ_i` (`1 ≤ i ≤ n̂`, `r < p`, `s < m`), as [`Realization::g`].
    #[inline]
    pub fn g(&self, i: usize, r: usize, s: usize) -> f64 {
        self.realization().g(i, r, s)
    }

    /// `z_k = y_k − φ_k θ_k` (2.26) of the last update (zeros after a non-finite input).
    pub fn prior_error(&self) -> &[f64] {
        &self.err
    }

    /// What the last update did (`λ_k`, `‖z_k‖`, guard reset).
    pub fn last_step(&self) -> RlsStep {
        self.last
    }

    /// `tr P_k` of the full covariance (`p · tr P̃_k` for the shared form).
    pub fn trace_p(&self) -> f64 {
        match &self.kernel {
            Kernel::Shared(k) => k.p() as f64 * k.trace_p_tilde(),
            Kernel::Full { rls, .. } => rls.trace_p(),
        }
    }

    /// Number of guard resets of the estimator since construction.
    pub fn resets(&self) -> u64 {
        match &self.kernel {
            Kernel::Shared(k) => k.resets(),
            Kernel::Full { rls, .. } => rls.resets(),
        }
    }

    /// Samples stored since construction (updates and observations).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The covariance `P_k` (full, `n̂p(p+m)` square; `P̃_k ⊗ I_p` for the shared form).
    /// Allocates: for tests and inspection.
    pub fn covariance(&self) -> nalgebra::DMatrix<f64> {
        match &self.kernel {
            Kernel::Shared(k) => {
                let (n, p) = (k.n(), k.p());
                let pt = k.covariance();
                nalgebra::DMatrix::from_fn(n * p, n * p, |a, b| {
                    if a % p == b % p {
                        pt[(a / p, b / p)]
                    } else {
                        0.0
                    }
                })
            }
            Kernel::Full { rls, .. } => rls.covariance(),
        }
    }

    /// The one-step prediction of (2.24) for `y_{k+1}` with the current coefficients:
    /// `−Σ F̂_i y_{k+1−i} + Σ Ĝ_i u_{k+1−i}`, from the stored `y_k … y_{k−n̂+1}`,
    /// `u_{k−1} … u_{k−n̂+1}` and the given `u_k` (length `m`), into `out` (length `p`).
    ///
    /// # Errors
    ///
    /// [`DimError`] for a slice of the wrong length.
    pub fn predict_one_step(&self, u_k: &[f64], out: &mut [f64]) -> Result<(), DimError> {
        check("u_k", u_k.len(), self.m)?;
        check("prediction", out.len(), self.p)?;
        let (p, m) = (self.p, self.m);
        for (r, o) in out.iter_mut().enumerate() {
            let mut v = 0.0;
            for i in 1..=self.n_hat {
                let y = self.ys.back(i - 1);
                for s in 0..p {
                    v -= self.f(i, r, s) * y[s];
                }
                let u = if i == 1 { u_k } else { self.us.back(i - 2) };
                for s in 0..m {
                    v += self.g(i, r, s) * u[s];
                }
            }
            *o = v;
        }
        Ok(())
    }

    /// The block observable canonical realization (2.36)–(2.42) of the current
    /// coefficients `θ_{k+1}` ([`crate::bocf`]): `Â_k`, `B̂_k`, the state step, the Markov
    /// parameters and the free response; with this model as its [`DataWindow`] it also
    /// builds the state estimate `x̂_k` (2.38)–(2.39). Never allocates.
    #[inline]
    pub fn realization(&self) -> Realization<'_> {
        Realization::new_unchecked(self.n_hat, self.p, self.m, &self.coef)
    }
}

/// `y_{k−j}` and `u_{k−j}` from the stored histories (see the call order on [`IoModel`]).
impl DataWindow for IoModel {
    #[inline]
    fn past_output(&self, j: usize) -> &[f64] {
        self.ys.back(j)
    }

    #[inline]
    fn past_input(&self, j: usize) -> &[f64] {
        self.us.back(j.saturating_sub(1))
    }
}

impl IdentifiedModel for IoModel {
    #[inline]
    fn realization(&self) -> Realization<'_> {
        IoModel::realization(self)
    }
}
