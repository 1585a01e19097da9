//! Linear matrix inequalities as clarabel's positive semidefinite cones.
//!
//! A program
//!
//! ```text
//! minimize cᵀ x   subject to   F_l(x) = F_{l,0} + Σ_i x_i F_{l,i} ⪰ 0,   l = 1 … L
//! ```
//!
//! with symmetric `F_{l,i}` is clarabel's `A x + s = b`, `s ∈ K` with one
//! `PSDTriangleConeT(n_l)` per inequality: `s_l = svec(F_l(x))`, so the rows of `b` are
//! `svec(F_{l,0})` and column `i` of `A` is `−svec(F_{l,i})`.
//!
//! `svec` is clarabel's packing of a symmetric `n × n` matrix into `n(n+1)/2` numbers: the
//! upper triangle column by column, `(0,0), (0,1), (1,1), (0,2), (1,2), (2,2), …`, with the
//! off-diagonal entries multiplied by `√2` (so that `svec(X)ᵀ svec(Y) = trace(X Y)`).
//! The tests prove the order and the scaling on small programs with known solutions.
//!
//! [`affine_lmis`] builds the `F_{l,i}` of an affine matrix function from its values at
//! `x = 0` and at the unit vectors, so a caller writes the inequalities once, as matrices.
//!
//! # What a solve guarantees
//!
//! The solver's stopping rule is the whole of what a caller may rely on, so the tolerances
//! are set here explicitly ([`Tolerances::DEFAULT`], clarabel's documented defaults; a
//! change of clarabel's defaults cannot move them). With `p = cᵀ x` and `d` the dual cost,
//! clarabel reports `Solved` when
//!
//! ```text
//! |p − d| < gap_abs   or   |p − d| / max(1, min(|p|, |d|)) < gap_rel,
//! ‖A x + s − b‖₂ < feas · max(1, ‖b‖₂ + ‖x‖₂ + ‖s‖₂),   and the same for the dual residual,
//! ```
//!
//! so the optimal cost is known to within [`Tolerances::cost_accuracy`]
//! `= max(gap_abs, gap_rel · max(1, |p|))` of the returned `p` (up to the residuals, which
//! a caller checks on the returned point itself). `AlmostSolved` means clarabel fell back
//! to its *reduced* tolerances (5·10⁻⁵ on the gap, 10⁻⁴ on feasibility): [`minimize`]
//! accepts it, but [`SdpSolution::full_accuracy`] is then `false` and the bounds above do
//! not hold.
//!
//! # When the first solve stops on numerics
//!
//! Clarabel's PSD cones do their linear algebra through BLAS, and OpenBLAS picks its
//! kernels by the CPU it runs on, so the same program's iterates differ in their last bits
//! from one machine to the next. On a badly scaled program (the robust gain's, whose state
//! is scaled by 100) that decides whether clarabel's Ruiz equilibration leads the
//! iterates into a KKT system it cannot factor (`NumericalError`) or not. [`minimize`]
//! therefore solves in up to [`ATTEMPTS`] settings, in order, and stops at the first that
//! reports `Solved` or `AlmostSolved`: clarabel's defaults, then the same without
//! equilibration, then that with a shorter step (`max_step_fraction` 0.9). Only the
//! numerical stops (`NumericalError`, `InsufficientProgress`, `MaxIterations`) lead to the
//! next attempt; an infeasible program is reported at once. The tolerances and hence the
//! guarantee above are the same in every attempt; [`SdpSolution::status`] names the
//! attempt that solved. CI solves the design programs with OpenBLAS forced to several
//! CPUs' kernels (`OPENBLAS_CORETYPE`).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::DMatrix;

/// A semidefinite program that cannot be set up or solved, naming the inequality at fault
/// or clarabel's status.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SdpError {
    /// An inequality's constant or coefficient count does not fit.
    #[error(
        "inequality {inequality}: F_0 is {rows}×{cols} with {coefficients} coefficients for \
         {variables} variables"
    )]
    Shape {
        /// The inequality, from 0.
        inequality: usize,
        /// Rows of `F_0`.
        rows: usize,
        /// Columns of `F_0`.
        cols: usize,
        /// Its coefficient matrices.
        coefficients: usize,
        /// The variables.
        variables: usize,
    },
    /// A coefficient matrix of the wrong size.
    #[error("inequality {inequality}: F_{index} is not {dim}×{dim}")]
    Coefficient {
        /// The inequality, from 0.
        inequality: usize,
        /// The coefficient, from 1.
        index: usize,
        /// The inequality's size.
        dim: usize,
    },
    /// clarabel refused the settings (its message).
    #[error("clarabel settings: {0}")]
    Settings(String),
    /// clarabel refused the problem (its error, debug form).
    #[error("clarabel rejected the problem: {0}")]
    Rejected(String),
    /// clarabel stopped without a solution in every attempt it was given.
    #[error("clarabel stopped with status {status} after {iterations} iterations")]
    Stopped {
        /// Its status (debug form) in each attempt made, with the attempt's settings.
        status: String,
        /// Its iterations in the last attempt.
        iterations: u32,
    },
}

message_from!(SdpError);

/// One inequality `F(x) = constant + Σ_i x_i coefficients[i] ⪰ 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct Lmi {
    /// `F_0`, symmetric.
    pub constant: DMatrix<f64>,
    /// `F_i`, one per variable, symmetric, of the size of `F_0`.
    pub coefficients: Vec<DMatrix<f64>>,
}

/// The stopping tolerances of the interior-point solve (clarabel's `tol_gap_abs`,
/// `tol_gap_rel` and `tol_feas`; the module docs state the rule they enter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// Absolute duality gap `|p − d|`.
    pub gap_abs: f64,
    /// Duality gap relative to `max(1, min(|p|, |d|))`.
    pub gap_rel: f64,
    /// Primal and dual residuals relative to `max(1, ‖b‖ + ‖x‖ + ‖s‖)` (resp. the dual's).
    pub feas: f64,
}

impl Tolerances {
    /// Clarabel's defaults (0.11): `10⁻⁸` on both gaps and on feasibility. [`minimize`]
    /// uses these.
    pub const DEFAULT: Tolerances = Tolerances {
        gap_abs: 1e-8,
        gap_rel: 1e-8,
        feas: 1e-8,
    };

    /// The same tolerance `tol` on the gaps and feasibility (for measuring how a solution
    /// moves as the solve is tightened).
    pub fn uniform(tol: f64) -> Tolerances {
        Tolerances {
            gap_abs: tol,
            gap_rel: tol,
            feas: tol,
        }
    }

    /// The largest duality gap `|p − d|` a `Solved` solve with cost `p` may stop at:
    /// `max(gap_abs, gap_rel · max(1, |p|))` (the stopping rule is an *or* of the two gaps).
    pub fn cost_accuracy(&self, cost: f64) -> f64 {
        self.gap_abs.max(self.gap_rel * cost.abs().max(1.0))
    }
}

/// A solution of [`minimize`].
#[derive(Debug, Clone, PartialEq)]
pub struct SdpSolution {
    /// The minimizer `x`.
    pub x: Vec<f64>,
    /// The optimal cost `cᵀ x`.
    pub cost: f64,
    /// The dual cost (the gap `|cost − dual_cost|` is below
    /// [`Tolerances::cost_accuracy`] when [`SdpSolution::full_accuracy`]).
    pub dual_cost: f64,
    /// Clarabel's status (`Solved` or `AlmostSolved`), followed by the settings of the
    /// attempt that reached it when that was not the first ([`ATTEMPTS`]).
    pub status: String,
    /// `true` for `Solved` (the tolerances asked for hold), `false` for `AlmostSolved`
    /// (only clarabel's reduced tolerances do).
    pub full_accuracy: bool,
    /// Interior-point iterations.
    pub iterations: u32,
}

/// `svec(M)` of a symmetric matrix (the upper triangle by columns, off-diagonals × √2).
pub fn svec(m: &DMatrix<f64>) -> Vec<f64> {
    let n = m.nrows();
    let mut v = Vec::with_capacity(n * (n + 1) / 2);
    for col in 0..n {
        for row in 0..=col {
            v.push(if row == col {
                m[(row, col)]
            } else {
                std::f64::consts::SQRT_2 * m[(row, col)]
            });
        }
    }
    v
}

/// The symmetric `n × n` matrix of a packed `svec`.
pub fn smat(v: &[f64], n: usize) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(n, n);
    let mut idx = 0;
    for col in 0..n {
        for row in 0..=col {
            if row == col {
                m[(row, col)] = v[idx];
            } else {
                let x = v[idx] / std::f64::consts::SQRT_2;
                m[(row, col)] = x;
                m[(col, row)] = x;
            }
            idx += 1;
        }
    }
    m
}

/// The inequalities of an affine map `x ↦ [F_1(x), …, F_L(x)]` of `n` variables, from its
/// values at `0` and at the unit vectors.
pub fn affine_lmis(n: usize, f: impl Fn(&[f64]) -> Vec<DMatrix<f64>>) -> Vec<Lmi> {
    let f0 = f(&vec![0.0; n]);
    let fi: Vec<Vec<DMatrix<f64>>> = (0..n)
        .map(|i| {
            let mut e = vec![0.0; n];
            e[i] = 1.0;
            f(&e)
        })
        .collect();
    f0.iter()
        .enumerate()
        .map(|(l, c)| Lmi {
            constant: c.clone(),
            coefficients: fi.iter().map(|v| &v[l] - c).collect(),
        })
        .collect()
}

/// Minimizes `cᵀ x` subject to `lmis` with clarabel's interior-point method at
/// [`Tolerances::DEFAULT`]. `Err` when an inequality is malformed or the solver does not
/// report `Solved`/`AlmostSolved`.
pub fn minimize(c: &[f64], lmis: &[Lmi]) -> Result<SdpSolution, SdpError> {
    minimize_with(c, lmis, &Tolerances::DEFAULT)
}

/// [`minimize`] with the stopping tolerances `tol`.
pub fn minimize_with(c: &[f64], lmis: &[Lmi], tol: &Tolerances) -> Result<SdpSolution, SdpError> {
    minimize_in(c, lmis, tol, &ATTEMPTS)
}

/// [`minimize_with`] trying the settings `attempts` in order.
fn minimize_in(
    c: &[f64],
    lmis: &[Lmi],
    tol: &Tolerances,
    attempts: &[Attempt],
) -> Result<SdpSolution, SdpError> {
    let n = c.len();
    let mut b = Vec::new();
    let mut columns: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    let mut cones = Vec::with_capacity(lmis.len());
    for (l, lmi) in lmis.iter().enumerate() {
        let dim = lmi.constant.nrows();
        if lmi.constant.ncols() != dim || lmi.coefficients.len() != n {
            return Err(SdpError::Shape {
                inequality: l,
                rows: dim,
                cols: lmi.constant.ncols(),
                coefficients: lmi.coefficients.len(),
                variables: n,
            });
        }
        let row0 = b.len();
        b.extend(svec(&lmi.constant));
        for (i, fi) in lmi.coefficients.iter().enumerate() {
            if fi.shape() != (dim, dim) {
                return Err(SdpError::Coefficient {
                    inequality: l,
                    index: i + 1,
                    dim,
                });
            }
            for (r, v) in svec(fi).into_iter().enumerate() {
                if v != 0.0 {
                    columns[i].push((row0 + r, -v));
                }
            }
        }
        cones.push(SupportedConeT::PSDTriangleConeT(dim));
    }
    let m = b.len();
    let mut colptr = Vec::with_capacity(n + 1);
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    colptr.push(0);
    for col in &columns {
        for &(r, v) in col {
            rowval.push(r);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(m, n, colptr, rowval, nzval);
    let p = CscMatrix::zeros((n, n));
    let mut stops = Vec::new();
    let mut iterations = 0;
    for attempt in attempts {
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .tol_gap_abs(tol.gap_abs)
            .tol_gap_rel(tol.gap_rel)
            .tol_feas(tol.feas)
            .equilibrate_enable(attempt.equilibrate)
            .max_step_fraction(attempt.max_step_fraction)
            .build()
            .map_err(|e| SdpError::Settings(e.to_string()))?;
        let mut solver = DefaultSolver::new(&p, c, &a, &b, &cones, settings)
            .map_err(|e| SdpError::Rejected(format!("{e:?}")))?;
        solver.solve();
        let status = solver.solution.status;
        iterations = solver.solution.iterations;
        match status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                let status = if stops.is_empty() {
                    format!("{status:?}")
                } else {
                    format!(
                        "{status:?} ({}; before: {})",
                        attempt.name,
                        stops.join(", ")
                    )
                };
                return Ok(SdpSolution {
                    x: solver.solution.x.clone(),
                    cost: solver.solution.obj_val,
                    dual_cost: solver.solution.obj_val_dual,
                    status,
                    full_accuracy: solver.solution.status == SolverStatus::Solved,
                    iterations,
                });
            }
            SolverStatus::NumericalError
            | SolverStatus::InsufficientProgress
            | SolverStatus::MaxIterations => {
                stops.push(format!("{status:?} with {}", attempt.name));
            }
            other => {
                stops.push(format!("{other:?} with {}", attempt.name));
                break;
            }
        }
    }
    Err(SdpError::Stopped {
        status: stops.join(", then "),
        iterations,
    })
}

/// One set of solver settings [`minimize`] may solve in (the module docs say when the next
/// is tried).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attempt {
    /// What it changes from clarabel's defaults, for the solution's status.
    pub name: &'static str,
    /// Clarabel's `equilibrate_enable` (Ruiz scaling of the KKT data).
    pub equilibrate: bool,
    /// Clarabel's `max_step_fraction` (of the step to the cone's boundary).
    pub max_step_fraction: f64,
}

/// The settings [`minimize`] tries, in order.
pub const ATTEMPTS: [Attempt; 3] = [
    Attempt {
        name: "clarabel's defaults",
        equilibrate: true,
        max_step_fraction: 0.99,
    },
    Attempt {
        name: "without equilibration",
        equilibrate: false,
        max_step_fraction: 0.99,
    },
    Attempt {
        name: "without equilibration, step fraction 0.9",
        equilibrate: false,
        max_step_fraction: 0.9,
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    fn sym(rows: &[&[f64]]) -> DMatrix<f64> {
        let n = rows.len();
        DMatrix::from_fn(n, n, |i, j| rows[i][j])
    }

    #[test]
    fn svec_follows_the_upper_triangle_by_columns_with_root_two() {
        let m = sym(&[&[1.0, 2.0, 4.0], &[2.0, 3.0, 5.0], &[4.0, 5.0, 6.0]]);
        let r2 = std::f64::consts::SQRT_2;
        assert_eq!(svec(&m), vec![1.0, 2.0 * r2, 3.0, 4.0 * r2, 5.0 * r2, 6.0]);
        assert!((smat(&svec(&m), 3) - &m).abs().max() < 1e-15);
        // The inner product of svecs is the trace inner product.
        let k = sym(&[&[0.5, -1.0, 2.0], &[-1.0, 4.0, 0.0], &[2.0, 0.0, -3.0]]);
        let dot: f64 = svec(&m).iter().zip(svec(&k)).map(|(a, b)| a * b).sum();
        assert!((dot - (&m * &k).trace()).abs() < 1e-12);
    }

    /// `X` as six variables in svec order without the √2 (plain entries).
    fn sym_of(x: &[f64]) -> DMatrix<f64> {
        sym(&[
            &[x[0], x[1], x[3]],
            &[x[1], x[2], x[4]],
            &[x[3], x[4], x[5]],
        ])
    }

    #[test]
    fn min_trace_above_a_known_matrix_returns_that_matrix() {
        // minimize trace X subject to X − M ⪰ 0: the unique optimum is X = M (X − M ⪰ 0
        // with zero trace is 0). A wrong order or scale of the packing moves it.
        let m = sym(&[&[2.0, 0.7, -0.4], &[0.7, 1.5, 0.3], &[-0.4, 0.3, 1.0]]);
        let mm = m.clone();
        let lmis = affine_lmis(6, move |x| vec![sym_of(x) - &mm]);
        let c = [1.0, 0.0, 1.0, 0.0, 0.0, 1.0];
        let sol = minimize(&c, &lmis).unwrap();
        assert!((sym_of(&sol.x) - &m).abs().max() < 1e-6, "{:?}", sol.x);
        assert!((sol.cost - m.trace()).abs() < 1e-6);
    }

    #[test]
    fn the_smallest_bound_on_a_matrix_is_its_largest_eigenvalue() {
        // minimize t subject to t I − M ⪰ 0 (constant off-diagonals in b).
        let m = sym(&[&[1.0, 0.0, 2.0], &[0.0, -1.0, 0.5], &[2.0, 0.5, 3.0]]);
        let mm = m.clone();
        let lmis = affine_lmis(1, move |x| vec![DMatrix::identity(3, 3) * x[0] - &mm]);
        let sol = minimize(&[1.0], &lmis).unwrap();
        let want = m.symmetric_eigenvalues().max();
        assert!((sol.x[0] - want).abs() < 1e-6, "{} vs {want}", sol.x[0]);
    }

    #[test]
    fn a_schur_complement_gives_the_bound_of_a_two_by_two() {
        // minimize x subject to [[x, 1], [1, 2]] ⪰ 0: x = 1/2.
        let lmis = affine_lmis(1, |x| vec![sym(&[&[x[0], 1.0], &[1.0, 2.0]])]);
        let sol = minimize(&[1.0], &lmis).unwrap();
        assert!((sol.x[0] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn an_infeasible_program_is_an_error() {
        // −1 − x² ... as an LMI: [[−1, 0], [0, x]] ⪰ 0 has no solution.
        let lmis = affine_lmis(1, |x| vec![sym(&[&[-1.0, 0.0], &[0.0, x[0]]])]);
        let e = minimize(&[1.0], &lmis).unwrap_err().to_string();
        assert!(e.contains("Infeasible"), "{e}");
        // Infeasibility is the program's, not the numerics': no second attempt.
        assert!(!e.contains("then"), "{e}");
    }

    #[test]
    fn a_numerical_stop_leads_to_the_next_attempt_and_the_status_names_it() {
        // min x subject to [[x, 1], [1, 1]] ⪰ 0: x = 1. A step fraction of 10⁻³ cannot reach
        // it in clarabel's 200 iterations, so the first attempt stops on MaxIterations.
        let lmis = affine_lmis(1, |x| vec![sym(&[&[x[0], 1.0], &[1.0, 1.0]])]);
        let crawl = Attempt {
            name: "a crawl",
            equilibrate: true,
            max_step_fraction: 1e-3,
        };
        let sol = minimize_in(&[1.0], &lmis, &Tolerances::DEFAULT, &[crawl, ATTEMPTS[1]]).unwrap();
        assert!((sol.x[0] - 1.0).abs() < 1e-6, "{:?}", sol.x);
        assert!(sol.full_accuracy);
        assert_eq!(
            sol.status,
            "Solved (without equilibration; before: MaxIterations with a crawl)"
        );
        let e = minimize_in(&[1.0], &lmis, &Tolerances::DEFAULT, &[crawl, crawl])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("MaxIterations with a crawl, then MaxIterations with a crawl"),
            "{e}"
        );
        // The ladder's first attempt is clarabel's defaults, and it solves this at once.
        assert_eq!(minimize(&[1.0], &lmis).unwrap().status, "Solved");
    }
}
