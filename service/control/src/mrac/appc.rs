//! Adaptive pole placement control (APPC), §4.2, (4.7)–(4.43).
//!
//! # Controller (4.10)
//!
//! ```text
//! u_k = N_c(q⁻¹) y_k + D_c(q⁻¹) u_k + H(q⁻¹) r_k                                  (4.10)
//! N_c = Σ_{i=1}^{n} N_{c,i} q⁻ⁱ,  D_c = Σ_{i=1}^{n} D_{c,i} q⁻ⁱ,  H = 1 + Σ_{i=1}^{n} H_i q⁻ⁱ   (4.11)–(4.13)
//! ```
//!
//! `H` asymptotically stable and monic. With `N_c*`, `D_c*` solving the Diophantine
//! equation `D_m H = D − N_c* N − D_c* D` (4.18)–(4.19) the closed loop is
//! `y_k = N/D_m r_k` (4.20); with the Bezout pair `1 = B* N + C* D` (4.22)–(4.24),
//!
//! ```text
//! D_m H [B* y_k + C* u_k] = u_k − N_c* y_k − D_c* u_k                               (4.32)
//! ```
//!
//! holds for any input, which is the regression of the algorithm.
//!
//! # Regression and update (4.35)–(4.42)
//!
//! ```text
//! θ_1 = [N_{c,1} … N_{c,n} D_{c,1} … D_{c,n}]ᵀ,  θ_2 = [B_1 … B_n C_1 … C_n]ᵀ           (4.35)–(4.36)
//! Φ_k     = [y_{k−1} … y_{k−n} u_{k−1} … u_{k−n}]                                     (4.38)
//! Φ_{f,k} = D_m(q⁻¹) H(q⁻¹) Φ_k                                                      (4.39)
//! u_{f,k} = [D_m(q⁻¹) H(q⁻¹) − 1] u_k                                                 (4.40)
//! ẑ_k(θ̂_1, θ̂_2) = [Φ_k Φ_{f,k}] [θ̂_1; θ̂_2] + u_{f,k}                                   (4.41)
//! ```
//!
//! and RLS minimizes (4.42) with `θ̂_0 = [θ̂_{1,0}; θ̂_{2,0}]`, `R_θ` (diagonal) and the
//! forgetting factor of any [`ForgettingRule`] (`λ` constant in the dissertation); see
//! [`crate::mrac`] ("RLS with `R_θ`") for how `R_θ` enters the kernel. `D_m H − 1` has no `q⁰` term,
//! so `ẑ_k` involves `y_{k−1}, u_{k−1}` and older only.
//!
//! # Input (4.43) and timing
//!
//! At sample `k` (the service's compute-first step) the controller takes `y_k` and
//! `r_k`, updates `θ̂_{k−1} → θ̂_k` with the regression of index `k`, and applies
//!
//! ```text
//! u_k = Φ_k θ̂_{1,k} + H(q⁻¹) r_k                                                      (4.43)
//! ```
//!
//! (saturated to the output limits if any; the applied `u_k` enters the histories). This
//! is (4.43) with the index shifted by one: `u_{k+1} = Φ_{k+1} θ̂_{1,k+1} + H r_{k+1}`. The
//! Bezout estimates `θ̂_2` are identified but not used for the input. The reference model
//! (4.4) runs alongside only to report `y_{m,k}` and `e_k = y_k − y_{m,k}` (APPC's closed
//! loop is `N/D_m`; `N_m` should be `N`).
//!
//! Bad and missing samples: [`crate::mrac`] ("Bad and missing samples"); on a bad sample the input
//! is held and the status is [`CONTROLLER_FAULT`](crate::status::CONTROLLER_FAULT), as when the RLS guard resets
//! `θ̂` or a regression is not finite (its update is then skipped).
//!
//! # Internals
//!
//! `appc_y_m` (`y_{m,k}`), `appc_e` (`e_k`), `appc_zhat` (`ẑ_k(θ̂_k)` (4.41), with the
//! updated estimate), `theta_norm` (`‖θ̂_k‖`), `trace_p` (`tr(R_θ^{1/2} P_k R_θ^{1/2})`),
//! `lambda` (`λ_k`), `resets` (guard resets), then `theta[i]`, the first entries of
//! `θ̂_k = [θ̂_1; θ̂_2]` (up to [`MAX_INTERNALS`] signals in all).

use super::adaptive::{Adaptive, Law, adaptive_accessors, adaptive_controller};
use super::checks;
use super::estimator::Estimator;
use super::poly;
use super::signals::Signals;
use crate::ParamError;
use crate::controller::{Controller, Dimensions, MAX_INTERNALS, OutputLimits, StepInput};
use crate::forgetting::ForgettingRule;

/// Parameters of an [`Appc`] controller (coefficients of `q⁰, q⁻¹, …`).
#[derive(Debug, Clone, PartialEq)]
pub struct AppcParams {
    /// The plant order `n ≥ 1` (the degree of `D`, (4.3)).
    pub n: usize,
    /// `D_m` (4.6), (4.17): the desired closed-loop poles; monic, asymptotically stable,
    /// degree `≤ n`.
    pub d_m: Vec<f64>,
    /// `N_m` (4.5): the reference model's numerator, degree `≤ n` (used for `y_m`, `e`).
    pub n_m: Vec<f64>,
    /// `H` (4.13): monic, asymptotically stable, degree `≤ n`.
    pub h: Vec<f64>,
    /// `θ̂_0 = [θ̂_{1,0}; θ̂_{2,0}]` (length `4n`); `None`: zero.
    pub theta0: Option<Vec<f64>>,
    /// The diagonal of `R_θ` in (4.42) (length `4n`, positive).
    pub r_theta: Vec<f64>,
    /// How `λ_k` is chosen ((4.42): constant `λ ∈ (0, 1]`).
    pub forgetting: ForgettingRule,
    /// The RLS guard: `tr(R_θ^{1/2} P R_θ^{1/2})` above this resets `θ̂, P` (must exceed
    /// `4n`; may be `+∞`).
    pub trace_limit: f64,
    /// Output saturation, if any.
    pub limits: Option<OutputLimits>,
}

impl AppcParams {
    /// `R_θ = DEFAULT_R_THETA · I`, as in Examples 1a and 2a.
    pub const DEFAULT_R_THETA: f64 = 1e-5;

    /// Parameters with `θ̂_0 = 0`, `R_θ = 10⁻⁵ I_{4n}`, `λ = 1`, no trace limit and no
    /// saturation (the chapter's examples).
    pub fn new(n: usize, d_m: Vec<f64>, n_m: Vec<f64>, h: Vec<f64>) -> Self {
        Self {
            n,
            d_m,
            n_m,
            h,
            theta0: None,
            r_theta: vec![Self::DEFAULT_R_THETA; Self::theta_len(n)],
            forgetting: ForgettingRule::DEFAULT,
            trace_limit: f64::INFINITY,
            limits: None,
        }
    }

    /// `4n`, the length of `[θ_1; θ_2]`.
    pub fn theta_len(n: usize) -> usize {
        4 * n
    }

    /// Checks the parameters without building anything.
    ///
    /// # Errors
    ///
    /// The first refused field: `"n"` (0), `"d-m"` and `"h"` (empty, non-finite, degree
    /// above `n`, not monic, not asymptotically stable), `"n-m"` (empty, non-finite,
    /// degree above `n`), `"theta0"`, `"r-theta"` (not `4n` entries, not positive),
    /// `"trace-limit"`, the forgetting rule's fields, `"u-min"`.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.check().map(|_| ())
    }

    /// The trimmed `D_m`, `N_m`, `H`.
    fn check(&self) -> Result<Polynomials, ParamError> {
        let n = self.n;
        if n == 0 {
            return Err(ParamError::new("n", "the plant order must be at least 1"));
        }
        let d_m = checks::stable_monic(&self.d_m, "d-m", n, "the plant order n")?;
        let n_m = checks::polynomial(&self.n_m, "n-m", n, "the plant order n")?;
        let h = checks::stable_monic(&self.h, "h", n, "the plant order n")?;
        super::estimator::check(
            Self::theta_len(n),
            self.theta0.as_deref(),
            &self.r_theta,
            &self.forgetting,
            self.trace_limit,
        )?;
        checks::limits(self.limits.as_ref())?;
        Ok(Polynomials { d_m, n_m, h })
    }
}

/// What [`AppcParams::check`] keeps: the polynomials up to their degrees.
struct Polynomials {
    d_m: Vec<f64>,
    n_m: Vec<f64>,
    h: Vec<f64>,
}

/// The APPC controller (module docs).
#[derive(Debug, Clone)]
pub struct Appc {
    counts: Dimensions,
    law: AppcLaw,
    core: Adaptive,
}

/// What is APPC's own: the regression (4.37)–(4.41) and the law (4.43).
#[derive(Debug, Clone)]
struct AppcLaw {
    n: usize,
    /// `D_m H` (degree ≤ 2n).
    g: Vec<f64>,
    h: Vec<f64>,
}

impl Appc {
    /// Builds the controller for a SISO rig (`n_y = n_r = n_u = 1`; `z` is not read).
    ///
    /// # Errors
    ///
    /// Those of [`AppcParams::validate`], and `"channels"` for other counts.
    pub fn new(params: &AppcParams, counts: Dimensions) -> Result<Self, ParamError> {
        checks::siso(counts)?;
        let Polynomials { d_m, n_m, h } = params.check()?;
        let n = params.n;
        let g = poly::mul(&d_m, &h);
        // Φ_{k−d} for d ≤ deg(D_m H) reads y_{k−d−j}, u_{k−d−j}, j ≤ n.
        let len = g.len() + n;
        let est = Estimator::new(
            AppcParams::theta_len(n),
            params.theta0.as_deref(),
            &params.r_theta,
            &params.forgetting,
            params.trace_limit,
        )?;
        let sig = Signals::new(len.max(h.len()), &n_m, &d_m, &[1.0]);
        Ok(Self {
            counts,
            law: AppcLaw { n, g, h },
            core: Adaptive::new(sig, est, params.limits.clone()),
        })
    }

    adaptive_accessors!(
        "= `[θ̂_1; θ̂_2]` (4.35)–(4.36): `[N_{c,1..n}, D_{c,1..n}, B_{1..n}, C_{1..n}]`",
        "(4.41)",
        "`[Φ_k Φ_{f,k}]` (4.38)–(4.39)"
    );
}

impl Law for AppcLaw {
    /// `[Φ_k Φ_{f,k}]` into `phi`; returns `−u_{f,k}` (4.40)–(4.41).
    fn regression(&self, sig: &Signals, phi: &mut [f64]) -> f64 {
        let n = self.n;
        let (phi, phi_f) = phi.split_at_mut(2 * n);
        for j in 1..=n {
            if let Some(d) = phi.get_mut(j - 1) {
                *d = sig.y.get(j);
            }
            if let Some(d) = phi.get_mut(n + j - 1) {
                *d = sig.u_lag(j);
            }
            let (mut fy, mut fu) = (0.0, 0.0);
            for (d, gd) in self.g.iter().enumerate() {
                fy += gd * sig.y.get(d + j);
                fu += gd * sig.u_lag(d + j);
            }
            if let Some(d) = phi_f.get_mut(j - 1) {
                *d = fy;
            }
            if let Some(d) = phi_f.get_mut(n + j - 1) {
                *d = fu;
            }
        }
        let mut uf = 0.0;
        for (d, gd) in self.g.iter().enumerate().skip(1) {
            uf += gd * sig.u_lag(d);
        }
        -uf
    }

    /// `Φ_k θ̂_1 + H r_k` (4.43).
    fn law(&self, sig: &Signals, theta: &[f64]) -> f64 {
        let n = self.n;
        let mut u = 0.0;
        for j in 1..=n {
            u += theta.get(j - 1).copied().unwrap_or(0.0) * sig.y.get(j);
            u += theta.get(n + j - 1).copied().unwrap_or(0.0) * sig.u_lag(j);
        }
        u + sig.r_fir(&self.h)
    }
}

adaptive_controller!(Appc, "appc", "appc");

const _: () = assert!(MAX_INTERNALS >= 8);
