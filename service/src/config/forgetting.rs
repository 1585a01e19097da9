//! The recursive-least-squares settings RCAC (`update = "rls"`) and PCAC share: `p0` and
//! the forgetting ([`ForgettingRule`]).
//!
//! ```toml
//! [controller]
//! p0 = 1.0                        # P_0 = p0 I, required, positive and finite
//! lambda = 0.999                  # constant forgetting λ ∈ (0, 1] (default 1), or a table:
//! [controller.forgetting]
//! rule = "f-test"                 # Algorithm 1, (5.1)–(5.7): tau-n, tau-d, eta, alpha
//! tau-n = 40                      # short window τn ≥ p
//! tau-d = 200                     # long window τd > τn (F-test with p > 1: τd > p + 3)
//! eta = 0.1                       # forgetting gain η > 0
//! alpha = 0.001                   # significance level α ∈ (0, 1)
//! # rule = "rms-ratio"            # Proposition 5.2.1: tau-n, tau-d, eta
//! # rule = "constant"             # lambda
//! ```
//!
//! `lambda` and `[controller.forgetting]` exclude each other; a field of the table that its
//! rule does not read is refused (for example `lambda` under `rule = "f-test"`), and the
//! windows are at most 10⁶ samples.

use super::bounds::MAX_FORGETTING_WINDOW;
use super::values::{count, refuse_given};
use super::{ConfigError, ErrFn};
use control::ParamError;
use control::forgetting::ForgettingRule;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawForgetting {
    rule: String,
    lambda: Option<f64>,
    tau_n: Option<usize>,
    tau_d: Option<usize>,
    eta: Option<f64>,
    alpha: Option<f64>,
}

/// `p0` of `P_0 = p0 I` in the table at `table` (`"controller"`, `"controller.pcac"`):
/// required (`when` says for which setting); the kernel checks that it is positive and
/// finite.
pub(super) fn required_p0(
    p0: Option<f64>,
    table: &str,
    when: &str,
    err: &ErrFn<'_>,
) -> Result<f64, ConfigError> {
    p0.ok_or_else(|| {
        err(
            &format!("{table}.p0"),
            format!("missing (P_0 = p0 I) {when}"),
        )
    })
}

/// The forgetting rule as read, and where: from `lambda` or from the table.
pub(super) struct ReadRule {
    /// The rule.
    pub rule: ForgettingRule,
    /// It came from the `lambda` field, not from `[controller.forgetting]`.
    from_lambda: bool,
}

impl ReadRule {
    /// The kernel names the constant rule's factor `forgetting.lambda`, the field of the
    /// table; when the file gave it as `lambda`, the error names `lambda`.
    pub fn locate(&self, e: ParamError) -> ParamError {
        if self.from_lambda && e.field == "forgetting.lambda" {
            ParamError {
                field: "lambda",
                ..e
            }
        } else {
            e
        }
    }
}

/// The forgetting of an RLS in the table at `at` (`"controller"`, `"controller.pcac"`):
/// `lambda` (constant, default [`ForgettingRule::DEFAULT`]) or a `[<at>.forgetting]`
/// table, not both. The values are the kernel's to check.
pub(super) fn forgetting_rule(
    lambda: Option<f64>,
    table: Option<&RawForgetting>,
    at: &str,
    err: &ErrFn<'_>,
) -> Result<ReadRule, ConfigError> {
    match (lambda, table) {
        (Some(_), Some(_)) => Err(err(
            &format!("{at}.lambda"),
            format!("give lambda or [{at}.forgetting], not both"),
        )),
        (Some(lambda), None) => Ok(ReadRule {
            rule: ForgettingRule::Constant { lambda },
            from_lambda: true,
        }),
        (None, None) => Ok(ReadRule {
            rule: ForgettingRule::DEFAULT,
            from_lambda: false,
        }),
        (None, Some(f)) => Ok(ReadRule {
            rule: parse_table(f, &format!("{at}.forgetting"), err)?,
            from_lambda: false,
        }),
    }
}

/// The forgetting table at `table` (`controller.forgetting`): the rule and the fields it
/// needs; a field the rule does not read is refused, and the windows are at most
/// [`MAX_FORGETTING_WINDOW`].
fn parse_table(
    f: &RawForgetting,
    table: &str,
    err: &ErrFn<'_>,
) -> Result<ForgettingRule, ConfigError> {
    let missing = |name: &str| {
        err(
            &format!("{table}.{name}"),
            format!("missing for rule = \"{}\"", f.rule),
        )
    };
    let need = |v: Option<f64>, name: &str| v.ok_or_else(|| missing(name));
    let need_n = |v: Option<usize>, name: &str| -> Result<usize, ConfigError> {
        let n = v.ok_or_else(|| missing(name))?;
        let field = format!("{table}.{name}");
        Ok(count(n as u64, 0, MAX_FORGETTING_WINDOW, &field, err)? as usize)
    };
    let not_read = |fields: &[(bool, &str)]| {
        let why = format!("not read by rule = \"{}\"", f.rule);
        refuse_given(fields, table, &why, err)
    };
    let lambda = (f.lambda.is_some(), "lambda");
    let windows = [(f.tau_n.is_some(), "tau-n"), (f.tau_d.is_some(), "tau-d")];
    let eta = (f.eta.is_some(), "eta");
    let alpha = (f.alpha.is_some(), "alpha");
    match f.rule.as_str() {
        "constant" => {
            not_read(&[windows[0], windows[1], eta, alpha])?;
            Ok(ForgettingRule::Constant {
                lambda: need(f.lambda, "lambda")?,
            })
        }
        "f-test" => {
            not_read(&[lambda])?;
            Ok(ForgettingRule::FTest {
                tau_n: need_n(f.tau_n, "tau-n")?,
                tau_d: need_n(f.tau_d, "tau-d")?,
                eta: need(f.eta, "eta")?,
                alpha: need(f.alpha, "alpha")?,
            })
        }
        "rms-ratio" => {
            not_read(&[lambda, alpha])?;
            Ok(ForgettingRule::RmsRatio {
                tau_n: need_n(f.tau_n, "tau-n")?,
                tau_d: need_n(f.tau_d, "tau-d")?,
                eta: need(f.eta, "eta")?,
            })
        }
        other => Err(err(
            &format!("{table}.rule"),
            format!("'{other}' is not one of constant, f-test, rms-ratio"),
        )),
    }
}
