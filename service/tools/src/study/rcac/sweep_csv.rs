//! The measured columns of the RCAC studies' sweep CSV files (`sweep-{method}.csv` of
//! `rcac-siso`, `sweep.csv` of `rcac-miso`): what every [`Row`] measured, after the
//! columns that say where in the sweep it lies, which each study writes itself.
//!
//! Per tone `j`: the error of `G_f` (magnitude dB, phase °), then the open and closed
//! amplitudes, the closed amplitude on the window before and the suppression, then the
//! peaks, optionally the peak suppression, whether the run stayed finite and the settling
//! time. With one tone the columns carry no tone number (`open_amp`), with more they are
//! numbered from 1 (`open_amp1`, `open_amp2`).

use crate::study::rcac::driver::Row;

/// The tone number in a column name: none with one tone, `j + 1` with more.
fn tone<const N: usize>(j: usize) -> String {
    if N == 1 {
        String::new()
    } else {
        (j + 1).to_string()
    }
}

/// The names of the measured columns, comma separated; `peak_suppression` adds
/// `peak_suppression_db` after the peaks.
pub fn header<const N: usize>(peak_suppression: bool) -> String {
    let mut cols = Vec::new();
    for j in 0..N {
        let t = tone::<N>(j);
        cols.push(format!("mag_err{t}_db"));
        cols.push(format!("phase_err{t}_deg"));
    }
    for (name, suffix) in [
        ("open_amp", ""),
        ("closed_amp", ""),
        ("closed_amp", "_prev"),
        ("suppression", "_db"),
    ] {
        cols.extend((0..N).map(|j| format!("{name}{}{suffix}", tone::<N>(j))));
    }
    cols.extend(["open_peak", "closed_peak"].map(String::from));
    if peak_suppression {
        cols.push("peak_suppression_db".into());
    }
    cols.extend(["finite", "settle_s"].map(String::from));
    cols.join(",")
}

/// The measured columns of `r` in the order of [`header`], comma separated.
pub fn fields<At, const N: usize>(r: &Row<At, N>, peak_suppression: bool) -> String {
    let mut f = Vec::new();
    for (mag, phase) in r.error {
        f.push(format!("{mag:.6}"));
        f.push(format!("{phase:.6}"));
    }
    for amps in [&r.open_amp, &r.closed_amp, &r.closed_amp_prev] {
        f.extend(amps.iter().map(|a| format!("{a:.6e}")));
    }
    f.extend((0..N).map(|j| format!("{:.3}", r.suppression(j))));
    f.push(format!("{:.6e}", r.open_peak));
    f.push(format!("{:.6e}", r.closed_peak));
    if peak_suppression {
        f.push(format!("{:.3}", r.peak_suppression()));
    }
    f.push(r.finite.to_string());
    f.push(r.settle.map_or("never".into(), |t| format!("{t:.2}")));
    f.join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tone_has_unnumbered_columns_and_two_tones_numbered_ones() {
        assert_eq!(
            header::<1>(true),
            "mag_err_db,phase_err_deg,open_amp,closed_amp,closed_amp_prev,suppression_db,open_peak,closed_peak,peak_suppression_db,finite,settle_s"
        );
        assert_eq!(
            header::<2>(false),
            "mag_err1_db,phase_err1_deg,mag_err2_db,phase_err2_deg,open_amp1,open_amp2,closed_amp1,closed_amp2,closed_amp1_prev,closed_amp2_prev,suppression1_db,suppression2_db,open_peak,closed_peak,finite,settle_s"
        );
    }
}
