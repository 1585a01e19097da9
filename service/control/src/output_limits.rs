//! The one output-limiting rule of every controller, and what its two status bits mean.
//!
//! Every input a controller hands out — its step's `u_k`, the ready input of its ahead
//! form, every row of its plan — passes [`limit_output`] last. Entry by entry, with the
//! limits `u_min ≤ u_max` of [`OutputLimits`] (`u-min`, `u-max` of the `[controller]`
//! table) or none:
//!
//! ```text
//!  u_i not finite              u_i ← clip(0, u_min,i, u_max,i)   (0 without limits)  CONTROLLER_FAULT
//!  u_i < u_min,i  or > u_max,i  u_i ← clip(u_i, u_min,i, u_max,i)                      SATURATED
//!  otherwise                   unchanged
//! ```
//!
//! So [`status::CONTROLLER_FAULT`] always means that the law produced a value that is not a
//! number and the input sent is not the law's, and [`status::SATURATED`] always means that
//! a finite value of the law was bounded; one step may carry both (different entries).
//! The result is always finite and within the limits. PCAC bounds its inputs inside its
//! receding-horizon problem (2.49) and reports `SATURATED` when the first move lies on a
//! bound; a non-finite solution is its fallback ([`status::FALLBACK`]).

use crate::ParamError;
use crate::controller::status;

/// Per-channel limits on `u`.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputLimits {
    /// Lower limits, one per input.
    pub min: Vec<f64>,
    /// Upper limits, one per input.
    pub max: Vec<f64>,
}

impl OutputLimits {
    /// `|u_i| ≤ bound` on each of `n_u` inputs.
    pub fn symmetric(bound: f64, n_u: usize) -> Self {
        Self {
            min: vec![-bound; n_u],
            max: vec![bound; n_u],
        }
    }

    /// Checks that there are `n_u` lower and upper limits with `u-min ≤ u-max` (no NaN)
    /// for every input; the error names the field `u-min`.
    pub fn validate(&self, n_u: usize) -> Result<(), ParamError> {
        if self.min.len() != n_u || self.max.len() != n_u {
            return Err(ParamError::new(
                "u-min",
                format!("output limits need {n_u} entries for min and max"),
            ));
        }
        if self
            .min
            .iter()
            .zip(&self.max)
            .any(|(lo, hi)| lo.is_nan() || hi.is_nan() || lo > hi)
        {
            return Err(ParamError::new(
                "u-min",
                "output limits need u-min ≤ u-max for every input",
            ));
        }
        Ok(())
    }
}

/// Applies the rule of the module docs to `u` in place and returns its status bits
/// ([`status::OK`], [`status::SATURATED`], [`status::CONTROLLER_FAULT`], or both).
#[inline]
pub fn limit_output(limits: Option<&OutputLimits>, u: &mut [f64]) -> u32 {
    let mut st = status::OK;
    for (i, v) in u.iter_mut().enumerate() {
        let bounds = limits.and_then(|l| Some((*l.min.get(i)?, *l.max.get(i)?)));
        if !v.is_finite() {
            *v = bounds.map_or(0.0, |(lo, hi)| 0.0_f64.clamp(lo, hi));
            st |= status::CONTROLLER_FAULT;
        } else if let Some((lo, hi)) = bounds
            && (*v < lo || *v > hi)
        {
            *v = v.clamp(lo, hi);
            st |= status::SATURATED;
        }
    }
    st
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn entry() -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => -10.0..10.0_f64,
            1 => Just(f64::NAN),
            1 => Just(f64::INFINITY),
            1 => Just(f64::NEG_INFINITY),
        ]
    }

    proptest! {
        /// The conformance property of the rule: each entry's outcome and the status bits
        /// are exactly those of the module docs' table, with or without limits.
        #[test]
        fn each_entry_follows_the_table(
            u in proptest::collection::vec(entry(), 1..6),
            bounds in proptest::collection::vec((-5.0..0.0_f64, 0.0..5.0_f64), 6),
            limited in any::<bool>(),
        ) {
            let n = u.len();
            let limits = OutputLimits {
                min: bounds[..n].iter().map(|b| b.0).collect(),
                max: bounds[..n].iter().map(|b| b.1).collect(),
            };
            let given = limited.then_some(&limits);
            let mut out = u.clone();
            let st = limit_output(given, &mut out);
            let mut fault = false;
            let mut clipped = false;
            for i in 0..n {
                prop_assert!(out[i].is_finite());
                if !u[i].is_finite() {
                    fault = true;
                    // 0 lies within every generated pair of limits.
                    prop_assert_eq!(out[i], 0.0);
                } else if limited && (u[i] < limits.min[i] || u[i] > limits.max[i]) {
                    clipped = true;
                    prop_assert_eq!(out[i], u[i].clamp(limits.min[i], limits.max[i]));
                } else {
                    prop_assert_eq!(out[i], u[i]);
                }
                if limited {
                    prop_assert!(limits.min[i] <= out[i] && out[i] <= limits.max[i]);
                }
            }
            prop_assert_eq!(st & status::CONTROLLER_FAULT != 0, fault);
            prop_assert_eq!(st & status::SATURATED != 0, clipped);
            prop_assert_eq!(st & !(status::CONTROLLER_FAULT | status::SATURATED), 0);
        }
    }

    #[test]
    fn a_non_finite_entry_becomes_zero_clipped_into_limits_that_exclude_zero() {
        let limits = OutputLimits {
            min: vec![1.0],
            max: vec![2.0],
        };
        let mut u = [f64::NAN];
        assert_eq!(
            limit_output(Some(&limits), &mut u),
            status::CONTROLLER_FAULT
        );
        assert_eq!(u, [1.0]);
    }
}
