//! Variable-rate forgetting factors for RLS (dissertation ch. 5).
//!
//! [`Forgetting::beta`] receives the prior error `e_k = y_k − φ_k θ_k` (2.7) of every RLS
//! step and returns `β_k = 1/λ_k ≥ 1`, the factor of (2.14) `L_k = β_k P_k`.
//!
//! # Rules
//!
//! - [`ForgettingRule::Constant`]: `λ_k = λ`, `β_k = 1/λ` (constant-rate forgetting, the
//!   `λ` of (2.6)–(2.9)).
//! - [`ForgettingRule::FTest`]: RLS/FTVRF, Algorithm 1. `β_k = 1 + η g 1[g]` (5.1) with
//!   - for `p = 1` the F-test statistic (5.4):
//!     `g = sqrt(σ²_{τn} / σ²_{τd}) − sqrt(F⁻¹_{τn,τd}(1 − α))`;
//!   - for `p > 1` the Lawley–Hotelling trace with the approximation (5.5)–(5.7):
//!     `g = sqrt((τn/τd) tr(Σ_{τn} Σ_{τd}⁻¹) / c) − sqrt(F⁻¹_{pτn,b}(1 − α))`, with `a, b, c`
//!     from (5.6), which requires `τd > p + 3`.
//! - [`ForgettingRule::RmsRatio`]: RLS/RMSVRF, the special case of Proposition 5.2.1:
//!   `g = sqrt(ratio) − 1` with `ratio = σ²_{τn}/σ²_{τd}` for `p = 1` and
//!   `ratio = tr(Σ_{τn} Σ_{τd}⁻¹)/p` for `p > 1`, and `β_k = 1 + η g 1[g]` (5.1).
//!
//! The F quantiles come from `statrs` and are computed once, in [`Forgetting::new`].
//!
//! # Windowed sample covariances
//!
//! `Σ_{τ}` is the unbiased sample covariance of the last `τ + 1` prior errors (the current
//! one included): with `m = τ + 1`, `Σ_τ = (Σ (e_i − c)(e_i − c)ᵀ − d dᵀ/m) / (m − 1)`,
//! `d = Σ (e_i − c)`, where `c` is a shift (see below) that makes the formula free of
//! cancellation. Both rules use this same estimator, so Proposition 5.2.1 holds exactly
//! (up to the accuracy of the F quantile).
//!
//! One ring buffer holds the last `τd + 1` errors; the `τn` window is its newest `τn + 1`
//! entries. Per step the running sums of both windows are updated incrementally: the new
//! error is added and the error leaving each window is subtracted, `O(p²)`. Numerical
//! stability over millions of steps is obtained by two measures together:
//!
//! 1. every running sum is a Neumaier-compensated sum (the rounding error of each add is
//!    carried in a separate term), so large errors that pass through the windows (a
//!    transient) do not leave residue larger than `~ε²` of their size;
//! 2. every `τd + 1` steps (each time the ring buffer wraps) all sums are recomputed exactly
//!    from the buffer, and the shift `c` is reset to the current `τd`-window mean. This costs
//!    `O(τd p²)` once per `τd + 1` steps, i.e. `O(p²)` amortized, and bounds any drift.
//!
//! Until the `τd` window is full (`τd + 1` errors pushed since construction or
//! [`Forgetting::reset`]) `g = 0` and `β = 1` (no forgetting), as in Algorithm 1.
//!
//! # Numerical zero ("no evidence") rule
//!
//! When the data are noiseless and RLS has converged both window variances are at the
//! roundoff level, and their ratio is meaningless. The data scale `s_k` is the larger of
//! the largest `tr(Σ_{τd})` seen since the last reset and, when the caller supplies the
//! measurement ([`Forgetting::beta_scaled`], as [`Rls`](crate::rls::Rls) does), a decaying
//! peak of `‖y_k‖²` (decay `1 − 1/(τd + 1)` per step). With
//! `δ_k = 10⁻²⁰ · s_k + 10⁻³⁰⁰` (a relative standard deviation of `10⁻¹⁰`, far below any
//! sensor noise and far above double-precision roundoff):
//!
//! - if `tr(Σ_{τd}) ≤ p·δ_k` there is no evidence: `g = −∞`, `β = 1`;
//! - otherwise the ratio is computed with the regularized `Σ_{τd} + δ_k I` (an invisible
//!   change at relative size `10⁻²⁰` that keeps the Cholesky factorization defined when a
//!   single output is noiseless).
//!
//! A non-finite error vector is not pushed into the windows; that step returns `β = 1`
//! and `g = NaN`. A non-finite `g` never produces forgetting.
//!
//! # Real time
//!
//! [`Forgetting::beta`] does not allocate: every buffer is sized in [`Forgetting::new`].

use crate::ParamError;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// Relative size of the "no evidence" floor `δ` with respect to the data scale.
const FLOOR_REL: f64 = 1e-20;
/// Absolute part of the "no evidence" floor `δ`.
const FLOOR_ABS: f64 = 1e-300;

/// How the forgetting factor `λ_k = 1/β_k` is chosen at every step.
#[derive(Debug, Clone, PartialEq)]
pub enum ForgettingRule {
    /// Constant-rate forgetting: `λ_k = λ`, `0 < λ ≤ 1`.
    Constant {
        /// The forgetting factor `λ` of (2.6).
        lambda: f64,
    },
    /// F-test variable-rate forgetting, Algorithm 1 with (5.1), (5.4) for `p = 1` and the
    /// Lawley–Hotelling approximation (5.5)–(5.7) for `p > 1`.
    FTest {
        /// Short window length: `Σ_{τn}` uses the last `τn + 1` errors (`τn ≥ p`).
        tau_n: usize,
        /// Long window length: `Σ_{τd}` uses the last `τd + 1` errors (`τd > τn`).
        tau_d: usize,
        /// Forgetting gain `η > 0` of (5.1).
        eta: f64,
        /// Significance level `α ∈ (0, 1)` of the test.
        alpha: f64,
    },
    /// RMS-ratio variable-rate forgetting (RLS/RMSVRF), the special case of
    /// Proposition 5.2.1: `g = sqrt(ratio) − 1`.
    RmsRatio {
        /// Short window length (`τn ≥ p`).
        tau_n: usize,
        /// Long window length (`τd > τn`).
        tau_d: usize,
        /// Forgetting gain `η > 0` of (5.1).
        eta: f64,
    },
}

/// Which statistic `g` is computed from the window covariances.
#[derive(Debug, Clone, Copy)]
enum Kind {
    Constant {
        beta: f64,
    },
    /// `g = sqrt(scale · statistic) − threshold`, where statistic is `σn²/σd²` (`p = 1`) or
    /// `tr(Σn Σd⁻¹)` (`p > 1`).
    Windowed {
        eta: f64,
        scale: f64,
        threshold: f64,
    },
}

/// Running, compensated sums of one window: `Σ (e − c)` and `Σ (e − c)(e − c)ᵀ`.
#[derive(Debug, Clone)]
struct WindowSums {
    /// `Σ (e − c)` (len p), value part.
    s1: Vec<f64>,
    /// Compensation terms of `s1`.
    c1: Vec<f64>,
    /// `Σ (e − c)(e − c)ᵀ` (p×p, row-major), value part.
    s2: Vec<f64>,
    /// Compensation terms of `s2`.
    c2: Vec<f64>,
}

impl WindowSums {
    fn new(p: usize) -> Self {
        Self {
            s1: vec![0.0; p],
            c1: vec![0.0; p],
            s2: vec![0.0; p * p],
            c2: vec![0.0; p * p],
        }
    }

    fn clear(&mut self) {
        self.s1.fill(0.0);
        self.c1.fill(0.0);
        self.s2.fill(0.0);
        self.c2.fill(0.0);
    }

    /// Adds `sign · (e − c)` and `sign · (e − c)(e − c)ᵀ`; `d` holds `e − c`.
    fn add(&mut self, d: &[f64], sign: f64) {
        let p = d.len();
        for i in 0..p {
            neumaier(&mut self.s1[i], &mut self.c1[i], sign * d[i]);
            for j in 0..p {
                neumaier(
                    &mut self.s2[i * p + j],
                    &mut self.c2[i * p + j],
                    sign * (d[i] * d[j]),
                );
            }
        }
    }

    /// Writes the unbiased sample covariance of `m` samples into `out` (p×p row-major).
    fn covariance(&self, m: usize, out: &mut [f64]) {
        let p = self.s1.len();
        let mf = m as f64;
        let denom = (m - 1) as f64;
        for i in 0..p {
            let di = self.s1[i] + self.c1[i];
            for j in 0..p {
                let dj = self.s1[j] + self.c1[j];
                let s = self.s2[i * p + j] + self.c2[i * p + j];
                out[i * p + j] = (s - di * dj / mf) / denom;
            }
        }
        // The products are symmetric term by term; enforce it against any residue.
        for i in 0..p {
            for j in 0..i {
                let v = 0.5 * (out[i * p + j] + out[j * p + i]);
                out[i * p + j] = v;
                out[j * p + i] = v;
            }
        }
    }
}

/// Neumaier's compensated summation step: `s + c` tracks the exact sum.
#[inline]
fn neumaier(s: &mut f64, c: &mut f64, x: f64) {
    let t = *s + x;
    if s.abs() >= x.abs() {
        *c += (*s - t) + x;
    } else {
        *c += (x - t) + *s;
    }
    *s = t;
}

/// The forgetting-factor state: the rule's constants and, for the windowed rules, the
/// ring buffer of the last `τd + 1` prior errors with the incremental window sums.
#[derive(Debug, Clone)]
pub struct Forgetting {
    kind: Kind,
    p: usize,
    tau_n: usize,
    tau_d: usize,
    /// Ring buffer of the last `τd + 1` errors, each of length p.
    ring: Vec<f64>,
    /// Next slot to write in `ring` (in units of errors).
    head: usize,
    /// Errors pushed since the last reset (saturating).
    count: u64,
    /// Shift `c` subtracted from every error before it enters the sums.
    shift: Vec<f64>,
    sums_n: WindowSums,
    sums_d: WindowSums,
    /// Scratch: `e − c`.
    dev: Vec<f64>,
    /// Scratch: `Σ_{τn}` (p×p row-major).
    sig_n: Vec<f64>,
    /// Scratch: `Σ_{τd} + δ I`, then its Cholesky factor (p×p row-major).
    sig_d: Vec<f64>,
    /// Scratch column for the triangular solves.
    col: Vec<f64>,
    /// Largest `tr(Σ_{τd})` since the last reset (the data scale of the floor rule).
    peak_trace: f64,
    /// Decaying peak of `‖y_k‖²` (factor `1 − 1/(τd + 1)` per step), the second data scale.
    y_scale: f64,
    /// The per-step decay factor of `y_scale`.
    y_decay: f64,
    last_g: f64,
}

impl ForgettingRule {
    /// No forgetting, `λ = 1`: the rule when a configuration gives none.
    pub const DEFAULT: ForgettingRule = ForgettingRule::Constant { lambda: 1.0 };

    /// The [`ForgettingRule::FTest`] of the dissertation's PCAC examples: `τ_n = 40`,
    /// `τ_d = 200`, `η = 0.1`, `α = 0.001`, the settings of the truss (§6) and of the
    /// sampling arm (§7.3) alike.
    pub const PCAC_EXAMPLES: ForgettingRule = ForgettingRule::FTest {
        tau_n: 40,
        tau_d: 200,
        eta: 0.1,
        alpha: 0.001,
    };

    /// Checks the rule for `p` outputs without building anything.
    ///
    /// # Errors
    ///
    /// The first refused field, named as in a `[forgetting]` table (`"forgetting.lambda"`,
    /// `"forgetting.tau-n"`, `"forgetting.tau-d"`, `"forgetting.eta"`,
    /// `"forgetting.alpha"`; `"forgetting"` for `p = 0` and for `τd ≤ τn`, which involves
    /// both windows): `λ ∉ (0, 1]`, not `τd > τn ≥ p`,
    /// `η ≤ 0`, `α ∉ (0, 1)`, or (F-test, `p > 1`) `τd ≤ p + 3`, where (5.6) is undefined.
    pub fn validate(&self, p: usize) -> Result<(), ParamError> {
        self.kind(p).map(|_| ())
    }

    /// The rule's constants for `p` outputs (the F quantile is computed here), or the first
    /// refused field ([`ForgettingRule::validate`]).
    fn kind(&self, p: usize) -> Result<Kind, ParamError> {
        if p == 0 {
            return Err(ParamError::new(
                "forgetting",
                "the output dimension p must be at least 1",
            ));
        }
        match *self {
            ForgettingRule::Constant { lambda } => {
                if !(lambda > 0.0 && lambda <= 1.0) {
                    return Err(ParamError::new(
                        "forgetting.lambda",
                        format!("lambda = {lambda} must be in (0, 1]"),
                    ));
                }
                Ok(Kind::Constant { beta: 1.0 / lambda })
            }
            ForgettingRule::FTest {
                tau_n,
                tau_d,
                eta,
                alpha,
            } => {
                check_windows(tau_n, tau_d, eta, p)?;
                if !(alpha > 0.0 && alpha < 1.0) {
                    return Err(ParamError::new(
                        "forgetting.alpha",
                        format!("alpha = {alpha} must be in (0, 1)"),
                    ));
                }
                let (tn, td, pf) = (tau_n as f64, tau_d as f64, p as f64);
                let (scale, d1, d2) = if p == 1 {
                    // (5.4): plain F-test on σn²/σd².
                    (1.0, tn, td)
                } else {
                    // (5.6)-(5.7): Lawley–Hotelling trace approximation.
                    if tau_d <= p + 3 {
                        return Err(ParamError::new(
                            "forgetting.tau-d",
                            format!(
                                "the F-test for p = {p} needs tau_d > p + 3 (5.6), got {tau_d}"
                            ),
                        ));
                    }
                    let a = (tn + td - pf - 1.0) * (td - 1.0) / ((td - pf - 3.0) * (td - pf));
                    if a <= 1.0 {
                        return Err(ParamError::new(
                            "forgetting.tau-d",
                            format!("(5.6) gives a = {a} ≤ 1"),
                        ));
                    }
                    let b = 4.0 + (pf * tn + 2.0) / (a - 1.0);
                    let c = pf * tn * (b - 2.0) / (b * (td - pf - 1.0));
                    if !(c > 0.0 && c.is_finite()) {
                        return Err(ParamError::new(
                            "forgetting.tau-d",
                            format!("(5.6) gives c = {c} ≤ 0"),
                        ));
                    }
                    (tn / (td * c), pf * tn, b)
                };
                let f = FisherSnedecor::new(d1, d2).map_err(|e| {
                    ParamError::new(
                        "forgetting.tau-n",
                        format!("F({d1}, {d2}) distribution: {e}"),
                    )
                })?;
                let q = f.inverse_cdf(1.0 - alpha);
                if !(q.is_finite() && q > 0.0) {
                    return Err(ParamError::new(
                        "forgetting.alpha",
                        format!("F quantile {q} is not usable"),
                    ));
                }
                Ok(Kind::Windowed {
                    eta,
                    scale,
                    threshold: q.sqrt(),
                })
            }
            ForgettingRule::RmsRatio { tau_n, tau_d, eta } => {
                check_windows(tau_n, tau_d, eta, p)?;
                Ok(Kind::Windowed {
                    eta,
                    scale: 1.0 / p as f64,
                    threshold: 1.0,
                })
            }
        }
    }
}

impl Forgetting {
    /// Builds the forgetting state for `p` outputs, validating the rule and computing the
    /// F quantile (once, here).
    ///
    /// # Errors
    ///
    /// The [`ForgettingRule::validate`] error as text (`"forgetting.tau-d: …"`); the RLS
    /// kernels that build this state report their errors as text.
    pub fn new(rule: &ForgettingRule, p: usize) -> Result<Self, String> {
        let kind = rule.kind(p).map_err(|e| e.to_string())?;
        let (tau_n, tau_d) = match *rule {
            ForgettingRule::Constant { .. } => (0, 0),
            ForgettingRule::FTest { tau_n, tau_d, .. }
            | ForgettingRule::RmsRatio { tau_n, tau_d, .. } => (tau_n, tau_d),
        };
        let windowed = matches!(kind, Kind::Windowed { .. });
        let len = if windowed { (tau_d + 1) * p } else { 0 };
        let pp = if windowed { p } else { 0 };
        Ok(Self {
            kind,
            p,
            tau_n,
            tau_d,
            ring: vec![0.0; len],
            head: 0,
            count: 0,
            shift: vec![0.0; pp],
            sums_n: WindowSums::new(pp),
            sums_d: WindowSums::new(pp),
            dev: vec![0.0; pp],
            sig_n: vec![0.0; pp * pp],
            sig_d: vec![0.0; pp * pp],
            col: vec![0.0; pp],
            peak_trace: 0.0,
            y_scale: 0.0,
            y_decay: 1.0 - 1.0 / (tau_d + 1) as f64,
            last_g: f64::NAN,
        })
    }

    /// Pushes the prior error `e_k` (length `p`) and returns `β_k = 1/λ_k ≥ 1`.
    ///
    /// Never allocates. A non-finite `e_k` is not pushed and gives `β = 1`.
    ///
    /// # Panics
    ///
    /// Only on a caller bug: `e.len() != p` for a windowed rule.
    pub fn beta(&mut self, e: &[f64]) -> f64 {
        self.beta_scaled(e, 0.0)
    }

    /// [`Forgetting::beta`] with the squared size of the measurement, `y_sq = ‖y_k‖²`, as
    /// an additional data scale for the "no evidence" floor: prior errors below
    /// `~10⁻¹⁰ ‖y‖` are roundoff and never cause forgetting (see the module docs).
    /// [`Rls`](crate::rls::Rls) calls this. Never allocates.
    ///
    /// # Panics
    ///
    /// Only on a caller bug: `e.len() != p` for a windowed rule.
    pub fn beta_scaled(&mut self, e: &[f64], y_sq: f64) -> f64 {
        let (eta, scale, threshold) = match self.kind {
            Kind::Constant { beta } => return beta,
            Kind::Windowed {
                eta,
                scale,
                threshold,
            } => (eta, scale, threshold),
        };
        assert_eq!(e.len(), self.p, "forgetting: error length must be p");
        if e.iter().any(|x| !x.is_finite()) {
            self.last_g = f64::NAN;
            return 1.0;
        }
        self.push(e);
        self.y_scale *= self.y_decay;
        if y_sq.is_finite() && y_sq > self.y_scale {
            self.y_scale = y_sq;
        }
        let full = self.count > self.tau_d as u64;
        if !full {
            self.last_g = 0.0;
            return 1.0;
        }
        let g = self.statistic().map_or(f64::NEG_INFINITY, |stat| {
            (scale * stat).max(0.0).sqrt() - threshold
        });
        self.last_g = g;
        if g > 0.0 { 1.0 + eta * g } else { 1.0 }
    }

    /// The last `g` of (5.1) (`NaN` for [`ForgettingRule::Constant`] and after a
    /// non-finite error, `0` while the windows fill, `−∞` when there is no evidence).
    pub fn last_g(&self) -> f64 {
        self.last_g
    }

    /// Empties the windows: no forgetting until they are full again.
    pub fn reset(&mut self) {
        self.ring.fill(0.0);
        self.head = 0;
        self.count = 0;
        self.shift.fill(0.0);
        self.sums_n.clear();
        self.sums_d.clear();
        self.peak_trace = 0.0;
        self.y_scale = 0.0;
        self.last_g = if matches!(self.kind, Kind::Constant { .. }) {
            f64::NAN
        } else {
            0.0
        };
    }

    /// Inserts `e` into the ring buffer and updates both windows' sums.
    fn push(&mut self, e: &[f64]) {
        let p = self.p;
        let m_d = self.tau_d + 1;
        let m_n = self.tau_n + 1;
        if self.count == 0 {
            self.shift.copy_from_slice(e);
        }
        // Error leaving the τd window: the one being overwritten (if the ring is full).
        if self.count >= m_d as u64 {
            let old = &self.ring[self.head * p..(self.head + 1) * p];
            deviation(old, &self.shift, &mut self.dev);
            self.sums_d.add(&self.dev, -1.0);
        }
        // Error leaving the τn window: pushed τn + 1 steps ago.
        if self.count >= m_n as u64 {
            let idx = (self.head + m_d - m_n) % m_d;
            let old = &self.ring[idx * p..(idx + 1) * p];
            deviation(old, &self.shift, &mut self.dev);
            self.sums_n.add(&self.dev, -1.0);
        }
        self.ring[self.head * p..(self.head + 1) * p].copy_from_slice(e);
        deviation(e, &self.shift, &mut self.dev);
        self.sums_d.add(&self.dev, 1.0);
        self.sums_n.add(&self.dev, 1.0);
        self.head += 1;
        self.count = self.count.saturating_add(1);
        if self.head == m_d {
            self.head = 0;
            self.recompute();
        }
    }

    /// Exact recomputation of both windows' sums from the (full) ring buffer, with the
    /// shift moved to the `τd`-window mean. Called when the ring wraps (`head == 0`), so
    /// the oldest error is at slot 0 and the newest `τn + 1` are at the end.
    fn recompute(&mut self) {
        let p = self.p;
        let m_d = self.tau_d + 1;
        let m_n = self.tau_n + 1;
        for i in 0..p {
            let mut s = 0.0;
            let mut c = 0.0;
            for k in 0..m_d {
                neumaier(&mut s, &mut c, self.ring[k * p + i]);
            }
            self.shift[i] = (s + c) / m_d as f64;
        }
        self.sums_d.clear();
        self.sums_n.clear();
        for k in 0..m_d {
            for i in 0..p {
                self.dev[i] = self.ring[k * p + i] - self.shift[i];
            }
            self.sums_d.add(&self.dev, 1.0);
            if k >= m_d - m_n {
                self.sums_n.add(&self.dev, 1.0);
            }
        }
    }

    /// The unscaled statistic: `σn²/σd²` (`p = 1`) or `tr(Σn (Σd + δI)⁻¹)` (`p > 1`);
    /// `None` when there is no evidence (the floor rule) or the factorization fails.
    fn statistic(&mut self) -> Option<f64> {
        let p = self.p;
        self.sums_n.covariance(self.tau_n + 1, &mut self.sig_n);
        self.sums_d.covariance(self.tau_d + 1, &mut self.sig_d);
        let trace_d: f64 = (0..p).map(|i| self.sig_d[i * p + i]).sum();
        if !trace_d.is_finite() {
            return None;
        }
        if trace_d > self.peak_trace {
            self.peak_trace = trace_d;
        }
        let delta = FLOOR_REL * self.peak_trace.max(self.y_scale) + FLOOR_ABS;
        if trace_d <= p as f64 * delta {
            return None;
        }
        if p == 1 {
            let r = self.sig_n[0] / (self.sig_d[0] + delta);
            return r.is_finite().then_some(r);
        }
        for i in 0..p {
            self.sig_d[i * p + i] += delta;
        }
        if !cholesky_in_place(&mut self.sig_d, p) {
            return None;
        }
        // tr(Σn Σd⁻¹) = Σ_j (Σd⁻¹ Σn)_{jj}: solve Σd x = Σn[:, j] for each column j.
        let mut tr = 0.0;
        for j in 0..p {
            for i in 0..p {
                self.col[i] = self.sig_n[i * p + j];
            }
            cholesky_solve(&self.sig_d, p, &mut self.col);
            tr += self.col[j];
        }
        tr.is_finite().then_some(tr)
    }
}

/// `out = e − c`, elementwise.
#[inline]
fn deviation(e: &[f64], c: &[f64], out: &mut [f64]) {
    for ((o, x), m) in out.iter_mut().zip(e).zip(c) {
        *o = x - m;
    }
}

/// `τd > τn ≥ max(p, 1)` and `η > 0`, finite.
fn check_windows(tau_n: usize, tau_d: usize, eta: f64, p: usize) -> Result<(), ParamError> {
    if tau_n < p.max(1) {
        return Err(ParamError::new(
            "forgetting.tau-n",
            format!("tau_n = {tau_n} must be at least p = {p} and 1"),
        ));
    }
    if tau_d <= tau_n {
        // A relation between two fields: the table is named.
        return Err(ParamError::new(
            "forgetting",
            format!("tau_d = {tau_d} must exceed tau_n = {tau_n}"),
        ));
    }
    if !(eta > 0.0 && eta.is_finite()) {
        return Err(ParamError::new(
            "forgetting.eta",
            format!("eta = {eta} must be positive"),
        ));
    }
    Ok(())
}

/// In-place Cholesky `A = C Cᵀ` of a p×p row-major symmetric matrix; the lower triangle
/// receives `C`. Returns `false` on a non-positive or non-finite pivot.
pub(crate) fn cholesky_in_place(a: &mut [f64], p: usize) -> bool {
    for j in 0..p {
        let mut d = a[j * p + j];
        for k in 0..j {
            d -= a[j * p + k] * a[j * p + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * p + j] = d;
        for i in j + 1..p {
            let mut s = a[i * p + j];
            for k in 0..j {
                s -= a[i * p + k] * a[j * p + k];
            }
            a[i * p + j] = s / d;
        }
    }
    true
}

/// Solves `C Cᵀ x = b` in place given the lower-triangular factor `C` (row-major p×p).
pub(crate) fn cholesky_solve(c: &[f64], p: usize, b: &mut [f64]) {
    for i in 0..p {
        let mut s = b[i];
        for k in 0..i {
            s -= c[i * p + k] * b[k];
        }
        b[i] = s / c[i * p + i];
    }
    for i in (0..p).rev() {
        let mut s = b[i];
        for k in i + 1..p {
            s -= c[k * p + i] * b[k];
        }
        b[i] = s / c[i * p + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_support::{Gauss, f_test, proposition_5_2_1_rules};

    fn direct_cov(errs: &[Vec<f64>], p: usize) -> Vec<f64> {
        let m = errs.len() as f64;
        let mut mean = vec![0.0; p];
        for e in errs {
            for i in 0..p {
                mean[i] += e[i] / m;
            }
        }
        let mut s = vec![0.0; p * p];
        for e in errs {
            for i in 0..p {
                for j in 0..p {
                    s[i * p + j] += (e[i] - mean[i]) * (e[j] - mean[j]) / (m - 1.0);
                }
            }
        }
        s
    }

    #[test]
    fn constant_rule_returns_one_over_lambda() {
        let mut f = Forgetting::new(&ForgettingRule::Constant { lambda: 0.98 }, 2).unwrap();
        assert_eq!(f.beta(&[1.0, 2.0]), 1.0 / 0.98);
        assert!(f.last_g().is_nan());
    }

    #[test]
    fn invalid_rules_are_rejected() {
        let bad = [
            ForgettingRule::Constant { lambda: 0.0 },
            ForgettingRule::Constant { lambda: 1.5 },
            f_test(10, 10, 1.0, 0.01),
            f_test(10, 80, 0.0, 0.01),
            f_test(10, 80, 1.0, 1.0),
            ForgettingRule::RmsRatio {
                tau_n: 0,
                tau_d: 80,
                eta: 1.0,
            },
        ];
        for r in &bad {
            assert!(Forgetting::new(r, 1).is_err(), "{r:?} accepted");
        }
        let r = f_test(3, 6, 1.0, 0.01);
        assert!(Forgetting::new(&r, 3).is_err(), "tau_d <= p + 3 accepted");
    }

    #[test]
    fn a_refused_rule_names_the_field_of_the_forgetting_table() {
        let field = |r: ForgettingRule, p: usize| r.validate(p).unwrap_err().path();
        assert_eq!(
            field(ForgettingRule::Constant { lambda: 0.0 }, 1),
            "forgetting.lambda"
        );
        assert_eq!(field(f_test(1, 80, 1.0, 0.01), 2), "forgetting.tau-n");
        assert_eq!(field(f_test(10, 10, 1.0, 0.01), 1), "forgetting");
        assert_eq!(field(f_test(10, 80, 0.0, 0.01), 1), "forgetting.eta");
        assert_eq!(field(f_test(10, 80, 1.0, 1.0), 1), "forgetting.alpha");
        assert_eq!(field(f_test(3, 6, 1.0, 0.01), 3), "forgetting.tau-d");
        assert_eq!(ForgettingRule::DEFAULT.validate(4), Ok(()));
        // Forgetting::new refuses exactly what validate refuses.
        let e = Forgetting::new(&f_test(3, 6, 1.0, 0.01), 3).unwrap_err();
        assert!(e.starts_with("forgetting.tau-d: "), "{e}");
    }

    #[test]
    fn windowed_covariances_match_direct_computation_over_a_million_steps() {
        let p = 3;
        let (tn, td) = (7, 40);
        let rule = ForgettingRule::RmsRatio {
            tau_n: tn,
            tau_d: td,
            eta: 1.0,
        };
        let mut f = Forgetting::new(&rule, p).unwrap();
        let mut g = Gauss::new(7);
        let mut hist: Vec<Vec<f64>> = Vec::new();
        let steps = 1_000_000;
        for k in 0..steps {
            // A large offset and a transient of size 1e6 early on stress cancellation.
            let big = if (100..200).contains(&k) { 1e6 } else { 1.0 };
            let e: Vec<f64> = (0..p).map(|i| 50.0 + i as f64 + big * g.normal()).collect();
            f.beta(&e);
            hist.push(e);
            if hist.len() > td + 1 {
                hist.remove(0);
            }
            if k > 1000 && (k % 99_991 == 0 || k == steps - 1) {
                let mut sn = vec![0.0; p * p];
                let mut sd = vec![0.0; p * p];
                f.sums_n.covariance(tn + 1, &mut sn);
                f.sums_d.covariance(td + 1, &mut sd);
                let dn = direct_cov(&hist[hist.len() - (tn + 1)..], p);
                let dd = direct_cov(&hist, p);
                for i in 0..p * p {
                    assert!(
                        (sn[i] - dn[i]).abs() <= 1e-12 * (1.0 + dn[i].abs()),
                        "n {k}"
                    );
                    assert!(
                        (sd[i] - dd[i]).abs() <= 1e-12 * (1.0 + dd[i].abs()),
                        "d {k}"
                    );
                }
            }
        }
    }

    #[test]
    fn no_forgetting_until_the_long_window_is_full() {
        let rule = ForgettingRule::RmsRatio {
            tau_n: 2,
            tau_d: 5,
            eta: 1.0,
        };
        let mut f = Forgetting::new(&rule, 1).unwrap();
        for k in 0..5 {
            // Growing errors would trigger forgetting once the window is full.
            assert_eq!(f.beta(&[(k * k) as f64]), 1.0);
            assert_eq!(f.last_g(), 0.0);
        }
        assert!(f.beta(&[100.0]) > 1.0);
        f.reset();
        assert_eq!(f.beta(&[1e3]), 1.0);
    }

    #[test]
    fn variances_at_numerical_zero_give_no_forgetting() {
        for p in [1, 3] {
            let rule = ForgettingRule::RmsRatio {
                tau_n: 5,
                tau_d: 30,
                eta: 1.0,
            };
            let mut f = Forgetting::new(&rule, p).unwrap();
            let mut g = Gauss::new(3);
            let e = vec![0.0; p];
            // A transient of order one, then errors at the roundoff level (and exact zeros).
            for k in 0..2000 {
                let e: Vec<f64> = if k < 40 {
                    (0..p).map(|_| g.normal()).collect()
                } else if k % 3 == 0 {
                    e.clone()
                } else {
                    (0..p)
                        .map(|_| 1e-16 * g.normal() * (k % 7) as f64)
                        .collect()
                };
                let b = f.beta(&e);
                if k > 100 {
                    assert_eq!(b, 1.0, "p = {p}, k = {k}");
                    assert_eq!(f.last_g(), f64::NEG_INFINITY);
                }
            }
            // Exactly zero errors from the start: also no forgetting and no NaN.
            let mut f = Forgetting::new(&rule, p).unwrap();
            for _ in 0..200 {
                assert_eq!(f.beta(&e), 1.0);
                assert!(!f.last_g().is_nan());
            }
        }
    }

    #[test]
    fn non_finite_errors_are_not_pushed() {
        let rule = f_test(5, 30, 1.0, 0.01);
        let mut f = Forgetting::new(&rule, 1).unwrap();
        let mut g = Gauss::new(5);
        for _ in 0..100 {
            f.beta(&[g.normal()]);
        }
        assert_eq!(f.beta(&[f64::NAN]), 1.0);
        assert!(f.last_g().is_nan());
        for _ in 0..100 {
            let b = f.beta(&[g.normal()]);
            assert!(b.is_finite() && b >= 1.0);
            assert!(f.last_g().is_finite());
        }
    }

    #[test]
    fn proposition_5_2_1_f_test_equals_rms_ratio_when_alpha_is_one_minus_f_of_one() {
        let (ft, rms) = proposition_5_2_1_rules(10, 80, 0.7);
        let (mut a, mut b) = (
            Forgetting::new(&ft, 1).unwrap(),
            Forgetting::new(&rms, 1).unwrap(),
        );
        let mut g = Gauss::new(11);
        let mut forgot = 0;
        for k in 0..20_000 {
            let s = if (k / 500) % 2 == 0 { 1.0 } else { 3.0 };
            let e = [s * g.normal()];
            let (ba, bb) = (a.beta(&e), b.beta(&e));
            assert!((1.0 / ba - 1.0 / bb).abs() <= 1e-9, "k = {k}: {ba} vs {bb}");
            forgot += usize::from(bb > 1.0);
        }
        assert!(forgot > 1000, "the comparison must exercise forgetting");
    }

    #[test]
    fn lawley_hotelling_test_fires_when_the_error_covariance_jumps() {
        for p in [2, 3] {
            let rule = f_test(10, 80, 1.0, 0.001);
            let mut f = Forgetting::new(&rule, p).unwrap();
            let mut g = Gauss::new(21 + p as u64);
            let mut first = None;
            for k in 0..400 {
                let s = if k < 300 { 0.1 } else { 1.0 };
                let e: Vec<f64> = (0..p).map(|_| s * g.normal()).collect();
                let b = f.beta(&e);
                if b > 1.0 && first.is_none() {
                    first = Some(k);
                }
            }
            let k = first.expect("never fired");
            assert!((300..312).contains(&k), "p = {p}: first fired at {k}");
        }
    }

    #[test]
    fn f_test_fires_rarely_on_stationary_noise() {
        for p in [1, 2, 4] {
            let rule = f_test(10, 80, 1.0, 0.001);
            let mut f = Forgetting::new(&rule, p).unwrap();
            let mut g = Gauss::new(99 + p as u64);
            let n = 100_000;
            let mut fired = 0;
            for _ in 0..n {
                let e: Vec<f64> = (0..p).map(|_| 0.3 * g.normal()).collect();
                fired += usize::from(f.beta(&e) > 1.0);
            }
            let frac = fired as f64 / n as f64;
            assert!(frac < 0.01, "p = {p}: fraction {frac}");
        }
    }
}
