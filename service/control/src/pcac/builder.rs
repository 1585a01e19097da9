//! [`PcacParams`] from the settings a problem must state, every other setting at its
//! default: the one place where PCAC's defaults are written, used by the configuration
//! reader, the tests, the benchmarks and the studies.
//!
//! A problem states the model order `n̂` (2.24), the plant's `p` outputs and `m` inputs,
//! `P_0 = p0 · I` of the identification (2.30)–(2.32) and the horizon `ℓ` of (2.43). The
//! defaults of the rest:
//!
//! | setting | default |
//! | --- | --- |
//! | `θ_0` | `0` |
//! | forgetting | none (`λ = 1`) |
//! | trace limit | `10⁶ · tr P_0` ([`PcacParams::default_trace_limit`]) |
//! | identification kernel | [`IdKernel::Shared`] |
//! | `C_t` | `I_p` (every output tracked) |
//! | `Q`, `R` | [`PcacParams::DEFAULT_Q`], [`PcacParams::DEFAULT_R`] on every channel |
//! | `u_min`, `u_max` | `−∞`, `+∞` |
//! | move bounds, output constraints (2.49) | none |
//! | timing | [`PcacTiming::SameStep`] |
//! | QP settings | [`QpSettings::default`] |
//! | warm start | [`PcacParams::DEFAULT_WARM_START`] |
//! | unconstrained fast path | [`FastPathMode::Auto`] (when the Riccati recursion is cheaper) |
//! | augmentation (7.53)–(7.57) | none |
//! | re-planning period `N` ([`PcacParams::replan_every`]) | [`PcacParams::DEFAULT_REPLAN_EVERY`] (every sample) |
//! | QP share per re-planning period ([`PcacParams::qp_changes_per_period`]) | 0 (the whole QP in one period) |
//! | cycles per Hessian build `M` ([`PcacParams::hessian_every`]), the build cycle's length ([`PcacParams::hessian_cycle`]) | [`PcacParams::DEFAULT_HESSIAN_EVERY`] (every cycle), `N` |
//!
//! [`PcacParams::chapter_6`] and [`PcacParams::chapter_7`] start from the settings of the
//! dissertation's examples instead: the truss (§6.2) and the sampling arm (§7.3).
//!
//! [`PcacBuilder::build`] returns the parameters unchecked; [`PcacParams::validate`] (which
//! [`super::Pcac::new`] calls) names the field of a bad setting.

use super::augmentation::OutputFeedback;
use super::controller::{PcacParams, PcacTiming};
use super::model::{IdKernel, IoModelParams};
use crate::forgetting::ForgettingRule;
use crate::mpc::condense::{MoveBounds, MpcSpec, OutputConstraints, Weight};
use crate::mpc::fast_path::FastPathMode;
use crate::mpc::qp::QpSettings;

/// Builds [`PcacParams`] (module docs); start with [`PcacParams::builder`].
#[derive(Debug, Clone, PartialEq)]
pub struct PcacBuilder {
    params: PcacParams,
}

impl PcacParams {
    /// The builder of the parameters for order `n_hat`, `p` outputs, `m` inputs,
    /// `P_0 = p0 · I` and horizon `ℓ = horizon`, every other setting at its default
    /// (module docs of [`super::builder`]).
    pub fn builder(n_hat: usize, p: usize, m: usize, p0: f64, horizon: usize) -> PcacBuilder {
        PcacBuilder {
            params: PcacParams {
                model: IoModelParams {
                    n_hat,
                    p,
                    m,
                    theta0: Vec::new(),
                    p0,
                    rule: ForgettingRule::Constant { lambda: 1.0 },
                    trace_limit: PcacParams::default_trace_limit(n_hat, p, m, p0),
                    kernel: IdKernel::default(),
                },
                mpc: MpcSpec {
                    horizon,
                    n_inputs: m,
                    n_outputs: p,
                    n_tracked: p,
                    tracking: (0..p * p)
                        .map(|i| if i / p == i % p { 1.0 } else { 0.0 })
                        .collect(),
                    q: Weight::PerChannel(vec![PcacParams::DEFAULT_Q; p]),
                    r: Weight::PerChannel(vec![PcacParams::DEFAULT_R; m]),
                    u_min: vec![f64::NEG_INFINITY; m],
                    u_max: vec![f64::INFINITY; m],
                    move_bounds: None,
                    output_constraints: None,
                    input_notch: None,
                },
                timing: PcacTiming::default(),
                qp: QpSettings::default(),
                warm_start: PcacParams::DEFAULT_WARM_START,
                fast_path: FastPathMode::default(),
                augmentation: None,
                qp_changes_per_period: 0,
                hessian_every: PcacParams::DEFAULT_HESSIAN_EVERY,
                hessian_cycle: 0,
                replan_every: PcacParams::DEFAULT_REPLAN_EVERY,
                internal_model: None,
            },
        }
    }

    /// `u_max = −u_min` of the sampling arm's PCAC (§7.3).
    pub const CHAPTER_7_U_MAX: f64 = 100.0;

    /// The builder at the PCAC settings of the truss (§6.2): `p = 4` outputs, `m = 2`
    /// inputs, the cold start `θ_0 = 10⁻¹⁰ 1_{600}`, `n̂ = 25`, `P_0 = I`, the F-test
    /// forgetting [`ForgettingRule::PCAC_EXAMPLES`], `ℓ = 40`, `C_t = [0_{1×3} 1]`,
    /// `Q = 10⁶` and `R = I`. Input bounds and timing are the caller's (the chapter gives
    /// none; defaults: unbounded, [`PcacTiming::SameStep`]).
    pub fn chapter_6() -> PcacBuilder {
        const N_HAT: usize = 25;
        const P: usize = 4;
        const M: usize = 2;
        PcacParams::builder(N_HAT, P, M, 1.0, 40)
            .theta0(vec![1e-10; PcacParams::theta_len(N_HAT, P, M)])
            .forgetting(ForgettingRule::PCAC_EXAMPLES)
            .tracking(1, vec![0.0, 0.0, 0.0, 1.0])
            .q(Weight::PerChannel(vec![1e6]))
    }

    /// The builder at the PCAC settings of the sampling arm (§7.3): `p = 5` outputs `ζ`,
    /// `m = 2` inputs, `n̂ = 1`, `P_0 = 10 I`, the F-test forgetting
    /// [`ForgettingRule::PCAC_EXAMPLES`], `ℓ = 50`, `C_t = [0_{3×2} I_3]`,
    /// `Q = diag(1000, 100, 1)`, `R = I` and `u_max = −u_min =` [`Self::CHAPTER_7_U_MAX`].
    /// The chapter's prior `w_0` ([`PcacBuilder::theta0`]), move bounds and timing are the
    /// caller's (defaults: `θ_0 = 0`, none, [`PcacTiming::SameStep`]).
    pub fn chapter_7() -> PcacBuilder {
        const P: usize = 5;
        const M: usize = 2;
        // C_t = [0_{3×2} I_3]: the tracked outputs are χ = [ẋ, ẏ, e].
        let tracking = (0..3 * P)
            .map(|i| if i % P == 2 + i / P { 1.0 } else { 0.0 })
            .collect();
        let u_max = PcacParams::CHAPTER_7_U_MAX;
        PcacParams::builder(1, P, M, 10.0, 50)
            .forgetting(ForgettingRule::PCAC_EXAMPLES)
            .tracking(3, tracking)
            .q(Weight::PerChannel(vec![1000.0, 100.0, 1.0]))
            .input_bounds(vec![-u_max; M], vec![u_max; M])
    }
}

impl PcacBuilder {
    /// `θ_0` in the order of (2.27) (empty: `θ_0 = 0`).
    pub fn theta0(mut self, theta0: Vec<f64>) -> Self {
        self.params.model.theta0 = theta0;
        self
    }

    /// The forgetting rule of the identification.
    pub fn forgetting(mut self, rule: ForgettingRule) -> Self {
        self.params.model.rule = rule;
        self
    }

    /// The trace limit of the identification's covariance (may be `+∞`).
    pub fn trace_limit(mut self, limit: f64) -> Self {
        self.params.model.trace_limit = limit;
        self
    }

    /// The RLS form of the identification.
    pub fn kernel(mut self, kernel: IdKernel) -> Self {
        self.params.model.kernel = kernel;
        self
    }

    /// `C_t`: `n_tracked` rows of `p`, row-major; `Q` then weighs `n_tracked` channels
    /// (set it after this).
    pub fn tracking(mut self, n_tracked: usize, rows: Vec<f64>) -> Self {
        self.params.mpc.n_tracked = n_tracked;
        self.params.mpc.tracking = rows;
        self.params.mpc.q = Weight::PerChannel(vec![PcacParams::DEFAULT_Q; n_tracked]);
        self
    }

    /// `Q` on the tracked outputs.
    pub fn q(mut self, q: Weight) -> Self {
        self.params.mpc.q = q;
        self
    }

    /// `R` on the inputs.
    pub fn r(mut self, r: Weight) -> Self {
        self.params.mpc.r = r;
        self
    }

    /// The input bounds `u_min ≤ u ≤ u_max` (`m` each).
    pub fn input_bounds(mut self, u_min: Vec<f64>, u_max: Vec<f64>) -> Self {
        self.params.mpc.u_min = u_min;
        self.params.mpc.u_max = u_max;
        self
    }

    /// The move bounds `Δu_min ≤ Δu ≤ Δu_max`.
    pub fn move_bounds(mut self, bounds: Option<MoveBounds>) -> Self {
        self.params.mpc.move_bounds = bounds;
        self
    }

    /// The output constraints (2.49).
    pub fn output_constraints(mut self, constraints: Option<OutputConstraints>) -> Self {
        self.params.mpc.output_constraints = constraints;
        self
    }

    /// The internal model of known tones ([`super::tone_model`]; `None`: none).
    pub fn internal_model(mut self, internal_model: Option<super::InternalModel>) -> Self {
        self.params.internal_model = internal_model;
        self
    }

    /// When the computed input is applied.
    pub fn timing(mut self, timing: PcacTiming) -> Self {
        self.params.timing = timing;
        self
    }

    /// The QP solver's limits.
    pub fn qp(mut self, qp: QpSettings) -> Self {
        self.params.qp = qp;
        self
    }

    /// Whether each QP starts from the previous active set shifted by one step.
    pub fn warm_start(mut self, warm_start: bool) -> Self {
        self.params.warm_start = warm_start;
        self
    }

    /// Whether to try the unconstrained fast path before condensing
    /// ([`crate::mpc::fast_path`]).
    pub fn fast_path(mut self, mode: FastPathMode) -> Self {
        self.params.fast_path = mode;
        self
    }

    /// The fixed output feedback `K̄` this PCAC augments (chapter 7).
    pub fn augmentation(mut self, feedback: Option<OutputFeedback>) -> Self {
        self.params.augmentation = feedback;
        self
    }

    /// The QP's share of each re-planning period before the last, in active-set changes
    /// ([`PcacParams::qp_changes_per_period`]; needs `replan_every ≥ 4`; 0 = the whole QP
    /// in one period).
    pub fn qp_changes_per_period(mut self, changes: usize) -> Self {
        self.params.qp_changes_per_period = changes;
        self
    }

    /// Build the Hessian in every `m_every`-th re-planning cycle only, those cycles `len`
    /// samples long (0: `N`) ([`PcacParams::hessian_every`], [`PcacParams::hessian_cycle`]).
    pub fn hessian_every(mut self, m_every: usize, len: usize) -> Self {
        self.params.hessian_every = m_every;
        self.params.hessian_cycle = len;
        self
    }

    /// Re-plan every `n` samples ([`PcacParams::replan_every`]; needs next-step timing
    /// when `n > 1`).
    pub fn replan_every(mut self, n: usize) -> Self {
        self.params.replan_every = n;
        self
    }

    /// The parameters, unchecked ([`PcacParams::validate`] checks them).
    pub fn build(self) -> PcacParams {
        self.params
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dimensions;

    #[test]
    fn the_defaults_are_those_of_the_table_and_valid() {
        let p = PcacParams::builder(3, 2, 1, 10.0, 8).build();
        assert!(p.model.theta0.is_empty());
        assert_eq!(p.model.rule, ForgettingRule::Constant { lambda: 1.0 });
        assert_eq!(p.model.trace_limit, 1e6 * (3 * 2 * 3) as f64 * 10.0);
        assert_eq!(p.mpc.tracking, vec![1.0, 0.0, 0.0, 1.0]);
        assert_eq!(p.mpc.q, Weight::PerChannel(vec![1.0, 1.0]));
        assert_eq!(p.mpc.r, Weight::PerChannel(vec![1.0]));
        assert_eq!(p.mpc.u_min, vec![f64::NEG_INFINITY]);
        assert_eq!(p.timing, PcacTiming::SameStep);
        assert!(p.warm_start && p.augmentation.is_none());
        assert_eq!(p.fast_path, FastPathMode::Auto);
        assert_eq!(p.replan_every, 1);
        p.validate(Dimensions::new(2, 0, 0, 1)).unwrap();
        p.validate(Dimensions::new(2, 0, 2, 1)).unwrap();
    }

    #[test]
    fn chapter_7_is_the_setting_of_section_7_3() {
        let p = PcacParams::chapter_7().build();
        assert_eq!((p.model.n_hat, p.model.p, p.model.m), (1, 5, 2));
        assert_eq!((p.model.p0, p.mpc.horizon), (10.0, 50));
        assert_eq!(p.model.rule, ForgettingRule::PCAC_EXAMPLES);
        let mut c_t = vec![0.0; 15];
        for i in 0..3 {
            c_t[i * 5 + 2 + i] = 1.0;
        }
        assert_eq!((p.mpc.n_tracked, &p.mpc.tracking), (3, &c_t));
        assert_eq!(p.mpc.q, Weight::PerChannel(vec![1000.0, 100.0, 1.0]));
        assert_eq!(p.mpc.r, Weight::PerChannel(vec![1.0; 2]));
        assert_eq!(
            (&p.mpc.u_min, &p.mpc.u_max),
            (&vec![-100.0; 2], &vec![100.0; 2])
        );
        p.validate(Dimensions::new(5, 0, 0, 2)).unwrap();
    }

    #[test]
    fn chapter_6_is_the_setting_of_section_6_2() {
        let p = PcacParams::chapter_6().build();
        assert_eq!((p.model.n_hat, p.model.p, p.model.m), (25, 4, 2));
        assert_eq!((&p.model.theta0, p.model.p0), (&vec![1e-10; 600], 1.0));
        assert_eq!(p.model.rule, ForgettingRule::PCAC_EXAMPLES);
        assert_eq!(p.mpc.horizon, 40);
        assert_eq!(
            (p.mpc.n_tracked, &p.mpc.tracking),
            (1, &vec![0.0, 0.0, 0.0, 1.0])
        );
        assert_eq!(p.mpc.q, Weight::PerChannel(vec![1e6]));
        assert_eq!(p.mpc.r, Weight::PerChannel(vec![1.0; 2]));
        p.validate(Dimensions::new(4, 0, 0, 2)).unwrap();
    }

    #[test]
    fn tracking_one_output_weighs_one_channel() {
        let p = PcacParams::builder(2, 2, 1, 1.0, 5)
            .tracking(1, vec![0.0, 1.0])
            .build();
        assert_eq!(p.mpc.q, Weight::PerChannel(vec![1.0]));
        p.validate(Dimensions::new(2, 0, 1, 1)).unwrap();
    }
}
