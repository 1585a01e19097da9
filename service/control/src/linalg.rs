//! The small vector helpers the kernels share.
//!
//! The order in which a sum is accumulated changes its rounding, and the kernels'
//! results are reproducible to the bit, so each reduction order is a helper of its own:
//!
//! - [`dot`]: `Σ a_i b_i` with four accumulators (RLS, RCAC, PCAC's identification);
//! - [`dot_wide`]: eight accumulators (the QP solver's long products);
//! - [`dot_in_order`]: the plain left-to-right sum (condensing, the studies' regressors);
//! - [`axpy`]: `y ← y + a x`;
//! - [`percentile`]: order statistics by linear interpolation, for summaries (allocates
//!   nothing, sorts in place; not for the real-time path).

/// `Σ a_i b_i` over the common length, with four accumulators (lets the compiler
/// vectorize without reassociation licence).
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// `Σ a_i b_i` over the common length with eight independent accumulators (so that the
/// reduction vectorizes and is not bound by the add latency).
#[inline]
pub fn dot_wide(a: &[f64], b: &[f64]) -> f64 {
    let k = a.len().min(b.len());
    let (a, b) = (&a[..k], &b[..k]);
    let mut acc = [0.0f64; 8];
    let mut ca = a.chunks_exact(8);
    let mut cb = b.chunks_exact(8);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s += x * y;
    }
    s
}

/// `Σ a_i b_i` over the common length, summed left to right.
#[inline]
pub fn dot_in_order(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `y ← y + a x` over the common length.
#[inline(always)]
pub fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// Percentile `q ∈ [0, 1]` of `v` (sorted in place) by linear interpolation between order
/// statistics; NaN for an empty slice. `+∞` entries sort last.
pub fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    if lo == hi || v[lo] == v[hi] {
        return v[lo];
    }
    let f = pos - lo as f64;
    v[lo] + f * (v[hi] - v[lo])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dot_order_gives_the_exact_sum_of_small_integers() {
        let a: Vec<f64> = (0..19).map(|i| i as f64).collect();
        let b: Vec<f64> = (0..19).map(|i| (i % 5) as f64 - 2.0).collect();
        let want: f64 = (0..19i64).map(|i| (i * (i % 5 - 2)) as f64).sum();
        assert_eq!(dot(&a, &b), want);
        assert_eq!(dot_wide(&a, &b), want);
        assert_eq!(dot_in_order(&a, &b), want);
        assert_eq!(dot(&a[..3], &b), dot_in_order(&a[..3], &b[..3]));
    }

    #[test]
    fn axpy_adds_a_multiple_over_the_common_length() {
        let mut y = [1.0, 1.0, 1.0];
        axpy(2.0, &[1.0, 2.0], &mut y);
        assert_eq!(y, [3.0, 5.0, 1.0]);
    }

    #[test]
    fn percentiles_interpolate_between_order_statistics() {
        let mut v = [4.0, 1.0, 3.0, 2.0, f64::INFINITY];
        assert_eq!(percentile(&mut v, 0.0), 1.0);
        assert_eq!(percentile(&mut v, 0.5), 3.0);
        assert_eq!(percentile(&mut v, 0.625), 3.5);
        assert!(percentile(&mut [], 0.5).is_nan());
    }
}
