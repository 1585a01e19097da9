//! The measurement gate: which samples may reach the controller.
//!
//! A measurement `m` is accepted when all three checks pass, tried in this order; the first
//! that fails names the rejection and increments its counter (one count per sample):
//!
//! 1. contract: `m.contract_version = CONTRACT_VERSION` and `m.counts` equal the configured
//!    channel counts — else [`Rejection::Contract`];
//! 2. finite: every used value of `y`, `z` and `r` is finite (no NaN, no ±∞) — else
//!    [`Rejection::NonFinite`];
//! 3. range: `y_min[i] ≤ y_i ≤ y_max[i]` and `z_min[j] ≤ z_j ≤ z_max[j]` for every used
//!    channel, bounds included (`service.y-min` … `service.z-max`; an unset bound is ∓∞;
//!    `r` has no range) — else [`Rejection::OutOfRange`].
//!
//! A rejected sample never reaches the controller: the loop holds the last input and marks
//! the actuation `MEASUREMENT_REJECTED`. The gate does no I/O and reads no clock; a check is
//! O(channels) on fixed arrays.

use crate::config::MeasurementLimits;
use ipc_types::{CONTRACT_VERSION, ChannelCounts, MAX_Y, MAX_Z, Measurement};

/// Why a measurement was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// Another contract version or other channel counts than configured.
    Contract,
    /// A NaN or infinite value in `y`, `z` or `r`.
    NonFinite,
    /// A value of `y` or `z` outside its configured range.
    OutOfRange,
}

/// Rejections counted so far, one counter per [`Rejection`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RejectionCounts {
    /// Samples of another contract version or other channel counts.
    pub contract: u64,
    /// Samples with a NaN or infinite value.
    pub non_finite: u64,
    /// Samples with a value outside the configured range.
    pub out_of_range: u64,
}

/// The checks of the module docs with their counters; plain data, built before the loop.
#[derive(Debug, Clone)]
pub struct MeasurementGate {
    counts: ChannelCounts,
    y_min: [f64; MAX_Y],
    y_max: [f64; MAX_Y],
    z_min: [f64; MAX_Z],
    z_max: [f64; MAX_Z],
    rejected: RejectionCounts,
}

/// Copies `src` into a full-capacity array whose unset entries are `default`.
fn bounds<const N: usize>(src: &[f64], default: f64) -> [f64; N] {
    let mut a = [default; N];
    let n = src.len().min(N);
    a[..n].copy_from_slice(&src[..n]);
    a
}

impl MeasurementGate {
    /// A gate for samples with `counts` channels and the ranges of `limits`.
    pub fn new(counts: ChannelCounts, limits: &MeasurementLimits) -> Self {
        Self {
            counts,
            y_min: bounds(&limits.y_min, f64::NEG_INFINITY),
            y_max: bounds(&limits.y_max, f64::INFINITY),
            z_min: bounds(&limits.z_min, f64::NEG_INFINITY),
            z_max: bounds(&limits.z_max, f64::INFINITY),
            rejected: RejectionCounts::default(),
        }
    }

    /// Checks `m` (module docs) and counts a rejection.
    pub fn check(&mut self, m: &Measurement) -> Result<(), Rejection> {
        let verdict = self.judge(m);
        match verdict {
            Ok(()) => {}
            Err(Rejection::Contract) => self.rejected.contract += 1,
            Err(Rejection::NonFinite) => self.rejected.non_finite += 1,
            Err(Rejection::OutOfRange) => self.rejected.out_of_range += 1,
        }
        verdict
    }

    fn judge(&self, m: &Measurement) -> Result<(), Rejection> {
        if m.contract_version != CONTRACT_VERSION || m.counts != self.counts {
            return Err(Rejection::Contract);
        }
        let (y, z, r) = (m.y(), m.z(), m.r());
        if !y.iter().chain(z).chain(r).all(|v| v.is_finite()) {
            return Err(Rejection::NonFinite);
        }
        let within = |v: &[f64], lo: &[f64], hi: &[f64]| {
            v.iter()
                .zip(lo.iter().zip(hi))
                .all(|(v, (lo, hi))| *v >= *lo && *v <= *hi)
        };
        if !(within(y, &self.y_min, &self.y_max) && within(z, &self.z_min, &self.z_max)) {
            return Err(Rejection::OutOfRange);
        }
        Ok(())
    }

    /// The rejections counted so far.
    pub fn rejected(&self) -> RejectionCounts {
        self.rejected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two `y`, one `z`, one `r`, one `u`; `y ∈ [-1, 1]`, `z ≤ 10`.
    fn gate() -> MeasurementGate {
        let limits = MeasurementLimits {
            y_min: vec![-1.0, -1.0],
            y_max: vec![1.0, 1.0],
            z_min: vec![f64::NEG_INFINITY],
            z_max: vec![10.0],
        };
        MeasurementGate::new(counts(), &limits)
    }

    fn counts() -> ChannelCounts {
        ChannelCounts::new(2, 1, 1, 1).unwrap()
    }

    fn sample(y: [f64; 2], z: f64, r: f64) -> Measurement {
        let mut m = Measurement::zeroed(counts());
        m.y[..2].copy_from_slice(&y);
        m.z[0] = z;
        m.r[0] = r;
        m
    }

    #[test]
    fn each_sample_gets_the_first_failing_check_as_its_verdict() {
        let other_counts = {
            let mut m = sample([0.0, 0.0], 0.0, 0.0);
            m.counts = ChannelCounts::new(1, 1, 1, 1).unwrap();
            m
        };
        let other_version = {
            let mut m = sample([f64::NAN, 0.0], 0.0, 0.0);
            m.contract_version = CONTRACT_VERSION.wrapping_add(1);
            m
        };
        let table: [(&str, Measurement, Result<(), Rejection>); 13] = [
            ("inside", sample([0.5, -0.5], 3.0, 0.0), Ok(())),
            ("on the bounds", sample([1.0, -1.0], 10.0, 0.0), Ok(())),
            ("r has no range", sample([0.0, 0.0], 0.0, 1e300), Ok(())),
            (
                "z has no lower bound",
                sample([0.0, 0.0], -1e300, 0.0),
                Ok(()),
            ),
            (
                "NaN in y",
                sample([f64::NAN, 0.0], 0.0, 0.0),
                Err(Rejection::NonFinite),
            ),
            (
                "+inf in z",
                sample([0.0, 0.0], f64::INFINITY, 0.0),
                Err(Rejection::NonFinite),
            ),
            (
                "-inf in r",
                sample([0.0, 0.0], 0.0, f64::NEG_INFINITY),
                Err(Rejection::NonFinite),
            ),
            (
                "y above",
                sample([0.0, 1.0 + 1e-12], 0.0, 0.0),
                Err(Rejection::OutOfRange),
            ),
            (
                "y below",
                sample([-2.0, 0.0], 0.0, 0.0),
                Err(Rejection::OutOfRange),
            ),
            (
                "z above",
                sample([0.0, 0.0], 10.5, 0.0),
                Err(Rejection::OutOfRange),
            ),
            (
                "NaN wins over range",
                sample([5.0, f64::NAN], 0.0, 0.0),
                Err(Rejection::NonFinite),
            ),
            (
                "other channel counts",
                other_counts,
                Err(Rejection::Contract),
            ),
            (
                "contract wins over NaN",
                other_version,
                Err(Rejection::Contract),
            ),
        ];
        for (what, m, expected) in table {
            assert_eq!(gate().check(&m), expected, "{what}");
        }
    }

    #[test]
    fn every_rejection_is_counted_once_under_its_reason() {
        let mut g = gate();
        let mut wrong = sample([0.0, 0.0], 0.0, 0.0);
        wrong.contract_version = CONTRACT_VERSION.wrapping_add(1);
        let stream = [
            sample([0.0, 0.0], 0.0, 0.0),
            sample([f64::NAN, f64::INFINITY], 0.0, 0.0),
            wrong,
            sample([3.0, 0.0], 0.0, 0.0),
            sample([0.0, 0.0], 20.0, 0.0),
            sample([0.0, 0.0], 0.0, f64::NAN),
            sample([0.0, 0.0], 0.0, 0.0),
        ];
        let accepted = stream.iter().filter(|m| g.check(m).is_ok()).count();
        assert_eq!(accepted, 2);
        assert_eq!(
            g.rejected(),
            RejectionCounts {
                contract: 1,
                non_finite: 2,
                out_of_range: 2,
            }
        );
    }

    #[test]
    fn unset_bounds_accept_any_finite_value() {
        let limits = MeasurementLimits {
            y_min: vec![],
            y_max: vec![],
            z_min: vec![],
            z_max: vec![],
        };
        let mut g = MeasurementGate::new(counts(), &limits);
        assert_eq!(g.check(&sample([-1e300, 1e300], f64::MAX, 0.0)), Ok(()));
        assert_eq!(
            g.check(&sample([0.0, 0.0], f64::INFINITY, 0.0)),
            Err(Rejection::NonFinite)
        );
    }
}
