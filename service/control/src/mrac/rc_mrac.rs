//! Retrospective cost model reference adaptive control (RC-MRAC), §4.3, (4.46)–(4.77).
//!
//! # Known part of the plant (4.46)
//!
//! ```text
//! N(q⁻¹) = N_{n_r} N_u(q⁻¹) N_s(q⁻¹) q^{−n_r}                                        (4.46)
//! ```
//!
//! The configuration gives the leading coefficient `N_{n_r} ≠ 0`, the relative degree
//! `n_r ≥ 1` and the nonminimum-phase factor `N_u` (monic in `q`, of degree `n_u`, every
//! root of modulus at least 1); `N_s` (the minimum-phase zeros, degree `n_s`) is unknown,
//! only `n_s` is given, with `n_r + n_u + n_s ≤ n`.
//!
//! # Controller (4.47)
//!
//! ```text
//! u_k = N_c(q⁻¹) y_k + D_c(q⁻¹) u_k + R_c(q⁻¹) F(q⁻¹) r_k                          (4.47)
//! R_c = R_{c,0} + Σ_{i=1}^{n_s} R_{c,i} q⁻ⁱ,   F = 1 + Σ_{i=1}^{n−n_s} F_i q⁻ⁱ        (4.48)–(4.49)
//! ```
//!
//! `F` is an asymptotically stable monic polynomial (degree `≤ n − n_s`). With `N_c*`,
//! `D_c*` solving `D_m N_s F = D − N_c* N − D_c* D` (4.54)–(4.55) and `R_c*` with
//! `N_m = N_{n_r} N_u R_c* q^{−n_r}` (4.57) the closed loop is
//! `y_k = N_{n_r} N_u R_c q^{−n_r} / D_m r_k = N_m/D_m r_k` (4.56), and
//!
//! ```text
//! D_m F (y_k − y_{m,k}) − N_{n_r} N_u q^{−n_r} [u_k − N_c* y_k − D_c* u_k − R_c* F r_k] = 0   (4.65)
//! ```
//!
//! holds for any input. `N_m` must therefore have the form (4.57): its first `n_r`
//! coefficients zero and `N_{n_r} N_u` a factor with a cofactor of degree `≤ n_s`
//! (checked).
//!
//! # Regression and update (4.68)–(4.76)
//!
//! ```text
//! θ       = [N_{c,1} … N_{c,n} D_{c,1} … D_{c,n} R_{c,0} … R_{c,n_s}]ᵀ                (4.68)
//! r_{f,k} = F(q⁻¹) r_k                                                               (4.70)
//! Φ_k     = [y_{k−1} … y_{k−n} u_{k−1} … u_{k−n} r_{f,k} … r_{f,k−n_s}]              (4.71)
//! Φ_{f,k} = N_{n_r} N_u(q⁻¹) q^{−n_r} Φ_k                                            (4.72)
//! u_{f,k} = N_{n_r} N_u(q⁻¹) q^{−n_r} u_k                                            (4.73)
//! z_{f,k} = D_m(q⁻¹) F(q⁻¹) (y_k − y_{m,k})                                          (4.74)
//! ẑ_k(θ̂)  = z_{f,k} − u_{f,k} + Φ_{f,k} θ̂                                            (4.75)
//! ```
//!
//! RLS minimizes (4.76) with `θ̂_0`, `R_θ` (diagonal) and the forgetting factor of any
//! [`ForgettingRule`] (`λ` constant in the dissertation); [`crate::mrac`]
//! ("RLS with `R_θ`") says how `R_θ` enters the kernel. Since `n_r ≥ 1`, `ẑ_k` involves
//! `y_k, r_{k−n_r}` and older, and `u_{k−n_r}` and older.
//!
//! # Input (4.77) and timing
//!
//! At sample `k` the controller takes `y_k` and `r_k`, forms `y_{m,k}`, `e_k`, updates
//! `θ̂_{k−1} → θ̂_k` with the regression of index `k` and applies
//!
//! ```text
//! u_k = Φ_k θ̂_k                                                                      (4.77)
//! ```
//!
//! ((4.77) with the index shifted by one), saturated to the output limits if any (the
//! applied `u_k` enters the histories).
//!
//! Bad and missing samples: [`crate::mrac`] ("Bad and missing samples"); on a bad sample the input
//! is held and the status is [`CONTROLLER_FAULT`](crate::status::CONTROLLER_FAULT), as when the RLS guard resets
//! `θ̂` or a regression is not finite (its update is then skipped).
//!
//! # Internals
//!
//! `rc_mrac_y_m` (`y_{m,k}`), `rc_mrac_e` (`e_k`), `rc_mrac_zhat` (`ẑ_k(θ̂_k)` (4.75),
//! with the updated estimate), `theta_norm`, `trace_p` (`tr(R_θ^{1/2} P_k R_θ^{1/2})`),
//! `lambda`, `resets`, then `theta[i]`, the first entries of `θ̂_k`.

use super::adaptive::{Adaptive, Law, adaptive_accessors, adaptive_controller};
use super::checks;
use super::estimator::Estimator;
use super::poly;
use super::signals::Signals;
use crate::ParamError;
use crate::controller::{Controller, Dimensions, OutputLimits, StepInput};
use crate::forgetting::ForgettingRule;

/// Relative size of the remainder of `N_m / (N_{n_r} N_u)` below which `N_m` is taken to
/// have the form (4.57).
const FACTOR_TOL: f64 = 1e-9;
/// `N_u` may have roots on the unit circle (modulus at least 1); a root modulus below
/// `1 − ROOT_TOL` is refused.
const ROOT_TOL: f64 = 1e-9;

/// Parameters of an [`RcMrac`] controller (coefficients of `q⁰, q⁻¹, …`).
#[derive(Debug, Clone, PartialEq)]
pub struct RcMracParams {
    /// The plant order `n ≥ 1`.
    pub n: usize,
    /// The relative degree `n_r ≥ 1` of (4.2).
    pub relative_degree: usize,
    /// The leading numerator coefficient `N_{n_r} ≠ 0` (4.46).
    pub leading_coefficient: f64,
    /// `N_u` (4.46): the known nonminimum-phase zeros, monic in `q` (`N_u[0] = 1`), roots
    /// of modulus at least 1; `[1.0]` for a minimum-phase plant.
    pub n_u: Vec<f64>,
    /// `n_s`, the degree of the unknown minimum-phase factor `N_s` (and of `R_c`).
    pub n_s: usize,
    /// `F` (4.49): monic, asymptotically stable, degree `≤ n − n_s`.
    pub f: Vec<f64>,
    /// `D_m` (4.6), (4.53): monic, asymptotically stable, degree `≤ n`.
    pub d_m: Vec<f64>,
    /// `N_m` (4.5), of the form (4.57) `N_{n_r} N_u R_c* q^{−n_r}`, `deg R_c* ≤ n_s`.
    pub n_m: Vec<f64>,
    /// `θ̂_0` (length `2n + n_s + 1`); `None`: zero.
    pub theta0: Option<Vec<f64>>,
    /// The diagonal of `R_θ` in (4.76) (length `2n + n_s + 1`, positive).
    pub r_theta: Vec<f64>,
    /// How `λ_k` is chosen ((4.76): constant `λ ∈ (0, 1]`).
    pub forgetting: ForgettingRule,
    /// The RLS guard: `tr(R_θ^{1/2} P R_θ^{1/2})` above this resets `θ̂, P` (must exceed
    /// `2n + n_s + 1`; may be `+∞`).
    pub trace_limit: f64,
    /// Output saturation, if any.
    pub limits: Option<OutputLimits>,
}

impl RcMracParams {
    /// `R_θ = DEFAULT_R_THETA · I`, as in Examples 1b, 2b and 3.
    pub const DEFAULT_R_THETA: f64 = 1e-5;

    /// Parameters with `θ̂_0 = 0`, `R_θ = 10⁻⁵ I`, `λ = 1`, no trace limit and no
    /// saturation (the chapter's examples).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        n: usize,
        relative_degree: usize,
        leading_coefficient: f64,
        n_u: Vec<f64>,
        n_s: usize,
        f: Vec<f64>,
        d_m: Vec<f64>,
        n_m: Vec<f64>,
    ) -> Self {
        Self {
            n,
            relative_degree,
            leading_coefficient,
            n_u,
            n_s,
            f,
            d_m,
            n_m,
            theta0: None,
            r_theta: vec![Self::DEFAULT_R_THETA; Self::theta_len(n, n_s)],
            forgetting: ForgettingRule::DEFAULT,
            trace_limit: f64::INFINITY,
            limits: None,
        }
    }

    /// `2n + n_s + 1`, the length of `θ` (4.68).
    pub fn theta_len(n: usize, n_s: usize) -> usize {
        2 * n + n_s + 1
    }

    /// Checks the parameters without building anything.
    ///
    /// # Errors
    ///
    /// The first refused field: `"n"` (0), `"relative-degree"` (0), `"leading-coefficient"`
    /// (zero or not finite), `"n-u"` (empty, non-finite, not monic, a root of modulus
    /// below 1), `"n-s"` (`n_r + n_u + n_s > n`), `"f"` (degree above `n − n_s`, not
    /// monic, not asymptotically stable), `"d-m"` (degree above `n`, not monic, not
    /// asymptotically stable), `"n-m"` (degree above `n`, or not of the form (4.57)),
    /// `"theta0"`, `"r-theta"` (not `2n + n_s + 1` entries, not positive),
    /// `"trace-limit"`, the forgetting rule's fields, `"u-min"`.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.check().map(|_| ())
    }

    /// The trimmed `N_u`, `F`, `D_m`, `N_m`.
    fn check(&self) -> Result<Checked, ParamError> {
        let n = self.n;
        if n == 0 {
            return Err(ParamError::new("n", "the plant order must be at least 1"));
        }
        let nr = self.relative_degree;
        if nr == 0 {
            return Err(ParamError::new(
                "relative-degree",
                "must be at least 1 (a strictly proper plant)",
            ));
        }
        let lead = self.leading_coefficient;
        if !(lead.is_finite() && lead != 0.0) {
            return Err(ParamError::new(
                "leading-coefficient",
                format!("N_{{n_r}} = {lead} must be finite and nonzero"),
            ));
        }
        let n_u = checks::polynomial(&self.n_u, "n-u", n, "the plant order n")?;
        if !poly::is_monic(&n_u) {
            return Err(ParamError::new(
                "n-u",
                format!(
                    "must be monic (coefficient of q⁰ equal to 1), got {}",
                    n_u[0]
                ),
            ));
        }
        let m = poly::min_root_modulus(&n_u);
        if m < 1.0 - ROOT_TOL {
            return Err(ParamError::new(
                "n-u",
                format!(
                    "has a root of modulus {m:.6} inside the unit circle; N_u holds the \
                     zeros of modulus at least 1 (minimum-phase zeros belong to N_s)"
                ),
            ));
        }
        let nu = poly::degree(&n_u);
        if nr + nu + self.n_s > n {
            return Err(ParamError::new(
                "n-s",
                format!(
                    "n_r + n_u + n_s = {nr} + {nu} + {} exceeds the plant order n = {n}",
                    self.n_s
                ),
            ));
        }
        let f = checks::stable_monic(&self.f, "f", n - self.n_s, "n − n_s")?;
        let d_m = checks::stable_monic(&self.d_m, "d-m", n, "the plant order n")?;
        let n_m = checks::polynomial(&self.n_m, "n-m", n, "the plant order n")?;
        self.check_model_numerator(&n_m, &n_u)?;
        super::estimator::check(
            Self::theta_len(n, self.n_s),
            self.theta0.as_deref(),
            &self.r_theta,
            &self.forgetting,
            self.trace_limit,
        )?;
        checks::limits(self.limits.as_ref())?;
        Ok(Checked { n_u, f, d_m, n_m })
    }

    /// `N_m = N_{n_r} N_u R_c* q^{−n_r}` with `deg R_c* ≤ n_s` (4.57), up to [`FACTOR_TOL`].
    fn check_model_numerator(&self, n_m: &[f64], n_u: &[f64]) -> Result<(), ParamError> {
        let nr = self.relative_degree;
        let scale = n_m.iter().fold(0.0_f64, |a, c| a.max(c.abs()));
        if scale == 0.0 {
            return Err(ParamError::new("n-m", "is zero"));
        }
        if let Some(i) = n_m.iter().take(nr).position(|&c| c != 0.0) {
            return Err(ParamError::at(
                "n-m",
                i,
                format!("must be 0: the reference model needs relative degree n_r = {nr} (4.5)"),
            ));
        }
        let tail: Vec<f64> = n_m[nr..]
            .iter()
            .map(|c| c / self.leading_coefficient)
            .collect();
        let (rc, rem) = poly::divide(&tail, n_u);
        let rem_max = rem.iter().fold(0.0_f64, |a, c| a.max(c.abs()));
        let rc_degree = if rc.is_empty() {
            usize::MAX
        } else {
            poly::degree(&rc)
        };
        if rc.is_empty() || rem_max > FACTOR_TOL * scale / self.leading_coefficient.abs() {
            return Err(ParamError::new(
                "n-m",
                "is not of the form N_{n_r} N_u R_c q^{−n_r} (4.57): N_u does not divide it",
            ));
        }
        if rc_degree > self.n_s {
            return Err(ParamError::new(
                "n-m",
                format!(
                    "needs R_c of degree {rc_degree} in (4.57), more than n_s = {}",
                    self.n_s
                ),
            ));
        }
        Ok(())
    }

    /// `R_c*` of (4.57) for these parameters: `N_m q^{n_r} / (N_{n_r} N_u)` (length
    /// `n_s + 1`), or `None` when the parameters are refused.
    pub fn model_cofactor(&self) -> Option<Vec<f64>> {
        let c = self.check().ok()?;
        let tail: Vec<f64> = c.n_m[self.relative_degree.min(c.n_m.len())..]
            .iter()
            .map(|v| v / self.leading_coefficient)
            .collect();
        let (mut rc, _) = poly::divide(&tail, &c.n_u);
        rc.resize(self.n_s + 1, 0.0);
        Some(rc)
    }
}

/// What [`RcMracParams::check`] keeps.
struct Checked {
    n_u: Vec<f64>,
    f: Vec<f64>,
    d_m: Vec<f64>,
    n_m: Vec<f64>,
}

/// The RC-MRAC controller (module docs).
#[derive(Debug, Clone)]
pub struct RcMrac {
    counts: Dimensions,
    law: RcMracLaw,
    core: Adaptive,
}

/// What is RC-MRAC's own: the filtered regression (4.70)–(4.75) and the law (4.77).
#[derive(Debug, Clone)]
struct RcMracLaw {
    n: usize,
    n_s: usize,
    n_r: usize,
    /// `N_{n_r} N_u` (applied at lag `n_r`).
    nu_scaled: Vec<f64>,
    /// `D_m F`.
    dmf: Vec<f64>,
}

impl RcMrac {
    /// Builds the controller for a SISO rig (`n_y = n_r = n_u = 1`; `z` is not read).
    ///
    /// # Errors
    ///
    /// Those of [`RcMracParams::validate`], and `"channels"` for other counts.
    pub fn new(params: &RcMracParams, counts: Dimensions) -> Result<Self, ParamError> {
        checks::siso(counts)?;
        let Checked { n_u, f, d_m, n_m } = params.check()?;
        let (n, n_s, n_r) = (params.n, params.n_s, params.relative_degree);
        let nu_scaled: Vec<f64> = n_u.iter().map(|c| c * params.leading_coefficient).collect();
        let dmf = poly::mul(&d_m, &f);
        // Φ_{k−m}, m ≤ n_r + n_u, reads y_{k−m−j}, u_{k−m−j} (j ≤ n), r_{f,k−m−i} (i ≤ n_s).
        let len = (n_r + nu_scaled.len() + n).max(dmf.len()).max(f.len());
        let est = Estimator::new(
            RcMracParams::theta_len(n, n_s),
            params.theta0.as_deref(),
            &params.r_theta,
            &params.forgetting,
            params.trace_limit,
        )?;
        let sig = Signals::new(len, &n_m, &d_m, &f);
        Ok(Self {
            counts,
            law: RcMracLaw {
                n,
                n_s,
                n_r,
                nu_scaled,
                dmf,
            },
            core: Adaptive::new(sig, est, params.limits.clone()),
        })
    }

    adaptive_accessors!(
        "(4.68): `[N_{c,1..n}, D_{c,1..n}, R_{c,0..n_s}]`",
        "(4.75)",
        "`Φ_{f,k}` (4.72)"
    );

    /// `n_s`.
    pub fn n_s(&self) -> usize {
        self.law.n_s
    }
}

impl RcMracLaw {
    /// Entry `i` of `Φ_{k−m}` (4.71).
    #[inline]
    fn phi_entry(&self, sig: &Signals, m: usize, i: usize) -> f64 {
        let n = self.n;
        if i < n {
            sig.y.get(m + i + 1)
        } else if i < 2 * n {
            sig.u_lag(m + i - n + 1)
        } else {
            sig.rf.get(m + i - 2 * n)
        }
    }
}

impl Law for RcMracLaw {
    /// `Φ_{f,k}` into `phi`; returns `u_{f,k} − z_{f,k}` ((4.72)–(4.74)).
    fn regression(&self, sig: &Signals, phi: &mut [f64]) -> f64 {
        for (i, d) in phi.iter_mut().enumerate() {
            let mut s = 0.0;
            for (l, c) in self.nu_scaled.iter().enumerate() {
                s += c * self.phi_entry(sig, self.n_r + l, i);
            }
            *d = s;
        }
        let mut uf = 0.0;
        for (l, c) in self.nu_scaled.iter().enumerate() {
            uf += c * sig.u_lag(self.n_r + l);
        }
        let zf = sig.e.fir(&self.dmf, 0);
        uf - zf
    }

    /// `Φ_k θ̂_k` (4.77).
    fn law(&self, sig: &Signals, theta: &[f64]) -> f64 {
        let mut u = 0.0;
        for (i, t) in theta.iter().enumerate() {
            u += t * self.phi_entry(sig, 0, i);
        }
        u
    }
}

adaptive_controller!(RcMrac, "rc-mrac", "rc_mrac");
