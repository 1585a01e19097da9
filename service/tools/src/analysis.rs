//! Power spectral densities (Welch) for figures and studies; the tone fit is
//! `control::tones`.
//!
//! [`psd`] is Welch's method: segments of `L` samples with 50 % overlap, mean removed,
//! periodic Hann window `w_n = ½ − ½ cos(2πn/L)`, one-sided density
//!
//! ```text
//!   S(f_k) = c_k / (f_s Σ w_n² K) Σ_s |Σ_n w_n x^{(s)}_n e^{−j2πkn/L}|²,   f_k = k f_s / L,
//! ```
//!
//! with `c_k = 2` except at DC and Nyquist (`c_k = 1`), `K` segments; `Σ_k S(f_k) f_s/L`
//! is the variance of `x` (Parseval), so `S` is in units²/Hz.

use rustfft::{FftPlanner, num_complex::Complex};

/// A one-sided power spectral density.
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    /// Frequencies in Hz, `k f_s / L`, `k = 0 … L/2`.
    pub freq_hz: Vec<f64>,
    /// Density in units²/Hz.
    pub density: Vec<f64>,
}

/// A PSD that cannot be estimated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PsdError {
    /// Fewer than 8 samples per segment (the signal, or the segment, is too short).
    #[error("a PSD needs at least 8 samples per segment, got {samples}")]
    TooShort {
        /// The samples of a segment.
        samples: usize,
    },
}

message_from!(PsdError);

/// Welch PSD of `x` sampled at `fs` Hz with segments of `segment` samples (50 % overlap).
/// When `x` is shorter than one segment the segment is shortened to `x.len()`.
pub fn psd(x: &[f64], fs: f64, segment: usize) -> Result<Psd, PsdError> {
    let l = segment.min(x.len());
    if l < 8 {
        return Err(PsdError::TooShort { samples: l });
    }
    let hop = (l / 2).max(1);
    let segments = (x.len() - l) / hop + 1;
    let w: Vec<f64> = (0..l)
        .map(|n| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * n as f64 / l as f64).cos())
        .collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let fft = FftPlanner::<f64>::new().plan_fft_forward(l);
    let bins = l / 2 + 1;
    let mut acc = vec![0.0; bins];
    let mut buf = vec![Complex::new(0.0, 0.0); l];
    for s in 0..segments {
        let seg = &x[s * hop..s * hop + l];
        let mean = seg.iter().sum::<f64>() / l as f64;
        for ((b, v), wn) in buf.iter_mut().zip(seg).zip(&w) {
            *b = Complex::new((v - mean) * wn, 0.0);
        }
        fft.process(&mut buf);
        for (a, b) in acc.iter_mut().zip(&buf) {
            *a += b.norm_sqr();
        }
    }
    let norm = fs * w2 * segments as f64;
    let density = acc
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let c = if k == 0 || (l.is_multiple_of(2) && k == l / 2) {
                1.0
            } else {
                2.0
            };
            c * a / norm
        })
        .collect();
    Ok(Psd {
        freq_hz: (0..bins).map(|k| k as f64 * fs / l as f64).collect(),
        density,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_psd_integrates_to_the_variance_and_peaks_at_the_tone() {
        let fs = 100.0;
        let x: Vec<f64> = (0..10_000)
            .map(|n| 2.0 * (2.0 * std::f64::consts::PI * 12.5 * n as f64 / fs).sin())
            .collect();
        let p = psd(&x, fs, 512).unwrap();
        let df = fs / 512.0;
        let power: f64 = p.density.iter().sum::<f64>() * df;
        // Variance of a sine of amplitude 2 is 2.
        assert!((power - 2.0).abs() < 0.02, "{power}");
        let k = p
            .density
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert!((p.freq_hz[k] - 12.5).abs() <= df);
    }
}
