//! Tests of the dense QP solver against clarabel and the KKT conditions.

use super::*;
use crate::linalg::percentile;
use clarabel::solver::SolverStatus;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// An owned QP of `n` variables (its vectors reached through `Deref`).
#[derive(Clone, Debug)]
struct Owned {
    n: usize,
    qp: QpData,
}

impl std::ops::Deref for Owned {
    type Target = QpData;
    fn deref(&self) -> &QpData {
        &self.qp
    }
}

impl std::ops::DerefMut for Owned {
    fn deref_mut(&mut self) -> &mut QpData {
        &mut self.qp
    }
}

impl Owned {
    fn n_ineq(&self) -> usize {
        self.h.len()
    }
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

/// `H = L Lᵀ / n + ε I` with a random `L`.
fn random_spd(n: usize, eps: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let l: Vec<f64> = (0..n * n).map(|_| normal(rng)).collect();
    let mut h = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let s: f64 = (0..n).map(|k| l[i * n + k] * l[j * n + k]).sum();
            h[i * n + j] = s / n as f64 + if i == j { eps } else { 0.0 };
        }
    }
    h
}

/// Move-bound rows (2.51) for `ℓ` steps of `m` inputs: `ΔU_min ≤ D U − c ≤ ΔU_max` as
/// `[D; −D] U ≤ [ΔU_max + c; −ΔU_min − c]`, `c = [u_k; 0; …]`.
fn move_rows(ell: usize, m: usize, u_k: &[f64], du_max: f64) -> (Vec<f64>, Vec<f64>) {
    let n = ell * m;
    let mut d = vec![0.0; n * n];
    for i in 0..n {
        d[i * n + i] = 1.0;
        if i >= m {
            d[i * n + i - m] = -1.0;
        }
    }
    let mut g = vec![0.0; 2 * n * n];
    let mut h = vec![0.0; 2 * n];
    for i in 0..n {
        let c = if i < m { u_k[i] } else { 0.0 };
        for j in 0..n {
            g[i * n + j] = d[i * n + j];
            g[(n + i) * n + j] = -d[i * n + j];
        }
        h[i] = du_max + c;
        h[n + i] = du_max - c;
    }
    (g, h)
}

/// A random dense problem with boxes, move rows and `n_out` dense output-like rows.
fn random_problem(ell: usize, m: usize, n_out: usize, active: bool, rng: &mut ChaCha8Rng) -> Owned {
    let n = ell * m;
    let hess = random_spd(n, 0.1, rng);
    let scale = if active { 5.0 } else { 0.05 };
    let f: Vec<f64> = (0..n).map(|_| scale * normal(rng)).collect();
    let lb = vec![-1.0; n];
    let ub = vec![1.0; n];
    let u_k: Vec<f64> = (0..m).map(|_| 0.3 * normal(rng)).collect();
    let du = if active { 0.5 } else { 10.0 };
    let (mut g, mut h) = move_rows(ell, m, &u_k, du);
    for _ in 0..n_out {
        let row: Vec<f64> = (0..n).map(|_| normal(rng) / (n as f64).sqrt()).collect();
        g.extend_from_slice(&row);
        h.push(if active { 0.2 } else { 50.0 });
    }
    Owned {
        n,
        qp: QpData {
            hess,
            f,
            lb,
            ub,
            g,
            h,
        },
    }
}

/// A PCAC-shaped problem (2.43)–(2.51): one output, `m` inputs, Markov parameters of a
/// lightly damped mode, `T` block Toeplitz (2.46), `Q = I`, `R = r I`, a step command.
fn pcac_problem(
    ell: usize,
    m: usize,
    with_moves: bool,
    n_out: usize,
    amp: f64,
    rng: &mut ChaCha8Rng,
) -> Owned {
    let n = ell * m;
    let (rho, omega): (f64, f64) = (0.97, 0.3 + 0.2 * rng.random::<f64>());
    let phase: Vec<f64> = (0..m).map(|_| rng.random::<f64>() * 3.0).collect();
    let gain: Vec<f64> = (0..m).map(|_| 0.5 + rng.random::<f64>()).collect();
    // markov[i][j] = H_{i+1}, input j.
    let markov =
        |i: usize, j: usize| gain[j] * rho.powi(i as i32) * (omega * i as f64 + phase[j]).sin();
    // T: row i (y_{i+1|k}) depends on u_{1..i} through H_i, …, H_1; row 0 is zero.
    let mut t = vec![0.0; ell * n];
    for i in 1..ell {
        for blk in 0..i {
            for j in 0..m {
                t[i * n + blk * m + j] = markov(i - 1 - blk, j);
            }
        }
    }
    let free: Vec<f64> = (0..ell)
        .map(|i| 0.3 * rho.powi(i as i32) * (omega * i as f64).cos())
        .collect();
    let reference: Vec<f64> = (0..ell).map(|i| if i > 2 { amp } else { 0.0 }).collect();
    let r_w = 0.05;
    let u_k: Vec<f64> = (0..m).map(|_| 0.1 * normal(rng)).collect();
    // D and c.
    let mut d = vec![0.0; n * n];
    for i in 0..n {
        d[i * n + i] = 1.0;
        if i >= m {
            d[i * n + i - m] = -1.0;
        }
    }
    let mut c = vec![0.0; n];
    c[..m].copy_from_slice(&u_k);
    // H = 2(TᵀT + r DᵀD), f = 2Tᵀ(free − ref) − 2 r Dᵀ c.
    let mut hess = vec![0.0; n * n];
    for a in 0..n {
        for b in 0..n {
            let tt: f64 = (0..ell).map(|i| t[i * n + a] * t[i * n + b]).sum();
            let dd: f64 = (0..n).map(|i| d[i * n + a] * d[i * n + b]).sum();
            hess[a * n + b] = 2.0 * (tt + r_w * dd);
        }
    }
    let mut f = vec![0.0; n];
    for a in 0..n {
        let e: f64 = (0..ell)
            .map(|i| t[i * n + a] * (free[i] - reference[i]))
            .sum();
        let dc: f64 = (0..n).map(|i| d[i * n + a] * c[i]).sum();
        f[a] = 2.0 * e - 2.0 * r_w * dc;
    }
    let lb = vec![-1.0; n];
    let ub = vec![1.0; n];
    let (mut g, mut h) = if with_moves {
        move_rows(ell, m, &u_k, 0.2)
    } else {
        (Vec::new(), Vec::new())
    };
    // Output constraints (2.49): y_{i|k} ≤ y_max for the last n_out steps.
    for k in 0..n_out {
        let i = ell - 1 - k;
        g.extend_from_slice(&t[i * n..(i + 1) * n]);
        h.push(0.8 * amp - free[i]);
    }
    Owned {
        n,
        qp: QpData {
            hess,
            f,
            lb,
            ub,
            g,
            h,
        },
    }
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |a, b| a.max(b.abs()))
}

/// Largest KKT residual (stationarity, primal feasibility, complementarity, dual sign),
/// each relative to the data's scale.
fn kkt_residual(p: &Owned, s: &DenseQpSolver) -> f64 {
    let n = p.n;
    let m = p.n_ineq();
    let x = s.x();
    let mut worst: f64 = 0.0;
    let scale = 1.0 + inf_norm(&p.f);
    for i in 0..n {
        let mut r = p.f[i] - s.lambda_lower()[i] + s.lambda_upper()[i];
        r += p.hess[i * n..(i + 1) * n]
            .iter()
            .zip(x)
            .map(|(a, b)| a * b)
            .sum::<f64>();
        for j in 0..m {
            r += p.g[j * n + i] * s.lambda_ineq()[j];
        }
        worst = worst.max(r.abs() / scale);
    }
    let mut feas = |slack: f64, lam: f64| {
        worst = worst.max(slack.max(0.0));
        worst = worst.max((-lam).max(0.0));
        worst = worst.max((lam * slack).abs());
    };
    for (i, &xi) in x.iter().enumerate() {
        feas(xi - p.ub[i], s.lambda_upper()[i]);
        feas(p.lb[i] - xi, s.lambda_lower()[i]);
    }
    for j in 0..m {
        let gx: f64 = (0..n).map(|c| p.g[j * n + c] * x[c]).sum();
        feas(gx - p.h[j], s.lambda_ineq()[j]);
    }
    worst
}

/// Deviations of our solution from clarabel's.
#[derive(Clone, Copy, Debug, Default)]
struct Deviation {
    /// `‖U − U_clarabel‖∞ / (1 + ‖U_clarabel‖∞)`.
    u: f64,
    /// `|J − J_clarabel| / (1 + |J_clarabel|)`.
    objective: f64,
    /// `‖U − U_polished‖∞ / (1 + ‖U_polished‖∞)`, where `U_polished` solves the
    /// equality-constrained QP on clarabel's strongly active constraints exactly.
    polished: f64,
    /// Condition number of `H`.
    cond_h: f64,
}

/// The exact minimizer of `½UᵀHU + fᵀU` subject to the constraints that clarabel reports
/// as active (multiplier above `rel` times the largest plus `1e-9`), held with equality:
/// the KKT system solved by SVD (parallel active rows are allowed). Returns the point,
/// whether it is feasible (to `1e-9`) with the equality-constrained KKT equations solved
/// (to `1e-9`), and whether it is moreover certified optimal by the KKT conditions of the
/// full problem (the minimum-norm multipliers of the equality rows `≥ −1e-9`). A certified
/// point is a reference independent of clarabel's accuracy in the flat directions of an
/// ill-conditioned `H`. With linearly dependent active rows the minimum-norm multipliers
/// can be negative although nonnegative ones exist (clarabel's own): then a feasible
/// point is the reference.
fn polish_with(p: &Owned, c: &ClarabelSolution, rel: f64) -> (Vec<f64>, bool, bool) {
    use nalgebra::{DMatrix, DVector};
    let n = p.n;
    let lam_max = c
        .lambda_lower
        .iter()
        .chain(&c.lambda_upper)
        .chain(&c.lambda_ineq)
        .fold(0.0f64, |a, b| a.max(*b));
    let thr = rel * lam_max + 1e-9;
    let mut rows: Vec<(Vec<f64>, f64)> = Vec::new();
    for i in 0..n {
        let mut e = vec![0.0; n];
        if c.lambda_upper[i] > thr {
            e[i] = 1.0;
            rows.push((e.clone(), p.ub[i]));
        }
        if c.lambda_lower[i] > thr {
            e[i] = -1.0;
            rows.push((e, -p.lb[i]));
        }
    }
    for j in 0..p.n_ineq() {
        if c.lambda_ineq[j] > thr {
            rows.push((p.g[j * n..(j + 1) * n].to_vec(), p.h[j]));
        }
    }
    let k = rows.len();
    let mut kkt = DMatrix::<f64>::zeros(n + k, n + k);
    let mut rhs = DVector::<f64>::zeros(n + k);
    for i in 0..n {
        for j in 0..n {
            kkt[(i, j)] = p.hess[i * n + j];
        }
        rhs[i] = -p.f[i];
    }
    for (r, (a, b)) in rows.iter().enumerate() {
        for j in 0..n {
            kkt[(n + r, j)] = a[j];
            kkt[(j, n + r)] = a[j];
        }
        rhs[n + r] = *b;
    }
    let sol = kkt
        .clone()
        .svd(true, true)
        .solve(&rhs, 1e-12)
        .expect("SVD solve");
    let residual = (&kkt * &sol - &rhs).amax();
    let x = sol.as_slice()[..n].to_vec();
    let dual_ok = sol.as_slice()[n..]
        .iter()
        .all(|&v| v >= -1e-9 * (1.0 + lam_max));
    let mut primal_ok = true;
    for (i, &xi) in x.iter().enumerate() {
        primal_ok &= xi <= p.ub[i] + 1e-9 * (1.0 + p.ub[i].abs());
        primal_ok &= xi >= p.lb[i] - 1e-9 * (1.0 + p.lb[i].abs());
    }
    for j in 0..p.n_ineq() {
        let gx: f64 = (0..n).map(|c| p.g[j * n + c] * x[c]).sum();
        primal_ok &= gx <= p.h[j] + 1e-9 * (1.0 + p.h[j].abs());
    }
    let solved = residual <= 1e-9 * (1.0 + rhs.amax());
    (x, solved && primal_ok, solved && primal_ok && dual_ok)
}

/// [`polish_with`] for thresholds from `1e-2` down to `1e-12` in half decades (nearly
/// degenerate problems have multipliers decaying geometrically down to the size of
/// clarabel's own noise); the first certified point, else the first feasible one, else
/// the one for `1e-7`.
fn polish(p: &Owned, c: &ClarabelSolution) -> Vec<f64> {
    let mut feasible = None;
    for k in 4..=24 {
        let rel = 10f64.powf(-(k as f64) / 2.0);
        let (x, ok, certified) = polish_with(p, c, rel);
        if certified {
            return x;
        }
        if ok && feasible.is_none() {
            feasible = Some(x);
        }
    }
    feasible.unwrap_or_else(|| polish_with(p, c, 1e-7).0)
}

fn condition_number(p: &Owned) -> f64 {
    let h = nalgebra::DMatrix::from_row_slice(p.n, p.n, &p.hess);
    let ev = h.symmetric_eigenvalues();
    ev.max() / ev.min()
}

fn deviation_from_clarabel(p: &Owned, s: &DenseQpSolver) -> Deviation {
    let c = solve_with_clarabel(&p.problem(), 1e-12).expect("clarabel accepts the data");
    assert!(
        matches!(c.status, SolverStatus::Solved | SolverStatus::AlmostSolved),
        "clarabel: {:?}",
        c.status
    );
    let rel = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()))
            / (1.0 + inf_norm(b))
    };
    let polished = polish(p, &c);
    Deviation {
        u: rel(s.x(), &c.x),
        objective: (s.objective() - c.objective).abs() / (1.0 + c.objective.abs()),
        polished: rel(s.x(), &polished),
        cond_h: condition_number(p),
    }
}

/// Solves `p`, checks the KKT conditions to `1e-8`, the objective against clarabel's to
/// `1e-9`, `U` against the polished clarabel solution to `1e-8` and against clarabel's raw
/// `U` to `raw_tol`.
fn check_against_clarabel(p: &Owned, warm: WarmStart, raw_tol: f64) -> (usize, Deviation) {
    let mut s = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
    let status = s.solve(&p.problem(), warm);
    assert_eq!(status, QpStatus::Solved);
    let kkt = kkt_residual(p, &s);
    assert!(kkt < 1e-8, "KKT residual {kkt:e}");
    let d = deviation_from_clarabel(p, &s);
    assert!(
        d.objective < 1e-9 && d.polished < 1e-8 && d.u < raw_tol,
        "deviation from clarabel: {d:?}"
    );
    (s.active_len(), d)
}

#[test]
fn solutions_match_clarabel_and_satisfy_kkt_on_random_problems() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut worst: f64 = 0.0;
    let mut active_seen = 0;
    for (ell, m, n_out) in [(10, 2, 0), (10, 2, 3), (25, 2, 4), (50, 2, 2), (20, 1, 5)] {
        for active in [false, true] {
            let p = random_problem(ell, m, n_out, active, &mut rng);
            let (n_active, d) = check_against_clarabel(&p, WarmStart::Cold, 1e-6);
            eprintln!("random ℓ = {ell}, m = {m}: {n_active} active, {d:?}");
            if !active {
                assert_eq!(n_active, 0, "slack problem has no active constraints");
            } else {
                active_seen += n_active;
            }
            worst = worst.max(d.u).max(d.objective);
        }
    }
    assert!(active_seen > 10);
    eprintln!("random problems: worst relative deviation from clarabel {worst:e}");
}

#[test]
fn solutions_match_clarabel_on_pcac_shaped_problems() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut worst: f64 = 0.0;
    // (ℓ, m, move rows, output rows, command amplitude)
    for (ell, m, moves, n_out, amp) in [
        (50, 2, true, 3, 3.0),
        (50, 2, true, 0, 0.2),
        (40, 2, false, 0, 4.0),
        (40, 2, false, 0, 0.1),
        (15, 2, true, 2, 2.0),
    ] {
        let p = pcac_problem(ell, m, moves, n_out, amp, &mut rng);
        // H = 2(TᵀT + r DᵀD) is ill-conditioned (cond ~1e6–1e7), so clarabel's U is only
        // as accurate as its gap tolerance allows in the flat directions: the raw U is
        // checked to 1e-4, the polished one to 1e-8.
        let (n_active, d) = check_against_clarabel(&p, WarmStart::Cold, 1e-4);
        assert!(d.cond_h > 1e4, "PCAC Hessians are ill-conditioned");
        eprintln!("PCAC ℓ = {ell}, m = {m}: {n_active} active, {d:?}");
        worst = worst.max(d.polished).max(d.objective);
    }
    eprintln!(
        "PCAC problems: worst relative deviation from polished clarabel / objective {worst:e}"
    );
}

#[test]
fn sixty_random_pcac_and_dense_problems_match_clarabel() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let (mut worst_polished, mut worst_obj, mut worst_raw_dense): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let mut active = 0;
    for k in 0..60 {
        let m = 1 + k % 2;
        let ell = rng.random_range(10..=50usize);
        if k % 3 == 0 {
            let p = random_problem(ell, m, k % 4, k % 2 == 0, &mut rng);
            let (n_active, d) = check_against_clarabel(&p, WarmStart::Cold, 1e-6);
            active += n_active;
            worst_raw_dense = worst_raw_dense.max(d.u);
            worst_polished = worst_polished.max(d.polished);
            worst_obj = worst_obj.max(d.objective);
        } else {
            let amp = 0.1 + 3.0 * rng.random::<f64>();
            let p = pcac_problem(ell, m, k % 3 == 1, k % 4, amp, &mut rng);
            let (n_active, d) = check_against_clarabel(&p, WarmStart::Cold, 1e-4);
            active += n_active;
            worst_polished = worst_polished.max(d.polished);
            worst_obj = worst_obj.max(d.objective);
        }
    }
    assert!(active > 100);
    eprintln!(
        "60 problems, {active} active constraints in all: worst deviation from clarabel in U \
         (well-conditioned) {worst_raw_dense:e}, from polished clarabel {worst_polished:e}, \
         objective {worst_obj:e}"
    );
}

#[test]
fn an_unconstrained_problem_returns_the_newton_point() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 30;
    let hess = random_spd(n, 0.5, &mut rng);
    let f: Vec<f64> = (0..n).map(|_| normal(&mut rng)).collect();
    let p = Owned {
        n,
        qp: QpData {
            hess,
            f,
            lb: vec![f64::NEG_INFINITY; n],
            ub: vec![f64::INFINITY; n],
            g: vec![],
            h: vec![],
        },
    };
    let mut s = DenseQpSolver::new(n, 0, QpSettings::default());
    assert_eq!(s.solve(&p.problem(), WarmStart::Cold), QpStatus::Solved);
    assert_eq!(s.iterations(), 0);
    for i in 0..n {
        let r: f64 = (0..n).map(|j| p.hess[i * n + j] * s.x()[j]).sum::<f64>() + p.f[i];
        assert!(r.abs() < 1e-10);
    }
}

#[test]
fn warm_starts_reach_the_same_solution_in_fewer_iterations() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let p = pcac_problem(50, 2, true, 3, 3.0, &mut rng);
    let mut s = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
    assert_eq!(s.solve(&p.problem(), WarmStart::Cold), QpStatus::Solved);
    let cold_iters = s.iterations();
    let x_cold = s.x().to_vec();
    let mut ids = vec![ConstraintId::Row(0); p.n];
    let k = s.active_set_into(&mut ids);
    assert_eq!(
        s.solve(&p.problem(), WarmStart::ActiveSet(&ids[..k])),
        QpStatus::Solved
    );
    assert!(s.iterations() <= cold_iters);
    eprintln!(
        "cold: {cold_iters} iterations, warm from the exact active set ({k}): {}",
        s.iterations()
    );
    assert!(
        inf_norm(
            &x_cold
                .iter()
                .zip(s.x())
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>()
        ) < 1e-10
    );
    // From a primal guess (the previous solution itself).
    assert_eq!(
        s.solve(&p.problem(), WarmStart::Primal(&x_cold)),
        QpStatus::Solved
    );
    assert!(s.iterations() <= cold_iters);
    assert!(kkt_residual(&p, &s) < 1e-8);
    // A perturbed problem warm-started from the old active set still solves exactly.
    let mut p2 = p.clone();
    for v in p2.f.iter_mut() {
        *v += 0.05 * normal(&mut rng);
    }
    assert_eq!(
        s.solve(&p2.problem(), WarmStart::ActiveSet(&ids[..k])),
        QpStatus::Solved
    );
    assert!(kkt_residual(&p2, &s) < 1e-8);
    let d = deviation_from_clarabel(&p2, &s);
    assert!(d.objective < 1e-9 && d.polished < 1e-8, "{d:?}");
}

/// Bounds fixed from the warm start, right or wrong, end at clarabel's solution: the exact
/// active set, that set with wrong bounds added (every other variable at its upper bound,
/// and both sides of some), every variable at its upper bound, and the old active set on
/// a perturbed problem. Wrong fixed bounds are freed, at the start or in a dual step.
#[test]
fn fixed_bounds_from_any_warm_start_reach_clarabels_solution() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut fixed, mut freed, mut refactors) = (0, 0, 0);
    for k in 0..12 {
        let ell = [10, 25, 50][k % 3];
        let p = if k % 2 == 0 {
            pcac_problem(ell, 2, true, k % 3, 2.0 + 0.3 * k as f64, &mut rng)
        } else {
            random_problem(ell, 2, k % 4, true, &mut rng)
        };
        let raw_tol = if k % 2 == 0 { 1e-4 } else { 1e-6 };
        let n = p.n;
        let mut s = DenseQpSolver::new(n, p.n_ineq(), QpSettings::default());
        assert_eq!(s.solve(&p.problem(), WarmStart::Cold), QpStatus::Solved);
        let cold_iterations = s.iterations();
        let mut exact = vec![ConstraintId::Row(0); n];
        let na = s.active_set_into(&mut exact);
        exact.truncate(na);
        let bounds_in_exact = exact
            .iter()
            .filter(|c| !matches!(c, ConstraintId::Row(_)))
            .count();
        let mut wrong = exact.clone();
        for i in (0..n).step_by(2) {
            wrong.push(ConstraintId::Upper(i));
        }
        for i in (1..n).step_by(7) {
            wrong.push(ConstraintId::Upper(i));
            wrong.push(ConstraintId::Lower(i));
        }
        let all_upper: Vec<ConstraintId> = (0..n).map(ConstraintId::Upper).collect();
        for warm in [&exact, &wrong, &all_upper] {
            let (_, d) = check_against_clarabel(&p, WarmStart::ActiveSet(warm), raw_tol);
            assert!(d.objective < 1e-9, "{d:?}");
            s.solve(&p.problem(), WarmStart::ActiveSet(warm));
            fixed += s.fixed_at_start();
            freed += s.freed_bounds();
            refactors += s.refactors;
        }
        s.solve(&p.problem(), WarmStart::ActiveSet(&exact));
        // Its bounds are fixed (and bounds violated at the start in bulk, when rows of
        // the set are not yet active); the rows are then added in fewer steps than cold.
        assert!(s.fixed_at_start() >= bounds_in_exact);
        assert!(s.iterations() <= cold_iterations);
        eprintln!(
            "{k}: cold {cold_iterations} iterations; exact warm start: {} fixed, {} freed, \
             {} iterations",
            s.fixed_at_start(),
            s.freed_bounds(),
            s.iterations()
        );
        let mut p2 = p.clone();
        for v in p2.f.iter_mut() {
            *v += 0.1 * (1.0 + v.abs()) * normal(&mut rng);
        }
        check_against_clarabel(&p2, WarmStart::ActiveSet(&exact), raw_tol);
    }
    eprintln!("{fixed} bounds fixed at the start, {freed} freed, {refactors} refactorizations");
    assert!(fixed > 500 && freed > 100, "{fixed} fixed, {freed} freed");
    // Wrong warm starts free many bounds in one round, which factors H_FF anew.
    assert!(refactors > 0);
}

/// The bulk fix (the first step of a saturation) runs on a cold start whose unconstrained
/// minimizer leaves the box far, and fixes only bounds the objective pushes against; a
/// warm start that fixes a bound skips it, and the dual steps reach the same solution.
#[test]
fn the_bulk_fix_runs_only_when_the_warm_start_fixes_no_bound() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let p = pcac_problem(50, 2, true, 3, 4.0, &mut rng);
    let n = p.n;
    let mut s = DenseQpSolver::new(n, p.n_ineq(), QpSettings::default());
    assert_eq!(s.solve(&p.problem(), WarmStart::Cold), QpStatus::Solved);
    let cold_x = s.x().to_vec();
    let mut ids = vec![ConstraintId::Row(0); n + p.n_ineq()];
    let k = s.active_set_into(&mut ids);
    let bounds: Vec<ConstraintId> = ids[..k]
        .iter()
        .copied()
        .filter(|c| !matches!(c, ConstraintId::Row(_)))
        .collect();
    // Cold: nothing fixed by the warm start, so all fixed bounds come from the bulk fix.
    assert!(s.fixed_at_start() >= BULK_FIX, "{}", s.fixed_at_start());
    assert!(bounds.len() > n / 2, "{} bounds active", bounds.len());
    assert!(kkt_residual(&p, &s) < 1e-9);
    // One bound of the solution as the warm start: only it is fixed at the start.
    let warm = [bounds[0]];
    assert_eq!(
        s.solve(&p.problem(), WarmStart::ActiveSet(&warm)),
        QpStatus::Solved
    );
    assert_eq!(s.fixed_at_start(), 1);
    assert!(kkt_residual(&p, &s) < 1e-9);
    let diff = s
        .x()
        .iter()
        .zip(&cold_x)
        .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
    assert!(diff < 1e-8 * (1.0 + inf_norm(&cold_x)), "{diff}");
}

/// A fixed bound whose multiplier reaches zero while a row is added is freed in that
/// dual step: `min ½(2u₀² − 2u₀u₁ + 2u₁²) − u₀` with `u₀ ≤ 0` fixed and `u₁ ≤ −3`. At
/// the start (`u₁ = 0`) the bound's multiplier is 1; moving `u₁` down lowers it to zero
/// at `u₁ = −1`, and the solution is `(−1, −3)` with the bound inactive.
#[test]
fn a_fixed_bound_is_freed_inside_a_dual_step() {
    let p = Owned {
        n: 2,
        qp: QpData {
            hess: vec![2.0, -1.0, -1.0, 2.0],
            f: vec![-1.0, 0.0],
            lb: vec![f64::NEG_INFINITY; 2],
            ub: vec![0.0, f64::INFINITY],
            g: vec![0.0, 1.0],
            h: vec![-3.0],
        },
    };
    let mut s = DenseQpSolver::new(2, 1, QpSettings::default());
    let warm = [ConstraintId::Upper(0)];
    assert_eq!(
        s.solve(&p.problem(), WarmStart::ActiveSet(&warm)),
        QpStatus::Solved
    );
    assert_eq!((s.fixed_at_start(), s.freed_bounds()), (1, 1));
    assert!((s.x()[0] + 1.0).abs() < 1e-12 && (s.x()[1] + 3.0).abs() < 1e-12);
    assert_eq!(s.lambda_upper()[0], 0.0);
    assert!((s.lambda_ineq()[0] - 5.0).abs() < 1e-12);
    assert_eq!(s.active_len(), 1);
    assert!(kkt_residual(&p, &s) < 1e-12);
    // Every variable fixed, and a row on them violated: only dual steps are possible
    // until one is freed. min ½|u|² − 2(u₀ + u₁), u ≤ 1 fixed, u₀ + u₁ ≤ 1.
    let p = Owned {
        n: 2,
        qp: QpData {
            hess: vec![1.0, 0.0, 0.0, 1.0],
            f: vec![-2.0, -2.0],
            lb: vec![-1.0; 2],
            ub: vec![1.0; 2],
            g: vec![1.0, 1.0],
            h: vec![1.0],
        },
    };
    let warm = [ConstraintId::Upper(0), ConstraintId::Upper(1)];
    assert_eq!(
        s.solve(&p.problem(), WarmStart::ActiveSet(&warm)),
        QpStatus::Solved
    );
    assert_eq!(s.fixed_at_start(), 2);
    assert!(s.freed_bounds() >= 1);
    assert!((s.x()[0] - 0.5).abs() < 1e-12 && (s.x()[1] - 0.5).abs() < 1e-12);
    assert!((s.lambda_ineq()[0] - 1.5).abs() < 1e-12);
    assert!(kkt_residual(&p, &s) < 1e-12);
}

#[test]
fn contradictory_constraints_are_reported_infeasible() {
    let n = 4;
    let base = Owned {
        n,
        qp: QpData {
            hess: (0..n * n)
                .map(|k| if k % (n + 1) == 0 { 2.0 } else { 0.0 })
                .collect(),
            f: vec![1.0, -1.0, 0.5, 0.0],
            lb: vec![-1.0; n],
            ub: vec![1.0; n],
            g: vec![],
            h: vec![],
        },
    };
    let mut s = DenseQpSolver::new(n, 0, QpSettings::default());
    // Crossed bounds.
    let mut p = base.clone();
    p.lb[2] = 2.0;
    assert_eq!(s.solve(&p.problem(), WarmStart::Cold), QpStatus::Infeasible);
    assert!(s.x().iter().all(|v| v.is_finite()));
    // A row that the box cannot satisfy: u₀ + u₁ + u₂ + u₃ ≥ 5.
    let mut p = base.clone();
    p.g = vec![-1.0; n];
    p.h = vec![-5.0];
    let mut s1 = DenseQpSolver::new(n, 1, QpSettings::default());
    assert_eq!(
        s1.solve(&p.problem(), WarmStart::Cold),
        QpStatus::Infeasible
    );
    assert!(s1.x().iter().all(|v| v.is_finite()));
    // Two contradictory rows: u₀ − u₁ ≤ −1 and u₁ − u₀ ≤ −1, no boxes.
    let mut p = base.clone();
    p.lb = vec![f64::NEG_INFINITY; n];
    p.ub = vec![f64::INFINITY; n];
    p.g = vec![1.0, -1.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0];
    p.h = vec![-1.0, -1.0];
    let mut s2 = DenseQpSolver::new(n, 2, QpSettings::default());
    assert_eq!(
        s2.solve(&p.problem(), WarmStart::Cold),
        QpStatus::Infeasible
    );
    // A zero row with a negative right-hand side.
    let mut p = base.clone();
    p.g = vec![0.0; n];
    p.h = vec![-1.0];
    assert_eq!(
        s1.solve(&p.problem(), WarmStart::Cold),
        QpStatus::Infeasible
    );
    // Random PCAC problem whose move bounds cannot reach the box: u_k far outside.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut p = pcac_problem(10, 2, true, 0, 1.0, &mut rng);
    let (g, h) = move_rows(10, 2, &[5.0, 5.0], 0.2);
    p.g = g;
    p.h = h;
    let mut s3 = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
    assert_eq!(
        s3.solve(&p.problem(), WarmStart::Cold),
        QpStatus::Infeasible
    );
    // The same with every variable fixed at a bound from the warm start.
    let all_lower: Vec<ConstraintId> = (0..p.n).map(ConstraintId::Lower).collect();
    assert_eq!(
        s3.solve(&p.problem(), WarmStart::ActiveSet(&all_lower)),
        QpStatus::Infeasible
    );
    assert!(s3.x().iter().all(|v| v.is_finite()));
    let c = solve_with_clarabel(&p.problem(), 1e-8).unwrap();
    assert!(matches!(
        c.status,
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible
    ));
}

#[test]
fn the_iteration_cap_returns_a_finite_iterate_within_the_box() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let p = pcac_problem(50, 2, true, 3, 3.0, &mut rng);
    let settings = QpSettings {
        max_iterations: 3,
        ..QpSettings::default()
    };
    let mut s = DenseQpSolver::new(p.n, p.n_ineq(), settings);
    assert_eq!(
        s.solve(&p.problem(), WarmStart::Cold),
        QpStatus::MaxIterations
    );
    assert_eq!(s.iterations(), 3);
    assert!(s.objective().is_finite());
    for i in 0..p.n {
        assert!(s.x()[i].is_finite() && s.x()[i] >= p.lb[i] && s.x()[i] <= p.ub[i]);
    }
}

#[test]
fn bad_data_give_a_status_not_a_panic() {
    let n = 3;
    let good = Owned {
        n,
        qp: QpData {
            hess: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            f: vec![1.0; n],
            lb: vec![-1.0; n],
            ub: vec![1.0; n],
            g: vec![1.0; n],
            h: vec![f64::INFINITY],
        },
    };
    let mut s = DenseQpSolver::new(n, 1, QpSettings::default());
    assert_eq!(s.solve(&good.problem(), WarmStart::Cold), QpStatus::Solved);
    let mut p = good.clone();
    p.f[1] = f64::NAN;
    assert_eq!(
        s.solve(&p.problem(), WarmStart::Cold),
        QpStatus::NumericalError
    );
    let mut p = good.clone();
    p.hess[4] = -1.0;
    assert_eq!(
        s.solve(&p.problem(), WarmStart::Cold),
        QpStatus::NumericalError
    );
    let mut p = good.clone();
    p.h.clear();
    assert_eq!(
        s.solve(&p.problem(), WarmStart::Cold),
        QpStatus::InvalidDimensions
    );
    let mut s4 = DenseQpSolver::new(4, 1, QpSettings::default());
    assert_eq!(
        s4.solve(&good.problem(), WarmStart::Cold),
        QpStatus::InvalidDimensions
    );
    // Invalid warm-start ids are ignored.
    let ids = [ConstraintId::Row(7), ConstraintId::Upper(99)];
    assert_eq!(
        s.solve(&good.problem(), WarmStart::ActiveSet(&ids)),
        QpStatus::Solved
    );
}

#[test]
fn empty_and_tiny_problems_do_not_panic() {
    let mut s = DenseQpSolver::new(0, 0, QpSettings::default());
    let p = QpProblem {
        hess: &[],
        f: &[],
        lb: &[],
        ub: &[],
        g: &[],
        h: &[],
    };
    assert_eq!(s.solve(&p, WarmStart::Cold), QpStatus::Solved);
    assert_eq!(s.objective(), 0.0);
    // One variable, both bounds and a row, all active in turn.
    let mut s = DenseQpSolver::new(1, 1, QpSettings::default());
    for (f, expect) in [(5.0, -1.0), (-5.0, 0.5), (0.2, -0.2)] {
        let p = QpProblem {
            hess: &[1.0],
            f: &[f],
            lb: &[-1.0],
            ub: &[1.0],
            g: &[2.0],
            h: &[1.0],
        };
        assert_eq!(s.solve(&p, WarmStart::Cold), QpStatus::Solved);
        assert!((s.x()[0] - expect).abs() < 1e-14, "f = {f}: {}", s.x()[0]);
    }
}

#[test]
fn parallel_box_and_move_rows_are_handled() {
    // The first move row u_{1|k} − u_k ≤ Δ is parallel to the box on u_{1|k}; with
    // u_k + Δ = ub both are active at the solution (degenerate).
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let mut p = pcac_problem(20, 2, true, 0, 3.0, &mut rng);
    let (g, h) = move_rows(20, 2, &[0.8, 0.8], 0.2);
    p.g = g;
    p.h = h;
    let (n_active, d) = check_against_clarabel(&p, WarmStart::Cold, 1e-4);
    eprintln!("parallel rows: {n_active} active, {d:?}");
}

/// A straightforward row-oriented in-place Cholesky (row-major lower triangle), the
/// alternative to faer's that the timing test compares against.
fn row_cholesky(a: &mut [f64], n: usize) -> bool {
    for i in 0..n {
        let (before, rest) = a.split_at_mut(i * n);
        let row_i = &mut rest[..n];
        for j in 0..i {
            let row_j = &before[j * n..j * n + j + 1];
            let s = row_i[j] - super::dot(&row_i[..j], &row_j[..j]);
            row_i[j] = s / row_j[j];
        }
        let d = row_i[i] - super::dot(&row_i[..i], &row_i[..i]);
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        row_i[i] = d.sqrt();
    }
    true
}

fn summary(name: &str, v: &mut [f64]) {
    println!(
        "  {name:34} p50 {:8.1} µs  p99 {:8.1} µs  max {:8.1} µs",
        percentile(v, 0.5),
        percentile(v, 0.99),
        v[v.len() - 1]
    );
}

/// Timing: `cargo test --release -p control --lib qp_timing -- --ignored --nocapture`.
///
/// For each command amplitude `a`, a sequence of PCAC-shaped problems at `n = 100` (ℓ = 50,
/// m = 2, boxes, 200 move rows, 3 output rows; one model) whose command amplitude
/// varies slowly, `a (1 + 0.05 sin(2πk/50))`, so consecutive problems are neighbours as in
/// the receding horizon; every step is solved cold and warm-started from the previous
/// step's active set.
#[test]
#[ignore]
fn qp_timing_at_n_100_with_active_constraints() {
    use std::time::Instant;
    let reps = 1000;
    for amp in [0.5, 1.0, 2.0, 4.0] {
        let seq: Vec<Owned> = (0..50)
            .map(|k| {
                let mut rng = ChaCha8Rng::seed_from_u64(21);
                let a = amp * (1.0 + 0.05 * (2.0 * std::f64::consts::PI * k as f64 / 50.0).sin());
                pcac_problem(50, 2, true, 3, a, &mut rng)
            })
            .collect();
        let mut s = DenseQpSolver::new(seq[0].n, seq[0].n_ineq(), QpSettings::default());
        let mut ids = vec![ConstraintId::Row(0); seq[0].n];
        let mut k_ids = 0;
        let (mut cold, mut warm) = (Vec::with_capacity(reps), Vec::with_capacity(reps));
        let (mut n_active, mut it_cold, mut it_warm) = (0usize, 0usize, 0usize);
        let mut max_active = 0;
        for k in 0..reps {
            let p = &seq[k % seq.len()];
            let t = Instant::now();
            let st = s.solve(&p.problem(), WarmStart::Cold);
            cold.push(t.elapsed().as_secs_f64() * 1e6);
            assert_eq!(st, QpStatus::Solved);
            n_active += s.active_len();
            max_active = max_active.max(s.active_len());
            it_cold += s.iterations();
            let t = Instant::now();
            let st = s.solve(&p.problem(), WarmStart::ActiveSet(&ids[..k_ids]));
            warm.push(t.elapsed().as_secs_f64() * 1e6);
            assert_eq!(st, QpStatus::Solved);
            it_warm += s.iterations();
            k_ids = s.active_set_into(&mut ids);
        }
        let p = &seq[0];
        let mut clar = Vec::with_capacity(reps / 5);
        for _ in 0..reps / 5 {
            let t = Instant::now();
            let c = solve_with_clarabel(&p.problem(), 1e-8).unwrap();
            clar.push(t.elapsed().as_secs_f64() * 1e6);
            assert!(matches!(c.status, SolverStatus::Solved));
        }
        let r = reps as f64;
        println!(
            "n = 100 (ℓ = 50, m = 2), {} rows, amplitude {amp}: active mean {:.1}, max {max_active}; \
             iterations cold {:.1}, warm {:.1}",
            p.n_ineq(),
            n_active as f64 / r,
            it_cold as f64 / r,
            it_warm as f64 / r
        );
        summary("dual active set, cold", &mut cold);
        summary("dual active set, warm", &mut warm);
        summary("clarabel set-up + solve (tol 1e-8)", &mut clar);
    }
    // The factorization alone: a row-oriented one, faer's blocked one in one call, and
    // the panels the solver uses (faer's kernels, left-looking).
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let p0 = pcac_problem(50, 2, true, 3, 1.0, &mut rng);
    let n = p0.n;
    let mut buf = p0.hess.clone();
    let (mut ours, mut faer_t, mut panels) = (
        Vec::with_capacity(reps),
        Vec::with_capacity(reps),
        Vec::with_capacity(reps),
    );
    let mut mem = MemBuffer::new(factor::cholesky_in_place_scratch::<f64>(
        n,
        Par::Seq,
        Default::default(),
    ));
    for _ in 0..reps {
        buf.copy_from_slice(&p0.hess);
        let t = Instant::now();
        assert!(row_cholesky(&mut buf, n));
        ours.push(t.elapsed().as_secs_f64() * 1e6);
        buf.copy_from_slice(&p0.hess);
        let t = Instant::now();
        let mat = faer::MatMut::from_column_major_slice_mut(&mut buf, n, n);
        let whole = factor::cholesky_in_place(
            mat,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        );
        faer_t.push(t.elapsed().as_secs_f64() * 1e6);
        assert!(whole.is_ok());
        buf.copy_from_slice(&p0.hess);
        let t = Instant::now();
        assert!(cholesky_columns(&mut buf, n, n, (0, n), &mut mem));
        panels.push(t.elapsed().as_secs_f64() * 1e6);
    }
    println!("Cholesky, n = 100:");
    summary("row-oriented in place", &mut ours);
    summary("faer in place, one call", &mut faer_t);
    summary("faer kernels in panels (used)", &mut panels);
}

/// A solve split into `start` and `proceed` calls of a small budget ends with the very
/// result of one `solve` (bit for bit: iterate, multipliers, active set, iteration count),
/// cold and warm, on problems with many active constraints; each `proceed` stops after at
/// most its budget plus the partial steps of one addition, or after one panel of the
/// factorization; and `proceed` with no solve running repeats the last outcome.
#[test]
fn a_solve_split_over_calls_ends_bit_for_bit_where_one_solve_does() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut split_runs, mut panel_calls) = (0, 0);
    for case in 0..12 {
        let p = if case % 2 == 0 {
            pcac_problem(40, 2, true, 3, 3.0, &mut rng)
        } else {
            random_problem(20, 2, 4, true, &mut rng)
        };
        let mut whole = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
        let mut split = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
        let status = whole.solve(&p.problem(), WarmStart::Cold);
        let mut ids = vec![ConstraintId::Row(0); p.n + p.n_ineq()];
        let k = whole.active_set_into(&mut ids);
        let warm_ids = ids[..k / 2].to_vec();
        for warm in [WarmStart::Cold, WarmStart::ActiveSet(&warm_ids)] {
            let status = if matches!(warm, WarmStart::Cold) {
                status
            } else {
                whole.solve(&p.problem(), warm)
            };
            for budget in [1, 2, 5] {
                let mut progress = split.start(&p.problem(), warm);
                let mut calls = 0;
                while progress == QpProgress::Running {
                    assert!(split.is_running());
                    let (before, panels_before) = (split.iterations(), split.panel_stops);
                    progress = split.proceed(&p.problem(), budget);
                    let made = split.iterations() - before;
                    assert!(
                        made <= budget + p.n + p.n_ineq(),
                        "case {case}: {made} changes"
                    );
                    let panel_stop = split.panel_stops > panels_before;
                    assert!(split.panel_stops <= panels_before + 1);
                    if progress == QpProgress::Running && panel_stop {
                        // A call that reaches a factorization ends after one panel.
                        panel_calls += 1;
                    } else if progress == QpProgress::Running {
                        assert!(
                            made >= budget,
                            "case {case}: stopped after {made} < {budget}"
                        );
                    }
                    calls += 1;
                    assert!(calls <= 10_000);
                }
                assert!(!split.is_running());
                assert_eq!(progress, QpProgress::Done(status), "case {case}");
                if calls > 1 {
                    split_runs += 1;
                }
                assert_eq!(split.iterations(), whole.iterations(), "case {case}");
                assert_eq!(split.x(), whole.x(), "case {case}, budget {budget}");
                assert_eq!(split.lambda_lower(), whole.lambda_lower());
                assert_eq!(split.lambda_upper(), whole.lambda_upper());
                assert_eq!(split.lambda_ineq(), whole.lambda_ineq());
                assert_eq!(split.objective().to_bits(), whole.objective().to_bits());
                let mut a = vec![ConstraintId::Row(0); p.n + p.n_ineq()];
                let mut b = a.clone();
                let (ka, kb) = (split.active_set_into(&mut a), whole.active_set_into(&mut b));
                assert_eq!(a[..ka], b[..kb]);
                assert_eq!(
                    split.proceed(&p.problem(), budget),
                    QpProgress::Done(status)
                );
            }
        }
    }
    // The budgets did split most solves, and the factorizations at n = 80 into panels.
    assert!(
        split_runs >= 40,
        "{split_runs} of 72 solves ran over several calls"
    );
    assert!(panel_calls >= 36, "{panel_calls} calls factored a panel");
}

/// `proceed` with a problem of other dimensions ends the running solve with
/// `InvalidDimensions`, and `start` refuses such a problem at once.
#[test]
fn a_split_solve_refuses_a_problem_of_other_dimensions() {
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    let p = pcac_problem(20, 2, true, 3, 3.0, &mut rng);
    let q = pcac_problem(10, 2, true, 3, 3.0, &mut rng);
    let mut s = DenseQpSolver::new(p.n, p.n_ineq(), QpSettings::default());
    assert_eq!(
        s.start(&q.problem(), WarmStart::Cold),
        QpProgress::Done(QpStatus::InvalidDimensions)
    );
    assert_eq!(s.start(&p.problem(), WarmStart::Cold), QpProgress::Running);
    assert_eq!(
        s.proceed(&q.problem(), 1),
        QpProgress::Done(QpStatus::InvalidDimensions)
    );
    assert!(!s.is_running());
}

/// The factorization by column panels: at `n = 128` (the acoustic rig's PCAC) it takes
/// several panels, their factor satisfies `L Lᵀ = H` to round-off and agrees with faer's
/// blocked factorization in one call, the same panels give the same factor bit for bit
/// however the columns are split over calls, and an indefinite matrix is refused.
#[test]
fn the_factorization_by_panels_is_cholesky_and_splits_bit_for_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let n = 128;
    let h = random_spd(n, 1e-3, &mut rng);
    let scale = h.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let req = factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default());
    let mut mem = MemBuffer::new(req);
    let mut bounds = vec![0];
    while *bounds.last().unwrap() < n {
        bounds.push(panel_end(n, *bounds.last().unwrap()));
    }
    assert!(bounds.len() > 3, "panels {bounds:?}");
    let mut whole = h.clone();
    assert!(cholesky_columns(&mut whole, n, n, (0, n), &mut mem));
    // Panel by panel, one call each.
    let mut split = h.clone();
    for w in bounds.windows(2) {
        assert!(cholesky_columns(&mut split, n, n, (w[0], w[1]), &mut mem));
    }
    let lower = |a: &[f64], i: usize, j: usize| if i >= j { a[j * n + i] } else { 0.0 };
    for j in 0..n {
        for i in j..n {
            assert_eq!(lower(&split, i, j).to_bits(), lower(&whole, i, j).to_bits());
        }
    }
    let mut faer_l = h.clone();
    let mat = faer::MatMut::from_column_major_slice_mut(&mut faer_l, n, n);
    assert!(
        factor::cholesky_in_place(
            mat,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default()
        )
        .is_ok()
    );
    let mut worst = (0.0f64, 0.0f64);
    for i in 0..n {
        for j in 0..=i {
            let llt: f64 = (0..=j)
                .map(|k| lower(&whole, i, k) * lower(&whole, j, k))
                .sum();
            worst.0 = worst.0.max((llt - h[j * n + i]).abs() / scale);
            worst.1 = worst
                .1
                .max((lower(&whole, i, j) - lower(&faer_l, i, j)).abs());
        }
    }
    assert!(worst.0 < 1e-13, "L Lᵀ − H: {:e}", worst.0);
    assert!(worst.1 < 1e-9, "against faer's factor: {:e}", worst.1);
    let mut indefinite = h.clone();
    indefinite[(n - 1) * n + n - 1] = -1.0;
    assert!(!cholesky_columns(&mut indefinite, n, n, (0, n), &mut mem));
}

/// A solve's status, changes, `U`, multipliers and objective, bit for bit.
type Outcome = (QpStatus, usize, Vec<u64>, Vec<u64>, u64);

/// Everything a solve leaves, bit for bit.
fn outcome(s: &DenseQpSolver, status: QpStatus) -> Outcome {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut lam = bits(s.lambda_lower());
    lam.extend(bits(s.lambda_upper()));
    lam.extend(bits(s.lambda_ineq()));
    (
        status,
        s.iterations(),
        bits(s.x()),
        lam,
        s.objective().to_bits(),
    )
}

/// [`outcome`] of a solve of `p` by `s`.
fn solved(s: &mut DenseQpSolver, p: &Owned, warm: WarmStart) -> Outcome {
    let status = s.solve(&p.problem(), warm);
    outcome(s, status)
}

/// A solver that keeps its factorization starts from it when `H` is unchanged and the
/// warm start fixes no bound, and ends bit for bit where a solver that factors does (whole
/// or split); a changed `H`, or a warm start that fixes a bound, factors as before; a
/// solve that overwrote `L` (the bulk fix) does not lose the kept factor.
#[test]
fn a_kept_factorization_is_reused_only_for_the_same_hessian_and_changes_nothing() {
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let (mut reused, mut bulk_then_reused) = (0, 0);
    for case in 0..8 {
        let mut p = if case % 2 == 0 {
            pcac_problem(40, 2, true, 3, 1.0 + case as f64, &mut rng)
        } else {
            random_problem(20, 2, 4, case > 3, &mut rng)
        };
        let (n, ni) = (p.n, p.n_ineq());
        let mut keep = DenseQpSolver::new(n, ni, QpSettings::default());
        keep.keep_factorization(true);
        let mut fresh = DenseQpSolver::new(n, ni, QpSettings::default());
        let first = keep.solve(&p.problem(), WarmStart::Cold);
        assert!(!keep.factor_reused());
        let bulk_fixed = keep.fixed_at_start() > 0;
        assert_eq!(
            outcome(&keep, first),
            solved(&mut fresh, &p, WarmStart::Cold)
        );
        // A new gradient and right-hand side with the same H.
        for f in p.f.iter_mut() {
            *f = 0.3 * *f + normal(&mut rng);
        }
        for budget in [usize::MAX, 1] {
            let mut progress = keep.start(&p.problem(), WarmStart::Cold);
            while progress == QpProgress::Running {
                progress = keep.proceed(&p.problem(), budget);
            }
            let QpProgress::Done(status) = progress else {
                unreachable!()
            };
            // Only a cold start after a solve that factored the whole H can reuse it.
            assert!(keep.factor_reused(), "case {case}, budget {budget}");
            assert_eq!(
                outcome(&keep, status),
                solved(&mut fresh, &p, WarmStart::Cold),
                "case {case}, budget {budget}"
            );
            reused += 1;
            bulk_then_reused += usize::from(bulk_fixed);
        }
        // A warm start that fixes a bound factors H_FF.
        let mut ids = vec![ConstraintId::Row(0); n + ni];
        let k = fresh.active_set_into(&mut ids);
        if let Some(b) = ids[..k]
            .iter()
            .copied()
            .find(|c| !matches!(c, ConstraintId::Row(_)))
        {
            let warm = [b];
            let status = keep.solve(&p.problem(), WarmStart::ActiveSet(&warm));
            assert!(!keep.factor_reused());
            assert_eq!(
                outcome(&keep, status),
                solved(&mut fresh, &p, WarmStart::ActiveSet(&warm))
            );
        }
        // A changed H (still symmetric) factors anew.
        p.hess[0] *= 1.0 + 1e-12;
        let status = keep.solve(&p.problem(), WarmStart::Cold);
        assert!(!keep.factor_reused(), "case {case}");
        assert_eq!(
            outcome(&keep, status),
            solved(&mut fresh, &p, WarmStart::Cold)
        );
    }
    assert_eq!(reused, 16);
    // Some first solves fixed bounds in bulk (overwriting L) and the kept factor served
    // the next ones all the same.
    assert!(bulk_then_reused > 0, "no case fixed bounds in bulk");
}
