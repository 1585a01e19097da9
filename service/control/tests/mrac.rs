//! The chapter-4 kernels on the dissertation's examples: APPC (4.7)–(4.43) and RC-MRAC
//! (4.46)–(4.77) against the Diophantine solutions computed here independently (by a
//! Sylvester-matrix solve), Proposition 4.4.1, the adaptive runs of Examples 1 and 2
//! (200 steps, ‖e‖ of (4.85)), and the parameter checks.
//!
//! `cargo test --release -p control --test mrac -- --nocapture` prints the measured ‖e‖.

#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

use control::OutputLimits;
use control::forgetting::ForgettingRule;
use control::mrac::{Appc, AppcParams, RcMrac, RcMracParams, poly};
use control::{Controller, Dimensions, StepInput, status};
use nalgebra::{DMatrix, DVector};

const SISO: Dimensions = Dimensions {
    n_y: 1,
    n_z: 1,
    n_r: 1,
    n_u: 1,
};

// ---------------------------------------------------------------------------------------
// Polynomials and the plant, written here independently of the crate.

/// `D = (1 − ρ e^{jν} q⁻¹)(1 − ρ e^{−jν} q⁻¹) = 1 − 2ρ cos ν q⁻¹ + ρ² q⁻²` (4.83), (4.88).
fn plant_den(rho: f64, nu: f64) -> Vec<f64> {
    vec![1.0, -2.0 * rho * nu.cos(), rho * rho]
}

/// `D_m` of (4.84), (4.89): poles `0.5 e^{±jπ/2}`, `1 + 0.25 q⁻²`.
fn model_den() -> Vec<f64> {
    plant_den(0.5, PI / 2.0)
        .iter()
        .map(|c| if c.abs() < 1e-15 { 0.0 } else { *c })
        .collect()
}

/// The FIR filter `P(q⁻¹) x` from zero initial conditions.
fn fir(p: &[f64], x: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|k| {
            p.iter()
                .enumerate()
                .filter(|(i, _)| *i <= k)
                .map(|(i, c)| c * x[k - i])
                .sum()
        })
        .collect()
}

/// `N(q⁻¹)/D(q⁻¹) x` from zero initial conditions (`D` monic).
fn tf(num: &[f64], den: &[f64], x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    for k in 0..x.len() {
        let mut v = 0.0;
        for (i, c) in num.iter().enumerate() {
            if i <= k {
                v += c * x[k - i];
            }
        }
        for (i, c) in den.iter().enumerate().skip(1) {
            if i <= k {
                v -= c * y[k - i];
            }
        }
        y[k] = v;
    }
    y
}

fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = a.len().max(b.len());
    (0..n)
        .map(|i| a.get(i).copied().unwrap_or(0.0) - b.get(i).copied().unwrap_or(0.0))
        .collect()
}

/// Solves `X A + Y B = T` for `X = Σ_{i=1}^{n} X_i q⁻ⁱ`, `Y = Σ_{i=1}^{n} Y_i q⁻ⁱ`
/// (coefficients `1..=2n` of `T`; `T_0` must be 0) by the Sylvester matrix.
fn diophantine(a: &[f64], b: &[f64], t: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(
        t.first().copied().unwrap_or(0.0).abs() < 1e-14,
        "T_0 = {t:?}"
    );
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    for i in 1..=n {
        for (l, c) in a.iter().enumerate() {
            if i + l <= 2 * n {
                m[(i + l - 1, i - 1)] = *c;
            }
        }
        for (l, c) in b.iter().enumerate() {
            if i + l <= 2 * n {
                m[(i + l - 1, n + i - 1)] = *c;
            }
        }
    }
    assert!(t.len() <= 2 * n + 1 || t[2 * n + 1..].iter().all(|c| c.abs() < 1e-14));
    let rhs = DVector::from_fn(2 * n, |r, _| t.get(r + 1).copied().unwrap_or(0.0));
    let s = m
        .lu()
        .solve(&rhs)
        .expect("coprime: the Sylvester matrix is invertible");
    let x = std::iter::once(0.0)
        .chain(s.iter().take(n).copied())
        .collect();
    let y = std::iter::once(0.0)
        .chain(s.iter().skip(n).copied())
        .collect();
    (x, y)
}

/// The SISO plant (4.1) as its difference equation, `y_k` from `u_{k−1}` and older.
struct Plant {
    num: Vec<f64>,
    den: Vec<f64>,
    y: Vec<f64>,
    u: Vec<f64>,
}

impl Plant {
    fn new(num: &[f64], den: &[f64]) -> Self {
        assert_eq!(num[0], 0.0, "strictly proper");
        Self {
            num: num.to_vec(),
            den: den.to_vec(),
            y: Vec::new(),
            u: Vec::new(),
        }
    }

    /// `y_k` for the next `k` (inputs `u_0 … u_{k−1}` applied so far).
    fn output(&mut self) -> f64 {
        let k = self.y.len();
        let mut v = 0.0;
        for (i, c) in self.num.iter().enumerate().skip(1) {
            if i <= k {
                v += c * self.u[k - i];
            }
        }
        for (i, c) in self.den.iter().enumerate().skip(1) {
            if i <= k {
                v -= c * self.y[k - i];
            }
        }
        self.y.push(v);
        v
    }

    fn apply(&mut self, u: f64) {
        self.u.push(u);
    }
}

/// A closed-loop run: samples `k = 0..steps`, with `y`, `u`, `r` and the controller's `e`
/// and `ẑ` recorded, and the statuses.
struct Run {
    y: Vec<f64>,
    u: Vec<f64>,
    r: Vec<f64>,
    e: Vec<f64>,
    zhat: Vec<f64>,
    statuses: Vec<u32>,
}

/// One step of the SISO controller `c` at sample `k` with `y` and `r`, on time (no loss,
/// no reported input); returns `u` and the status.
fn step_on_time(c: &mut dyn Controller, k: usize, y: f64, r: f64) -> ([f64; 1], u32) {
    let mut u = [0.0];
    let input = StepInput {
        seq: k as u64,
        y: &[y],
        z: &[y],
        r: &[r],
        u_applied: None,
        lost: 0,
    };
    let st = c.step(&input, &mut u);
    (u, st)
}

fn run(
    c: &mut dyn Controller,
    plant: &mut Plant,
    command: impl Fn(usize) -> f64,
    steps: usize,
) -> Run {
    let mut out = Run {
        y: vec![],
        u: vec![],
        r: vec![],
        e: vec![],
        zhat: vec![],
        statuses: vec![],
    };
    let names = c.internal_names();
    let ie = names
        .iter()
        .position(|n| n.ends_with("_e"))
        .expect("e internal");
    let iz = names
        .iter()
        .position(|n| n.ends_with("_zhat"))
        .expect("zhat internal");
    let mut internals = [0.0; control::MAX_INTERNALS];
    for k in 0..steps {
        let y = plant.output();
        let r = command(k);
        let (u, st) = step_on_time(c, k, y, r);
        plant.apply(u[0]);
        c.internals(&mut internals);
        out.y.push(y);
        out.u.push(u[0]);
        out.r.push(r);
        out.e.push(internals[ie]);
        out.zhat.push(internals[iz]);
        out.statuses.push(st);
    }
    out
}

/// `‖e‖ = sqrt(Σ_{i=101}^{200} e_i²)` (4.85).
fn e_norm(e: &[f64]) -> f64 {
    e[101..=200].iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// The bound on ‖e‖ (4.85) of RC-MRAC on the step of Example 1b at ρ = 0.5, ν = π/4
/// (measured: 1.2·10⁻⁶). Why 10⁻⁴: the reference output over the same samples has
/// ‖y_m‖ = 4.0 (`y_m → N(1)/D_m(1) = 0.4`), so the bound asks for model following to
/// 2.5·10⁻⁵ of the reference's own size, i.e. converged: RLS with `λ = 1` and
/// `R_θ = 10⁻⁵ I` identifies the `2n + n_s + 1 = 6` coefficients from the transient of
/// the first samples (the chapter's point that RC-MRAC needs no persistency), after which
/// the residual error decays with the closed-loop poles (`|0.5 e^{±jπ/2}| = 0.5`) and the
/// slowly vanishing RLS correction. The factor of about 80 over the measured value leaves
/// room for rounding differences (FMA or not in the RLS kernel) without letting a
/// non-converged run (‖e‖ of order 10⁻²–1) pass.
const RC_MRAC_STEP_BOUND: f64 = 1e-4;
/// The bound on ‖e‖ (4.85) of APPC on the four-harmonic command of Example 1a at ρ = 0.5,
/// ν = π/4 (measured: 1.0·10⁻²). Why 5·10⁻²: APPC identifies `4n = 8` coefficients and
/// converges only as fast as the command excites them (the persistency condition (4.45),
/// for which (4.44) asks `2n = 4` harmonics), so after 200 steps its error is still a
/// fraction of a percent of the reference (‖y_m‖ = 8.4 over the same samples); the
/// bound, 0.6 % of ‖y_m‖, asserts that level of following, and the test also asserts the
/// chapter's ordering: the four-harmonic error is below those of the step and of the
/// two-harmonic command.
const APPC_FOUR_HARMONIC_BOUND: f64 = 5e-2;

/// A command `r_k`.
type Command = fn(usize) -> f64;

fn step_command(_: usize) -> f64 {
    1.0
}

fn two_harmonic(k: usize) -> f64 {
    let k = k as f64;
    k.cos() + (k / 8.0).cos()
}

fn four_harmonic(k: usize) -> f64 {
    let k = k as f64;
    k.cos() + (k / 2.0).cos() + (k / 4.0).cos() + (k / 8.0).cos()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |a, x| a.max(x.abs()))
}

// ---------------------------------------------------------------------------------------
// The examples.

/// Example 1 (4.83)–(4.84): `N = q⁻¹ − 0.5 q⁻²`; Example 2 (4.88)–(4.89):
/// `N = q⁻¹ − 1.5 q⁻²`; `N_m = N` in both.
struct Example {
    num: Vec<f64>,
    den: Vec<f64>,
    d_m: Vec<f64>,
    /// `N_u`, `N_s` of (4.46) (`N_{n_r} = 1`, `n_r = 1`).
    n_u: Vec<f64>,
    n_s: Vec<f64>,
    /// `F` of (4.87) / (4.91) and `H` of (4.86) / (4.90).
    f: Vec<f64>,
    h: Vec<f64>,
}

fn example1(rho: f64, nu: f64) -> Example {
    Example {
        num: vec![0.0, 1.0, -0.5],
        den: plant_den(rho, nu),
        d_m: model_den(),
        n_u: vec![1.0],
        n_s: vec![1.0, -0.5],
        f: vec![1.0, 0.5],
        h: vec![1.0, 0.0, -0.25],
    }
}

fn example2(rho: f64, nu: f64) -> Example {
    Example {
        num: vec![0.0, 1.0, -1.5],
        den: plant_den(rho, nu),
        d_m: model_den(),
        n_u: vec![1.0, -1.5],
        n_s: vec![1.0],
        f: vec![1.0, 0.0, -0.25],
        h: vec![1.0, 0.0, -0.25],
    }
}

impl Example {
    fn appc_params(&self) -> AppcParams {
        AppcParams::new(2, self.d_m.clone(), self.num.clone(), self.h.clone())
    }

    fn rc_mrac_params(&self) -> RcMracParams {
        RcMracParams::new(
            2,
            1,
            1.0,
            self.n_u.clone(),
            poly::degree(&self.n_s),
            self.f.clone(),
            self.d_m.clone(),
            self.num.clone(),
        )
    }

    /// `N_c*`, `D_c*` of (4.18)–(4.19): `N_c N + D_c D = D − D_m H`.
    fn appc_controller(&self, h: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let t = sub(&self.den, &poly::mul(&self.d_m, h));
        diophantine(&self.num, &self.den, &t, 2)
    }

    /// `B*`, `C*` of (4.22)–(4.24): `B N + C D = 1`, `C = 1 + C'`, so `B N + C' D = 1 − D`.
    fn bezout(&self) -> (Vec<f64>, Vec<f64>) {
        let t = sub(&[1.0], &self.den);
        let (b, mut c) = diophantine(&self.num, &self.den, &t, 2);
        c[0] = 1.0;
        (b, c)
    }

    /// `N_c*`, `D_c*` of (4.54)–(4.55): `N_c N + D_c D = D − D_m N_s F`.
    fn rc_mrac_controller(&self) -> (Vec<f64>, Vec<f64>) {
        let t = sub(
            &self.den,
            &poly::mul(&poly::mul(&self.d_m, &self.n_s), &self.f),
        );
        diophantine(&self.num, &self.den, &t, 2)
    }
}

/// `θ* = [N_c,1..n, D_c,1..n, B_1..n, C_1..n]` (4.35)–(4.36).
fn appc_theta_star(ex: &Example) -> Vec<f64> {
    let (nc, dc) = ex.appc_controller(&ex.h);
    let (b, c) = ex.bezout();
    [&nc[1..], &dc[1..], &b[1..], &c[1..]].concat()
}

/// `θ* = [N_c,1..n, D_c,1..n, R_c,0..n_s]` (4.68), `R_c* = N_s` (4.57) with `N_m = N`.
fn rc_mrac_theta_star(ex: &Example) -> Vec<f64> {
    let (nc, dc) = ex.rc_mrac_controller();
    [&nc[1..], &dc[1..], &ex.n_s[..]].concat()
}

// ---------------------------------------------------------------------------------------
// True coefficients: the performance variables are zero and the closed loop is (4.20),
// (4.56).

/// A run started at the true coefficients `θ*` (relative to `scale`): the performance
/// `z.0` (from the recorded signals, by equation `z.1`) and `ẑ` vanish and every status is
/// OK; `θ̂` stays at `θ*`; `y` is the closed loop's `want` and `e` vanishes.
fn assert_exact(
    out: &Run,
    z: (&[f64], &str),
    theta_hat: &[f64],
    theta: &[f64],
    want: &[f64],
    scale: f64,
) {
    let (z, eq) = z;
    for k in 0..200 {
        assert!(z[k].abs() < 1e-12 * scale, "{eq} z_{k} = {:e}", z[k]);
        assert!(
            out.zhat[k].abs() < 1e-10 * scale,
            "ẑ_{k} = {:e}",
            out.zhat[k]
        );
        assert_eq!(out.statuses[k], status::OK);
    }
    for (t, w) in theta_hat.iter().zip(theta) {
        assert!((t - w).abs() < 1e-9, "θ̂ {t} vs θ* {w}");
    }
    for k in 0..200 {
        assert!(
            (out.y[k] - want[k]).abs() < 1e-10 * scale,
            "y_{k}: {} vs {}",
            out.y[k],
            want[k]
        );
        assert!(out.e[k].abs() < 1e-10 * scale, "e_{k} = {:e}", out.e[k]);
    }
}

#[test]
fn appc_with_the_true_coefficients_has_zero_performance_and_the_closed_loop_4_20() {
    for ex in [
        example1(0.5, PI / 4.0),
        example1(0.9, 2.0),
        example2(0.5, PI / 4.0),
    ] {
        let theta = appc_theta_star(&ex);
        let mut p = ex.appc_params();
        p.theta0 = Some(theta.clone());
        let mut c = Appc::new(&p, SISO).expect("valid");
        let mut plant = Plant::new(&ex.num, &ex.den);
        let out = run(&mut c, &mut plant, four_harmonic, 200);
        // (4.33) with the true polynomials, from the recorded signals.
        let (nc, dc) = ex.appc_controller(&ex.h);
        let (b, cc) = ex.bezout();
        let dmh = poly::mul(&ex.d_m, &ex.h);
        let inner: Vec<f64> = fir(&b, &out.y)
            .iter()
            .zip(fir(&cc, &out.u))
            .map(|(a, b)| a + b)
            .collect();
        let lhs = fir(&dmh, &inner);
        let ncy = fir(&nc, &out.y);
        let dcu = fir(&dc, &out.u);
        let scale = max_abs(&out.u).max(max_abs(&out.y));
        let z: Vec<f64> = (0..200)
            .map(|k| lhs[k] - (out.u[k] - ncy[k] - dcu[k]))
            .collect();
        // The closed loop is y = N/D_m r (4.20), so e = 0 with N_m = N.
        let want = tf(&ex.num, &ex.d_m, &out.r);
        assert_exact(&out, (&z, "(4.33)"), c.theta(), &theta, &want, scale);
    }
}

#[test]
fn rc_mrac_with_the_true_coefficients_has_zero_performance_and_the_closed_loop_4_56() {
    for ex in [
        example1(0.5, PI / 4.0),
        example1(0.9, 2.0),
        example2(0.5, PI / 4.0),
    ] {
        let theta = rc_mrac_theta_star(&ex);
        let mut p = ex.rc_mrac_params();
        assert_eq!(p.model_cofactor().expect("valid"), ex.n_s, "R_c* of (4.57)");
        p.theta0 = Some(theta.clone());
        let mut c = RcMrac::new(&p, SISO).expect("valid");
        let mut plant = Plant::new(&ex.num, &ex.den);
        let out = run(&mut c, &mut plant, two_harmonic, 200);
        // (4.66) with the true polynomials: D_m F e − N_{n_r} N_u q^{−n_r}[u − N_c y − D_c u − R_c F r].
        let (nc, dc) = ex.rc_mrac_controller();
        let y_m = tf(&ex.num, &ex.d_m, &out.r);
        let e: Vec<f64> = out.y.iter().zip(&y_m).map(|(a, b)| a - b).collect();
        let zf = fir(&poly::mul(&ex.d_m, &ex.f), &e);
        let rcf = fir(&poly::mul(&ex.n_s, &ex.f), &out.r);
        let ncy = fir(&nc, &out.y);
        let dcu = fir(&dc, &out.u);
        let bracket: Vec<f64> = (0..200)
            .map(|k| out.u[k] - ncy[k] - dcu[k] - rcf[k])
            .collect();
        let nuq = [&[0.0][..], &ex.n_u[..]].concat(); // N_{n_r} N_u q^{−1}
        let second = fir(&nuq, &bracket);
        let scale = max_abs(&out.u).max(max_abs(&out.y)).max(1.0);
        let z: Vec<f64> = (0..200).map(|k| zf[k] - second[k]).collect();
        // (4.56): y = N_{n_r} N_u R_c q^{−n_r} / D_m r = N/D_m r.
        let num_cl = poly::mul(&nuq, &ex.n_s);
        let want = tf(&num_cl, &ex.d_m, &out.r);
        assert_exact(&out, (&z, "(4.66)"), c.theta(), &theta, &want, scale);
    }
}

// ---------------------------------------------------------------------------------------
// Proposition 4.4.1.

#[test]
fn proposition_4_4_1_the_same_controller_satisfies_4_65_and_4_32() {
    let ex = example1(0.5, PI / 4.0);
    // H = N_s F (4.86).
    let h = poly::mul(&ex.n_s, &ex.f);
    assert_eq!(h, ex.h);
    let (nc_a, dc_a) = ex.appc_controller(&h);
    let (nc_r, dc_r) = ex.rc_mrac_controller();
    for (a, r) in nc_a.iter().chain(&dc_a).zip(nc_r.iter().chain(&dc_r)) {
        assert!((a - r).abs() < 1e-12, "{a} vs {r}");
    }
    // Both identities on the same data: an arbitrary input and command (open loop).
    let u: Vec<f64> = (0..200)
        .map(|k| ((k * 7919) % 101) as f64 / 50.0 - 1.0)
        .collect();
    let r: Vec<f64> = (0..200).map(four_harmonic).collect();
    let y = tf(&ex.num, &ex.den, &u);
    let y_m = tf(&ex.num, &ex.d_m, &r); // N_m = N
    let (b, c) = ex.bezout();
    let (nc, dc) = (nc_a, dc_a);
    let ctrl: Vec<f64> = {
        let ncy = fir(&nc, &y);
        let dcu = fir(&dc, &u);
        (0..200).map(|k| u[k] - ncy[k] - dcu[k]).collect()
    };
    // (4.32): D_m H [B y + C u] = u − N_c y − D_c u.
    let by_cu: Vec<f64> = fir(&b, &y)
        .iter()
        .zip(fir(&c, &u))
        .map(|(a, b)| a + b)
        .collect();
    let lhs_432 = fir(&poly::mul(&ex.d_m, &h), &by_cu);
    // (4.65): D_m F (y − y_m) − N_{n_r} N_u q^{−n_r}[u − N_c y − D_c u − R_c F r] = 0, R_c = N_s.
    let e: Vec<f64> = y.iter().zip(&y_m).map(|(a, b)| a - b).collect();
    let zf = fir(&poly::mul(&ex.d_m, &ex.f), &e);
    let rcf = fir(&poly::mul(&ex.n_s, &ex.f), &r);
    let bracket: Vec<f64> = (0..200).map(|k| ctrl[k] - rcf[k]).collect();
    let second = fir(&[0.0, 1.0], &bracket);
    let scale = max_abs(&y).max(max_abs(&u));
    for k in 0..200 {
        assert!(
            (lhs_432[k] - ctrl[k]).abs() < 1e-12 * scale,
            "(4.32) at {k}"
        );
        assert!((zf[k] - second[k]).abs() < 1e-12 * scale, "(4.65) at {k}");
    }
}

// ---------------------------------------------------------------------------------------
// Adaptive runs of 200 steps, θ̂_0 = 0, R_θ = 10⁻⁵ I, λ = 1.

fn rc_mrac_e_norm(ex: &Example, command: fn(usize) -> f64) -> (f64, Run) {
    let mut c = RcMrac::new(&ex.rc_mrac_params(), SISO).expect("valid");
    let mut plant = Plant::new(&ex.num, &ex.den);
    let out = run(&mut c, &mut plant, command, 201);
    (e_norm(&out.e), out)
}

fn appc_e_norm(ex: &Example, command: fn(usize) -> f64) -> (f64, Run) {
    let mut c = Appc::new(&ex.appc_params(), SISO).expect("valid");
    let mut plant = Plant::new(&ex.num, &ex.den);
    let out = run(&mut c, &mut plant, command, 201);
    (e_norm(&out.e), out)
}

#[test]
fn rc_mrac_follows_the_step_of_example_1() {
    let (norm, out) = rc_mrac_e_norm(&example1(0.5, PI / 4.0), step_command);
    println!("RC-MRAC, Example 1b, step, ρ = 0.5, ν = π/4: ‖e‖ = {norm:.3e}");
    assert!(out.statuses.iter().all(|&s| s == status::OK));
    assert!(norm < RC_MRAC_STEP_BOUND, "‖e‖ = {norm:e}");
    println!(
        "  ‖y_m‖ over the same samples = {:.3}",
        model_output_norm(step_command)
    );
}

#[test]
fn appc_follows_the_four_harmonic_command_of_example_1() {
    let (norm, out) = appc_e_norm(&example1(0.5, PI / 4.0), four_harmonic);
    println!("APPC, Example 1a, four harmonics, ρ = 0.5, ν = π/4: ‖e‖ = {norm:.3e}");
    assert!(out.statuses.iter().all(|&s| s == status::OK));
    assert!(norm < APPC_FOUR_HARMONIC_BOUND, "‖e‖ = {norm:e}");
    let ym = model_output_norm(four_harmonic);
    println!("  ‖y_m‖ over the same samples = {ym:.3}");
    let ex = example1(0.5, PI / 4.0);
    let (step, _) = appc_e_norm(&ex, step_command);
    let (two, _) = appc_e_norm(&ex, two_harmonic);
    assert!(
        norm < step && norm < two,
        "four {norm:e}, step {step:e}, two {two:e}"
    );
}

/// `sqrt(Σ_{i=101}^{200} y_{m,i}²)` for the reference model of Example 1.
fn model_output_norm(command: fn(usize) -> f64) -> f64 {
    let ex = example1(0.5, PI / 4.0);
    let r: Vec<f64> = (0..201).map(command).collect();
    e_norm(&tf(&ex.num, &ex.d_m, &r))
}

/// Prints ‖e‖ for every command of Examples 1 and 2 at ρ = 0.5, ν = π/4 (the figures'
/// b panels); asserts only that the runs stay finite.
#[test]
fn the_chapter_table_at_rho_one_half_nu_pi_over_four() {
    let commands: [(&str, Command); 3] = [
        ("step", step_command),
        ("two harmonics", two_harmonic),
        ("four harmonics", four_harmonic),
    ];
    for (name, ex) in [
        ("Example 1", example1(0.5, PI / 4.0)),
        ("Example 2", example2(0.5, PI / 4.0)),
    ] {
        for (cname, cmd) in commands {
            let (a, ra) = appc_e_norm(&ex, cmd);
            let (r, rr) = rc_mrac_e_norm(&ex, cmd);
            println!("{name}, {cname}: APPC ‖e‖ = {a:.3e}, RC-MRAC ‖e‖ = {r:.3e}");
            assert!(ra.y.iter().chain(&rr.y).all(|v| v.is_finite()));
            if name == "Example 1" {
                // "For minimum-phase systems, RC-MRAC outperforms APPC" (§4.8).
                assert!(r < a, "{cname}: RC-MRAC {r:e} vs APPC {a:e}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Bad parameters are refused naming the field.

#[test]
fn bad_rc_mrac_parameters_are_refused_by_field() {
    let ex = example1(0.5, PI / 4.0);
    let good = ex.rc_mrac_params();
    assert!(good.validate().is_ok());
    let field = |p: &RcMracParams| RcMrac::new(p, SISO).expect_err("refused").field;

    let mut p = good.clone();
    p.f = vec![1.0, -1.2]; // root 1.2: unstable
    assert_eq!(field(&p), "f");
    p.f = vec![2.0, 0.5]; // not monic
    assert_eq!(field(&p), "f");
    p.f = vec![1.0, 0.5, 0.06]; // degree 2 > n − n_s = 1
    assert_eq!(field(&p), "f");

    let mut p = good.clone();
    p.n_u = vec![1.0, -0.5]; // root 0.5, inside the unit circle
    assert_eq!(field(&p), "n-u");
    p.n_u = vec![2.0, -3.0]; // not monic
    assert_eq!(field(&p), "n-u");

    let mut p = good.clone();
    p.n_s = 2; // n_r + n_u + n_s = 3 > n = 2
    assert_eq!(field(&p), "n-s");
    let mut p = good.clone();
    p.relative_degree = 0;
    assert_eq!(field(&p), "relative-degree");
    let mut p = good.clone();
    p.leading_coefficient = 0.0;
    assert_eq!(field(&p), "leading-coefficient");
    let mut p = good.clone();
    p.n = 0;
    assert_eq!(field(&p), "n");

    let mut p = good.clone();
    p.d_m = vec![1.0, 0.0, 1.44]; // poles ±1.2j
    assert_eq!(field(&p), "d-m");
    let mut p = good.clone();
    p.n_m = vec![1.0, -0.5]; // relative degree 0 < n_r
    assert_eq!(field(&p), "n-m");
    let ex2 = example2(0.5, PI / 4.0);
    let mut p = ex2.rc_mrac_params();
    assert!(p.validate().is_ok());
    p.n_m = vec![0.0, 1.0, -0.5]; // N_u = 1 − 1.5 q⁻¹ does not divide it (4.57)
    assert_eq!(field(&p), "n-m");

    let mut p = good.clone();
    p.r_theta = vec![1e-5; 5]; // 2n + n_s + 1 = 6
    assert_eq!(field(&p), "r-theta");
    let mut p = good.clone();
    p.theta0 = Some(vec![0.0; 8]);
    assert_eq!(field(&p), "theta0");
    let mut p = good.clone();
    p.forgetting = ForgettingRule::Constant { lambda: 0.0 };
    assert_eq!(field(&p), "forgetting.lambda");
    let mut p = good.clone();
    p.limits = Some(OutputLimits {
        min: vec![1.0],
        max: vec![-1.0],
    });
    assert_eq!(field(&p), "u-min");

    let e = RcMrac::new(&good, Dimensions::new(2, 1, 1, 1)).expect_err("MIMO");
    assert_eq!(e.field, "channels");
}

#[test]
fn bad_appc_parameters_are_refused_by_field() {
    let ex = example1(0.5, PI / 4.0);
    let good = ex.appc_params();
    assert!(good.validate().is_ok());
    let field = |p: &AppcParams| Appc::new(p, SISO).expect_err("refused").field;

    let mut p = good.clone();
    p.h = vec![0.5, 0.0, -0.25]; // not monic
    assert_eq!(field(&p), "h");
    p.h = vec![1.0, 0.0, -1.21]; // roots ±1.1
    assert_eq!(field(&p), "h");
    p.h = vec![1.0, 0.0, 0.0, 0.1]; // degree 3 > n
    assert_eq!(field(&p), "h");
    let mut p = good.clone();
    p.d_m = vec![1.0, -1.0]; // root on the unit circle: not asymptotically stable
    assert_eq!(field(&p), "d-m");
    let mut p = good.clone();
    p.n_m = vec![0.0, 1.0, f64::NAN];
    assert_eq!(field(&p), "n-m");
    let mut p = good.clone();
    p.r_theta = vec![1e-5; 6]; // 4n = 8
    assert_eq!(field(&p), "r-theta");
    p.r_theta = vec![1e-5; 8];
    p.r_theta[3] = -1.0;
    let e = Appc::new(&p, SISO).expect_err("refused");
    assert_eq!((e.field, e.index), ("r-theta", Some(3)));
    let mut p = good.clone();
    p.theta0 = Some(vec![0.0; 6]);
    assert_eq!(field(&p), "theta0");
    let mut p = good.clone();
    p.trace_limit = 8.0;
    assert_eq!(field(&p), "trace-limit");
    let mut p = good.clone();
    p.n = 0;
    assert_eq!(field(&p), "n");
}

// ---------------------------------------------------------------------------------------
// Bad samples.

/// Example 1 at ρ = 1/2, ν = π/4 and its APPC and RC-MRAC controllers.
fn both_of_example1() -> (Example, [Box<dyn Controller>; 2]) {
    let ex = example1(0.5, PI / 4.0);
    let controllers: [Box<dyn Controller>; 2] = [
        Box::new(Appc::new(&ex.appc_params(), SISO).expect("valid")),
        Box::new(RcMrac::new(&ex.rc_mrac_params(), SISO).expect("valid")),
    ];
    (ex, controllers)
}

#[test]
fn a_non_finite_sample_holds_the_input_with_a_fault_and_the_loop_goes_on() {
    let (ex, mut controllers) = both_of_example1();
    for c in controllers.iter_mut() {
        let mut plant = Plant::new(&ex.num, &ex.den);
        let mut last = 0.0;
        for k in 0..300 {
            let mut y = plant.output();
            let mut r = four_harmonic(k);
            if k == 120 {
                y = f64::NAN;
            }
            if k == 150 {
                r = f64::INFINITY;
            }
            let (u, st) = step_on_time(c.as_mut(), k, y, r);
            if k == 120 || k == 150 {
                assert_eq!(st, status::CONTROLLER_FAULT, "{} at {k}", c.kind());
                assert_eq!(u[0], last, "{}: the input is held", c.kind());
            } else {
                assert_eq!(st, status::OK, "{} at {k}", c.kind());
            }
            assert!(u[0].is_finite());
            last = u[0];
            plant.apply(u[0]);
        }
        let mut internals = [0.0; control::MAX_INTERNALS];
        let n = c.internals(&mut internals);
        assert_eq!(n, c.internal_names().len());
        // Still following after the faults: e of the last sample is small.
        assert!(
            internals[1].abs() < 0.05,
            "{}: e = {}",
            c.kind(),
            internals[1]
        );
    }
}

#[test]
fn the_adaptation_counts_say_which_closed_loop_steps_updated_and_why_the_others_did_not() {
    let (ex, mut controllers) = both_of_example1();
    for c in controllers.iter_mut() {
        let mut plant = Plant::new(&ex.num, &ex.den);
        let (mut last, mut steps, mut lost) = (0.0, 0, 0);
        for k in 0..300 {
            let mut y = plant.output();
            // One bad sample, three samples that never reach the controller, one sample
            // taken in late (observed, not answered).
            if k == 120 {
                y = f64::NAN;
            }
            if (200..203).contains(&k) {
                lost += 1;
                plant.apply(last);
                continue;
            }
            let input = StepInput {
                seq: k as u64,
                y: &[y],
                z: &[y],
                r: &[four_harmonic(k)],
                u_applied: None,
                lost: std::mem::take(&mut lost),
            };
            let mut u = [0.0];
            if k == 250 {
                c.observe(&input, &mut u);
            } else {
                c.step(&input, &mut u);
                last = u[0];
                steps += 1;
            }
            plant.apply(last);
        }
        let a = c.adaptation().expect("an adaptive controller counts");
        let cause = |name: &str| {
            a.suspended
                .iter()
                .find(|(c, _)| *c == name)
                .map(|(_, n)| *n)
                .unwrap_or_else(|| panic!("{name}: {:?}", a.suspended))
        };
        let (gap, bad) = (cause("a bridged gap in its windows"), cause("a bad sample"));
        // Every closed-loop step is counted once, the observed sample not at all.
        assert_eq!(a.updated + a.suspended(), steps, "{}: {a:?}", c.kind());
        // The bad sample itself and the windows after it; after the gap, its windows (the
        // lost samples already filled part of them).
        assert!(gap > 0, "{}: {a:?}", c.kind());
        assert_eq!(bad, gap + 1, "{}: {a:?}", c.kind());
        assert!(a.updated > 250, "{}: {a:?}", c.kind());
    }
}

// ---------------------------------------------------------------------------------------
// Example 3 (§4.7): an unknown harmonic input disturbance, rejected by raising the order.

/// RC-MRAC on Example 1's plant with `d_k = sin(0.35 k)` added at the input, a unit step
/// command, 200 steps; returns ‖e‖ (4.85).
fn example3_e_norm(n: usize, n_s: usize) -> f64 {
    let ex = example1(0.5, PI / 4.0);
    let p = RcMracParams::new(
        n,
        1,
        1.0,
        vec![1.0],
        n_s,
        ex.f.clone(),
        ex.d_m.clone(),
        ex.num.clone(),
    );
    assert_eq!(p.r_theta.len(), 2 * n + n_s + 1);
    let mut c = RcMrac::new(&p, SISO).expect("valid");
    let mut plant = Plant::new(&ex.num, &ex.den);
    let mut e = Vec::new();
    let mut internals = [0.0; control::MAX_INTERNALS];
    for k in 0..201 {
        let y = plant.output();
        let (u, st) = step_on_time(&mut c, k, y, 1.0);
        assert_eq!(st, status::OK);
        plant.apply(u[0] + (0.35 * k as f64).sin());
        c.internals(&mut internals);
        e.push(internals[1]);
    }
    e_norm(&e)
}

#[test]
fn rc_mrac_of_order_4_rejects_the_harmonic_disturbance_of_example_3() {
    // n = 4, n_s = 3, θ̂_0 = 0_{12×1}, R_θ = 10⁻⁵ I_12, λ = 1, F = 1 + 0.5 q⁻¹ (§4.7).
    let rejecting = example3_e_norm(4, 3);
    // The order of Example 1b (n = 2, n_s = 1) has no room for the disturbance's model.
    let plain = example3_e_norm(2, 1);
    println!(
        "Example 3, step with sin(0.35 k) at the input: n = 4 ‖e‖ = {rejecting:.3e}, n = 2 ‖e‖ = {plain:.3e}"
    );
    // Measured: 1.6·10⁻² for n = 4 against 2.6 for n = 2, whose controller cannot model
    // the harmonic (the disturbance stays in y). The bound 5·10⁻², and a factor of 10
    // below the plain order, assert that it is rejected while the step is followed.
    assert!(rejecting < 5e-2, "‖e‖ = {rejecting:e}");
    assert!(rejecting < 0.1 * plain, "{rejecting:e} vs {plain:e}");
}

// ---------------------------------------------------------------------------------------
// Lost samples and the applied input.

#[test]
fn lost_samples_are_bridged_and_counted_and_the_loop_recovers() {
    let ex = example1(0.5, PI / 4.0);
    let mut c = RcMrac::new(&ex.rc_mrac_params(), SISO).expect("valid");
    let mut plant = Plant::new(&ex.num, &ex.den);
    let mut held = 0.0;
    let mut seq = 0u64;
    for k in 0..400usize {
        let y = plant.output();
        // Samples 100..103 never reach the controller: the plant holds its input.
        if (100..103).contains(&k) {
            plant.apply(held);
            continue;
        }
        let lost = if k == 103 { 3 } else { 0 };
        let mut u = [0.0];
        let st = c.step(
            &StepInput {
                seq,
                y: &[y],
                z: &[y],
                r: &[1.0],
                u_applied: Some(&[held]),
                lost,
            },
            &mut u,
        );
        seq += 1 + lost;
        assert_eq!(st, status::OK);
        held = u[0];
        plant.apply(u[0]);
    }
    assert!(c.counters().contains(&("gaps bridged", 1)));
    assert!(c.e().abs() < 1e-6, "e = {:e}", c.e());
}
