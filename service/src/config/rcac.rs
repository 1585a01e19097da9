//! `kind = "rcac"`: retrospective cost adaptive control ([`Rcac`](control::Rcac),
//! (2.15)–(2.23), (3.51)–(3.63)).
//!
//! ```toml
//! [controller]
//! kind = "rcac"
//! update = "rls"                  # or "gradient"
//! input = "y"                     # the only input RCAC takes
//! nc = 50                         # controller order n_c (1 to 1000; with update = "rls",
//!                                 # l_θ = l_u nc (l_u + l_y) at most 4096)
//! kw = 100                        # u = 0, no update for the first kw steps (default: nc plus
//!                                 # the largest lag of G_f)
//! rz = 1.0                        # R_z: scalar (times I) or l_z×l_z matrix, positive definite
//! ru = 0.0                        # R_u: scalar or l_u×l_u matrix, ≥ 0 (default 0)
//! theta0 = [0.0, 0.0]             # optional, l_θ = l_u nc (l_u + l_y) values (default 0),
//!                                 # each within ±10⁶
//! u-min = -1.0                    # optional saturation, scalar or per input
//! u-max = 1.0
//! gap-rule = "resume-plan"       # lost samples: "resume-plan" (default), "resume-hold" or
//!                                 # "suspend" (the original rule), see below
//! gap-pause = 50                  # steps without an update after a gap, 0 to L (resume-*
//!                                 # only; default nc)
//! target-model-file = "target-model.toml"   # relative to this file's folder, or inline:
//! # [controller.target-model] with the fields of control::target (form, sample-period, …)
//!
//! # update = "rls" (the forgetting module lists p0, lambda, [controller.forgetting]):
//! p0 = 1.0                        # P_0 = p0 I (R_θ = I / p0), required
//! lambda = 0.999                  # constant forgetting (default 1), or [controller.forgetting]
//! trace-limit = 1e9               # tr P above this resets θ, P (default 10⁶ l_θ p0)
//!
//! # update = "gradient":
//! # step-size = "exp"             # "opt" (3.57), "sigma" (3.60), "frobenius" (3.61), "exp" (3.63)
//! # alpha = 0.5                   # in (0, 1], required
//! # r = 0.0                       # R = r I ≥ 0 (default 0)
//! ```
//!
//! The target model must have `l_z` outputs and `l_u` inputs and the rig's sample period.
//!
//! `gap-rule` says what RCAC does with samples that never reached the service
//! ([`GapRule`], module docs of `control::rcac`, "Imperfect loops"; measured in
//! docs/results/gap-rule.md):
//!
//! - `"resume-plan"` (the default): the lost samples are bridged by the plan (`y` predicted
//!   at 0, `u` the controller run on with `θ` held: what a plant with the plan late policy
//!   applied), and the update resumes `gap-pause` steps after the gap;
//! - `"resume-hold"`: bridged by the held `y` and `u`, resumed after `gap-pause` steps;
//! - `"suspend"`: bridged by the held `y` and `u`, the update suspended for the history
//!   length `L` (largest lag of `G_f` plus `n_c`) after every gap, the original rule.

use super::bounds::{MAX_RCAC_NC, MAX_RCAC_RLS_THETA, MAX_THETA0, max_cycles};
use super::controller::{ControllerConfig, Rig, output_limits, param_error};
use super::forgetting::{RawForgetting, forgetting_rule, required_p0};
use super::target_model_file::read_table;
use super::values::{ScalarOrMatrix, ScalarOrVec, count, magnitudes, one_of, refuse_given, weight};
use super::{ConfigError, ErrFn, TargetModelFile};
use control::target::TargetModel;
use control::{GapBridge, GapRule, RcacParams, RcacUpdate, StepSize};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawRcac {
    #[allow(dead_code)]
    kind: String,
    update: Option<String>,
    input: Option<String>,
    nc: Option<usize>,
    kw: Option<usize>,
    target_model: Option<toml::Value>,
    target_model_file: Option<String>,
    rz: Option<ScalarOrMatrix>,
    ru: Option<ScalarOrMatrix>,
    theta0: Option<Vec<f64>>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    p0: Option<f64>,
    lambda: Option<f64>,
    forgetting: Option<RawForgetting>,
    trace_limit: Option<f64>,
    step_size: Option<String>,
    alpha: Option<f64>,
    r: Option<f64>,
    gap_rule: Option<String>,
    gap_pause: Option<usize>,
}

/// Reads the table into [`RcacParams`] and validates them (the controller is built later,
/// once, by the runtime).
pub(super) fn parse(
    raw: RawRcac,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let counts = rig.counts;
    let period = rig.period;
    let base_dir = rig.base_dir;
    let dims = crate::wire::dimensions(counts);
    let (n_z, n_u) = (dims.n_z, dims.n_u);
    match raw.input.as_deref().unwrap_or("y") {
        "y" => {}
        other => {
            return Err(err(
                "controller.input",
                format!("'{other}': RCAC takes input = \"y\" only"),
            ));
        }
    }
    let nc = raw
        .nc
        .ok_or_else(|| err("controller.nc", "missing (the controller order n_c)".into()))?;
    let nc = count(nc as u64, 0, MAX_RCAC_NC, "controller.nc", err)? as usize;
    if let Some(kw) = raw.kw {
        count(kw as u64, 0, max_cycles(period), "controller.kw", err)?;
    }
    if let Some(theta0) = &raw.theta0 {
        magnitudes(theta0, MAX_THETA0, "controller.theta0", err)?;
    }
    let target = target_model(raw.target_model, raw.target_model_file, base_dir, err)?;
    let rz = weight(&raw.rz, n_z, RcacParams::DEFAULT_RZ, "controller.rz", err)?;
    let ru = weight(&raw.ru, n_u, RcacParams::DEFAULT_RU, "controller.ru", err)?;
    let update = one_of(
        raw.update.as_deref(),
        Update::Rls,
        &[("rls", Update::Rls), ("gradient", Update::Gradient)],
        "controller.update",
        err,
    )?;
    let mut rule = None;
    let update = match update {
        Update::Rls => {
            only_for(
                &[
                    (raw.step_size.is_some(), "step-size"),
                    (raw.alpha.is_some(), "alpha"),
                    (raw.r.is_some(), "r"),
                ],
                "gradient",
                err,
            )?;
            let ltheta = RcacParams::theta_len(nc, dims);
            if ltheta > MAX_RCAC_RLS_THETA {
                return Err(err(
                    "controller.nc",
                    format!(
                        "{nc} gives l_θ = l_u n_c (l_u + l_y) = {ltheta} coefficients; with \
                         update = \"rls\" (an l_θ × l_θ covariance) at most \
                         {MAX_RCAC_RLS_THETA}"
                    ),
                ));
            }
            let p0 = required_p0(raw.p0, "controller", "for update = \"rls\"", err)?;
            let read = forgetting_rule(raw.lambda, raw.forgetting.as_ref(), "controller", err)?;
            let update = RcacUpdate::Rls {
                p0,
                rule: read.rule.clone(),
                trace_limit: raw
                    .trace_limit
                    .unwrap_or_else(|| RcacParams::default_trace_limit(nc, dims, p0)),
            };
            rule = Some(read);
            update
        }
        Update::Gradient => {
            only_for(
                &[
                    (raw.p0.is_some(), "p0"),
                    (raw.lambda.is_some(), "lambda"),
                    (raw.forgetting.is_some(), "forgetting"),
                    (raw.trace_limit.is_some(), "trace-limit"),
                ],
                "rls",
                err,
            )?;
            RcacUpdate::Gradient {
                step_size: one_of(
                    raw.step_size.as_deref(),
                    RcacParams::DEFAULT_STEP_SIZE,
                    &[
                        ("opt", StepSize::Opt),
                        ("sigma", StepSize::Sigma),
                        ("frobenius", StepSize::Frobenius),
                        ("exp", StepSize::Exp),
                    ],
                    "controller.step-size",
                    err,
                )?,
                alpha: raw.alpha.ok_or_else(|| {
                    err(
                        "controller.alpha",
                        "missing (the step-size factor α ∈ (0, 1])".into(),
                    )
                })?,
                r: raw.r.unwrap_or(RcacParams::DEFAULT_GRADIENT_R),
            }
        }
    };
    let gap_rule = gap_rule(raw.gap_rule.as_deref(), raw.gap_pause, err)?;
    let params = RcacParams {
        nc,
        kw: raw.kw,
        target,
        rz,
        ru,
        theta0: raw.theta0,
        update,
        limits: output_limits(&raw.u_min, &raw.u_max, n_u, err)?,
        sample_period: period,
        gap_rule,
    };
    params.validate(dims).map_err(|e| {
        let e = match &rule {
            Some(read) => read.locate(e),
            None => e,
        };
        param_error(e, err)
    })?;
    Ok(ControllerConfig::Rcac {
        params: Box::new(params),
    })
}

/// `gap-rule` and `gap-pause` (module docs); the pause's upper bound, the history length,
/// is checked by [`RcacParams::validate`] (field `gap-pause`).
fn gap_rule(
    rule: Option<&str>,
    pause: Option<usize>,
    err: &ErrFn<'_>,
) -> Result<GapRule, ConfigError> {
    #[derive(Clone, Copy)]
    enum Rule {
        Suspend,
        Resume(GapBridge),
    }
    let default = match RcacParams::DEFAULT_GAP_RULE {
        GapRule::Suspend => Rule::Suspend,
        GapRule::Resume { bridge, .. } => Rule::Resume(bridge),
    };
    let rule = one_of(
        rule,
        default,
        &[
            ("resume-plan", Rule::Resume(GapBridge::Plan)),
            ("resume-hold", Rule::Resume(GapBridge::Hold)),
            ("suspend", Rule::Suspend),
        ],
        "controller.gap-rule",
        err,
    )?;
    match rule {
        Rule::Suspend => {
            refuse_given(
                &[(pause.is_some(), "gap-pause")],
                "controller",
                "only for gap-rule = \"resume-plan\" or \"resume-hold\" (\"suspend\" pauses \
                 the history length)",
                err,
            )?;
            Ok(GapRule::Suspend)
        }
        Rule::Resume(bridge) => Ok(GapRule::Resume { bridge, pause }),
    }
}

/// The update laws, as `update` names them.
#[derive(Clone, Copy)]
enum Update {
    Rls,
    Gradient,
}

/// Refuses the fields of the other update law (`(given, name)` pairs) that are given.
fn only_for(fields: &[(bool, &str)], law: &str, err: &ErrFn<'_>) -> Result<(), ConfigError> {
    refuse_given(
        fields,
        "controller",
        &format!("only for update = \"{law}\""),
        err,
    )
}

/// The target model: inline (`[controller.target-model]`) or from `target-model-file`
/// (relative to `base_dir`), exactly one of the two.
fn target_model(
    inline: Option<toml::Value>,
    file: Option<String>,
    base_dir: &Path,
    err: &ErrFn<'_>,
) -> Result<TargetModel, ConfigError> {
    match (inline, file) {
        (Some(v), None) => {
            read_table(v).map_err(|e| err(&format!("controller.{}", e.field), e.message))
        }
        (None, Some(f)) => {
            let p = Path::new(&f);
            let path = if p.is_relative() {
                base_dir.join(p)
            } else {
                p.to_path_buf()
            };
            if !path.is_file() {
                return Err(err(
                    "controller.target-model-file",
                    format!(
                        "'{f}' resolves to {}, which is not a readable file",
                        path.display()
                    ),
                ));
            }
            TargetModel::load(&path).map_err(|m| err("controller.target-model-file", m))
        }
        (Some(_), Some(_)) => Err(err(
            "controller.target-model",
            "give [controller.target-model] or target-model-file, not both".into(),
        )),
        (None, None) => Err(err(
            "controller.target-model",
            "missing: give [controller.target-model] or target-model-file".into(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ServiceConfig;
    use crate::config::refusal_cases::assert_refused_naming_fields;
    use control::forgetting::ForgettingRule;
    use nalgebra::DMatrix;

    const GOOD: &str = include_str!("../../../tests/fixtures/config/lti-static-gain.toml");
    const RCAC: &str = include_str!("../../../tests/fixtures/config/rcac-inline-target-model.toml");

    #[test]
    fn an_rcac_controller_is_read_with_an_inline_target_model_and_built() {
        let c = ServiceConfig::parse(RCAC, "rcac.toml").unwrap();
        let ControllerConfig::Rcac { params } = &c.controller else {
            panic!("not rcac: {:?}", c.controller);
        };
        assert_eq!(params.nc, 4);
        assert_eq!(params.target.inputs, 2);
        assert_eq!(
            params.update,
            RcacUpdate::Rls {
                p0: 10.0,
                rule: ForgettingRule::Constant { lambda: 0.999 },
                trace_limit: 1e6 * 24.0 * 10.0,
            }
        );
        let ctl = c.controller.build(c.counts).unwrap();
        assert_eq!(ctl.kind(), "rcac");
        assert_eq!(ctl.internal_names().len(), 7);
        // The gradient variant, and the forgetting table.
        let g = RCAC
            .replace("update = \"rls\"", "update = \"gradient\"")
            .replace(
                "p0 = 10.0\n",
                "step-size = \"sigma\"\nalpha = 0.3\nr = 0.01\n",
            )
            .replace("lambda = 0.999\n", "");
        let c = ServiceConfig::parse(&g, "rcac.toml").unwrap();
        let ControllerConfig::Rcac { params } = &c.controller else {
            panic!()
        };
        assert_eq!(
            params.update,
            RcacUpdate::Gradient {
                step_size: StepSize::Sigma,
                alpha: 0.3,
                r: 0.01
            }
        );
        let f = RCAC.replace(
            "lambda = 0.999",
            "[controller.forgetting]\nrule = \"f-test\"\ntau-n = 10\ntau-d = 80\neta = 0.5\nalpha = 0.01",
        );
        let c = ServiceConfig::parse(&f, "rcac.toml");
        assert!(c.is_ok(), "{c:?}");
    }

    #[test]
    fn a_target_model_file_is_found_next_to_the_scenario() {
        let dir = std::env::temp_dir().join(format!("rcac-config-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let (head, tm) = RCAC.split_once("[controller.target-model]").unwrap();
        let tm = format!(
            "[target-model]{}",
            tm.replace("controller.target-model.", "target-model.")
        );
        std::fs::write(dir.join("sub/tm.toml"), tm).unwrap();
        let text = head.replace(
            "kind = \"rcac\"",
            "kind = \"rcac\"\ntarget-model-file = \"sub/tm.toml\"",
        );
        let origin = dir.join("scenario.toml").display().to_string();
        let c = ServiceConfig::parse(&text, &origin).unwrap();
        assert!(matches!(c.controller, ControllerConfig::Rcac { .. }));
        // A controller file elsewhere: relative to its own folder.
        std::fs::write(
            dir.join("scenario.toml"),
            GOOD.replace("u = 1", "u = 2").replace("0.001", "0.01"),
        )
        .unwrap();
        std::fs::write(
            dir.join("sub/ctl.toml"),
            text.split_once("[controller]")
                .unwrap()
                .1
                .replace("sub/tm.toml", "tm.toml")
                .replace("kind", "[controller]\nkind"),
        )
        .unwrap();
        let c = ServiceConfig::load_with_controller(
            &dir.join("scenario.toml"),
            &dir.join("sub/ctl.toml"),
        );
        assert!(
            matches!(
                c,
                Ok(ServiceConfig {
                    controller: ControllerConfig::Rcac { .. },
                    ..
                })
            ),
            "{c:?}"
        );
        // A Markov (FIR) model as the design tools write it (TargetModel::save), as is.
        let fir = TargetModel {
            sample_period: 0.01,
            outputs: 1,
            inputs: 2,
            beta: 0.9,
            source: "rig-design markov".into(),
            form: control::target::TargetForm::Markov(vec![
                DMatrix::zeros(1, 2),
                DMatrix::from_row_slice(1, 2, &[0.05, 0.0]),
                DMatrix::from_row_slice(1, 2, &[0.0, -0.02]),
            ]),
        };
        fir.save(&dir.join("sub/fir.toml")).unwrap();
        let c = ServiceConfig::parse(&text.replace("sub/tm.toml", "sub/fir.toml"), &origin);
        assert!(
            matches!(&c, Ok(ServiceConfig { controller: ControllerConfig::Rcac { params }, .. })
                if params.target == fir),
            "{c:?}"
        );
        // Not there: the field is named.
        let m = ServiceConfig::parse(&text.replace("sub/tm.toml", "nope.toml"), &origin)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("field 'controller.target-model-file'") && m.contains("nope.toml"),
            "{m}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_rcac_settings_are_refused_naming_file_and_field() {
        let cases = include_str!("../../../tests/fixtures/refusals/controller-rcac.toml");
        assert_refused_naming_fields(RCAC, "bad.toml", cases);
        let grad = RCAC
            .replace("update = \"rls\"", "update = \"gradient\"")
            .replace("p0 = 10.0\n", "alpha = 0.5\n")
            .replace("lambda = 0.999\n", "");
        let cases = include_str!("../../../tests/fixtures/refusals/controller-rcac-gradient.toml");
        assert_refused_naming_fields(&grad, "bad.toml", cases);
    }

    #[test]
    fn the_gradient_updates_alpha_is_offered_to_the_operator_within_its_declared_bounds() {
        let grad = RCAC
            .replace("update = \"rls\"", "update = \"gradient\"")
            .replace("p0 = 10.0\n", "alpha = 0.5\n")
            .replace("lambda = 0.999\n", "")
            .replace(
                "channels = { y = 1, z = 1, u = 2 }",
                "channels = { y = 1, z = 1, u = 2 }\n[service.operator]\n\
                 tunables = { alpha = [0.1, 0.9] }",
            );
        let c = ServiceConfig::parse(&grad, "g.toml").unwrap();
        assert_eq!(
            c.live.tunables,
            vec![crate::config::DeclaredTunable {
                name: "alpha".into(),
                index: 0,
                min: 0.1,
                max: 0.9,
                initial: 0.5,
            }]
        );
        assert!(c.live.commands && c.live.telemetry);
    }

    #[test]
    fn a_forgetting_factor_is_named_where_the_file_gives_it() {
        let field_of = |text: &str| {
            ServiceConfig::parse(text, "bad.toml")
                .expect_err("must be refused")
                .field
        };
        assert_eq!(
            field_of(&RCAC.replace("lambda = 0.999", "lambda = 1.5")),
            "controller.lambda"
        );
        assert_eq!(
            field_of(&RCAC.replace(
                "lambda = 0.999",
                "[controller.forgetting]\nrule = \"constant\"\nlambda = 1.5"
            )),
            "controller.forgetting.lambda"
        );
        assert_eq!(
            field_of(&RCAC.replace(
                "lambda = 0.999",
                "[controller.forgetting]\nrule = \"f-test\"\ntau-n = 10\ntau-d = 80\neta = 0.0\nalpha = 0.01"
            )),
            "controller.forgetting.eta"
        );
    }

    #[test]
    fn the_defaults_come_from_the_kernel() {
        let c = ServiceConfig::parse(&RCAC.replace("lambda = 0.999\n", ""), "rcac.toml").unwrap();
        let ControllerConfig::Rcac { params } = &c.controller else {
            panic!("not rcac: {:?}", c.controller);
        };
        let dims = crate::wire::dimensions(c.counts);
        assert_eq!(
            params.update,
            RcacUpdate::Rls {
                p0: 10.0,
                rule: ForgettingRule::DEFAULT,
                trace_limit: RcacParams::default_trace_limit(4, dims, 10.0),
            }
        );
        assert_eq!(params.rz, DMatrix::identity(1, 1) * RcacParams::DEFAULT_RZ);
        assert_eq!(params.kw, None);
        assert_eq!(params.gap_rule, RcacParams::DEFAULT_GAP_RULE);
        assert_eq!(c.controller.validate(c.counts), Ok(()));
    }

    #[test]
    fn the_gap_rule_is_read_and_checked() {
        let rule_of = |extra: &str| {
            let text = RCAC.replace("nc = 4", &format!("nc = 4\n{extra}"));
            let c = ServiceConfig::parse(&text, "rcac.toml").unwrap();
            let ControllerConfig::Rcac { params } = c.controller else {
                panic!("not rcac");
            };
            params.gap_rule
        };
        assert_eq!(rule_of("gap-rule = \"suspend\""), GapRule::Suspend);
        assert_eq!(
            rule_of("gap-rule = \"resume-hold\"\ngap-pause = 3"),
            GapRule::Resume {
                bridge: GapBridge::Hold,
                pause: Some(3)
            }
        );
        assert_eq!(
            rule_of("gap-rule = \"resume-plan\""),
            GapRule::Resume {
                bridge: GapBridge::Plan,
                pause: None
            }
        );
        let cases = include_str!("../../../tests/fixtures/refusals/controller-rcac-gap-rule.toml");
        assert_refused_naming_fields(RCAC, "bad.toml", cases);
    }
}
