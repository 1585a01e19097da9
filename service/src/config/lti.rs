//! `kind = "lti"`: a discrete-time LTI controller ([`LtiController`](control::LtiController)).
//!
//! ```toml
//! [controller]
//! kind = "lti"
//! input = "y"                     # "y", "error" (r − y) or "y-and-r"
//! u-min = -1.0                    # optional saturation, scalar or per input
//! u-max = 1.0
//! [controller.ss]                 # discrete state space (rows of each matrix) …
//! a = [[0.5]]                     # n × n (no rows: a static gain, n = 0)
//! b = [[1.0]]                     # n × n_e
//! c = [[-0.2]]                    # n_u × n (may be omitted when n = 0)
//! d = [[0.0]]                     # n_u × n_e
//! x0 = [0.0]                      # optional initial state
//! # … or, not both:
//! # [controller.tf]               # discrete transfer functions in z, n_u × n_e
//! # entries = [[{ num = [0.1], den = [1.0, -0.9] }, 0]]   # 0: no path
//! ```
//!
//! `n_e` is the number of controller inputs: `n_y`, or `n_y + n_r` for `"y-and-r"`. The
//! controller has at most 1000 states.

use super::bounds::MAX_LTI_STATES;
use super::controller::{ControllerConfig, Rig, output_limits, param_error};
use super::values::{ScalarOrVec, matrix, one_of};
use super::{ConfigError, ErrFn};
use control::ControllerInput;
use control::lti::LtiParams;
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawLti {
    #[allow(dead_code)]
    kind: String,
    input: Option<String>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    ss: Option<RawSs>,
    tf: Option<RawTfMatrix>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawSs {
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
    d: Vec<Vec<f64>>,
    x0: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTfMatrix {
    entries: Vec<Vec<RawTfEntry>>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum RawTfEntry {
    Zero(i64),
    Tf { num: Vec<f64>, den: Vec<f64> },
}

/// The four matrices of a state-space realization.
type Abcd = (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>);

/// Reads the table.
pub(super) fn parse(
    raw: RawLti,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let counts = rig.counts;
    let input = one_of(
        raw.input.as_deref(),
        ControllerInput::Y,
        &[
            ("y", ControllerInput::Y),
            ("error", ControllerInput::Error),
            ("y-and-r", ControllerInput::YAndR),
        ],
        "controller.input",
        err,
    )?;
    let n_u = counts.n_u as usize;
    let n_e = LtiParams::input_len(input, crate::wire::dimensions(counts));
    let limits = output_limits(&raw.u_min, &raw.u_max, n_u, err)?;
    let (a, b, c, d, x0) = match (raw.ss, raw.tf) {
        (Some(ss), None) => {
            let a = matrix(&ss.a, 0, "a").map_err(|m| err("controller.ss.a", m))?;
            let n = a.nrows();
            let b = matrix(&ss.b, n_e, "b").map_err(|m| err("controller.ss.b", m))?;
            let c = if ss.c.is_empty() || (n == 0 && ss.c.iter().all(|r| r.is_empty())) {
                DMatrix::zeros(n_u, n)
            } else {
                matrix(&ss.c, n, "c").map_err(|m| err("controller.ss.c", m))?
            };
            let d = matrix(&ss.d, n_e, "d").map_err(|m| err("controller.ss.d", m))?;
            (a, b, c, d, ss.x0.map(DVector::from_vec))
        }
        (None, Some(tf)) => {
            let (a, b, c, d) = realize_tf_entries(&tf.entries, n_u, n_e)
                .map_err(|m| err("controller.tf.entries", m))?;
            (a, b, c, d, None)
        }
        (Some(_), Some(_)) => {
            return Err(err(
                "controller",
                "give [controller.ss] or [controller.tf], not both".into(),
            ));
        }
        (None, None) => {
            return Err(err(
                "controller",
                "an lti controller needs [controller.ss] or [controller.tf]".into(),
            ));
        }
    };
    if a.nrows() > MAX_LTI_STATES {
        return Err(err(
            "controller",
            format!("{} states, at most {MAX_LTI_STATES}", a.nrows()),
        ));
    }
    let params = LtiParams {
        a,
        b,
        c,
        d,
        x0,
        input,
        limits,
    };
    params
        .validate(crate::wire::dimensions(counts))
        .map_err(|e| match e.field {
            // The matrices may be a realization of [controller.tf]: the table is named, the
            // message names the matrix and its sizes.
            "a" | "b" | "c" | "d" | "x0" => err("controller", e.message),
            _ => param_error(e, err),
        })?;
    Ok(ControllerConfig::Lti {
        params: Box::new(params),
    })
}

/// Realizes an `n_u × n_e` matrix of discrete transfer functions with the scenario
/// schema's realization ([`rig_scenario::lti::realize_tf_matrix`]).
fn realize_tf_entries(entries: &[Vec<RawTfEntry>], n_u: usize, n_e: usize) -> Result<Abcd, String> {
    use rig_scenario::lti::{Tf, realize_tf_matrix};
    if entries.len() != n_u {
        return Err(format!(
            "{} rows, expected one per input u ({n_u})",
            entries.len()
        ));
    }
    let mut m = Vec::with_capacity(n_u);
    for (i, row) in entries.iter().enumerate() {
        if row.len() != n_e {
            return Err(format!(
                "row {i} has {} entries, expected one per controller input ({n_e})",
                row.len()
            ));
        }
        let mut r = Vec::with_capacity(n_e);
        for (j, e) in row.iter().enumerate() {
            r.push(match e {
                RawTfEntry::Zero(0) => None,
                RawTfEntry::Zero(v) => {
                    return Err(format!("[{i}][{j}] = {v}: an entry is 0 or {{ num, den }}"));
                }
                RawTfEntry::Tf { num, den } if num.len().max(den.len()) > MAX_LTI_STATES + 1 => {
                    return Err(format!(
                        "[{i}][{j}]: more than {} coefficients (the controller has at most \
                         {MAX_LTI_STATES} states)",
                        MAX_LTI_STATES + 1
                    ));
                }
                RawTfEntry::Tf { num, den } => Some(
                    Tf::new(num.clone(), den.clone()).map_err(|e| format!("[{i}][{j}]: {e}"))?,
                ),
            });
        }
        m.push(r);
    }
    let ss = realize_tf_matrix(&m).map_err(|e| e.to_string())?;
    Ok((ss.a, ss.b, ss.c, ss.d))
}
