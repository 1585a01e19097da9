//! The time-varying plant (5.8) of the chapter 5 example, derived from a continuous
//! mass-spring-damper model and discretized with `plant_proxy::lti`.
//!
//! # The continuous model
//!
//! The chapter states `M = 5 kg`, `K = 1 N/m`, `C = 1 N·s/m`, changing at step 100 to
//! `K = 10 N/m`, `C = 0.01 N·s/m`. Inverting (5.8) — the discrete poles `z` of each
//! denominator give `s = ln(z)/T`, hence `2ζω_n = −2 Re s` and `ω_n² = |s|²`, and the DC gain
//! `G(1)` gives the continuous gain `b = G(1) ω_n²` — yields, with `T = 1 s`
//! (`0.8187 = e^{−0.2}` and `C/M = 0.2 s⁻¹`):
//!
//! ```text
//! before: C/M = 0.2  s⁻¹, K/M = 0.2 s⁻², b = 1      (M = 5, C = 1,    K = 1)
//! after:  C/M = 0.002 s⁻¹, K/M = 2  s⁻², b = 1      (M = 5, C = 0.01, K = 10)
//! ```
//!
//! so the printed transfer functions are the zero-order-hold discretizations at `T = 1 s`
//! of `G(s) = 1/(s² + (C/M) s + K/M) = M/(M s² + C s + K)`: the input is the applied force
//! per unit mass, `u = F/M` (a plain `1/(M s² + C s + K)` would have DC gain `1/K = 1`
//! before the change, not the printed `0.8913/0.1787 ≈ 5`).
//!
//! # The discrete model and the regressor
//!
//! With `G_k(q) = (b_0 q² + b_1 q + b_2)/(q² + a_1 q + a_2)` the output obeys
//! `y_k = −a_1 y_{k−1} − a_2 y_{k−2} + b_0 u_k + b_1 u_{k−1} + b_2 u_{k−2} = φ_k θ` with
//! `φ_k = [y_{k−1} y_{k−2} u_k u_{k−1} u_{k−2}]` and `θ = [−a_1, −a_2, b_0, b_1, b_2]`
//! (`b_0 = 0`: the plant is strictly proper). The time-varying plant (5.8) is this
//! difference equation with the coefficients switched at `k = 100`, from zero initial
//! conditions.

use plant_proxy::lti::Tf;

use crate::study::forgetting::ForgettingError;

/// Sample period `T` (s) recovered from (5.8): `−ln(0.8187)/(C/M)` with `C/M = 0.2 s⁻¹`.
pub const SAMPLE_PERIOD: f64 = 1.0;
/// The step at which the plant coefficients change.
pub const CHANGE_STEP: usize = 100;
/// Mass `M` (kg) of the chapter's example.
pub const MASS: f64 = 5.0;

/// The printed coefficients of (5.8): `(num [b_1, b_2], den [1, a_1, a_2])` before and after.
pub const PRINTED: [([f64; 2], [f64; 3]); 2] = [
    ([0.4606, 0.4307], [1.0, -1.64, 0.8187]),
    ([0.4218, 0.4215], [1.0, -0.3116, 0.998]),
];

/// A continuous mass-spring-damper `G(s) = b/(s² + (C/M) s + K/M)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Msd {
    /// Damping per unit mass `C/M` (s⁻¹).
    pub c_over_m: f64,
    /// Stiffness per unit mass `K/M` (s⁻²).
    pub k_over_m: f64,
    /// Numerator gain `b` (input: force per unit mass).
    pub gain: f64,
}

impl Msd {
    /// The chapter's model before (`false`) or after (`true`) the change at step 100.
    pub fn chapter(after: bool) -> Self {
        let (k, c) = if after { (10.0, 0.01) } else { (1.0, 1.0) };
        Self {
            c_over_m: c / MASS,
            k_over_m: k / MASS,
            gain: 1.0,
        }
    }

    /// Inverts a printed discrete second-order transfer function `(b_1 q + b_2)/(q² + a_1 q
    /// + a_2)` with complex poles at sample period `t`: `s = ln(z)/t` and the DC gain.
    pub fn from_discrete(num: [f64; 2], den: [f64; 3], t: f64) -> Self {
        let (a1, a2) = (den[1] / den[0], den[2] / den[0]);
        let disc = a1 * a1 / 4.0 - a2;
        assert!(disc < 0.0, "from_discrete expects complex poles");
        // z = r e^{±jw}: r² = a2, r cos w = −a1/2.
        let r = a2.sqrt();
        let w = (-a1 / 2.0 / r).acos();
        let (sigma, wd) = (r.ln() / t, w / t);
        let k_over_m = sigma * sigma + wd * wd;
        let c_over_m = -2.0 * sigma;
        let dc = (num[0] + num[1]) / (1.0 + a1 + a2);
        Self {
            c_over_m,
            k_over_m,
            gain: dc * k_over_m,
        }
    }

    /// The zero-order-hold discretization at period `t` with `plant_proxy::lti`: numerator
    /// `[b_0, b_1, b_2]` and monic denominator `[1, a_1, a_2]`.
    pub fn discretize(&self, t: f64) -> Result<([f64; 3], [f64; 3]), ForgettingError> {
        let tf = Tf::new(vec![self.gain], vec![1.0, self.c_over_m, self.k_over_m])?;
        let ss = tf.realize().c2d_zoh(t)?;
        let (num, den) = ss.channel_tf(0, 0)?;
        if num.len() != 3 || den.len() != 3 {
            return Err(ForgettingError::Orders { num, den });
        }
        Ok(([num[0], num[1], num[2]], [den[0], den[1], den[2]]))
    }
}

/// `θ = [−a_1, −a_2, b_0, b_1, b_2]` of a discrete `(num, den)` (den monic).
pub fn theta_of(num: &[f64; 3], den: &[f64; 3]) -> [f64; 5] {
    [-den[1], -den[2], num[0], num[1], num[2]]
}

/// The time-varying plant (5.8) as the true parameter vectors before and after the change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plant {
    /// True `θ` for `k < 100`.
    pub before: [f64; 5],
    /// True `θ` for `k ≥ 100`.
    pub after: [f64; 5],
}

impl Plant {
    /// Discretizes the chapter's continuous models at [`SAMPLE_PERIOD`].
    pub fn chapter() -> Result<Self, ForgettingError> {
        let (nb, db) = Msd::chapter(false).discretize(SAMPLE_PERIOD)?;
        let (na, da) = Msd::chapter(true).discretize(SAMPLE_PERIOD)?;
        Ok(Self {
            before: theta_of(&nb, &db),
            after: theta_of(&na, &da),
        })
    }

    /// True `θ` generating `y_k`.
    pub fn theta_at(&self, k: usize) -> &[f64; 5] {
        if k < CHANGE_STEP {
            &self.before
        } else {
            &self.after
        }
    }

    /// Noiseless outputs `y_0 … y_{N−1}` for inputs `u` (zero initial conditions).
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; u.len()];
        let mut phi = [0.0; 5];
        for k in 0..u.len() {
            regressor(&y, u, k, &mut phi);
            y[k] = dot(self.theta_at(k), &phi);
        }
        y
    }
}

/// Fills `φ_k = [y_{k−1} y_{k−2} u_k u_{k−1} u_{k−2}]` (zero before the start).
pub fn regressor(y: &[f64], u: &[f64], k: usize, phi: &mut [f64; 5]) {
    let at = |v: &[f64], lag: usize| if k >= lag { v[k - lag] } else { 0.0 };
    *phi = [at(y, 1), at(y, 2), u[k], at(u, 1), at(u, 2)];
}

pub use control::linalg::dot_in_order as dot;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    #[test]
    fn discretized_plant_matches_printed_5_8() {
        for (i, (num, den)) in PRINTED.iter().enumerate() {
            let (n, d) = Msd::chapter(i == 1).discretize(SAMPLE_PERIOD).unwrap();
            assert!(n[0].abs() < 1e-12, "b0 = {}", n[0]);
            let got = [n[1], n[2], d[1], d[2]];
            let want = [num[0], num[1], den[1], den[2]];
            for (g, w) in got.iter().zip(&want) {
                // (5.8) prints 4 significant digits ("1.64" is 1.640).
                assert!((g - w).abs() < 5e-4, "case {i}: {got:?} vs {want:?}");
                assert!(((g - w) / w).abs() < 5e-4, "case {i}: {got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn inverting_5_8_recovers_the_chapter_parameters() {
        for (i, (num, den)) in PRINTED.iter().enumerate() {
            let m = Msd::from_discrete(*num, *den, SAMPLE_PERIOD);
            let c = Msd::chapter(i == 1);
            assert!(
                (m.c_over_m - c.c_over_m).abs() < 2e-3 * c.c_over_m.max(0.05),
                "{m:?}"
            );
            // "1.64" is printed with 3 digits (true 1.6405), hence K/M = 0.2005 before.
            assert!((m.k_over_m / c.k_over_m - 1.0).abs() < 5e-3, "{m:?}");
            assert!((m.gain - 1.0).abs() < 5e-3, "{m:?}");
        }
    }

    #[test]
    fn state_space_simulation_obeys_the_regressor_equation() {
        // Simulate the discretized state-space model (Φ, Γ, C, D) of the pre-change plant
        // and check y_k = φ_k θ_true to rounding.
        let ss = Tf::new(vec![1.0], vec![1.0, 0.2, 0.2])
            .unwrap()
            .realize()
            .c2d_zoh(SAMPLE_PERIOD)
            .unwrap();
        let plant = Plant::chapter().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let u: Vec<f64> = (0..200).map(|_| rng.sample(StandardNormal)).collect();
        let mut x = nalgebra::DVector::zeros(2);
        let mut y = vec![0.0; u.len()];
        for k in 0..u.len() {
            y[k] = (&ss.c * &x)[0] + ss.d[(0, 0)] * u[k];
            x = &ss.a * x + &ss.b * u[k];
        }
        let mut phi = [0.0; 5];
        for k in 0..u.len() {
            regressor(&y, &u, k, &mut phi);
            assert!((y[k] - dot(&plant.before, &phi)).abs() < 1e-9, "k = {k}");
        }
        // The study's time-varying simulator satisfies the equation exactly.
        let y = plant.simulate(&u);
        for k in 0..u.len() {
            regressor(&y, &u, k, &mut phi);
            assert_eq!(y[k], dot(plant.theta_at(k), &phi));
        }
    }
}
