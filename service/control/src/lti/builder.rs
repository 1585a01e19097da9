//! [`LtiParams`] from the state-space matrices, every other setting at its default,
//! checked when built.
//!
//! The defaults, those of the service's `[controller]` table for `kind = "lti"`:
//!
//! | setting | default |
//! | --- | --- |
//! | `x_0` | `0` |
//! | controller input | [`ControllerInput::Y`] (`e_k = y_k`) |
//! | saturation | none |

use super::{ControllerInput, LtiParams};
use crate::ParamError;
use crate::controller::{Dimensions, OutputLimits};
use nalgebra::{DMatrix, DVector};

/// Builds [`LtiParams`] (module docs); start with [`LtiParams::builder`].
#[derive(Debug, Clone, PartialEq)]
pub struct LtiBuilder {
    params: LtiParams,
}

impl LtiParams {
    /// The builder for `A`, `B`, `C`, `D`, every other setting at its default (module
    /// docs of [`super::builder`]).
    pub fn builder(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> LtiBuilder {
        LtiBuilder {
            params: LtiParams {
                a,
                b,
                c,
                d,
                x0: None,
                input: ControllerInput::default(),
                limits: None,
            },
        }
    }
}

impl LtiBuilder {
    /// The initial state (`None`: zero).
    pub fn x0(mut self, x0: Option<DVector<f64>>) -> Self {
        self.params.x0 = x0;
        self
    }

    /// What feeds the controller.
    pub fn input(mut self, input: ControllerInput) -> Self {
        self.params.input = input;
        self
    }

    /// The output saturation.
    pub fn limits(mut self, limits: Option<OutputLimits>) -> Self {
        self.params.limits = limits;
        self
    }

    /// The parameters, checked for a rig with `counts`.
    ///
    /// # Errors
    ///
    /// The first refused field, as [`LtiParams::validate`] names it.
    pub fn build(self, counts: Dimensions) -> Result<LtiParams, ParamError> {
        self.params.validate(counts)?;
        Ok(self.params)
    }
}
