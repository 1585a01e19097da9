//! Retrospective cost adaptive control (RCAC), dissertation §2.2, with the target model of
//! §3.1 and the instantaneous-cost gradient variant of §3.4.
//!
//! # Controller, (2.15)–(2.18)
//!
//! ```text
//! u_k = Σ_{i=1}^{n_c} P_i u_{k−i} + Σ_{i=1}^{n_c} Q_i y_{k−i} = Φ_k θ          (2.15)
//! φ_k = [u_{k−1}; …; u_{k−n_c}; y_{k−1}; …; y_{k−n_c}] ∈ ℝ^N,  N = n_c (l_u + l_y)
//! Φ_k = I_{l_u} ⊗ φ_kᵀ ∈ ℝ^{l_u × l_θ}                                           (2.17)
//! θ   = row-major stacking of Θ = [P_1 … P_{n_c} Q_1 … Q_{n_c}] ∈ ℝ^{l_u × N},
//!       l_θ = l_u n_c (l_u + l_y)                                                  (2.18)
//! u_k = 0 for k < k_w                                                             (2.16)
//! ```
//!
//! so `u_{j,k} = θ_jᵀ φ_k` with `θ_j` the `j`-th block of `N` entries (the row-major order
//! makes `Φ_k` block diagonal; (2.17) writes the same product for the column-major `vec`).
//! `k` counts the steps since construction or [`Controller::reset`]. The applied input is
//! saturated to `u-min`/`u-max`, and the **applied** (saturated, or held) `u` is what
//! enters `φ` and the filters.
//!
//! # Target model and filtered quantities, (2.19)–(2.20), (3.39), (3.49)
//!
//! `G_f(q)` (`l_z × l_u`) is a [`TargetModel`]: FIR from Markov parameters (3.39) or
//! per-channel transfer functions `β z^{−d} Ĝ_d(z)` (3.49). [`TargetFilter`] keeps
//! `u_{f,k} = G_f(q) u_k` and `Φ_{f,k} = G_f(q) Φ_k` incrementally; row `o` of `Φ_{f,k}` is
//! `[ψ_{o,1,k}ᵀ … ψ_{o,l_u,k}ᵀ]`, `ψ_{o,j,k} = G_{f,oj}(q) φ_k`. The retrospective
//! performance variable is
//!
//! ```text
//! ẑ_k(θ̂) = z_k − (u_{f,k} − Φ_{f,k} θ̂)                                         (2.20)
//! ```
//!
//! `G_f` must be strictly proper (`H_0 = 0`): in this system `z_k` is sampled before `u_k`
//! is applied, so the plant's `G_{zu,d}` is strictly proper, and then `u_{f,k}` and
//! `Φ_{f,k}` only involve `u_{k−1}, y_{k−2}` and older.
//!
//! # Timing of the update
//!
//! At step `k` the controller has `y_k`, `z_k` and the past. It
//!
//! 1. forms `u_{f,k}`, `Φ_{f,k}` (past data only, `G_f` strictly proper) and `Φ_k`
//!    (`u_{k−1}, y_{k−1}` and older);
//! 2. updates `θ_k → θ_{k+1}` with the cost term of index `k` (which contains `z_k`);
//! 3. applies `u_k = sat(Φ_k θ_{k+1})` (0 for `k < k_w`);
//! 4. stores `u_k` and `y_k` (they enter `φ_{k+1}`).
//!
//! `u_k` thus uses the coefficients `θ_{k+1}` that already account for `z_k`, which is the
//! `ũ_k(θ_{k+1}) = u_k − Φ_k θ_{k+1}` of §3.1 (3.27)–(3.29): with this timing
//! `ũ_k(θ_{k+1}) = 0` at the newest sample (before saturation) and `G_f` acts on the
//! older `ũ_{k−i}(θ_{k+1})`, `i ≥ 1`. `y_k` itself enters `u_{k+1}` (the controller (2.15)
//! is strictly proper). For `k < k_w` steps 2 and 3 are skipped (`θ = θ_0`, `u_k = 0`)
//! while the history fills: (2.16) with "`k_w ≥ n_c` the number of steps to wait until
//! `Φ_k` is populated with data". This matters for the normalized gradient step sizes,
//! which would take huge steps on the nearly empty regressor of the first samples. The
//! default `k_w` is `n_c` plus the largest lag of `G_f` (then every entry of `Φ_{f,k}`
//! holds measured data).
//!
//! This is the compute-first timing of [`Controller::step`]: `u_k` waits for `z_k`. It
//! departs from (2.16), `u_k = Φ_k θ_k`, by one update, and it needs the update's cost
//! inside the period. The ahead form below is (2.16) itself.
//!
//! # Ahead form (2.16) and plans
//!
//! (2.16) is strictly causal: `u_k = Φ_k θ_k` with `Φ_k` holding `u_{k−1}, y_{k−1}` and
//! older and `θ_k` updated with the cost term of index `k − 1`, so `u_{k+1}` is known as
//! soon as sample `k` is in. [`Controller::ahead`] is therefore always `Some`
//! ([`RcacParams::answers_ahead`]), and the [`Ahead`] form runs, for sample `k`,
//!
//! 1. `advance(k, applied, adapt)`: steps 1–2 above, exactly as `step` (the same code:
//!    [`StepInput::u_applied`] corrects the stored `u_{k−1}`, lost samples are bridged,
//!    `Φ_{f,k}` and `u_{f,k}` are formed, and `θ_k → θ_{k+1}` with the cost term of index
//!    `k`), except that the update is skipped when `adapt` is false (the analogue of
//!    [`Controller::observe`]); then `applied`, the input the plant applies for sample
//!    `k` as far as the loop knows, is stored as `u_k` with `y_k` (they enter `φ_{k+1}`;
//!    a non-finite entry of `applied` keeps the previous input), and the counter becomes
//!    `k + 1`;
//! 2. it prepares the ready input, which [`Ahead::ready`] returns until the next
//!    `advance`, with its status bits (`SATURATED`; `CONTROLLER_FAULT` with `applied`
//!    held when `y_k` or `z_k` was not finite, or when the guard reset `θ`):
//!
//! ```text
//! u_{k+1} = sat(Φ_{k+1} θ_{k+1})    (0, saturated, while k + 1 < k_w)              (2.16)
//! ```
//!
//! After [`Controller::reset`] or [`Controller::restart_data`] the ready input is the
//! start-up input `sat(0)` (the counter is 0 < `k_w`). So, per (2.16), `u_k = 0` for
//! `k < k_w` in both forms, and from `k_w` on the ahead form applies
//! `Φ_k θ_k` where compute-first applies `Φ_k θ_{k+1}`: one sample of adaptation later,
//! none of the update's cost in the response time. `theta_norm` and `zhat0` are those of
//! `θ_{k+1}` in both forms.
//!
//! **A smaller gradient step.** Using each update one sample later is harmless for RLS,
//! but a large normalized gradient step can overshoot with it: on the lightly damped
//! SISO loop of the tests (`μ_Exp`), α = 0.25 gives the same rejection as compute-first
//! (90.5 against 89.8 dB, largest `|z|` 5.0 against 4.1), while α = 0.5 gives a transient
//! with `|z|` up to about 10⁵ before it converges (compute-first: 5), and α = 1 about
//! 5·10⁹. Check α for the ahead form on the rig (the acoustic rig's scenario uses
//! α = 0.05).
//!
//! **The plan** ([`Ahead::plan`]). Beyond the ready input nothing is exact: the inputs
//! `u_{k+2}, …` depend on measurements not yet taken. The plan runs the controller (2.15)
//! on with `θ_{k+1}` held and the coming measurements `y_{k+1}, y_{k+2}, …` predicted at
//! their regulation target 0:
//!
//! ```text
//! φ̂_{k+2} = [u_{k+1}; u_k; …; u_{k+2−n_c}; 0; y_k; …; y_{k+2−n_c}]
//! û_{k+2+j} = sat(Θ φ̂_{k+2+j}),   φ̂_{k+3+j} = φ̂_{k+2+j} with û_{k+2+j} and 0 shifted in
//! ```
//!
//! (0 while the counter would be below `k_w`), i.e. exactly the ready inputs a copy of
//! the controller would prepare if it were fed `y = 0` and did not adapt. Row `j` of the
//! plan is `û_{k+2+j}`; the cost is `O(H l_θ)` for `H ≤` [`MAX_PLAN_ROWS`] rows. The `u`
//! parts of the `φ̂` are windows of one pre-allocated buffer into which each row is
//! written as it is made, the `y` parts windows of one that holds the predicted zeros
//! before the measured past: nothing is shifted. A plant applies a plan entry only when an answer is
//! late; the prediction at 0 is the closed loop's goal (z → 0), and the controller's own
//! dynamics carry the input on.
//!
//! # RLS update, (2.21)–(2.23)
//!
//! ```text
//! J_k(θ̂) = Σ_{i=1}^{k} λ^{k−i} [ẑ_iᵀ R_z ẑ_i + (Φ_i θ̂)ᵀ R_u (Φ_i θ̂)] + λ^k (θ̂ − θ_0)ᵀ R_θ (θ̂ − θ_0)   (2.21)
//! ```
//!
//! is a weighted least-squares problem for [`Rls`] (`y = φ θ`, unit weights): with
//! `R_z = W_zᵀ W_z` and `R_u = W_uᵀ W_u` (symmetric square roots from an eigen
//! decomposition; `W_u` keeps only the rows of positive eigenvalues), the rows of step `k`
//! are
//!
//! ```text
//! φ = [W_z Φ_{f,k}; W_u Φ_k],   y = [W_z (u_{f,k} − z_k); 0],   R_θ = I / p0 (P_0 = p0 I)
//! ```
//!
//! because `W_z ẑ_k(θ̂) = W_z Φ_{f,k} θ̂ − y_z` (2.20), so
//! `|φ θ̂ − y|² = ẑ_kᵀ R_z ẑ_k + (Φ_k θ̂)ᵀ R_u (Φ_k θ̂)`, the bracket of (2.21).
//!
//! Sign check against (2.22): the RLS prior error is `e = y − φ θ_k = −[W_z(Φ_{f,k} θ_k + z_k − u_{f,k}); W_u Φ_k θ_k]`, and
//! `θ_{k+1} = θ_k + β P_k φᵀ (I + β φ P_k φᵀ)⁻¹ e
//!          = θ_k − P_k Φ̄ᵀ (λ R̄⁻¹ + Φ̄ P_k Φ̄ᵀ)⁻¹ (Φ̄ θ_k + [z_k − u_{f,k}; 0])` with
//! `Φ̄ = [Φ_{f,k}; Φ_k]`, `R̄ = diag(R_z, R_u)`, `λ = 1/β` — (2.22), and the covariance
//! recursion of [`Rls`] is (2.23) in the same way. The forgetting factor `λ_k` comes from
//! any [`ForgettingRule`] (constant `λ`, or the F-test / RMS rules of chapter 5 applied
//! to the `l_z + rank R_u` prior errors). [`Rls`]'s guard resets `θ, P` to `θ_0, P_0` on
//! blow-up (`tr P > trace-limit`, non-finite values); each reset is counted.
//!
//! # Gradient update, (3.51)–(3.63)
//!
//! With the same rows `A = [W_z Φ_{f,k}; W_u Φ_k]`, `b = [W_z(u_{f,k} − z_k); 0]` and
//! `R = r I` (`r ≥ 0`), the instantaneous cost and its gradient are
//!
//! ```text
//! J_k(θ) = ½ (|A θ − b|² + r |θ|²)          (3.51)  (= ½(ẑ_kᵀẑ_k + θᵀRθ) for R_z = I, R_u = 0)
//! g_k    = Aᵀ(A θ_k − b) + r θ_k             (3.52)  (= Φ_{f,k}ᵀ ẑ_k(θ_k) + R θ_k)
//! θ_{k+1} = θ_k − μ_k g_k                     (3.53)–(3.54)
//! ```
//!
//! with one of the step sizes, each multiplied by `α ∈ (0, 1]`:
//!
//! ```text
//! μ_opt = gᵀg / (gᵀ(AᵀA + rI)g) = |g|² / (|A g|² + r|g|²)                         (3.57)
//! μ_σ   = 1 / σ_max(AᵀA + rI)   = 1 / (λ_max(A Aᵀ) + r)                            (3.60)
//! μ_F   = 1 / ‖AᵀA + rI‖_F      = 1 / sqrt(‖A Aᵀ‖_F² + 2 r ‖A‖_F² + r² l_θ)        (3.61)
//! μ_Exp = 1 / ‖A‖_F²   (r = 0; for r > 0: 1 / (‖A‖_F² + r √l_θ) ≤ μ_F)             (3.63)
//! ```
//!
//! None of them forms an `l_θ × l_θ` matrix: `A Aᵀ` is `p × p` (`p = l_z + rank R_u`,
//! its largest eigenvalue by cyclic Jacobi with a bounded number of sweeps) and
//! `‖AᵀA‖_F = ‖AAᵀ‖_F`. The work per step is `O(p² l_θ)`. When the denominator is zero
//! (no data yet) the step is skipped (`μ_k = 0`). A non-finite `θ` is reset to `θ_0`
//! (counted).
//!
//! # Imperfect loops: late actuations and lost samples
//!
//! `φ`, `u_f` and `Φ_f` must hold what the plant saw. In real time two things break that:
//!
//! - **A late actuation.** The plant then held an older (or its safe) input instead of
//!   `u_{k−1}`. When the measurement reports the input really applied
//!   ([`StepInput::u_applied`]), it replaces the stored `u_{k−1}` at the start of step `k`,
//!   before anything reads it (the filter's lags are ≥ 1), so the history stays exact.
//! - **Samples the loop received late or never.** A sample that arrived while a newer
//!   one was waiting is recorded without an update or an input
//!   ([`Controller::observe`]: filter and history advance). `m` samples that never
//!   arrived ([`StepInput::lost`]) are bridged by `m` history entries and the update
//!   pauses, as the [`GapRule`] says (a gap of `L` or more, `L` the history length, clears
//!   the history and waits `L` steps under every rule). The input is still computed during
//!   the pause. Each gap is counted (internal `gaps`); the steps suspended for it are
//!   counted by [`Controller::adaptation`].
//!
//! **Gap rules.** A bridged entry at sample `j` sits in the direct window of `φ_k` for
//! `k ∈ (j, j + n_c]` and in the windows of `Φ_{f,k}`, `u_{f,k}` until `k = j + L`.
//!
//! - [`GapRule::Suspend`], the original rule: the held `y` and `u` bridge the gap (the
//!   reported `u_applied` first replaces the newest stored input) and the update is
//!   suspended for `L` steps, until the bridged entries have left every window: only
//!   exact rows, but on a rig with a long target model (the acoustic rig: `L` = 250) a gap
//!   every few hundred samples stops the adaptation.
//! - [`GapRule::Resume`] with [`GapBridge::Plan`] (the default): the bridged inputs are
//!   the ready input `u_{j} = sat(Φ_j θ)` and then (2.15) run on over the bridged
//!   regressor with `θ` held and the bridged measurements at their regulation target 0:
//!   the ready input and the plan's entries of the ahead form, i.e. what a plant whose
//!   late policy applies the plan did apply. The input reported for the last lost sample
//!   (`u_applied`) then replaces the last bridged one. The update resumes `p` steps after
//!   the first sample that arrived again (`p = n_c` by default: `φ_k`, which `θ`
//!   multiplies for the new input, then holds measured data only), accepting rows whose
//!   `Φ_{f,k}`, `u_{f,k}` windows still hold bridged entries: their `u` parts are exact
//!   under the plan policy and their `y` parts are off by the residual `y` (small in
//!   closed loop), so `ẑ_k(θ)` (2.20) stays near the retrospective performance of the
//!   measured data.
//! - [`GapRule::Resume`] with [`GapBridge::Hold`]: the same pause with the held values.
//!
//! Without a lost sample every rule runs the same code (the original one): a loss-free
//! run does not depend on the rule. docs/results/gap-rule.md measures the rules.
//!
//! # Real time
//!
//! [`Controller::step`] and the ahead form ([`Ahead::advance`], [`Ahead::ready`],
//! [`Ahead::plan`]) do not allocate (every buffer is sized in [`Rcac::new`]), do not
//! index out of bounds (slices are taken with `get`), and their loops are bounded by the
//! dimensions (and the plan's length). A non-finite `y_k` or `z_k` skips the update,
//! holds the last applied input and reports [`status::CONTROLLER_FAULT`] (the
//! non-finite entries of `y_k` are replaced by the last finite ones in the history). A
//! guard reset of `θ` also reports `CONTROLLER_FAULT`.
//!
//! Cost per step: the RLS update is dominated by the `O(l_θ² p)` covariance sweep of
//! [`Rls`], the gradient update is `O(l_θ p)`; latency-bench measures both at the acoustic
//! rig's size (`docs/results/latency-bench.md`).
//!
//! # Internals (signal log)
//!
//! `theta_norm` (`‖θ_{k+1}‖`), `trace_p` (RLS: `tr P_{k+1}`) or `mu` (gradient: `μ_k`,
//! α included), `z0` (`z_{k,0}`), `zhat0` (`ẑ_{k,0}(θ_{k+1})`, the retrospective
//! performance with the updated coefficients), `lambda` (`λ_k`; 1 for the gradient) and
//! `resets` (guard resets of `θ` since construction).

pub mod builder;
mod filter;
#[cfg(test)]
mod tests;

pub use builder::RcacBuilder;
pub use filter::TargetFilter;

use crate::ParamError;
use crate::ahead::{Ahead, MAX_PLAN_ROWS};
use crate::controller::{Controller, OutputLimits, StepInput};
use crate::controller::{Dimensions, Tunable, status};
use crate::forgetting::ForgettingRule;
use crate::linalg::{axpy, dot};
use crate::output_limits::limit_output;
use crate::rls::{Rls, RlsConfig};
use crate::target::TargetModel;
use nalgebra::DMatrix;

/// Step size of the gradient variant (§3.4), each multiplied by `α`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepSize {
    /// `μ_opt` (3.57), the exact line minimizer of the instantaneous cost.
    Opt,
    /// `μ_σ` (3.60).
    Sigma,
    /// `μ_F` (3.61).
    Frobenius,
    /// `μ_Exp` (3.63).
    Exp,
}

/// How `θ` is updated.
#[derive(Debug, Clone, PartialEq)]
pub enum RcacUpdate {
    /// RLS (2.22)–(2.23) through [`Rls`].
    Rls {
        /// `P_0 = p0 I`, i.e. `R_θ = I / p0`.
        p0: f64,
        /// Forgetting rule for `λ_k`.
        rule: ForgettingRule,
        /// `tr P` above this resets `θ, P` (must exceed `l_θ p0`; may be `+∞`).
        trace_limit: f64,
    },
    /// Gradient descent on the instantaneous cost (3.51)–(3.63).
    Gradient {
        /// Which step size.
        step_size: StepSize,
        /// `α ∈ (0, 1]`.
        alpha: f64,
        /// `R = r I`, `r ≥ 0`.
        r: f64,
    },
}

/// How the history bridges samples that never reached the controller, and when the
/// update resumes after them (module docs, "Imperfect loops").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GapRule {
    /// The original rule: the gap is bridged with the held `y` and `u`, and the update is
    /// suspended for `L` steps (the history length), until no bridged entry is left in any
    /// window of `u_{f,k}`, `Φ_{f,k}` or `Φ_k`.
    Suspend,
    /// The gap is bridged as `bridge` says and the update resumes `pause` steps after the
    /// first sample that arrived again, accepting the rows whose windows still hold
    /// bridged entries; the input the plant reports for the last lost sample
    /// ([`StepInput::u_applied`]) replaces the bridged one.
    Resume {
        /// What stands in for the lost samples.
        bridge: GapBridge,
        /// Steps without an update after the gap, `≤ L`; `None`: `n_c`, the length of the
        /// direct windows of `φ_k` (then the regressor that the new input multiplies holds
        /// measured data only).
        pause: Option<usize>,
    },
}

/// What stands in for the lost samples in the history under [`GapRule::Resume`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GapBridge {
    /// The held `y` and `u`, as [`GapRule::Suspend`] does.
    Hold,
    /// The ahead form's plan: `y` predicted at its regulation target 0 and `u` the
    /// controller (2.15) run on over the bridged regressor with `θ` held (0 before `k_w`),
    /// i.e. the ready input and then the plan's entries, which is what a plant whose late
    /// policy applies the plan did apply.
    Plan,
}

/// Validated parameters of an [`Rcac`] controller.
#[derive(Debug, Clone, PartialEq)]
pub struct RcacParams {
    /// Controller order `n_c ≥ 1`.
    pub nc: usize,
    /// Steps with `u_k = 0` and no update (2.16); `None`: `n_c` plus the largest lag of
    /// `G_f`, the first step at which `Φ_{f,k}` holds measured data in every entry.
    pub kw: Option<usize>,
    /// The target model `G_f` (`l_z × l_u`, at the rig's sample period).
    pub target: TargetModel,
    /// `R_z` (`l_z × l_z`, symmetric positive definite).
    pub rz: DMatrix<f64>,
    /// `R_u` (`l_u × l_u`, symmetric positive semidefinite).
    pub ru: DMatrix<f64>,
    /// `θ_0` (length `l_θ`); `None`: zero.
    pub theta0: Option<Vec<f64>>,
    /// The update law.
    pub update: RcacUpdate,
    /// Output saturation.
    pub limits: Option<OutputLimits>,
    /// The rig's sample period in s; the target model's must equal it.
    pub sample_period: f64,
    /// What bridges lost samples and when the update resumes after them.
    pub gap_rule: GapRule,
}

enum Law {
    Rls(Box<Rls>),
    Gradient {
        step_size: StepSize,
        alpha: f64,
        r: f64,
        theta: Vec<f64>,
        /// `A θ − b`, then `A g` (p).
        res: Vec<f64>,
        /// `g` (l_θ).
        grad: Vec<f64>,
        /// `A Aᵀ` scratch (p × p).
        gram: Vec<f64>,
        resets: u64,
    },
}

/// Whether the gradient update admits the step-size factor `α`: `α ∈ (0, 1]`.
fn alpha_admits(alpha: f64) -> bool {
    alpha > 0.0 && alpha <= 1.0
}

/// Index of `α` in [`TUNABLES`].
const ALPHA: usize = 0;

/// What an operator may change while RCAC runs ([`Controller::tunables`]).
static TUNABLES: [Tunable; 1] = [Tunable {
    name: "alpha",
    range: "(0, 1]",
    admits: alpha_admits,
}];

/// The RCAC controller (see the module docs).
pub struct Rcac {
    counts: Dimensions,
    lu: usize,
    ly: usize,
    lz: usize,
    nphi: usize,
    ltheta: usize,
    kw: u64,
    filter: TargetFilter,
    /// `W_z` (l_z × l_z row-major).
    wz: Vec<f64>,
    /// `W_u` (ru_rows × l_u row-major).
    wu: Vec<f64>,
    ru_rows: usize,
    /// `Φ_{f,k}` (l_z × l_θ row-major).
    phi_f: Vec<f64>,
    /// `u_{f,k}`.
    u_f: Vec<f64>,
    /// Stacked rows `A` ((l_z + ru_rows) × l_θ) and targets `b`.
    a: Vec<f64>,
    b: Vec<f64>,
    law: Law,
    theta0: Vec<f64>,
    /// Last applied `u`.
    u_last: Vec<f64>,
    /// Last finite `y`.
    y_hold: Vec<f64>,
    k: u64,
    /// No update before this step: the windows still hold samples bridged over a gap
    /// ([`GapRule::Suspend`]) or the pause after one ([`GapRule::Resume`]) is not over.
    update_from: u64,
    gap_rule: GapRule,
    /// Steps without an update after a gap under [`GapRule::Resume`].
    gap_pause: u64,
    /// A bridged input (l_u) and a zero measurement (l_y), for [`GapBridge::Plan`].
    bridge_u: Vec<f64>,
    y_zero: Vec<f64>,
    /// Gaps bridged (lost samples, counted once per gap).
    gaps: u64,
    /// Steps asked to adapt (from `k_w` on): updated, suspended for a bridged gap in the
    /// windows, suspended for a bad sample ([`Controller::adaptation`]).
    adapted: [u64; 3],
    /// The operator froze the update ([`Controller::set_adaptation`]).
    frozen: bool,
    /// Steps asked to adapt (from `k_w` on) while frozen.
    frozen_steps: u64,
    limits: Option<OutputLimits>,
    /// [`RcacParams::answers_ahead`], computed once at construction.
    ahead: bool,
    /// The ahead form's ready input `u_{k+1}` and its status bits.
    ready_u: Vec<f64>,
    ready_status: u32,
    /// Plan scratch: the `u` and `y` parts of the predicted regressors `φ̂`, each one
    /// buffer that the rows' regressors are windows of (`MAX_PLAN_ROWS + n_c` blocks of
    /// `l_u`, `MAX_PLAN_ROWS + 1 + n_c` of `l_y`; see [`Ahead::plan`]).
    plan_u: Vec<f64>,
    plan_y: Vec<f64>,
    // Internals.
    theta_norm: f64,
    trace_or_mu: f64,
    z0: f64,
    zhat0: f64,
    lambda: f64,
}

impl std::fmt::Debug for Rcac {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rcac")
            .field("counts", &self.counts)
            .field("l_theta", &self.ltheta)
            .field("k", &self.k)
            .finish_non_exhaustive()
    }
}

/// `Ok` when the weight `m`, named `name`, has the `n` rows of an `n × n` weight, else
/// the refusal that names its size.
fn check_weight_size(m: &DMatrix<f64>, name: &'static str, n: usize) -> Result<(), ParamError> {
    if m.nrows() == n {
        return Ok(());
    }
    Err(ParamError::new(
        name,
        format!("{name} is {}×{}, expected {n}×{n}", m.nrows(), m.ncols()),
    ))
}

/// Symmetric square root rows `W` with `Wᵀ W = M` (eigen decomposition; rows of zero
/// eigenvalues dropped when `drop_zero`). Errors when `M` is not symmetric, has a
/// negative eigenvalue, or (without `drop_zero`) is not positive definite.
fn sqrt_rows(
    m: &DMatrix<f64>,
    name: &'static str,
    definite: bool,
) -> Result<(Vec<f64>, usize), ParamError> {
    let n = m.nrows();
    if m.ncols() != n {
        return Err(ParamError::new(
            name,
            format!("{name} is {}×{}, must be square", n, m.ncols()),
        ));
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(ParamError::new(
            name,
            format!("{name} has a non-finite entry"),
        ));
    }
    let scale = m.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if (m - m.transpose())
        .iter()
        .any(|v| v.abs() > 1e-12 * scale.max(1e-300))
    {
        return Err(ParamError::new(name, format!("{name} is not symmetric")));
    }
    let eig = m.clone().symmetric_eigen();
    let tol = 1e-12 * scale.max(1e-300) * n as f64;
    let mut rows = Vec::new();
    let mut count = 0;
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if definite && (l.is_nan() || l <= tol) {
            return Err(ParamError::new(
                name,
                format!("{name} is not positive definite (eigenvalue {l:e})"),
            ));
        }
        if l < -tol {
            return Err(ParamError::new(
                name,
                format!("{name} is not positive semidefinite (eigenvalue {l:e})"),
            ));
        }
        if l <= tol {
            continue;
        }
        let s = l.sqrt();
        for j in 0..n {
            rows.push(s * eig.eigenvectors[(j, i)]);
        }
        count += 1;
    }
    Ok((rows, count))
}

/// What [`RcacParams::validate`] computes and [`Rcac::new`] keeps.
struct Checked {
    /// `W_z` (l_z × l_z row-major).
    wz: Vec<f64>,
    /// `W_u` (ru_rows × l_u row-major).
    wu: Vec<f64>,
    ru_rows: usize,
    theta0: Vec<f64>,
}

impl RcacParams {
    /// `R_z = DEFAULT_RZ · I` when a configuration gives none.
    pub const DEFAULT_RZ: f64 = 1.0;
    /// `R_u = DEFAULT_RU · I` when a configuration gives none.
    pub const DEFAULT_RU: f64 = 0.0;
    /// The default trace limit is this many times `tr P_0 = l_θ p0`.
    pub const TRACE_LIMIT_FACTOR: f64 = 1e6;
    /// The gradient update's step size when a configuration gives none.
    pub const DEFAULT_STEP_SIZE: StepSize = StepSize::Exp;
    /// The gradient update's `R = r I` when a configuration gives none.
    pub const DEFAULT_GRADIENT_R: f64 = 0.0;
    /// The gap rule when a configuration gives none: the plan bridge and a pause of `n_c`
    /// steps (docs/results/gap-rule.md measures it against the others).
    pub const DEFAULT_GAP_RULE: GapRule = GapRule::Resume {
        bridge: GapBridge::Plan,
        pause: None,
    };

    /// Whether the controller answers ahead ([`Controller::ahead`] is `Some`, module docs
    /// "Ahead form (2.16) and plans"): always. The controller (2.15)–(2.16),
    /// `u_k = Φ_k θ_k`, is strictly causal, `Φ_k` holding `u_{k−1}, y_{k−1}` and older, so
    /// `u_{k+1}` is known as soon as sample `k` is in. The service's configuration check
    /// calls this to decide whether the loop may answer first or send ahead.
    pub fn answers_ahead(&self) -> bool {
        true
    }

    /// Parameters with the configuration's defaults for everything but the target model,
    /// the order and the update law: `R_z = DEFAULT_RZ · I`, `R_u = DEFAULT_RU · I`,
    /// `θ_0 = 0`, the default `k_w`, no saturation; the sample period is the target
    /// model's.
    pub fn new(target: TargetModel, nc: usize, update: RcacUpdate) -> Self {
        let (lz, lu) = (target.outputs, target.inputs);
        Self {
            nc,
            kw: None,
            rz: DMatrix::identity(lz, lz) * Self::DEFAULT_RZ,
            ru: DMatrix::identity(lu, lu) * Self::DEFAULT_RU,
            theta0: None,
            update,
            limits: None,
            sample_period: target.sample_period,
            target,
            gap_rule: Self::DEFAULT_GAP_RULE,
        }
    }

    /// The pause of [`GapRule::Resume`] in steps (`n_c` when it gives none); `None` for
    /// [`GapRule::Suspend`].
    pub fn gap_pause(&self) -> Option<usize> {
        match self.gap_rule {
            GapRule::Suspend => None,
            GapRule::Resume { pause, .. } => Some(pause.unwrap_or(self.nc)),
        }
    }

    /// `l_θ = l_u n_c (l_u + l_y)`, the number of coefficients for a rig with `counts`.
    pub fn theta_len(nc: usize, counts: Dimensions) -> usize {
        counts.n_u * nc * (counts.n_u + counts.n_y)
    }

    /// The trace limit when a configuration gives none: `10⁶ l_θ p0`.
    pub fn default_trace_limit(nc: usize, counts: Dimensions, p0: f64) -> f64 {
        Self::TRACE_LIMIT_FACTOR * Self::theta_len(nc, counts) as f64 * p0
    }

    /// `k_w` when [`RcacParams::kw`] is `None`: `n_c` plus the largest lag of `G_f`, the
    /// first step at which `Φ_{f,k}` holds measured data in every entry.
    ///
    /// # Errors
    ///
    /// A target model that [`TargetFilter::validate`] refuses (field `"target-model"`).
    pub fn default_kw(&self) -> Result<usize, ParamError> {
        let lag = TargetFilter::largest_lag(&self.target).map_err(in_target_model)?;
        Ok(lag + self.nc.max(1))
    }

    /// Checks the parameters for a rig with `counts` (`l_y = n_y`, `l_z = n_z`,
    /// `l_u = n_u`) without building anything; [`Rcac::new`] calls it.
    ///
    /// # Errors
    ///
    /// The first refused field, named as RCAC's configuration table names it: `"nc"`
    /// (`n_c = 0`); `"target-model"` (`outputs ≠ l_z`, `inputs ≠ l_u`, or what
    /// [`TargetFilter::validate`] refuses: a feedthrough or an unstable pole, the message
    /// naming the entry; the model's own values are [`TargetModel::validate`]'s to check
    /// when it is read); `"target-model.sample-period"` (another sample period); `"rz"` (not
    /// `l_z × l_z` symmetric positive definite); `"ru"` (not `l_u × l_u` symmetric positive
    /// semidefinite); `"theta0"` (not `l_θ` finite values); `"u-min"` (bad limits);
    /// `"p0"`, `"trace-limit"` and the [`ForgettingRule::validate`] fields for RLS;
    /// `"alpha"` (`∉ (0, 1]`) and `"r"` (`< 0`) for the gradient update.
    pub fn validate(&self, counts: Dimensions) -> Result<(), ParamError> {
        self.check(counts).map(|_| ())
    }

    fn check(&self, counts: Dimensions) -> Result<Checked, ParamError> {
        let (lz, lu) = (counts.n_z, counts.n_u);
        if self.nc == 0 {
            return Err(ParamError::new(
                "nc",
                "0: the controller order n_c must be at least 1",
            ));
        }
        if lz == 0 || lu == 0 {
            return Err(ParamError::new(
                "target-model",
                format!(
                    "RCAC needs at least one performance variable z and one input u (z: {lz}, u: {lu})"
                ),
            ));
        }
        let t = &self.target;
        if t.outputs != lz || t.inputs != lu {
            return Err(ParamError::new(
                "target-model",
                format!(
                    "has {} outputs and {} inputs; the rig has l_z = {lz} performance \
                     variables and l_u = {lu} inputs",
                    t.outputs, t.inputs
                ),
            ));
        }
        let ts = self.sample_period;
        if ts.is_nan() || ts <= 0.0 || (t.sample_period - ts).abs() > 1e-9 * ts {
            return Err(ParamError::new(
                "target-model.sample-period",
                format!(
                    "{} s differs from the rig's sample period {ts} s",
                    t.sample_period
                ),
            ));
        }
        TargetFilter::validate(t).map_err(in_target_model)?;
        if let Some(pause) = self.gap_pause() {
            let len = TargetFilter::largest_lag(t).map_err(in_target_model)? + self.nc;
            if pause > len {
                return Err(ParamError::new(
                    "gap-pause",
                    format!(
                        "{pause} exceeds the history length L = {len} (the largest lag of G_f \
                         plus n_c); gap-rule = \"suspend\" pauses L steps"
                    ),
                ));
            }
        }
        let ltheta = Self::theta_len(self.nc, counts);
        let (wz, _) = sqrt_rows(&self.rz, "rz", true)?;
        check_weight_size(&self.rz, "rz", lz)?;
        check_weight_size(&self.ru, "ru", lu)?;
        let (wu, ru_rows) = sqrt_rows(&self.ru, "ru", false)?;
        let theta0 = match &self.theta0 {
            None => vec![0.0; ltheta],
            Some(v) if v.len() == ltheta && v.iter().all(|x| x.is_finite()) => v.clone(),
            Some(v) if v.len() == ltheta => {
                return Err(ParamError::new("theta0", "theta0 has a non-finite entry"));
            }
            Some(v) => {
                return Err(ParamError::new(
                    "theta0",
                    format!(
                        "theta0 has {} entries, expected l_θ = l_u n_c (l_u + l_y) = {ltheta}",
                        v.len()
                    ),
                ));
            }
        };
        if let Some(l) = &self.limits {
            l.validate(lu)?;
        }
        match &self.update {
            RcacUpdate::Rls {
                p0,
                rule,
                trace_limit,
            } => {
                if !(*p0 > 0.0 && p0.is_finite()) {
                    return Err(ParamError::new(
                        "p0",
                        format!("{p0} must be positive and finite"),
                    ));
                }
                let trace0 = ltheta as f64 * p0;
                if trace_limit.is_nan() || *trace_limit <= trace0 {
                    return Err(ParamError::new(
                        "trace-limit",
                        format!("{trace_limit} must exceed tr(P_0) = l_θ p0 = {trace0}"),
                    ));
                }
                rule.validate(lz + ru_rows)?;
            }
            RcacUpdate::Gradient { alpha, r, .. } => {
                if !alpha_admits(*alpha) {
                    return Err(ParamError::new(
                        "alpha",
                        format!("{alpha} is outside (0, 1]"),
                    ));
                }
                if !(*r >= 0.0 && r.is_finite()) {
                    return Err(ParamError::new("r", format!("{r} must be finite and ≥ 0")));
                }
            }
        }
        Ok(Checked {
            wz,
            wu,
            ru_rows,
            theta0,
        })
    }
}

/// A target-model error as an error of RCAC's `target-model` field, the entry in the
/// message.
fn in_target_model(e: ParamError) -> ParamError {
    ParamError::new("target-model", e.to_string())
}

impl Rcac {
    /// Builds the controller for the rig's channels (`l_y = n_y`, `l_z = n_z`,
    /// `l_u = n_u`), allocating every buffer, after [`RcacParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`RcacParams::validate`].
    pub fn new(params: &RcacParams, counts: Dimensions) -> Result<Self, ParamError> {
        let Checked {
            wz,
            wu,
            ru_rows,
            theta0,
        } = params.check(counts)?;
        let (ly, lz, lu) = (counts.n_y, counts.n_z, counts.n_u);
        let filter = TargetFilter::new(&params.target, ly, params.nc).map_err(in_target_model)?;
        let nphi = filter.regressor_len();
        let ltheta = lu * nphi;
        let p = lz + ru_rows;
        let law = match &params.update {
            RcacUpdate::Rls {
                p0,
                rule,
                trace_limit,
            } => Law::Rls(Box::new(
                Rls::new(&RlsConfig {
                    n: ltheta,
                    p,
                    theta0: theta0.clone(),
                    p0: *p0,
                    rule: rule.clone(),
                    trace_limit: *trace_limit,
                })
                .map_err(|e| ParamError::new("update", e))?,
            )),
            RcacUpdate::Gradient {
                step_size,
                alpha,
                r,
            } => Law::Gradient {
                step_size: *step_size,
                alpha: *alpha,
                r: *r,
                theta: theta0.clone(),
                res: vec![0.0; p],
                grad: vec![0.0; ltheta],
                gram: vec![0.0; p * p],
                resets: 0,
            },
        };
        let mut s = Self {
            counts,
            lu,
            ly,
            lz,
            nphi,
            ltheta,
            kw: params.kw.unwrap_or(filter.history_len()) as u64,
            filter,
            wz,
            wu,
            ru_rows,
            phi_f: vec![0.0; lz * ltheta],
            u_f: vec![0.0; lz],
            a: vec![0.0; p * ltheta],
            b: vec![0.0; p],
            law,
            theta0,
            u_last: vec![0.0; lu],
            y_hold: vec![0.0; ly],
            k: 0,
            update_from: 0,
            gap_rule: params.gap_rule,
            gap_pause: params.gap_pause().unwrap_or(0) as u64,
            bridge_u: vec![0.0; lu],
            y_zero: vec![0.0; ly],
            gaps: 0,
            adapted: [0; 3],
            frozen: false,
            frozen_steps: 0,
            limits: params.limits.clone(),
            ahead: params.answers_ahead(),
            ready_u: vec![0.0; lu],
            ready_status: status::OK,
            plan_u: vec![0.0; (MAX_PLAN_ROWS + params.nc) * lu],
            plan_y: vec![0.0; (MAX_PLAN_ROWS + 1 + params.nc) * ly],
            theta_norm: 0.0,
            trace_or_mu: 0.0,
            z0: 0.0,
            zhat0: 0.0,
            lambda: 1.0,
        };
        s.reset();
        Ok(s)
    }

    /// The current coefficients `θ` (length `l_θ`, row-major `Θ`).
    pub fn theta(&self) -> &[f64] {
        law_theta(&self.law)
    }

    /// `l_θ = l_u n_c (l_u + l_y)`.
    pub fn theta_len(&self) -> usize {
        self.ltheta
    }

    /// Guard resets of `θ` since construction.
    pub fn resets(&self) -> u64 {
        match &self.law {
            Law::Rls(r) => r.resets(),
            Law::Gradient { resets, .. } => *resets,
        }
    }

    /// The target-model filter (for inspection and tests).
    pub fn filter(&self) -> &TargetFilter {
        &self.filter
    }

    /// `Φ_{f,k}` of the last step (`l_z × l_θ` row-major).
    pub fn phi_f(&self) -> &[f64] {
        &self.phi_f
    }

    /// `u_{f,k}` of the last step.
    pub fn u_f(&self) -> &[f64] {
        &self.u_f
    }

    /// Gaps bridged so far (each run of lost samples counts once).
    pub fn gaps(&self) -> u64 {
        self.gaps
    }

    /// Brings the history in line with the plant before sample `k` is used: the input the
    /// plant really applied after sample `k − 1` replaces the one stored, and samples lost
    /// before `k` are bridged as the [`GapRule`] says (module docs, "Imperfect loops").
    fn absorb(&mut self, input: &StepInput<'_>) {
        let applied = input
            .u_applied
            .filter(|ua| ua.len() >= self.lu && ua.iter().take(self.lu).all(|v| v.is_finite()));
        let GapRule::Resume { bridge, .. } = self.gap_rule else {
            self.absorb_suspend(applied, input.lost);
            return;
        };
        if input.lost == 0 {
            if let Some(ua) = applied {
                self.correct_last_u(ua);
            }
            return;
        }
        let len = self.filter.history_len() as u64;
        if input.lost >= len {
            self.filter.reset();
            self.k = self.k.saturating_add(input.lost);
            self.update_from = self.k.saturating_add(len);
        } else {
            for _ in 0..input.lost {
                self.filter.filter(&mut self.phi_f, &mut self.u_f);
                if bridge == GapBridge::Plan {
                    // u_j = sat(Φ_j θ) (0 before k_w) with y_j predicted at 0: the plan.
                    if self.k < self.kw {
                        self.bridge_u.fill(0.0);
                    } else {
                        let (pu, py) = self.filter.regressor(0);
                        let theta = law_theta(&self.law);
                        controller_output(theta, pu, py, self.nphi, self.lu, &mut self.bridge_u);
                    }
                    let _ = limit_output(self.limits.as_ref(), &mut self.bridge_u);
                    self.u_last.copy_from_slice(&self.bridge_u);
                    self.filter.push(&self.bridge_u, &self.y_zero);
                } else {
                    self.filter.push(&self.u_last, &self.y_hold);
                }
                self.k = self.k.saturating_add(1);
            }
            self.update_from = self.k.saturating_add(self.gap_pause);
        }
        // u_applied is the input applied after sample k − 1, the last bridged one.
        if let Some(ua) = applied {
            self.correct_last_u(ua);
        }
        self.gaps += 1;
    }

    /// [`Rcac::absorb`] under [`GapRule::Suspend`], the original rule: the reported input
    /// replaces the newest stored one, then `lost` entries of the held `y` and `u` bridge
    /// the gap and the update waits `L` steps.
    fn absorb_suspend(&mut self, applied: Option<&[f64]>, lost: u64) {
        if let Some(ua) = applied {
            self.correct_last_u(ua);
        }
        if lost > 0 {
            let len = self.filter.history_len() as u64;
            if lost >= len {
                self.filter.reset();
            } else {
                for _ in 0..lost {
                    self.filter.filter(&mut self.phi_f, &mut self.u_f);
                    self.filter.push(&self.u_last, &self.y_hold);
                }
            }
            self.k = self.k.saturating_add(lost);
            self.update_from = self.k.saturating_add(len);
            self.gaps += 1;
        }
    }

    /// The held input and the newest stored one become `ua` (its first `l_u` entries).
    fn correct_last_u(&mut self, ua: &[f64]) {
        if let Some(ua) = ua.get(..self.lu) {
            self.u_last.copy_from_slice(ua);
            self.filter.correct_last_u(&self.u_last);
        }
    }

    /// Steps (1)–(2) of the module docs ("Timing of the update") for sample `k`, shared by
    /// [`Controller::step`] and [`Ahead::advance`]: brings the history in line with the
    /// plant ([`Rcac::absorb`]), forms `Φ_{f,k}` and `u_{f,k}`, and updates `θ_k → θ_{k+1}`
    /// when `adapt` (from `k_w` on, not while a bridged gap is in the windows); then the
    /// internals. Returns whether `y_k`, `z_k` and the filtered quantities were finite
    /// (`ok`) and the status bits so far (`CONTROLLER_FAULT` on a bad sample or a guard
    /// reset of `θ`).
    fn take_in(&mut self, input: &StepInput<'_>, adapt: bool) -> (bool, u32) {
        let mut status = status::OK;
        self.absorb(input);
        let lz = self.lz;
        let y_ok = input.y.len() >= self.ly && input.y.iter().all(|v| v.is_finite());
        let z_ok = input.z.len() >= lz && input.z.iter().take(lz).all(|v| v.is_finite());
        // (1) Filtered quantities of index k (past data only).
        self.filter.filter(&mut self.phi_f, &mut self.u_f);
        let filt_sq: f64 = self.phi_f.iter().chain(&self.u_f).map(|v| v * v).sum();
        let filt_ok = filt_sq.is_finite();
        if !filt_ok {
            self.filter.reset();
            self.phi_f.fill(0.0);
            self.u_f.fill(0.0);
        }
        let ok = y_ok && z_ok && filt_ok;
        let learn = self.k >= self.kw && self.k >= self.update_from;
        self.z0 = input.z.first().copied().unwrap_or(f64::NAN);
        // (2) θ_k → θ_{k+1} (from k = k_w on, not while a bridged gap is in the windows,
        // not while the operator holds it frozen).
        if adapt && self.frozen && self.k >= self.kw {
            self.frozen_steps += 1;
        }
        let adapt = adapt && !self.frozen;
        if adapt && self.k >= self.kw {
            let i = if !ok {
                2
            } else if learn {
                0
            } else {
                1
            };
            self.adapted[i] += 1;
        }
        if ok && learn && adapt {
            if self.update_theta(input.z) {
                status |= status::CONTROLLER_FAULT;
            }
        } else if !ok {
            status |= status::CONTROLLER_FAULT;
        }
        self.note_internals(ok);
        (ok, status)
    }

    /// `θ_k → θ_{k+1}` with the rows of step `k` (RLS (2.22)–(2.23) or the gradient step
    /// (3.53)); returns true when the guard reset `θ`.
    fn update_theta(&mut self, z: &[f64]) -> bool {
        self.build_rows(z);
        match &mut self.law {
            Law::Rls(rls) => {
                let st = rls.update(&self.a, &self.b);
                self.lambda = st.lambda;
                self.trace_or_mu = rls.trace_p();
                st.reset
            }
            Law::Gradient {
                step_size,
                alpha,
                r,
                theta,
                res,
                grad,
                gram,
                resets,
            } => {
                let mu = *alpha
                    * gradient_step(*step_size, &self.a, &self.b, theta, *r, res, grad, gram);
                axpy(-mu, grad, theta);
                self.trace_or_mu = mu;
                self.lambda = 1.0;
                if theta.iter().all(|v| v.is_finite()) {
                    false
                } else {
                    theta.copy_from_slice(&self.theta0);
                    *resets += 1;
                    true
                }
            }
        }
    }

    /// `theta_norm` (`‖θ_{k+1}‖`) and `zhat0` (`ẑ_{k,0}(θ_{k+1})`, NaN on a bad sample).
    fn note_internals(&mut self, ok: bool) {
        let lt = self.ltheta;
        let theta = law_theta(&self.law);
        let mut sq = 0.0;
        for t in theta {
            sq += t * t;
        }
        self.theta_norm = sq.sqrt();
        self.zhat0 = if ok {
            let row = self.phi_f.get(..lt).unwrap_or(&[]);
            self.z0 - self.u_f.first().copied().unwrap_or(0.0) + dot(row, theta)
        } else {
            f64::NAN
        };
    }

    /// The ahead form's ready input `u_{k+1}` after `store` of step `k` (the counter is
    /// then `k + 1` and `φ_{k+1}` is `regressor(0)`): `sat(Φ_{k+1} θ_{k+1})` (2.16), `0`
    /// while the counter is below `k_w`, the applied input held on a bad sample (`!ok`,
    /// with `CONTROLLER_FAULT`). Returns the bits of the saturation (and of the hold).
    fn prepare_ready(&mut self, ok: bool) -> u32 {
        let mut st = status::OK;
        if !ok {
            for (d, s) in self.ready_u.iter_mut().zip(&self.u_last) {
                *d = *s;
            }
            st |= status::CONTROLLER_FAULT;
        } else if self.k < self.kw {
            self.ready_u.fill(0.0);
        } else {
            let (pu, py) = self.filter.regressor(0);
            controller_output(
                law_theta(&self.law),
                pu,
                py,
                self.nphi,
                self.lu,
                &mut self.ready_u,
            );
        }
        st | limit_output(self.limits.as_ref(), &mut self.ready_u)
    }

    /// Stores `y_k` (non-finite entries held) with the applied `u_k` at the end of step
    /// `k`.
    fn store(&mut self, y: &[f64]) {
        for (h, v) in self.y_hold.iter_mut().zip(y) {
            if v.is_finite() {
                *h = *v;
            }
        }
        self.filter.push(&self.u_last, &self.y_hold);
        self.k = self.k.saturating_add(1);
    }

    /// Builds the stacked rows `A`, `b` of step `k` from `Φ_{f,k}`, `u_{f,k}`, `z_k`, `φ_k`.
    fn build_rows(&mut self, z: &[f64]) {
        let (lz, lt, nphi) = (self.lz, self.ltheta, self.nphi);
        self.a.fill(0.0);
        for o in 0..lz {
            let mut bo = 0.0;
            for q in 0..lz {
                let w = self.wz.get(o * lz + q).copied().unwrap_or(0.0);
                if w == 0.0 {
                    continue;
                }
                if let (Some(dst), Some(src)) = (
                    self.a.get_mut(o * lt..(o + 1) * lt),
                    self.phi_f.get(q * lt..(q + 1) * lt),
                ) {
                    axpy(w, src, dst);
                }
                let uf = self.u_f.get(q).copied().unwrap_or(0.0);
                let zq = z.get(q).copied().unwrap_or(0.0);
                bo += w * (uf - zq);
            }
            if let Some(d) = self.b.get_mut(o) {
                *d = bo;
            }
        }
        if self.ru_rows > 0 {
            let (pu, py) = self.filter.regressor(0);
            let nu = pu.len();
            for q in 0..self.ru_rows {
                let row = lz + q;
                if let Some(d) = self.b.get_mut(row) {
                    *d = 0.0;
                }
                for j in 0..self.lu {
                    let w = self.wu.get(q * self.lu + j).copied().unwrap_or(0.0);
                    let start = row * lt + j * nphi;
                    if let Some(dst) = self.a.get_mut(start..start + nphi) {
                        let (du, dy) = dst.split_at_mut(nu.min(nphi));
                        axpy(w, pu, du);
                        axpy(w, py, dy);
                    }
                }
            }
        }
    }
}

/// The coefficients `θ` of either update law.
fn law_theta(law: &Law) -> &[f64] {
    match law {
        Law::Rls(r) => r.theta(),
        Law::Gradient { theta, .. } => theta,
    }
}

/// The controller (2.15), `u_j = θ_jᵀ φ` for `j < l_u` (`θ_j` the `j`-th block of `N`
/// entries), with `φ = [pu; py]` given as its `u` and `y` parts. Writes the first `l_u`
/// entries of `u`; does not allocate or panic.
fn controller_output(theta: &[f64], pu: &[f64], py: &[f64], nphi: usize, lu: usize, u: &mut [f64]) {
    let nu = pu.len();
    for (j, d) in u.iter_mut().enumerate().take(lu) {
        let blk = theta.get(j * nphi..(j + 1) * nphi).unwrap_or(&[]);
        let (tu, ty) = blk.split_at(nu.min(blk.len()));
        *d = dot(tu, pu) + dot(ty, py);
    }
}

/// Largest eigenvalue of the symmetric `n × n` matrix `m` (row-major, overwritten) by
/// cyclic Jacobi rotations, at most 64 sweeps. Does not allocate.
fn sym_max_eig(m: &mut [f64], n: usize) -> f64 {
    if n == 0 || m.len() < n * n {
        return 0.0;
    }
    if n == 1 {
        return m[0];
    }
    for _ in 0..64 {
        let mut off = 0.0;
        let mut diag = 0.0;
        for i in 0..n {
            diag += m[i * n + i] * m[i * n + i];
            for j in i + 1..n {
                off += m[i * n + j] * m[i * n + j];
            }
        }
        if off.is_nan() || off <= 1e-30 * diag {
            break;
        }
        for pi in 0..n {
            for qi in pi + 1..n {
                let apq = m[pi * n + qi];
                if apq == 0.0 {
                    continue;
                }
                let (app, aqq) = (m[pi * n + pi], m[qi * n + qi]);
                let tau = (aqq - app) / (2.0 * apq);
                let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
                let t = if tau == 0.0 { 1.0 } else { t };
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = t * c;
                for kk in 0..n {
                    let (akp, akq) = (m[kk * n + pi], m[kk * n + qi]);
                    m[kk * n + pi] = c * akp - s * akq;
                    m[kk * n + qi] = s * akp + c * akq;
                }
                for kk in 0..n {
                    let (apk, aqk) = (m[pi * n + kk], m[qi * n + kk]);
                    m[pi * n + kk] = c * apk - s * aqk;
                    m[qi * n + kk] = s * apk + c * aqk;
                }
            }
        }
    }
    (0..n)
        .map(|i| m[i * n + i])
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The gradient `g = Aᵀ(Aθ − b) + rθ` (3.52) into `grad` and the step size `μ` (3.57),
/// (3.60), (3.61) or (3.63) **without** the factor `α`; 0 when it is undefined (no data,
/// `g = 0`). `a` is `p × l_θ` row-major with `p = res.len()`, `gram` is `p × p` scratch.
/// Does not allocate; `O(p l_θ)` (`O(p² l_θ)` for `Sigma` and `Frobenius`).
#[allow(clippy::too_many_arguments)]
fn gradient_step(
    step_size: StepSize,
    a: &[f64],
    b: &[f64],
    theta: &[f64],
    r: f64,
    res: &mut [f64],
    grad: &mut [f64],
    gram: &mut [f64],
) -> f64 {
    let p = res.len();
    let lt = theta.len();
    let row = |i: usize| a.get(i * lt..(i + 1) * lt).unwrap_or(&[]);
    // res = A θ − b, g = Aᵀ res + r θ.
    let mut a_sq = 0.0;
    for (i, e) in res.iter_mut().enumerate() {
        let ri = row(i);
        a_sq += dot(ri, ri);
        *e = dot(ri, theta) - b.get(i).copied().unwrap_or(0.0);
    }
    for (g, t) in grad.iter_mut().zip(theta) {
        *g = r * t;
    }
    for (i, e) in res.iter().enumerate() {
        axpy(*e, row(i), grad);
    }
    let g2 = dot(grad, grad);
    if matches!(step_size, StepSize::Sigma | StepSize::Frobenius) {
        for i in 0..p {
            for j in 0..=i {
                let v = dot(row(i), row(j));
                if let Some(d) = gram.get_mut(i * p + j) {
                    *d = v;
                }
                if let Some(d) = gram.get_mut(j * p + i) {
                    *d = v;
                }
            }
        }
    }
    let denom = match step_size {
        // μ_opt = |g|² / (|A g|² + r |g|²)  (3.57)
        StepSize::Opt => {
            let mut ag2 = 0.0;
            for i in 0..p {
                let v = dot(row(i), grad);
                ag2 += v * v;
            }
            (ag2 + r * g2) / g2
        }
        // μ_σ = 1 / (λ_max(A Aᵀ) + r)  (3.60)
        StepSize::Sigma => sym_max_eig(gram, p) + r,
        // μ_F = 1 / ‖AᵀA + rI‖_F, ‖AᵀA‖_F = ‖AAᵀ‖_F, tr(AᵀA) = ‖A‖_F²  (3.61)
        StepSize::Frobenius => {
            let f2: f64 = gram.iter().map(|v| v * v).sum();
            (f2 + 2.0 * r * a_sq + r * r * lt as f64).sqrt()
        }
        // μ_Exp = 1 / ‖A‖_F²  (3.63), plus r √l_θ when r > 0
        StepSize::Exp => a_sq + r * (lt as f64).sqrt(),
    };
    let mu = if denom > 0.0 && g2 > 0.0 {
        1.0 / denom
    } else {
        0.0
    };
    if mu.is_finite() { mu } else { 0.0 }
}

impl Controller for Rcac {
    fn kind(&self) -> &'static str {
        "rcac"
    }

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        // (1)–(2) Filtered quantities of index k and θ_k → θ_{k+1}.
        let (ok, mut status) = self.take_in(input, true);
        // (3) u_k = sat(Φ_k θ_{k+1}), 0 before k_w; the last applied u on a bad input.
        if !ok {
            for (d, s) in u.iter_mut().zip(&self.u_last) {
                *d = *s;
            }
        } else if self.k < self.kw {
            u.fill(0.0);
        } else {
            let (pu, py) = self.filter.regressor(0);
            controller_output(law_theta(&self.law), pu, py, self.nphi, self.lu, u);
        }
        status |= limit_output(self.limits.as_ref(), u);
        // (4) Store the applied u_k and y_k (non-finite entries held).
        for (d, s) in self.u_last.iter_mut().zip(u.iter()) {
            *d = *s;
        }
        self.store(input.y);
        status
    }

    /// Records sample `k` without an update or a new input: the history advances with
    /// `y_k` and the input the plant holds (the last applied one, corrected by the next
    /// sample's `u_applied` when the plant reports it).
    fn observe(&mut self, input: &StepInput<'_>, _u: &mut [f64]) {
        self.absorb(input);
        self.filter.filter(&mut self.phi_f, &mut self.u_f);
        self.z0 = input.z.first().copied().unwrap_or(f64::NAN);
        self.store(input.y);
    }

    fn reset(&mut self) {
        match &mut self.law {
            Law::Rls(r) => {
                r.reset();
                self.trace_or_mu = r.trace_p();
            }
            Law::Gradient { theta, .. } => {
                theta.copy_from_slice(&self.theta0);
                self.trace_or_mu = 0.0;
            }
        }
        self.theta_norm = self.theta0.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.restart_data();
    }

    /// Forgets `Φ_f`, `u_f`, the target filter's state, the held `u` and `y`, the sample
    /// counter (the first `k_w` steps of (2.16) wait again while the regressor fills with
    /// the new stream) and the forgetting windows; keeps `θ_k` and `P_k`.
    fn restart_data(&mut self) {
        self.filter.reset();
        if let Law::Rls(r) = &mut self.law {
            r.restart_data();
        }
        self.phi_f.fill(0.0);
        self.u_f.fill(0.0);
        self.u_last.fill(0.0);
        self.y_hold.fill(0.0);
        self.k = 0;
        self.update_from = 0;
        self.z0 = 0.0;
        self.zhat0 = 0.0;
        self.lambda = 1.0;
        self.ready_status = self.prepare_ready(true);
    }

    /// `theta` (θ_k) and, with RLS, its covariance blocks ([`Rls::learned`]).
    fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        match &self.law {
            Law::Rls(r) => r.learned(visit),
            Law::Gradient { theta, .. } => visit("theta", theta),
        }
    }

    fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let restored = match &mut self.law {
            Law::Rls(r) => r.restore_learned(saved).map(|()| {
                self.trace_or_mu = r.trace_p();
                r.theta()
            }),
            Law::Gradient { theta, .. } => saved.block("theta", theta.len()).map(|t| {
                theta.copy_from_slice(t);
                &theta[..]
            }),
        };
        match restored {
            Ok(theta) => {
                self.theta_norm = theta.iter().map(|v| v * v).sum::<f64>().sqrt();
                self.ready_status = self.prepare_ready(true);
                Ok(())
            }
            Err(e) => {
                self.reset();
                Err(e)
            }
        }
    }

    /// `Some` always ([`RcacParams::answers_ahead`]): (2.16) is strictly causal.
    fn ahead(&mut self) -> Option<&mut dyn Ahead> {
        if self.ahead { Some(self) } else { None }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("coefficient resets", self.resets()),
            ("gaps bridged", self.gaps()),
        ]
    }

    /// From `k_w` on: steps updated, suspended for a gap (while a bridged gap is in the
    /// windows under [`GapRule::Suspend`], during the pause after it under
    /// [`GapRule::Resume`]), and suspended on a bad sample.
    fn adaptation(&self) -> Option<crate::controller::Adaptation> {
        let [updated, gap, bad] = self.adapted;
        let gap_cause = match self.gap_rule {
            GapRule::Suspend => crate::controller::Adaptation::BRIDGED_GAP,
            GapRule::Resume { .. } => "the pause after a gap",
        };
        Some(crate::controller::Adaptation {
            updated,
            suspended: vec![
                (gap_cause, gap),
                (crate::controller::Adaptation::BAD_SAMPLE, bad),
            ],
            frozen: self.frozen_steps,
        })
    }

    fn set_adaptation(&mut self, on: bool) -> bool {
        self.frozen = !on;
        true
    }

    /// `α`, the gradient update's step-size factor (3.53); with the RLS update
    /// [`Controller::tunable`] gives `None` for it.
    fn tunables(&self) -> &'static [Tunable] {
        &TUNABLES
    }

    fn tunable(&self, index: usize) -> Option<f64> {
        match (&self.law, index) {
            (Law::Gradient { alpha, .. }, ALPHA) => Some(*alpha),
            _ => None,
        }
    }

    fn set_tunable(&mut self, index: usize, value: f64) -> bool {
        match (&mut self.law, index) {
            (Law::Gradient { alpha, .. }, ALPHA) if alpha_admits(value) => {
                *alpha = value;
                true
            }
            _ => false,
        }
    }

    fn internal_names(&self) -> Vec<String> {
        let second = match self.law {
            Law::Rls(_) => "trace_p",
            Law::Gradient { .. } => "mu",
        };
        [
            "theta_norm",
            second,
            "rcac_z0",
            "rcac_zhat0",
            "lambda",
            "resets",
            "gaps",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    }

    fn internals(&self, out: &mut [f64]) -> usize {
        let vals = [
            self.theta_norm,
            self.trace_or_mu,
            self.z0,
            self.zhat0,
            self.lambda,
            self.resets() as f64,
            self.gaps as f64,
        ];
        let n = vals.len().min(out.len());
        for (d, v) in out.iter_mut().zip(vals) {
            *d = v;
        }
        n
    }
}

/// The ahead form (2.16) (module docs, "Ahead form (2.16) and plans").
impl Ahead for Rcac {
    /// `u_{k+1} = sat(Φ_{k+1} θ_{k+1})` as prepared by the last [`Ahead::advance`] (the
    /// start-up input `sat(0)` after a reset or a new data stream).
    fn ready(&self, u: &mut [f64]) -> u32 {
        for (d, s) in u.iter_mut().zip(&self.ready_u) {
            *d = *s;
        }
        self.ready_status
    }

    /// Takes sample `k` in as [`Controller::step`] does (the update only when `adapt`),
    /// stores `applied` as `u_k` (non-finite entries keep the previous input) and `y_k`,
    /// and prepares `u_{k+1} = sat(Φ_{k+1} θ_{k+1})`.
    fn advance(&mut self, input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u32 {
        let (ok, status) = self.take_in(input, adapt);
        for (d, s) in self.u_last.iter_mut().zip(applied) {
            if s.is_finite() {
                *d = *s;
            }
        }
        self.store(input.y);
        self.ready_status = status | self.prepare_ready(ok);
        self.ready_status
    }

    /// (2.15) run on from `φ_{k+1}` with `θ_{k+1}` held and `y_{k+1}, y_{k+2}, …`
    /// predicted at 0: row `j` is `sat(Θ φ̂_{k+2+j})`, `φ̂` shifting in the previous
    /// (predicted) input and a zero measurement; `0` (saturated) while the counter would
    /// be below `k_w`. `O(H l_θ)`.
    fn plan(&mut self, out: &mut [f64]) -> usize {
        let (lu, ly, nphi) = (self.lu, self.ly, self.nphi);
        if lu == 0 {
            return 0;
        }
        // The u window, newest block first: [û_{k+1+H}, …, û_{k+2}, u_{k+1}, u_k, …,
        // u_{k+2−n_c}], the ready input at block MAX_PLAN_ROWS; row j's `u` part is the
        // n_c blocks from block MAX_PLAN_ROWS − j on, and row j is written just before it.
        let (pu, py) = self.filter.regressor(0);
        let nu = pu.len();
        let ready_at = MAX_PLAN_ROWS * lu;
        self.plan_u[ready_at..ready_at + lu].copy_from_slice(&self.ready_u);
        for (d, s) in self.plan_u[ready_at + lu..].iter_mut().zip(pu) {
            *d = *s;
        }
        // The `y` window: MAX_PLAN_ROWS + 1 zeros (never written) before y_k, y_{k−1}, ….
        for (d, s) in self.plan_y[(MAX_PLAN_ROWS + 1) * ly..].iter_mut().zip(py) {
            *d = *s;
        }
        let theta = law_theta(&self.law);
        let mut sample = self.k.saturating_add(1);
        let mut rows = 0;
        for (j, row) in out.chunks_exact_mut(lu).take(MAX_PLAN_ROWS).enumerate() {
            let at = ready_at - j * lu;
            if sample < self.kw {
                row.fill(0.0);
            } else {
                // The `y` part of φ̂_{k+2+j}: j + 1 predicted zeros, then y_k, y_{k−1}, ….
                let wu = self.plan_u.get(at..at + nu).unwrap_or(&[]);
                let y_at = (MAX_PLAN_ROWS - j) * ly;
                let wy = self.plan_y.get(y_at..y_at + py.len()).unwrap_or(&[]);
                controller_output(theta, wu, wy, nphi, lu, row);
            }
            let _ = limit_output(self.limits.as_ref(), row);
            if let Some(dst) = self.plan_u.get_mut(at - lu..at) {
                dst.copy_from_slice(row);
            }
            sample = sample.saturating_add(1);
            rows += 1;
        }
        rows
    }

    fn plan_source(&self) -> &'static str {
        "u_{k+1} exact (2.16); beyond it (2.15) run on with θ_{k+1} held and the \
         measurements predicted at 0"
    }
}
