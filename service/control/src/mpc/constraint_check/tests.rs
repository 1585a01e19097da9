//! The check against the QP solver's own verdict: on random constrained problems, the
//! unconstrained minimizer passes exactly when the solver, started cold, returns it with an
//! empty active set; and each kind of constraint, moved just past the plan, fails it.

use super::*;
use crate::bocf::{HorizonPrediction, Realization};
use crate::mpc::condense::{Condenser, MoveBounds, OutputConstraints, Weight};
use crate::mpc::qp::{ConstraintId, DenseQpSolver, QpSettings, QpStatus, WarmStart};
use crate::mpc::riccati::Riccati;
// A stable model (`‖F̂_i‖_F = 0.9 / n`) with random histories.
use crate::mpc::riccati::tests::stable_model as model;
use crate::pcac::IoModel;
use crate::test_support::{Gauss, max_abs, max_abs_diff};

const TOL: f64 = 1e-10;

/// A spec with input bounds `±u_max`, move bounds `±du_max` and the output constraint
/// `y_1 ≤ y_max` (all optional through their size), tracking `y_1`.
fn spec(ell: usize, p: usize, m: usize, u_max: f64, du_max: f64, y_max: f64) -> MpcSpec {
    let mut c = vec![0.0; p];
    c[0] = 1.0;
    MpcSpec {
        horizon: ell,
        n_inputs: m,
        n_outputs: p,
        n_tracked: 1,
        tracking: c.clone(),
        q: Weight::Scalar(5.0),
        r: Weight::Scalar(0.5),
        u_min: vec![-u_max; m],
        u_max: vec![u_max; m],
        move_bounds: Some(MoveBounds::symmetric(du_max, m)),
        output_constraints: Some(OutputConstraints { c, d: vec![-y_max] }),
        input_notch: None,
    }
}

/// The data of one problem: the prediction, `u_k`, the command.
struct Data {
    model: IoModel,
    pred: HorizonPrediction,
    u_k: Vec<f64>,
    reference: Vec<f64>,
}

fn data(g: &mut Gauss, ell: usize, p: usize, m: usize, level: f64) -> Data {
    let model = model(g, 2, p, m);
    let mut pred = HorizonPrediction::new(&model, ell).unwrap();
    let u_k: Vec<f64> = g.vec(m).iter().map(|v| 0.3 * v).collect();
    pred.compute(&model, &u_k).unwrap();
    Data {
        model,
        pred,
        u_k,
        reference: vec![level; ell],
    }
}

/// `U*` and its outputs for `spec` on `d`.
fn minimizer(spec: &MpcSpec, d: &Data) -> (Vec<f64>, Vec<f64>) {
    let mut ric = Riccati::new(spec, 2).unwrap();
    let real: Realization<'_> = d.model.realization();
    ric.solve(&real, d.pred.one_step_state(), &d.u_k, &d.reference)
        .unwrap();
    (ric.u().to_vec(), ric.outputs().to_vec())
}

fn satisfied(spec: &MpcSpec, d: &Data, u: &[f64], y: &[f64]) -> bool {
    ConstraintCheck::new(spec, TOL).satisfied(u, y, d.pred.free_response(), d.pred.markov(), &d.u_k)
}

#[test]
fn the_minimizer_passes_exactly_when_the_solver_keeps_it_with_no_active_constraint() {
    let mut g = Gauss::new(23);
    let (ell, p, m) = (12, 2, 2);
    let (mut passed, mut failed) = (0, 0);
    for case in 0..120 {
        // Commands from small to large, bounds from loose to tight.
        let level = 0.2 + 0.05 * (case % 40) as f64;
        let u_max = [0.6, 3.0, 30.0][case % 3];
        let du_max = [0.3, 3.0, 30.0][(case / 3) % 3];
        let y_max = [1.0, 10.0, 100.0][(case / 9) % 3];
        let s = spec(ell, p, m, u_max, du_max, y_max);
        let d = data(&mut g, ell, p, m, level);
        let (u, y) = minimizer(&s, &d);
        let ok = satisfied(&s, &d, &u, &y);
        let mut cond = Condenser::new(&s).unwrap();
        let (n, n_ineq) = (cond.n(), cond.n_ineq());
        let qp = cond
            .build(
                d.pred.markov(),
                d.pred.free_response(),
                &d.u_k,
                &d.reference,
            )
            .unwrap();
        let mut solver = DenseQpSolver::new(n, n_ineq, QpSettings::default());
        let st = solver.solve(&qp, WarmStart::Cold);
        let mut active = vec![ConstraintId::Row(0); n + n_ineq];
        let na = solver.active_set_into(&mut active);
        if st == QpStatus::Infeasible {
            assert!(!ok, "case {case}: passed an infeasible problem");
            failed += 1;
            continue;
        }
        assert_eq!(st, QpStatus::Solved, "case {case}");
        assert_eq!(ok, na == 0, "case {case}: {na} active, check {ok}");
        if ok {
            let d = max_abs_diff(solver.x(), &u) / max_abs(&u).max(1e-3);
            assert!(d < 1e-9, "case {case}: the solver moved U* by {d:e}");
            passed += 1;
        } else {
            failed += 1;
        }
    }
    eprintln!("the minimizer passed {passed} and failed {failed} of 120 checks");
    assert!(
        passed >= 20 && failed >= 20,
        "passed {passed}, failed {failed}"
    );
}

#[test]
fn each_kind_of_constraint_just_past_the_plan_fails_it() {
    let mut g = Gauss::new(8);
    let (ell, p, m) = (10, 2, 2);
    let loose = spec(ell, p, m, 1e3, 1e3, 1e3);
    let d = data(&mut g, ell, p, m, 1.0);
    let (u, y) = minimizer(&loose, &d);
    assert!(satisfied(&loose, &d, &u, &y));
    let margin = |v: f64| 1e-6 * (1.0 + v.abs());
    // Input bounds (2.50): at the largest |u|.
    let u_top = max_abs(&u);
    assert!(satisfied(
        &spec(ell, p, m, u_top + margin(u_top), 1e3, 1e3),
        &d,
        &u,
        &y
    ));
    assert!(!satisfied(
        &spec(ell, p, m, u_top - margin(u_top), 1e3, 1e3),
        &d,
        &u,
        &y
    ));
    // Move bounds (2.51), the first move relative to u_k included.
    let moves: Vec<f64> = (0..ell * m)
        .map(|k| u[k] - if k < m { d.u_k[k] } else { u[k - m] })
        .collect();
    let du_top = max_abs(&moves);
    assert!(satisfied(
        &spec(ell, p, m, 1e3, du_top + margin(du_top), 1e3),
        &d,
        &u,
        &y
    ));
    assert!(!satisfied(
        &spec(ell, p, m, 1e3, du_top - margin(du_top), 1e3),
        &d,
        &u,
        &y
    ));
    // The first move alone: with u_k moved so that u_{1|k} − u_k exceeds the bound and
    // no later move does.
    let later = max_abs(&moves[m..]);
    let bound = later + 1e-3;
    let u_k: Vec<f64> = u[..m].iter().map(|u0| u0 - (later + 2e-3)).collect();
    let tight = spec(ell, p, m, 1e3, bound, 1e3);
    let check = |u_k: &[f64]| {
        ConstraintCheck::new(&tight, TOL).satisfied(
            &u,
            &y,
            d.pred.free_response(),
            d.pred.markov(),
            u_k,
        )
    };
    assert!(!check(&u_k));
    let u_k: Vec<f64> = u[..m].iter().map(|u0| u0 - later).collect();
    assert!(check(&u_k));
    // Output constraints (2.49) on y_1 of the steps U reaches.
    let y1_top = (1..ell).map(|i| y[i * p]).fold(f64::NEG_INFINITY, f64::max);
    let y0 = y[0];
    if y1_top > y0 {
        assert!(satisfied(
            &spec(ell, p, m, 1e3, 1e3, y1_top + margin(y1_top)),
            &d,
            &u,
            &y
        ));
        assert!(!satisfied(
            &spec(ell, p, m, 1e3, 1e3, y1_top - margin(y1_top)),
            &d,
            &u,
            &y
        ));
    }
    // y_{1|k} already violating its constraint: the QP is infeasible, the check fails.
    assert!(!satisfied(
        &spec(ell, p, m, 1e3, 1e3, y0 - 1e-3 * (1.0 + y0.abs())),
        &d,
        &u,
        &y
    ));
    // Wrong sizes and NaN fail, without a panic.
    assert!(!satisfied(&loose, &d, &u[1..], &y));
    let mut bad = u.clone();
    bad[3] = f64::NAN;
    assert!(!satisfied(&loose, &d, &bad, &y));
}
