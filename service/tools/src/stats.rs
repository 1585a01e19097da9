//! Order statistics of the tools' result tables, written once.
//!
//! The median of the `n` values of `v` that are numbers, sorted `x_(1) ≤ … ≤ x_(n)`:
//!
//! ```text
//!  median = x_((n+1)/2)                        n odd
//!         = ½ (x_(n/2) + x_(n/2+1))             n even
//!         = NaN                                 n = 0
//! ```
//!
//! NaN entries (a run that failed, a figure that was not measured) are left out; `±∞`
//! take part. Not for the real-time path: it sorts a copy.

/// The median of the values of `v` that are not NaN (module docs); NaN when there is none.
pub fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        let (a, b) = (s[n / 2 - 1], s[n / 2]);
        if a == b { a } else { 0.5 * (a + b) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_odd_even_empty_and_partly_missing_lists() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&[]).is_nan());
        assert!(median(&[f64::NAN, f64::NAN]).is_nan());
        assert_eq!(median(&[f64::NAN, 5.0, 1.0, f64::NAN, 3.0]), 3.0);
        assert_eq!(median(&[f64::INFINITY, f64::INFINITY]), f64::INFINITY);
        assert_eq!(median(&[1.0, f64::INFINITY]), f64::INFINITY);
    }
}
