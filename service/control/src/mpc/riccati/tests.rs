//! The Riccati minimizer against the condensed problem's `U* = −H⁻¹ f` (nalgebra's
//! Cholesky on [`Condenser::build`]'s `H`, `f`) on random stable models of several shapes,
//! weights and timings; its predicted outputs against `Γ̂ x_0 + T̂ U*` (2.43); its cost
//! count; its refusals.

use super::*;
use crate::bocf::HorizonPrediction;
use crate::forgetting::ForgettingRule;
use crate::mpc::condense::{Condenser, MoveBounds, Weight};
use crate::pcac::{IdKernel, IoModel};
use crate::test_support::{Gauss, io_model_params, max_abs, max_abs_diff};
use nalgebra::{DMatrix, DVector};

/// A model of order `n`, `p` outputs, `m` inputs with stable coefficients
/// (`‖F̂_i‖_F = 0.9 / n`, so `Σ ‖F̂_i‖₂ < 1`), random `Ĝ_i` and random histories.
pub(crate) fn stable_model(g: &mut Gauss, n: usize, p: usize, m: usize) -> IoModel {
    let nr = n * (p + m);
    let mut coef = vec![0.0; p * nr];
    for i in 0..n {
        let blk = g.vec(p * p);
        let norm = blk.iter().map(|x| x * x).sum::<f64>().sqrt();
        for r in 0..p {
            for s in 0..p {
                coef[r * nr + i * p + s] = 0.9 / n as f64 * blk[r * p + s] / norm;
            }
            for s in 0..m {
                coef[r * nr + n * p + i * m + s] = g.normal();
            }
        }
    }
    let mut pr = io_model_params(
        n,
        p,
        m,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    // θ = vec Θ̃, column-stacked (2.27).
    pr.theta0 = (0..p * nr).map(|k| coef[(k % p) * nr + k / p]).collect();
    let mut model = IoModel::new(&pr).unwrap();
    for _ in 0..n + 3 {
        model.observe(&g.vec(p), &g.vec(m)).unwrap();
    }
    model
}

/// One problem shape of the comparison.
struct Case {
    n_hat: usize,
    p: usize,
    m: usize,
    ell: usize,
    pt: usize,
    /// Per-step `Q` (a terminal weight ×10 and a zero weight at step 2) and per-step `R`.
    per_step: bool,
    /// Start from `x_{1|k}` (next step) rather than `x̂_k` (same step).
    next_step: bool,
}

fn spec_of(c: &Case, g: &mut Gauss) -> MpcSpec {
    let (ell, pt, m) = (c.ell, c.pt, c.m);
    let (q, r) = if c.per_step {
        let mut q: Vec<f64> = (0..ell * pt).map(|k| 1.0 + (k % pt) as f64).collect();
        q[(ell - 1) * pt..].iter_mut().for_each(|v| *v *= 10.0);
        if ell > 3 {
            q[2 * pt..3 * pt].fill(0.0);
        }
        let r = (0..ell * m)
            .map(|k| 0.2 + 0.1 * ((k / m) % 3) as f64)
            .collect();
        (Weight::PerStep(q), Weight::PerStep(r))
    } else {
        (
            Weight::PerChannel((0..pt).map(|t| 1.0 + t as f64).collect()),
            Weight::Scalar(0.3),
        )
    };
    MpcSpec {
        horizon: ell,
        n_inputs: m,
        n_outputs: c.p,
        n_tracked: pt,
        tracking: g.vec(pt * c.p),
        q,
        r,
        u_min: vec![-1.0; m],
        u_max: vec![1.0; m],
        move_bounds: Some(MoveBounds::symmetric(0.5, m)),
        output_constraints: None,
        input_notch: None,
    }
}

/// `−H⁻¹ f` of the condensed problem, by nalgebra's Cholesky.
fn dense_minimizer(
    cond: &mut Condenser,
    pred: &HorizonPrediction,
    u_k: &[f64],
    r: &[f64],
) -> Vec<f64> {
    let qp = cond
        .build(pred.markov(), pred.free_response(), u_k, r)
        .unwrap();
    let n = qp.f.len();
    let h = DMatrix::from_row_slice(n, n, qp.hess);
    let f = DVector::from_column_slice(qp.f);
    let x = h.cholesky().expect("H is positive definite").solve(&(-f));
    x.iter().copied().collect()
}

#[test]
fn the_recursion_gives_the_condensed_problems_unconstrained_minimizer() {
    let mut g = Gauss::new(47);
    let cases = [
        // The sampling arm's shape (n̂ 1, p 5, m 2, ℓ 50, p_t 3).
        Case {
            n_hat: 1,
            p: 5,
            m: 2,
            ell: 50,
            pt: 3,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 1,
            p: 5,
            m: 2,
            ell: 50,
            pt: 3,
            per_step: true,
            next_step: true,
        },
        Case {
            n_hat: 3,
            p: 2,
            m: 1,
            ell: 12,
            pt: 1,
            per_step: false,
            next_step: true,
        },
        Case {
            n_hat: 3,
            p: 2,
            m: 1,
            ell: 12,
            pt: 2,
            per_step: true,
            next_step: false,
        },
        Case {
            n_hat: 2,
            p: 3,
            m: 2,
            ell: 8,
            pt: 2,
            per_step: true,
            next_step: true,
        },
        Case {
            n_hat: 4,
            p: 1,
            m: 1,
            ell: 10,
            pt: 1,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 2,
            p: 2,
            m: 3,
            ell: 6,
            pt: 1,
            per_step: false,
            next_step: true,
        },
        Case {
            n_hat: 5,
            p: 4,
            m: 2,
            ell: 9,
            pt: 1,
            per_step: true,
            next_step: false,
        },
        // The shortest horizon: only y_{2|k} is tracked and u_{2|k} holds u_{1|k}.
        Case {
            n_hat: 2,
            p: 2,
            m: 2,
            ell: 2,
            pt: 2,
            per_step: false,
            next_step: true,
        },
        // Every row width of the recursion: N = 3, 10, 14, 18, 26 and 32 (w = 4, 12, 16,
        // 20, 28, 32; the cases above have w = 8 and 24).
        Case {
            n_hat: 2,
            p: 1,
            m: 1,
            ell: 8,
            pt: 1,
            per_step: true,
            next_step: true,
        },
        Case {
            n_hat: 4,
            p: 2,
            m: 2,
            ell: 10,
            pt: 2,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 4,
            p: 3,
            m: 2,
            ell: 6,
            pt: 1,
            per_step: true,
            next_step: true,
        },
        Case {
            n_hat: 4,
            p: 4,
            m: 2,
            ell: 6,
            pt: 2,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 6,
            p: 4,
            m: 2,
            ell: 5,
            pt: 1,
            per_step: false,
            next_step: true,
        },
        Case {
            n_hat: 10,
            p: 3,
            m: 2,
            ell: 5,
            pt: 3,
            per_step: true,
            next_step: false,
        },
    ];
    let mut worst: f64 = 0.0;
    for (ci, c) in cases.iter().enumerate() {
        let spec = spec_of(c, &mut g);
        let model = stable_model(&mut g, c.n_hat, c.p, c.m);
        let mut pred = HorizonPrediction::new(&model, c.ell).unwrap();
        let u_k = g.vec(c.m);
        if c.next_step {
            pred.compute(&model, &u_k).unwrap();
        } else {
            pred.compute_from_state(&model).unwrap();
        }
        let reference: Vec<f64> = g.vec(c.ell * c.pt);
        let mut cond = Condenser::new(&spec).unwrap();
        let want = dense_minimizer(&mut cond, &pred, &u_k, &reference);
        let mut ric = Riccati::new(&spec, c.n_hat).unwrap();
        let real = model.realization();
        ric.solve(&real, pred.one_step_state(), &u_k, &reference)
            .unwrap();
        let rel = max_abs_diff(ric.u(), &want) / max_abs(&want);
        assert!(rel < 1e-9, "case {ci}: |U − U_dense| / |U_dense| = {rel:e}");
        worst = worst.max(rel);
        // Y = Γ̂ x_0 + T̂ U (2.43), the outputs the constraint check reads.
        let (p, m) = (c.p, c.m);
        let mut y = pred.free_response().to_vec();
        for i in 0..c.ell {
            for j in 0..i {
                let h = &pred.markov()[(i - j - 1) * p * m..(i - j) * p * m];
                for a in 0..p {
                    for b in 0..m {
                        y[i * p + a] += h[a * m + b] * ric.u()[j * m + b];
                    }
                }
            }
        }
        let d = max_abs_diff(ric.outputs(), &y) / max_abs(&y).max(1.0);
        assert!(d < 1e-9, "case {ci}: predicted outputs off by {d:e}");
        // u_{ℓ|k} affects no output: its move costs, so it holds u_{ℓ−1|k}.
        if c.ell >= 2 {
            let last = &ric.u()[(c.ell - 1) * m..];
            let before = &ric.u()[(c.ell - 2) * m..(c.ell - 1) * m];
            assert!(max_abs_diff(last, before) < 1e-12, "case {ci}");
        }
    }
    eprintln!("riccati vs −H⁻¹f: worst relative difference {worst:.2e}");
}

#[test]
fn a_second_solve_on_other_data_does_not_depend_on_the_first() {
    let mut g = Gauss::new(5);
    let c = Case {
        n_hat: 2,
        p: 3,
        m: 2,
        ell: 15,
        pt: 2,
        per_step: true,
        next_step: true,
    };
    let spec = spec_of(&c, &mut g);
    let (m1, m2) = (stable_model(&mut g, 2, 3, 2), stable_model(&mut g, 2, 3, 2));
    let (x1, x2, u1, u2) = (g.vec(6), g.vec(6), g.vec(2), g.vec(2));
    let (r1, r2) = (g.vec(30), g.vec(30));
    let mut fresh = Riccati::new(&spec, 2).unwrap();
    fresh.solve(&m2.realization(), &x2, &u2, &r2).unwrap();
    let mut reused = Riccati::new(&spec, 2).unwrap();
    reused.solve(&m1.realization(), &x1, &u1, &r1).unwrap();
    reused.solve(&m2.realization(), &x2, &u2, &r2).unwrap();
    assert_eq!(fresh.u(), reused.u());
    assert_eq!(fresh.outputs(), reused.outputs());
}

/// The AVX2 compilation of the passes (taken on this CPU when it has AVX2) gives the
/// baseline compilation's `U*` and outputs bit for bit, at every row width from 4 to 32.
#[test]
fn the_avx2_form_equals_the_baseline_bit_for_bit() {
    let mut g = Gauss::new(17);
    let mut widths = Vec::new();
    for (n_hat, p, m) in [
        (1, 1, 1),
        (1, 5, 2),
        (2, 5, 1),
        (2, 5, 3),
        (4, 4, 3),
        (6, 4, 3),
        (5, 5, 4),
        (5, 4, 2),
        (6, 5, 2),
    ] {
        let c = Case {
            n_hat,
            p,
            m,
            ell: 12,
            pt: 1,
            per_step: true,
            next_step: false,
        };
        let spec = spec_of(&c, &mut g);
        let model = stable_model(&mut g, n_hat, p, m);
        let (x0, u_k, r) = (g.vec(n_hat * p), g.vec(m), g.vec(c.ell));
        let mut base = Riccati::new(&spec, n_hat).unwrap();
        base.avx2 = false;
        base.solve(&model.realization(), &x0, &u_k, &r).unwrap();
        let mut wide = Riccati::new(&spec, n_hat).unwrap();
        wide.solve(&model.realization(), &x0, &u_k, &r).unwrap();
        assert_eq!(base.u(), wide.u(), "n̂ {n_hat}, p {p}, m {m}");
        assert_eq!(base.outputs(), wide.outputs(), "n̂ {n_hat}, p {p}, m {m}");
        assert!(max_abs(base.u()) > 0.0);
        widths.push(wide.w);
    }
    widths.sort_unstable();
    widths.dedup();
    assert_eq!(widths, [4, 8, 12, 16, 20, 24, 28, 32]);
    eprintln!("AVX2 form taken: {}", avx2_available());
}

#[test]
fn wrong_sizes_and_non_finite_data_are_refused() {
    let mut g = Gauss::new(9);
    let c = Case {
        n_hat: 2,
        p: 2,
        m: 1,
        ell: 6,
        pt: 1,
        per_step: false,
        next_step: true,
    };
    let spec = spec_of(&c, &mut g);
    let model = stable_model(&mut g, 2, 2, 1);
    let other = stable_model(&mut g, 3, 2, 1);
    let mut ric = Riccati::new(&spec, 2).unwrap();
    let (x, u, r) = (g.vec(4), g.vec(1), g.vec(6));
    let real = model.realization();
    assert!(ric.solve(&real, &x, &u, &r).is_ok());
    assert!(matches!(
        ric.solve(&other.realization(), &g.vec(6), &u, &r),
        Err(RiccatiError::Length {
            what: "realization n_hat",
            ..
        })
    ));
    assert!(matches!(
        ric.solve(&real, &x[..3], &u, &r),
        Err(RiccatiError::Length { what: "x0", .. })
    ));
    assert!(matches!(
        ric.solve(&real, &x, &u, &r[..5]),
        Err(RiccatiError::Length {
            what: "reference",
            ..
        })
    ));
    let mut bad = r.clone();
    bad[0] = f64::NAN;
    assert_eq!(
        ric.solve(&real, &x, &u, &bad),
        Err(RiccatiError::NonFinite { what: "reference" })
    );
    let mut bad = x.clone();
    bad[3] = f64::INFINITY;
    assert_eq!(
        ric.solve(&real, &bad, &u, &r),
        Err(RiccatiError::NonFinite { what: "x0" })
    );
    // Huge coefficients overflow the recursion: refused, not a non-finite U.
    let mut pr = io_model_params(
        2,
        2,
        1,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    pr.theta0 = vec![1e200; 12];
    let huge = IoModel::new(&pr).unwrap();
    assert!(ric.solve(&huge.realization(), &x, &u, &r).is_err());
}

#[test]
fn new_refuses_what_the_condenser_refuses_of_the_cost() {
    let mut g = Gauss::new(3);
    let c = Case {
        n_hat: 1,
        p: 2,
        m: 1,
        ell: 4,
        pt: 1,
        per_step: false,
        next_step: true,
    };
    let good = spec_of(&c, &mut g);
    assert!(Riccati::new(&good, 0).is_err());
    let mut s = good.clone();
    s.r = Weight::Scalar(0.0);
    assert!(Riccati::new(&s, 1).is_err());
    let mut s = good.clone();
    s.q = Weight::PerStep(vec![1.0; 3]);
    assert!(Riccati::new(&s, 1).is_err());
    let mut s = good.clone();
    s.tracking = vec![1.0];
    assert!(Riccati::new(&s, 1).is_err());
}

#[test]
fn the_operation_counts_are_those_of_the_module_docs() {
    // The sampling arm: N = 7, w = 8; ℓ (2·35·8 + 49 + 2·7·8 + 2·4·8) + ℓ (2·8 + 35).
    assert_eq!(
        Riccati::operation_count(1, 5, 2, 50),
        50 * (560 + 49 + 112 + 64) + 50 * 51
    );
    // The truss: N = 102, w = 104.
    let truss = Riccati::operation_count(25, 4, 2, 40);
    assert_eq!(
        truss,
        40 * (2 * 600 * 104 + 102 * 102 + 2 * 102 * 104 + 8 * 104) + 40 * (208 + 600)
    );
    assert_eq!(Riccati::operation_count(usize::MAX, 2, 2, 2), u64::MAX);
}

#[test]
fn new_refuses_states_beyond_its_rows() {
    let mut g = Gauss::new(4);
    let c = Case {
        n_hat: 10,
        p: 3,
        m: 2,
        ell: 4,
        pt: 1,
        per_step: false,
        next_step: true,
    };
    let mut spec = spec_of(&c, &mut g);
    // N = n̂p + m = 32 is the widest; 33 is refused.
    assert!(Riccati::new(&spec, 10).is_ok());
    assert!(Riccati::new(&spec, 11).is_err());
    spec.n_outputs = 1;
    spec.tracking = vec![1.0];
    assert!(Riccati::new(&spec, 30).is_ok());
    spec.n_inputs = 3;
    assert!(Riccati::new(&spec, 30).is_err());
}

/// [`Riccati::solve`] against condensing and the dense solve of the same unconstrained
/// problem (`Condenser::build` + `DenseQpSolver::solve`, cold) at the sampling arm's size
/// and two others; prints p50 and p99 (run with `cargo test --release -p control --lib
/// riccati_timing -- --ignored --nocapture`).
#[test]
#[ignore = "timing; run with --ignored --nocapture"]
fn riccati_timing() {
    use crate::linalg::percentile;
    use crate::mpc::qp::{DenseQpSolver, QpSettings, WarmStart};
    use std::time::Instant;
    let mut g = Gauss::new(1);
    for c in [
        Case {
            n_hat: 1,
            p: 5,
            m: 2,
            ell: 50,
            pt: 3,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 3,
            p: 2,
            m: 2,
            ell: 40,
            pt: 1,
            per_step: false,
            next_step: false,
        },
        Case {
            n_hat: 4,
            p: 1,
            m: 1,
            ell: 20,
            pt: 1,
            per_step: false,
            next_step: false,
        },
    ] {
        let spec = spec_of(&c, &mut g);
        let model = stable_model(&mut g, c.n_hat, c.p, c.m);
        let mut pred = HorizonPrediction::new(&model, c.ell).unwrap();
        pred.compute_from_state(&model).unwrap();
        let (u_k, reference) = (g.vec(c.m), g.vec(c.ell * c.pt));
        let mut ric = Riccati::new(&spec, c.n_hat).unwrap();
        let mut base = Riccati::new(&spec, c.n_hat).unwrap();
        base.avx2 = false;
        let mut cond = Condenser::new(&spec).unwrap();
        let mut solver = DenseQpSolver::new(cond.n(), cond.n_ineq(), QpSettings::default());
        let real = model.realization();
        let (mut tr, mut tb, mut td) = (Vec::new(), Vec::new(), Vec::new());
        let mut sink = 0.0;
        for _ in 0..3000 {
            let t = Instant::now();
            ric.solve(&real, pred.one_step_state(), &u_k, &reference)
                .unwrap();
            tr.push(t.elapsed().as_secs_f64() * 1e6);
            sink += ric.u()[0];
            let t = Instant::now();
            base.solve(&real, pred.one_step_state(), &u_k, &reference)
                .unwrap();
            tb.push(t.elapsed().as_secs_f64() * 1e6);
            sink += base.u()[0];
            let t = Instant::now();
            let qp = cond
                .build(pred.markov(), pred.free_response(), &u_k, &reference)
                .unwrap();
            solver.solve(&qp, WarmStart::Cold);
            td.push(t.elapsed().as_secs_f64() * 1e6);
            sink += solver.x()[0];
        }
        println!(
            "n̂ {}, p {}, m {}, ℓ {}: Riccati min {:.2} µs p50 {:.2} µs p99 {:.2} µs ({} multiply–adds, \
             AVX2 form {}); baseline form min {:.2} µs p50 {:.2} µs; \
             condensing + dense solve min {:.2} µs p50 {:.2} µs p99 {:.2} µs ({sink:.1e})",
            c.n_hat,
            c.p,
            c.m,
            c.ell,
            percentile(&mut tr, 0.0),
            percentile(&mut tr, 0.5),
            percentile(&mut tr, 0.99),
            Riccati::operation_count(c.n_hat, c.p, c.m, c.ell),
            ric.avx2,
            percentile(&mut tb, 0.0),
            percentile(&mut tb, 0.5),
            percentile(&mut td, 0.0),
            percentile(&mut td, 0.5),
            percentile(&mut td, 0.99),
        );
    }
}
