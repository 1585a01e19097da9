//! OSQP as a second anchor beside clarabel: the dense QP of `control::mpc::qp`,
//!
//! ```text
//! min ½ UᵀHU + fᵀU   s.t.   lb ≤ U ≤ ub,   G U ≤ h,
//! ```
//!
//! mapped onto OSQP's form `min ½ xᵀPx + qᵀx  s.t.  l ≤ A x ≤ u` as
//!
//! ```text
//! P = triu(H)  (upper triangle, CSC),   q = f,
//! A = [ I ]    l = [ lb ]    u = [ ub ]
//!     [ G ]        [ −∞ ]        [ h  ]
//! ```
//!
//! with every infinite bound (`lb = −∞`, `ub = +∞`, a row disabled by `h = +∞`) clamped
//! to OSQP's own infinity [`OSQP_INFINITY`], which OSQP treats as no bound. `H` is
//! symmetrized (`½ (H + Hᵀ)`) as the dense solver and clarabel read it.
//!
//! **Set-up once, update each step.** A PCAC workload solves QPs of one size whose
//! sparsity is fixed by the condensing (`H` dense, `G` the move-bound differences), while
//! every value changes from step to step: `H` with the identified Markov parameters, `f`
//! with the free response, the move bounds' `h` with `u_{k−1}`. So [`OsqpAnchor`] sets
//! OSQP up (allocation, scaling, symbolic and numeric factorization of its KKT matrix) at
//! its first problem, with `P` the whole upper triangle and `A` the nonzero pattern of
//! that problem's `[I; G]`, and afterwards only writes the new values into that pattern
//! (`osqp_update_P_A`, which refactors numerically; `osqp_update_lin_cost`,
//! `osqp_update_bounds`) — what an OSQP user does for a parametric QP. A later problem of
//! another size, or with a nonzero of `G` outside the pattern, is set up anew, on the
//! union of the patterns seen ([`OsqpAnchor::setups`] counts these).
//!
//! **Warm start.** Before each solve after the first, OSQP starts from the previous
//! solution `(x, y)` as it stands (unshifted: shifting the horizon is the dense solver's
//! own trick for its active set, and a plain OSQP user keeps the last iterate). The call
//! is explicit (`osqp_warm_start`) because the update of `P` and `A` rescales the data.
//!
//! **Settings.** `eps_abs = eps_rel = tol`, polishing on (after ADMM has guessed the
//! active set, OSQP solves the KKT system of that guess, which gives a solution as
//! accurate as an active-set solver's when the guess is right) with its regularization
//! δ = [`POLISH_DELTA`] and [`POLISH_REFINE`] refinement steps, a fixed rho-adaptation
//! interval of [`RHO_INTERVAL`] iterations (OSQP's default picks the interval from the
//! measured set-up time, which would make iteration counts depend on the machine), and
//! at most [`MAX_ITER`] ADMM iterations. Everything else is OSQP's default. The polishing
//! settings are not OSQP's defaults (δ = 10⁻⁶, 3 steps) because with those, polishing
//! failed on most PCAC QPs (their Hessians are badly scaled: `Q = 10⁶` on millimetres,
//! `|J|` up to 10¹³): on 400 QPs of the arm workload at tolerance 10⁻⁸, 33 polished
//! with the defaults, 396 with these; unpolished points violated the move bounds by up to
//! 10⁻⁶.
//!
//! OSQP allocates at set-up and is called through C; it runs in the bench and in tests
//! only, never in the service's step.

use control::mpc::qp::QpProblem;
use osqp::{CscMatrix, PolishStatus, Problem, Settings, Status};
use std::borrow::Cow;

/// OSQP's infinity (`OSQP_INFTY` of OSQP 0.6's `constants.h`): a bound at or beyond it
/// is no bound.
pub const OSQP_INFINITY: f64 = 1e30;

/// Iterations between two adaptations of OSQP's step size ρ (module docs).
pub const RHO_INTERVAL: u32 = 25;

/// The regularization δ of OSQP's polishing (OSQP's default: 10⁻⁶; see the module docs).
pub const POLISH_DELTA: f64 = 1e-9;

/// Iterative-refinement steps of OSQP's polishing (OSQP's default: 3).
pub const POLISH_REFINE: u32 = 20;

/// OSQP's cap on ADMM iterations per solve.
pub const MAX_ITER: u32 = 20_000;

/// How an OSQP solve ended, OSQP's status reduced to what the comparison needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OsqpStatus {
    /// Solved to the tolerances.
    Solved,
    /// Solved, but only to OSQP's looser "inaccurate" tolerances.
    SolvedInaccurate,
    /// The iteration cap [`MAX_ITER`] was reached first.
    MaxIterations,
    /// OSQP found the problem primal infeasible (possibly inaccurately).
    PrimalInfeasible,
    /// OSQP found the problem dual infeasible, i.e. unbounded (possibly inaccurately).
    DualInfeasible,
    /// Any other end (time limit, non-convex).
    Other,
}

/// Why [`OsqpAnchor::solve`] could not run OSQP.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OsqpAnchorError {
    /// The problem's slices do not have consistent lengths.
    Dimensions,
    /// OSQP refused the set-up (its reason).
    Setup(String),
}

impl std::fmt::Display for OsqpAnchorError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Dimensions => write!(f, "the QP's slices have inconsistent lengths"),
            Self::Setup(e) => write!(f, "OSQP set-up failed: {e}"),
        }
    }
}

impl std::error::Error for OsqpAnchorError {}

/// The outcome of one [`OsqpAnchor::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OsqpOutcome {
    /// How the solve ended.
    pub status: OsqpStatus,
    /// ADMM iterations.
    pub iterations: u32,
    /// Polishing succeeded (the solution is that of the guessed active set's KKT system).
    pub polished: bool,
    /// This solve set OSQP up (first problem, new size or new sparsity) instead of updating.
    pub set_up: bool,
}

/// A compressed-sparse-column pattern with its values, owned so that updates overwrite
/// the values in place.
struct Csc {
    m: CscMatrix<'static>,
}

impl Csc {
    fn new(nrows: usize, ncols: usize, indptr: Vec<usize>, indices: Vec<usize>) -> Self {
        let nnz = indices.len();
        Self {
            m: CscMatrix {
                nrows,
                ncols,
                indptr: Cow::Owned(indptr),
                indices: Cow::Owned(indices),
                data: Cow::Owned(vec![0.0; nnz]),
            },
        }
    }
}

/// OSQP on a stream of [`QpProblem`]s of one size: set up at the first, updated and
/// warm-started after (module docs).
///
/// ```
/// use control::mpc::qp::QpProblem;
/// use latency_bench::osqp_anchor::{OsqpAnchor, OsqpStatus};
///
/// // min ½(u₁² + u₂²) − u₁ − u₂  s.t.  u ≤ 0.25 (both), u₁ + u₂ ≤ 0.4
/// let (hess, f) = ([1.0, 0.0, 0.0, 1.0], [-1.0, -1.0]);
/// let (lb, ub) = ([f64::NEG_INFINITY; 2], [0.25; 2]);
/// let (g, h) = ([1.0, 1.0], [0.4]);
/// let p = QpProblem { hess: &hess, f: &f, lb: &lb, ub: &ub, g: &g, h: &h };
/// let mut osqp = OsqpAnchor::new(1e-9);
/// let out = osqp.solve(&p).unwrap();
/// assert_eq!(out.status, OsqpStatus::Solved);
/// assert!((osqp.x()[0] - 0.2).abs() < 1e-8 && (osqp.x()[1] - 0.2).abs() < 1e-8);
/// ```
pub struct OsqpAnchor {
    settings: Settings,
    problem: Option<Problem>,
    n: usize,
    n_ineq: usize,
    p: Csc,
    a: Csc,
    q: Vec<f64>,
    l: Vec<f64>,
    u: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    warm: bool,
    setups: u64,
    /// The entries of `G` in the pattern of `A` (`m × n`, row-major).
    g_mask: Vec<bool>,
}

impl OsqpAnchor {
    /// An anchor with OSQP's `eps_abs = eps_rel = tol` and the other settings of the
    /// module docs. Nothing is set up before the first [`OsqpAnchor::solve`].
    pub fn new(tol: f64) -> Self {
        let settings = Settings::default()
            .verbose(false)
            .eps_abs(tol)
            .eps_rel(tol)
            .polish(true)
            .delta(POLISH_DELTA)
            .polish_refine_iter(POLISH_REFINE)
            .adaptive_rho_interval(Some(RHO_INTERVAL))
            .max_iter(MAX_ITER)
            .warm_start(true);
        Self {
            settings,
            problem: None,
            n: 0,
            n_ineq: 0,
            p: Csc::new(0, 0, vec![0], Vec::new()),
            a: Csc::new(0, 0, vec![0], Vec::new()),
            q: Vec::new(),
            l: Vec::new(),
            u: Vec::new(),
            x: Vec::new(),
            y: Vec::new(),
            warm: false,
            setups: 0,
            g_mask: Vec::new(),
        }
    }

    /// Solves `p`: set-up at the first problem (or at a new size or sparsity), else an
    /// update of the values and a warm start from the previous solution (module docs).
    /// After a solve that produced a point (any status but the infeasibility ones),
    /// [`Self::x`] is it.
    pub fn solve(&mut self, p: &QpProblem) -> Result<OsqpOutcome, OsqpAnchorError> {
        let n = p.f.len();
        let m = p.h.len();
        if p.hess.len() != n * n || p.lb.len() != n || p.ub.len() != n || p.g.len() != m * n {
            return Err(OsqpAnchorError::Dimensions);
        }
        let reuse = self.problem.is_some()
            && self.n == n
            && self.n_ineq == m
            && self.fill_p(p)
            && self.fill_a(p);
        self.fill_vectors(p);
        if !reuse {
            self.set_up(p)?;
        }
        let problem = self.problem.as_mut().expect("set up above");
        if reuse {
            problem.update_P_A(&self.p.m, &self.a.m);
            problem.update_lin_cost(&self.q);
            problem.update_bounds(&self.l, &self.u);
            if self.warm {
                problem.warm_start(&self.x, &self.y);
            }
        }
        let status = problem.solve();
        let iterations = status.iter();
        let (code, solution) = match &status {
            Status::Solved(s) => (OsqpStatus::Solved, Some(s)),
            Status::SolvedInaccurate(s) => (OsqpStatus::SolvedInaccurate, Some(s)),
            Status::MaxIterationsReached(s) => (OsqpStatus::MaxIterations, Some(s)),
            Status::TimeLimitReached(s) => (OsqpStatus::Other, Some(s)),
            Status::PrimalInfeasible(_) | Status::PrimalInfeasibleInaccurate(_) => {
                (OsqpStatus::PrimalInfeasible, None)
            }
            Status::DualInfeasible(_) | Status::DualInfeasibleInaccurate(_) => {
                (OsqpStatus::DualInfeasible, None)
            }
            _ => (OsqpStatus::Other, None),
        };
        let polished = solution.is_some_and(|s| s.polish_status() == PolishStatus::Successful);
        match solution {
            Some(s) => {
                self.x.copy_from_slice(s.x());
                self.y.copy_from_slice(s.y());
                self.warm = true;
            }
            None => self.warm = false,
        }
        Ok(OsqpOutcome {
            status: code,
            iterations,
            polished,
            set_up: !reuse,
        })
    }

    /// The last solution's `U` (zeros before the first solve that produced a point).
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// The last solution's multipliers, one per row of `A = [I; G]` (OSQP's sign
    /// convention: positive at an active upper bound, negative at an active lower one).
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// How many solves set OSQP up rather than updating it.
    pub fn setups(&self) -> u64 {
        self.setups
    }

    /// OSQP's set-up on the nonzero pattern of `p` (the diagonal of `P` always kept).
    fn set_up(&mut self, p: &QpProblem) -> Result<(), OsqpAnchorError> {
        let n = p.f.len();
        let m = p.h.len();
        self.problem = None;
        // P: the whole upper triangle (the condensed H is dense; a zero is incidental).
        let (mut ptr, mut idx) = (vec![0], Vec::new());
        for j in 0..n {
            idx.extend(0..=j);
            ptr.push(idx.len());
        }
        self.p = Csc::new(n, n, ptr, idx);
        // A: column j holds row j of I and the rows n + r with G_rj ≠ 0 now or in an
        // earlier problem of this size (so that the pattern settles).
        if self.g_mask.len() != m * n {
            self.g_mask = vec![false; m * n];
        }
        for (k, g) in p.g.iter().enumerate() {
            self.g_mask[k] |= *g != 0.0;
        }
        let (mut ptr, mut idx) = (vec![0], Vec::new());
        for j in 0..n {
            idx.push(j);
            for r in 0..m {
                if self.g_mask[r * n + j] {
                    idx.push(n + r);
                }
            }
            ptr.push(idx.len());
        }
        self.a = Csc::new(n + m, n, ptr, idx);
        let filled = self.fill_p(p) && self.fill_a(p);
        debug_assert!(filled, "the pattern is the problem's");
        self.n = n;
        self.n_ineq = m;
        self.x = vec![0.0; n];
        self.y = vec![0.0; n + m];
        self.warm = false;
        let problem = Problem::new(
            &self.p.m,
            &self.q,
            &self.a.m,
            &self.l,
            &self.u,
            &self.settings,
        )
        .map_err(|e| OsqpAnchorError::Setup(e.to_string()))?;
        self.problem = Some(problem);
        self.setups += 1;
        Ok(())
    }

    /// Writes `triu(½(H + Hᵀ))` into the pattern of `P`; `false` if a nonzero falls
    /// outside it.
    fn fill_p(&mut self, p: &QpProblem) -> bool {
        let n = self.p.m.ncols;
        let (ptr, idx) = (&self.p.m.indptr, &self.p.m.indices);
        let data = self.p.m.data.to_mut();
        for j in 0..n {
            let mut k = ptr[j];
            for i in 0..=j {
                let v = sym(p.hess, n, i, j);
                if k < ptr[j + 1] && idx[k] == i {
                    data[k] = v;
                    k += 1;
                } else if v != 0.0 {
                    return false;
                }
            }
        }
        true
    }

    /// Writes `[I; G]` into the pattern of `A`; `false` if a nonzero of `G` falls outside
    /// it.
    fn fill_a(&mut self, p: &QpProblem) -> bool {
        let n = self.a.m.ncols;
        let m = self.a.m.nrows - n;
        let (ptr, idx) = (&self.a.m.indptr, &self.a.m.indices);
        let data = self.a.m.data.to_mut();
        for j in 0..n {
            let mut k = ptr[j];
            data[k] = 1.0;
            k += 1;
            for r in 0..m {
                let v = p.g[r * n + j];
                if k < ptr[j + 1] && idx[k] == n + r {
                    data[k] = v;
                    k += 1;
                } else if v != 0.0 {
                    return false;
                }
            }
        }
        true
    }

    /// `q = f`, `l = [lb; −∞]`, `u = [ub; h]`, infinities clamped to [`OSQP_INFINITY`].
    fn fill_vectors(&mut self, p: &QpProblem) {
        let clamp = |v: f64| v.clamp(-OSQP_INFINITY, OSQP_INFINITY);
        self.q.clear();
        self.q.extend_from_slice(p.f);
        self.l.clear();
        self.l.extend(p.lb.iter().map(|&v| clamp(v)));
        self.l.extend(p.h.iter().map(|_| -OSQP_INFINITY));
        self.u.clear();
        self.u.extend(p.ub.iter().chain(p.h).map(|&v| clamp(v)));
    }
}

/// `½ (H_ij + H_ji)` of the row-major `n × n` matrix `h`.
fn sym(h: &[f64], n: usize, i: usize, j: usize) -> f64 {
    0.5 * (h[i * n + j] + h[j * n + i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use control::mpc::qp::{DenseQpSolver, QpData, QpSettings, QpStatus, WarmStart};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// OSQP at 1e-9 with polishing against the dense solver.
    const TOL: f64 = 1e-9;

    /// Solves `p` with the dense solver (cold) and returns its `U`.
    fn dense(p: &QpProblem) -> Vec<f64> {
        let mut s = DenseQpSolver::new(p.f.len(), p.h.len(), QpSettings::default());
        assert_eq!(s.solve(p, WarmStart::Cold), QpStatus::Solved);
        s.x().to_vec()
    }

    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// A random strictly convex QP of size `n` with `m` rows, whose unconstrained
    /// minimizer lies well outside the box and the rows, so that some bounds and rows are
    /// active; one upper bound and one row are disabled (`+∞`) and one lower bound is
    /// `−∞`.
    fn random_qp(rng: &mut ChaCha8Rng, n: usize, m: usize) -> QpData {
        let l: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut hess = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                let s: f64 = (0..n).map(|k| l[i * n + k] * l[j * n + k]).sum();
                hess[i * n + j] = s + if i == j { 0.5 } else { 0.0 };
            }
        }
        let f = (0..n).map(|_| rng.random_range(-20.0..20.0)).collect();
        let mut lb = vec![-1.0; n];
        let mut ub = vec![1.0; n];
        lb[0] = f64::NEG_INFINITY;
        ub[n - 1] = f64::INFINITY;
        let g = (0..m * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut h: Vec<f64> = (0..m).map(|_| rng.random_range(0.1..1.0)).collect();
        h[m - 1] = f64::INFINITY;
        QpData {
            hess,
            f,
            lb,
            ub,
            g,
            h,
        }
    }

    /// The number of bounds and rows active at `x` (within `1e-7`).
    fn active(p: &QpProblem, x: &[f64]) -> (usize, usize) {
        let n = x.len();
        let bounds = x
            .iter()
            .zip(p.lb.iter().zip(p.ub))
            .filter(|(v, (l, u))| (*v - *l).abs() < 1e-7 || (*v - *u).abs() < 1e-7)
            .count();
        let rows =
            p.g.chunks(n)
                .zip(p.h)
                .filter(|(row, h)| {
                    let gx: f64 = row.iter().zip(x).map(|(a, b)| a * b).sum();
                    (gx - *h).abs() < 1e-7
                })
                .count();
        (bounds, rows)
    }

    #[test]
    fn osqp_and_the_dense_solver_agree_on_small_qps_with_active_bounds_and_rows() {
        let mut rng = ChaCha8Rng::seed_from_u64(30);
        let (mut any_bound, mut any_row) = (false, false);
        for case in 0..40 {
            let (n, m) = (2 + case % 7, 1 + case % 4);
            let qp = random_qp(&mut rng, n, m);
            let p = qp.problem();
            let ours = dense(&p);
            let mut osqp = OsqpAnchor::new(TOL);
            let out = osqp.solve(&p).unwrap();
            assert_eq!(out.status, OsqpStatus::Solved, "case {case}");
            assert!(out.set_up);
            let d = max_diff(osqp.x(), &ours);
            assert!(d < 1e-6, "case {case}: OSQP differs by {d:e}");
            let (b, r) = active(&p, &ours);
            any_bound |= b > 0;
            any_row |= r > 0;
        }
        assert!(
            any_bound && any_row,
            "the cases must activate bounds and rows"
        );
    }

    #[test]
    fn infinite_bounds_and_disabled_rows_become_osqp_infinity() {
        let qp = random_qp(&mut ChaCha8Rng::seed_from_u64(1), 3, 2);
        let mut osqp = OsqpAnchor::new(TOL);
        osqp.fill_vectors(&qp.problem());
        assert_eq!(
            osqp.l,
            [-OSQP_INFINITY, -1.0, -1.0, -OSQP_INFINITY, -OSQP_INFINITY]
        );
        assert_eq!(osqp.u, [1.0, 1.0, OSQP_INFINITY, qp.h[0], OSQP_INFINITY]);
    }

    #[test]
    fn a_second_problem_of_the_same_pattern_is_updated_not_set_up_again() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut qp = random_qp(&mut rng, 5, 3);
        let mut osqp = OsqpAnchor::new(TOL);
        assert!(osqp.solve(&qp.problem()).unwrap().set_up);
        // New values on the same (dense) pattern: updated, warm-started, still exact.
        for v in qp.f.iter_mut() {
            *v = -*v;
        }
        for v in qp.hess.iter_mut() {
            *v *= 1.5;
        }
        qp.h[0] = 0.05;
        let out = osqp.solve(&qp.problem()).unwrap();
        assert!(!out.set_up);
        assert_eq!(out.status, OsqpStatus::Solved);
        assert!(max_diff(osqp.x(), &dense(&qp.problem())) < 1e-6);
        // A nonzero of the pattern that becomes zero stays in it (an explicit zero).
        qp.g[0] = 0.0;
        assert!(!osqp.solve(&qp.problem()).unwrap().set_up);
        assert!(max_diff(osqp.x(), &dense(&qp.problem())) < 1e-6);
        // Set up on that problem, a zero that becomes nonzero leaves the pattern: set up
        // again.
        let mut fresh = OsqpAnchor::new(TOL);
        assert!(fresh.solve(&qp.problem()).unwrap().set_up);
        qp.g[0] = 0.3;
        let out = fresh.solve(&qp.problem()).unwrap();
        assert!(out.set_up);
        assert_eq!(fresh.setups(), 2);
        assert_eq!(out.status, OsqpStatus::Solved);
        assert!(max_diff(fresh.x(), &dense(&qp.problem())) < 1e-6);
    }

    #[test]
    fn inconsistent_slices_are_refused() {
        let qp = random_qp(&mut ChaCha8Rng::seed_from_u64(2), 3, 2);
        let mut p = qp.problem();
        p.g = &qp.g[..5];
        assert_eq!(
            OsqpAnchor::new(TOL).solve(&p).unwrap_err(),
            OsqpAnchorError::Dimensions
        );
    }
}
