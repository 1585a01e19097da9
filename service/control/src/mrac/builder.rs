//! [`AppcParams`] and [`RcMracParams`] from the polynomials a problem must state
//! ([`AppcParams::new`], [`RcMracParams::new`]), the estimation settings at their
//! defaults: one builder, [`MracBuilder`] ([`MracParams::into_builder`]), for both
//! methods, whose estimation settings ((4.42), (4.76)) are the same.
//!
//! The defaults, those of the chapter's examples (§4.5: "`θ̂_0 = 0` … with
//! `R_θ = 10⁻⁵ I` and `λ = 1`") and of the service's `[controller]` table for
//! `kind = "appc"` and `"rc-mrac"`:
//!
//! | setting | default |
//! | --- | --- |
//! | `θ̂_0` | `0` |
//! | `R_θ` | [`AppcParams::DEFAULT_R_THETA`] ` · I` ([`RcMracParams::DEFAULT_R_THETA`]) |
//! | forgetting | [`ForgettingRule::DEFAULT`] (`λ = 1`) |
//! | trace limit | `+∞` (no guard reset on the trace) |
//! | saturation | none |
//!
//! [`MracBuilder::build`] checks the parameters ([`AppcParams::validate`],
//! [`RcMracParams::validate`]) and names the field it refuses.

use super::appc::AppcParams;
use super::rc_mrac::RcMracParams;
use crate::ParamError;
use crate::controller::OutputLimits;
use crate::forgetting::ForgettingRule;

/// The estimation settings that APPC and RC-MRAC share, borrowed from their parameters.
pub struct Estimation<'a> {
    theta0: &'a mut Option<Vec<f64>>,
    r_theta: &'a mut Vec<f64>,
    forgetting: &'a mut ForgettingRule,
    trace_limit: &'a mut f64,
    limits: &'a mut Option<OutputLimits>,
}

/// The parameters a [`MracBuilder`] builds: [`AppcParams`] or [`RcMracParams`].
pub trait MracParams: Sized + private::Sealed {
    /// The shared estimation settings.
    fn estimation(&mut self) -> Estimation<'_>;
    /// The method's check ([`AppcParams::validate`], [`RcMracParams::validate`]).
    fn check_params(&self) -> Result<(), ParamError>;

    /// The builder that starts from these parameters (from [`AppcParams::new`] or
    /// [`RcMracParams::new`]: the estimation at its defaults).
    fn into_builder(self) -> MracBuilder<Self> {
        MracBuilder { params: self }
    }
}

mod private {
    /// Only the two methods of this module implement [`super::MracParams`].
    pub trait Sealed {}
    impl Sealed for super::AppcParams {}
    impl Sealed for super::RcMracParams {}
}

/// [`MracParams`] for a method's parameters: the fields of the estimation have the same
/// names in both.
macro_rules! mrac_params {
    ($params:ty) => {
        impl MracParams for $params {
            fn estimation(&mut self) -> Estimation<'_> {
                Estimation {
                    theta0: &mut self.theta0,
                    r_theta: &mut self.r_theta,
                    forgetting: &mut self.forgetting,
                    trace_limit: &mut self.trace_limit,
                    limits: &mut self.limits,
                }
            }

            fn check_params(&self) -> Result<(), ParamError> {
                self.validate()
            }
        }
    };
}

mrac_params!(AppcParams);
mrac_params!(RcMracParams);

/// Builds [`AppcParams`] or [`RcMracParams`] (module docs); start with
/// [`MracParams::into_builder`] on the parameters of [`AppcParams::new`] or
/// [`RcMracParams::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct MracBuilder<P> {
    params: P,
}

impl<P: MracParams> MracBuilder<P> {
    /// `θ̂_0` (`None`: zero).
    pub fn theta0(mut self, theta0: Option<Vec<f64>>) -> Self {
        *self.params.estimation().theta0 = theta0;
        self
    }

    /// The diagonal of `R_θ`, one entry per coefficient.
    pub fn r_theta(mut self, r_theta: Vec<f64>) -> Self {
        *self.params.estimation().r_theta = r_theta;
        self
    }

    /// The forgetting rule.
    pub fn forgetting(mut self, rule: ForgettingRule) -> Self {
        *self.params.estimation().forgetting = rule;
        self
    }

    /// The RLS guard's trace limit (may be `+∞`).
    pub fn trace_limit(mut self, limit: f64) -> Self {
        *self.params.estimation().trace_limit = limit;
        self
    }

    /// The output saturation.
    pub fn limits(mut self, limits: Option<OutputLimits>) -> Self {
        *self.params.estimation().limits = limits;
        self
    }

    /// The parameters, checked.
    ///
    /// # Errors
    ///
    /// The first refused field, as the method's `validate` names it.
    pub fn build(self) -> Result<P, ParamError> {
        self.params.check_params()?;
        Ok(self.params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_those_of_the_chapters_examples() {
        let p = AppcParams::new(2, vec![1.0, -0.5], vec![0.0, 0.5], vec![1.0])
            .into_builder()
            .build()
            .unwrap();
        assert_eq!(p.theta0, None);
        assert_eq!(p.r_theta, vec![1e-5; 8]);
        assert_eq!(p.forgetting, ForgettingRule::Constant { lambda: 1.0 });
        assert_eq!((p.trace_limit, p.limits), (f64::INFINITY, None));
    }

    #[test]
    fn build_names_the_refused_field() {
        let b = AppcParams::new(2, vec![1.0, -0.5], vec![0.0, 0.5], vec![1.0]).into_builder();
        let field = |b: MracBuilder<AppcParams>| b.build().unwrap_err().field;
        assert_eq!(field(b.clone().r_theta(vec![1.0; 3])), "r-theta");
        assert_eq!(field(b.clone().theta0(Some(vec![f64::NAN; 8]))), "theta0");
        assert_eq!(
            field(b.forgetting(ForgettingRule::Constant { lambda: 2.0 })),
            "forgetting.lambda"
        );
    }
}
