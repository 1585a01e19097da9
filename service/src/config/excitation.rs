//! `kind = "excitation"`: independent white Gaussian inputs for an identification run
//! ([`ExcitationSource`](control::ExcitationSource)).
//!
//! ```toml
//! [controller]
//! kind = "excitation"
//! std = [2.0, 2.0]                # standard deviation per input (or one scalar), ≥ 0, not all 0
//! seed = 1                        # generator seed (default 1)
//! u-min = -5.0                    # optional saturation, scalar or per input
//! u-max = 5.0
//! ```

use super::controller::{ControllerConfig, Rig, output_limits, param_error};
use super::values::ScalarOrVec;
use super::{ConfigError, ErrFn};
use control::excitation::ExcitationParams;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawExcitation {
    #[allow(dead_code)]
    kind: String,
    std: ScalarOrVec,
    seed: Option<u64>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
}

/// Reads the table.
pub(super) fn parse(
    raw: RawExcitation,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let counts = rig.counts;
    let n_u = counts.n_u as usize;
    let std = match raw.std {
        ScalarOrVec::Scalar(x) => vec![x; n_u],
        ScalarOrVec::Vec(v) => v,
    };
    let params = ExcitationParams {
        std,
        seed: raw.seed.unwrap_or(ExcitationParams::DEFAULT_SEED),
        limits: output_limits(&raw.u_min, &raw.u_max, n_u, err)?,
    };
    params
        .validate(crate::wire::dimensions(counts))
        .map_err(|e| param_error(e, err))?;
    Ok(ControllerConfig::Excitation {
        params: Box::new(params),
    })
}
