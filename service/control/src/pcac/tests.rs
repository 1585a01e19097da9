//! Tests of PCAC's model: identification and the Kronecker reduction (the realization's
//! tests are in [`crate::bocf`]).

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
