//! [`Pcac`]: the PCAC controller of the service, joining the identification and
//! realization of [`super::model`] with the condensed receding-horizon QP of
//! [`crate::mpc`].
//!
//! # One step (sample `k`)
//!
//! 1. **Data.** `u_{k−1}`, the input held over the period that ends at sample `k`, is the
//!    plant's report ([`StepInput::u_applied`]) when there is one, else the input this
//!    controller last gave. Samples lost before `k` ([`StepInput::lost`]) are bridged with
//!    the held `y` and `u` (at most `n̂` entries: older ones leave the regressor anyway) and
//!    identification is suspended until the bridged entries have left `ψ` (`n̂` samples),
//!    so that invented data never enter `θ`. A closed-loop step counts whether it
//!    identified or why not (a bridged gap, a bad sample, a restart of the histories:
//!    [`Controller::adaptation`]).
//! 2. **Identification** (2.24)–(2.35): [`IoModel::update`]`(y_k, u_{k−1})` gives `θ_{k+1}`
//!    with the configured forgetting rule (the F-test (2.33)–(2.35) in chapter 6).
//! 3. **Realization and prediction** (2.36)–(2.46): `x̂_k` (2.38)–(2.39), the Markov
//!    parameters `Ĥ_i` and the free response, from the companion structure.
//! 4. **MPC** (2.47)–(2.51): when [`PcacParams::fast_path`] chooses it, first the
//!    unconstrained fast path ([`crate::mpc::fast_path`]): the Riccati minimizer of (2.48)
//!    and, if it meets every constraint, that is the QP's solution (status solved, no
//!    iteration, an empty active set; when re-planning every `N`, in the condensing
//!    unit's period, on the realization the prediction kept). Otherwise, or without it,
//!    [`Condenser::build`] and [`DenseQpSolver::solve`], warm-started
//!    from the previous step's active set shifted by one step
//!    ([`Condenser::shift_active_set`]). The first move is the input. Samples taken in
//!    without a solve since then (caught up: [`Controller::observe`], or
//!    [`Ahead::advance`] without adaptation; lost and bridged) shift that guess one more
//!    step each ([`Condenser::shift_active_set_by`]), so that the first step after the
//!    loop fell behind starts from where the last solution left off rather than cold.
//! 5. **Fallback.** When the QP is infeasible (e.g. output constraints the predicted
//!    `y_{1|k}` already violates), hits its iteration cap, meets a numerical error, or the
//!    build refuses non-finite predictions, the input is [`Condenser::fallback_input`]: the
//!    current input held within the input and move bounds. The step returns
//!    [`status::FALLBACK`], the reason is counted ([`Controller::counters`]), and
//!    the next step starts cold. Nothing in the step panics, blocks or allocates.
//!
//! # Timing ([`PcacTiming`])
//!
//! The dissertation (§2.3.2.2) computes at step `k` the input of the *next* step:
//! `x_{1|k} = Â_k x̂_k + B̂_k u_k` (2.36) with `u_k` already decided, and `u_{1|k}` applied at
//! `k + 1`, a full sample of computation delay ([`PcacTiming::NextStep`]). In this service
//! the answer to sample `k` is applied over `[kT, (k+1)T)` within the same period, so the
//! default [`PcacTiming::SameStep`] chooses `u_k` itself: the same problem (2.43)–(2.51)
//! with `x_{1|k}` replaced by `x̂_k` and the move reference `u_k` of (2.47) by `u_{k−1}`,
//! i.e. `U = [u_k; …; u_{k+ℓ−1}]` and `Y = [y_k; ŷ_{k+1}; …; ŷ_{k+ℓ−1}]` (`y_k` is measured,
//! so its term is a constant). Both use `ℓ` inputs and `ℓ − 1` outputs they influence,
//! and the same QP size.
//!
//! # Ahead form
//!
//! In [`PcacTiming::NextStep`] the input for sample `k + 1` is `u_{1|k}`, decided at `k`
//! (§2.3.2.2), so it is ready before sample `k + 1` arrives, and [`Controller::ahead`] is
//! `Some` ([`PcacParams::answers_ahead`]; `None` for [`PcacTiming::SameStep`], whose
//! `u_k` needs `y_k`). The [`Ahead`] form runs, for sample `k`:
//!
//! - [`Ahead::ready`] gives `u_{1|k−1}` (the input the last MPC step decided for `k`),
//!   with that step's status bits; after a reset or a new data stream the start-up input
//!   (0 clipped into the bounds).
//! - [`Ahead::advance`]`(k, applied, adapt)` takes `y_k` in exactly as the step does
//!   (steps 1–2: `u_applied` corrects `u_{k−1}`, lost samples bridged, identification),
//!   takes `applied` as `u_k`, the input the plant applies for sample `k`, and, when
//!   `adapt`, runs steps 3–5 with `u_k` in (2.36) and as the move reference of (2.47),
//!   exactly as `step` does in [`PcacTiming::NextStep`]: so `ready; advance` with
//!   `applied` = the ready input gives the inputs of `step`, bit for bit. Without
//!   `adapt` it is [`Controller::observe`]: identification only, and the ready input is
//!   `applied` held.
//! - [`Ahead::plan`] gives the rest of the solution, `u_{2|k}, …, u_{ℓ|k}` (2.44), the
//!   inputs the MPC expects for the samples after the ready one (clipped exactly into the
//!   input bounds, as the first move is), up to `ℓ − 1` rows: the open-loop optimum of
//!   (2.48) at `k`, what the controller would apply if the identified model's prediction
//!   held exactly and it did not re-plan. After a fallback or a sample taken in
//!   without adaptation there is no solution to give, and the plan is empty.
//!
//! # Re-planning every `N` samples
//!
//! With [`PcacParams::replan_every`] `= N > 1` (next-step timing) the MPC is solved at
//! every `N`-th sample only, its three units of work (prediction, condensing, QP) spread
//! over the periods that follow, and between solves the ready input is the next row of
//! the plan in force, which the plant follows; a solve started at `k` plans from
//! `x_{N|k}`, the state the committed inputs `u_k … u_{k+N−1}` lead to, and its plan
//! takes over at `k + N` ([`super::replan`]). [`Ahead::plan`] gives the rows of the plan in
//! force after the ready one. `N = 1` is the step above.
//!
//! # Commands
//!
//! The tracked outputs `C_t y` (2.48) follow `r_k` held over the horizon
//! (`𝓡 = 1_ℓ ⊗ r_k`; no preview) when the rig has `n_r = p_t` commands, and `0` when it
//! has none (disturbance rejection, as in chapter 6).

use crate::controller::{Dimensions, status};

use super::augmentation::{Augmentation, AugmentedModel, OutputFeedback};
use super::model::{HorizonPrediction, IoModel, IoModelParams};
use super::replan::Replan;
use super::tone_model::{InternalModel, ToneModel, ToneProductModel};
use crate::ParamError;
use crate::ahead::Ahead;
use crate::bocf::{DimError, IdentifiedModel};
use crate::controller::{Adaptation, Controller, MAX_INTERNALS, StepInput};
use crate::internal_model::{ToneAnnihilator, ToneError};
use crate::mpc::condense::{Condenser, MpcSpec, NotchInputCost, Weight};
use crate::mpc::fast_path::{FastPath, FastPathMode};
use crate::mpc::qp::{ConstraintId, DenseQpSolver, QpProgress, QpSettings, QpStatus, WarmStart};

#[cfg(test)]
mod tests;
mod unconstrained;

/// When the input computed at sample `k` is applied (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PcacTiming {
    /// `u_k` is chosen from `y_k` and applied over `[kT, (k+1)T)`.
    #[default]
    SameStep,
    /// The dissertation's timing: `u_{1|k}` is computed at `k` and applied at `k + 1`.
    NextStep,
}

/// Everything a [`Pcac`] controller needs.
#[derive(Debug, Clone, PartialEq)]
pub struct PcacParams {
    /// The identified model: `n̂`, `θ_0`, `P_0`, forgetting; `p` and `m` must equal the
    /// rig's `n_y` and `n_u`.
    pub model: IoModelParams,
    /// The receding-horizon problem: `ℓ`, `C_t`, `Q`, `R`, bounds, output constraints.
    pub mpc: MpcSpec,
    /// When the computed input is applied.
    pub timing: PcacTiming,
    /// The QP solver's limits (the iteration cap bounds the step's work).
    pub qp: QpSettings,
    /// Start each QP from the previous active set shifted by one step (default true).
    pub warm_start: bool,
    /// Whether to try the unconstrained fast path before condensing
    /// ([`crate::mpc::fast_path`]; default [`FastPathMode::Auto`]).
    pub fast_path: FastPathMode,
    /// A fixed output feedback `K̄` that this PCAC augments (chapter 7, (7.53)–(7.57);
    /// [`super::augmentation`]): the plant's input is `K̄ y_k + u_k`, identification
    /// regresses on it, and the MPC plans `u_k` with the closed-loop model. `None`: plain
    /// PCAC, the plant's input is `u_k`.
    pub augmentation: Option<OutputFeedback>,
    /// Re-plan every `N` samples (multi-rate PCAC, [`super::replan`]): the QP is solved at
    /// every `N`-th sample only, its work spread over the `N` periods that follow, and the
    /// plant follows the plan in between. `1` (the default) solves at every sample; `N > 1`
    /// needs [`PcacTiming::NextStep`] and `N ≤ ℓ`.
    pub replan_every: usize,
    /// When re-planning every `N ≥ 4` samples, the QP's share of each period before the
    /// last of a cycle, in active-set changes ([`super::replan`], "The work of one solve"):
    /// the solve starts in the third period (without factoring), factors `H` one panel per
    /// period after it, then makes at most this many changes per period, and ends in the
    /// last one (at `N = 4` all of it falls to the last period). `0` (the default) solves
    /// the whole QP in the third period.
    pub qp_changes_per_period: usize,
    /// When re-planning, build the QP's Hessian `H` (from the identified model's Markov
    /// parameters, (2.43)–(2.48)) and factor it in every `M`-th cycle only; the cycles in
    /// between keep both and condense only the gradient and right-hand sides from their
    /// own free response ([`super::replan`], "Keeping the Hessian"). `1` (the default)
    /// builds at every solve. `M > 1` needs [`PcacTiming::NextStep`] and
    /// [`FastPathMode::Never`].
    pub hessian_every: usize,
    /// The length `N_H` of a cycle that builds the Hessian when
    /// [`PcacParams::hessian_every`] `> 1` (room for the build and the factorization's
    /// panels), `N ≤ N_H ≤ ℓ`; `0` (the default) means `N`.
    pub hessian_cycle: usize,
    /// The internal model of known tones ([`super::tone_model`], an extension beyond the
    /// dissertation): identification on `D(q)`-filtered data, prediction with the product
    /// model, and the tone-notch and level input cost (2.47')–(2.48') added to (2.48)
    /// (whose `R` may then be 0). Not with [`PcacParams::augmentation`], and not with
    /// [`FastPathMode::Always`]. `None`: the dissertation's PCAC.
    pub internal_model: Option<InternalModel>,
}

/// Why a step fell back, and how often (see [`Pcac::counts_of`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PcacCounters {
    /// MPC solves started (one per sample, or one per `N` samples when re-planning every
    /// `N`: [`PcacParams::replan_every`]; observations start none).
    pub steps: u64,
    /// QPs solved.
    pub solved: u64,
    /// Of those, solved by the unconstrained fast path (no condensing, no QP solve).
    pub fast_path: u64,
    /// QPs proven infeasible.
    pub infeasible: u64,
    /// QPs stopped by the iteration cap.
    pub max_iterations: u64,
    /// QPs that met a numerical error (non-finite data, `H` not positive definite).
    pub numerical_error: u64,
    /// Problems not built (non-finite predictions) or of the wrong size.
    pub refused: u64,
    /// Steps whose input is the fallback (the sum of the four above).
    pub fallbacks: u64,
    /// Identification resets by the RLS guard (non-finite data, trace limit).
    pub id_resets: u64,
    /// QP Hessians built from the Markov parameters (one per solve unless
    /// [`PcacParams::hessian_every`] `> 1`).
    pub hessians_built: u64,
    /// QP solves that started from the kept factorization of an unchanged Hessian.
    pub factorizations_kept: u64,
    /// Samples bridged after losses.
    pub bridged: u64,
    /// Samples taken in without an answer ([`Controller::observe`]).
    pub observed: u64,
}

/// Index of [`SUSPENSION_CAUSES`]: the sample was identified from.
const IDENTIFIED: usize = 0;
/// Index of [`SUSPENSION_CAUSES`]: bridged lost samples are in `ψ`.
const GAP: usize = 1;
/// Index of [`SUSPENSION_CAUSES`]: a held, non-finite sample is in `ψ`.
const BAD_SAMPLE: usize = 2;
/// Index of [`SUSPENSION_CAUSES`]: the histories restarted at a new phase.
const RESTART: usize = 3;

/// What a closed-loop step did with its identification, as the report names it
/// ([`Adaptation`]), indexed by [`IDENTIFIED`], [`GAP`], [`BAD_SAMPLE`], [`RESTART`].
/// Index of the steps the operator froze ([`Controller::set_adaptation`]); not a
/// suspension.
const FROZEN: usize = 4;
const SUSPENSION_CAUSES: [&str; 4] = [
    "identified",
    Adaptation::BRIDGED_GAP,
    Adaptation::BAD_SAMPLE,
    "a restart of its histories (a new phase)",
];

/// Step 3's prediction with `model`: from `x̂_k` when nothing is `committed` (same-step
/// timing), else from the state the committed inputs lead to.
fn predict_with<M: IdentifiedModel + ?Sized>(
    pred: &mut HorizonPrediction,
    model: &M,
    committed: &[f64],
) -> Result<(), DimError> {
    if committed.is_empty() {
        pred.compute_from_state(model)
    } else {
        pred.compute_committed(model, committed)
    }
}

/// The last QP's outcome as a number for the signal log (`qp_status`).
fn status_code(s: Option<QpStatus>) -> f64 {
    match s {
        None => -1.0,
        Some(QpStatus::Solved) => 0.0,
        Some(QpStatus::MaxIterations) => 1.0,
        Some(QpStatus::Infeasible) => 2.0,
        Some(QpStatus::NumericalError) => 3.0,
        Some(QpStatus::InvalidDimensions) => 4.0,
    }
}

/// Predictive cost adaptive control (dissertation §2.3.2, chapters 6–7) as a [`Controller`].
///
/// Reads `y` (`p = n_y` outputs, all identified) and, when present, `r` (`n_r = p_t`
/// commands for the tracked outputs); writes `u` (`m = n_u`). `z` is not used.
pub struct Pcac {
    counts: Dimensions,
    timing: PcacTiming,
    warm_start: bool,
    /// [`PcacParams::qp_changes_per_period`].
    qp_changes_per_period: usize,
    model: IoModel,
    /// The closed-loop coefficients and the `u` history when augmenting a fixed `K̄`.
    aug: Option<Augmentation>,
    /// The internal model of known tones, when configured.
    tones: Option<ToneModel>,
    pred: HorizonPrediction,
    cond: Condenser,
    solver: DenseQpSolver,
    /// The unconstrained fast path, when [`PcacParams::fast_path`] chooses it.
    fast: Option<FastPath>,
    /// The running solve's prediction kept its realization for the fast path.
    fast_model: bool,
    /// The running solve's build unit found the fast path's `U*` to be the solution.
    fast_found: bool,
    /// The last MPC step's solution is the fast path's `U*` (not the solver's).
    fast_used: bool,
    /// `u_{k−1}` as this controller believes it (the input over the last period).
    u_last: Vec<f64>,
    /// Next-step timing: the input decided for the coming period (`u_{1|k−1}`).
    u_next: Vec<f64>,
    /// Scratch: the move reference and the fallback.
    u_ref: Vec<f64>,
    u_tmp: Vec<f64>,
    /// The held measurement for bridging and non-finite samples.
    y_work: Vec<f64>,
    reference: Vec<f64>,
    active: Vec<ConstraintId>,
    shifted: Vec<ConstraintId>,
    n_shifted: usize,
    /// Identification suspended for this many more samples (bridged data in `ψ`).
    suspend: usize,
    /// Why it is suspended: [`GAP`], [`BAD_SAMPLE`] or [`RESTART`].
    suspend_cause: usize,
    /// Closed-loop steps (a step, or an advance with adaptation): identified (index 0),
    /// suspended per cause of [`SUSPENSION_CAUSES`], and frozen (index [`FROZEN`]).
    adapted: [u64; 5],
    /// The operator froze the identification ([`Controller::set_adaptation`]).
    frozen: bool,
    last_status: Option<QpStatus>,
    last_iterations: usize,
    last_active: usize,
    counters: PcacCounters,
    /// `C_t y_{1|k}`'s first tracked entry for the log (the prediction of the next output).
    tracked_prediction: f64,
    /// [`PcacParams::answers_ahead`], computed once at construction.
    ahead: bool,
    /// The status bits of the MPC step that produced `u_next` (the ahead form's ready
    /// input).
    ready_status: u32,
    /// Next-step timing: the plan in force and the schedule of the solves
    /// ([`super::replan`]; every sample when not re-planning at a lower rate).
    replan: Replan,
    /// The running solve's prediction succeeded.
    predicted: bool,
    /// The running solve's QP was built.
    built: bool,
    /// The condenser holds a Hessian built from the current model's Markov parameters,
    /// which a cycle that keeps it may use ([`PcacParams::hessian_every`]).
    hessian_ready: bool,
    /// A solve's QP unit has begun and its result is not taken yet.
    qp_open: bool,
    /// The split QP solve's progress (`None`: nothing to run, the fast path's solution
    /// or a refused build).
    qp_progress: Option<QpProgress>,
}

impl PcacParams {
    /// Whether the controller answers ahead ([`Controller::ahead`] is `Some`, module docs
    /// "Ahead form"): for [`PcacTiming::NextStep`], the dissertation's timing, where
    /// `u_{1|k}` is computed at `k` and applied at `k + 1`; not for
    /// [`PcacTiming::SameStep`], whose `u_k` needs `y_k`. The service's configuration
    /// check calls this to decide whether the loop may answer first or send ahead.
    pub fn answers_ahead(&self) -> bool {
        self.timing == PcacTiming::NextStep
    }

    /// The default trace limit is this many times `tr P_0 = n̂ p (p+m) p0`.
    pub const TRACE_LIMIT_FACTOR: f64 = 1e6;
    /// `Q` on every tracked output when a configuration gives none.
    pub const DEFAULT_Q: f64 = 1.0;
    /// `R` on every input when a configuration gives none.
    pub const DEFAULT_R: f64 = 1.0;
    /// Warm starts when a configuration does not say.
    pub const DEFAULT_WARM_START: bool = true;
    /// Re-planning period `N` when a configuration does not say: a solve at every sample.
    pub const DEFAULT_REPLAN_EVERY: usize = 1;
    /// Cycles per Hessian build `M` when a configuration does not say: every cycle builds.
    pub const DEFAULT_HESSIAN_EVERY: usize = 1;

    /// `n̂ p (p+m)`, the number of identified coefficients.
    pub fn theta_len(n_hat: usize, p: usize, m: usize) -> usize {
        n_hat * p * (p + m)
    }

    /// The trace limit when a configuration gives none: `10⁶ n̂ p (p+m) p0`.
    pub fn default_trace_limit(n_hat: usize, p: usize, m: usize, p0: f64) -> f64 {
        Self::TRACE_LIMIT_FACTOR * (Self::theta_len(n_hat, p, m) as f64 * p0)
    }

    /// Checks the parameters for a rig with `counts` without building anything;
    /// [`Pcac::new`] calls it.
    ///
    /// # Errors
    ///
    /// The first refused field, named as PCAC's configuration table names it: `"n-hat"`,
    /// `"theta0"`, `"p0"`, `"trace-limit"`, the [`ForgettingRule::validate`] fields
    /// (`"forgetting.tau-d"`, …), `"horizon"` (`ℓ < 2`), `"tracking"` (a `C_t` of the
    /// wrong size or non-finite, or `n_r` neither 0 nor `p_t`), `"q"` (not finite and
    /// `≥ 0`), `"r"` (not finite and `> 0`), `"u-min"` (`u_min ≤ u_max` violated),
    /// `"du-min"`, `"du-max"` (holding the input not allowed), `"output-constraints.c"`,
    /// `"output-constraints.d"`, `"qp-max-iterations"` (0), `"replan-every"` (0, above
    /// `ℓ`, or above 1 without next-step timing), `"qp-changes-per-period"` (above 0 with
    /// `N < 4`), `"hessian-every"` (0, or above 1 without next-step timing or with a fast
    /// path), `"hessian-cycle"` (below `N` or above `ℓ`, or other than `N` with
    /// `hessian-every = 1`), `"augmentation"` (a `K̄` that
    /// is not `m × p` or not finite); and the empty field when the model's or the MPC
    /// problem's `p`, `m` do not match the rig's `n_y`, `n_u`.
    ///
    /// [`ForgettingRule::validate`]: crate::forgetting::ForgettingRule::validate
    pub fn validate(&self, counts: Dimensions) -> Result<(), ParamError> {
        let (n_y, n_r, n_u) = (counts.n_y, counts.n_r, counts.n_u);
        let mp = &self.model;
        let (p, m) = (mp.p, mp.m);
        if p != n_y || m != n_u || p == 0 || m == 0 {
            return Err(ParamError::new(
                "",
                format!(
                    "pcac: the model has p = {p} outputs and m = {m} inputs, the rig has {n_y} \
                     measurements y and {n_u} inputs u"
                ),
            ));
        }
        let spec = &self.mpc;
        if spec.n_outputs != p || spec.n_inputs != m {
            return Err(ParamError::new(
                "",
                format!(
                    "pcac: the MPC problem has {} outputs and {} inputs, the model {p} and {m}",
                    spec.n_outputs, spec.n_inputs
                ),
            ));
        }
        self.validate_model()?;
        let pt = spec.n_tracked;
        if spec.horizon < 2 {
            return Err(ParamError::new(
                "horizon",
                format!(
                    "{}: the horizon ℓ must be at least 2 (y_{{1|k}} is already decided)",
                    spec.horizon
                ),
            ));
        }
        if pt == 0 || spec.tracking.len() != pt * p {
            return Err(ParamError::new(
                "tracking",
                format!(
                    "has {} values, expected p_t × {p} with p_t = {pt} ≥ 1 tracked outputs",
                    spec.tracking.len()
                ),
            ));
        }
        if spec.tracking.iter().any(|x| !x.is_finite()) {
            return Err(ParamError::new("tracking", "entries must be finite"));
        }
        if n_r != 0 && n_r != pt {
            return Err(ParamError::new(
                "tracking",
                format!(
                    "has {pt} tracked outputs but the rig has {n_r} commands r (need 0 or {pt}: \
                     regulate C_t y to 0, or one command per tracked output)"
                ),
            ));
        }
        check_weight(&spec.q, "q", pt, spec.horizon, false)?;
        check_weight(&spec.r, "r", m, spec.horizon, self.internal_model.is_none())?;
        self.validate_internal_model()?;
        if spec.u_min.len() != m || spec.u_max.len() != m {
            return Err(ParamError::new(
                "u-min",
                format!("u-min and u-max need {m} values"),
            ));
        }
        for j in 0..m {
            let (lo, hi) = (spec.u_min[j], spec.u_max[j]);
            if lo.is_nan()
                || hi.is_nan()
                || lo > hi
                || lo == f64::INFINITY
                || hi == f64::NEG_INFINITY
            {
                return Err(ParamError::new(
                    "u-min",
                    format!("input {j}: need u-min ≤ u-max, got [{lo}, {hi}]"),
                ));
            }
        }
        if let Some(mb) = &spec.move_bounds {
            if mb.min.len() != m || mb.max.len() != m {
                return Err(ParamError::new(
                    "du-min",
                    format!("du-min and du-max need {m} values"),
                ));
            }
            for j in 0..m {
                if mb.min[j].is_nan() || mb.min[j] > 0.0 {
                    return Err(ParamError::new(
                        "du-min",
                        format!(
                            "input {j}: {} must be ≤ 0 (holding the input must be allowed)",
                            mb.min[j]
                        ),
                    ));
                }
                if mb.max[j].is_nan() || mb.max[j] < 0.0 {
                    return Err(ParamError::new(
                        "du-max",
                        format!(
                            "input {j}: {} must be ≥ 0 (holding the input must be allowed)",
                            mb.max[j]
                        ),
                    ));
                }
            }
        }
        if let Some(oc) = &spec.output_constraints {
            if oc.d.is_empty() || oc.c.len() != oc.d.len() * p {
                return Err(ParamError::new(
                    "output-constraints.d",
                    format!(
                        "has {} values, expected one per row of C_c ({} entries, {p} per row)",
                        oc.d.len(),
                        oc.c.len()
                    ),
                ));
            }
            if oc.c.iter().any(|x| !x.is_finite()) {
                return Err(ParamError::new("output-constraints.c", "must be finite"));
            }
            if oc.d.iter().any(|x| !x.is_finite()) {
                return Err(ParamError::new("output-constraints.d", "must be finite"));
            }
        }
        if self.qp.max_iterations == 0 {
            return Err(ParamError::new("qp-max-iterations", "must be at least 1"));
        }
        self.validate_replan()?;
        if let Some(fb) = &self.augmentation {
            if fb.gain.len() != m * p {
                return Err(ParamError::new(
                    "augmentation",
                    format!(
                        "the output feedback K̄ has {} entries, expected m × p = {m} × {p}",
                        fb.gain.len()
                    ),
                ));
            }
            if fb.gain.iter().any(|x| !x.is_finite()) {
                return Err(ParamError::new("augmentation", "K̄ must be finite"));
            }
        }
        Ok(())
    }

    /// The internal-model part of [`PcacParams::validate`].
    fn validate_internal_model(&self) -> Result<(), ParamError> {
        let Some(im) = &self.internal_model else {
            return Ok(());
        };
        let m = self.model.m;
        if self.augmentation.is_some() {
            return Err(ParamError::new(
                "internal-model",
                "cannot be combined with an augmented output feedback",
            ));
        }
        if self.fast_path == FastPathMode::Always {
            return Err(ParamError::new(
                "fast-path",
                "\"always\" cannot be used with the internal model: the Riccati fast path \
                 does not know its tone-notch input cost (2.48'); use \"auto\" (which then \
                 never takes it) or \"never\"",
            ));
        }
        if let Err(e) = ToneAnnihilator::new(&im.omegas, im.notch_radius) {
            let field = match e {
                ToneError::Radius(_) => "internal-model.notch-radius",
                ToneError::Tones(_) => "internal-model.tones-hz",
            };
            return Err(ParamError::new(field, e.to_string()));
        }
        for (field, w, positive) in [
            ("internal-model.r-notch", &im.r_notch, true),
            ("internal-model.r-level", &im.r_level, false),
        ] {
            if w.len() != m {
                return Err(ParamError::new(
                    field,
                    format!("has {} values, expected one per input ({m})", w.len()),
                ));
            }
            if w.iter()
                .any(|x| !x.is_finite() || *x < 0.0 || (positive && *x == 0.0))
            {
                let need = if positive { "> 0" } else { "≥ 0" };
                return Err(ParamError::new(
                    field,
                    format!("weights must be finite and {need}"),
                ));
            }
        }
        Ok(())
    }

    /// The MPC problem with the internal model's input cost (2.47')–(2.48') when there is
    /// one. Allocates.
    fn mpc_spec(&self) -> Result<MpcSpec, String> {
        let mut spec = self.mpc.clone();
        if let Some(im) = &self.internal_model {
            let ann =
                ToneAnnihilator::new(&im.omegas, im.notch_radius).map_err(|e| e.to_string())?;
            spec.input_notch = Some(NotchInputCost {
                impulse_response: ann.notch_impulse_response(spec.horizon),
                r_notch: im.r_notch.clone(),
                r_level: im.r_level.clone(),
            });
        }
        Ok(spec)
    }

    /// `N_H`: the length of a cycle that builds the Hessian ([`PcacParams::hessian_cycle`],
    /// `N` when 0).
    pub fn hessian_cycle_len(&self) -> usize {
        if self.hessian_cycle == 0 {
            self.replan_every
        } else {
            self.hessian_cycle
        }
    }

    /// The re-planning part of [`PcacParams::validate`].
    fn validate_replan(&self) -> Result<(), ParamError> {
        let (n, ell) = (self.replan_every, self.mpc.horizon);
        if n == 0 {
            return Err(ParamError::new("replan-every", "must be at least 1"));
        }
        self.validate_hessian_every()?;
        if n > 1 && self.timing != PcacTiming::NextStep {
            return Err(ParamError::new(
                "replan-every",
                format!(
                    "{n}: re-planning every N > 1 samples needs timing = \"next-step\" (the \
                     plan's inputs are sent ahead; same-step timing solves for the input of \
                     the sample at hand)"
                ),
            ));
        }
        if self.qp_changes_per_period > 0 && n < 4 {
            return Err(ParamError::new(
                "qp-changes-per-period",
                format!(
                    "{}: the QP goes on over later periods only when re-planning every N ≥ 4 \
                     samples (replan-every is {n}: the solve has one period); leave it out \
                     or 0",
                    self.qp_changes_per_period
                ),
            ));
        }
        if n > ell {
            return Err(ParamError::new(
                "replan-every",
                format!(
                    "{n} exceeds the horizon ℓ = {ell}: a plan must cover the samples until the \
                     next one takes over"
                ),
            ));
        }
        Ok(())
    }

    /// The [`PcacParams::hessian_every`] part of [`PcacParams::validate_replan`].
    fn validate_hessian_every(&self) -> Result<(), ParamError> {
        let (m_every, len) = (self.hessian_every, self.hessian_cycle_len());
        let (n, ell) = (self.replan_every, self.mpc.horizon);
        if m_every == 0 {
            return Err(ParamError::new("hessian-every", "must be at least 1"));
        }
        if m_every == 1 {
            if self.hessian_cycle != 0 && self.hessian_cycle != n {
                return Err(ParamError::new(
                    "hessian-cycle",
                    format!(
                        "{}: a cycle of its own length for the Hessian's build needs \
                         hessian-every > 1 (every cycle builds it now, in replan-every = {n} \
                         samples); leave it out",
                        self.hessian_cycle
                    ),
                ));
            }
            return Ok(());
        }
        if self.timing != PcacTiming::NextStep {
            return Err(ParamError::new(
                "hessian-every",
                format!(
                    "{m_every}: keeping the Hessian between solves needs timing = \"next-step\" \
                     (the re-planning cycles)"
                ),
            ));
        }
        if self.fast_path != FastPathMode::Never {
            return Err(ParamError::new(
                "hessian-every",
                format!(
                    "{m_every}: the kept Hessian serves the QP, and the unconstrained fast path \
                     has none; set fast-path = \"never\" or leave hessian-every out"
                ),
            ));
        }
        if len < n || len > ell {
            return Err(ParamError::new(
                "hessian-cycle",
                format!(
                    "{len}: the cycle that builds the Hessian must be at least replan-every = \
                     {n} and at most the horizon ℓ = {ell} samples long"
                ),
            ));
        }
        Ok(())
    }

    /// The identification part of [`PcacParams::validate`].
    fn validate_model(&self) -> Result<(), ParamError> {
        let mp = &self.model;
        if mp.n_hat == 0 {
            return Err(ParamError::new("n-hat", "must be at least 1"));
        }
        let ntheta = Self::theta_len(mp.n_hat, mp.p, mp.m);
        if !mp.theta0.is_empty() && mp.theta0.len() != ntheta {
            return Err(ParamError::new(
                "theta0",
                format!(
                    "has {} values, expected n̂·p·(p+m) = {}·{}·{} = {ntheta}",
                    mp.theta0.len(),
                    mp.n_hat,
                    mp.p,
                    mp.p + mp.m
                ),
            ));
        }
        if mp.theta0.iter().any(|x| !x.is_finite()) {
            return Err(ParamError::new("theta0", "must be finite"));
        }
        if !(mp.p0 > 0.0 && mp.p0.is_finite()) {
            return Err(ParamError::new(
                "p0",
                format!("{} must be positive and finite", mp.p0),
            ));
        }
        let trace0 = ntheta as f64 * mp.p0;
        if mp.trace_limit.is_nan() || mp.trace_limit <= trace0 {
            return Err(ParamError::new(
                "trace-limit",
                format!(
                    "{} must exceed tr(P_0) = n̂ p (p+m) p0 = {trace0}",
                    mp.trace_limit
                ),
            ));
        }
        mp.rule.validate(mp.p)
    }
}

/// A weight of the cost: the right number of values, finite, `≥ 0` (`> 0` when
/// `positive`).
fn check_weight(
    w: &Weight,
    field: &'static str,
    channels: usize,
    ell: usize,
    positive: bool,
) -> Result<(), ParamError> {
    let values: &[f64] = match w {
        Weight::Scalar(s) => std::slice::from_ref(s),
        Weight::PerChannel(c) if c.len() == channels => c,
        Weight::PerStep(c) if c.len() == ell * channels => c,
        Weight::PerChannel(c) | Weight::PerStep(c) => {
            return Err(ParamError::new(
                field,
                format!(
                    "has {} values, expected {channels} (one per channel) or {} (per step)",
                    c.len(),
                    ell * channels
                ),
            ));
        }
    };
    if positive && values.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err(ParamError::new(
            field,
            "weights must be finite and > 0 (they make the QP strictly convex)",
        ));
    }
    if values.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
        return Err(ParamError::new(field, "weights must be finite and ≥ 0"));
    }
    Ok(())
}

impl Pcac {
    /// Builds the controller (allocating every workspace) for a rig with `counts`, after
    /// [`PcacParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`PcacParams::validate`].
    pub fn new(params: &PcacParams, counts: Dimensions) -> Result<Self, ParamError> {
        params.validate(counts)?;
        let (n_y, n_u) = (counts.n_y, counts.n_u);
        let mp = &params.model;
        // Validated above: what the pieces still refuse is reported for the whole table.
        let whole = |e: String| ParamError::new("", e);
        let spec = &params.mpc_spec().map_err(whole)?;
        let model = IoModel::new(mp).map_err(whole)?;
        let aug = params
            .augmentation
            .as_ref()
            .map(|fb| Augmentation::new(&model, fb));
        let tones = match &params.internal_model {
            None => None,
            Some(im) => Some(ToneModel::new(&model, im, spec.horizon).map_err(whole)?),
        };
        let pred = match &tones {
            None => HorizonPrediction::new(&model, spec.horizon),
            Some(t) => HorizonPrediction::new(&t.view(), spec.horizon),
        }
        .map_err(whole)?;
        let cond = Condenser::new(spec).map_err(|e| whole(format!("pcac: {e}")))?;
        let mut solver = DenseQpSolver::new(cond.n(), cond.n_ineq(), params.qp);
        solver.keep_factorization(params.hessian_every > 1);
        let fast = FastPath::new(spec, mp.n_hat, params.qp.feasibility_tol, params.fast_path)
            .map_err(|e| whole(format!("pcac: {e}")))?;
        // The fast path without output constraints needs only the prediction's start state;
        // the rest waits until a QP is condensed.
        let mut pred = pred;
        pred.defer_horizon(tones.is_none() && fast.as_ref().is_some_and(|f| !f.reads_prediction()));
        let n_ids = cond.n() + cond.n_ineq();
        let mut c = Self {
            counts,
            timing: params.timing,
            warm_start: params.warm_start,
            qp_changes_per_period: params.qp_changes_per_period,
            model,
            aug,
            tones,
            pred,
            solver,
            fast,
            fast_model: false,
            fast_found: false,
            fast_used: false,
            u_last: vec![0.0; n_u],
            u_next: vec![0.0; n_u],
            u_ref: vec![0.0; n_u],
            u_tmp: vec![0.0; n_u],
            y_work: vec![0.0; n_y],
            reference: vec![0.0; spec.horizon * spec.n_tracked],
            active: vec![ConstraintId::Row(0); n_ids],
            shifted: vec![ConstraintId::Row(0); n_ids],
            n_shifted: 0,
            suspend: 0,
            suspend_cause: GAP,
            adapted: [0; 5],
            frozen: false,
            last_status: None,
            last_iterations: 0,
            last_active: 0,
            counters: PcacCounters::default(),
            tracked_prediction: 0.0,
            ahead: params.answers_ahead(),
            ready_status: status::OK,
            replan: {
                let mut r = Replan::new(params.replan_every, n_u, spec.horizon);
                if params.hessian_every > 1 {
                    r.set_hessian_every(params.hessian_every, params.hessian_cycle_len());
                }
                r
            },
            predicted: false,
            built: false,
            hessian_ready: false,
            qp_open: false,
            qp_progress: None,
            cond,
        };
        c.initial_inputs();
        c.hold_identification_for_the_filter();
        Ok(c)
    }

    /// The starting input: 0 clipped into the input bounds.
    fn initial_inputs(&mut self) {
        self.u_tmp.fill(0.0);
        self.cond.fallback_input(&self.u_tmp, &mut self.u_last);
        self.u_next.copy_from_slice(&self.u_last);
    }

    /// The planned and held inputs back to their initial values and the gap bookkeeping
    /// cleared (a reset or a new data stream).
    fn restart_plan(&mut self) {
        if let Some(aug) = &mut self.aug {
            aug.clear();
            aug.refresh(&self.model);
        }
        if let Some(t) = &mut self.tones {
            t.clear();
            t.refresh(&self.model);
        }
        self.initial_inputs();
        self.n_shifted = 0;
        self.suspend = 0;
        self.hold_identification_for_the_filter();
        self.last_status = None;
        self.tracked_prediction = 0.0;
        self.ready_status = status::OK;
        self.hessian_ready = false;
        self.replan.clear();
    }

    /// With the internal model, the first `n̂ + 2n_t` samples after zero histories only
    /// fill them: `D(q)` applied across the zeros before the data is not the data's.
    fn hold_identification_for_the_filter(&mut self) {
        if let Some(t) = &self.tones {
            self.suspend = t.window();
            self.suspend_cause = RESTART;
        }
    }

    /// The identified model (coefficients `θ_{k+1}`, covariance, prior error). With an
    /// augmented `K̄` these are the plant's coefficients `F̂_i`, `Ĝ_i` of (7.42), identified
    /// on its input `τ_f` ([`super::augmentation`]).
    pub fn model(&self) -> &IoModel {
        &self.model
    }

    /// With an augmented `K̄` ([`PcacParams::augmentation`]), the closed-loop model the MPC
    /// plans with: the coefficients `F̂_i − Ĝ_i K̄`, `Ĝ_i` and the data `y`, `u`
    /// ((7.53)–(7.57), [`super::augmentation`]); `None` for plain PCAC.
    pub fn closed_loop_model(&self) -> Option<AugmentedModel<'_>> {
        self.aug.as_ref().map(|a| a.view(&self.model))
    }

    /// With the internal model of known tones ([`PcacParams::internal_model`]), the
    /// product model the MPC predicts with ([`super::tone_model`]), as of the last
    /// prediction; `None` without it.
    pub fn tone_product_model(&self) -> Option<ToneProductModel<'_>> {
        self.tones.as_ref().map(ToneModel::view)
    }

    /// The samples a datum stays in the identification's regressor: `n̂`, or `n̂ + 2n_t`
    /// with the internal model (its filter spreads a sample over `2n_t` more).
    fn id_window(&self) -> usize {
        self.tones
            .as_ref()
            .map_or(self.model.n_hat(), ToneModel::window)
    }

    /// The output feedback `K̄` this PCAC augments, if any.
    pub fn augmentation(&self) -> Option<&OutputFeedback> {
        self.aug.as_ref().map(Augmentation::feedback)
    }

    /// Starts a new phase of the same experiment after a gap in the data (the sampling
    /// arm's next contact, chapter 7): the identification's histories, the `u` history and
    /// the plan start again (the held input back to its start-up value), and the first
    /// `n̂` samples only refill the regressor, so that identification never regresses
    /// across the gap; the estimate `θ`, `P` **and the forgetting windows** are kept
    /// ([`IoModel::restart_histories`]), so that the F-test forgets at once when the new
    /// phase's data no longer fit (§7.3.3). Does not allocate.
    pub fn restart_histories(&mut self) {
        self.model.restart_histories();
        self.restart_plan();
        self.suspend = self.id_window();
        self.suspend_cause = RESTART;
    }

    /// The last horizon prediction (state, Markov parameters, free response), completed
    /// first when the step deferred its horizon for the fast path
    /// ([`HorizonPrediction::defer_horizon`]; that costs the rest of the prediction here,
    /// not in the step).
    pub fn prediction(&mut self) -> &HorizonPrediction {
        let _ = self.complete_prediction();
        &self.pred
    }

    /// The counters so far.
    pub fn counts_of(&self) -> PcacCounters {
        self.counters
    }

    /// The last QP's status (`None` before the first MPC step or after a refused build).
    pub fn last_qp_status(&self) -> Option<QpStatus> {
        self.last_status
    }

    /// The condensed QP of the last MPC step that condensed (e.g. to solve it with
    /// `mpc::qp::solve_with_clarabel` (feature `clarabel`) for comparison); after a step
    /// that took the fast path, an older one: [`Pcac::condensed_problem`] condenses the
    /// last step's.
    pub fn last_problem(&self) -> crate::mpc::qp::QpProblem<'_> {
        self.cond.problem()
    }

    /// The last QP's solution `U` (all `ℓ m` planned inputs; the fast path's when the
    /// last MPC step took it).
    pub fn planned_inputs(&self) -> &[f64] {
        self.solution()
    }

    /// Steps 1–2 of the module docs: bring in `y_k` with `u_{k−1}`. Returns [`IDENTIFIED`]
    /// when the sample was identified from, else the cause of the suspension.
    fn take_in(&mut self, input: &StepInput<'_>) -> usize {
        let m = self.u_last.len();
        if let Some(ua) = input.u_applied
            && ua.len() >= m
            && ua[..m].iter().all(|v| v.is_finite())
        {
            self.u_last.copy_from_slice(&ua[..m]);
        }
        let n_hat = self.id_window();
        if input.lost > 0 {
            // Bridge with the held output and input; at most n̂ entries matter.
            self.y_work.copy_from_slice(self.model.last_y());
            let bridge = (input.lost as usize).min(n_hat);
            for _ in 0..bridge {
                self.store_sample(false);
            }
            self.counters.bridged += input.lost;
            self.suspend = n_hat + 1;
            self.suspend_cause = GAP;
            self.age_warm_start(input.lost);
        }
        let p = self.y_work.len();
        let good = input.y.len() >= p && input.y[..p].iter().all(|v| v.is_finite());
        if good {
            self.y_work.copy_from_slice(&input.y[..p]);
        } else {
            // The runtime rejects such samples before the controller; hold the last y and
            // keep it out of θ.
            self.y_work.copy_from_slice(self.model.last_y());
            self.suspend = self.suspend.max(n_hat + 1);
            self.suspend_cause = BAD_SAMPLE;
        }
        if self.suspend > 0 {
            self.suspend -= 1;
            self.store_sample(false);
            return self.suspend_cause;
        }
        if self.frozen {
            self.store_sample(false);
            return FROZEN;
        }
        if self.store_sample(true) {
            self.counters.id_resets += 1;
            // The model starts over: so does the Hessian built from it.
            self.hessian_ready = false;
            self.replan.build_next();
        }
        IDENTIFIED
    }

    /// Stores `y_k = self.y_work` with the input of the period before it, identifying
    /// from the sample when `identify` ([`IoModel::update`], else [`IoModel::observe`]);
    /// returns whether the RLS guard reset the estimate. The input is `u_{k−1}` itself,
    /// or with an augmented `K̄` the plant's input `τ_{f,k−1} = u_{k−1} + K̄ y_{k−1}`
    /// ([`super::augmentation`]), whose `u_{k−1}` joins the closed-loop model's history.
    fn store_sample(&mut self, identify: bool) -> bool {
        if let Some(t) = &mut self.tones {
            // The internal model: the identification sees D(q) y and D(q) u.
            t.take_sample(&self.y_work, &self.u_last);
            let (yf, uf) = t.filtered();
            if !identify {
                let _ = self.model.observe(yf, uf);
                return false;
            }
            // The product coefficients follow at the next prediction (`predict`).
            return matches!(self.model.update(yf, uf), Ok(st) if st.reset);
        }
        let input: &[f64] = match &mut self.aug {
            None => &self.u_last,
            Some(aug) => aug.take_input(self.model.last_y(), &self.u_last),
        };
        if !identify {
            let _ = self.model.observe(&self.y_work, input);
            return false;
        }
        let reset = matches!(self.model.update(&self.y_work, input), Ok(st) if st.reset);
        if let Some(aug) = &mut self.aug {
            aug.refresh(&self.model);
        }
        reset
    }

    /// Moves the next QP's warm start `samples` more steps along the horizon: the samples
    /// since the last solve that were taken in without one (caught up, or lost and
    /// bridged). The guess the last solve left (its active set shifted by one step,
    /// [`Condenser::shift_active_set`]) is then the one of the sample the next MPC step
    /// plans from ([`Condenser::shift_active_set_by`]), rather than a cold start that
    /// adds every active bound and row one dual step at a time (module docs, step 4).
    /// `O(|A|)` whatever `samples`; allocation-free.
    fn age_warm_start(&mut self, samples: u64) {
        let n = self.n_shifted;
        if n == 0 || samples == 0 {
            return;
        }
        let steps = usize::try_from(samples).unwrap_or(usize::MAX);
        self.active[..n].copy_from_slice(&self.shifted[..n]);
        self.n_shifted = self
            .cond
            .shift_active_set_by(&self.active[..n], steps, &mut self.shifted);
    }

    /// Steps 3–5 in one go (a solve at every sample): the input for the period the MPC
    /// plans from, into `self.u_tmp`; returns the status bits. The committed inputs of
    /// next-step timing (`u_k`) must be in [`Replan::commit`] already.
    fn solve_mpc(&mut self, input: &StepInput<'_>) -> u32 {
        self.predicted = self.predict(input);
        self.built = self.predicted && self.build_qp() && self.build_rest();
        self.start_qp(self.built);
        self.qp_slice(true).unwrap_or(status::OK)
    }

    /// Step 3, the first unit of a solve ([`super::replan`]): the move reference (2.47),
    /// the command and the prediction — from `x̂_k` (same step) or from the committed
    /// inputs (next step: `x_{1|k}`, or `x_{N|k}` when re-planning every `N`). Returns
    /// whether the prediction is usable.
    fn predict(&mut self, input: &StepInput<'_>) -> bool {
        self.counters.steps += 1;
        self.qp_open = false;
        self.last_iterations = 0;
        self.last_active = 0;
        // The move reference (2.47): u_{k−1} (same step) or the last committed input.
        match self.timing {
            PcacTiming::SameStep => self.u_ref.copy_from_slice(&self.u_last),
            PcacTiming::NextStep => self.u_ref.copy_from_slice(self.replan.last_committed()),
        }
        let pt = self.cond.n_tracked();
        for (i, r) in self.reference.iter_mut().enumerate() {
            *r = input
                .r
                .get(i % pt)
                .copied()
                .filter(|v| v.is_finite())
                .unwrap_or(0.0);
        }
        let committed = match self.timing {
            PcacTiming::SameStep => &[][..],
            PcacTiming::NextStep => self.replan.committed(),
        };
        let predicted = match (&self.aug, &mut self.tones) {
            (Some(aug), _) => predict_with(&mut self.pred, &aug.view(&self.model), committed),
            (None, Some(t)) => {
                t.refresh(&self.model);
                t.fill_v_free(committed);
                predict_with(&mut self.pred, &t.view(), committed)
            }
            (None, None) => predict_with(&mut self.pred, &self.model, committed),
        };
        self.fast_found = false;
        self.fast_model = predicted.is_ok() && self.keep_fast_model();
        // Without the fast path's realization, the QP needs the whole prediction now.
        predicted.is_ok() && (self.fast_model || self.complete_prediction_now())
    }

    /// Step 4's condensing, first half (the second unit of a solve): first the
    /// unconstrained fast path when [`PcacParams::fast_path`] chooses it, whose `U*`, when
    /// it meets every constraint, is the solution (nothing to condense; the solve unit only
    /// takes it); otherwise the QP's Hessian from the Markov parameters
    /// ([`Condenser::build_quadratic`]). Whether the second half may follow.
    fn build_qp(&mut self) -> bool {
        self.fast_found = self.try_fast_path();
        if self.fast_found {
            return true;
        }
        let built =
            self.complete_prediction() && self.cond.build_quadratic(self.pred.markov()).is_ok();
        self.counters.hessians_built += u64::from(built);
        built
    }

    /// Step 4's condensing, second half (at the start of the solve unit): the QP's
    /// gradient and right-hand sides from the free response
    /// ([`Condenser::build_linear`]), unless the fast path found the solution. Whether the
    /// solve unit has a solution or a QP.
    fn build_rest(&mut self) -> bool {
        self.fast_found
            || self
                .cond
                .build_linear(
                    self.pred.free_response(),
                    &self.u_ref,
                    &self.reference,
                    self.tones.as_ref().map_or(&[][..], ToneModel::v_free),
                )
                .is_ok()
    }

    /// Step 5's beginning, the first period of the solve unit: the fast path's solution
    /// when the build found one, else the QP of the last build when `built` (its
    /// factorization, [`DenseQpSolver::start`]), else nothing (the build
    /// was refused).
    fn start_qp(&mut self, built: bool) {
        self.qp_open = true;
        self.fast_used = built && self.fast_found;
        self.qp_progress = if self.fast_used || !built {
            None
        } else {
            let warm = if self.warm_start && self.n_shifted > 0 {
                WarmStart::ActiveSet(&self.shifted[..self.n_shifted])
            } else {
                WarmStart::Cold
            };
            Some(self.solver.start(&self.cond.problem(), warm))
        };
    }

    /// This period's share of the solve unit: at most
    /// [`PcacParams::qp_changes_per_period`] active-set changes, or all that remain when
    /// `last` (the cycle's last period) or when no share is set. When the solve is over
    /// (or had nothing to run), `take_solution` and its status bits.
    fn qp_slice(&mut self, last: bool) -> Option<u32> {
        if !self.qp_open {
            return None;
        }
        if let Some(QpProgress::Running) = self.qp_progress {
            let share = self.qp_changes_per_period;
            let budget = if last || share == 0 {
                usize::MAX
            } else {
                share
            };
            self.qp_progress = Some(self.solver.proceed(&self.cond.problem(), budget));
        }
        match self.qp_progress {
            Some(QpProgress::Running) if !last => None,
            _ => {
                self.qp_open = false;
                Some(self.take_solution())
            }
        }
    }

    /// Step 5's end, once the solve unit is over: the first move of its solution (or the
    /// fallback) into `self.u_tmp`, the next warm start ([`PcacParams::replan_every`]
    /// samples on), and the plan into [`Replan`] (next-step timing). Returns the status
    /// bits.
    fn take_solution(&mut self) -> u32 {
        let status = if self.fast_used {
            self.counters.fast_path += 1;
            Some(QpStatus::Solved)
        } else {
            match self.qp_progress {
                Some(QpProgress::Done(status)) => Some(status),
                // Only after usize::MAX changes in the last period, which the iteration
                // cap prevents.
                Some(QpProgress::Running) => Some(QpStatus::MaxIterations),
                None => None,
            }
        };
        self.last_status = status;
        if !self.fast_used {
            self.last_iterations = self.solver.iterations();
            if self.qp_progress.is_some() && self.solver.factor_reused() {
                self.counters.factorizations_kept += 1;
            }
        }
        self.tracked_prediction = self.tracked_one_step();
        let bits = match status {
            Some(QpStatus::Solved) => {
                self.counters.solved += 1;
                let planned = unconstrained::solution_of(&self.fast, self.fast_used, &self.solver);
                let first = self.cond.first_move(planned);
                if first.iter().all(|v| v.is_finite()) {
                    self.u_tmp.copy_from_slice(first);
                    let na = if self.fast_used {
                        0
                    } else {
                        self.solver.active_set_into(&mut self.active)
                    };
                    self.last_active = na;
                    self.n_shifted = self.cond.shift_active_set_by(
                        &self.active[..na],
                        self.replan.next_len(),
                        &mut self.shifted,
                    );
                    // Within the input bounds up to round-off; clip it exactly.
                    self.cond.clip_to_input_bounds(&mut self.u_tmp);
                    let bits = if self.cond.at_input_bound(&self.u_tmp) {
                        status::SATURATED
                    } else {
                        status::OK
                    };
                    let cond = &self.cond;
                    self.replan
                        .set_pending(planned, bits, |row| cond.clip_to_input_bounds(row));
                    return bits;
                }
                self.counters.numerical_error += 1;
                self.fall_back()
            }
            Some(QpStatus::Infeasible) => {
                self.counters.infeasible += 1;
                self.fall_back()
            }
            Some(QpStatus::MaxIterations) => {
                self.counters.max_iterations += 1;
                self.fall_back()
            }
            Some(QpStatus::NumericalError) => {
                self.counters.numerical_error += 1;
                self.fall_back()
            }
            Some(QpStatus::InvalidDimensions) | None => {
                self.counters.refused += 1;
                self.fall_back()
            }
        };
        self.replan.set_pending_fallback(&self.u_tmp, bits);
        bits
    }

    /// Next-step timing, a closed-loop sample `k` after steps 1–2, with `u_k` in
    /// `self.u_next`: this period's units of the running solve ([`super::replan`]; all
    /// three when solving at every sample), then `u_{k+1}` from the plan in force into
    /// `self.u_next` (`u_k` held when it has none) and `u_k` into `self.u_last`. Returns
    /// the status bits of the solve that made `u_{k+1}`.
    fn plan_ahead(&mut self, input: &StepInput<'_>) -> u32 {
        self.replan.skip(input.lost);
        let units = self.replan.units();
        if units.predict {
            let _ = self.replan.commit(&self.u_next);
            self.predicted = self.predict(input);
            // A cycle that keeps the Hessian condenses only the rest of the QP.
            self.built = units.reuse && self.predicted && self.hessian_ready;
            if units.reuse && !self.hessian_ready {
                self.replan.build_next();
            }
        }
        if units.build {
            self.built = self.predicted && self.build_qp();
            self.hessian_ready = self.built && !self.fast_found;
            if !self.hessian_ready {
                self.replan.build_next();
            }
        }
        if units.solve {
            self.built = self.built && self.build_rest();
            self.start_qp(self.built);
        }
        // With shares, the period that starts the solve goes no further.
        let shared = self.qp_changes_per_period > 0 && !units.take_over;
        if (units.solve && !shared) || units.solve_more {
            let _ = self.qp_slice(units.take_over);
        }
        self.replan.next_sample(units.take_over);
        self.u_last.copy_from_slice(&self.u_next);
        self.ready_status = self
            .replan
            .next_input(&mut self.u_next)
            .unwrap_or(status::OK);
        self.ready_status
    }

    /// The first tracked output of the next sample's prediction with the planned inputs.
    fn tracked_one_step(&self) -> f64 {
        let free = self.pred.free_response();
        let p = self.y_work.len();
        // Same step: block 0 is y_k, block 1 the prediction of y_{k+1}.
        let (off, with_u) = match self.timing {
            PcacTiming::SameStep if free.len() >= 2 * p => (p, true),
            _ => (0, false),
        };
        let mut v = 0.0;
        let ct = self.cond.tracking_row(0);
        for (s, c) in ct.iter().enumerate() {
            let mut y = free.get(off + s).copied().unwrap_or(0.0);
            if with_u {
                let h = self.pred.markov();
                let m = self.u_tmp.len();
                let x = self.solution();
                for j in 0..m {
                    y +=
                        h.get(s * m + j).copied().unwrap_or(0.0) * x.get(j).copied().unwrap_or(0.0);
                }
            }
            v += c * y;
        }
        if v.is_finite() { v } else { 0.0 }
    }

    fn fall_back(&mut self) -> u32 {
        self.counters.fallbacks += 1;
        self.n_shifted = 0;
        self.cond.fallback_input(&self.u_ref, &mut self.u_tmp);
        status::FALLBACK
    }
}

impl Controller for Pcac {
    fn kind(&self) -> &'static str {
        "pcac"
    }

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        let identified = self.take_in(input);
        self.adapted[identified] += 1;
        let status = match self.timing {
            PcacTiming::SameStep => {
                let status = self.solve_mpc(input);
                self.u_last.copy_from_slice(&self.u_tmp);
                status
            }
            // Apply u_k (decided before); u_{k+1} waits for the next sample.
            PcacTiming::NextStep => self.plan_ahead(input),
        };
        for (d, s) in u.iter_mut().zip(self.u_last.iter()) {
            *d = *s;
        }
        status
    }

    /// Identifies from the sample without planning: the plant holds its input, which the
    /// next sample's `u_applied` confirms.
    fn observe(&mut self, input: &StepInput<'_>, _u: &mut [f64]) {
        let _ = self.take_in(input);
        self.counters.observed += 1;
        self.age_warm_start(1);
        self.replan.clear();
        self.u_next.copy_from_slice(&self.u_last);
    }

    fn reset(&mut self) {
        self.model.reset();
        self.restart_plan();
    }

    /// Forgets the identification's histories, its forgetting windows and the planned
    /// inputs; keeps the identified model's `θ` and `P`.
    fn restart_data(&mut self) {
        self.model.restart_data();
        self.restart_plan();
    }

    fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        self.model.learned(visit);
    }

    fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let restored = self.model.restore_learned(saved);
        if let Some(aug) = &mut self.aug {
            aug.refresh(&self.model);
        }
        if let Some(t) = &mut self.tones {
            t.refresh(&self.model);
        }
        restored
    }

    /// `Some` for [`PcacTiming::NextStep`] ([`PcacParams::answers_ahead`]).
    fn ahead(&mut self) -> Option<&mut dyn Ahead> {
        if self.ahead { Some(self) } else { None }
    }

    fn prepare_thread(&mut self) {
        self.solver.prepare_thread();
    }

    /// Closed-loop steps (a step, or an advance with adaptation) whose identification ran,
    /// and those whose identification was suspended, per cause.
    fn adaptation(&self) -> Option<Adaptation> {
        Some(Adaptation {
            updated: self.adapted[IDENTIFIED],
            suspended: SUSPENSION_CAUSES[GAP..]
                .iter()
                .zip(&self.adapted[GAP..])
                .map(|(c, n)| (*c, *n))
                .collect(),
            frozen: self.adapted[FROZEN],
        })
    }

    /// Freezes or resumes the identification; the MPC keeps planning with the model.
    fn set_adaptation(&mut self, on: bool) -> bool {
        self.frozen = !on;
        true
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let c = &self.counters;
        vec![
            (
                "samples per solve (replan-every)",
                self.replan.every() as u64,
            ),
            (
                "solves per hessian (hessian-every)",
                self.replan.hessian_every() as u64,
            ),
            (
                "samples per hessian cycle (hessian-cycle)",
                self.replan.hessian_cycle() as u64,
            ),
            ("hessians built", c.hessians_built),
            ("factorizations kept", c.factorizations_kept),
            ("mpc steps", c.steps),
            ("qp solved", c.solved),
            ("fast path", c.fast_path),
            ("infeasible", c.infeasible),
            ("iteration cap", c.max_iterations),
            ("numerical error", c.numerical_error),
            ("refused", c.refused),
            ("fallbacks", c.fallbacks),
            ("identification resets", c.id_resets),
            ("bridged samples", c.bridged),
            ("observed", c.observed),
        ]
    }

    fn internal_names(&self) -> Vec<String> {
        [
            "theta_norm",
            "trace_p",
            "lambda",
            "id_error",
            "qp_status",
            "qp_iterations",
            "qp_active",
            "y_pred",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    }

    fn internals(&self, out: &mut [f64]) -> usize {
        let theta_norm = self
            .model
            .coefficients()
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt();
        let step = self.model.last_step();
        let vals = [
            theta_norm,
            self.model.trace_p(),
            step.lambda,
            step.error_norm,
            status_code(self.last_status),
            self.last_iterations as f64,
            self.last_active as f64,
            self.tracked_prediction,
        ];
        let n = vals.len().min(out.len()).min(MAX_INTERNALS);
        out[..n].copy_from_slice(&vals[..n]);
        n
    }
}

/// The ahead form of [`PcacTiming::NextStep`] (module docs, "Ahead form"); with
/// [`PcacTiming::SameStep`] [`Controller::ahead`] is `None` and this form is not used.
impl Ahead for Pcac {
    /// `u_{1|k}`, the first move of the last solution (the fallback input after a
    /// fallback, the applied input held after a sample taken in without adaptation, the
    /// start-up input after a reset or a new data stream), with the status of the MPC step
    /// that produced it.
    fn ready(&self, u: &mut [f64]) -> u32 {
        for (d, s) in u.iter_mut().zip(&self.u_next) {
            *d = *s;
        }
        self.ready_status
    }

    /// Steps 1–2 with `y_k` as [`Controller::step`] does, `u_k = applied` (non-finite
    /// entries keep the ready input), then, when `adapt`, steps 3–5 with `u_k` as the move
    /// reference (2.47), exactly as `step` in [`PcacTiming::NextStep`]; without `adapt`
    /// as [`Controller::observe`]: identification only, and `applied` held — unless
    /// `applied` is the plan in force's row for this sample, whose next row is then the
    /// ready input ([`super::replan`]).
    fn advance(&mut self, input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u32 {
        let identified = self.take_in(input);
        if adapt {
            self.adapted[identified] += 1;
        }
        for (d, s) in self.u_next.iter_mut().zip(applied) {
            if s.is_finite() {
                *d = *s;
            }
        }
        if adapt {
            self.plan_ahead(input);
        } else {
            self.counters.observed += 1;
            self.age_warm_start(1);
            self.u_last.copy_from_slice(&self.u_next);
            self.ready_status = status::OK;
            if self.replan.row_applied(&self.u_next) {
                // The plant followed the plan in force: it goes on ([`super::replan`]),
                // and the running cycle is dropped, as over a lost sample.
                self.replan.skip(1);
                if let Some(s) = self.replan.next_input(&mut self.u_next) {
                    self.ready_status = s;
                }
            } else {
                self.replan.clear();
            }
        }
        self.ready_status
    }

    /// The rows of the plan in force after the ready input, each clipped exactly into the
    /// input bounds (2.50) as the first move is, as many as fit: `u_{2|k}, …, u_{ℓ|k}` of
    /// the last solution `U` (2.44) when solving at every sample, the rows still ahead
    /// when re-planning every `N` ([`PcacParams::replan_every`]); none after a fallback
    /// or a sample taken in without adaptation.
    fn plan(&mut self, out: &mut [f64]) -> usize {
        self.replan.rows_after_next(out)
    }

    fn plan_source(&self) -> &'static str {
        if self.replan.every() > 1 {
            "the plan in force of the MPC (2.43)–(2.51) of the identified model, solved every \
             N samples (replan-every) from the state its committed inputs lead to: its rows \
             after the ready input; none after a fallback"
        } else {
            "the MPC solution u_{2|k}, …, u_{ℓ|k} (2.43)–(2.51) of the identified model; \
             none after a fallback"
        }
    }
}
