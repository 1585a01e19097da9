//! When a signal has converged to its own late level: the reading of chapter 6's "converges
//! within 10 s" (node 8 of the truss, [`crate::study::pcac_truss`]) and of chapter 5's "8
//! more steps for its error to converge" (the prior error of RLS,
//! [`crate::study::forgetting`]).
//!
//! The trailing RMS over `W` samples, `r_k = √(mean of x² over samples k−W+1 … k)`; the
//! signal has converged from the first `k` after which `r_j ≤ 2 · target` for every
//! `j ≥ k`, where `target` is its late level (the RMS over the late part of the run): the
//! end of the first trailing window from which on the level stays within twice its final
//! value.

/// RMS of `x` (NaN when empty).
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return f64::NAN;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// The time to converge of the module docs: `z` sampled every `ts` s, trailing windows of
/// `window` samples, `target` the final level (twice it is the bound). `None` when the
/// last trailing window is above the bound.
pub fn convergence_time(z: &[f64], ts: f64, window: usize, target: f64) -> Option<f64> {
    let w = window.max(1);
    if z.len() < w || !target.is_finite() {
        return None;
    }
    let bound = 2.0 * target;
    let mut last_violation: Option<usize> = None;
    for k in (w - 1)..z.len() {
        // Recomputed rather than updated so that round-off cannot accumulate.
        let r = rms(&z[k + 1 - w..=k]);
        if r.is_nan() || r > bound {
            last_violation = Some(k);
        }
    }
    match last_violation {
        None => Some((w - 1) as f64 * ts),
        Some(k) if k + 1 < z.len() => Some((k + 1) as f64 * ts),
        Some(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_to_converge_is_where_the_trailing_rms_last_enters_twice_the_final_level() {
        // 1.0 for 100 samples, then 0.1: the final level (0.1) doubled is 0.2; a trailing
        // window of 10 is below it once at most 1 large sample is inside (√(0.01·9 + 1)/√10
        // = 0.33 > 0.2), i.e. from the window ending at sample 109.
        let mut z = vec![1.0; 100];
        z.extend(vec![0.1; 200]);
        let t = convergence_time(&z, 0.5, 10, 0.1).unwrap();
        assert_eq!(t, 109.0 * 0.5);
        // A late burst that does not settle: never.
        let mut z2 = vec![0.1; 100];
        z2.extend(vec![5.0; 10]);
        assert_eq!(convergence_time(&z2, 1.0, 10, 0.1), None);
        // Always within: the first full window.
        assert_eq!(convergence_time(&[0.1; 50], 1.0, 10, 0.1), Some(9.0));
    }
}
