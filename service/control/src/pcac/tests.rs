//! Tests of PCAC's model: identification and the Kronecker reduction (the realization's
//! tests are in [`crate::bocf`]); and of the step's unconstrained fast path
//! ([`crate::mpc::fast_path`]) against condensing and the QP, in closed loop.

#![allow(clippy::needless_range_loop)] // index-heavy reference computations

use super::model::{DimError, IdKernel, IoModel, IoModelParams};
use crate::forgetting::ForgettingRule;
use crate::test_support::{Gauss, f_test, io_model_params, max_abs, max_abs_diff};

fn ftest() -> ForgettingRule {
    f_test(10, 80, 1.0, 0.001)
}

/// A MIMO ARX system (2.24) with known coefficients, simulated exactly.
struct Arx {
    n: usize,
    p: usize,
    m: usize,
    /// `Θ̃ = [F_1 … F_n G_1 … G_n]`, p × n(p+m) row-major.
    coef: Vec<f64>,
    ys: Vec<Vec<f64>>,
    us: Vec<Vec<f64>>,
}

impl Arx {
    /// Stable by construction: `‖F_i‖_F = 0.9 / n`, so `Σ ‖F_i‖₂ < 1`.
    fn random(g: &mut Gauss, n: usize, p: usize, m: usize) -> Self {
        let nr = n * (p + m);
        let mut coef = vec![0.0; p * nr];
        for i in 0..n {
            let blk = g.vec(p * p);
            let norm = blk.iter().map(|x| x * x).sum::<f64>().sqrt();
            for r in 0..p {
                for s in 0..p {
                    coef[r * nr + i * p + s] = 0.9 / n as f64 * blk[r * p + s] / norm;
                }
            }
            for r in 0..p {
                for s in 0..m {
                    coef[r * nr + n * p + i * m + s] = g.normal();
                }
            }
        }
        Self {
            n,
            p,
            m,
            coef,
            ys: vec![vec![0.0; p]; n],
            us: vec![vec![0.0; m]; n],
        }
    }

    /// A random system and the random coefficients it jumps to later (drawn after it).
    fn random_with_jump(g: &mut Gauss, n: usize, p: usize, m: usize) -> (Self, Vec<f64>) {
        let sys = Self::random(g, n, p, m);
        let jump = Self::random(g, n, p, m).coef;
        (sys, jump)
    }

    /// `y_k` given `u_{k−1}` (pushed first); histories newest first.
    fn step(&mut self, u_prev: &[f64]) -> Vec<f64> {
        let (n, p, m) = (self.n, self.p, self.m);
        let nr = n * (p + m);
        self.us.insert(0, u_prev.to_vec());
        self.us.truncate(n);
        let mut y = vec![0.0; p];
        for r in 0..p {
            for i in 0..n {
                for s in 0..p {
                    y[r] -= self.coef[r * nr + i * p + s] * self.ys[i][s];
                }
                for s in 0..m {
                    y[r] += self.coef[r * nr + n * p + i * m + s] * self.us[i][s];
                }
            }
        }
        self.ys.insert(0, y.clone());
        self.ys.truncate(n);
        y
    }
}

#[test]
fn identification_recovers_a_stable_mimo_arx_system_exactly() {
    let (n, p, m) = (3, 2, 2);
    let mut g = Gauss::new(11);
    let mut sys = Arx::random(&mut g, n, p, m);
    let mut worst: f64 = 0.0;
    for kernel in [IdKernel::Shared, IdKernel::Full] {
        let mut pr = io_model_params(n, p, m, ForgettingRule::Constant { lambda: 1.0 }, kernel);
        pr.p0 = 1e8;
        let mut model = IoModel::new(&pr).unwrap();
        let mut gu = Gauss::new(12);
        sys.ys.iter_mut().for_each(|v| v.fill(0.0));
        sys.us.iter_mut().for_each(|v| v.fill(0.0));
        let mut u_prev = vec![0.0; m];
        for _ in 0..400 {
            let y = sys.step(&u_prev);
            let st = model.update(&y, &u_prev).unwrap();
            assert!(!st.reset);
            u_prev = gu.vec(m);
        }
        let d = max_abs_diff(model.coefficients(), &sys.coef);
        assert!(d < 1e-8, "{kernel:?}: coefficients off by {d}");
        assert!(model.last_step().error_norm < 1e-9);
        worst = worst.max(d);
    }
    eprintln!("identification: max coefficient error {worst:.2e}");
}

#[test]
fn shared_covariance_rls_equals_the_full_kronecker_rls() {
    // p = 4 outputs (the truss), F-test forgetting fed with the 4-dimensional z_k, noise
    // and a parameter jump, so forgetting is exercised.
    let (n, p, m) = (4, 4, 2);
    let mut g = Gauss::new(21);
    let (mut sys, jump) = Arx::random_with_jump(&mut g, n, p, m);
    let mut th0 = g.vec(n * p * (p + m));
    th0.iter_mut().for_each(|x| *x *= 0.1);
    let mk = |kernel| {
        let mut pr = io_model_params(n, p, m, ftest(), kernel);
        pr.theta0 = th0.clone();
        pr.p0 = 10.0;
        IoModel::new(&pr).unwrap()
    };
    let (mut a, mut b) = (mk(IdKernel::Shared), mk(IdKernel::Full));
    let mut u_prev = vec![0.0; m];
    let (mut forgot, mut dl) = (0, 0.0f64);
    for k in 0..1500 {
        if k == 800 {
            sys.coef.copy_from_slice(&jump);
        }
        let mut y = sys.step(&u_prev);
        y.iter_mut().for_each(|v| *v += 0.01 * g.normal());
        let sa = a.update(&y, &u_prev).unwrap();
        let sb = b.update(&y, &u_prev).unwrap();
        assert!(!sa.reset && !sb.reset);
        dl = dl.max((sa.lambda - sb.lambda).abs());
        forgot += usize::from(sa.lambda < 1.0);
        assert!(max_abs_diff(a.prior_error(), b.prior_error()) < 1e-9 * (1.0 + max_abs(&y)));
        u_prev = g.vec(m);
    }
    assert!(forgot > 0, "forgetting was not exercised");
    assert!(dl < 1e-10, "lambda differs by {dl}");
    let dth = max_abs_diff(a.coefficients(), b.coefficients()) / max_abs(b.coefficients());
    assert!(dth < 1e-9, "theta differs by {dth} (relative)");
    // P_k = P̃_k ⊗ I_p: the full kernel's covariance has the Kronecker form.
    let (pa, pb) = (a.covariance(), b.covariance());
    let dp = (&pa - &pb).abs().max() / pb.abs().max();
    assert!(dp < 1e-9, "P differs from P̃ ⊗ I_p by {dp} (relative)");
    assert!(((a.trace_p() - b.trace_p()) / b.trace_p()).abs() < 1e-9);
    eprintln!(
        "shared vs full: θ {dth:.2e}, P {dp:.2e}, λ {dl:.2e} (relative/absolute), {forgot} steps forgot"
    );
}

/// F-test forgetting on the identification of a MIMO system: quiet on stationary noise,
/// active after a jump of the coefficients.
#[test]
fn f_test_forgetting_reacts_to_a_jump_and_not_to_noise() {
    let (n, p, m) = (2, 2, 2);
    let mut g = Gauss::new(51);
    let (mut sys, after) = Arx::random_with_jump(&mut g, n, p, m);
    let run = |rule: ForgettingRule, g: &mut Gauss, sys: &mut Arx| {
        let mut model = IoModel::new(&io_model_params(n, p, m, rule, IdKernel::Shared)).unwrap();
        let mut lambdas = Vec::new();
        let before = sys.coef.clone();
        let mut u_prev = vec![0.0; m];
        for k in 0..3300 {
            if k == 3000 {
                sys.coef.copy_from_slice(&after);
            }
            let mut y = sys.step(&u_prev);
            y.iter_mut().for_each(|v| *v += 0.05 * g.normal());
            lambdas.push(model.update(&y, &u_prev).unwrap().lambda);
            u_prev = g.vec(m);
        }
        sys.coef.copy_from_slice(&before);
        let err = max_abs_diff(model.coefficients(), &after);
        (lambdas, err)
    };
    let (lam, err_ft) = run(ftest(), &mut Gauss::new(52), &mut sys);
    let (_, err_const) = run(
        ForgettingRule::Constant { lambda: 1.0 },
        &mut Gauss::new(52),
        &mut sys,
    );
    let noise_forget = lam[100..3000].iter().filter(|&&l| l < 1.0).count();
    let jump_forget = lam[3000..3030].iter().filter(|&&l| l < 1.0).count();
    eprintln!(
        "F-test: forgot in {noise_forget}/2900 stationary steps, {jump_forget}/30 after the jump; \
         final error {err_ft:.3} vs {err_const:.3} without forgetting"
    );
    assert!(
        noise_forget <= 29,
        "forgot {noise_forget} times on stationary noise"
    );
    assert!(
        jump_forget >= 3,
        "forgot only {jump_forget} times after the jump"
    );
    assert!(err_ft < 0.5 * err_const, "{err_ft} vs {err_const}");
}

#[test]
fn bad_parameters_and_lengths_are_refused_with_a_message() {
    let ok = io_model_params(3, 2, 1, ftest(), IdKernel::Shared);
    assert!(IoModel::new(&ok).is_ok());
    let bad = |f: &dyn Fn(&mut IoModelParams), want: &str| {
        for kernel in [IdKernel::Shared, IdKernel::Full] {
            let mut pr = ok.clone();
            pr.kernel = kernel;
            f(&mut pr);
            let e = IoModel::new(&pr).unwrap_err();
            assert!(e.contains(want), "{e:?} does not mention {want:?}");
        }
    };
    bad(&|p| p.n_hat = 0, "n_hat");
    bad(&|p| p.p = 0, "outputs");
    bad(&|p| p.m = 0, "inputs");
    bad(&|p| p.p0 = 0.0, "p0");
    bad(&|p| p.p0 = -1.0, "p0");
    bad(&|p| p.p0 = f64::NAN, "p0");
    bad(
        &|p| p.theta0 = vec![0.0; 5],
        "theta0 has length 5, expected n_hat·p·(p+m) = 18",
    );
    bad(&|p| p.theta0 = vec![f64::NAN; 18], "theta0");
    bad(&|p| p.trace_limit = 10.0, "trace_limit");
    bad(&|p| p.rule = f_test(2, 5, 1.0, 0.01), "forgetting");

    let mut model = IoModel::new(&ok).unwrap();
    let e = model.update(&[1.0], &[0.0]).unwrap_err();
    assert_eq!(
        e,
        DimError {
            what: "y",
            expected: 2,
            got: 1
        }
    );
    assert_eq!(e.to_string(), "y has length 1, expected 2");
    assert!(model.update(&[1.0, 2.0], &[0.0, 0.0]).is_err());
    assert_eq!(model.samples(), 0, "a refused update must change nothing");
    assert!(model.theta_vec(&mut [0.0; 17]).is_err());
    assert!(model.theta_vec(&mut [0.0; 18]).is_ok());
}

#[test]
fn non_finite_data_reset_the_estimate_without_nan() {
    for kernel in [IdKernel::Shared, IdKernel::Full] {
        let mut model = IoModel::new(&io_model_params(2, 2, 1, ftest(), kernel)).unwrap();
        let mut g = Gauss::new(61);
        for _ in 0..50 {
            model.update(&g.vec(2), &g.vec(1)).unwrap();
        }
        let st = model.update(&[f64::NAN, 0.0], &[0.0]).unwrap();
        assert!(st.reset);
        assert_eq!(model.resets(), 1);
        assert!(model.coefficients().iter().all(|&x| x == 0.0));
        assert_eq!(model.trace_p(), 2.0 * 2.0 * 3.0 * 100.0);
    }
}

#[test]
fn both_forms_reset_at_the_same_steps_on_a_covariance_blow_up() {
    // No excitation and λ = 0.5: tr P doubles per step until the limit resets it.
    let mut steps = Vec::new();
    for kernel in [IdKernel::Shared, IdKernel::Full] {
        let mut pr = io_model_params(2, 2, 1, ForgettingRule::Constant { lambda: 0.5 }, kernel);
        pr.trace_limit = 1e6;
        let mut model = IoModel::new(&pr).unwrap();
        let resets: Vec<bool> = (0..60)
            .map(|_| model.update(&[0.0, 0.0], &[0.0]).unwrap().reset)
            .collect();
        assert!(model.trace_p() <= 1e6);
        assert!(model.resets() >= 5, "{kernel:?}: {} resets", model.resets());
        steps.push(resets);
    }
    assert_eq!(steps[0], steps[1]);
}

/// Timing of one identification step at the truss size (n̂ = 25, p = 4, m = 2), both
/// forms: `cargo test --release -p control --lib pcac_id_timing -- --ignored --nocapture`.
#[test]
#[ignore]
fn pcac_id_timing() {
    let (n, p, m) = (25, 4, 2);
    for kernel in [IdKernel::Shared, IdKernel::Full] {
        let mut model = IoModel::new(&io_model_params(n, p, m, ftest(), kernel)).unwrap();
        let mut g = Gauss::new(71);
        let data: Vec<(Vec<f64>, Vec<f64>)> = (0..2000).map(|_| (g.vec(p), g.vec(m))).collect();
        let mut times = Vec::with_capacity(data.len());
        for (y, u) in &data {
            let t = std::time::Instant::now();
            model.update(y, u).unwrap();
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
        times.sort_by(f64::total_cmp);
        let q = |f: f64| times[((times.len() - 1) as f64 * f) as usize];
        eprintln!(
            "{kernel:?}: update p50 {:.1} µs, p99 {:.1} µs",
            q(0.5),
            q(0.99)
        );
    }
}

// ---------------------------------------------------------------------------------------
// The unconstrained fast path in the step.

/// PCAC on the plant `sys` (`n̂ 2`, `p 2`, `m 2`, `θ_0` its coefficients, identification
/// on), `ℓ = 15`, tracking `y_1` with `Q = 10`, `R = diag(0.1, 0.2)`, `|u| ≤ 1`,
/// `|Δu| ≤ 0.4`, `y_2 ≤ 0.8` at every predicted step when `output_constraint` (without
/// it, the fast path defers the prediction's horizon,
/// [`crate::bocf::HorizonPrediction::defer_horizon`]), the fast path `mode`, re-planning
/// every `replan` samples; optionally augmenting `K̄ = −0.1 I` (7.53)–(7.57).
fn fast_path_params(
    sys: &Arx,
    mode: crate::mpc::fast_path::FastPathMode,
    (timing, augmented, replan, output_constraint): (super::PcacTiming, bool, usize, bool),
) -> super::PcacParams {
    use crate::mpc::condense::{MoveBounds, OutputConstraints, Weight};
    let (n, p, m) = (sys.n, sys.p, sys.m);
    let nr = n * (p + m);
    super::PcacParams::builder(n, p, m, 1.0, 15)
        // θ = vec Θ̃, column-stacked (2.27).
        .theta0(
            (0..p * nr)
                .map(|k| sys.coef[(k % p) * nr + k / p])
                .collect(),
        )
        .tracking(1, vec![1.0, 0.0])
        .q(Weight::Scalar(10.0))
        .r(Weight::PerChannel(vec![0.1, 0.2]))
        .input_bounds(vec![-1.0; 2], vec![1.0; 2])
        .move_bounds(Some(MoveBounds::symmetric(0.4, 2)))
        .output_constraints(output_constraint.then(|| OutputConstraints {
            c: vec![0.0, 1.0],
            d: vec![-0.8],
        }))
        .timing(timing)
        .fast_path(mode)
        .replan_every(replan)
        .augmentation(augmented.then(|| super::OutputFeedback {
            gain: vec![-0.1, 0.0, 0.0, -0.1],
        }))
        .build()
}

/// One step of a fast-path run: the input, the plan's rows, whether the fast path gave
/// them, and the QP's active-set size.
struct FastStep {
    u: Vec<f64>,
    plan: Vec<f64>,
    fast: bool,
    active: f64,
}

/// 400 samples of `params` in closed loop with a copy of `sys` (measurement noise
/// `10⁻³`), the command of `y_1` a square wave between 0 and 1.2 of period 60 samples
/// (large enough that the plans ride the bounds after each edge, and settle inside
/// them); the steps and the controller's counters.
fn fast_path_run(sys: &Arx, params: &super::PcacParams) -> (Vec<FastStep>, super::PcacCounters) {
    use crate::{Controller, Dimensions, StepInput};
    let mut sys = Arx {
        n: sys.n,
        p: sys.p,
        m: sys.m,
        coef: sys.coef.clone(),
        ys: vec![vec![0.0; sys.p]; sys.n],
        us: vec![vec![0.0; sys.m]; sys.n],
    };
    let mut c = super::Pcac::new(params, Dimensions::new(2, 2, 1, 2)).unwrap();
    let gain = params.augmentation.as_ref().map(|fb| fb.gain.clone());
    let mut noise = Gauss::new(77);
    let mut plant_input = vec![0.0; 2];
    let mut internals = [0.0; crate::MAX_INTERNALS];
    let names = c.internal_names();
    let active_at = names.iter().position(|s| s == "qp_active").unwrap();
    let mut out = Vec::new();
    for k in 0..400 {
        let mut y = sys.step(&plant_input);
        y.iter_mut().for_each(|v| *v += 1e-3 * noise.normal());
        let r = [if (k / 30) % 2 == 1 { 1.2 } else { 0.0 }];
        let mut u = vec![f64::NAN; 2];
        let status = c.step(
            &StepInput {
                seq: k as u64,
                y: &y,
                z: &y,
                r: &r,
                ..Default::default()
            },
            &mut u,
        );
        assert_eq!(status & crate::status::FALLBACK, 0, "step {k} fell back");
        let mut plan = vec![0.0; 2 * 14];
        let rows = c.ahead().map_or(0, |a| a.plan(&mut plan));
        plan.truncate(2 * rows);
        c.internals(&mut internals);
        out.push(FastStep {
            fast: c.fast_path_taken(),
            active: internals[active_at],
            u: u.clone(),
            plan,
        });
        // The plant's input: u, or K̄ y + u with the augmentation.
        plant_input.copy_from_slice(&u);
        if let Some(g) = &gain {
            for (j, pi) in plant_input.iter_mut().enumerate() {
                *pi += g[j * 2] * y[0] + g[j * 2 + 1] * y[1];
            }
        }
    }
    (out, c.counts_of())
}

/// With and without the fast path the controller gives the same inputs (and, in the
/// next-step timing, the same plans) to 10⁻⁹ on a closed loop whose constraints are
/// active after each edge of the command and inactive in between; the fast path is taken
/// exactly at the solves whose QP has an empty active set, and falls back to condensing
/// and the QP at the others; in four configurations (same step, next step, an augmented
/// `K̄`, and next step re-planning every 3 samples, where the fast path runs in the
/// condensing unit's period and the plan in force is its `U*`), and in the last two
/// without the output constraint, where the fast path's step defers the prediction's
/// horizon and a fallback completes it.
#[test]
fn the_fast_path_gives_the_qps_inputs_and_falls_back_when_a_constraint_is_active() {
    use super::PcacTiming;
    use crate::mpc::fast_path::FastPathMode;
    let mut g = Gauss::new(31);
    let sys = Arx::random(&mut g, 2, 2, 2);
    for case in [
        (PcacTiming::SameStep, false, 1, true),
        (PcacTiming::NextStep, false, 1, true),
        (PcacTiming::SameStep, true, 1, true),
        (PcacTiming::NextStep, false, 3, true),
        // Without the output constraint the horizon of the prediction is deferred, and
        // completed where the QP runs.
        (PcacTiming::SameStep, true, 1, false),
        (PcacTiming::NextStep, false, 3, false),
    ] {
        let (timing, augmented, replan, output_constraint) = case;
        let what = format!(
            "{timing:?}, augmented {augmented}, replan-every {replan}, output constraint \
             {output_constraint}"
        );
        let (with, cw) = fast_path_run(&sys, &fast_path_params(&sys, FastPathMode::Always, case));
        let (without, co) = fast_path_run(&sys, &fast_path_params(&sys, FastPathMode::Never, case));
        let (mut du, mut dplan) = (0.0f64, 0.0f64);
        for (k, (a, b)) in with.iter().zip(&without).enumerate() {
            du = du.max(max_abs_diff(&a.u, &b.u));
            assert_eq!(a.plan.len(), b.plan.len(), "{what}: step {k}");
            if !a.plan.is_empty() {
                dplan = dplan.max(max_abs_diff(&a.plan, &b.plan));
            }
            assert!(!b.fast, "{what}: step {k}");
            // The fast path is the QP's solution exactly when no constraint is active
            // (the active-set size is that of the last solve at the solve's own sample:
            // every sample, or every third one when re-planning).
            if k % replan == replan - 1 {
                assert_eq!(
                    a.fast,
                    b.active == 0.0,
                    "{what}: step {k}, {} active",
                    b.active
                );
                if a.fast {
                    assert_eq!(a.active, 0.0, "{what}: step {k}");
                }
            }
        }
        assert!(du < 1e-9, "{what}: inputs differ by {du:e}");
        assert!(dplan < 1e-9, "{what}: plans differ by {dplan:e}");
        if timing == PcacTiming::NextStep && replan == 1 {
            assert!(with.iter().all(|s| s.plan.len() == 2 * 14), "{what}");
        }
        if replan > 1 {
            // The plant follows the plan between solves: the plan rows are read.
            assert!(with.iter().any(|s| !s.plan.is_empty()), "{what}");
        }
        // Both branches ran, and the counters say so.
        let solves = 400u64.div_ceil(replan as u64);
        let solved_at_end = with
            .iter()
            .enumerate()
            .filter(|(k, s)| k % replan == replan - 1 && s.fast)
            .count() as u64;
        assert_eq!(cw.fast_path, solved_at_end, "{what}");
        assert_eq!(co.fast_path, 0, "{what}");
        assert_eq!((cw.steps, co.steps), (solves, solves), "{what}");
        let solved = 400 / replan as u64;
        assert_eq!((cw.solved, co.solved), (solved, solved), "{what}");
        let taken = cw.fast_path;
        assert!(
            taken >= solved / 4,
            "{what}: fast path at {taken} of {solved} solves"
        );
        assert!(
            cw.solved - taken >= solved / 20,
            "{what}: {} solves fell back to the QP",
            cw.solved - taken
        );
        eprintln!("{what}: fast path {taken}/{solved}, |Δu| {du:.1e}, |Δplan| {dplan:.1e}");
    }
}

/// [`FastPathMode::Auto`] takes the fast path at the sampling arm's size (§7.3: `n̂ 1`,
/// `p 5`, `m 2`, `ℓ 50`) and not at the truss's (§6.2: `n̂ 25`, `p 4`, `ℓ 40`), and the
/// counter names it.
#[test]
fn auto_takes_the_fast_path_for_the_arm_and_not_for_the_truss() {
    use crate::{Controller, Dimensions, StepInput};
    let arm = super::PcacParams::chapter_7().build();
    let truss = super::PcacParams::chapter_6().build();
    for (params, p, want) in [(arm, 5, true), (truss, 4, false)] {
        let m = params.model.m;
        let mut c = super::Pcac::new(&params, Dimensions::new(p, p, 0, m)).unwrap();
        let y = vec![0.01; p];
        let mut u = vec![0.0; m];
        for k in 0..3 {
            let input = StepInput {
                seq: k,
                y: &y,
                z: &y,
                ..Default::default()
            };
            c.step(&input, &mut u);
        }
        let taken = c.counts_of().fast_path;
        assert_eq!(
            taken > 0,
            want,
            "n̂ = {}: fast path at {taken} steps",
            params.model.n_hat
        );
        assert!(c.counters().contains(&("fast path", taken)));
    }
}
