//! `kind = "pcac"`: the `[controller]` table of predictive cost adaptive control
//! ([`Pcac`](control::pcac::Pcac), (2.24)–(2.51)). `p0`, `lambda` and
//! `[controller.forgetting]` are described in the `forgetting` module.
//!
//! ```toml
//! [controller]
//! kind = "pcac"
//! n-hat = 25                      # model order n̂ (2.24), 1 to 200
//! p0 = 1.0                        # P_0 = p0 I (2.30), required
//! theta0 = 1e-10                  # θ_0: one value for every entry, or n̂ p (p+m) values,
//!                                 # each within ±10⁶
//! trace-limit = 1e12              # tr P beyond this resets θ, P (default 10⁶ tr P_0)
//! horizon = 40                    # ℓ (2.43), 2 to 200
//! tracking = [[0.0, 0.0, 0.0, 1.0]]   # C_t (p_t × p); default I_p
//! q = 1e6                         # Q: scalar or one per tracked output (≥ 0)
//! r = 1.0                         # R on the moves: scalar or one per input (> 0)
//! u-min = -10.0                   # input bounds (2.50): scalar or per input (default none)
//! u-max = 10.0
//! du-min = -2.0                   # move bounds (2.51), optional, ≤ 0 / ≥ 0
//! du-max = 2.0
//! timing = "same-step"            # or "next-step" (the dissertation's u_{1|k} at k+1)
//! warm-start = true
//! qp-max-iterations = 500         # the solver's cap on active-set changes per step (≤ 10⁶)
//! fast-path = "auto"              # the unconstrained Riccati fast path: "auto" (when its
//!                                 # operation count is below condensing + the dense
//!                                 # factorization), "always" or "never"
//! replan-every = 1                # N: solve every N samples, the work spread over N periods,
//!                                 # the plant following the plan between (next-step; ≤ ℓ)
//! qp-changes-per-period = 0       # N ≥ 4: the QP's share of each period before the last, in
//!                                 # active-set changes (0: the whole QP in one period)
//! hessian-every = 1               # M: build the QP's Hessian and factor it in every M-th
//!                                 # cycle only, the others keep both (next-step, fast-path
//!                                 # "never")
//! hessian-cycle = 4               # N_H: the length of a cycle that builds it (N ≤ N_H ≤ ℓ;
//!                                 # default N)
//! lambda = 1.0                    # constant forgetting, or:
//! [controller.forgetting]         # rule = "f-test" (tau-n, tau-d, eta, alpha) | …
//! rule = "f-test"
//! tau-n = 40
//! tau-d = 200
//! eta = 0.1
//! alpha = 0.001
//! [controller.output-constraints] # (2.49) C_c y_{i|k} + 𝓓 ≤ 0 at every step, optional
//! c = [[0.0, 0.0, 0.0, 1.0]]      # C_c (n_c × p)
//! d = [-0.5]                      # 𝓓 (n_c)
//! [controller.internal-model]     # known tones (beyond the dissertation), optional
//! tones-hz = [800.0, 900.0]       # the tones' frequencies, each in (0, Nyquist), 1 to 32
//! notch-radius = 0.97             # ρ of the notch W = D(q)/D(ρq), in (0, 1); default 0.97
//! r-notch = 1.0                   # R_v on the notched input: scalar or per input (> 0); default 1
//! r-level = [100.0, 0.0]          # R_u on the input's level: scalar or per input (≥ 0); default 0
//! ```
//!
//! With `[controller.internal-model]` ([`control::pcac::tone_model`]) the identification
//! runs on `D(q)`-filtered data, the prediction uses the product model and the cost
//! (2.48') adds `Vᵀ R_v V + Uᵀ R_u U`; `r` (the move weight) then defaults to 0 and may be
//! 0, and `fast-path = "always"` is refused.

use serde::Deserialize;

use super::bounds::{MAX_PCAC_HORIZON, MAX_PCAC_N_HAT, MAX_QP_ITERATIONS, MAX_THETA0};
use super::controller::{ControllerConfig, Rig, param_error};
use super::forgetting::{RawForgetting, ReadRule, forgetting_rule, required_p0};
use super::values::{ScalarOrVec, count, magnitudes, matrix, one_of, per_channel, row_major};
use super::{ConfigError, ErrFn};
use control::internal_model::MAX_TONES;
use control::mpc::condense::{MoveBounds, OutputConstraints, Weight};
use control::mpc::fast_path::FastPathMode;
use control::mpc::qp::QpSettings;
use control::pcac::{InternalModel, PcacParams, PcacTiming};

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawPcac {
    /// `"pcac"` for the kind; absent in the sampling-arm controller's `[controller.pcac]`.
    #[allow(dead_code)]
    kind: Option<String>,
    n_hat: Option<usize>,
    p0: Option<f64>,
    theta0: Option<ScalarOrVec>,
    trace_limit: Option<f64>,
    lambda: Option<f64>,
    forgetting: Option<RawForgetting>,
    horizon: Option<usize>,
    tracking: Option<Vec<Vec<f64>>>,
    q: Option<ScalarOrVec>,
    r: Option<ScalarOrVec>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    du_min: Option<ScalarOrVec>,
    du_max: Option<ScalarOrVec>,
    timing: Option<String>,
    warm_start: Option<bool>,
    qp_max_iterations: Option<usize>,
    fast_path: Option<String>,
    replan_every: Option<usize>,
    qp_changes_per_period: Option<usize>,
    hessian_every: Option<usize>,
    hessian_cycle: Option<usize>,
    output_constraints: Option<RawOutputConstraints>,
    internal_model: Option<RawInternalModel>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawInternalModel {
    tones_hz: Vec<f64>,
    notch_radius: Option<f64>,
    r_notch: Option<ScalarOrVec>,
    r_level: Option<ScalarOrVec>,
}

/// The notch radius `ρ` when `[controller.internal-model]` gives none.
const DEFAULT_NOTCH_RADIUS: f64 = 0.97;

/// `[<table>.internal-model]` into an [`InternalModel`] for the sampling period `period`
/// (s): the tones in hertz within `(0, Nyquist)`, converted to rad/sample.
fn internal_model(
    raw: &RawInternalModel,
    table: &str,
    m: usize,
    period: f64,
    err: &ErrFn<'_>,
) -> Result<InternalModel, ConfigError> {
    let f = |name: &str| format!("{table}.internal-model.{name}");
    let nyquist = 0.5 / period;
    if raw.tones_hz.is_empty() || raw.tones_hz.len() > MAX_TONES {
        return Err(err(
            &f("tones-hz"),
            format!(
                "has {} tones, expected 1 to {MAX_TONES}",
                raw.tones_hz.len()
            ),
        ));
    }
    if let Some(bad) = raw
        .tones_hz
        .iter()
        .find(|x| !(x.is_finite() && **x > 0.0 && **x < nyquist))
    {
        return Err(err(
            &f("tones-hz"),
            format!(
                "{bad} Hz: every tone must lie strictly between 0 and the Nyquist frequency \
                 {nyquist} Hz"
            ),
        ));
    }
    Ok(InternalModel {
        omegas: raw
            .tones_hz
            .iter()
            .map(|hz| 2.0 * std::f64::consts::PI * hz * period)
            .collect(),
        notch_radius: raw.notch_radius.unwrap_or(DEFAULT_NOTCH_RADIUS),
        r_notch: per_channel(&raw.r_notch, m, 1.0, &f("r-notch"), err)?,
        r_level: per_channel(&raw.r_level, m, 0.0, &f("r-level"), err)?,
    })
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawOutputConstraints {
    c: Vec<Vec<f64>>,
    d: Vec<f64>,
}

/// Reads the table into [`PcacParams`] and validates them (the controller is built
/// later, once, by the runtime).
pub(super) fn parse(
    raw: RawPcac,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let dims = crate::wire::dimensions(rig.counts);
    let (params, rule) = read(raw, "controller", dims.n_y, dims.n_u, rig.period, err)?;
    params
        .validate(dims)
        .map_err(|e| param_error(rule.locate(e), err))?;
    Ok(ControllerConfig::Pcac {
        params: Box::new(params),
    })
}

/// Reads a PCAC table found at `table` (`"controller"`, or `"controller.pcac"` in the
/// sampling-arm controller) for a model with `p` outputs and `m` inputs into
/// [`PcacParams`] (without an augmentation; the internal model's tones in hertz at the
/// sampling period `period`, s), naming its fields `<table>.<field>`; the
/// caller validates the result (the kernel's fields are relative to the table) with the
/// returned rule's [`ReadRule::locate`].
pub(super) fn read(
    raw: RawPcac,
    table: &str,
    p: usize,
    m: usize,
    period: f64,
    err: &ErrFn<'_>,
) -> Result<(PcacParams, ReadRule), ConfigError> {
    let f = |name: &str| format!("{table}.{name}");
    let n_hat = raw
        .n_hat
        .ok_or_else(|| err(&f("n-hat"), "missing (the model order n̂)".into()))?;
    let n_hat = count(n_hat as u64, 0, MAX_PCAC_N_HAT, &f("n-hat"), err)? as usize;
    let p0 = required_p0(raw.p0, table, "for PCAC", err)?;
    let theta0 = match &raw.theta0 {
        None => Vec::new(),
        Some(ScalarOrVec::Scalar(x)) => vec![*x; PcacParams::theta_len(n_hat, p, m)],
        Some(ScalarOrVec::Vec(v)) => v.clone(),
    };
    magnitudes(&theta0, MAX_THETA0, &f("theta0"), err)?;
    let trace_limit = raw
        .trace_limit
        .unwrap_or_else(|| PcacParams::default_trace_limit(n_hat, p, m, p0));
    let rule = forgetting_rule(raw.lambda, raw.forgetting.as_ref(), table, err)?;
    let horizon = raw
        .horizon
        .ok_or_else(|| err(&f("horizon"), "missing (the horizon ℓ)".into()))?;
    let horizon = count(horizon as u64, 0, MAX_PCAC_HORIZON, &f("horizon"), err)? as usize;
    let tracking = match &raw.tracking {
        None => nalgebra::DMatrix::identity(p, p),
        Some(rows) => matrix(rows, p, &f("tracking")).map_err(|m| err(&f("tracking"), m))?,
    };
    if tracking.ncols() != p || tracking.nrows() == 0 {
        return Err(err(
            &f("tracking"),
            format!(
                "is {}×{}, expected p_t × {p} (one column per identified output)",
                tracking.nrows(),
                tracking.ncols()
            ),
        ));
    }
    let pt = tracking.nrows();
    let q = per_channel(&raw.q, pt, PcacParams::DEFAULT_Q, &f("q"), err)?;
    let internal = match &raw.internal_model {
        None => None,
        Some(im) => Some(internal_model(im, table, m, period, err)?),
    };
    // With the internal model the tone-notch cost makes the QP strictly convex: R may be 0
    // and is 0 unless given.
    let r_default = if internal.is_some() {
        0.0
    } else {
        PcacParams::DEFAULT_R
    };
    let r = per_channel(&raw.r, m, r_default, &f("r"), err)?;
    let u_min = per_channel(&raw.u_min, m, f64::NEG_INFINITY, &f("u-min"), err)?;
    let u_max = per_channel(&raw.u_max, m, f64::INFINITY, &f("u-max"), err)?;
    let move_bounds = if raw.du_min.is_none() && raw.du_max.is_none() {
        None
    } else {
        Some(MoveBounds {
            min: per_channel(&raw.du_min, m, f64::NEG_INFINITY, &f("du-min"), err)?,
            max: per_channel(&raw.du_max, m, f64::INFINITY, &f("du-max"), err)?,
        })
    };
    let output_constraints = match &raw.output_constraints {
        None => None,
        Some(oc) => {
            let field = f("output-constraints.c");
            let c = matrix(&oc.c, p, &field).map_err(|m| err(&field, m))?;
            if c.ncols() != p || c.nrows() == 0 {
                return Err(err(
                    &field,
                    format!("is {}×{}, expected n_c × {p}", c.nrows(), c.ncols()),
                ));
            }
            Some(OutputConstraints {
                c: row_major(&c),
                d: oc.d.clone(),
            })
        }
    };
    let timing = one_of(
        raw.timing.as_deref(),
        PcacTiming::default(),
        &[
            ("same-step", PcacTiming::SameStep),
            ("next-step", PcacTiming::NextStep),
        ],
        &f("timing"),
        err,
    )?;
    let fast_path = one_of(
        raw.fast_path.as_deref(),
        FastPathMode::default(),
        &[
            ("auto", FastPathMode::Auto),
            ("always", FastPathMode::Always),
            ("never", FastPathMode::Never),
        ],
        &f("fast-path"),
        err,
    )?;
    let mut qp = QpSettings::default();
    if let Some(n) = raw.qp_max_iterations {
        let field = f("qp-max-iterations");
        qp.max_iterations = count(n as u64, 0, MAX_QP_ITERATIONS, &field, err)? as usize;
    }
    let replan_every = match raw.replan_every {
        None => PcacParams::DEFAULT_REPLAN_EVERY,
        Some(n) => count(n as u64, 0, MAX_PCAC_HORIZON, &f("replan-every"), err)? as usize,
    };
    let qp_share = match raw.qp_changes_per_period {
        None => 0,
        Some(n) => count(
            n as u64,
            0,
            MAX_QP_ITERATIONS,
            &f("qp-changes-per-period"),
            err,
        )? as usize,
    };
    let hessian_every = match raw.hessian_every {
        None => PcacParams::DEFAULT_HESSIAN_EVERY,
        Some(n) => count(n as u64, 0, MAX_PCAC_HORIZON, &f("hessian-every"), err)? as usize,
    };
    let hessian_cycle = match raw.hessian_cycle {
        None => 0,
        Some(n) => count(n as u64, 1, MAX_PCAC_HORIZON, &f("hessian-cycle"), err)? as usize,
    };
    let params = PcacParams::builder(n_hat, p, m, p0, horizon)
        .theta0(theta0)
        .forgetting(rule.rule.clone())
        .trace_limit(trace_limit)
        .tracking(pt, row_major(&tracking))
        .q(Weight::PerChannel(q))
        .r(Weight::PerChannel(r))
        .input_bounds(u_min, u_max)
        .move_bounds(move_bounds)
        .output_constraints(output_constraints)
        .timing(timing)
        .qp(qp)
        .warm_start(raw.warm_start.unwrap_or(PcacParams::DEFAULT_WARM_START))
        .fast_path(fast_path)
        .replan_every(replan_every)
        .qp_changes_per_period(qp_share)
        .hessian_every(hessian_every, hessian_cycle)
        .internal_model(internal)
        .build();
    Ok((params, rule))
}

#[cfg(test)]
mod tests {
    use crate::config::ServiceConfig;
    use crate::config::refusal_cases::assert_refused_naming_fields;
    use control::mpc::condense::Weight;
    use control::mpc::fast_path::FastPathMode;
    use control::pcac::PcacTiming;

    const GOOD: &str = include_str!("../../../tests/fixtures/config/pcac-chapter-6.toml");

    fn params(text: &str) -> Result<Box<super::PcacParams>, String> {
        let c = ServiceConfig::parse(text, "pcac.toml").map_err(|e| e.to_string())?;
        match c.controller {
            crate::config::ControllerConfig::Pcac { params } => Ok(params),
            other => panic!("not pcac: {other:?}"),
        }
    }

    #[test]
    fn the_chapter_6_settings_are_read_into_the_controller() {
        let p = params(GOOD).unwrap();
        assert_eq!((p.model.n_hat, p.model.p, p.model.m), (25, 4, 2));
        assert_eq!(p.model.theta0, vec![1e-10; 600]);
        assert_eq!(p.mpc.horizon, 40);
        assert_eq!(p.mpc.tracking, vec![0.0, 0.0, 0.0, 1.0]);
        assert_eq!(p.mpc.q, Weight::PerChannel(vec![1e6]));
        assert_eq!(p.mpc.r, Weight::PerChannel(vec![1.0, 1.0]));
        let mb = p.mpc.move_bounds.as_ref().unwrap();
        assert_eq!(
            (mb.min.clone(), mb.max.clone()),
            (vec![f64::NEG_INFINITY; 2], vec![3.0; 2])
        );
        assert_eq!(p.mpc.output_constraints.as_ref().unwrap().d, vec![-5.0]);
        assert_eq!(p.timing, PcacTiming::NextStep);
        assert!(p.warm_start);
        assert_eq!(p.fast_path, FastPathMode::Auto);
        assert_eq!(p.replan_every, 1);
        let every4 = params(&GOOD.replace(
            "timing = \"next-step\"",
            "timing = \"next-step\"\nreplan-every = 4",
        ))
        .unwrap();
        assert_eq!(every4.replan_every, 4);
        assert_eq!(every4.qp_changes_per_period, 0);
        let shared = params(&GOOD.replace(
            "timing = \"next-step\"",
            "timing = \"next-step\"\nreplan-every = 4\nqp-changes-per-period = 8",
        ))
        .unwrap();
        assert_eq!(shared.qp_changes_per_period, 8);
        let kept = params(&GOOD.replace(
            "timing = \"next-step\"",
            "timing = \"next-step\"\nfast-path = \"never\"\nreplan-every = 4\nhessian-every = 8\nhessian-cycle = 11",
        ))
        .unwrap();
        assert_eq!((kept.hessian_every, kept.hessian_cycle_len()), (8, 11));
        assert_eq!((every4.hessian_every, every4.hessian_cycle_len()), (1, 4));
        let c = ServiceConfig::parse(GOOD, "pcac.toml").unwrap();
        let ctl = c.controller.build(c.counts).unwrap();
        assert_eq!(ctl.kind(), "pcac");
    }

    #[test]
    fn the_fast_path_setting_is_read() {
        for (text, mode) in [
            ("always", FastPathMode::Always),
            ("never", FastPathMode::Never),
            ("auto", FastPathMode::Auto),
        ] {
            let with = GOOD.replace(
                "timing = \"next-step\"",
                &format!("timing = \"next-step\"\nfast-path = \"{text}\""),
            );
            assert_ne!(with, GOOD, "the fixture sets the timing");
            assert_eq!(params(&with).unwrap().fast_path, mode);
        }
    }

    #[test]
    fn the_internal_model_is_read_in_radians_per_sample_with_r_zero_by_default() {
        let text = include_str!("../../../tests/fixtures/config/pcac-internal-model.toml");
        let p = params(text).unwrap();
        let im = p.internal_model.as_ref().unwrap();
        let two_pi = 2.0 * std::f64::consts::PI;
        assert!((im.omegas[0] - two_pi * 0.1).abs() < 1e-12);
        assert!((im.omegas[1] - two_pi * 0.375).abs() < 1e-12);
        assert_eq!(im.notch_radius, 0.97);
        assert_eq!(
            (im.r_notch.clone(), im.r_level.clone()),
            (vec![1.0; 2], vec![100.0, 0.0])
        );
        assert_eq!(p.mpc.r, Weight::PerChannel(vec![0.0, 0.0]));
        let c = ServiceConfig::parse(text, "pcac.toml").unwrap();
        let ctl = c.controller.build(c.counts).unwrap();
        assert_eq!(ctl.kind(), "pcac");
        // The defaults: ρ = 0.97, R_v = 1, R_u = 0.
        let bare = params(
            &text
                .replace("notch-radius = 0.97\n", "")
                .replace("r-notch = 1.0\n", "")
                .replace("r-level = [100.0, 0.0]\n", ""),
        )
        .unwrap();
        let im = bare.internal_model.as_ref().unwrap();
        assert_eq!((im.notch_radius, im.r_level.clone()), (0.97, vec![0.0; 2]));
    }

    #[test]
    fn bad_pcac_settings_are_refused_naming_the_field() {
        let cases = include_str!("../../../tests/fixtures/refusals/controller-pcac.toml");
        assert_refused_naming_fields(GOOD, "pcac.toml", cases);
        let im = include_str!("../../../tests/fixtures/config/pcac-internal-model.toml");
        let cases =
            include_str!("../../../tests/fixtures/refusals/controller-pcac-internal-model.toml");
        assert_refused_naming_fields(im, "pcac.toml", cases);
        // Commands must match the tracked outputs.
        let m = params(&GOOD.replace("r = 0, u = 2", "r = 2, u = 2")).unwrap_err();
        assert!(m.contains("2 commands r"), "{m}");
    }
}
