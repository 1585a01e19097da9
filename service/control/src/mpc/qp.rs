//! # qp: a dense, allocation-free QP solver for PCAC's MPC
//!
//! ## The problem
//!
//! PCAC's receding-horizon problem (2.48)–(2.51) of the dissertation,
//!
//! ```text
//! min_U  (Y_t − 𝓡)ᵀ Q (Y_t − 𝓡) + ΔUᵀ R ΔU                         (2.48)
//! s.t.   C_ℓ Y + D_ℓ ≤ 0                                           (2.49)
//!        U_min ≤ U ≤ U_max                                         (2.50)
//!        ΔU_min ≤ ΔU ≤ ΔU_max                                      (2.51)
//! ```
//!
//! with `Y = Γ x + T U` (2.43), `Y_t = C_{t,ℓ} Y`, the command `𝓡` and the move sizes
//! `ΔU = S U − [u_kᵀ 0 ⋯ 0]ᵀ` of (2.47) relative to the current input `u_k` (`S` the block
//! difference matrix), is, once condensed in the `n = ℓ·m` future inputs `U`, the dense strictly
//! convex quadratic program
//!
//! ```text
//! min_U  ½ Uᵀ H U + fᵀ U
//! s.t.   lb ≤ U ≤ ub          (the input bounds (2.50), entries may be ±∞)
//!        G U ≤ h              (move bounds (2.51): rows of the difference matrix, both
//!                              signs; output constraints (2.49): rows C_ℓ T)
//! ```
//!
//! with `H = 2(C_{t,ℓ} T)ᵀ Q (C_{t,ℓ} T) + 2 Sᵀ R S` symmetric positive definite. Building
//! `H, f, G, h` from the model is the condensing step and lives elsewhere; this module takes
//! the condensed data ([`QpProblem`]).
//!
//! ## The method: a dual active-set method (Goldfarb–Idnani)
//!
//! With Lagrange multipliers `λ ≥ 0` for the inequalities `a_iᵀ U ≤ b_i` (the boxes are
//! the rows `±e_iᵀ`), the KKT conditions are
//! `H U + f + Σ λ_i a_i = 0`, `a_iᵀ U ≤ b_i`, `λ_i ≥ 0`, `λ_i (a_iᵀ U − b_i) = 0`.
//! The dual method starts from the unconstrained minimizer `U = −H⁻¹ f` (dual feasible,
//! empty active set `A`) and keeps dual feasibility throughout: it picks a violated
//! constraint `p`, raises its multiplier `t` while moving `U` so that the active
//! constraints stay satisfied with equality, and stops either when `p` becomes satisfied
//! (full step: `p` joins `A`) or when an active multiplier reaches zero first (partial
//! step: that constraint leaves `A`). With `H = L Lᵀ` (Cholesky), `w = L⁻¹ a_p` and the
//! active normals `W = L⁻¹ N_A = Q R` (thin QR, `Q` orthonormal), the step directions are
//!
//! ```text
//! r = Qᵀ w,    u = R⁻¹ r,    ρ = w − Q r,    z = L⁻ᵀ ρ,
//! U(t) = U − t z,   λ_A(t) = λ_A − t u,   λ_p(t) = λ_p + t,
//! a_pᵀ U(t) − b_p = s_p − t ‖ρ‖²,
//! ```
//!
//! so the full step is `t₁ = s_p / ‖ρ‖²` and the partial step
//! `t₂ = min_{u_j > 0} λ_j / u_j`. If `ρ = 0` (`a_p` depends on the active normals) only a
//! dual step is possible, and if in addition no `u_j > 0` the problem is primal
//! infeasible. The objective increases strictly at every full step, so the method
//! terminates; a configurable iteration cap bounds the work in the real-time step.
//!
//! ## Bounds fixed from the warm start
//!
//! In a saturated horizon most active constraints are input bounds (at the
//! sampling-arm size, up to 76 of 100 variables), and adding them one dual step at a time
//! costs `O(n·|A|)` each. The solver therefore starts with the warm start's bounds *fixed*:
//! the variables `B` sit at their bounds and are eliminated, and the method runs on the
//! free ones `F` with `H_FF = L_F L_Fᵀ` (the formulas above with `L_F`, and the normals
//! restricted to `F`). The fixed bounds' multipliers follow from stationarity on their
//! rows, `λ_i = ∓(H U + f + Σ_A λ_j a_j)_i` for an upper (lower) bound, and take part in
//! the dual step like the active ones: with `z` zero on `B`,
//!
//! ```text
//! λ_B(t) = λ_B − t u_B,   u_i = s_i (−(H z)_i − Σ_A u_j (a_j)_i + (a_p)_i),   s_i = ±1,
//! ```
//!
//! so the partial step is `min(t₂, t₃)` with `t₃ = min_{u_i > 0} λ_i / u_i`. When a fixed
//! bound's multiplier reaches zero first, its variable is freed: `L_F` gains the row
//! `[lᵀ δ]` (`L_F l = H_Fb`, `δ² = H_bb − lᵀl`) and `W = L_F⁻¹ N_A` gains the row
//! `(N_bᵀ − lᵀ W)/δ`, which `|A|` Givens rotations fold into `Q R` (`O(|F|·|A|)`, no
//! refactorization). Fixed bounds are thus active constraints handled in the variables
//! rather than in `Q R`, and the method is the same.
//!
//! The start must be dual feasible. It is the minimizer with `B` fixed and the warm
//! start's rows `R` held with equality, `U_F = U⁰_F − L_F⁻ᵀ Q R⁻ᵀ s` with
//! `s = N_Rᵀ U⁰ − b_R` and `λ_R = R⁻¹ R⁻ᵀ s` (`U⁰` the minimizer without the rows); rows
//! and fixed bounds with a negative multiplier leave (their variables are freed) until
//! none is left. A round that frees `k` variables into `|F|` free ones grows `L_F` a row
//! at a time, or factors `H_FF` anew when that is cheaper (`5k ≥ |F| + k`, see
//! `refactor_pays`). When the warm start fixed no bound and at least [`BULK_FIX`] bounds
//! are violated at that point (the first step of a saturation, which the shifted active
//! set cannot foresee), they are fixed as well — those the objective pushes against, a
//! positive multiplier estimate `∓(H U_clip + f)_i` at the start point clipped to the box —
//! and the start is computed once more: one more factorization instead of one dual step
//! per bound. A warm start that fixes bounds already stands in a saturated horizon; there
//! the dual steps add the few bounds it missed (on the truss, whose ill-conditioned `H`
//! sends the unconstrained minimizer far past the box, fixing the violated bounds in bulk
//! and freeing most of them again cost about twice the solve). A wrong guess costs work,
//! never the result: the final point satisfies the KKT conditions of the whole problem,
//! with every multiplier (fixed bounds' included) nonnegative.
//!
//! Why this method rather than an interior-point method: an interior-point iteration costs
//! a fresh `O(n³)` factorization of `H + Gᵀ D G` (≈ 0.3 Mflop at `n = 100`, about the same
//! as the whole factorization here) and needs 10–20 of them, whereas the dual method
//! factors `H` once and then pays `O(n²)` per active-set change (two triangular solves and
//! a Gram–Schmidt step against the `|A|` active directions). MPC problems have few active
//! constraints compared with `n`, the solution is exact to round-off on the final active
//! set (no barrier residual: the KKT residuals in the tests are ~1e-13), and warm starts
//! are natural:
//! constraints active at the previous step are tried first ([`WarmStart`]).
//!
//! Implementation notes:
//! - `Q` and `R` are kept by classical Gram–Schmidt on addition, with a second pass when
//!   the first cancels more than half of `‖w‖²` (CGS2, "twice is enough"), and by Givens
//!   rotations on deletion (`O(n·|A|)` each), never through a Gram matrix.
//! - Box bounds are not stored as rows: `L⁻¹(±e_i)` is a forward solve that starts at
//!   row `i`, and their violations are read off `U` directly. Fixed bounds are not in
//!   `Q R` at all (see above).
//! - The rows of `G` are copied at the start of each solve into a compressed (sparse-row)
//!   buffer sized at construction, so the two-nonzero move-bound rows cost two flops each
//!   when violations are checked.
//! - The Cholesky factorization is left-looking by column panels, each panel with faer's
//!   kernels (its product, blocked Cholesky and triangular solve) on a buffer and scratch
//!   sized at construction (`nalgebra`'s `cholesky()` allocates): for a panel `J` of
//!   columns, `A[J.., J] −= L[J.., :J] L[J, :J]ᵀ`, `A[J, J] = L_JJ L_JJᵀ`,
//!   `L[below J, J] = A[below J, J] L_JJ⁻ᵀ`. A panel takes at most about 130 000
//!   multiply–adds, so the factorization can be spread over calls (below). The ignored
//!   timing test compares it with faer's blocked factorization in one call and with a
//!   straightforward row-oriented one.
//!
//! ## Real-time use
//!
//! [`DenseQpSolver::new`] allocates every workspace for given `(n, n_ineq)` (and runs
//! faer's one-time kernel initialization); [`DenseQpSolver::solve`] takes only borrowed
//! slices and allocates nothing (every buffer, including the lists of free and fixed
//! variables, is sized at construction; the counting-allocator tests of the PCAC step
//! cover it), and it never panics: the
//! outcome is a [`QpStatus`]. The iteration cap ([`QpSettings::max_iterations`]) bounds
//! its work. `solve_with_clarabel` (crate feature `clarabel`) solves the same problem
//! with clarabel (it allocates; for tests and benchmarks).
//!
//! A solve can also be split over several calls, so that a controller that re-plans
//! every `N` samples spreads it over sample periods: [`DenseQpSolver::start`] does the
//! checks and copies `H_FF`; each [`DenseQpSolver::proceed`] with a budget factors one
//! panel of it while the factorization lasts, and then goes on until the solution is
//! reached or it has made the active-set changes it was given: the start point's rounds
//! (each frees the fixed bounds with negative multipliers, one change each, and
//! re-minimizes), the bulk fix, then the additions of violated constraints. The budget is
//! checked between rounds and between additions. Every iterate in between is dual
//! feasible but not yet primal feasible, so nothing is usable before the end; the split
//! changes when the work is done, not the work: the operations are those of one
//! [`DenseQpSolver::solve`], in the same order, and the result is the same bit for bit.
//!
//! ## Keeping the factorization
//!
//! A controller that rebuilds `H` less often than it solves (PCAC's
//! `hessian-every`, [`crate::pcac::PcacParams::hessian_every`]) asks the solver to keep
//! ([`DenseQpSolver::keep_factorization`]) the factor `L` of each solve that factored the
//! whole `H` (`F` all variables), with a copy of that `H`. A later solve whose `H` equals
//! the copy entry for entry and whose warm start fixes no bound starts from `L` (copied
//! back only when the solve in between wrote over it) and goes straight to the start
//! point: the fixed part of the solve is then the compression of `G` and the comparison
//! of `H`, `O(n²)` reads instead of `n³/6` multiply–adds. Anything else (another `H`, a
//! fixed bound) factors as before, and the result is the same bit for bit either way
//! (the same panels factor the same matrix).
//!
//! Warm start in the receding horizon: take the previous step's active set
//! ([`DenseQpSolver::active_set_into`]), shift it by one step (`Upper(i)` → `Upper(i − m)`
//! and likewise for the move rows, dropping those that fall off the front), and pass it
//! as [`WarmStart::ActiveSet`]; or pass the shifted previous solution as
//! [`WarmStart::Primal`]. The guess's bounds are fixed and its rows start active; a wrong
//! guess costs iterations, never correctness.
//!
//! ## Cost
//!
//! Each solve has a fixed part (the Cholesky factorization of `H_FF`, checking `H` and
//! compressing `G`), then one dual step per active-set change, `O(|F|·|A|)` for the
//! Gram–Schmidt update. Warm-started from the previous active set, the bounds are fixed
//! and the rows held from the start, so neighbouring problems need almost no dual step;
//! bounds violated at the unconstrained minimizer of a cold start are fixed in bulk.
//! `latency-bench pcac` measures the solve at the truss and sampling-arm sizes beside
//! clarabel on the same problems (results: `docs/results/latency-bench.md`), and the
//! ignored test `qp_timing_at_n_100_with_active_constraints` times it by active-set size.

use crate::linalg::{axpy, dot_wide as dot};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{self, LltRegularization};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, Par};

#[cfg(any(test, feature = "clarabel"))]
mod clarabel_reference;
#[cfg(any(test, feature = "clarabel"))]
pub use clarabel_reference::{ClarabelSolution, solve_with_clarabel};
#[cfg(test)]
mod tests;

/// The condensed QP `min ½ Uᵀ H U + fᵀ U  s.t.  lb ≤ U ≤ ub,  G U ≤ h`, borrowed.
///
/// `n = f.len()` variables and `n_ineq = h.len()` general rows. Matrices are dense and
/// row-major.
#[derive(Clone, Copy, Debug)]
pub struct QpProblem<'a> {
    /// The Hessian `H` (`n × n`, row-major, symmetric positive definite; the factorization
    /// reads its upper triangle, the objective value the whole matrix).
    pub hess: &'a [f64],
    /// The linear term `f` (`n`).
    pub f: &'a [f64],
    /// Lower bounds `lb` (`n`); `-∞` for none.
    pub lb: &'a [f64],
    /// Upper bounds `ub` (`n`); `+∞` for none.
    pub ub: &'a [f64],
    /// The inequality matrix `G` (`n_ineq × n`, row-major).
    pub g: &'a [f64],
    /// The right-hand side `h` (`n_ineq`); `+∞` disables a row.
    pub h: &'a [f64],
}

/// The vectors of a [`QpProblem`], owned: what a condenser fills and lends to the solver
/// ([`QpData::problem`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QpData {
    /// `H` (`n × n`, row-major).
    pub hess: Vec<f64>,
    /// `f` (`n`).
    pub f: Vec<f64>,
    /// `lb` (`n`).
    pub lb: Vec<f64>,
    /// `ub` (`n`).
    pub ub: Vec<f64>,
    /// `G` (`n_ineq × n`, row-major).
    pub g: Vec<f64>,
    /// `h` (`n_ineq`).
    pub h: Vec<f64>,
}

impl QpData {
    /// All zero, for `n` variables and `n_ineq` rows of `G U ≤ h`.
    pub fn zeros(n: usize, n_ineq: usize) -> Self {
        Self {
            hess: vec![0.0; n * n],
            f: vec![0.0; n],
            lb: vec![0.0; n],
            ub: vec![0.0; n],
            g: vec![0.0; n_ineq * n],
            h: vec![0.0; n_ineq],
        }
    }

    /// The problem these vectors state.
    pub fn problem(&self) -> QpProblem<'_> {
        QpProblem {
            hess: &self.hess,
            f: &self.f,
            lb: &self.lb,
            ub: &self.ub,
            g: &self.g,
            h: &self.h,
        }
    }
}

/// The outcome of [`DenseQpSolver::solve`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpStatus {
    /// The KKT conditions hold to the tolerances of [`QpSettings`].
    Solved,
    /// The iteration cap was reached; the iterate is finite and within the box bounds but
    /// may violate rows of `G U ≤ h` (and is not optimal).
    MaxIterations,
    /// The constraints admit no solution (contradictory bounds or rows); the iterate is
    /// the last dual iterate clipped into the box (finite when the data are finite).
    Infeasible,
    /// The data are not finite, `H` is not (numerically) positive definite, or a step
    /// produced a non-finite value.
    NumericalError,
    /// The problem's dimensions differ from the ones the solver was built for (`n`,
    /// `n_ineq`), or a slice has the wrong length.
    InvalidDimensions,
}

/// Where a solve split over several calls stands ([`DenseQpSolver::start`],
/// [`DenseQpSolver::proceed`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpProgress {
    /// The solve is over, with this outcome.
    Done(QpStatus),
    /// Violated constraints remain to be added: [`DenseQpSolver::proceed`] goes on.
    Running,
}

/// The stages of a solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// The factorization `H_FF = L_F L_Fᵀ`, done up to column `col` (panel by panel,
    /// [`cholesky_panel`]); `refactored` as in `Start`, for the rounds that follow.
    Factor { col: usize, refactored: bool },
    /// The start point's rounds; `minimized`: the next round need not re-minimize;
    /// `refactored`: the bulk fix has been done.
    Start { minimized: bool, refactored: bool },
    /// The dual iterations.
    Add,
}

/// Tolerances and limits of [`DenseQpSolver`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QpSettings {
    /// Maximum number of active-set changes (additions and deletions) per solve.
    pub max_iterations: usize,
    /// A constraint counts as violated when
    /// `(a_iᵀ U − b_i) / ‖a_i‖ > feasibility_tol · (1 + |b_i| / ‖a_i‖)`.
    pub feasibility_tol: f64,
    /// A new constraint counts as linearly dependent on the active ones when
    /// `‖ρ‖ ≤ dependence_tol · ‖L⁻¹ a_p‖`. A dependent violated constraint whose dual step
    /// cannot drop any active one proves infeasibility; constraints closer to parallel than
    /// this tolerance are therefore treated as parallel.
    pub dependence_tol: f64,
}

/// At most 1000 active-set changes per solve (the service's `qp-max-iterations` when a
/// configuration gives none), feasibility and dependence tolerances `10⁻¹⁰` (relative,
/// near the rounding of the dense factorizations; not configurable in the service).
impl Default for QpSettings {
    fn default() -> Self {
        Self {
            max_iterations: 1000,
            feasibility_tol: 1e-10,
            dependence_tol: 1e-10,
        }
    }
}

/// One constraint of the QP, as reported in the active set and accepted by
/// [`WarmStart::ActiveSet`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConstraintId {
    /// The upper bound `U_i ≤ ub_i`.
    Upper(usize),
    /// The lower bound `U_i ≥ lb_i`.
    Lower(usize),
    /// Row `j` of `G U ≤ h`.
    Row(usize),
}

/// How [`DenseQpSolver::solve`] starts.
#[derive(Clone, Copy, Debug)]
pub enum WarmStart<'a> {
    /// From the unconstrained minimizer (bounds it violates fixed in bulk when there are
    /// at least [`BULK_FIX`]), choosing the most violated constraint each time.
    Cold,
    /// A guess of the active set (e.g. the previous step's, shifted by one horizon step,
    /// `m` variables): its bounds are fixed at the start, its rows held with equality,
    /// those with negative multipliers leave, and its remaining constraints are added
    /// first while they are violated. Invalid ids are ignored.
    ActiveSet(&'a [ConstraintId]),
    /// The constraints active or violated at this point (e.g. the previous solution
    /// shifted by one horizon step), within `1e-7` relative, used as in
    /// [`WarmStart::ActiveSet`]. A slice of the wrong length is ignored.
    Primal(&'a [f64]),
}

/// The dense dual active-set QP solver, with every workspace allocated at construction.
///
/// The bounds of the warm start are fixed at the start and eliminated (the method runs
/// on the free variables); see "Bounds fixed from the warm start" in the module docs.
///
/// Not `Clone` (faer's scratch buffer is not); build one per controller.
///
/// ```
/// use control::mpc::qp::{DenseQpSolver, QpProblem, QpSettings, QpStatus, WarmStart};
/// // min ½(u₁² + u₂²) − u₁ − u₂  s.t.  u ≤ 0.8,  u₁ + u₂ ≤ 1
/// let mut solver = DenseQpSolver::new(2, 1, QpSettings::default());
/// let p = QpProblem {
///     hess: &[1.0, 0.0, 0.0, 1.0],
///     f: &[-1.0, -1.0],
///     lb: &[f64::NEG_INFINITY; 2],
///     ub: &[0.8, 0.8],
///     g: &[1.0, 1.0],
///     h: &[1.0],
/// };
/// assert_eq!(solver.solve(&p, WarmStart::Cold), QpStatus::Solved);
/// assert!((solver.x()[0] - 0.5).abs() < 1e-12 && (solver.x()[1] - 0.5).abs() < 1e-12);
/// assert!((solver.lambda_ineq()[0] - 0.5).abs() < 1e-12);
/// ```
pub struct DenseQpSolver {
    n: usize,
    n_ineq: usize,
    settings: QpSettings,
    /// Cholesky factor `L_F` of `H_FF`: the lower triangle of the leading `|F| × |F|`
    /// block of a column-major `n × n` buffer, rows and columns in the order of `free`.
    l: Vec<f64>,
    /// faer's scratch for the factorization (for every size up to `n`).
    chol_mem: MemBuffer,
    /// The kept factorization ([`DenseQpSolver::keep_factorization`]): `L` of the whole
    /// `h_kept` in the layout of `l` (both empty when not kept).
    l_kept: Vec<f64>,
    h_kept: Vec<f64>,
    /// `l_kept` holds the factor of `h_kept`.
    kept: bool,
    /// `l` holds `l_kept` (nothing has written `l` since).
    l_is_kept: bool,
    /// This solve started from the kept factorization.
    reused: bool,
    /// The iterate `U` (all `n` entries; the fixed variables at their bounds).
    x: Vec<f64>,
    /// Per variable: `FREE`, `AT_UPPER` or `AT_LOWER`.
    fix: Vec<u8>,
    /// The free variables in the order of `L_F`, and each variable's position there
    /// (`NONE` when fixed).
    free: Vec<usize>,
    pos: Vec<usize>,
    /// The fixed variables.
    fixed: Vec<usize>,
    /// Per variable: the fixed bound's multiplier, and its decrease per unit dual step.
    lam_fixed: Vec<f64>,
    u_fixed: Vec<f64>,
    /// Compressed rows of `G`: `row_ptr[j]..row_ptr[j+1]` index `cols`/`vals`.
    row_ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    /// `1 / ‖g_j‖` (zero for a zero row).
    inv_norm: Vec<f64>,
    /// Active constraints (internal ids: `0..n` upper, `n..2n` lower, `2n..` rows),
    /// excluding the fixed bounds until the solve ends.
    active: Vec<usize>,
    lambda_active: Vec<f64>,
    /// Per constraint: `CANDIDATE`, `ACTIVE`, `ABSENT` (infinite bound or zero row) or
    /// `FIXED` (a bound of a fixed variable, either side).
    state: Vec<u8>,
    /// Per constraint: try it first (the warm start).
    want: Vec<bool>,
    /// The warm start's rows held with equality at the starting point.
    start_rows: Vec<usize>,
    /// `Q` (one orthonormal `|F|`-vector per active constraint, rows of stride `n`).
    q: Vec<f64>,
    /// `R` (upper triangular, row-major with stride `n`).
    r: Vec<f64>,
    w: Vec<f64>,
    rho: Vec<f64>,
    z: Vec<f64>,
    rv: Vec<f64>,
    rv2: Vec<f64>,
    uv: Vec<f64>,
    /// Scratch of length `n`: `z` scattered to all variables, a column of `H`, the extra
    /// column of a `Q` update.
    full: Vec<f64>,
    col: Vec<f64>,
    extra: Vec<f64>,
    lam_lower: Vec<f64>,
    lam_upper: Vec<f64>,
    lam_ineq: Vec<f64>,
    objective: f64,
    iterations: usize,
    fixed_at_start: usize,
    freed: usize,
    /// Calls of this solve that ended in a factorization's panel (budgeted calls only).
    panel_stops: usize,
    /// Start-point rounds of this solve that factored `H_FF` anew ([`refactor_pays`]).
    refactors: usize,
    /// A solve begun by `start` awaits `proceed`.
    running: bool,
    /// Where the running solve stands.
    phase: Phase,
    /// The outcome of the last solve that ended.
    last_status: QpStatus,
}

impl core::fmt::Debug for DenseQpSolver {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DenseQpSolver")
            .field("n", &self.n)
            .field("n_ineq", &self.n_ineq)
            .field("settings", &self.settings)
            .field("active", &self.active.len())
            .field("iterations", &self.iterations)
            .finish_non_exhaustive()
    }
}

const CANDIDATE: u8 = 0;
const ACTIVE: u8 = 1;
const ABSENT: u8 = 2;
const FIXED: u8 = 3;

const FREE: u8 = 0;
const AT_UPPER: u8 = 1;
const AT_LOWER: u8 = 2;

const NONE: usize = usize::MAX;

/// The number of bounds violated at the starting point from which they are fixed in bulk
/// (see the module docs).
pub const BULK_FIX: usize = 3;

fn all_finite(v: &[f64]) -> bool {
    v.iter().fold(true, |ok, x| ok & x.is_finite())
}

/// `false` for NaN anywhere in `H`, `f` and the bounds, or an infinity where none is
/// allowed (`G` is checked while it is compressed).
fn data_ok(p: &QpProblem) -> bool {
    all_finite(p.hess)
        && all_finite(p.f)
        && !(p.lb.iter().any(|v| v.is_nan() || *v == f64::INFINITY)
            || p.ub.iter().any(|v| v.is_nan() || *v == f64::NEG_INFINITY)
            || p.h.iter().any(|v| v.is_nan() || *v == f64::NEG_INFINITY))
}

/// Solves `L y = b` in place for the leading `k × k` block of `L` (lower triangular,
/// column-major with stride `ld`; `b` is zero before `start`).
fn forward_solve(l: &[f64], ld: usize, k: usize, b: &mut [f64], start: usize) {
    for j in start..k {
        let col = &l[j * ld..j * ld + k];
        let yj = b[j] / col[j];
        b[j] = yj;
        if yj != 0.0 {
            axpy(-yj, &col[j + 1..], &mut b[j + 1..k]);
        }
    }
}

/// Solves `Lᵀ z = y` in place for the leading `k × k` block of `L` (lower triangular,
/// column-major with stride `ld`).
fn backward_solve(l: &[f64], ld: usize, k: usize, y: &mut [f64]) {
    for i in (0..k).rev() {
        let col = &l[i * ld..i * ld + k];
        let s = y[i] - dot(&col[i + 1..], &y[i + 1..k]);
        y[i] = s / col[i];
    }
}

/// Multiply–adds a panel of the factorization may take ([`panel_end`]): about a third of
/// a `128 × 128` factorization (the acoustic rig's PCAC, `ℓ m = 128`), about twenty
/// microseconds.
const PANEL_WORK: usize = 1 << 17;

/// The narrowest panel (columns); a panel that would leave fewer columns takes them too.
const MIN_PANEL: usize = 8;

/// The end of the panel that begins at column `j0` of the left-looking factorization of a
/// `k × k` matrix: columns are added while the panel's multiply–adds — the update by the
/// columns before it, `(k − j0) w j0`, the diagonal block's factorization, `w³/6`, and
/// the solve below it, `(k − j0 − w) w²/2`, for `w` columns — stay within
/// [`PANEL_WORK`], with at least [`MIN_PANEL`] columns, and none fewer left after it.
fn panel_end(k: usize, j0: usize) -> usize {
    let cost = |w: usize| (k - j0) * w * j0 + w * w * w / 6 + (k - j0 - w) * w * w / 2;
    let mut w = MIN_PANEL.min(k - j0);
    while j0 + w < k && cost(w + 1) <= PANEL_WORK {
        w += 1;
    }
    if k - (j0 + w) < MIN_PANEL { k } else { j0 + w }
}

/// Columns `j0..j1` of the Cholesky factor of the leading `k × k` block of the
/// column-major matrix `a` (stride `ld`, lower triangle read and written), when the
/// columns before `j0` already hold `L` (left-looking, with faer's kernels on the
/// pre-sized scratch `mem`):
///
/// ```text
/// A[j0.., J] −= L[j0.., ..j0] L[J, ..j0]ᵀ
/// A[J, J] = L_JJ L_JJᵀ
/// L[j1.., J] = A[j1.., J] L_JJ⁻ᵀ
/// ```
///
/// for `J = j0..j1`. The same panels give the same factor, bit for bit, however the
/// calls are spread. Returns `false` if the block is not numerically positive definite.
fn cholesky_panel(
    a: &mut [f64],
    ld: usize,
    k: usize,
    (j0, j1): (usize, usize),
    mem: &mut MemBuffer,
) -> bool {
    let mat = faer::MatMut::from_column_major_slice_with_stride_mut(a, k, k, ld);
    let (done, rest) = mat.split_at_col_mut(j0);
    let w = j1 - j0;
    let mut panel = rest.subcols_mut(0, w).subrows_mut(j0, k - j0);
    if j0 > 0 {
        let below = done.as_ref().subrows(j0, k - j0);
        let across = done.as_ref().subrows(j0, w);
        matmul(
            panel.as_mut(),
            Accum::Add,
            below,
            across.transpose(),
            -1.0,
            Par::Seq,
        );
    }
    let (mut diag, below) = panel.split_at_row_mut(w);
    if factor::cholesky_in_place(
        diag.as_mut(),
        LltRegularization::default(),
        Par::Seq,
        MemStack::new(mem),
        Default::default(),
    )
    .is_err()
    {
        return false;
    }
    solve_lower_triangular_in_place(diag.as_ref(), below.transpose_mut(), Par::Seq);
    true
}

/// Columns `from..to` of the Cholesky factor of the leading `k × k` block, panel by panel
/// ([`cholesky_panel`], panels of [`panel_end`]), when the columns before `from` hold
/// `L`. Returns `false` if it is not numerically positive definite.
fn cholesky_columns(
    a: &mut [f64],
    ld: usize,
    k: usize,
    (from, to): (usize, usize),
    mem: &mut MemBuffer,
) -> bool {
    let mut j = from;
    while j < to {
        let end = panel_end(k, j);
        if !cholesky_panel(a, ld, k, (j, end), mem) {
            return false;
        }
        j = end;
    }
    true
}

/// How a round of the start point ended ([`DenseQpSolver::start_round`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Round {
    /// Every multiplier is nonnegative: the start point is dual feasible.
    DualFeasible,
    /// Bounds were freed into `L_F` or rows dropped; another round re-minimizes.
    Again,
    /// So many bounds were freed that `H_FF` is factored again ([`refactor_pays`]).
    Refactor,
}

/// Whether freeing `k` fixed variables into `nf` free ones costs more one at a time than
/// a new factorization of the `N = nf + k` free ones. One at a time, each adds a row to
/// `L_F` by a forward solve, `Σ_{j<k} (nf + j)²/2 ≈ (N³ − nf³)/6` multiply–adds in
/// dependent column sweeps; the factorization takes `N³/6` in faer's blocked panels, which
/// run them about twice as fast (`qp_timing`). The refactorization pays when
/// `N³ − nf³ > N³/2`, i.e. `nf < 0.79 N`, taken as `5k ≥ N`, and for at least
/// [`MIN_REFACTOR`] variables.
fn refactor_pays(nf: usize, k: usize) -> bool {
    k >= MIN_REFACTOR && 5 * k >= nf + k
}

/// The fewest freed variables that [`refactor_pays`] factors anew for.
const MIN_REFACTOR: usize = 4;

/// The right-hand side `b_id` of constraint `id` (internal ids for `n` variables).
fn rhs(p: &QpProblem, n: usize, id: usize) -> f64 {
    if id < n {
        p.ub[id]
    } else if id < 2 * n {
        -p.lb[id - n]
    } else {
        p.h[id - 2 * n]
    }
}

impl DenseQpSolver {
    /// A solver for problems with `n` variables and `n_ineq` rows in `G U ≤ h`; allocates
    /// all workspaces (`O(n² + n_ineq·n)`).
    ///
    /// It also factors an `n × n` identity once: faer's matrix-multiply kernels initialize
    /// their cache-size information (reading `/sys`, allocating) on first use in the
    /// process, and this keeps that out of the first real-time solve. Their packing
    /// scratch is per thread, though: call [`Self::prepare_thread`] on the thread that
    /// will solve, before its real-time loop.
    pub fn new(n: usize, n_ineq: usize, settings: QpSettings) -> Self {
        let n_con = 2 * n + n_ineq;
        // The scratch serves every size of H_FF, not only the largest.
        let req = (0..=n).fold(StackReq::EMPTY, |acc, k| {
            acc.or(factor::cholesky_in_place_scratch::<f64>(
                k,
                Par::Seq,
                Default::default(),
            ))
        });
        let mut solver = Self {
            n,
            n_ineq,
            settings,
            l: vec![0.0; n * n],
            chol_mem: MemBuffer::new(req),
            l_kept: Vec::new(),
            h_kept: Vec::new(),
            kept: false,
            l_is_kept: false,
            reused: false,
            x: vec![0.0; n],
            fix: vec![FREE; n],
            free: Vec::with_capacity(n),
            pos: vec![NONE; n],
            fixed: Vec::with_capacity(n),
            lam_fixed: vec![0.0; n],
            u_fixed: vec![0.0; n],
            row_ptr: vec![0; n_ineq + 1],
            cols: vec![0; n_ineq * n],
            vals: vec![0.0; n_ineq * n],
            inv_norm: vec![0.0; n_ineq],
            active: Vec::with_capacity(n),
            lambda_active: Vec::with_capacity(n),
            state: vec![ABSENT; n_con],
            want: vec![false; n_con],
            start_rows: Vec::with_capacity(n_ineq),
            q: vec![0.0; n * n],
            r: vec![0.0; n * n],
            w: vec![0.0; n],
            rho: vec![0.0; n],
            z: vec![0.0; n],
            rv: vec![0.0; n],
            rv2: vec![0.0; n],
            uv: vec![0.0; n],
            full: vec![0.0; n],
            col: vec![0.0; n],
            extra: vec![0.0; n],
            lam_lower: vec![0.0; n],
            lam_upper: vec![0.0; n],
            lam_ineq: vec![0.0; n_ineq],
            objective: f64::NAN,
            iterations: 0,
            fixed_at_start: 0,
            freed: 0,
            panel_stops: 0,
            refactors: 0,
            running: false,
            phase: Phase::Add,
            last_status: QpStatus::InvalidDimensions,
        };
        solver.prepare_thread();
        solver
    }

    /// Factors an `n × n` identity in the solver's buffers on the calling thread, so that
    /// the matrix-multiply kernels' per-thread packing buffer (allocated on a thread's
    /// first blocked product, for `n` above about 64) exists before the first real-time
    /// solve. Call it on the real-time thread before its loop (the service does, through
    /// [`Controller::prepare_thread`](crate::controller::Controller::prepare_thread)); it
    /// allocates on a thread that has not multiplied yet, and never again.
    pub fn prepare_thread(&mut self) {
        let n = self.n;
        self.l_is_kept = false;
        self.l.fill(0.0);
        for j in 0..n {
            self.l[j * n + j] = 1.0;
        }
        let _ = cholesky_columns(&mut self.l, n, n, (0, n), &mut self.chol_mem);
    }

    /// The number of variables `n` this solver was built for.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The number of rows of `G` this solver was built for.
    pub fn n_ineq(&self) -> usize {
        self.n_ineq
    }

    /// The settings.
    pub fn settings(&self) -> &QpSettings {
        &self.settings
    }

    /// Replaces the settings (e.g. the iteration cap).
    pub fn set_settings(&mut self, settings: QpSettings) {
        self.settings = settings;
    }

    /// The last iterate `U` (the solution after [`QpStatus::Solved`]).
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// Multipliers of the lower bounds `U ≥ lb` (`≥ 0`).
    pub fn lambda_lower(&self) -> &[f64] {
        &self.lam_lower
    }

    /// Multipliers of the upper bounds `U ≤ ub` (`≥ 0`).
    pub fn lambda_upper(&self) -> &[f64] {
        &self.lam_upper
    }

    /// Multipliers of the rows `G U ≤ h` (`≥ 0`). Stationarity reads
    /// `H U + f − λ_lower + λ_upper + Gᵀ λ_ineq = 0`.
    pub fn lambda_ineq(&self) -> &[f64] {
        &self.lam_ineq
    }

    /// The objective `½ Uᵀ H U + fᵀ U` at the last iterate.
    pub fn objective(&self) -> f64 {
        self.objective
    }

    /// Active-set changes made by the last solve: constraints added and dropped, fixed
    /// bounds freed (the bounds fixed at the start are not counted).
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The number of bounds of the warm start that the last solve fixed at its start.
    pub fn fixed_at_start(&self) -> usize {
        self.fixed_at_start
    }

    /// The number of fixed bounds the last solve freed (their multipliers were negative
    /// at the start, or reached zero in a dual step).
    pub fn freed_bounds(&self) -> usize {
        self.freed
    }

    /// The number of constraints in the final active set.
    pub fn active_len(&self) -> usize {
        self.active.len()
    }

    /// The `k`-th constraint of the final active set (`k < active_len()`).
    pub fn active_constraint(&self, k: usize) -> Option<ConstraintId> {
        self.active.get(k).map(|&id| self.to_public(id))
    }

    /// Writes the final active set into `out` (as many as fit) and returns how many were
    /// written; allocation-free, for [`WarmStart::ActiveSet`] at the next step.
    pub fn active_set_into(&self, out: &mut [ConstraintId]) -> usize {
        let k = self.active.len().min(out.len());
        for (o, &id) in out.iter_mut().zip(&self.active[..k]) {
            *o = self.to_public(id);
        }
        k
    }

    fn to_public(&self, id: usize) -> ConstraintId {
        if id < self.n {
            ConstraintId::Upper(id)
        } else if id < 2 * self.n {
            ConstraintId::Lower(id - self.n)
        } else {
            ConstraintId::Row(id - 2 * self.n)
        }
    }

    fn to_internal(&self, c: ConstraintId) -> Option<usize> {
        match c {
            ConstraintId::Upper(i) if i < self.n => Some(i),
            ConstraintId::Lower(i) if i < self.n => Some(self.n + i),
            ConstraintId::Row(j) if j < self.n_ineq => Some(2 * self.n + j),
            _ => None,
        }
    }

    /// `a_pᵀ x − b_p` for internal id `p`.
    fn slack(&self, p: &QpProblem, id: usize, x: &[f64]) -> f64 {
        let n = self.n;
        if id < n {
            x[id] - p.ub[id]
        } else if id < 2 * n {
            let i = id - n;
            p.lb[i] - x[i]
        } else {
            let j = id - 2 * n;
            let (a, b) = (self.row_ptr[j], self.row_ptr[j + 1]);
            let mut s = 0.0;
            for k in a..b {
                s += self.vals[k] * x[self.cols[k]];
            }
            s - p.h[j]
        }
    }

    /// Writes `L_F⁻¹ a_id` (the normal restricted to the free variables) into `self.w`.
    fn load_w(&mut self, id: usize) {
        let (n, nf) = (self.n, self.free.len());
        self.w[..nf].fill(0.0);
        let start;
        if id < n {
            start = self.pos[id];
            self.w[start] = 1.0;
        } else if id < 2 * n {
            start = self.pos[id - n];
            self.w[start] = -1.0;
        } else {
            let j = id - 2 * n;
            let mut first = nf;
            for k in self.row_ptr[j]..self.row_ptr[j + 1] {
                let a = self.pos[self.cols[k]];
                if a != NONE {
                    self.w[a] = self.vals[k];
                    first = first.min(a);
                }
            }
            start = first;
        }
        forward_solve(&self.l, n, nf, &mut self.w, start);
    }

    /// Solves the problem; allocation-free. See [`QpStatus`] for what the iterate means.
    /// The same as [`DenseQpSolver::start`] followed by one [`DenseQpSolver::proceed`]
    /// without a budget.
    pub fn solve(&mut self, p: &QpProblem, warm: WarmStart) -> QpStatus {
        match self.start(p, warm) {
            QpProgress::Done(status) => status,
            QpProgress::Running => match self.proceed(p, usize::MAX) {
                QpProgress::Done(status) => status,
                // Only after usize::MAX iterations, which the iteration cap prevents.
                QpProgress::Running => self.conclude(p, QpStatus::MaxIterations),
            },
        }
    }

    /// The first part of a solve split over several calls (module docs, "Real-time
    /// use"): the checks and the copy of `H_FF`; the factorization, the start point and
    /// the constraint additions follow in [`DenseQpSolver::proceed`]. [`DenseQpSolver::proceed`] goes on with the same problem
    /// (`p` must not change in between). Allocation-free.
    pub fn start(&mut self, p: &QpProblem, warm: WarmStart) -> QpProgress {
        self.running = false;
        self.iterations = 0;
        self.fixed_at_start = 0;
        self.freed = 0;
        self.panel_stops = 0;
        self.refactors = 0;
        self.reused = false;
        self.objective = f64::NAN;
        self.active.clear();
        self.lambda_active.clear();
        self.lam_lower.fill(0.0);
        self.lam_upper.fill(0.0);
        self.lam_ineq.fill(0.0);
        self.x.fill(0.0);
        self.fixed.clear();
        self.free.clear();
        if !self.dims_ok(p) {
            self.last_status = QpStatus::InvalidDimensions;
            return QpProgress::Done(QpStatus::InvalidDimensions);
        }
        match self.begin(p, warm) {
            Ok(()) => {
                self.running = true;
                QpProgress::Running
            }
            Err(status) => QpProgress::Done(self.conclude(p, status)),
        }
    }

    /// Goes on with the solve begun by [`DenseQpSolver::start`] on the same, unchanged
    /// problem `p`: while a factorization lasts, factors one panel of it (all of it
    /// when `budget` is `usize::MAX`) and returns; then computes the start point and adds
    /// violated constraints until the KKT conditions hold, the iteration cap is reached,
    /// or this call has made `budget` active-set changes (a start-point round or a
    /// constraint addition that has begun is always completed, so a call may exceed
    /// `budget` by the bounds one round frees or the partial steps of one addition). A
    /// start-point round that frees many bounds at once, and the bulk fix, are followed by
    /// a new factorization, whose first panel ends the call. `Running`: call again;
    /// `Done(status)`: the solve is over, with the outcome [`DenseQpSolver::solve`]
    /// would have returned, bit for bit. With no solve running, `Done` repeats the last
    /// outcome. Allocation-free.
    pub fn proceed(&mut self, p: &QpProblem, budget: usize) -> QpProgress {
        if !self.running {
            return QpProgress::Done(self.last_status);
        }
        if !self.dims_ok(p) {
            self.running = false;
            self.last_status = QpStatus::InvalidDimensions;
            return QpProgress::Done(QpStatus::InvalidDimensions);
        }
        match self.work(p, budget) {
            Some(status) => QpProgress::Done(self.conclude(p, status)),
            None => QpProgress::Running,
        }
    }

    /// Whether `p` has the dimensions the solver was built for.
    fn dims_ok(&self, p: &QpProblem) -> bool {
        let (n, m) = (self.n, self.n_ineq);
        p.hess.len() == n * n
            && p.f.len() == n
            && p.lb.len() == n
            && p.ub.len() == n
            && p.g.len() == m * n
            && p.h.len() == m
    }

    /// Keeps (`true`) the factorization `H = L Lᵀ` of each solve that factors the whole
    /// `H` (no bound fixed), with a copy of that `H`, and lets a later solve whose `H`
    /// equals it entry for entry and whose warm start fixes no bound start from it instead
    /// of factoring: for a controller that rebuilds `H` less often than it solves
    /// (module docs, "Keeping the factorization"). Allocates two `n × n` buffers (call it
    /// before the real-time loop); `false` frees them. Results are those of a solve that
    /// factors, bit for bit: faer's factorization of the same matrix is the same.
    pub fn keep_factorization(&mut self, keep: bool) {
        let len = if keep { self.n * self.n } else { 0 };
        self.l_kept = vec![0.0; len];
        self.h_kept = vec![0.0; len];
        self.kept = false;
        self.l_is_kept = false;
    }

    /// Whether the last solve started from the kept factorization
    /// ([`DenseQpSolver::keep_factorization`]) rather than factoring.
    pub fn factor_reused(&self) -> bool {
        self.reused
    }

    /// The start of a solve from the kept factorization, when there is one of this `H`
    /// and the warm start fixed no bound: every variable free, `L` the kept factor (copied
    /// only if something wrote `l` since), and the start point's rounds next. Returns
    /// whether it did; otherwise nothing has changed.
    fn reuse_kept(&mut self, p: &QpProblem) -> bool {
        if !self.kept || self.fix.iter().any(|&f| f != FREE) || p.hess != &self.h_kept[..] {
            return false;
        }
        self.free.clear();
        self.fixed.clear();
        for i in 0..self.n {
            self.pos[i] = i;
            self.free.push(i);
        }
        if !self.l_is_kept {
            self.l.copy_from_slice(&self.l_kept);
            self.l_is_kept = true;
        }
        self.fixed_at_start = 0;
        self.start_rows();
        self.phase = Phase::Start {
            minimized: false,
            refactored: false,
        };
        self.reused = true;
        true
    }

    /// Whether a solve begun by [`DenseQpSolver::start`] awaits [`DenseQpSolver::proceed`].
    pub fn is_running(&self) -> bool {
        self.running
    }

    /// [`DenseQpSolver::finish`], and the solve is over.
    fn conclude(&mut self, p: &QpProblem, status: QpStatus) -> QpStatus {
        self.running = false;
        let status = self.finish(p, status);
        self.last_status = status;
        status
    }

    /// The fixed part of a solve: the compressed rows, the warm start's fixed bounds and
    /// the factorization; the start point's rounds are set to follow (`work`).
    fn begin(&mut self, p: &QpProblem, warm: WarmStart) -> Result<(), QpStatus> {
        let n = self.n;
        let m = self.n_ineq;
        if !data_ok(p) {
            return Err(QpStatus::NumericalError);
        }

        // Compressed rows of G (NaN and infinities are nonzero, so every one is seen).
        let (mut g_finite, mut zero_row_violated) = (true, false);
        let mut nnz = 0;
        self.row_ptr[0] = 0;
        for j in 0..m {
            let row = &p.g[j * n..(j + 1) * n];
            let mut s2 = 0.0;
            // Blocks of eight zeros (most of a move-bound row) are skipped with one
            // branch-free test.
            let mut chunks = row.chunks_exact(8);
            let mut base = 0;
            for chunk in &mut chunks {
                if chunk.iter().fold(false, |any, v| any | (*v != 0.0)) {
                    for (c, &v) in chunk.iter().enumerate() {
                        if v != 0.0 {
                            self.cols[nnz] = base + c;
                            self.vals[nnz] = v;
                            nnz += 1;
                            s2 += v * v;
                            g_finite &= v.is_finite();
                        }
                    }
                }
                base += 8;
            }
            for (c, &v) in chunks.remainder().iter().enumerate() {
                if v != 0.0 {
                    self.cols[nnz] = base + c;
                    self.vals[nnz] = v;
                    nnz += 1;
                    s2 += v * v;
                    g_finite &= v.is_finite();
                }
            }
            self.row_ptr[j + 1] = nnz;
            self.inv_norm[j] = if s2 > 0.0 { 1.0 / s2.sqrt() } else { 0.0 };
            // A zero row with negative h (beyond round-off: the condensed rows of outputs
            // that no input reaches) is trivially infeasible.
            let tol = self.settings.feasibility_tol;
            zero_row_violated |= nnz == self.row_ptr[j] && p.h[j] < -tol * (1.0 + p.h[j].abs());
        }
        if !g_finite {
            return Err(QpStatus::NumericalError);
        }
        if zero_row_violated || p.lb.iter().zip(p.ub).any(|(l, u)| l > u) {
            return Err(QpStatus::Infeasible);
        }

        // Which constraints exist, and which the warm start wants first.
        for i in 0..n {
            self.set_bound_states(p, i);
        }
        for j in 0..m {
            let present = p.h[j].is_finite() && self.row_ptr[j + 1] > self.row_ptr[j];
            self.state[2 * n + j] = if present { CANDIDATE } else { ABSENT };
        }
        self.mark_warm(p, warm);

        // Fix the warm start's bounds (a variable with both bounds wanted only if they
        // coincide).
        for i in 0..n {
            let up = self.want[i] && p.ub[i].is_finite();
            let lo = self.want[n + i] && p.lb[i].is_finite();
            self.fix[i] = match (up, lo) {
                (true, false) => AT_UPPER,
                (false, true) => AT_LOWER,
                (true, true) if p.lb[i] == p.ub[i] => AT_UPPER,
                _ => FREE,
            };
        }
        if self.reuse_kept(p) {
            return Ok(());
        }
        self.gather_free(p);
        self.fixed_at_start = self.fixed.len();
        self.start_rows();
        // The factorization and the starting point (dual feasible, see `start_rows` and
        // `start_round`) follow in `work`.
        self.phase = Phase::Factor {
            col: 0,
            refactored: false,
        };
        Ok(())
    }

    /// Bounds violated at the start point, and pushed against by the objective at the
    /// start point clipped to the box, are fixed in bulk when there are at least
    /// `BULK_FIX` of them: one more factorization instead of one dual step each (the
    /// first steps of a saturated horizon, which the warm start does not foresee; called
    /// only when the warm start fixed no bound).
    /// Returns whether they were (`H_FF` is then gathered, to be factored before the start
    /// point is computed again).
    fn fix_in_bulk(&mut self, p: &QpProblem) -> bool {
        let n = self.n;
        let tol = self.settings.feasibility_tol;
        // The start point clipped to the box, in `col`.
        self.col.copy_from_slice(&self.x);
        for &i in &self.free {
            let xi = self.x[i];
            if xi - p.ub[i] > tol * (1.0 + p.ub[i].abs()) {
                self.fix[i] = AT_UPPER;
                self.col[i] = p.ub[i];
            } else if p.lb[i] - xi > tol * (1.0 + p.lb[i].abs()) {
                self.fix[i] = AT_LOWER;
                self.col[i] = p.lb[i];
            }
        }
        // A violated bound is fixed only if the objective's gradient at the clipped point
        // pushes against it (its multiplier estimate `∓(H U_clip + f)_i` is positive).
        let mut violated = 0;
        for &i in &self.free {
            if self.fix[i] == FREE {
                continue;
            }
            let g = p.f[i] + dot(&p.hess[i * n..(i + 1) * n], &self.col);
            let lam = if self.fix[i] == AT_UPPER { -g } else { g };
            if lam > 0.0 {
                violated += 1;
            } else {
                self.fix[i] = FREE;
            }
        }
        if violated >= BULK_FIX {
            self.fixed_at_start += violated;
            self.clear_active();
            self.gather_free(p);
            self.start_rows();
            true
        } else {
            for &i in &self.free {
                self.fix[i] = FREE;
            }
            false
        }
    }

    /// The work after the factorization, in order: the start point's rounds (each
    /// freeing the fixed bounds and dropping the rows with negative multipliers), the
    /// bulk fix (and the rounds again after it), then the dual iterations: the violated
    /// constraint (prioritized first, then the most violated) is added, until none is
    /// left (`Solved`) or a step fails; or until `budget` active-set changes have been
    /// made in this call (`None`: more to do), checked between rounds and additions.
    fn work(&mut self, p: &QpProblem, budget: usize) -> Option<QpStatus> {
        let max_iter = self.settings.max_iterations;
        let tol = self.settings.feasibility_tol;
        let mark = self.iterations;
        loop {
            if let Phase::Factor { col, refactored } = self.phase {
                // One panel per call when the call has a budget; all of them otherwise.
                let nf = self.free.len();
                let end = if budget == usize::MAX {
                    nf
                } else {
                    panel_end(nf, col)
                };
                if let Err(status) = self.factor_panels(col, end) {
                    return Some(status);
                }
                if end < nf {
                    self.phase = Phase::Factor {
                        col: end,
                        refactored,
                    };
                    self.panel_stops += 1;
                    return None;
                }
                if nf == self.n && !self.l_kept.is_empty() {
                    self.l_kept.copy_from_slice(&self.l);
                    self.h_kept.copy_from_slice(p.hess);
                    self.kept = true;
                    self.l_is_kept = true;
                }
                self.phase = Phase::Start {
                    minimized: false,
                    refactored,
                };
                if budget != usize::MAX {
                    self.panel_stops += 1;
                    return None;
                }
                continue;
            }
            if self.iterations - mark >= budget {
                return None;
            }
            if let Phase::Start {
                minimized,
                refactored,
            } = self.phase
            {
                match self.start_round(p, minimized, max_iter) {
                    Err(status) => return Some(status),
                    Ok(Round::Again) => {
                        self.phase = Phase::Start {
                            minimized: false,
                            refactored,
                        }
                    }
                    Ok(Round::Refactor) => self.phase = Phase::Factor { col: 0, refactored },
                    Ok(Round::DualFeasible) if refactored || self.fixed_at_start > 0 => {
                        self.phase = Phase::Add
                    }
                    Ok(Round::DualFeasible) => {
                        if self.fix_in_bulk(p) {
                            self.phase = Phase::Factor {
                                col: 0,
                                refactored: true,
                            }
                        } else {
                            self.phase = Phase::Add
                        }
                    }
                }
                continue;
            }
            let (best, best_v, best_pri) = self.select_violated(p, tol);
            let pid = if best_pri != usize::MAX {
                best_pri
            } else {
                best
            };
            if pid == usize::MAX {
                return Some(QpStatus::Solved);
            }
            if !best_v.is_finite() {
                return Some(QpStatus::NumericalError);
            }
            if let Err(status) = self.add_constraint(p, pid, max_iter) {
                return Some(status);
            }
        }
    }

    /// Marks the warm start's constraints in `want`.
    fn mark_warm(&mut self, p: &QpProblem, warm: WarmStart) {
        let (n, m) = (self.n, self.n_ineq);
        self.want.fill(false);
        match warm {
            WarmStart::Cold => {}
            WarmStart::ActiveSet(ids) => {
                for &c in ids {
                    if let Some(id) = self.to_internal(c) {
                        self.want[id] = true;
                    }
                }
            }
            WarmStart::Primal(xg) => {
                if xg.len() != n || !all_finite(xg) {
                    return;
                }
                // Active or violated within 1e-7 relative.
                let near = |s: f64, scale: f64| s >= -1e-7 * scale;
                for (i, &xi) in xg.iter().enumerate() {
                    if p.ub[i].is_finite() {
                        self.want[i] = near(xi - p.ub[i], 1.0 + p.ub[i].abs());
                    }
                    if p.lb[i].is_finite() {
                        self.want[n + i] = near(p.lb[i] - xi, 1.0 + p.lb[i].abs());
                    }
                }
                for j in 0..m {
                    if self.state[2 * n + j] != ABSENT {
                        let nrm = 1.0 / self.inv_norm[j];
                        let s = self.slack(p, 2 * n + j, xg);
                        self.want[2 * n + j] = near(s, nrm + p.h[j].abs());
                    }
                }
            }
        }
    }

    /// The dual method's starting point: the minimizer over the free variables with the
    /// fixed ones at their bounds and the warm start's rows `R` held with equality,
    ///
    /// ```text
    /// U_F = U⁰_F − L_F⁻ᵀ Q R⁻ᵀ s,   λ_R = R⁻¹ R⁻ᵀ s,   s = N_Rᵀ U⁰ − b_R,
    /// ```
    ///
    /// (`U⁰` the minimizer without the rows, `L_F⁻¹ N_R = Q R`), and the fixed bounds'
    /// multipliers from stationarity on their rows. It is dual feasible when every
    /// multiplier is nonnegative; rows and fixed bounds with negative ones leave (the
    /// variables are freed) until it is.
    ///
    /// This collects the warm start's rows `R`; each [`DenseQpSolver::start_round`]
    /// computes the point for the present `B` and `R` and frees (drops) those with
    /// negative multipliers, until none is left.
    fn start_rows(&mut self) {
        let n = self.n;
        self.start_rows.clear();
        for j in 0..self.n_ineq {
            let id = 2 * n + j;
            if self.want[id] && self.state[id] == CANDIDATE {
                self.start_rows.push(id);
            }
        }
    }

    /// One round of the start point ([`DenseQpSolver::start_rows`]): whether it is dual
    /// feasible, or bounds were freed or rows dropped and another round follows,
    /// re-minimizing ([`Round`]). `minimized`: `U_F` already holds `U⁰_F`.
    fn start_round(
        &mut self,
        p: &QpProblem,
        minimized: bool,
        max_iter: usize,
    ) -> Result<Round, QpStatus> {
        let n = self.n;
        {
            if !minimized {
                self.minimize_free(p)?;
            }
            let nf = self.free.len();
            // Q R of the rows (a dependent one leaves).
            self.clear_active();
            let mut k = 0;
            while k < self.start_rows.len() {
                let id = self.start_rows[k];
                self.load_w(id);
                let w_norm = dot(&self.w[..nf], &self.w[..nf]).sqrt();
                let rho2 = self.orthogonalize(nf, w_norm);
                let q = self.active.len();
                if q >= nf || rho2.sqrt() <= self.settings.dependence_tol * w_norm {
                    self.start_rows.swap_remove(k);
                } else {
                    self.append_active(id, 0.0, rho2);
                    k += 1;
                }
            }
            let q = self.active.len();
            if q > 0 {
                // t = R⁻ᵀ s (in rv2), λ_R = R⁻¹ t (in uv), U_F −= L_F⁻ᵀ Q t.
                for k in 0..q {
                    let mut s = self.slack(p, self.active[k], &self.x);
                    for i in 0..k {
                        s -= self.r[i * n + k] * self.rv2[i];
                    }
                    self.rv2[k] = s / self.r[k * n + k];
                }
                for i in (0..q).rev() {
                    let row = &self.r[i * n..i * n + q];
                    let s = self.rv2[i] - dot(&row[i + 1..q], &self.uv[i + 1..q]);
                    self.uv[i] = s / row[i];
                }
                self.z[..nf].fill(0.0);
                for k in 0..q {
                    axpy(self.rv2[k], &self.q[k * n..k * n + nf], &mut self.z[..nf]);
                }
                backward_solve(&self.l, n, nf, &mut self.z);
                for (a, &i) in self.free.iter().enumerate() {
                    self.x[i] -= self.z[a];
                }
                self.lambda_active.copy_from_slice(&self.uv[..q]);
            }
            // The fixed bounds' multipliers: stationarity g_i ± λ_i = 0 with
            // g = H U + f + N_R λ_R, so λ_upper = −g_i, λ_lower = g_i.
            for &i in &self.fixed {
                let row = &p.hess[i * n..(i + 1) * n];
                self.lam_fixed[i] = p.f[i] + dot(row, &self.x);
            }
            for (&id, &lam) in self.active.iter().zip(&self.lambda_active) {
                let j = id - 2 * n;
                for e in self.row_ptr[j]..self.row_ptr[j + 1] {
                    let c = self.cols[e];
                    if self.fix[c] != FREE {
                        self.lam_fixed[c] += lam * self.vals[e];
                    }
                }
            }
            // Any negative multiplier, however small, leaves: accepting one would end at
            // a point that is not the minimizer (PCAC's Hessians are ill-conditioned, and
            // a small multiplier can stand for a large move in a flat direction). Round-off
            // on a zero multiplier costs at most a dual step that adds it back.
            let mut negative = 0;
            for &i in &self.fixed {
                let g = self.lam_fixed[i];
                let lam = if self.fix[i] == AT_UPPER { -g } else { g };
                if !lam.is_finite() {
                    return Err(QpStatus::NumericalError);
                }
                self.lam_fixed[i] = lam;
                if lam < 0.0 {
                    negative += 1;
                }
            }
            for k in 0..self.active.len() {
                let lam = self.lambda_active[k];
                if !lam.is_finite() {
                    return Err(QpStatus::NumericalError);
                }
                if lam < 0.0 {
                    negative += 1;
                    let id = self.active[k];
                    if let Some(r) = self.start_rows.iter().position(|&x| x == id) {
                        self.start_rows.swap_remove(r);
                    }
                }
            }
            if negative == 0 {
                return Ok(Round::DualFeasible);
            }
            // Rebuilt in the next round; free the variables without updating Q R.
            self.clear_active();
            let freeing = self
                .fixed
                .iter()
                .filter(|&&i| self.lam_fixed[i] < 0.0)
                .count();
            let refactor = refactor_pays(self.free.len(), freeing);
            let mut k = 0;
            while k < self.fixed.len() {
                let i = self.fixed[k];
                if self.lam_fixed[i] >= 0.0 {
                    k += 1;
                } else if refactor {
                    self.fixed.swap_remove(k);
                    self.fix[i] = FREE;
                    self.lam_fixed[i] = 0.0;
                    self.freed += 1;
                    self.set_bound_states(p, i);
                } else {
                    self.free_variable(p, i)?;
                }
            }
            self.iterations += negative;
            if self.iterations >= max_iter {
                return Err(QpStatus::MaxIterations);
            }
            if refactor {
                self.refactors += 1;
                self.gather_free(p);
                return Ok(Round::Refactor);
            }
        }
        Ok(Round::Again)
    }

    /// CGS2 of `w` (norm `w_norm`) against the active `Q` on the first `nf` coordinates:
    /// `r = Qᵀw` into `rv`, `ρ = w − Q r` into `rho`, re-orthogonalized once when the
    /// first pass cancelled more than half of `‖w‖²` ("twice is enough"). Returns `‖ρ‖²`.
    fn orthogonalize(&mut self, nf: usize, w_norm: f64) -> f64 {
        let n = self.n;
        let q = self.active.len();
        self.rho[..nf].copy_from_slice(&self.w[..nf]);
        for k in 0..q {
            self.rv[k] = dot(&self.q[k * n..k * n + nf], &self.w[..nf]);
        }
        for k in 0..q {
            axpy(-self.rv[k], &self.q[k * n..k * n + nf], &mut self.rho[..nf]);
        }
        if q > 0 && dot(&self.rho[..nf], &self.rho[..nf]) < 0.5 * w_norm * w_norm {
            for k in 0..q {
                self.rv2[k] = dot(&self.q[k * n..k * n + nf], &self.rho[..nf]);
            }
            for k in 0..q {
                axpy(
                    -self.rv2[k],
                    &self.q[k * n..k * n + nf],
                    &mut self.rho[..nf],
                );
                self.rv[k] += self.rv2[k];
            }
        }
        dot(&self.rho[..nf], &self.rho[..nf])
    }

    /// Constraint `id` joins the active set with multiplier `lam`: `Q` gains `ρ/δ`, `R`
    /// the column `[r; δ]` (`δ² = rho2`, from [`Self::orthogonalize`]).
    fn append_active(&mut self, id: usize, lam: f64, rho2: f64) {
        let n = self.n;
        let nf = self.free.len();
        let q = self.active.len();
        let delta = rho2.sqrt();
        for (dst, src) in self.q[q * n..q * n + nf].iter_mut().zip(&self.rho[..nf]) {
            *dst = src / delta;
        }
        for i in 0..q {
            self.r[i * n + q] = self.rv[i];
        }
        self.r[q * n + q] = delta;
        self.active.push(id);
        self.lambda_active.push(lam);
        self.state[id] = ACTIVE;
    }

    /// Builds `free`, `pos` and `fixed` from `fix` (fixed variables at their bounds, their
    /// bounds `FIXED`) and copies `H_FF` where [`Self::factor_panels`] factors it.
    fn gather_free(&mut self, p: &QpProblem) {
        let n = self.n;
        self.l_is_kept = false;
        self.free.clear();
        self.fixed.clear();
        for i in 0..n {
            if self.fix[i] == FREE {
                self.pos[i] = self.free.len();
                self.free.push(i);
            } else {
                self.pos[i] = NONE;
                self.fixed.push(i);
                self.state[i] = FIXED;
                self.state[n + i] = FIXED;
                self.x[i] = if self.fix[i] == AT_UPPER {
                    p.ub[i]
                } else {
                    p.lb[i]
                };
            }
        }
        let nf = self.free.len();
        if nf == n {
            // H's row-major upper triangle is, read column-major, the lower triangle
            // that faer factors in place.
            self.l.copy_from_slice(p.hess);
        } else {
            for (b, &jb) in self.free.iter().enumerate() {
                let row = &p.hess[jb * n..(jb + 1) * n];
                let dst = &mut self.l[b * n..b * n + nf];
                for a in b..nf {
                    dst[a] = row[self.free[a]];
                }
            }
        }
    }

    /// Columns `from..to` of `L_F` ([`cholesky_panel`], panels of [`panel_end`]), after
    /// [`Self::gather_free`] and the columns before `from`.
    fn factor_panels(&mut self, from: usize, to: usize) -> Result<(), QpStatus> {
        let (n, nf) = (self.n, self.free.len());
        if cholesky_columns(&mut self.l, n, nf, (from, to), &mut self.chol_mem) {
            Ok(())
        } else {
            Err(QpStatus::NumericalError)
        }
    }

    /// With no constraint active: the free variables ← the minimizer of the objective
    /// with the fixed ones at their bounds, `U_F = −H_FF⁻¹ (f_F + H_FB U_B)`.
    fn minimize_free(&mut self, p: &QpProblem) -> Result<(), QpStatus> {
        let (n, nf) = (self.n, self.free.len());
        for (a, &i) in self.free.iter().enumerate() {
            let row = &p.hess[i * n..(i + 1) * n];
            let mut c = p.f[i];
            for &j in &self.fixed {
                c += row[j] * self.x[j];
            }
            self.z[a] = -c;
        }
        forward_solve(&self.l, n, nf, &mut self.z, 0);
        backward_solve(&self.l, n, nf, &mut self.z);
        for (a, &i) in self.free.iter().enumerate() {
            self.x[i] = self.z[a];
        }
        if all_finite(&self.z[..nf]) {
            Ok(())
        } else {
            Err(QpStatus::NumericalError)
        }
    }

    /// Frees fixed variable `b` (its bound's multiplier is zero): `b` joins `F` at the
    /// end, `L_F` gains the row `[lᵀ δ]` with `L_F l = H_Fb`, `δ² = H_bb − lᵀl`, and the
    /// active normals `W = L_F⁻¹ N_A = Q R` gain the row `(N_bᵀ − lᵀW)/δ`, which Givens
    /// rotations fold back into `R` (`O(|F|·|A|)`).
    fn free_variable(&mut self, p: &QpProblem, b: usize) -> Result<(), QpStatus> {
        let (n, nf, q) = (self.n, self.free.len(), self.active.len());
        self.l_is_kept = false;
        for (a, &i) in self.free.iter().enumerate() {
            self.col[a] = p.hess[i * n + b];
        }
        forward_solve(&self.l, n, nf, &mut self.col, 0);
        let d2 = p.hess[b * n + b] - dot(&self.col[..nf], &self.col[..nf]);
        if !(d2 > 0.0 && d2.is_finite()) {
            return Err(QpStatus::NumericalError);
        }
        let delta = d2.sqrt();
        for a in 0..nf {
            self.l[a * n + nf] = self.col[a];
        }
        self.l[nf * n + nf] = delta;
        if q > 0 {
            // v = Qᵀ l, new row of W: (N_b − Rᵀ v)/δ, kept in `rv2`.
            for k in 0..q {
                self.uv[k] = dot(&self.q[k * n..k * n + nf], &self.col[..nf]);
            }
            for k in 0..q {
                let id = self.active[k];
                let nb = if id >= 2 * n {
                    p.g[(id - 2 * n) * n + b]
                } else {
                    0.0
                };
                let mut s = nb;
                for i in 0..=k {
                    s -= self.r[i * n + k] * self.uv[i];
                }
                self.rv2[k] = s / delta;
            }
            // Q's vectors gain a zero coordinate; the extra column starts as e_nf.
            for k in 0..q {
                self.q[k * n + nf] = 0.0;
            }
            self.extra[..=nf].fill(0.0);
            self.extra[nf] = 1.0;
            for k in 0..q {
                let (a, bb) = (self.r[k * n + k], self.rv2[k]);
                if bb == 0.0 {
                    continue;
                }
                let h = a.hypot(bb);
                let (c, s) = (a / h, bb / h);
                for col in k..q {
                    let (x0, x1) = (self.r[k * n + col], self.rv2[col]);
                    self.r[k * n + col] = c * x0 + s * x1;
                    self.rv2[col] = -s * x0 + c * x1;
                }
                let qk = &mut self.q[k * n..k * n + nf + 1];
                for (a0, a1) in qk.iter_mut().zip(self.extra[..=nf].iter_mut()) {
                    let (x0, x1) = (*a0, *a1);
                    *a0 = c * x0 + s * x1;
                    *a1 = -s * x0 + c * x1;
                }
            }
        }
        self.freed += 1;
        self.pos[b] = nf;
        self.free.push(b);
        if let Some(k) = self.fixed.iter().position(|&i| i == b) {
            self.fixed.swap_remove(k);
        }
        self.fix[b] = FREE;
        self.lam_fixed[b] = 0.0;
        self.set_bound_states(p, b);
        Ok(())
    }

    /// Empties the active set (its constraints become candidates again).
    fn clear_active(&mut self) {
        for &id in &self.active {
            self.state[id] = CANDIDATE;
        }
        self.active.clear();
        self.lambda_active.clear();
    }

    /// Variable `i`'s bounds become candidates (`ABSENT` where infinite).
    fn set_bound_states(&mut self, p: &QpProblem, i: usize) {
        let state = |finite: bool| if finite { CANDIDATE } else { ABSENT };
        self.state[i] = state(p.ub[i].is_finite());
        self.state[self.n + i] = state(p.lb[i].is_finite());
    }

    /// The most violated candidate constraint, its violation and the most violated
    /// prioritized one (`usize::MAX` for none). A constraint `a_iᵀU ≤ b_i` counts as
    /// violated when `(a_iᵀU − b_i)/‖a_i‖ > tol (1 + |b_i|/‖a_i‖)`; the violation compared is
    /// the excess over that threshold.
    fn select_violated(&self, p: &QpProblem, tol: f64) -> (usize, f64, usize) {
        let n = self.n;
        let x = &self.x;
        let (mut best, mut best_v) = (usize::MAX, 0.0);
        let (mut best_pri, mut best_pri_v) = (usize::MAX, 0.0);
        let mut consider = |id: usize, v: f64| {
            if v > best_v {
                best_v = v;
                best = id;
            }
            if self.want[id] && v > best_pri_v {
                best_pri_v = v;
                best_pri = id;
            }
        };
        for (i, &xi) in x.iter().enumerate() {
            if self.state[i] == CANDIDATE {
                consider(i, xi - p.ub[i] - tol * (1.0 + p.ub[i].abs()));
            }
            if self.state[n + i] == CANDIDATE {
                consider(n + i, p.lb[i] - xi - tol * (1.0 + p.lb[i].abs()));
            }
        }
        for j in 0..self.n_ineq {
            if self.state[2 * n + j] == CANDIDATE {
                let (a, b) = (self.row_ptr[j], self.row_ptr[j + 1]);
                let mut s = 0.0;
                for k in a..b {
                    s += self.vals[k] * x[self.cols[k]];
                }
                let inv = self.inv_norm[j];
                consider(
                    2 * n + j,
                    (s - p.h[j]) * inv - tol * (1.0 + p.h[j].abs() * inv),
                );
            }
        }
        (best, best_v, best_pri)
    }

    /// Steps until constraint `pid` is satisfied and added (or the problem is found
    /// infeasible, or the iteration cap is hit). Partial steps drop an active constraint
    /// or free a fixed variable, whichever multiplier reaches zero first.
    fn add_constraint(
        &mut self,
        p: &QpProblem,
        pid: usize,
        max_iter: usize,
    ) -> Result<(), QpStatus> {
        let n = self.n;
        let mut lam_p = 0.0;
        // w = L_F⁻¹ a_p changes only when a variable is freed.
        let mut w_stale = true;
        let mut w_norm = 0.0;
        loop {
            if self.iterations >= max_iter {
                return Err(QpStatus::MaxIterations);
            }
            self.iterations += 1;
            let nf = self.free.len();
            let q = self.active.len();
            if w_stale {
                self.load_w(pid);
                w_norm = dot(&self.w[..nf], &self.w[..nf]).sqrt();
                w_stale = false;
            }
            let rho2 = self.orthogonalize(nf, w_norm);
            // u = R⁻¹ r.
            for i in (0..q).rev() {
                let row = &self.r[i * n..i * n + q];
                let s = self.rv[i] - dot(&row[i + 1..q], &self.uv[i + 1..q]);
                self.uv[i] = s / row[i];
            }
            let dependent = q >= nf || rho2.sqrt() <= self.settings.dependence_tol * w_norm;
            let s_p = self.slack(p, pid, &self.x);
            let t1 = if dependent { f64::INFINITY } else { s_p / rho2 };
            let mut t2 = f64::INFINITY;
            let mut k_drop = usize::MAX;
            for k in 0..q {
                let uk = self.uv[k];
                if uk > 0.0 {
                    let t = self.lambda_active[k] / uk;
                    if t < t2 {
                        t2 = t;
                        k_drop = k;
                    }
                }
            }
            // The primal direction z = L_F⁻ᵀ ρ (zero on the fixed variables).
            if !dependent {
                self.z[..nf].copy_from_slice(&self.rho[..nf]);
                backward_solve(&self.l, n, nf, &mut self.z);
            }
            // The fixed bounds' multipliers move as λ_i − t u_i, where stationarity on
            // row i gives u_i = s_i (−(H z)_i − Σ_A u_k (a_k)_i + (a_p)_i), s_i = ±1 for
            // an upper or lower bound.
            let mut t3 = f64::INFINITY;
            let mut b_drop = usize::MAX;
            if !self.fixed.is_empty() {
                if !dependent {
                    self.full.fill(0.0);
                    for (a, &i) in self.free.iter().enumerate() {
                        self.full[i] = self.z[a];
                    }
                }
                for &i in &self.fixed {
                    self.u_fixed[i] = if dependent {
                        0.0
                    } else {
                        -dot(&p.hess[i * n..(i + 1) * n], &self.full)
                    };
                }
                if pid >= 2 * n {
                    let j = pid - 2 * n;
                    for e in self.row_ptr[j]..self.row_ptr[j + 1] {
                        let c = self.cols[e];
                        if self.fix[c] != FREE {
                            self.u_fixed[c] += self.vals[e];
                        }
                    }
                }
                for k in 0..q {
                    let id = self.active[k];
                    if id >= 2 * n {
                        let j = id - 2 * n;
                        for e in self.row_ptr[j]..self.row_ptr[j + 1] {
                            let c = self.cols[e];
                            if self.fix[c] != FREE {
                                self.u_fixed[c] -= self.uv[k] * self.vals[e];
                            }
                        }
                    }
                }
                for &i in &self.fixed {
                    let u = if self.fix[i] == AT_UPPER {
                        self.u_fixed[i]
                    } else {
                        -self.u_fixed[i]
                    };
                    self.u_fixed[i] = u;
                    if u > 0.0 {
                        let t = self.lam_fixed[i] / u;
                        if t < t3 {
                            t3 = t;
                            b_drop = i;
                        }
                    }
                }
            }
            if !(t1.is_finite() || t2.is_finite() || t3.is_finite()) {
                if t1.is_nan() || t2.is_nan() || t3.is_nan() {
                    return Err(QpStatus::NumericalError);
                }
                return Err(QpStatus::Infeasible);
            }
            let t_part = t2.min(t3);
            let full_step = !t1.is_nan() && t1 <= t_part;
            let t = if full_step { t1 } else { t_part }.max(0.0);
            if !dependent {
                for (a, &i) in self.free.iter().enumerate() {
                    self.x[i] -= t * self.z[a];
                }
            }
            for k in 0..q {
                self.lambda_active[k] -= t * self.uv[k];
            }
            for &i in &self.fixed {
                self.lam_fixed[i] -= t * self.u_fixed[i];
            }
            lam_p += t;
            if full_step {
                // p is satisfied and joins the active set.
                self.append_active(pid, lam_p, rho2);
                if !all_finite(&self.x) {
                    return Err(QpStatus::NumericalError);
                }
                return Ok(());
            }
            // Partial step: an active constraint leaves, or a fixed variable is freed.
            if t2 <= t3 {
                self.drop_active(k_drop);
            } else {
                self.lam_fixed[b_drop] = 0.0;
                self.free_variable(p, b_drop)?;
                w_stale = true;
            }
            if !all_finite(&self.x) || !lam_p.is_finite() {
                return Err(QpStatus::NumericalError);
            }
        }
    }

    /// Removes the `k`-th active constraint: column `k` of `R` goes, Givens rotations
    /// restore the triangle and rotate `Q` alike.
    fn drop_active(&mut self, k: usize) {
        let n = self.n;
        let nf = self.free.len();
        let q = self.active.len();
        let id = self.active[k];
        self.state[id] = CANDIDATE;
        // Shift columns k+1..q of R left.
        for i in 0..q {
            let row = &mut self.r[i * n..i * n + q];
            row.copy_within(k + 1..q, k);
        }
        // R is now q × (q−1), upper Hessenberg from column k.
        for j in k..q - 1 {
            let a = self.r[j * n + j];
            let b = self.r[(j + 1) * n + j];
            let h = a.hypot(b);
            if h == 0.0 {
                continue;
            }
            let (c, s) = (a / h, b / h);
            for col in j..q - 1 {
                let x0 = self.r[j * n + col];
                let x1 = self.r[(j + 1) * n + col];
                self.r[j * n + col] = c * x0 + s * x1;
                self.r[(j + 1) * n + col] = -s * x0 + c * x1;
            }
            self.r[(j + 1) * n + j] = 0.0;
            let (lo, hi) = self.q.split_at_mut((j + 1) * n);
            let qj = &mut lo[j * n..j * n + nf];
            let qj1 = &mut hi[..nf];
            for (a0, a1) in qj.iter_mut().zip(qj1.iter_mut()) {
                let (x0, x1) = (*a0, *a1);
                *a0 = c * x0 + s * x1;
                *a1 = -s * x0 + c * x1;
            }
        }
        self.active.remove(k);
        self.lambda_active.remove(k);
    }

    /// Multipliers, objective and (unless solved) the clipped iterate.
    fn finish(&mut self, p: &QpProblem, status: QpStatus) -> QpStatus {
        let n = self.n;
        if status == QpStatus::Solved {
            // The fixed bounds join the reported active set.
            for &i in &self.fixed {
                self.active
                    .push(if self.fix[i] == AT_UPPER { i } else { n + i });
                self.lambda_active.push(self.lam_fixed[i]);
            }
            // At a KKT point, H U + f = −N_A λ_A and a_iᵀU = b_i on A, so
            // ½UᵀHU + fᵀU = ½ fᵀU − ½ Σ_A λ_i b_i (O(n) instead of O(n²)).
            let mut obj = 0.5 * dot(p.f, &self.x);
            for (&id, &lam) in self.active.iter().zip(&self.lambda_active) {
                let lam = lam.max(0.0);
                obj -= 0.5 * lam * rhs(p, n, id);
                if id < n {
                    self.lam_upper[id] = lam;
                } else if id < 2 * n {
                    self.lam_lower[id - n] = lam;
                } else {
                    self.lam_ineq[id - 2 * n] = lam;
                }
            }
            self.objective = obj;
            return status;
        }
        self.active.clear();
        self.lambda_active.clear();
        if status == QpStatus::InvalidDimensions {
            return status;
        }
        for i in 0..n {
            let v = self.x[i];
            let v = if v.is_finite() { v } else { 0.0 };
            let (lo, hi) = (p.lb[i], p.ub[i]);
            self.x[i] = if lo <= hi { v.max(lo).min(hi) } else { v };
        }
        let mut obj = 0.0;
        for i in 0..n {
            obj += self.x[i] * (0.5 * dot(&p.hess[i * n..(i + 1) * n], &self.x) + p.f[i]);
        }
        self.objective = obj;
        status
    }
}
