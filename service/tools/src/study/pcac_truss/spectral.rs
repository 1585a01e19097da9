//! Peak by peak and mode by mode: the reductions that Figures 6.6 and 6.9 show in the Welch
//! PSDs of `z` (claims 6.9 and 6.13).
//!
//! Both are read on the same PSDs as the figures: Welch, Hann windows, 50 % overlap,
//! segments of a quarter of the late window (64 … 2048 samples, [`segment`]), over the late
//! window of the open and the closed loop (the same disturbance realization).
//!
//! - **A peak** of the open-loop PSD `Φ_OL(f)` is a local maximum (DC left out) whose
//!   topographic prominence is at least [`PEAK_PROMINENCE_DB`]: walking from it to each
//!   side until a higher bin (or the end), the lowest bin on each side; the higher of the
//!   two is the peak's base, and the prominence is `10 log10(Φ_OL(f_p) / base)`. A rule
//!   "above the median level" takes the Welch ripple on a plateau for peaks; prominence
//!   asks a peak to stand out from its own surroundings.
//! - **The reduction at a frequency** `f` is `10 log10(P_OL / P_CL)` with `P` the PSD
//!   summed over the bin nearest `f` and its two neighbours (a peak of a lightly damped
//!   mode spreads over the window's main lobe, three bins for Hann).
//! - **The modes inside the control bandwidth** are the truss modes below the Nyquist
//!   frequency `f_s / 2`; their reduction is read on the PSD summed over the four nodes, so
//!   that a mode that one node does not see is still measured.

use crate::analysis::{Psd, PsdError, psd};

/// Least topographic prominence of an open-loop PSD peak, dB.
pub const PEAK_PROMINENCE_DB: f64 = 10.0;

/// Welch segment length for a late window of `late` samples (as the PSD figures).
pub fn segment(late: usize) -> usize {
    (late / 4).clamp(64, 2048)
}

/// The PSD of the late window of `x` at `fs` Hz.
pub fn late_psd(x: &[f64], late_start: usize, fs: f64) -> Result<Psd, PsdError> {
    let late = &x[late_start.min(x.len())..];
    psd(late, fs, segment(late.len()))
}

/// The bins of the peaks of `density` (module docs) with a prominence of at least
/// `min_db`, in frequency order.
pub fn peaks(density: &[f64], min_db: f64) -> Vec<usize> {
    let n = density.len();
    let mut out = Vec::new();
    for k in 1..n {
        let v = density[k];
        let left_ok = k == 1 || density[k - 1] < v;
        let right_ok = k + 1 == n || density[k + 1] <= v;
        if !(v.is_finite() && v > 0.0 && left_ok && right_ok) {
            continue;
        }
        let base_of = |range: &mut dyn Iterator<Item = usize>| {
            let mut low = v;
            for j in range {
                if density[j] > v {
                    break;
                }
                low = low.min(density[j]);
            }
            low
        };
        let left = base_of(&mut (1..k).rev());
        let right = base_of(&mut (k + 1..n));
        let base = left.max(right);
        if base > 0.0 && 10.0 * (v / base).log10() >= min_db {
            out.push(k);
        }
    }
    out
}

/// The bin nearest `hz` in `p`.
fn nearest_bin(p: &Psd, hz: f64) -> usize {
    let df = p
        .freq_hz
        .get(1)
        .copied()
        .unwrap_or(1.0)
        .max(f64::MIN_POSITIVE);
    ((hz / df).round() as usize).min(p.density.len().saturating_sub(1))
}

/// The PSD summed over the bin nearest `hz` and its neighbours (module docs).
fn power_near(p: &Psd, hz: f64) -> f64 {
    let k = nearest_bin(p, hz);
    let lo = k.saturating_sub(1).max(1);
    let hi = (k + 1).min(p.density.len() - 1);
    p.density[lo..=hi].iter().sum()
}

/// The reduction at `hz` from `open` to `closed`, dB (module docs).
pub fn reduction_at(open: &Psd, closed: &Psd, hz: f64) -> f64 {
    10.0 * (power_near(open, hz) / power_near(closed, hz)).log10()
}

/// Each open-loop peak of `open` (frequency, Hz) with its reduction in `closed`, dB.
pub fn peak_reductions(open: &Psd, closed: &Psd) -> Vec<(f64, f64)> {
    peaks(&open.density, PEAK_PROMINENCE_DB)
        .into_iter()
        .map(|k| {
            let f = open.freq_hz[k];
            (f, reduction_at(open, closed, f))
        })
        .collect()
}

/// The bin-wise sum of PSDs on one frequency grid.
pub fn summed(psds: &[Psd]) -> Option<Psd> {
    let first = psds.first()?;
    let mut density = vec![0.0; first.density.len()];
    for p in psds {
        for (a, b) in density.iter_mut().zip(&p.density) {
            *a += b;
        }
    }
    Some(Psd {
        freq_hz: first.freq_hz.clone(),
        density,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat density of 1 with a bump of `height` at bin 20 and a smaller one at bin 60.
    fn density(height: f64) -> Vec<f64> {
        (0..100)
            .map(|k| match k {
                20 => height,
                19 | 21 => height / 4.0,
                60 => 3.0,
                _ => 1.0 + 0.1 * ((k % 3) as f64),
            })
            .collect()
    }

    #[test]
    fn a_peak_needs_its_prominence_and_plateau_ripple_is_not_one() {
        // Bump at 20 is 100 over its surroundings (20 dB); the one at 60 only about 4.8 dB;
        // the ripple 1, 1.1, 1.2 is 0.8 dB.
        assert_eq!(peaks(&density(100.0), 10.0), vec![20]);
        assert_eq!(peaks(&density(100.0), 3.0), vec![20, 60]);
        assert!(peaks(&density(5.0), 10.0).is_empty());
    }

    #[test]
    fn a_peak_on_the_shoulder_of_a_higher_one_is_measured_from_its_own_col() {
        // 1000 at 10, a dip to 50 at 15, a secondary peak of 600 at 18, then down to 1.
        let mut d = vec![1.0; 40];
        for (k, v) in [
            (9, 300.0),
            (10, 1000.0),
            (11, 300.0),
            (15, 50.0),
            (18, 600.0),
        ] {
            d[k] = v;
        }
        d[12..15].fill(100.0);
        d[16..18].fill(100.0);
        // 600 over its col of 50: 10.8 dB, a peak; it is not compared with the floor of 1.
        assert_eq!(peaks(&d, 10.0), vec![10, 18]);
        assert_eq!(peaks(&d, 11.0), vec![10]);
    }

    #[test]
    fn the_reduction_is_read_over_the_nearest_bin_and_its_neighbours() {
        let freq_hz: Vec<f64> = (0..100).map(|k| k as f64 * 0.5).collect();
        let open = Psd {
            freq_hz: freq_hz.clone(),
            density: density(100.0),
        };
        let closed = Psd {
            freq_hz,
            density: density(100.0).iter().map(|v| v / 10.0).collect(),
        };
        let r = peak_reductions(&open, &closed);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].0, 10.0);
        assert!((r[0].1 - 10.0).abs() < 1e-9, "{r:?}");
        let s = summed(&[open.clone(), open.clone()]).unwrap();
        assert!((reduction_at(&s, &open, 10.2) - 10.0 * 2f64.log10()).abs() < 1e-9);
    }
}
