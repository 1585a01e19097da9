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
//!   row `i`, and their violations are read off `U` directly.
//! - The rows of `G` are copied at the start of each solve into a compressed (sparse-row)
//!   buffer sized at construction, so the two-nonzero move-bound rows cost two flops each
//!   when violations are checked.
//! - The Cholesky factorization is faer's in-place blocked one on a buffer and scratch
//!   sized at construction (`nalgebra`'s `cholesky()` allocates); at `n = 100` it measured
//!   about 3.5× faster than a straightforward row-oriented in-place Cholesky.
//!
//! ## Real-time use
//!
//! [`DenseQpSolver::new`] allocates every workspace for given `(n, n_ineq)` (and runs
//! faer's one-time kernel initialization); [`DenseQpSolver::solve`] takes only borrowed
//! slices and allocates nothing (checked with a `malloc` uprobe over all the tests of this
//! module: no allocation inside `solve` once a solver exists), and it never panics: the
//! outcome is a [`QpStatus`]. The iteration cap ([`QpSettings::max_iterations`]) bounds
//! its work. [`solve_with_clarabel`] solves the same problem with clarabel (it allocates;
//! for tests and benchmarks).
//!
//! Warm start in the receding horizon: take the previous step's active set
//! ([`DenseQpSolver::active_set_into`]), shift it by one step (`Upper(i)` → `Upper(i − m)`
//! and likewise for the move rows, dropping those that fall off the front), and pass it
//! as [`WarmStart::ActiveSet`]; or pass the shifted previous solution as
//! [`WarmStart::Primal`]. A wrong guess costs iterations, never correctness.
//!
//! ## Cost, measured
//!
//! On the 2-core development VM (shared, no `target-cpu=native`), `n = 100` (`ℓ = 50`,
//! `m = 2`), boxes, 200 move rows and 3 output rows, a sequence of neighbouring problems
//! (`qp_timing_at_n_100_with_active_constraints`, 1000 solves each):
//!
//! | active (iterations cold / warm) | cold p50 / p99 | warm p50 / p99 | clarabel p50 / p99 |
//! | --- | --- | --- | --- |
//! | 8 (8 / 8) | 79 / 115 µs | 74 / 110 µs | 3.5 / 3.9 ms |
//! | 11 (15 / 11) | 116 / 161 µs | 90 / 131 µs | 3.8 / 4.3 ms |
//! | 15 (28 / 16) | 176 / 226 µs | 116 / 160 µs | 4.8 / 6.2 ms |
//! | 66 (134 / 67) | 1.19 / 1.72 ms | 518 / 784 µs | 4.2 / 4.7 ms |
//!
//! About 45 µs of each solve is fixed (the Cholesky factorization, 16 µs; copying and
//! checking `H` and compressing `G`), then 4–9 µs per active-set change, growing with
//! `|A|` (the Gram–Schmidt step is `O(n·|A|)`). With most of the horizon saturated
//! (`|A| ≈ 2n/3`) the dual method makes `O(|A|)` iterations of `O(n·|A|)` each; a method
//! that eliminates the fixed variables (primal active set on the free ones) would be
//! the next step if such horizons are common.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT,
};
use faer::Par;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{self, LltRegularization};

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
    /// From the unconstrained minimizer, choosing the most violated constraint each time.
    Cold,
    /// Constraints in this list (e.g. the previous step's active set shifted by one
    /// horizon step, `m` variables) are added first while they are violated. Invalid ids
    /// are ignored.
    ActiveSet(&'a [ConstraintId]),
    /// The constraints active or violated at this point (e.g. the previous solution
    /// shifted by one horizon step), within `1e-7` relative, are added first. A slice of
    /// the wrong length is ignored.
    Primal(&'a [f64]),
}

/// The dense dual active-set QP solver, with every workspace allocated at construction.
///
/// Not `Clone` (faer's scratch buffer is not); build one per controller.
///
/// ```
/// use service::mpc::qp::{DenseQpSolver, QpProblem, QpSettings, QpStatus, WarmStart};
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
    /// Cholesky factor `L` (column-major, lower triangle).
    l: Vec<f64>,
    /// faer's scratch for the factorization.
    chol_mem: MemBuffer,
    x: Vec<f64>,
    /// Compressed rows of `G`: `row_ptr[j]..row_ptr[j+1]` index `cols`/`vals`.
    row_ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    /// `1 / ‖g_j‖` (zero for a zero row).
    inv_norm: Vec<f64>,
    /// Active constraints (internal ids: `0..n` upper, `n..2n` lower, `2n..` rows).
    active: Vec<usize>,
    lambda_active: Vec<f64>,
    /// Per constraint: `CANDIDATE`, `ACTIVE` or `ABSENT` (infinite bound or zero row).
    state: Vec<u8>,
    priority: Vec<bool>,
    /// `Q` (one orthonormal `n`-vector per active constraint, row-major `n × n`).
    q: Vec<f64>,
    /// `R` (upper triangular, row-major with stride `n`).
    r: Vec<f64>,
    w: Vec<f64>,
    rho: Vec<f64>,
    z: Vec<f64>,
    rv: Vec<f64>,
    rv2: Vec<f64>,
    uv: Vec<f64>,
    lam_lower: Vec<f64>,
    lam_upper: Vec<f64>,
    lam_ineq: Vec<f64>,
    objective: f64,
    iterations: usize,
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

/// Dot product with eight independent accumulators (so that the reduction vectorizes and
/// is not bound by the add latency).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let k = a.len().min(b.len());
    let (a, b) = (&a[..k], &b[..k]);
    let mut acc = [0.0f64; 8];
    let mut ca = a.chunks_exact(8);
    let mut cb = b.chunks_exact(8);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s += x * y;
    }
    s
}

#[inline]
fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

/// Solves `L y = b` in place, `L` lower triangular and column-major (`b` is zero before
/// `start`).
fn forward_solve(l: &[f64], n: usize, b: &mut [f64], start: usize) {
    for j in start..n {
        let col = &l[j * n..(j + 1) * n];
        let yj = b[j] / col[j];
        b[j] = yj;
        if yj != 0.0 {
            axpy(-yj, &col[j + 1..], &mut b[j + 1..]);
        }
    }
}

/// Solves `Lᵀ z = y` in place, `L` lower triangular and column-major.
fn backward_solve(l: &[f64], n: usize, y: &mut [f64]) {
    for i in (0..n).rev() {
        let col = &l[i * n..(i + 1) * n];
        let s = y[i] - dot(&col[i + 1..], &y[i + 1..n]);
        y[i] = s / col[i];
    }
}

/// Factors the column-major `n × n` matrix `a` in place as `L Lᵀ` (lower triangle read and
/// written) with faer's blocked Cholesky on the pre-sized scratch `mem`. Returns `false`
/// if `a` is not numerically positive definite.
fn cholesky_in_place(a: &mut [f64], n: usize, mem: &mut MemBuffer) -> bool {
    let mat = faer::MatMut::from_column_major_slice_mut(a, n, n);
    factor::cholesky_in_place(
        mat,
        LltRegularization::default(),
        Par::Seq,
        MemStack::new(mem),
        Default::default(),
    )
    .is_ok()
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
        let mut solver = Self {
            n,
            n_ineq,
            settings,
            l: vec![0.0; n * n],
            chol_mem: MemBuffer::new(factor::cholesky_in_place_scratch::<f64>(
                n,
                Par::Seq,
                Default::default(),
            )),
            x: vec![0.0; n],
            row_ptr: vec![0; n_ineq + 1],
            cols: vec![0; n_ineq * n],
            vals: vec![0.0; n_ineq * n],
            inv_norm: vec![0.0; n_ineq],
            active: Vec::with_capacity(n),
            lambda_active: Vec::with_capacity(n),
            state: vec![ABSENT; n_con],
            priority: vec![false; n_con],
            q: vec![0.0; n * n],
            r: vec![0.0; n * n],
            w: vec![0.0; n],
            rho: vec![0.0; n],
            z: vec![0.0; n],
            rv: vec![0.0; n],
            rv2: vec![0.0; n],
            uv: vec![0.0; n],
            lam_lower: vec![0.0; n],
            lam_upper: vec![0.0; n],
            lam_ineq: vec![0.0; n_ineq],
            objective: f64::NAN,
            iterations: 0,
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
        self.l.fill(0.0);
        for j in 0..n {
            self.l[j * n + j] = 1.0;
        }
        let _ = cholesky_in_place(&mut self.l, n, &mut self.chol_mem);
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

    /// Active-set changes made by the last solve.
    pub fn iterations(&self) -> usize {
        self.iterations
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

    /// Writes `L⁻¹ a_id` into `self.w`.
    fn load_w(&mut self, id: usize) {
        let n = self.n;
        self.w.fill(0.0);
        let start;
        if id < n {
            self.w[id] = 1.0;
            start = id;
        } else if id < 2 * n {
            self.w[id - n] = -1.0;
            start = id - n;
        } else {
            let j = id - 2 * n;
            let (a, b) = (self.row_ptr[j], self.row_ptr[j + 1]);
            for k in a..b {
                self.w[self.cols[k]] = self.vals[k];
            }
            start = if b > a { self.cols[a] } else { n };
        }
        forward_solve(&self.l, n, &mut self.w, start);
    }

    /// Solves the problem; allocation-free. See [`QpStatus`] for what the iterate means.
    pub fn solve(&mut self, p: &QpProblem, warm: WarmStart) -> QpStatus {
        self.iterations = 0;
        self.objective = f64::NAN;
        self.active.clear();
        self.lambda_active.clear();
        let n = self.n;
        let m = self.n_ineq;
        if p.hess.len() != n * n
            || p.f.len() != n
            || p.lb.len() != n
            || p.ub.len() != n
            || p.g.len() != m * n
            || p.h.len() != m
        {
            self.x.fill(0.0);
            self.clear_multipliers();
            return QpStatus::InvalidDimensions;
        }
        let status = self.run(p, warm);
        self.finish(p, status)
    }

    fn clear_multipliers(&mut self) {
        self.lam_lower.fill(0.0);
        self.lam_upper.fill(0.0);
        self.lam_ineq.fill(0.0);
    }

    fn run(&mut self, p: &QpProblem, warm: WarmStart) -> QpStatus {
        let n = self.n;
        let m = self.n_ineq;
        self.x.fill(0.0);
        self.priority.fill(false);

        // Data checks: NaN anywhere, infinities only where allowed.
        let all_finite = |v: &[f64]| v.iter().fold(true, |ok, x| ok & x.is_finite());
        if !(all_finite(p.hess) && all_finite(p.f) && all_finite(p.g))
            || p.lb.iter().any(|v| v.is_nan() || *v == f64::INFINITY)
            || p.ub.iter().any(|v| v.is_nan() || *v == f64::NEG_INFINITY)
            || p.h.iter().any(|v| v.is_nan() || *v == f64::NEG_INFINITY)
        {
            return QpStatus::NumericalError;
        }

        // Factor H = L Lᵀ: H's row-major upper triangle is, read column-major, the lower
        // triangle that faer factors in place.
        self.l.copy_from_slice(p.hess);
        if !cholesky_in_place(&mut self.l, n, &mut self.chol_mem) {
            return QpStatus::NumericalError;
        }
        // Unconstrained minimizer x = −H⁻¹ f.
        for (xi, fi) in self.x.iter_mut().zip(p.f) {
            *xi = -fi;
        }
        forward_solve(&self.l, n, &mut self.x, 0);
        backward_solve(&self.l, n, &mut self.x);
        if !all_finite(&self.x) {
            return QpStatus::NumericalError;
        }

        // Compressed rows of G.
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
                }
            }
            self.row_ptr[j + 1] = nnz;
            self.inv_norm[j] = if s2 > 0.0 { 1.0 / s2.sqrt() } else { 0.0 };
        }

        // Trivially infeasible data: crossed bounds, zero rows with negative h.
        for i in 0..n {
            if p.lb[i] > p.ub[i] {
                return QpStatus::Infeasible;
            }
        }
        for j in 0..m {
            if self.row_ptr[j + 1] == self.row_ptr[j] && p.h[j] < 0.0 {
                return QpStatus::Infeasible;
            }
        }

        // Which constraints exist.
        for i in 0..n {
            self.state[i] = if p.ub[i].is_finite() {
                CANDIDATE
            } else {
                ABSENT
            };
            self.state[n + i] = if p.lb[i].is_finite() {
                CANDIDATE
            } else {
                ABSENT
            };
        }
        for j in 0..m {
            let present = p.h[j].is_finite() && self.row_ptr[j + 1] > self.row_ptr[j];
            self.state[2 * n + j] = if present { CANDIDATE } else { ABSENT };
        }

        // Warm start: priorities.
        let n_con = 2 * n + m;
        match warm {
            WarmStart::Cold => {}
            WarmStart::ActiveSet(ids) => {
                for &c in ids {
                    if let Some(id) = self.to_internal(c) {
                        self.priority[id] = true;
                    }
                }
            }
            WarmStart::Primal(xg) => {
                if xg.len() == n && xg.iter().all(|v| v.is_finite()) {
                    for id in 0..n_con {
                        if self.state[id] != ABSENT {
                            let s = self.slack(p, id, xg);
                            let b = self.rhs(p, id).abs();
                            let nrm = if id < 2 * n {
                                1.0
                            } else {
                                1.0 / self.inv_norm[id - 2 * n]
                            };
                            if s >= -1e-7 * (nrm + b) {
                                self.priority[id] = true;
                            }
                        }
                    }
                }
            }
        }

        let max_iter = self.settings.max_iterations;
        let tol = self.settings.feasibility_tol;
        loop {
            // Choose the violated constraint: prioritized first, then the most violated.
            let (best, best_v, best_pri) = self.select_violated(p, tol);
            let pid = if best_pri != usize::MAX {
                best_pri
            } else {
                best
            };
            if pid == usize::MAX {
                return QpStatus::Solved;
            }
            if !best_v.is_finite() {
                return QpStatus::NumericalError;
            }
            match self.add_constraint(p, pid, max_iter) {
                Ok(()) => {}
                Err(status) => return status,
            }
        }
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
            if self.priority[id] && v > best_pri_v {
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

    fn rhs(&self, p: &QpProblem, id: usize) -> f64 {
        let n = self.n;
        if id < n {
            p.ub[id]
        } else if id < 2 * n {
            -p.lb[id - n]
        } else {
            p.h[id - 2 * n]
        }
    }

    /// Steps until constraint `pid` is satisfied and added (or the problem is found
    /// infeasible, or the iteration cap is hit).
    fn add_constraint(
        &mut self,
        p: &QpProblem,
        pid: usize,
        max_iter: usize,
    ) -> Result<(), QpStatus> {
        let n = self.n;
        let mut lam_p = 0.0;
        // w = L⁻¹ a_p does not change while p waits for deletions.
        self.load_w(pid);
        let w_norm = dot(&self.w, &self.w).sqrt();
        loop {
            if self.iterations >= max_iter {
                return Err(QpStatus::MaxIterations);
            }
            self.iterations += 1;
            let q = self.active.len();
            // CGS2: r = Qᵀw, ρ = w − Q r, twice.
            self.rho.copy_from_slice(&self.w);
            for k in 0..q {
                let c = dot(&self.q[k * n..(k + 1) * n], &self.w);
                self.rv[k] = c;
            }
            for k in 0..q {
                axpy(-self.rv[k], &self.q[k * n..(k + 1) * n], &mut self.rho);
            }
            // Re-orthogonalize only if the first pass cancelled much of w ("twice is
            // enough": ‖ρ‖² < ½‖w‖²).
            if q > 0 && dot(&self.rho, &self.rho) < 0.5 * w_norm * w_norm {
                for k in 0..q {
                    self.rv2[k] = dot(&self.q[k * n..(k + 1) * n], &self.rho);
                }
                for k in 0..q {
                    axpy(-self.rv2[k], &self.q[k * n..(k + 1) * n], &mut self.rho);
                    self.rv[k] += self.rv2[k];
                }
            }
            // u = R⁻¹ r.
            for i in (0..q).rev() {
                let row = &self.r[i * n..i * n + q];
                let s = self.rv[i] - dot(&row[i + 1..q], &self.uv[i + 1..q]);
                self.uv[i] = s / row[i];
            }
            let rho2 = dot(&self.rho, &self.rho);
            let dependent = q >= n || rho2.sqrt() <= self.settings.dependence_tol * w_norm;
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
            if !(t1.is_finite() || t2.is_finite()) {
                if t1.is_nan() || t2.is_nan() {
                    return Err(QpStatus::NumericalError);
                }
                return Err(QpStatus::Infeasible);
            }
            if !t1.is_nan() && t1 <= t2 {
                // Full step: p becomes satisfied and joins the active set.
                let t = t1.max(0.0);
                self.z.copy_from_slice(&self.rho);
                backward_solve(&self.l, n, &mut self.z);
                axpy(-t, &self.z, &mut self.x);
                for k in 0..q {
                    self.lambda_active[k] -= t * self.uv[k];
                }
                lam_p += t;
                let delta = rho2.sqrt();
                // Q gains ρ/δ, R gains the column [r; δ].
                let (qs, qn) = (q * n, (q + 1) * n);
                for (dst, src) in self.q[qs..qn].iter_mut().zip(&self.rho) {
                    *dst = src / delta;
                }
                for i in 0..q {
                    self.r[i * n + q] = self.rv[i];
                }
                self.r[q * n + q] = delta;
                self.active.push(pid);
                self.lambda_active.push(lam_p);
                self.state[pid] = ACTIVE;
                if !self.x.iter().all(|v| v.is_finite()) {
                    return Err(QpStatus::NumericalError);
                }
                return Ok(());
            }
            // Partial step: the active constraint k_drop leaves.
            let t = t2.max(0.0);
            if !dependent {
                self.z.copy_from_slice(&self.rho);
                backward_solve(&self.l, n, &mut self.z);
                axpy(-t, &self.z, &mut self.x);
            }
            for k in 0..q {
                self.lambda_active[k] -= t * self.uv[k];
            }
            lam_p += t;
            self.drop_active(k_drop);
            if !self.x.iter().all(|v| v.is_finite()) || !lam_p.is_finite() {
                return Err(QpStatus::NumericalError);
            }
        }
    }

    /// Removes the `k`-th active constraint: column `k` of `R` goes, Givens rotations
    /// restore the triangle and rotate `Q` alike.
    fn drop_active(&mut self, k: usize) {
        let n = self.n;
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
            let qj = &mut lo[j * n..];
            let qj1 = &mut hi[..n];
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
        self.clear_multipliers();
        if status == QpStatus::Solved {
            for (&id, &lam) in self.active.iter().zip(&self.lambda_active) {
                let lam = lam.max(0.0);
                if id < n {
                    self.lam_upper[id] = lam;
                } else if id < 2 * n {
                    self.lam_lower[id - n] = lam;
                } else {
                    self.lam_ineq[id - 2 * n] = lam;
                }
            }
        } else {
            for i in 0..n {
                let v = self.x[i];
                let v = if v.is_finite() { v } else { 0.0 };
                let lo = if p.lb[i].is_finite() {
                    p.lb[i]
                } else {
                    f64::NEG_INFINITY
                };
                let hi = if p.ub[i].is_finite() {
                    p.ub[i]
                } else {
                    f64::INFINITY
                };
                self.x[i] = if lo <= hi { v.max(lo).min(hi) } else { v };
            }
        }
        if status == QpStatus::Solved {
            // At a KKT point, H U + f = −N_A λ_A and a_iᵀU = b_i on A, so
            // ½UᵀHU + fᵀU = ½ fᵀU − ½ Σ_A λ_i b_i (O(n) instead of O(n²)).
            let mut obj = 0.5 * dot(p.f, &self.x);
            for (&id, &lam) in self.active.iter().zip(&self.lambda_active) {
                obj -= 0.5 * lam * self.rhs(p, id);
            }
            self.objective = obj;
        } else if p.hess.len() == n * n && p.f.len() == n {
            let mut obj = 0.0;
            for i in 0..n {
                obj += self.x[i] * (0.5 * dot(&p.hess[i * n..(i + 1) * n], &self.x) + p.f[i]);
            }
            self.objective = obj;
        }
        status
    }
}

/// The result of [`solve_with_clarabel`].
#[derive(Clone, Debug)]
pub struct ClarabelSolution {
    /// clarabel's status.
    pub status: SolverStatus,
    /// The primal solution `U`.
    pub x: Vec<f64>,
    /// The objective `½ Uᵀ H U + fᵀ U`.
    pub objective: f64,
    /// Multipliers of the lower bounds (zero where `lb = −∞`).
    pub lambda_lower: Vec<f64>,
    /// Multipliers of the upper bounds (zero where `ub = +∞`).
    pub lambda_upper: Vec<f64>,
    /// Multipliers of the rows of `G U ≤ h` (zero where `h = +∞`).
    pub lambda_ineq: Vec<f64>,
}

/// Solves the same [`QpProblem`] with clarabel (set-up and solve; allocates). The reference
/// for tests and benchmarks: boxes become rows `±e_iᵀ U ≤ ±b` of one nonnegative cone with
/// the rows of `G`, infinite bounds are left out. `tol` sets clarabel's gap and feasibility
/// tolerances (its default is `1e-8`). Returns `None` if the data are malformed (clarabel
/// refuses them).
pub fn solve_with_clarabel(p: &QpProblem, tol: f64) -> Option<ClarabelSolution> {
    let n = p.f.len();
    let m = p.h.len();
    if p.hess.len() != n * n || p.lb.len() != n || p.ub.len() != n || p.g.len() != m * n {
        return None;
    }
    // P: upper triangle of H in CSC.
    let (mut pi, mut pj, mut pv) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..=j {
            let v = 0.5 * (p.hess[i * n + j] + p.hess[j * n + i]);
            if v != 0.0 {
                pi.push(i);
                pj.push(j);
                pv.push(v);
            }
        }
    }
    let pm = CscMatrix::new_from_triplets(n, n, pi, pj, pv);
    // A and b: upper bounds, lower bounds, rows.
    let (mut ai, mut aj, mut av, mut b) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    // (kind, index) for each row of A, to map the multipliers back.
    let mut map = Vec::new();
    for i in 0..n {
        if p.ub[i].is_finite() {
            ai.push(b.len());
            aj.push(i);
            av.push(1.0);
            b.push(p.ub[i]);
            map.push((0u8, i));
        }
    }
    for i in 0..n {
        if p.lb[i].is_finite() {
            ai.push(b.len());
            aj.push(i);
            av.push(-1.0);
            b.push(-p.lb[i]);
            map.push((1u8, i));
        }
    }
    for j in 0..m {
        if p.h[j].is_finite() {
            let r = b.len();
            for c in 0..n {
                let v = p.g[j * n + c];
                if v != 0.0 {
                    ai.push(r);
                    aj.push(c);
                    av.push(v);
                }
            }
            b.push(p.h[j]);
            map.push((2u8, j));
        }
    }
    let rows = b.len();
    let am = CscMatrix::new_from_triplets(rows, n, ai, aj, av);
    let cones: Vec<SupportedConeT<f64>> = if rows > 0 {
        vec![NonnegativeConeT(rows)]
    } else {
        Vec::new()
    };
    let settings = DefaultSettings::<f64> {
        verbose: false,
        tol_gap_abs: tol,
        tol_gap_rel: tol,
        tol_feas: tol,
        tol_ktratio: tol.max(1e-10),
        max_iter: 200,
        ..DefaultSettings::default()
    };
    let mut solver = DefaultSolver::new(&pm, p.f, &am, &b, &cones, settings).ok()?;
    solver.solve();
    let x = solver.solution.x.clone();
    let mut objective = 0.0;
    for i in 0..n {
        let hx: f64 = (0..n).map(|j| p.hess[i * n + j] * x[j]).sum();
        objective += x[i] * (0.5 * hx + p.f[i]);
    }
    let mut lambda_lower = vec![0.0; n];
    let mut lambda_upper = vec![0.0; n];
    let mut lambda_ineq = vec![0.0; m];
    for (k, &(kind, i)) in map.iter().enumerate() {
        let z = solver.solution.z[k];
        match kind {
            0 => lambda_upper[i] = z,
            1 => lambda_lower[i] = z,
            _ => lambda_ineq[i] = z,
        }
    }
    Some(ClarabelSolution {
        status: solver.solution.status,
        x,
        objective,
        lambda_lower,
        lambda_upper,
        lambda_ineq,
    })
}
