//! Tests of the target-model filter, the regressor bookkeeping, the gradient step sizes,
//! the real-time guards and closed-loop disturbance rejection on small discrete plants.

use super::*;
use crate::target::{TargetChannel, TargetForm};
use crate::test_support::Gauss;

fn counts(n_y: usize, n_z: usize, n_u: usize) -> Dimensions {
    Dimensions {
        n_y,
        n_z,
        n_r: 0,
        n_u,
    }
}

fn tf(output: usize, input: usize, delay: usize, num: &[f64], den: &[f64]) -> TargetChannel {
    TargetChannel {
        output,
        input,
        delay,
        num: num.to_vec(),
        den: den.to_vec(),
    }
}

const TS: f64 = 0.01;

/// A 2×2 transfer-function target with IIR channels, per-input delays, β and a zero
/// channel.
fn mimo_tf_target() -> TargetModel {
    TargetModel {
        sample_period: TS,
        outputs: 2,
        inputs: 2,
        beta: 0.8,
        source: "test".into(),
        form: TargetForm::TransferFunction(vec![
            tf(0, 0, 1, &[0.5], &[1.0, -0.5]),
            tf(0, 1, 3, &[0.2, 0.1], &[1.0, -1.2, 0.5]),
            tf(1, 0, 0, &[-0.3, 0.4], &[1.0, 0.3, 0.1]),
            // (1, 1) missing: zero.
        ]),
    }
}

/// A 1×2 transfer-function target (`β = 1`) with the given channels.
fn miso_tf_target(channels: Vec<TargetChannel>) -> TargetModel {
    TargetModel {
        sample_period: TS,
        outputs: 1,
        inputs: 2,
        beta: 1.0,
        source: String::new(),
        form: TargetForm::TransferFunction(channels),
    }
}

/// `φ_m = [u_{m−1}; …; u_{m−n_c}; y_{m−1}; …; y_{m−n_c}]` with zeros before time 0.
fn phi_direct(
    us: &[Vec<f64>],
    ys: &[Vec<f64>],
    m: isize,
    nc: usize,
    (lu, ly): (usize, usize),
) -> Vec<f64> {
    let mut v = Vec::new();
    let get = |h: &[Vec<f64>], t: isize, n: usize| -> Vec<f64> {
        if t < 0 {
            vec![0.0; n]
        } else {
            h[t as usize].clone()
        }
    };
    for i in 1..=nc as isize {
        v.extend(get(us, m - i, lu));
    }
    for i in 1..=nc as isize {
        v.extend(get(ys, m - i, ly));
    }
    v
}

/// The filter against the direct convolution `Σ_i H_i (·)_{k−i}` with
/// `TargetModel::markov`, for the IIR transfer-function form and for the FIR form.
#[test]
fn the_filter_equals_the_direct_convolution_with_the_markov_parameters() {
    let tf_model = mimo_tf_target();
    let fir_model = TargetModel {
        form: TargetForm::Markov(tf_model.markov(12)),
        beta: 0.5,
        ..tf_model.clone()
    };
    for model in [tf_model, fir_model] {
        let (ly, nc) = (1, 3);
        let (lz, lu) = (model.outputs, model.inputs);
        let mut f = TargetFilter::new(&model, ly, nc).unwrap();
        let nphi = f.regressor_len();
        assert_eq!(nphi, nc * (lu + ly));
        let lt = lu * nphi;
        let steps = 200;
        let h = model.markov(steps + 1);
        let mut g = Gauss::new(3);
        let (mut us, mut ys) = (Vec::new(), Vec::new());
        let mut phi_f = vec![0.0; lz * lt];
        let mut u_f = vec![0.0; lz];
        let mut worst: f64 = 0.0;
        for k in 0..steps {
            f.filter(&mut phi_f, &mut u_f);
            // Regressor windows of the stored history.
            for m in [0, 2] {
                let (pu, py) = f.regressor(m);
                let want = phi_direct(&us, &ys, k as isize - m as isize, nc, (lu, ly));
                let got: Vec<f64> = pu.iter().chain(py).copied().collect();
                assert_eq!(got, want, "k = {k}, m = {m}");
            }
            for o in 0..lz {
                let mut uf = 0.0;
                for j in 0..lu {
                    let mut psi = vec![0.0; nphi];
                    for (i, hi) in h.iter().enumerate().take(k + 1) {
                        let c = hi[(o, j)];
                        if c == 0.0 {
                            continue;
                        }
                        let ph = phi_direct(&us, &ys, k as isize - i as isize, nc, (lu, ly));
                        for (p, v) in psi.iter_mut().zip(&ph) {
                            *p += c * v;
                        }
                        if i >= 1 && k >= i {
                            uf += c * us[k - i][j];
                        }
                    }
                    let got = &phi_f[o * lt + j * nphi..o * lt + (j + 1) * nphi];
                    for (a, b) in got.iter().zip(&psi) {
                        worst = worst.max((a - b).abs());
                    }
                }
                worst = worst.max((u_f[o] - uf).abs());
            }
            let u = g.vec(lu);
            let y = g.vec(ly);
            f.push(&u, &y);
            us.push(u);
            ys.push(y);
        }
        assert!(worst < 1e-12, "largest deviation {worst:e}");
    }
}

#[test]
fn a_target_model_with_a_feedthrough_or_an_unstable_pole_is_refused() {
    let mut m = mimo_tf_target();
    if let TargetForm::TransferFunction(ch) = &mut m.form {
        ch[2] = tf(1, 0, 0, &[1.0, 0.4], &[1.0, 0.3]);
    }
    let e = TargetFilter::new(&m, 1, 2).unwrap_err();
    assert_eq!(e.path(), "channel[2]", "{e}");
    assert!(e.message.contains("feedthrough"), "{e}");
    let mut m = mimo_tf_target();
    if let TargetForm::TransferFunction(ch) = &mut m.form {
        ch[0] = tf(0, 0, 1, &[0.5], &[1.0, -1.01]);
    }
    let e = TargetFilter::new(&m, 1, 2).unwrap_err();
    assert_eq!(e.path(), "channel[0]", "{e}");
    assert!(e.message.contains("pole"), "{e}");
    let m = TargetModel {
        form: TargetForm::Markov(vec![DMatrix::from_element(2, 2, 0.1)]),
        ..mimo_tf_target()
    };
    let e = TargetFilter::new(&m, 1, 2).unwrap_err();
    assert_eq!(e.path(), "markov[0]", "{e}");
    assert!(e.message.contains("H_0"), "{e}");
}

fn params(target: TargetModel, nc: usize, update: RcacUpdate) -> RcacParams {
    RcacParams::new(target, nc, update)
}

fn rls(p0: f64, lambda: f64) -> RcacUpdate {
    RcacUpdate::Rls {
        p0,
        rule: ForgettingRule::Constant { lambda },
        trace_limit: f64::INFINITY,
    }
}

fn grad(step_size: StepSize, alpha: f64, r: f64) -> RcacUpdate {
    RcacUpdate::Gradient {
        step_size,
        alpha,
        r,
    }
}

/// The MISO case (2 inputs, 1 output, 2 measurements) of order `nc` with `update`:
/// `G_f = [0.4 z⁻¹/(1 − 0.3 z⁻¹), −0.2 z⁻⁴]`, `k_w = 5`, `|u| ≤ 0.5`.
fn miso_saturated(nc: usize, update: RcacUpdate) -> RcacParams {
    let target = miso_tf_target(vec![
        tf(0, 0, 1, &[0.4], &[1.0, -0.3]),
        tf(0, 1, 4, &[-0.2], &[1.0]),
    ]);
    RcacParams::builder(target, nc, update)
        .kw(Some(5))
        .limits(Some(OutputLimits::symmetric(0.5, 2)))
        .build(counts(2, 1, 2))
        .unwrap()
}

/// Input `j` of [`miso_saturated`] at sample `k` from the coefficients `theta` and the
/// regressor `phi`: `sat(φ θ_j)`, and 0 before `k_w = 5`.
fn miso_input(theta: &[f64], phi: &[f64], j: usize, k: usize) -> f64 {
    let raw: f64 = theta[j * phi.len()..(j + 1) * phi.len()]
        .iter()
        .zip(phi)
        .map(|(a, b)| a * b)
        .sum();
    if k < 5 { 0.0 } else { raw.clamp(-0.5, 0.5) }
}

/// MISO (2 inputs, 1 output, 2 measurements): `u_k = Φ_k θ_{k+1}` with `φ_k` built from
/// the applied inputs and the measurements, for both update laws and with saturation.
#[test]
fn the_input_is_the_updated_coefficients_times_the_regressor_of_applied_data() {
    for update in [rls(0.1, 0.999), grad(StepSize::Sigma, 0.5, 0.0)] {
        let nc = 3;
        let p = miso_saturated(nc, update);
        let mut c = Rcac::new(&p, counts(2, 1, 2)).unwrap();
        assert_eq!(c.theta_len(), 2 * nc * 4);
        let mut g = Gauss::new(8);
        let (mut us, mut ys) = (Vec::<Vec<f64>>::new(), Vec::<Vec<f64>>::new());
        let mut u = [0.0; 2];
        let mut saturated = 0;
        for k in 0..300 {
            let y = g.vec(2);
            let z = [g.normal()];
            let s = c.step(
                &StepInput {
                    seq: k as u64,
                    y: &y,
                    z: &z,
                    r: &[],
                    ..Default::default()
                },
                &mut u,
            );
            let phi = phi_direct(&us, &ys, k as isize, nc, (2, 2));
            for (j, uj) in u.iter().enumerate() {
                let want = miso_input(c.theta(), &phi, j, k);
                assert!((uj - want).abs() < 1e-12, "k = {k}: {uj} vs {want}");
            }
            saturated += usize::from(s & status::SATURATED != 0);
            assert_eq!(s & status::CONTROLLER_FAULT, 0);
            us.push(u.to_vec());
            ys.push(y);
        }
        assert!(saturated > 0, "saturation must be exercised");
    }
}

/// The step sizes against the `l_θ × l_θ` formulas written out with nalgebra, and
/// (3.62) `μ_F ≤ μ_σ ≤ μ_opt`.
#[test]
fn the_step_sizes_equal_their_definitions_without_forming_the_big_matrix() {
    let mut g = Gauss::new(21);
    for (p, lt, r) in [(1, 12, 0.0), (3, 20, 0.0), (3, 20, 0.7), (4, 9, 2.0)] {
        let a = g.vec(p * lt);
        let b = g.vec(p);
        let theta = g.vec(lt);
        let am = DMatrix::from_row_slice(p, lt, &a);
        let big = am.transpose() * &am + DMatrix::identity(lt, lt) * r;
        let gv = am.transpose()
            * (&am * nalgebra::DVector::from_column_slice(&theta)
                - nalgebra::DVector::from_column_slice(&b))
            + nalgebra::DVector::from_column_slice(&theta) * r;
        let want_opt = gv.norm_squared() / (gv.transpose() * &big * &gv)[(0, 0)];
        let want_sigma = 1.0 / big.singular_values().max();
        let want_f = 1.0 / big.norm();
        let want_exp = 1.0 / (am.norm_squared() + r * (lt as f64).sqrt());
        let (mut res, mut grd, mut gram) = (vec![0.0; p], vec![0.0; lt], vec![0.0; p * p]);
        let mut mu = |s| gradient_step(s, &a, &b, &theta, r, &mut res, &mut grd, &mut gram);
        let (opt, sigma, frob, exp) = (
            mu(StepSize::Opt),
            mu(StepSize::Sigma),
            mu(StepSize::Frobenius),
            mu(StepSize::Exp),
        );
        for (got, want) in [
            (opt, want_opt),
            (sigma, want_sigma),
            (frob, want_f),
            (exp, want_exp),
        ] {
            assert!((got - want).abs() <= 1e-10 * want, "{got} vs {want}");
        }
        assert!(frob <= sigma * (1.0 + 1e-12) && sigma <= opt * (1.0 + 1e-12));
        assert!(exp <= frob * (1.0 + 1e-12));
        for (x, y) in grd.iter().zip(gv.iter()) {
            assert!((x - y).abs() < 1e-10);
        }
    }
    // No data: no step.
    let (mut res, mut grd, mut gram) = (vec![0.0; 1], vec![0.0; 4], vec![0.0; 1]);
    let mu = gradient_step(
        StepSize::Exp,
        &[0.0; 4],
        &[1.0],
        &[0.0; 4],
        0.0,
        &mut res,
        &mut grd,
        &mut gram,
    );
    assert_eq!(mu, 0.0);
}

/// `R_z` and `R_u` as rows: `WᵀW` reproduces the weight; semidefinite `R_u` drops rows.
#[test]
fn weights_become_square_root_rows() {
    let rz = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
    let (w, n) = sqrt_rows(&rz, "rz", true).unwrap();
    assert_eq!(n, 2);
    let w = DMatrix::from_row_slice(2, 2, &w);
    assert!((w.transpose() * w - &rz).norm() < 1e-12);
    let ru = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
    let (w, n) = sqrt_rows(&ru, "ru", false).unwrap();
    assert_eq!(n, 1);
    let w = DMatrix::from_row_slice(1, 2, &w);
    assert!((w.transpose() * w - &ru).norm() < 1e-12);
    assert!(
        sqrt_rows(&ru, "rz", true)
            .unwrap_err()
            .message
            .contains("not positive definite")
    );
    let neg = DMatrix::from_row_slice(1, 1, &[-1.0]);
    assert!(sqrt_rows(&neg, "ru", false).is_err());
}

/// Non-finite measurements hold the last input, report a fault and leave θ finite; the
/// controller goes on afterwards.
#[test]
fn non_finite_measurements_hold_the_input_and_report_a_fault() {
    for update in [rls(1.0, 1.0), grad(StepSize::Exp, 1.0, 0.0)] {
        let mut c = Rcac::new(&params(siso_target(), 4, update), counts(1, 1, 1)).unwrap();
        let mut u = [0.0];
        let mut g = Gauss::new(1);
        let mut last = 0.0;
        for k in 0..400u64 {
            let bad = k % 50 == 49;
            let y = if bad { f64::NAN } else { g.normal() };
            let z = if k % 77 == 76 { f64::INFINITY } else { y };
            let s = c.step(
                &StepInput {
                    seq: k,
                    y: &[y],
                    z: &[z],
                    r: &[],
                    ..Default::default()
                },
                &mut u,
            );
            assert!(u[0].is_finite());
            if bad || !z.is_finite() {
                assert_ne!(s & status::CONTROLLER_FAULT, 0);
                assert_eq!(u[0], last);
            }
            last = u[0];
            assert!(c.theta().iter().all(|v| v.is_finite()));
        }
        let mut out = [0.0; crate::controller::MAX_INTERNALS];
        assert_eq!(c.internals(&mut out), c.internal_names().len());
        c.reset();
        assert!(c.theta().iter().all(|v| *v == 0.0));
    }
}

// ---------------------------------------------------------------------------------------
// Closed loop on a small discrete plant.

/// Lightly damped mode (ω_n = 2π·8 Hz, ζ = 0.02, T_s = 0.01) with numerator
/// `b_1 z + b_2`, behind a one-sample delay: `G_zu(z) = z^{−1}(b_1 z + b_2)/(z² + a_1 z + a_2)`,
/// first nonzero Markov parameter `H_2 = b_1`.
struct Plant {
    a: [f64; 2],
    /// Per input: numerator `[b_1, b_2]` and extra delay.
    b: Vec<([f64; 2], usize)>,
    /// Past outputs of each input's path: `[v_{k−1}, v_{k−2}]`.
    v: Vec<[f64; 2]>,
    /// Past inputs (newest first), per input.
    u: Vec<Vec<f64>>,
}

const B1: f64 = 0.05;
const B2: f64 = 0.03;

fn mode() -> [f64; 2] {
    let wn = 2.0 * std::f64::consts::PI * 8.0;
    let zeta = 0.02;
    let r = (-zeta * wn * TS).exp();
    let th = wn * (1.0 - zeta * zeta).sqrt() * TS;
    [-2.0 * r * th.cos(), r * r]
}

impl Plant {
    fn new(paths: Vec<([f64; 2], usize)>) -> Self {
        let n = paths.len();
        let len = 3 + paths.iter().map(|p| p.1).max().unwrap_or(0);
        Self {
            a: mode(),
            b: paths,
            v: vec![[0.0; 2]; n],
            u: vec![vec![0.0; len]; n],
        }
    }

    /// `z_k` without disturbance (depends on `u_{k−1}` and older only).
    fn output(&mut self) -> f64 {
        let mut z = 0.0;
        for (j, (bb, d)) in self.b.iter().enumerate() {
            // v_k = −a_1 v_{k−1} − a_2 v_{k−2} + b_1 u_{k−2−d} + b_2 u_{k−3−d}
            let uh = &self.u[j];
            let v = -self.a[0] * self.v[j][0] - self.a[1] * self.v[j][1]
                + bb[0] * uh[1 + d]
                + bb[1] * uh[2 + d];
            self.v[j] = [v, self.v[j][0]];
            z += v;
        }
        z
    }

    /// Applies `u_k`.
    fn apply(&mut self, u: &[f64]) {
        for (h, v) in self.u.iter_mut().zip(u) {
            h.rotate_right(1);
            h[0] = *v;
        }
    }

    /// `G_zu(e^{jω})` of input `j`.
    fn response(&self, j: usize, w: f64) -> nalgebra::Complex<f64> {
        use nalgebra::Complex as C;
        let z = C::from_polar(1.0, w);
        let (bb, d) = self.b[j];
        (bb[0] * z + bb[1]) / (z * z + self.a[0] * z + self.a[1]) * z.powi(-1 - d as i32)
    }
}

fn siso_target() -> TargetModel {
    TargetModel {
        sample_period: TS,
        outputs: 1,
        inputs: 1,
        beta: 1.0,
        source: "first nonzero Markov parameter".into(),
        form: TargetForm::Markov(vec![
            DMatrix::zeros(1, 1),
            DMatrix::zeros(1, 1),
            DMatrix::from_element(1, 1, B1),
        ]),
    }
}

/// Amplitude of the tone at `w` rad/sample in `x` (whole periods): projection on sin/cos.
fn tone_amplitude(x: &[f64], start: usize, w: f64) -> f64 {
    let n = x.len() as f64;
    let (mut s, mut c) = (0.0, 0.0);
    for (i, v) in x.iter().enumerate() {
        let t = w * (start + i) as f64;
        s += v * t.sin();
        c += v * t.cos();
    }
    2.0 / n * (s * s + c * c).sqrt()
}

/// Runs the loop with `z_k = G_zu u + sin(w k) + noise`, `y = z`, and returns the tone's
/// amplitude in `z` over the window `[end − window, end)`, the largest `|θ|` and the
/// controller.
fn run_loop(
    mut plant: Plant,
    mut c: Rcac,
    w: f64,
    steps: usize,
    window: usize,
) -> (f64, f64, Rcac) {
    let lu = plant.b.len();
    let mut u = vec![0.0; lu];
    let mut g = Gauss::new(17);
    let mut z_hist = Vec::with_capacity(window);
    let mut theta_max: f64 = 0.0;
    for k in 0..steps {
        let z = plant.output() + (w * k as f64).sin() + 1e-3 * g.normal();
        c.step(
            &StepInput {
                seq: k as u64,
                y: &[z],
                z: &[z],
                r: &[],
                ..Default::default()
            },
            &mut u,
        );
        plant.apply(&u);
        theta_max = c.theta().iter().fold(theta_max, |m, v| m.max(v.abs()));
        if k >= steps - window {
            z_hist.push(z);
        }
    }
    (tone_amplitude(&z_hist, steps - window, w), theta_max, c)
}

/// Disturbance at 3 Hz: `ωT = 0.06 π`; 500 samples are exactly 15 periods.
const W_D: f64 = 2.0 * std::f64::consts::PI * 3.0 * TS;

fn db(open: f64, closed: f64) -> f64 {
    20.0 * (open / closed).log10()
}

/// SISO, `n_c = 20`, target `G_f = H_2 z^{−2}` (the first nonzero Markov parameter),
/// whose phase error against the plant at 3 Hz is 5.7° (asserted below 90°). Open loop
/// the tone has amplitude 1 in `z` (plus white noise of σ = 10⁻³). The amplitude is
/// measured over steps 500–1000 (the loop starts adapting at `k_w = 22`). Measured
/// (seed 17): RLS (p0 = 100, λ = 1) 63.3 dB, RLS with F-test forgetting (τn = 10,
/// τd = 100, η = 0.1, α = 0.001) 63.3 dB (it never forgets on this stationary loop, so
/// it equals λ = 1), gradient with `μ_Exp`, α = 0.5: 88.9 dB
/// (over steps 2500–3000: 76.2 dB and 84.1 dB). Required: ≥ 40 dB within 1000 steps,
/// `θ` finite and small (measured max |θ_i| 3.7 and 2.9), no guard reset.
#[test]
fn rcac_rejects_a_tone_on_a_lightly_damped_siso_plant() {
    let plant = Plant::new(vec![([B1, B2], 0)]);
    let gf = nalgebra::Complex::from_polar(B1, -2.0 * W_D);
    let err = (plant.response(0, W_D) / gf).arg().to_degrees();
    assert!(err.abs() < 90.0, "phase error {err}°");
    let ftest = RcacUpdate::Rls {
        p0: 100.0,
        rule: ForgettingRule::FTest {
            tau_n: 10,
            tau_d: 100,
            eta: 0.1,
            alpha: 0.001,
        },
        trace_limit: 1e9,
    };
    for update in [rls(100.0, 1.0), ftest, grad(StepSize::Exp, 0.5, 0.0)] {
        let name = format!("{update:?}");
        let c = Rcac::new(&params(siso_target(), 20, update), counts(1, 1, 1)).unwrap();
        let (amp, theta_max, c) = run_loop(Plant::new(vec![([B1, B2], 0)]), c, W_D, 1000, 500);
        let red = db(1.0, amp);
        eprintln!("{name}: phase error {err:.1}°, reduction {red:.1} dB, max |θ| {theta_max:.3}");
        assert!(red >= 40.0, "{name}: only {red:.1} dB");
        assert!(
            theta_max.is_finite() && theta_max < 10.0,
            "{name}: {theta_max}"
        );
        assert_eq!(c.resets(), 0);
    }
}

/// Every gradient step size on the SISO loop with `R_u = 10⁻⁴` (two rows, so the step
/// sizes differ; with one row and `r = 0` all four coincide) and `r = 10⁻⁶`, α = 0.5.
/// Required: ≥ 20 dB over steps 500–1000. Measured: opt 39.1 dB, sigma 44.9 dB,
/// frobenius 44.8 dB, exp 44.8 dB (the `R_u` term of the instantaneous cost limits the
/// reduction; with `R_u = 0` it is 88.9 dB). (3.62) itself is checked on fixed data by
/// `the_step_sizes_equal_their_definitions_without_forming_the_big_matrix`.
#[test]
fn every_gradient_step_size_rejects_the_tone() {
    for s in [
        StepSize::Opt,
        StepSize::Sigma,
        StepSize::Frobenius,
        StepSize::Exp,
    ] {
        let mut p = params(siso_target(), 20, grad(s, 0.5, 1e-6));
        p.ru = DMatrix::from_element(1, 1, 1e-4);
        let c = Rcac::new(&p, counts(1, 1, 1)).unwrap();
        let (amp, theta_max, c) = run_loop(Plant::new(vec![([B1, B2], 0)]), c, W_D, 1000, 500);
        let red = db(1.0, amp);
        let mut out = [0.0; 8];
        c.internals(&mut out);
        eprintln!(
            "{s:?}: reduction {red:.1} dB, max |θ| {theta_max:.3}, μ {:.4e}",
            out[1]
        );
        assert!(red >= 20.0, "{s:?}: only {red:.1} dB");
        assert!(theta_max.is_finite());
    }
}

/// MISO: two inputs to one output, the second path with two more samples of delay; the
/// target model is a transfer-function model with per-input delays (the form the design
/// tools write): `[B1 z^{−2}, 0.6 B1 z^{−4}]`, `n_c = 20` (`l_θ = 120`). Measured over
/// steps 500–1000: RLS (p0 = 100) 59.3 dB, gradient `μ_Exp` α = 0.5: 95.5 dB. Required
/// ≥ 40 dB.
#[test]
fn rcac_rejects_a_tone_with_two_inputs_and_per_input_delays() {
    let target = miso_tf_target(vec![
        tf(0, 0, 1, &[B1], &[1.0, 0.0]),
        tf(0, 1, 3, &[0.6 * B1], &[1.0, 0.0]),
    ]);
    for update in [rls(100.0, 1.0), grad(StepSize::Exp, 0.5, 0.0)] {
        let name = format!("{update:?}");
        let plant = Plant::new(vec![([B1, B2], 0), ([0.6 * B1, 0.4 * B2], 2)]);
        let c = Rcac::new(&params(target.clone(), 20, update), counts(1, 1, 2)).unwrap();
        assert_eq!(c.theta_len(), 120);
        let (amp, theta_max, c) = run_loop(plant, c, W_D, 1000, 500);
        let red = db(1.0, amp);
        eprintln!("MISO {name}: reduction {red:.1} dB, max |θ| {theta_max:.3}");
        assert!(red >= 40.0, "{name}: only {red:.1} dB");
        assert!(theta_max.is_finite() && theta_max < 10.0);
        assert_eq!(c.resets(), 0);
    }
}

/// The plant holds the previous input every 7th step (a late actuation). With the applied
/// input reported (`u_applied`), the stored history and `u_{f,k}` are those of the inputs
/// the plant really applied, exactly; without it they are those RCAC computed, which the
/// plant did not apply (the check fails, so it can).
#[test]
fn the_history_holds_the_inputs_the_plant_applied() {
    for echo in [true, false] {
        let mut c = Rcac::new(
            &params(siso_target(), 20, grad(StepSize::Exp, 0.5, 0.0)),
            counts(1, 1, 1),
        )
        .unwrap();
        let mut plant = Plant::new(vec![([B1, B2], 0)]);
        let mut applied: Vec<f64> = Vec::new();
        let mut held = 0.0;
        let mut u = [0.0];
        let mut worst: f64 = 0.0;
        for k in 0..400usize {
            let z = plant.output() + (W_D * k as f64).sin();
            let prev = [held];
            c.step(
                &StepInput {
                    seq: k as u64,
                    y: &[z],
                    z: &[z],
                    u_applied: echo.then_some(&prev[..]),
                    ..Default::default()
                },
                &mut u,
            );
            // u_f,k = B1 u_{k−2} of the applied inputs (target H_2 = B1). After the step φ
            // holds [u_k (as computed, not yet known to be applied); u_{k−1}; …].
            let want_uf = if k >= 2 { B1 * applied[k - 2] } else { 0.0 };
            let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-3);
            worst = worst.max(rel(c.u_f()[0], want_uf));
            let (pu, _) = c.filter().regressor(0);
            if k >= 1 {
                worst = worst.max(rel(pu[1], applied[k - 1]));
            }
            if k % 7 != 6 {
                held = u[0];
            }
            applied.push(held);
            plant.apply(&[held]);
        }
        if echo {
            assert!(worst < 1e-12, "with the applied input reported: {worst:e}");
        } else {
            assert!(
                worst > 1e-3,
                "without it the history must differ: {worst:e}"
            );
        }
    }
}

/// An imperfect loop: every 50th sample arrives late (observed, not answered: the plant
/// holds the input), and every 400 steps two samples are lost altogether (the plant holds
/// the input, RCAC never sees them). With `u_applied`, `observe` and the gap bridge, RCAC
/// still rejects the tone. Measured over steps 3500–4000: RLS 58.4 dB, gradient 81.6 dB
/// (8 gaps bridged each). Required ≥ 40 dB, every gap counted, θ finite, no reset.
#[test]
fn rcac_rejects_the_tone_through_late_and_lost_samples() {
    for update in [rls(100.0, 1.0), grad(StepSize::Exp, 0.5, 0.0)] {
        let name = format!("{update:?}");
        let mut c = Rcac::new(&params(siso_target(), 20, update), counts(1, 1, 1)).unwrap();
        let mut plant = Plant::new(vec![([B1, B2], 0)]);
        let mut g = Gauss::new(5);
        let (mut held, mut u, mut lost) = (0.0, [0.0], 0u64);
        let (steps, window) = (4000usize, 500usize);
        let mut zs = Vec::new();
        let mut gaps = 0;
        for k in 0..steps {
            let z = plant.output() + (W_D * k as f64).sin() + 1e-3 * g.normal();
            if k >= steps - window {
                zs.push(z);
            }
            let prev = [held];
            let input = StepInput {
                seq: k as u64,
                y: &[z],
                z: &[z],
                u_applied: Some(&prev),
                lost,
                ..Default::default()
            };
            if k % 400 == 398 || k % 400 == 399 {
                // Lost: the service never sees these two.
                lost += 1;
            } else {
                if lost > 0 {
                    gaps += 1;
                }
                lost = 0;
                if k % 50 == 25 {
                    c.observe(&input, &mut u);
                } else {
                    c.step(&input, &mut u);
                    held = u[0];
                }
            }
            plant.apply(&[held]);
        }
        let red = db(1.0, tone_amplitude(&zs, steps - window, W_D));
        eprintln!(
            "{name}: {red:.1} dB through late and lost samples, {} gaps",
            c.gaps()
        );
        assert!(red >= 40.0, "{name}: only {red:.1} dB");
        assert_eq!(c.gaps(), gaps);
        assert!(c.theta().iter().all(|v| v.is_finite()));
        assert_eq!(c.resets(), 0);
    }
}

#[test]
fn refused_parameters_name_the_field_of_the_configuration_table() {
    let good = params(siso_target(), 4, rls(10.0, 0.99));
    let dims = counts(1, 1, 1);
    assert_eq!(good.validate(dims), Ok(()));
    let field = |p: RcacParams| p.validate(dims).unwrap_err().path();
    assert_eq!(
        field(RcacParams {
            nc: 0,
            ..good.clone()
        }),
        "nc"
    );
    assert_eq!(field(params(siso_target(), 4, rls(-1.0, 0.99))), "p0");
    assert_eq!(
        field(params(siso_target(), 4, rls(10.0, 1.5))),
        "forgetting.lambda"
    );
    let tight = RcacUpdate::Rls {
        p0: 10.0,
        rule: ForgettingRule::DEFAULT,
        trace_limit: 1.0,
    };
    assert_eq!(field(params(siso_target(), 4, tight)), "trace-limit");
    assert_eq!(
        field(params(siso_target(), 4, grad(StepSize::Exp, 0.0, 0.0))),
        "alpha"
    );
    assert_eq!(
        field(params(siso_target(), 4, grad(StepSize::Exp, 0.5, -1.0))),
        "r"
    );
    let rz = DMatrix::from_element(1, 1, -1.0);
    assert_eq!(field(RcacParams { rz, ..good.clone() }), "rz");
    let theta0 = Some(vec![0.0; 3]);
    assert_eq!(
        field(RcacParams {
            theta0,
            ..good.clone()
        }),
        "theta0"
    );
    let sample_period = TS / 2.0;
    assert_eq!(
        field(RcacParams {
            sample_period,
            ..good.clone()
        }),
        "target-model.sample-period"
    );
}

#[test]
fn the_defaults_are_those_the_constructor_uses() {
    let p = params(siso_target(), 4, rls(10.0, 0.99));
    let dims = counts(1, 1, 1);
    // l_θ = l_u n_c (l_u + l_y) = 8; the target's largest lag is 2.
    assert_eq!(RcacParams::theta_len(4, dims), 8);
    assert_eq!(
        RcacParams::default_trace_limit(4, dims, 10.0),
        1e6 * 8.0 * 10.0
    );
    assert_eq!(p.default_kw(), Ok(2 + 4));
    let c = Rcac::new(&p, dims).unwrap();
    assert_eq!(c.theta_len(), RcacParams::theta_len(4, dims));
}

#[test]
fn the_builder_starts_at_the_defaults_and_names_a_refused_field() {
    let dims = counts(1, 1, 1);
    let update = RcacUpdate::rls(10.0, 4, dims);
    let built = RcacParams::builder(siso_target(), 4, update.clone())
        .build(dims)
        .unwrap();
    assert_eq!(built, params(siso_target(), 4, update.clone()));
    assert_eq!(
        update,
        RcacUpdate::Rls {
            p0: 10.0,
            rule: ForgettingRule::DEFAULT,
            trace_limit: 1e6 * 8.0 * 10.0,
        }
    );
    let refused = RcacParams::builder(siso_target(), 4, RcacUpdate::gradient(1.5)).build(dims);
    assert_eq!(refused.unwrap_err().field, "alpha");
    let refused = RcacParams::builder(siso_target(), 4, update)
        .theta0(Some(vec![0.0; 3]))
        .build(dims);
    assert_eq!(refused.unwrap_err().field, "theta0");
}

/// Runs `c` for `steps` samples of a new data stream on a fresh plant (the tone and noise
/// of [`run_loop`], seed 29) and returns every input and the tone's amplitude in `z` over
/// samples `[from, steps)`.
fn new_stream(c: &mut Rcac, steps: usize, from: usize) -> (Vec<f64>, f64) {
    let mut plant = Plant::new(vec![([B1, B2], 0)]);
    let mut g = Gauss::new(29);
    let (mut inputs, mut zs) = (Vec::new(), Vec::new());
    let mut u = [0.0];
    for k in 0..steps {
        let z = plant.output() + (W_D * k as f64).sin() + 1e-3 * g.normal();
        let input = StepInput {
            seq: k as u64,
            y: &[z],
            z: &[z],
            r: &[],
            ..Default::default()
        };
        c.step(&input, &mut u);
        plant.apply(&u);
        inputs.push(u[0]);
        if k >= from {
            zs.push(z);
        }
    }
    (inputs, tone_amplitude(&zs, from, W_D))
}

/// What RCAC learned (θ and the RLS covariance, [`crate::learned`]) survives a checkpoint
/// and a new data stream. After 1000 samples on the SISO loop the blocks are copied into
/// a controller built afresh; the original restarts its data history. Fed the same new
/// stream, the two give the same inputs bit for bit, and both reject the tone over
/// samples 40–540 of it (the first `k_w` = 22 wait again while the regressor fills) far
/// better than a controller that starts from θ = 0 (measured: 68.6 dB against 30.4 dB;
/// required: 10 dB more). Bad blocks are refused by name and leave the controller at its
/// initial state.
#[test]
fn what_rcac_learned_survives_a_checkpoint_and_a_new_data_stream() {
    let build = || Rcac::new(&params(siso_target(), 20, rls(100.0, 1.0)), counts(1, 1, 1)).unwrap();
    let (_, _, mut learned) = run_loop(Plant::new(vec![([B1, B2], 0)]), build(), W_D, 1000, 500);
    let mut blocks = Vec::new();
    learned.learned(&mut |n, v| blocks.push((n.to_string(), v.to_vec())));
    let names: Vec<&str> = blocks.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["theta", "Q", "W", "beta-trace"]);
    let theta = learned.theta().to_vec();
    assert!(theta.iter().any(|v| *v != 0.0));

    let mut restored = build();
    restored
        .restore_learned(&crate::learned::Learned::new(&blocks))
        .unwrap();
    assert_eq!(restored.theta(), &theta[..]);
    learned.restart_data();
    assert_eq!(learned.theta(), &theta[..], "restart_data keeps θ");

    let (u_learned, _) = new_stream(&mut learned, 540, 40);
    let (u_restored, amp_restored) = new_stream(&mut restored, 540, 40);
    assert_eq!(u_learned, u_restored, "bit for bit");
    assert!(u_learned[..22].iter().all(|u| *u == 0.0), "k_w waits again");
    let (_, amp_fresh) = new_stream(&mut build(), 540, 40);
    let (kept, fresh) = (db(1.0, amp_restored), db(1.0, amp_fresh));
    eprintln!("samples 40–540 of a new stream: kept θ {kept:.1} dB, from θ = 0 {fresh:.1} dB");
    assert!(
        kept > fresh + 10.0,
        "kept {kept:.1} dB, fresh {fresh:.1} dB"
    );

    let refused = |edit: &dyn Fn(&mut crate::learned::Blocks), says: &str| {
        let mut bad = blocks.clone();
        edit(&mut bad);
        let mut c = build();
        let e = c
            .restore_learned(&crate::learned::Learned::new(&bad))
            .unwrap_err();
        assert!(e.contains(says), "{e}");
        assert!(
            c.theta().iter().all(|v| *v == 0.0),
            "left at θ_0 after: {e}"
        );
    };
    refused(
        &|b| {
            b[0].1.pop();
        },
        "block 'theta' has 39 values",
    );
    refused(
        &|b| b[1].1[0] = f64::NAN,
        "block 'Q': value 0 is not finite",
    );
    refused(&|b| b[1].1[0] = -1.0, "not positive definite");
    refused(&|b| b.retain(|(n, _)| n != "W"), "block 'W' is missing");
}

// ---------------------------------------------------------------------------------------
// The ahead form (2.16) and its plan.

/// `input` of sample `k` with `y` and `z`, on time.
fn sample<'a>(k: usize, y: &'a [f64], z: &'a [f64]) -> StepInput<'a> {
    StepInput {
        seq: k as u64,
        y,
        z,
        r: &[],
        ..Default::default()
    }
}

/// MISO (2 inputs, 1 output, 2 measurements), both update laws, with saturation: after
/// each `advance(k)` the ready input is `u_{k+1} = sat(Φ_{k+1} θ_{k+1})` (2.16), with
/// `φ_{k+1}` built directly from the applied inputs `u_k, u_{k−1}, …` and the measurements
/// `y_k, y_{k−1}, …` and `θ_{k+1}` read from [`Rcac::theta`], and 0 while `k + 1 < k_w`.
#[test]
fn the_ready_input_is_the_current_coefficients_times_the_next_regressor() {
    for update in [rls(0.1, 0.999), grad(StepSize::Sigma, 0.5, 0.0)] {
        let nc = 3;
        let p = miso_saturated(nc, update);
        assert!(p.answers_ahead());
        let mut c = Rcac::new(&p, counts(2, 1, 2)).unwrap();
        let mut g = Gauss::new(8);
        let (mut us, mut ys) = (Vec::<Vec<f64>>::new(), Vec::<Vec<f64>>::new());
        let mut u = [f64::NAN; 2];
        let a = c.ahead().expect("RCAC answers ahead");
        assert_eq!(a.ready(&mut u), status::OK);
        assert_eq!(u, [0.0, 0.0], "the start-up input");
        let (mut saturated, mut active) = (0, 0);
        for k in 0..300 {
            let y = g.vec(2);
            let z = [g.normal()];
            // u_k, prepared by advance(k − 1), is what the plant applies for sample k.
            let a = c.ahead().unwrap();
            a.ready(&mut u);
            us.push(u.to_vec());
            ys.push(y.clone());
            let s = a.advance(&sample(k, &y, &z), &u, true);
            let mut ready = [f64::NAN; 2];
            assert_eq!(a.ready(&mut ready), s, "advance returns the ready status");
            assert_eq!(s & status::CONTROLLER_FAULT, 0);
            let phi = phi_direct(&us, &ys, k as isize + 1, nc, (2, 2));
            for (j, uj) in ready.iter().enumerate() {
                let want = miso_input(c.theta(), &phi, j, k + 1);
                assert!(
                    (uj - want).abs() < 1e-12,
                    "k = {k}: u_(k+1) = {uj} vs Φ_(k+1) θ_(k+1) = {want}"
                );
                active += usize::from(want != 0.0);
            }
            saturated += usize::from(s & status::SATURATED != 0);
        }
        assert!(saturated > 0, "saturation must be exercised");
        assert!(active > 0);
    }
}

/// A bad measurement holds the applied input with a fault, as `step` does, and a reset
/// or a new data stream makes the ready input the start-up input again.
#[test]
fn a_bad_measurement_holds_the_applied_input_and_a_reset_gives_the_start_up_input() {
    let mut p = params(siso_target(), 4, rls(1.0, 1.0));
    p.limits = Some(OutputLimits {
        min: vec![0.1],
        max: vec![2.0],
    });
    let mut c = Rcac::new(&p, counts(1, 1, 1)).unwrap();
    let mut g = Gauss::new(4);
    let mut u = [0.0];
    let start = c.ahead().unwrap().ready(&mut u);
    // sat(0) into [0.1, 2]: the start-up input is clipped.
    assert_eq!((u[0], start), (0.1, status::SATURATED));
    for k in 0..100 {
        let y = if k == 60 { f64::NAN } else { g.normal() };
        let a = c.ahead().unwrap();
        a.ready(&mut u);
        let applied = [u[0] + 0.01];
        let s = a.advance(&sample(k, &[y], &[y]), &applied, true);
        a.ready(&mut u);
        if k == 60 {
            assert_ne!(s & status::CONTROLLER_FAULT, 0);
            assert_eq!(u, applied, "the applied input held");
        }
        assert!((0.1..=2.0).contains(&u[0]));
    }
    c.restart_data();
    assert_eq!(c.ahead().unwrap().ready(&mut u), start);
    assert_eq!(u[0], 0.1);
    c.advance(&sample(0, &[1.0], &[1.0]), &[0.5], true);
    c.reset();
    assert_eq!((c.ready(&mut u), u[0]), (start, 0.1));
}

/// The plan is what the controller would give if the coming measurements were 0 and it did
/// not adapt: two controllers built from the same parameters take the same history in;
/// then one plans 40 rows, and the other is fed `y = z = 0` with `adapt = false` (applying
/// its own ready inputs), and its ready inputs equal the plan's rows bit for bit. Checked
/// after 300 samples (both laws, 2 inputs, saturation) and at start-up with `θ_0 ≠ 0` and
/// `k_w = 5`, where the first row is still the waiting 0 of (2.16).
#[test]
fn the_plan_is_what_the_controller_would_give_if_the_coming_measurements_were_zero() {
    let target = miso_tf_target(vec![
        tf(0, 0, 1, &[0.4], &[1.0, -0.3]),
        tf(0, 1, 4, &[-0.2], &[1.0]),
    ]);
    let nc = 3;
    let dims = counts(2, 1, 2);
    let lt = RcacParams::theta_len(nc, dims);
    let mut cases = Vec::new();
    for update in [rls(0.1, 0.999), grad(StepSize::Sigma, 0.5, 0.0)] {
        let mut p = params(target.clone(), nc, update);
        p.kw = Some(5);
        p.limits = Some(OutputLimits::symmetric(0.8, 2));
        cases.push((p, 300));
    }
    let mut start = params(target, nc, rls(0.1, 1.0));
    start.kw = Some(5);
    start.theta0 = Some(Gauss::new(3).vec(lt).iter().map(|v| 0.3 * v).collect());
    cases.push((start, 3));
    for (p, history) in cases {
        let mut planner = Rcac::new(&p, dims).unwrap();
        let mut follower = Rcac::new(&p, dims).unwrap();
        let mut g = Gauss::new(12);
        let mut u = [0.0; 2];
        for k in 0..history {
            let (y, z) = (g.vec(2), [g.normal()]);
            for c in [&mut planner, &mut follower] {
                c.ready(&mut u);
                c.advance(&sample(k, &y, &z), &u, true);
            }
        }
        let h = 40;
        let mut plan = vec![f64::NAN; 2 * h + 1];
        assert_eq!(planner.plan(&mut plan), h, "as many rows as fit");
        let theta = follower.theta().to_vec();
        let (mut nonzero, mut zero) = (0, 0);
        for (j, row) in plan.chunks_exact(2).enumerate() {
            follower.ready(&mut u);
            follower.advance(&sample(history + j, &[0.0, 0.0], &[0.0]), &u, false);
            let mut want = [0.0; 2];
            follower.ready(&mut want);
            assert_eq!(bits(row), bits(&want), "row {j} after {history} samples");
            nonzero += usize::from(row.iter().any(|v| *v != 0.0));
            zero += usize::from(row.iter().all(|v| *v == 0.0));
        }
        assert_eq!(follower.theta(), &theta[..], "adapt = false keeps θ");
        assert!(nonzero > 0, "the plan must move");
        if history < 5 {
            // Row j is u_{history+1+j}: the rows of samples below k_w = 5 are 0.
            let waiting = 5 - history - 1;
            assert!(zero >= waiting, "{zero} zero rows");
            assert!(plan[..2 * waiting].iter().all(|v| *v == 0.0));
            assert!(plan[2 * waiting..2 * waiting + 2].iter().any(|v| *v != 0.0));
        }
    }
}

/// A plan asked for more rows than [`MAX_PLAN_ROWS`] writes that many, leaves the rest of
/// the buffer alone, and its rows are the same as those of a shorter plan.
#[test]
fn a_plan_holds_at_most_max_plan_rows() {
    let target = miso_tf_target(vec![
        tf(0, 0, 1, &[0.4], &[1.0]),
        tf(0, 1, 2, &[-0.2], &[1.0]),
    ]);
    let dims = counts(1, 1, 2);
    let mut p = params(target, 4, grad(StepSize::Sigma, 0.5, 0.0));
    p.kw = Some(2);
    let mut c = Rcac::new(&p, dims).unwrap();
    let mut g = Gauss::new(4);
    let mut u = [0.0; 2];
    for k in 0..50 {
        let y = [g.normal()];
        c.ready(&mut u);
        c.advance(&sample(k, &y, &y), &u, true);
    }
    let mut long = vec![f64::NAN; 2 * (MAX_PLAN_ROWS + 10)];
    assert_eq!(c.plan(&mut long), MAX_PLAN_ROWS);
    assert!(long[..2 * MAX_PLAN_ROWS].iter().all(|v| v.is_finite()));
    assert!(long[..2 * MAX_PLAN_ROWS].iter().any(|v| *v != 0.0));
    assert!(long[2 * MAX_PLAN_ROWS..].iter().all(|v| v.is_nan()));
    let mut short = vec![0.0; 10];
    assert_eq!(c.plan(&mut short), 5);
    assert_eq!(bits(&short), bits(&long[..10]));
}

fn bits(u: &[f64]) -> Vec<u64> {
    u.iter().map(|v| v.to_bits()).collect()
}

/// The SISO loop of `rcac_rejects_a_tone_on_a_lightly_damped_siso_plant` (`n_c = 20`,
/// `G_f = H_2 z^{−2}`, a tone of amplitude 1 at 3 Hz, seed 17), once compute-first
/// (`u_k = Φ_k θ_{k+1}`) and once in the ahead form (`u_k = Φ_k θ_k`, (2.16)), over steps
/// 500–1000, and the largest `|z|` of the whole run (the adaptation transient).
/// Measured: RLS (p0 = 100, λ = 1) compute-first 63.3 dB, ahead 62.3 dB (largest `|z|`
/// 6.06 and 7.18); gradient `μ_Exp`, α = 0.25: compute-first 89.8 dB, ahead 90.5 dB
/// (largest `|z|` 4.07 and 4.96). Required: the ahead form ≥ 55 dB and within 6 dB of
/// compute-first, a largest `|z|` at most twice compute-first's, θ finite and small, no
/// guard reset.
///
/// The gradient law with a large normalized step needs the smaller α in the ahead form:
/// with α = 0.5 (the value of the tests above) the one sample by which (2.16) uses the
/// update later gives a violent transient on this loop (largest `|z|` about 10⁵ against 5
/// compute-first, 4.9 dB over steps 500–1000, then 91.5 dB over 2500–3000), and with
/// α = 1 about 5·10⁹ (see the module docs, "Ahead form (2.16) and plans").
#[test]
fn the_ahead_form_rejects_a_tone_about_as_well_as_the_compute_first_step() {
    for update in [rls(100.0, 1.0), grad(StepSize::Exp, 0.25, 0.0)] {
        let name = format!("{update:?}");
        let build =
            || Rcac::new(&params(siso_target(), 20, update.clone()), counts(1, 1, 1)).unwrap();
        let plant = || Plant::new(vec![([B1, B2], 0)]);
        let (amp_step, peak_step, _) = run_loop_peak(plant(), build(), false);
        let (amp_ahead, peak_ahead, c) = run_loop_peak(plant(), build(), true);
        let (first, ahead) = (db(1.0, amp_step), db(1.0, amp_ahead));
        eprintln!(
            "{name}: compute-first {first:.1} dB (largest |z| {peak_step:.2}), ahead \
             {ahead:.1} dB (largest |z| {peak_ahead:.2})"
        );
        assert!(ahead >= 55.0, "{name}: ahead only {ahead:.1} dB");
        assert!(
            ahead >= first - 6.0,
            "{name}: ahead {ahead:.1} dB, compute-first {first:.1} dB"
        );
        assert!(
            peak_ahead <= 2.0 * peak_step,
            "{name}: {peak_ahead} vs {peak_step}"
        );
        let theta_max = c.theta().iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(
            theta_max.is_finite() && theta_max < 10.0,
            "{name}: {theta_max}"
        );
        assert_eq!(c.resets(), 0);
    }
}

/// 1000 steps of the loop of [`run_loop`] (seed 17), compute-first or in the ahead form
/// (at sample `k` the plant applies the ready input `u_k`, prepared from the data up to
/// `k − 1`, then RCAC advances with it); returns the tone's amplitude over steps
/// 500–1000, the largest `|z|` of the run and the controller.
fn run_loop_peak(mut plant: Plant, mut c: Rcac, ahead: bool) -> (f64, f64, Rcac) {
    let (steps, window) = (1000, 500);
    let mut u = [0.0];
    let mut g = Gauss::new(17);
    let (mut z_hist, mut peak) = (Vec::new(), 0.0_f64);
    for k in 0..steps {
        let z = plant.output() + (W_D * k as f64).sin() + 1e-3 * g.normal();
        if ahead {
            c.ready(&mut u);
            c.advance(&sample(k, &[z], &[z]), &u, true);
        } else {
            c.step(&sample(k, &[z], &[z]), &mut u);
        }
        plant.apply(&u);
        peak = peak.max(z.abs());
        if k >= steps - window {
            z_hist.push(z);
        }
    }
    (tone_amplitude(&z_hist, steps - window, W_D), peak, c)
}

/// The SISO target of [`siso_target`] with a negligible Markov parameter at lag 120, so
/// that the history is long (`L = 120 + n_c`) as on the acoustic rig.
fn long_target() -> TargetModel {
    let mut t = siso_target();
    if let TargetForm::Markov(h) = &mut t.form {
        h.resize(121, DMatrix::zeros(1, 1));
        h[120] = DMatrix::from_element(1, 1, 1e-6);
    }
    t
}

/// Runs RCAC (`n_c = 20`, gradient, the long target) in closed loop with a tone for
/// `steps` samples, losing `burst` samples whenever `lose(k)` is true at the first of
/// them; returns the controller and, per sample that arrived, whether it updated `θ`.
fn run_with_gaps(
    rule: GapRule,
    steps: usize,
    burst: usize,
    lose: impl Fn(usize) -> bool,
) -> (Rcac, Vec<(usize, bool)>) {
    let mut p = params(long_target(), 20, grad(StepSize::Exp, 0.5, 0.0));
    p.gap_rule = rule;
    let mut c = Rcac::new(&p, counts(1, 1, 1)).unwrap();
    let mut plant = Plant::new(vec![([B1, B2], 0)]);
    let (mut held, mut u, mut lost) = (0.0, [0.0], 0u64);
    let mut out = Vec::new();
    let mut skip = 0;
    for k in 0..steps {
        let z = plant.output() + (W_D * k as f64).sin();
        if skip == 0 && lose(k) {
            skip = burst;
        }
        if skip > 0 {
            skip -= 1;
            lost += 1;
        } else {
            let prev = [held];
            let before = c.adaptation().unwrap().updated;
            c.step(
                &StepInput {
                    seq: k as u64,
                    y: &[z],
                    z: &[z],
                    u_applied: Some(&prev),
                    lost,
                    ..Default::default()
                },
                &mut u,
            );
            lost = 0;
            held = u[0];
            out.push((k, c.adaptation().unwrap().updated > before));
        }
        plant.apply(&[held]);
    }
    (c, out)
}

/// Suspended steps right after the gap that starts at sample `at` (a 1-sample gap), and
/// whether every later step updated.
fn pause_after(steps: &[(usize, bool)], at: usize) -> (usize, bool) {
    let after: Vec<bool> = steps.iter().filter(|(k, _)| *k > at).map(|s| s.1).collect();
    let pause = after.iter().take_while(|u| !**u).count();
    (pause, after[pause..].iter().all(|u| *u))
}

/// After a 1-sample gap the update resumes after the pause (`n_c` by default, or the
/// configured number of steps); with the original rule it waits the history length `L`.
#[test]
fn after_a_one_sample_gap_the_update_resumes_after_the_pause() {
    let len = 120 + 20;
    let gap = 400;
    for (rule, want) in [
        (GapRule::Suspend, len),
        (
            GapRule::Resume {
                bridge: GapBridge::Plan,
                pause: None,
            },
            20,
        ),
        (
            GapRule::Resume {
                bridge: GapBridge::Hold,
                pause: Some(5),
            },
            5,
        ),
        (
            GapRule::Resume {
                bridge: GapBridge::Plan,
                pause: Some(0),
            },
            0,
        ),
    ] {
        let (c, steps) = run_with_gaps(rule, 800, 1, |k| k == gap);
        let (pause, rest) = pause_after(&steps, gap);
        assert_eq!(pause, want, "{rule:?}");
        assert!(rest, "{rule:?}: every step after the pause updates");
        assert_eq!(c.gaps(), 1);
        let a = c.adaptation().unwrap();
        assert_eq!(a.suspended[0].1, want as u64, "{rule:?}");
    }
}

/// A gap every 100 samples: the original rule (`L = 140 > 100`) never updates again after
/// the first gap, the default rule updates on most steps (all but `n_c = 20` of every
/// 99). The counters of `adaptation()` add up to the closed-loop steps, and the cause of
/// the suspension is named by the rule.
#[test]
fn a_gap_every_100_samples_keeps_most_steps_updating_with_the_resume_rule() {
    let steps = 3000;
    let lose = |k: usize| k >= 300 && k.is_multiple_of(100);
    let gaps = (300..steps)
        .filter(|k: &usize| k.is_multiple_of(100))
        .count() as u64;
    let (c, log) = run_with_gaps(RcacParams::DEFAULT_GAP_RULE, steps, 1, lose);
    let a = c.adaptation().unwrap();
    let kw = (120 + 20) as usize;
    let closed = log.iter().filter(|(k, _)| *k >= kw).count() as u64;
    assert_eq!(
        a.updated + a.suspended.iter().map(|s| s.1).sum::<u64>(),
        closed
    );
    assert_eq!(a.suspended[0], ("the pause after a gap", 20 * gaps));
    assert_eq!(a.suspended[1].1, 0);
    assert!(a.updated as f64 > 0.7 * closed as f64, "{a:?}");
    assert_eq!(c.gaps(), gaps);
    assert!(c.theta().iter().all(|v| v.is_finite()));
    let (c, _) = run_with_gaps(GapRule::Suspend, steps, 1, lose);
    let a = c.adaptation().unwrap();
    assert_eq!(a.suspended[0].0, "a bridged gap in its windows");
    assert_eq!(a.updated, (300 - kw) as u64, "{a:?}");
    assert_eq!(a.updated + a.suspended[0].1, closed);
}

/// The plan bridge stores what a plant with the plan late policy applied over the gap:
/// the ready input for the first lost sample, then the plan's entries, with the
/// measurements predicted at 0; the reported input for the last lost sample replaces the
/// bridged one.
#[test]
fn the_plan_bridge_stores_the_ready_input_and_the_plan() {
    let mut p = params(siso_target(), 6, grad(StepSize::Exp, 0.5, 0.0));
    p.kw = Some(8);
    let mut c = Rcac::new(&p, counts(1, 1, 1)).unwrap();
    let mut g = Gauss::new(3);
    let mut applied = [0.0];
    let mut k = 0u64;
    for _ in 0..60 {
        let y = [g.normal()];
        let st = StepInput {
            seq: k,
            y: &y,
            z: &y,
            ..Default::default()
        };
        Ahead::advance(&mut c, &st, &applied, true);
        Ahead::ready(&c, &mut applied);
        k += 1;
    }
    let mut ready = [0.0];
    Ahead::ready(&c, &mut ready);
    let mut plan = [0.0; 4];
    Ahead::plan(&mut c, &mut plan);
    // Samples k … k + 2 are lost; k + 3 arrives with the input applied for k + 2.
    let reported = [0.125];
    let y = [0.5];
    let st = StepInput {
        seq: k + 3,
        y: &y,
        z: &y,
        u_applied: Some(&reported),
        lost: 3,
        ..Default::default()
    };
    let newest = [0.75];
    Ahead::advance(&mut c, &st, &newest, true);
    let (pu, py) = c.filter().regressor(0);
    assert_eq!(pu[0], 0.75);
    assert_eq!(pu[1], 0.125, "the reported input of the last lost sample");
    assert_eq!(pu[2], plan[0], "the plan's first entry");
    assert_eq!(pu[3], ready[0], "the ready input");
    assert_eq!(&py[..4], &[0.5, 0.0, 0.0, 0.0]);
    assert_eq!(c.gaps(), 1);
}
