//! `kind = "appc"` and `kind = "rc-mrac"`: model reference adaptive control of chapter 4
//! ([`Appc`](control::mrac::Appc), (4.7)–(4.43); [`RcMrac`](control::mrac::RcMrac),
//! (4.46)–(4.77)). Both follow the reference model `y_m = N_m/D_m r` (4.4) with the
//! command `r_k` of each measurement (the rig needs `n_r = 1`, `n_y = 1`, `n_u = 1`) and
//! log `y_m` and the model-following error `e_k = y_k − y_{m,k}` among their internals.
//!
//! Polynomials are lists of the coefficients of `q⁰, q⁻¹, q⁻², …` ("monic": the first is
//! 1; "stable": the roots of `zᵈ + p_1 zᵈ⁻¹ + … + p_d` inside the unit circle).
//!
//! ```toml
//! [controller]
//! kind = "appc"
//! n = 2                           # the plant order (the degree of D, (4.3)), 1 to 64
//! d-m = [1.0, -0.5]               # D_m (4.6): the desired closed-loop poles, monic, stable
//! n-m = [0.0, 0.5]                # N_m (4.5): the reference model's numerator
//! h = [1.0]                       # H (4.13): monic, stable (default [1.0])
//! r-theta = 1e-5                  # diagonal of R_θ (4.42): scalar or 4n values (default 1e-5)
//! theta0 = [...]                  # optional θ̂_0, 4n values (default 0)
//! lambda = 1.0                    # constant forgetting (default 1), or [controller.forgetting]
//! trace-limit = 1e12              # tr(R_θ^½ P R_θ^½) above this resets θ̂, P (default: none)
//! u-min = -10.0                   # optional saturation
//! u-max = 10.0
//!
//! [controller]
//! kind = "rc-mrac"
//! n = 2
//! relative-degree = 1             # n_r (4.2)
//! leading-coefficient = 1.0       # N_{n_r} (4.46)
//! n-u = [1.0]                     # N_u (4.46): the known NMP zeros, monic, roots |z| ≥ 1
//! n-s = 1                         # the degree of the unknown minimum-phase factor N_s
//! f = [1.0]                       # F (4.49): monic, stable (default [1.0])
//! d-m = [1.0, -0.5]
//! n-m = [0.0, 0.5]                # of the form (4.57): N_{n_r} N_u R_c* q^{−n_r}
//! r-theta = 1e-5                  # scalar or 2n + n_s + 1 values
//! # theta0, lambda / [controller.forgetting], trace-limit, u-min, u-max as for APPC
//! ```

use super::bounds::{MAX_MRAC_ORDER, MAX_THETA0};
use super::controller::{ControllerConfig, Rig, output_limits, param_error};
use super::forgetting::{RawForgetting, forgetting_rule};
use super::values::{ScalarOrVec, count, magnitudes, per_channel};
use super::{ConfigError, ErrFn};
use control::mrac::{AppcParams, RcMracParams};
use serde::Deserialize;

/// The table of either kind as read: the fields of both; each kind refuses the fields
/// that are only the other's ([`RawMrac::refuse_others`]).
#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawMrac {
    #[allow(dead_code)]
    kind: String,
    n: Option<u64>,
    d_m: Option<Vec<f64>>,
    n_m: Option<Vec<f64>>,
    r_theta: Option<ScalarOrVec>,
    theta0: Option<Vec<f64>>,
    lambda: Option<f64>,
    forgetting: Option<RawForgetting>,
    trace_limit: Option<f64>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    /// APPC's only.
    h: Option<Vec<f64>>,
    /// RC-MRAC's only, as the next four.
    relative_degree: Option<u64>,
    leading_coefficient: Option<f64>,
    n_u: Option<Vec<f64>>,
    n_s: Option<u64>,
    f: Option<Vec<f64>>,
}

impl RawMrac {
    /// Refuses the first of `fields` (name, given) that the table gives: a field of the
    /// kind `other`, not of this one.
    fn refuse_others(
        fields: &[(&str, bool)],
        other: &str,
        err: &ErrFn<'_>,
    ) -> Result<(), ConfigError> {
        match fields.iter().find(|(_, given)| *given) {
            Some((name, _)) => Err(err(
                &format!("controller.{name}"),
                format!("is a field of kind = \"{other}\", not of this kind"),
            )),
            None => Ok(()),
        }
    }
}

/// The estimator and saturation fields, read for `theta_len` coefficients.
struct Common {
    r_theta: Vec<f64>,
    theta0: Option<Vec<f64>>,
    rule: super::forgetting::ReadRule,
    trace_limit: f64,
    limits: Option<control::OutputLimits>,
}

fn common(
    raw: &RawMrac,
    theta_len: usize,
    default_r_theta: f64,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<Common, ConfigError> {
    if let Some(theta0) = &raw.theta0 {
        magnitudes(theta0, MAX_THETA0, "controller.theta0", err)?;
    }
    Ok(Common {
        r_theta: per_channel(
            &raw.r_theta,
            theta_len,
            default_r_theta,
            "controller.r-theta",
            err,
        )?,
        theta0: raw.theta0.clone(),
        rule: forgetting_rule(raw.lambda, raw.forgetting.as_ref(), "controller", err)?,
        trace_limit: raw.trace_limit.unwrap_or(f64::INFINITY),
        limits: output_limits(&raw.u_min, &raw.u_max, rig.counts.n_u as usize, err)?,
    })
}

fn order(n: Option<u64>, err: &ErrFn<'_>) -> Result<usize, ConfigError> {
    let n = n.ok_or_else(|| err("controller.n", "missing (the plant order n)".into()))?;
    Ok(count(n, 1, MAX_MRAC_ORDER, "controller.n", err)? as usize)
}

fn polynomial(
    v: Option<Vec<f64>>,
    field: &str,
    what: &str,
    err: &ErrFn<'_>,
) -> Result<Vec<f64>, ConfigError> {
    let v = v.ok_or_else(|| err(field, format!("missing ({what})")))?;
    if v.len() > MAX_MRAC_ORDER as usize + 1 {
        return Err(err(
            field,
            format!(
                "{} coefficients; at most {} (degree {MAX_MRAC_ORDER})",
                v.len(),
                MAX_MRAC_ORDER + 1
            ),
        ));
    }
    Ok(v)
}

/// `D_m` and `N_m` of the reference model (4.4), both required.
fn reference_model(
    d_m: Option<Vec<f64>>,
    n_m: Option<Vec<f64>>,
    err: &ErrFn<'_>,
) -> Result<(Vec<f64>, Vec<f64>), ConfigError> {
    Ok((
        polynomial(
            d_m,
            "controller.d-m",
            "D_m, the reference model's poles",
            err,
        )?,
        polynomial(
            n_m,
            "controller.n-m",
            "N_m, the reference model's numerator",
            err,
        )?,
    ))
}

/// Reads `kind = "appc"` into [`AppcParams`] and validates them for the rig's channels.
pub(super) fn parse_appc(
    raw: RawMrac,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    RawMrac::refuse_others(
        &[
            ("relative-degree", raw.relative_degree.is_some()),
            ("leading-coefficient", raw.leading_coefficient.is_some()),
            ("n-u", raw.n_u.is_some()),
            ("n-s", raw.n_s.is_some()),
            ("f", raw.f.is_some()),
        ],
        "rc-mrac",
        err,
    )?;
    let n = order(raw.n, err)?;
    let (d_m, n_m) = reference_model(raw.d_m.clone(), raw.n_m.clone(), err)?;
    let h = polynomial(raw.h.clone().or(Some(vec![1.0])), "controller.h", "H", err)?;
    let c = common(
        &raw,
        AppcParams::theta_len(n),
        AppcParams::DEFAULT_R_THETA,
        rig,
        err,
    )?;
    let params = AppcParams {
        theta0: c.theta0,
        r_theta: c.r_theta,
        forgetting: c.rule.rule.clone(),
        trace_limit: c.trace_limit,
        limits: c.limits,
        ..AppcParams::new(n, d_m, n_m, h)
    };
    let config = ControllerConfig::Appc {
        params: Box::new(params),
    };
    config
        .validate(rig.counts)
        .map_err(|e| param_error(c.rule.locate(e), err))?;
    Ok(config)
}

/// Reads `kind = "rc-mrac"` into [`RcMracParams`] and validates them for the rig's
/// channels.
pub(super) fn parse_rc_mrac(
    raw: RawMrac,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    RawMrac::refuse_others(&[("h", raw.h.is_some())], "appc", err)?;
    let n = order(raw.n, err)?;
    let n_r = raw.relative_degree.ok_or_else(|| {
        err(
            "controller.relative-degree",
            "missing (the plant's relative degree n_r)".into(),
        )
    })?;
    let n_r = count(n_r, 1, n as u64, "controller.relative-degree", err)? as usize;
    let leading = raw.leading_coefficient.ok_or_else(|| {
        err(
            "controller.leading-coefficient",
            "missing (N_{n_r}, the plant's leading numerator coefficient)".into(),
        )
    })?;
    let n_s = raw.n_s.ok_or_else(|| {
        err(
            "controller.n-s",
            "missing (the degree of the unknown minimum-phase numerator factor N_s)".into(),
        )
    })?;
    let n_s = count(n_s, 0, n as u64, "controller.n-s", err)? as usize;
    let n_u = polynomial(
        raw.n_u.clone().or(Some(vec![1.0])),
        "controller.n-u",
        "N_u",
        err,
    )?;
    let f = polynomial(raw.f.clone().or(Some(vec![1.0])), "controller.f", "F", err)?;
    let (d_m, n_m) = reference_model(raw.d_m.clone(), raw.n_m.clone(), err)?;
    let c = common(
        &raw,
        RcMracParams::theta_len(n, n_s),
        RcMracParams::DEFAULT_R_THETA,
        rig,
        err,
    )?;
    let params = RcMracParams {
        theta0: c.theta0,
        r_theta: c.r_theta,
        forgetting: c.rule.rule.clone(),
        trace_limit: c.trace_limit,
        limits: c.limits,
        ..RcMracParams::new(n, n_r, leading, n_u, n_s, f, d_m, n_m)
    };
    let config = ControllerConfig::RcMrac {
        params: Box::new(params),
    };
    config
        .validate(rig.counts)
        .map_err(|e| param_error(c.rule.locate(e), err))?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::super::ServiceConfig;
    use super::super::refusal_cases::assert_refused_naming_fields;
    use super::ControllerConfig;

    const RIG: &str = include_str!("../../../tests/fixtures/config/mrac-rig.toml");
    const APPC: &str = include_str!("../../../scenarios/mrac/appc.toml");
    const RC_MRAC: &str = include_str!("../../../scenarios/mrac/rc-mrac.toml");

    fn file(controller: &str) -> String {
        format!("{RIG}\n{controller}")
    }

    #[test]
    fn the_chapter_4_controllers_read_into_their_kernel_parameters() {
        let c = ServiceConfig::parse(&file(APPC), "appc.toml").unwrap();
        let ControllerConfig::Appc { params } = &c.controller else {
            panic!("{:?}", c.controller)
        };
        assert_eq!((params.n, params.h.as_slice()), (2, &[1.0, 0.0, -0.25][..]));
        assert_eq!(params.r_theta, vec![1e-5; 8]);
        assert!(!c.controller.answers_ahead());

        let c = ServiceConfig::parse(&file(RC_MRAC), "rc-mrac.toml").unwrap();
        let ControllerConfig::RcMrac { params } = &c.controller else {
            panic!("{:?}", c.controller)
        };
        assert_eq!((params.n, params.n_s, params.relative_degree), (2, 1, 1));
        assert_eq!(params.f, vec![1.0, 0.5]);
        assert_eq!(params.r_theta.len(), 2 * 2 + 1 + 1);
        assert_eq!(c.controller.kind_name(), "rc-mrac");
    }

    #[test]
    fn what_the_methods_cannot_take_is_refused_naming_the_field() {
        assert_refused_naming_fields(
            &file(RC_MRAC),
            "bad.toml",
            include_str!("../../../tests/fixtures/refusals/controller-rc-mrac.toml"),
        );
        assert_refused_naming_fields(
            &file(APPC),
            "bad.toml",
            include_str!("../../../tests/fixtures/refusals/controller-appc.toml"),
        );
        // The rig must carry the command: without r the kernels refuse the channels.
        let no_r = file(APPC).replace("r = 1, ", "");
        let m = ServiceConfig::parse(&no_r, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(m.contains("channels"), "{m}");
    }
}
