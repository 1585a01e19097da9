//! When a signal of the identification converges (claim 6.5: "the disturbance is
//! suppressed before either ‖θ_k‖ or tr(P_k) converge").
//!
//! The chapter gives no definition; the study reads it off the traces of Figures 6.4, 6.7
//! and 6.10 as a reader would: `x_k` has settled from the first sample after which it stays
//! within [`SETTLED_FRACTION`] of its largest excursion from its final value,
//! `|x_k − x_N| ≤ 0.1 · max_j |x_j − x_N|` for every later `k` (anywhere in the run, not
//! only its end). The disturbance's suppression is node 8's time to converge
//! ([`super::convergence_time`]).

/// A signal has settled once it stays within this fraction of its largest excursion from
/// its final value.
pub const SETTLED_FRACTION: f64 = 0.1;

/// The time (s, samples `ts` apart) from which `x` stays within `fraction` of its largest
/// excursion from its last value; `None` when `x` is empty or not finite.
pub fn settling_time(x: &[f64], ts: f64, fraction: f64) -> Option<f64> {
    let last = *x.last()?;
    if !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    let excursion = x.iter().fold(0.0_f64, |a, v| a.max((v - last).abs()));
    let bound = fraction * excursion;
    let settled_from = x
        .iter()
        .rposition(|v| (v - last).abs() > bound)
        .map_or(0, |k| k + 1);
    Some(settled_from as f64 * ts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signal_settles_when_it_stays_inside_a_tenth_of_its_excursion() {
        // 10 for 5 samples, then 3, then 1 from sample 8: excursion 9, bound 0.9.
        let x = [10.0, 10.0, 10.0, 10.0, 10.0, 3.0, 3.0, 3.0, 1.0, 1.0];
        assert_eq!(settling_time(&x, 0.5, 0.1), Some(4.0));
        // A late excursion counts, not only the start.
        let y = [0.0, 1.0, 1.0, 1.0, 5.0, 1.0, 1.0];
        assert_eq!(settling_time(&y, 1.0, 0.1), Some(5.0));
        assert_eq!(settling_time(&[2.0; 4], 1.0, 0.1), Some(0.0));
        assert_eq!(settling_time(&[], 1.0, 0.1), None);
        assert_eq!(settling_time(&[1.0, f64::NAN, 1.0], 1.0, 0.1), None);
    }
}
