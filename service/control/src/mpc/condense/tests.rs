//! Tests of the condensing step against dense references (nalgebra) and, end to end,
//! against clarabel on a small plant.

use super::*;
use crate::linalg::percentile;
use crate::mpc::qp::{
    ConstraintId, DenseQpSolver, QpSettings, QpStatus, WarmStart, solve_with_clarabel,
};
use crate::test_support::siso_mpc_spec;
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

fn randn(len: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    (0..len).map(|_| normal(rng)).collect()
}

fn spec(ell: usize, m: usize, p: usize, pt: usize, rng: &mut ChaCha8Rng) -> MpcSpec {
    MpcSpec {
        horizon: ell,
        n_inputs: m,
        n_outputs: p,
        n_tracked: pt,
        tracking: randn(pt * p, rng),
        q: Weight::PerChannel((0..pt).map(|t| 1.0 + t as f64).collect()),
        r: Weight::PerChannel((0..m).map(|j| 0.1 + 0.05 * j as f64).collect()),
        u_min: vec![-1.0; m],
        u_max: vec![1.0; m],
        move_bounds: Some(MoveBounds {
            min: vec![-0.3; m],
            max: vec![0.2; m],
        }),
        output_constraints: Some(OutputConstraints {
            c: randn(2 * p, rng),
            d: randn(2, rng),
        }),
        input_notch: None,
    }
}

fn weights(w: &Weight, ch: usize, ell: usize) -> Vec<f64> {
    match w {
        Weight::Scalar(s) => vec![*s; ch * ell],
        Weight::PerChannel(c) => (0..ell).flat_map(|_| c.iter().copied()).collect(),
        Weight::PerStep(c) => c.clone(),
    }
}

/// The dense matrices of (2.43)–(2.51) built straight from the definitions.
struct Dense {
    t: DMatrix<f64>,
    ct: DMatrix<f64>,
    q: DMatrix<f64>,
    d: DMatrix<f64>,
    r: DMatrix<f64>,
    cl: DMatrix<f64>,
    dl: DVector<f64>,
}

fn dense(s: &MpcSpec, markov: &[f64]) -> Dense {
    let (ell, m, p, pt) = (s.horizon, s.n_inputs, s.n_outputs, s.n_tracked);
    let mut t = DMatrix::zeros(ell * p, ell * m);
    for i in 0..ell {
        for j in 0..i {
            let hs = &markov[(i - j - 1) * p * m..(i - j) * p * m];
            for a in 0..p {
                for b in 0..m {
                    t[(i * p + a, j * m + b)] = hs[a * m + b];
                }
            }
        }
    }
    let ct1 = DMatrix::from_row_slice(pt, p, &s.tracking);
    let mut ct = DMatrix::zeros(ell * pt, ell * p);
    for i in 0..ell {
        ct.view_mut((i * pt, i * p), (pt, p)).copy_from(&ct1);
    }
    let q = DMatrix::from_diagonal(&DVector::from_vec(weights(&s.q, pt, ell)));
    let r = DMatrix::from_diagonal(&DVector::from_vec(weights(&s.r, m, ell)));
    let mut d = DMatrix::identity(ell * m, ell * m);
    for k in m..ell * m {
        d[(k, k - m)] = -1.0;
    }
    let (cl, dl) = match &s.output_constraints {
        None => (DMatrix::zeros(0, ell * p), DVector::zeros(0)),
        Some(oc) => {
            let nc = oc.d.len();
            let c1 = DMatrix::from_row_slice(nc, p, &oc.c);
            let mut cl = DMatrix::zeros(ell * nc, ell * p);
            for i in 0..ell {
                cl.view_mut((i * nc, i * p), (nc, p)).copy_from(&c1);
            }
            (
                cl,
                DVector::from_iterator(ell * nc, (0..ell).flat_map(|_| oc.d.iter().copied())),
            )
        }
    };
    Dense {
        t,
        ct,
        q,
        d,
        r,
        cl,
        dl,
    }
}

/// ΔU of (2.47).
fn delta_u(dn: &Dense, u: &DVector<f64>, u_k: &[f64]) -> DVector<f64> {
    let mut du = &dn.d * u;
    for (j, v) in u_k.iter().enumerate() {
        du[j] -= v;
    }
    du
}

/// The cost (2.48) evaluated directly.
fn direct_cost(dn: &Dense, free: &[f64], u: &DVector<f64>, u_k: &[f64], reference: &[f64]) -> f64 {
    let y = DVector::from_column_slice(free) + &dn.t * u;
    let e = &dn.ct * y - DVector::from_column_slice(reference);
    let du = delta_u(dn, u, u_k);
    (e.transpose() * &dn.q * &e)[0] + (du.transpose() * &dn.r * &du)[0]
}

fn condensed_cost(c: &Condenser, u: &[f64]) -> f64 {
    let p = c.problem();
    let n = u.len();
    let mut s = c.cost_constant();
    for i in 0..n {
        s += p.f[i] * u[i];
        for j in 0..n {
            s += 0.5 * u[i] * p.hess[i * n + j] * u[j];
        }
    }
    s
}

struct Case {
    spec: MpcSpec,
    markov: Vec<f64>,
    free: Vec<f64>,
    u_k: Vec<f64>,
    reference: Vec<f64>,
}

fn random_case(spec: MpcSpec, rng: &mut ChaCha8Rng) -> Case {
    let (ell, m, p, pt) = (spec.horizon, spec.n_inputs, spec.n_outputs, spec.n_tracked);
    // Decaying Markov parameters, like a stable plant's.
    let mut markov = randn((ell - 1) * p * m, rng);
    for (s, hs) in markov.chunks_mut(p * m).enumerate() {
        let decay = 0.9f64.powi(s as i32);
        hs.iter_mut().for_each(|v| *v *= decay);
    }
    Case {
        markov,
        free: randn(ell * p, rng),
        u_k: randn(m, rng),
        reference: randn(ell * pt, rng),
        spec,
    }
}

/// A random case for `spec`, the condenser built on it, and its dense reference.
fn condensed_random_case(spec: MpcSpec, rng: &mut ChaCha8Rng) -> (Case, Condenser, Dense) {
    let case = random_case(spec, rng);
    let mut c = Condenser::new(&case.spec).unwrap();
    c.build(&case.markov, &case.free, &case.u_k, &case.reference)
        .unwrap();
    let dn = dense(&case.spec, &case.markov);
    (case, c, dn)
}

fn max_abs(m: &DMatrix<f64>) -> f64 {
    m.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}

#[test]
fn condensed_cost_gradient_and_hessian_match_the_definitions() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (ell, m, p, pt, q_kind) in [
        (7, 2, 3, 2, 0),
        (7, 2, 3, 2, 1),
        (1, 2, 3, 1, 0),
        (2, 1, 1, 1, 2),
        (12, 3, 4, 1, 1),
        (12, 2, 3, 2, 3),
    ] {
        let mut s = spec(ell, m, p, pt, &mut rng);
        s.q = match q_kind {
            0 => Weight::PerChannel((0..pt).map(|t| 0.5 + t as f64).collect()),
            1 => Weight::PerStep((0..ell * pt).map(|_| rng.random_range(0.1..3.0)).collect()),
            3 => Weight::PerStep(
                (0..ell * pt)
                    .map(|k| if k >= (ell - 1) * pt { 7.0 } else { 1.5 })
                    .collect(),
            ),
            _ => Weight::Scalar(2.5),
        };
        if q_kind == 1 {
            s.r = Weight::PerStep((0..ell * m).map(|_| rng.random_range(0.1..1.0)).collect());
        }
        let (case, c, dn) = condensed_random_case(s, &mut rng);
        let n = ell * m;

        // H and f against the dense formulas.
        let tt = &dn.ct * &dn.t;
        let h_ref = 2.0 * (tt.transpose() * &dn.q * &tt + dn.d.transpose() * &dn.r * &dn.d);
        let e = &dn.ct * DVector::from_column_slice(&case.free)
            - DVector::from_column_slice(&case.reference);
        let mut eu = DVector::zeros(n);
        eu.rows_mut(0, m)
            .copy_from(&DVector::from_column_slice(&case.u_k));
        let f_ref = 2.0 * (tt.transpose() * &dn.q * &e - dn.d.transpose() * &dn.r * eu);
        let h = DMatrix::from_row_slice(n, n, c.problem().hess);
        let f = DVector::from_column_slice(c.problem().f);
        let scale = max_abs(&h_ref).max(1.0);
        assert!(
            max_abs(&(&h - &h_ref)) <= 1e-12 * scale,
            "H: {}",
            max_abs(&(&h - &h_ref))
        );
        assert!((&f - &f_ref).amax() <= 1e-12 * f_ref.amax().max(1.0), "f");
        assert!(max_abs(&(&h - h.transpose())) == 0.0, "H symmetric");

        // The cost at random U, and its gradient by central differences (exact for a
        // quadratic up to round-off).
        for _ in 0..5 {
            let u = randn(n, &mut rng);
            let uv = DVector::from_column_slice(&u);
            let jd = direct_cost(&dn, &case.free, &uv, &case.u_k, &case.reference);
            let jc = condensed_cost(&c, &u);
            assert!(
                (jd - jc).abs() <= 1e-10 * (1.0 + jd.abs()),
                "cost {jd} vs {jc}"
            );
            let grad = &h * &uv + &f;
            let step = 1e-3;
            for k in 0..n {
                let (mut up, mut dn_) = (uv.clone(), uv.clone());
                up[k] += step;
                dn_[k] -= step;
                let fd = (direct_cost(&dn, &case.free, &up, &case.u_k, &case.reference)
                    - direct_cost(&dn, &case.free, &dn_, &case.u_k, &case.reference))
                    / (2.0 * step);
                assert!(
                    (fd - grad[k]).abs() <= 1e-7 * (1.0 + jd.abs()),
                    "gradient {k}: {fd} vs {}",
                    grad[k]
                );
            }
        }
    }
}

#[test]
fn structured_tqt_matches_the_dense_product() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for (ell, m, p, pt, q) in [
        (40, 2, 4, 1, Weight::Scalar(3.0)),
        (
            50,
            2,
            5,
            5,
            Weight::PerChannel(vec![1.0, 2.0, 0.5, 4.0, 1e-3]),
        ),
        (
            50,
            2,
            5,
            2,
            Weight::PerStep((0..100).map(|i| 1.0 + (i % 7) as f64).collect()),
        ),
        // A terminal weight (one correction of the recursion) and a few odd steps.
        (
            40,
            2,
            4,
            1,
            Weight::PerStep((0..40).map(|i| if i == 39 { 10.0 } else { 1.0 }).collect()),
        ),
        (
            30,
            2,
            3,
            2,
            Weight::PerStep(
                (0..60)
                    .map(|k| [1.0, 3.0, 0.2, 5.0][usize::from(k / 2 % 11 == 4) * 2 + k % 2])
                    .collect(),
            ),
        ),
        (9, 3, 2, 2, Weight::Scalar(1.0)),
        // Every tracked-output count with its own unrolled recursion row (1 to 4), the
        // sampling arm's (p_t = 3) among them.
        (50, 2, 5, 3, Weight::PerChannel(vec![1000.0, 100.0, 1.0])),
        (20, 2, 4, 4, Weight::Scalar(2.0)),
    ] {
        let mut s = spec(ell, m, p, pt, &mut rng);
        s.q = q;
        s.r = Weight::Scalar(0.25);
        let (_, c, dn) = condensed_random_case(s, &mut rng);
        let n = ell * m;
        // H − 2 DᵀRD is the structured 2 TᵀC̄ᵀQ̄C̄T.
        let h = DMatrix::from_row_slice(n, n, c.problem().hess)
            - 2.0 * dn.d.transpose() * &dn.r * &dn.d;
        let tqt = 2.0 * dn.t.transpose() * dn.ct.transpose() * &dn.q * &dn.ct * &dn.t;
        let err = max_abs(&(&h - &tqt));
        assert!(
            err <= 1e-10 * max_abs(&tqt).max(1.0),
            "ℓ = {ell}, p = {p}: {err}"
        );
        // The last block row and column are zero (u_{ℓ|k} affects no prediction).
        for k in 0..n {
            for j in n - m..n {
                assert!(tqt[(k, j)] == 0.0 && h[(k, j)].abs() <= 1e-12 * max_abs(&tqt));
            }
        }
    }
}

#[test]
fn rows_evaluate_to_the_moves_and_the_output_constraints() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (ell, m, p, pt) in [(6, 2, 3, 1), (1, 1, 2, 1), (10, 3, 4, 2)] {
        let case = random_case(spec(ell, m, p, pt, &mut rng), &mut rng);
        let mut c = Condenser::new(&case.spec).unwrap();
        let (n, nc) = (ell * m, 2);
        assert_eq!(c.n(), n);
        assert_eq!(c.n_ineq(), 2 * n + ell * nc);
        assert_eq!(c.output_rows_start(), 2 * n);
        c.build(&case.markov, &case.free, &case.u_k, &case.reference)
            .unwrap();
        let dn = dense(&case.spec, &case.markov);
        let mb = case.spec.move_bounds.clone().unwrap();
        let pr = c.problem();
        let g = DMatrix::from_row_slice(c.n_ineq(), n, pr.g);
        let h = DVector::from_column_slice(pr.h);
        assert!(pr.lb.iter().all(|v| *v == -1.0) && pr.ub.iter().all(|v| *v == 1.0));
        for _ in 0..5 {
            let u = DVector::from_column_slice(&randn(n, &mut rng));
            let s = &g * &u - &h;
            let du = delta_u(&dn, &u, &case.u_k);
            let y = DVector::from_column_slice(&case.free) + &dn.t * &u;
            let out = &dn.cl * y + &dn.dl;
            for k in 0..n {
                let j = k % m;
                assert!(
                    (s[k] - (du[k] - mb.max[j])).abs() < 1e-12,
                    "upper move row {k}"
                );
                assert!(
                    (s[n + k] - (mb.min[j] - du[k])).abs() < 1e-12,
                    "lower move row {k}"
                );
            }
            for k in 0..ell * nc {
                assert!(
                    (s[2 * n + k] - out[k]).abs() < 1e-12 * (1.0 + out[k].abs()),
                    "output row {k}"
                );
            }
        }
    }
    // Without move bounds and output constraints there are no rows; infinite move bounds
    // give infinite h (rows the solver drops).
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut s = spec(4, 2, 2, 1, &mut rng);
    s.output_constraints = None;
    s.move_bounds = None;
    assert_eq!(Condenser::new(&s).unwrap().n_ineq(), 0);
    s.move_bounds = Some(MoveBounds {
        min: vec![f64::NEG_INFINITY, -1.0],
        max: vec![0.5, f64::INFINITY],
    });
    let case = random_case(s, &mut rng);
    let mut c = Condenser::new(&case.spec).unwrap();
    let pr = c
        .build(&case.markov, &case.free, &case.u_k, &case.reference)
        .unwrap();
    for k in 0..8 {
        assert_eq!(pr.h[k].is_infinite(), k % 2 == 1, "upper {k}");
        assert_eq!(pr.h[8 + k].is_infinite(), k % 2 == 0, "lower {k}");
    }
}

/// The 2-state SISO plant of the end-to-end test: `x⁺ = A x + B u`, `y = C x`, poles
/// `0.75 ± 0.49i` (|z| = 0.894), zero at `−0.5` (minimum phase: with the output row
/// binding over the horizon, `U` inverts the plant, and a zero outside the unit circle
/// would make that solution grow like `(−2)^i` and the comparison ill-conditioned),
/// DC gain 5.
const A: [[f64; 2]; 2] = [[0.0, 1.0], [-0.8, 1.5]];
const B: [f64; 2] = [0.0, 1.0];
const C: [f64; 2] = [0.5, 1.0];

fn step(x: [f64; 2], u: f64) -> [f64; 2] {
    [
        A[0][0] * x[0] + A[0][1] * x[1] + B[0] * u,
        A[1][0] * x[0] + A[1][1] * x[1] + B[1] * u,
    ]
}

fn out(x: [f64; 2]) -> f64 {
    C[0] * x[0] + C[1] * x[1]
}

#[test]
fn receding_horizon_on_a_small_plant_matches_clarabel_and_respects_the_bounds() {
    let ell = 15;
    // The command 1.2 lies beyond the output limit 1.0: the output row binds at the end.
    let (u_max, du_max, y_max, command) = (0.3, 0.05, 1.0, 1.2);
    let spec = MpcSpec {
        output_constraints: Some(OutputConstraints {
            c: vec![1.0],
            d: vec![-y_max],
        }),
        ..siso_mpc_spec(ell, 1.0, 0.05, u_max, du_max)
    };
    let mut c = Condenser::new(&spec).unwrap();
    let mut solver = DenseQpSolver::new(c.n(), c.n_ineq(), QpSettings::default());
    // Markov parameters H_s = C A^{s−1} B, s = 1..ℓ (H_ℓ is accepted and unused).
    let mut markov = Vec::new();
    let mut v = B;
    for _ in 0..ell {
        markov.push(out(v));
        v = step(v, 0.0);
    }
    let reference = vec![command; ell];
    let (mut x, mut u) = ([0.0, 0.0], 0.0);
    let mut ids = vec![ConstraintId::Row(0); c.n() + c.n_ineq()];
    let mut k_ids = 0;
    let (mut saw_move_active, mut saw_output_active) = (false, false);
    for k in 0..60 {
        // x_{1|k} = A x_k + B u_k (2.36) and its free response y_{i|k} = C A^{i−1} x_{1|k}.
        let x1 = step(x, u);
        let mut free = Vec::with_capacity(ell);
        let mut xf = x1;
        for _ in 0..ell {
            free.push(out(xf));
            xf = step(xf, 0.0);
        }
        let problem = c.build(&markov, &free, &[u], &reference).unwrap();
        let status = solver.solve(&problem, WarmStart::ActiveSet(&ids[..k_ids]));
        assert_eq!(status, QpStatus::Solved, "step {k}");
        // Shift the active set by one step for the next warm start.
        let n = c.n();
        let mut active = [ConstraintId::Row(0); 64];
        let n_act = solver.active_set_into(&mut active);
        k_ids = c.shift_active_set(&active[..n_act], &mut ids);
        for &id in &active[..n_act] {
            match id {
                ConstraintId::Row(j) if j < 2 * n => saw_move_active = true,
                ConstraintId::Row(_) => saw_output_active = true,
                _ => {}
            }
        }
        let problem = c.problem();
        let cl = solve_with_clarabel(&problem, 1e-10).unwrap();
        let ours = solver.x();
        let dev = ours
            .iter()
            .zip(&cl.x)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        if dev > 1e-6 {
            let pr = c.problem();
            let obj = |x: &[f64]| {
                let n = x.len();
                (0..n)
                    .map(|i| {
                        pr.f[i] * x[i]
                            + 0.5 * x[i] * (0..n).map(|j| pr.hess[i * n + j] * x[j]).sum::<f64>()
                    })
                    .sum::<f64>()
            };
            let viol = |x: &[f64]| {
                let n = x.len();
                (0..pr.h.len())
                    .map(|r| (0..n).map(|j| pr.g[r * n + j] * x[j]).sum::<f64>() - pr.h[r])
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let hm = DMatrix::from_row_slice(c.n(), c.n(), pr.hess);
            let ev = hm.symmetric_eigenvalues();
            println!(
                "step {k}: ours obj {:.15e} viol {:.3e}, clarabel {:?} obj {:.15e} viol {:.3e}; eig {:.3e}..{:.3e}; active {}",
                obj(ours),
                viol(ours),
                cl.status,
                obj(&cl.x),
                viol(&cl.x),
                ev.min(),
                ev.max(),
                solver.active_len()
            );
            println!("ours {:?}\nclar {:?}", ours, cl.x);
        }
        assert!(dev <= 1e-6, "step {k}: U differs from clarabel's by {dev}");
        // Bounds (2.50), moves (2.51) and outputs (2.49) along the predicted horizon.
        let mut prev = u;
        let mut xs = x1;
        for (i, &ui) in ours.iter().enumerate() {
            assert!(ui.abs() <= u_max + 1e-9, "step {k}: u_{i} = {ui}");
            assert!(
                (ui - prev).abs() <= du_max + 1e-9,
                "step {k}: Δu_{i} = {}",
                ui - prev
            );
            // The predicted output equals the plant simulated with these inputs.
            let y_pred = free[i] + (0..i).map(|j| markov[i - j - 1] * ours[j]).sum::<f64>();
            assert!((y_pred - out(xs)).abs() < 1e-12, "prediction {i}");
            if k > 0 {
                assert!(y_pred <= y_max + 1e-8, "step {k}: y_{i} = {y_pred}");
            }
            prev = ui;
            xs = step(xs, ui);
        }
        // The cost (2.48) is the solver's objective plus the constant.
        let dn = dense(&spec, &markov[..ell - 1]);
        let jd = direct_cost(
            &dn,
            &free,
            &DVector::from_column_slice(ours),
            &[u],
            &reference,
        );
        assert!((jd - (solver.objective() + c.cost_constant())).abs() < 1e-10 * (1.0 + jd));
        // Apply u_{1|k} at k + 1.
        let u_next = c.first_move(ours)[0];
        x = step(x, u);
        u = u_next;
    }
    assert!(
        saw_move_active && saw_output_active,
        "both row kinds active at some step: {saw_move_active}, {saw_output_active}"
    );
    assert!(
        (out(x) - y_max).abs() < 1e-3,
        "settles at the output limit: y = {}",
        out(x)
    );

    // y_{1|k} beyond its constraint: infeasible whatever U; the fallback holds u_k.
    let x_hot = [1.5, 1.5];
    let x1 = step(x_hot, 0.1);
    let mut free = Vec::new();
    let mut xf = x1;
    for _ in 0..ell {
        free.push(out(xf));
        xf = step(xf, 0.0);
    }
    assert!(free[0] > y_max);
    let problem = c.build(&markov, &free, &[0.1], &reference).unwrap();
    assert_eq!(
        solver.solve(&problem, WarmStart::Cold),
        QpStatus::Infeasible
    );
    let mut fb = [0.0];
    c.fallback_input(&[0.1], &mut fb);
    assert_eq!(fb, [0.1]);
}

#[test]
fn active_sets_shift_by_one_step() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    // ℓ = 4, m = 2: n = 8, move rows 0..16, output rows (n_c = 2) 16..24.
    let c = Condenser::new(&spec(4, 2, 3, 1, &mut rng)).unwrap();
    use ConstraintId::{Lower, Row, Upper};
    let active = [
        Upper(1),
        Upper(2),
        Lower(7),
        Lower(8),
        Row(1),
        Row(3),
        Row(9),
        Row(10),
        Row(16),
        Row(17),
        Row(18),
        Row(23),
        Row(24),
    ];
    let mut out = [Row(0); 16];
    let k = c.shift_active_set(&active, &mut out);
    assert_eq!(
        &out[..k],
        &[Upper(0), Lower(5), Row(1), Row(8), Row(16), Row(21)]
    );
    assert_eq!(c.shift_active_set(&active, &mut out[..2]), 2);
    // Two steps at once: the same as shifting twice.
    let mut once = [Row(0); 16];
    let k1 = c.shift_active_set(&active, &mut once);
    let mut twice = [Row(0); 16];
    let k2 = c.shift_active_set(&once[..k1], &mut twice);
    let k = c.shift_active_set_by(&active, 2, &mut out);
    assert_eq!(&out[..k], &twice[..k2]);
    assert_eq!(&out[..k], &[Lower(3), Row(19)]);
    // ℓ steps or more leave nothing; none keeps every id in range.
    assert_eq!(c.shift_active_set_by(&active, 4, &mut out), 0);
    assert_eq!(c.shift_active_set_by(&active, usize::MAX, &mut out), 0);
    assert_eq!(c.shift_active_set_by(&active, 0, &mut out), 11);
}

#[test]
fn fallback_input_clips_with_bounded_moves() {
    let (lb, ub) = ([-1.0, -1.0, 0.0], [1.0, 1.0, 2.0]);
    let (dmin, dmax) = ([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]);
    let mut out = [9.0; 3];
    fallback_input(&[0.3, 1.2, -2.0], &lb, &ub, None, &mut out);
    assert_eq!(out, [0.3, 1.0, 0.0]);
    fallback_input(&[0.3, 1.2, -2.0], &lb, &ub, Some((&dmin, &dmax)), &mut out);
    // 1.2 reaches the box in one bounded move; −2.0 cannot (2.0 away), the box wins.
    assert_eq!(out, [0.3, 1.0, 0.0]);
    fallback_input(
        &[f64::NAN, f64::INFINITY, 0.5],
        &lb,
        &ub,
        Some((&dmin, &dmax)),
        &mut out,
    );
    assert_eq!(out, [0.0, 0.0, 0.5]);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let c = Condenser::new(&spec(3, 3, 2, 1, &mut rng)).unwrap();
    c.fallback_input(&[0.1, 1.1, -5.0], &mut out);
    assert_eq!(out, [0.1, 1.0, -1.0]);
    assert_eq!(c.first_move(&[1.0, 2.0, 3.0, 4.0]), &[1.0, 2.0, 3.0]);
}

#[test]
fn bad_specs_are_refused_with_clear_messages() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let good = spec(5, 2, 3, 1, &mut rng);
    assert!(Condenser::new(&good).is_ok());
    type Edit = fn(&mut MpcSpec);
    let cases: [(Edit, &str); 15] = [
        (|s| s.horizon = 0, "horizon must be at least 1"),
        (|s| s.n_inputs = 0, "must be at least 1"),
        (|s| s.tracking.push(1.0), "tracking (C_t"),
        (|s| s.tracking[0] = f64::NAN, "C_t): entries must be finite"),
        (
            |s| s.q = Weight::PerChannel(vec![1.0, 2.0]),
            "PerChannel needs 1 values, got 2",
        ),
        (
            |s| s.q = Weight::PerStep(vec![1.0; 4]),
            "PerStep needs horizon × 1 = 5 values, got 4",
        ),
        (|s| s.q = Weight::Scalar(-1.0), "finite and ≥ 0"),
        (
            |s| s.r = Weight::Scalar(0.0),
            "r (move weight R): every weight must be finite and > 0",
        ),
        (|s| s.u_min = vec![0.0], "u_min: expected 2 values, got 1"),
        (|s| s.u_min[1] = 2.0, "input 1: u_min = 2 > u_max = 1"),
        (|s| s.u_max[0] = f64::NAN, "input 0: bounds must be numbers"),
        (
            |s| s.move_bounds.as_mut().unwrap().min[0] = 0.1,
            "Δu_min ≤ 0 ≤ Δu_max",
        ),
        (
            |s| s.move_bounds.as_mut().unwrap().max = vec![1.0],
            "move_bounds.max: expected 2",
        ),
        (
            |s| {
                s.output_constraints
                    .as_mut()
                    .unwrap()
                    .c
                    .pop()
                    .map(|_| ())
                    .unwrap()
            },
            "output_constraints.c",
        ),
        (
            |s| s.output_constraints.as_mut().unwrap().d.clear(),
            "𝓓 is empty",
        ),
    ];
    for (edit, msg) in cases {
        let mut s = good.clone();
        edit(&mut s);
        let err = Condenser::new(&s).unwrap_err().to_string();
        assert!(err.contains(msg), "expected {msg:?} in {err:?}");
        assert!(err.starts_with("invalid MPC spec: "));
    }
}

#[test]
fn build_refuses_bad_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let case = random_case(spec(4, 2, 3, 1, &mut rng), &mut rng);
    let mut c = Condenser::new(&case.spec).unwrap();
    let err = c
        .build(&case.markov[1..], &case.free, &case.u_k, &case.reference)
        .unwrap_err();
    assert_eq!(
        err,
        BuildError::Length {
            what: "markov",
            expected: 18,
            got: 17
        }
    );
    assert_eq!(err.to_string(), "markov: expected length 18, got 17");
    let err = c
        .build(&case.markov, &case.free[1..], &case.u_k, &case.reference)
        .unwrap_err();
    assert!(matches!(
        err,
        BuildError::Length {
            what: "free_response",
            ..
        }
    ));
    let err = c
        .build(&case.markov, &case.free, &[0.0], &case.reference)
        .unwrap_err();
    assert!(matches!(err, BuildError::Length { what: "u_k", .. }));
    let err = c
        .build(&case.markov, &case.free, &case.u_k, &[])
        .unwrap_err();
    assert!(matches!(
        err,
        BuildError::Length {
            what: "reference",
            ..
        }
    ));
    let mut bad = case.u_k.clone();
    bad[1] = f64::NAN;
    let err = c
        .build(&case.markov, &case.free, &bad, &case.reference)
        .unwrap_err();
    assert_eq!(err.to_string(), "u_k: not finite");
    // H_1..H_ℓ is accepted (H_ℓ unused) and gives the same problem.
    c.build(&case.markov, &case.free, &case.u_k, &case.reference)
        .unwrap();
    let h1 = c.problem().hess.to_vec();
    let mut longer = case.markov.clone();
    longer.extend(randn(6, &mut rng));
    c.build(&longer, &case.free, &case.u_k, &case.reference)
        .unwrap();
    assert_eq!(c.problem().hess, &h1[..]);
}

#[test]
#[ignore = "timing; run with --ignored --nocapture"]
fn condense_timing() {
    use std::time::Instant;
    let reps = 5000;
    // q: 0 constant, 1 terminal weight (per step, one correction), 2 per step, all different.
    for (ell, m, p, pt, nc, q_kind) in [
        (40, 2, 4, 1, 1, 0),
        (50, 2, 5, 5, 2, 0),
        (50, 2, 5, 1, 2, 0),
        (50, 2, 5, 5, 2, 1),
        (50, 2, 5, 5, 2, 2),
    ] {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut s = spec(ell, m, p, pt, &mut rng);
        s.q = match q_kind {
            0 => Weight::Scalar(1.0),
            1 => Weight::PerStep(
                (0..ell * pt)
                    .map(|k| if k >= (ell - 1) * pt { 10.0 } else { 1.0 })
                    .collect(),
            ),
            _ => Weight::PerStep((0..ell * pt).map(|k| 1.0 + k as f64 / 10.0).collect()),
        };
        s.output_constraints = Some(OutputConstraints {
            c: randn(nc * p, &mut rng),
            d: vec![-1.0; nc],
        });
        let cases: Vec<Case> = (0..20).map(|_| random_case(s.clone(), &mut rng)).collect();
        let mut c = Condenser::new(&s).unwrap();
        let mut times = Vec::with_capacity(reps);
        let mut sink = 0.0;
        for k in 0..reps {
            let cs = &cases[k % cases.len()];
            let t = Instant::now();
            let pr = c
                .build(&cs.markov, &cs.free, &cs.u_k, &cs.reference)
                .unwrap();
            sink += pr.hess[1] + pr.f[0];
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
        // The dense triple product alone with nalgebra (matrixmultiply's blocked gemm),
        // W = C̄ T then 2 Wᵀ Q̄ W, for comparison.
        let dn = dense(&s, &cases[0].markov);
        let qdiag = DVector::from_vec(weights(&s.q, pt, ell));
        let mut dense_t = Vec::with_capacity(reps / 10);
        for _ in 0..reps / 10 {
            let t = Instant::now();
            let w = &dn.ct * &dn.t;
            let qw = DMatrix::from_diagonal(&qdiag) * &w;
            let out = 2.0 * w.transpose() * qw;
            sink += out[(0, 1)];
            dense_t.push(t.elapsed().as_secs_f64() * 1e6);
        }
        println!(
            "ℓ = {ell}, m = {m}, p = {p}, p_t = {pt}, n_c = {nc}, Q {}: n = {}, {} rows; build p50 {:.1} µs, \
             p99 {:.1} µs; dense 2TᵀC̄ᵀQ̄C̄T alone (nalgebra) p50 {:.1} µs ({sink:.1e})",
            ["constant", "terminal", "per step"][q_kind],
            c.n(),
            c.n_ineq(),
            percentile(&mut times, 0.5),
            percentile(&mut times, 0.99),
            percentile(&mut dense_t, 0.5),
        );
    }
}

/// (2.48') evaluated directly: (2.48) plus `Vᵀ R_v V + Uᵀ R_u U`, `V = 𝒲 U + v_free`,
/// with `𝒲` formed entry by entry from the impulse response.
fn direct_notched_cost(
    dn: &Dense,
    cost: &NotchInputCost,
    case: &Case,
    v_free: &[f64],
    u: &DVector<f64>,
) -> f64 {
    let m = cost.r_notch.len();
    let ell = cost.impulse_response.len();
    let mut v = DVector::from_column_slice(v_free);
    for i in 0..ell {
        for jstep in 0..=i {
            for c in 0..m {
                v[i * m + c] += cost.impulse_response[i - jstep] * u[jstep * m + c];
            }
        }
    }
    let mut extra = 0.0;
    for k in 0..ell * m {
        extra += cost.r_notch[k % m] * v[k] * v[k] + cost.r_level[k % m] * u[k] * u[k];
    }
    direct_cost(dn, &case.free, u, &case.u_k, &case.reference) + extra
}

#[test]
fn the_tone_notch_cost_condensed_equals_2_48_prime_evaluated_directly() {
    let mut rng = ChaCha8Rng::seed_from_u64(48);
    for (ell, m, p, pt, r_move) in [(9, 2, 1, 1, 0.0), (6, 2, 3, 2, 0.3), (12, 1, 2, 1, 0.0)] {
        let ann = crate::internal_model::ToneAnnihilator::new(&[0.4, 1.3], 0.9).expect("tones");
        let cost = NotchInputCost {
            impulse_response: ann.notch_impulse_response(ell),
            r_notch: (0..m).map(|j| 0.5 + j as f64).collect(),
            r_level: (0..m).map(|j| if j == 0 { 7.0 } else { 0.0 }).collect(),
        };
        let mut s = spec(ell, m, p, pt, &mut rng);
        s.r = Weight::Scalar(r_move);
        s.input_notch = Some(cost.clone());
        let case = random_case(s, &mut rng);
        let v_free = randn(ell * m, &mut rng);
        let mut c = Condenser::new(&case.spec).unwrap();
        assert!(c.has_input_notch());
        // Without v_free the notched problem is refused.
        assert!(matches!(
            c.build(&case.markov, &case.free, &case.u_k, &case.reference),
            Err(BuildError::Length { what: "v_free", .. })
        ));
        c.build_notched(
            &case.markov,
            &case.free,
            &case.u_k,
            &case.reference,
            &v_free,
        )
        .unwrap();
        let dn = dense(&case.spec, &case.markov);
        for _ in 0..5 {
            let u = DVector::from_vec(randn(ell * m, &mut rng));
            let want = direct_notched_cost(&dn, &cost, &case, &v_free, &u);
            let got = condensed_cost(&c, u.as_slice());
            assert!(
                (want - got).abs() <= 1e-9 * (1.0 + want.abs()),
                "ℓ = {ell}, m = {m}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn a_zero_move_weight_is_refused_without_the_tone_notch_cost_and_accepted_with_it() {
    let mut s = siso_mpc_spec(5, 1.0, 0.0, 1.0, 1.0);
    assert!(Condenser::new(&s).is_err());
    let ann = crate::internal_model::ToneAnnihilator::new(&[1.0], 0.9).expect("tone");
    s.input_notch = Some(NotchInputCost {
        impulse_response: ann.notch_impulse_response(5),
        r_notch: vec![1.0],
        r_level: vec![0.0],
    });
    assert!(Condenser::new(&s).is_ok());
    s.input_notch.as_mut().unwrap().r_notch = vec![0.0];
    assert!(Condenser::new(&s).is_err());
}
