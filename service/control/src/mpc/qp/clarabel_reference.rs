//! The clarabel reference for the dense QP of [`super`]: the same [`QpProblem`] solved by
//! the interior-point solver clarabel, for tests and benchmarks (it allocates). Compiled
//! for the unit tests and with the crate feature `clarabel`.

use super::QpProblem;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT,
};

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
