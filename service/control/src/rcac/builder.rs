//! [`RcacParams`] from the settings a problem must state, every other setting at its
//! default, checked when built.
//!
//! A problem states the target model `G_f` (its sample period is the rig's), the order
//! `n_c` and the update law ([`RcacUpdate`]). The defaults of the rest, those of
//! [`RcacParams::new`] and of the service's `[controller]` table for `kind = "rcac"`:
//!
//! | setting | default |
//! | --- | --- |
//! | `k_w` (2.16) | `None`: [`RcacParams::default_kw`], `n_c` plus the largest lag of `G_f` |
//! | `R_z` (2.21) | [`RcacParams::DEFAULT_RZ`] ` · I` |
//! | `R_u` (2.21) | [`RcacParams::DEFAULT_RU`] ` · I` |
//! | `θ_0` | `0` |
//! | saturation | none |
//! | gap rule | [`RcacParams::DEFAULT_GAP_RULE`] |
//!
//! The update laws' own defaults when a configuration gives none: the RLS trace limit
//! [`RcacParams::default_trace_limit`] and forgetting [`ForgettingRule::DEFAULT`]
//! ([`RcacUpdate::rls`]); the gradient's step size [`RcacParams::DEFAULT_STEP_SIZE`] and
//! `R = ` [`RcacParams::DEFAULT_GRADIENT_R`] ([`RcacUpdate::gradient`]).

use super::{GapRule, RcacParams, RcacUpdate};
use crate::ParamError;
use crate::controller::{Dimensions, OutputLimits};
use crate::forgetting::ForgettingRule;
use crate::target::TargetModel;
use nalgebra::DMatrix;

/// Builds [`RcacParams`] (module docs); start with [`RcacParams::builder`].
#[derive(Debug, Clone, PartialEq)]
pub struct RcacBuilder {
    params: RcacParams,
}

impl RcacParams {
    /// The builder for the target model `target`, the order `n_c = nc` and the update
    /// law, every other setting at its default (module docs of [`super::builder`]).
    pub fn builder(target: TargetModel, nc: usize, update: RcacUpdate) -> RcacBuilder {
        RcacBuilder {
            params: RcacParams::new(target, nc, update),
        }
    }
}

impl RcacUpdate {
    /// RLS with `P_0 = p0 I`, no forgetting and the default trace limit for order `nc` on
    /// a rig with `counts` ([`RcacParams::default_trace_limit`]).
    pub fn rls(p0: f64, nc: usize, counts: Dimensions) -> Self {
        RcacUpdate::Rls {
            p0,
            rule: ForgettingRule::DEFAULT,
            trace_limit: RcacParams::default_trace_limit(nc, counts, p0),
        }
    }

    /// The gradient update with step-size factor `alpha`, the default step size and
    /// `R = 0`.
    pub fn gradient(alpha: f64) -> Self {
        RcacUpdate::Gradient {
            step_size: RcacParams::DEFAULT_STEP_SIZE,
            alpha,
            r: RcacParams::DEFAULT_GRADIENT_R,
        }
    }
}

impl RcacBuilder {
    /// `k_w` (2.16) (`None`: the default).
    pub fn kw(mut self, kw: Option<usize>) -> Self {
        self.params.kw = kw;
        self
    }

    /// `R_z` (`l_z × l_z`).
    pub fn rz(mut self, rz: DMatrix<f64>) -> Self {
        self.params.rz = rz;
        self
    }

    /// `R_u` (`l_u × l_u`).
    pub fn ru(mut self, ru: DMatrix<f64>) -> Self {
        self.params.ru = ru;
        self
    }

    /// `θ_0` (`None`: zero).
    pub fn theta0(mut self, theta0: Option<Vec<f64>>) -> Self {
        self.params.theta0 = theta0;
        self
    }

    /// The output saturation.
    pub fn limits(mut self, limits: Option<OutputLimits>) -> Self {
        self.params.limits = limits;
        self
    }

    /// What bridges lost samples and when the update resumes after them.
    pub fn gap_rule(mut self, rule: GapRule) -> Self {
        self.params.gap_rule = rule;
        self
    }

    /// The parameters, checked for a rig with `counts`.
    ///
    /// # Errors
    ///
    /// The first refused field, as [`RcacParams::validate`] names it.
    pub fn build(self, counts: Dimensions) -> Result<RcacParams, ParamError> {
        self.params.validate(counts)?;
        Ok(self.params)
    }
}
