//! Amplitudes of known tones by least squares, for the run report's per-tone suppression
//! and the studies.
//!
//! The disturbances of chapter 3 of the dissertation are sums of harmonics at known
//! frequencies `ω_i` (rad/sample). Over a window `x_n`, `n = n_0 … n_0+N−1`, the model
//!
//! ```text
//!   x_n ≈ c_0 + Σ_i ( a_i cos(ω_i n) + b_i sin(ω_i n) )
//! ```
//!
//! is fitted by least squares (normal equations of the `(2m+1)`-column regressor, solved
//! by Cholesky), and the amplitude of tone `i` is `√(a_i² + b_i²)`. Fitting all tones and
//! the mean together makes the estimate exact for a noiseless sum of tones on any window,
//! whole periods or not, as long as the tones are resolvable (`N` larger than about
//! `2π / min |ω_i − ω_j|`); [`tone_amplitudes`] refuses windows where the normal
//! equations are singular. Broadband noise of variance `σ²` adds about `σ √(2/N)` to
//! each amplitude: that is the floor a suppression measured this way can show.
//!

use nalgebra::{DMatrix, DVector};

/// Amplitudes of the tones at `omegas` (rad/sample) in `x`, whose first sample has index
/// `start` (the phase reference), fitted jointly with the mean by least squares.
///
/// Errors when `x` is too short to resolve the tones (singular normal equations) or a
/// frequency is not in `(0, π]`.
pub fn tone_amplitudes(x: &[f64], start: usize, omegas: &[f64]) -> Result<Vec<f64>, String> {
    fit_tones(
        x.iter().enumerate().map(|(n, v)| ((start + n) as f64, *v)),
        x.len(),
        omegas,
    )
}

/// [`tone_amplitudes`] for samples at arbitrary indexes (a record with gaps): sample `i`
/// is `x[i]` at index `index[i]`. Errors as [`tone_amplitudes`], or when the lengths
/// differ.
pub fn tone_amplitudes_indexed(
    index: &[u64],
    x: &[f64],
    omegas: &[f64],
) -> Result<Vec<f64>, String> {
    if index.len() != x.len() {
        return Err(format!("{} indexes for {} samples", index.len(), x.len()));
    }
    fit_tones(
        index.iter().zip(x).map(|(n, v)| (*n as f64, *v)),
        x.len(),
        omegas,
    )
}

/// The joint least-squares fit of the module docs over `(index, value)` samples.
fn fit_tones(
    samples: impl Iterator<Item = (f64, f64)>,
    count: usize,
    omegas: &[f64],
) -> Result<Vec<f64>, String> {
    for &w in omegas {
        if !(w > 0.0 && w <= std::f64::consts::PI + 1e-12) {
            return Err(format!(
                "tone frequency {w} rad/sample is not in (0, π]: above Nyquist or not positive"
            ));
        }
    }
    let m = 2 * omegas.len() + 1;
    if count < m {
        return Err(format!(
            "{count} samples cannot resolve {} tones and a mean",
            omegas.len()
        ));
    }
    let mut g = DMatrix::<f64>::zeros(m, m);
    let mut rhs = DVector::<f64>::zeros(m);
    let mut row = vec![0.0; m];
    for (t, v) in samples {
        row[0] = 1.0;
        for (i, &w) in omegas.iter().enumerate() {
            let (s, c) = (w * t).sin_cos();
            row[1 + 2 * i] = c;
            row[2 + 2 * i] = s;
        }
        for a in 0..m {
            rhs[a] += row[a] * v;
            for b in 0..=a {
                g[(a, b)] += row[a] * row[b];
            }
        }
    }
    for a in 0..m {
        for b in 0..a {
            g[(b, a)] = g[(a, b)];
        }
    }
    // A tone at Nyquist has no sine component: drop that column's unknown.
    for (i, &w) in omegas.iter().enumerate() {
        if (w - std::f64::consts::PI).abs() < 1e-12 {
            let j = 2 + 2 * i;
            g.row_mut(j).fill(0.0);
            g.column_mut(j).fill(0.0);
            g[(j, j)] = 1.0;
            rhs[j] = 0.0;
        }
    }
    let scale = count as f64;
    let chol = (g / scale).cholesky().ok_or_else(|| {
        format!(
            "{count} samples cannot separate the tones {omegas:?} rad/sample (singular fit); use a longer window"
        )
    })?;
    let coef = chol.solve(&(rhs / scale));
    Ok((0..omegas.len())
        .map(|i| coef[1 + 2 * i].hypot(coef[2 + 2 * i]))
        .collect())
}

/// Suppression in dB of an amplitude `closed` against `open`: `20 log10(open / closed)`.
pub fn suppression_db(open: f64, closed: f64) -> f64 {
    20.0 * (open / closed).log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_is_exact_for_close_tones_on_a_window_of_partial_periods() {
        let w = [0.31, 0.37, 2.9];
        let amp = [1.5, 0.02, 0.7];
        let x: Vec<f64> = (0..300)
            .map(|n| {
                let t = (1000 + n) as f64;
                0.3 + amp[0] * (w[0] * t + 0.4).sin()
                    + amp[1] * (w[1] * t - 1.0).cos()
                    + amp[2] * (w[2] * t).sin()
            })
            .collect();
        let a = tone_amplitudes(&x, 1000, &w).unwrap();
        for (got, want) in a.iter().zip(amp) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        assert_eq!(suppression_db(1.0, 0.01), 40.0);
        // The same record with every third sample missing.
        let (idx, xs): (Vec<u64>, Vec<f64>) = x
            .iter()
            .enumerate()
            .filter(|(n, _)| n % 3 != 1)
            .map(|(n, v)| (1000 + n as u64, *v))
            .unzip();
        let b = tone_amplitudes_indexed(&idx, &xs, &w).unwrap();
        for (got, want) in b.iter().zip(amp) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
    }

    #[test]
    fn unresolvable_tones_and_bad_frequencies_are_refused() {
        let x = vec![0.0; 20];
        assert!(tone_amplitudes(&x, 0, &[0.5, 0.5]).is_err());
        assert!(
            tone_amplitudes(&x, 0, &[4.0])
                .unwrap_err()
                .contains("Nyquist")
        );
        assert!(tone_amplitudes(&x[..3], 0, &[0.5, 1.0]).is_err());
    }
}
