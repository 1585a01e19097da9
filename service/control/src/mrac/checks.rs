//! The parameter checks both controllers share, each refusal naming the field.

use super::poly;
use crate::ParamError;
use crate::controller::{Dimensions, OutputLimits};

/// The polynomial `p` (field `field`) up to its degree, after checking that it is
/// non-empty, finite and of degree at most `max_degree` (`what` names the bound in the
/// message).
pub(crate) fn polynomial(
    p: &[f64],
    field: &'static str,
    max_degree: usize,
    what: &str,
) -> Result<Vec<f64>, ParamError> {
    if p.is_empty() {
        return Err(ParamError::new(field, "has no coefficients"));
    }
    if let Some(i) = p.iter().position(|c| !c.is_finite()) {
        return Err(ParamError::at(field, i, "is not finite"));
    }
    let d = poly::degree(p);
    if d > max_degree {
        return Err(ParamError::new(
            field,
            format!("has degree {d}, more than {what} = {max_degree}"),
        ));
    }
    Ok(p[..=d].to_vec())
}

/// [`polynomial`], and monic with every root strictly inside the unit circle
/// (asymptotically stable as a function of `q`).
pub(crate) fn stable_monic(
    p: &[f64],
    field: &'static str,
    max_degree: usize,
    what: &str,
) -> Result<Vec<f64>, ParamError> {
    let p = polynomial(p, field, max_degree, what)?;
    if !poly::is_monic(&p) {
        return Err(ParamError::new(
            field,
            format!("must be monic (coefficient of q⁰ equal to 1), got {}", p[0]),
        ));
    }
    if !poly::is_schur_stable(&p) {
        let m = poly::roots(&p)
            .iter()
            .map(|z| z.norm())
            .fold(0.0_f64, f64::max);
        return Err(ParamError::new(
            field,
            format!("is not asymptotically stable: a root has modulus {m:.6} ≥ 1"),
        ));
    }
    Ok(p)
}

/// The channels of a SISO model-reference controller: one measurement, one command, one
/// input; `z` (if any) is not read. Refused as field `channels`.
pub(crate) fn siso(counts: Dimensions) -> Result<(), ParamError> {
    if counts.n_y == 1 && counts.n_r == 1 && counts.n_u == 1 {
        Ok(())
    } else {
        Err(ParamError::new(
            "channels",
            format!(
                "a SISO model-reference controller needs n_y = n_r = n_u = 1, got n_y = {}, \
                 n_r = {}, n_u = {}",
                counts.n_y, counts.n_r, counts.n_u
            ),
        ))
    }
}

/// The output limits, if any, for one input.
pub(crate) fn limits(l: Option<&OutputLimits>) -> Result<(), ParamError> {
    l.map_or(Ok(()), |l| l.validate(1))
}
