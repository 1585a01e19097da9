//! The live tone fit: the amplitude of each tone of the report in `z` over the newest
//! window of samples, and over the last window of the session's open-loop phase.
//!
//! The amplitudes are the least-squares fit of all tones jointly
//! ([`control::tones::tone_amplitudes_indexed`], the fit of the run report's
//! [`ToneMeter`](crate::runtime::ToneMeter), at `ω_i = 2π f_i T` per sample, indexed by
//! the sequence numbers so that lost samples leave gaps), run on the telemetry thread.

use control::tones::tone_amplitudes_indexed;
use ipc_types::telemetry::{MAX_TONES, ToneSnapshot};
use ipc_types::{MAX_Z, actuation_status};
use std::collections::VecDeque;

/// A window of `(seq, z)`.
#[derive(Debug)]
struct Window {
    capacity: usize,
    seq: VecDeque<u64>,
    z: VecDeque<[f64; MAX_Z]>,
    changed: bool,
}

impl Window {
    fn new(capacity: usize) -> Self {
        Self {
            capacity,
            seq: VecDeque::with_capacity(capacity),
            z: VecDeque::with_capacity(capacity),
            changed: false,
        }
    }

    fn push(&mut self, seq: u64, z: &[f64; MAX_Z]) {
        if self.seq.len() == self.capacity {
            self.seq.pop_front();
            self.z.pop_front();
        }
        self.seq.push_back(seq);
        self.z.push_back(*z);
        self.changed = true;
    }

    fn clear(&mut self) {
        self.seq.clear();
        self.z.clear();
        self.changed = true;
    }

    /// The amplitudes `out[i][j]` of tone `i` in channel `j`; NaN when the window is too
    /// short for the fit.
    fn fit(&self, omegas: &[f64], n_z: usize, out: &mut [[f64; MAX_Z]; MAX_TONES]) {
        for row in out.iter_mut() {
            row.fill(f64::NAN);
        }
        let seq: Vec<u64> = self.seq.iter().copied().collect();
        for j in 0..n_z.min(MAX_Z) {
            let x: Vec<f64> = self.z.iter().map(|z| z[j]).collect();
            if let Ok(a) = tone_amplitudes_indexed(&seq, &x, omegas) {
                for (i, v) in a.iter().take(MAX_TONES).enumerate() {
                    out[i][j] = *v;
                }
            }
        }
    }
}

/// The two windows and the latest fits.
#[derive(Debug)]
pub struct ToneFit {
    omegas: Vec<f64>,
    n_z: usize,
    recent: Window,
    open_loop: Window,
    /// The newest sample was in the open-loop phase.
    in_open_loop: bool,
    snapshot: ToneSnapshot,
}

impl ToneFit {
    /// A fit of `hz` (the first [`MAX_TONES`]) in `n_z` channels sampled every `period`
    /// s, over windows of `window` samples.
    pub fn new(hz: &[f64], n_z: usize, period: f64, window: usize) -> Self {
        let hz = &hz[..hz.len().min(MAX_TONES)];
        let mut snapshot = ToneSnapshot {
            n_tones: hz.len() as u32,
            ..ToneSnapshot::default()
        };
        snapshot.hz[..hz.len()].copy_from_slice(hz);
        Self {
            omegas: hz
                .iter()
                .map(|f| 2.0 * std::f64::consts::PI * f * period)
                .collect(),
            n_z,
            recent: Window::new(window.max(1)),
            open_loop: Window::new(window.max(1)),
            in_open_loop: false,
            snapshot,
        }
    }

    /// Takes in sample `seq` with its `z` and the status of the input given for it; a new
    /// open-loop phase (after closed-loop samples) starts its window afresh.
    pub fn push(&mut self, seq: u64, z: &[f64; MAX_Z], status: u32) {
        if self.omegas.is_empty() {
            return;
        }
        let open = status & actuation_status::OPEN_LOOP != 0;
        if open && !self.in_open_loop {
            self.open_loop.clear();
        }
        self.in_open_loop = open;
        if open {
            self.open_loop.push(seq, z);
        }
        self.recent.push(seq, z);
    }

    /// Refits the windows that changed since the last call and returns the snapshot.
    pub fn snapshot(&mut self) -> &ToneSnapshot {
        if self.recent.changed {
            self.recent.changed = false;
            self.recent
                .fit(&self.omegas, self.n_z, &mut self.snapshot.amplitude);
            self.snapshot.window_samples = self.recent.seq.len() as u32;
        }
        if self.open_loop.changed {
            self.open_loop.changed = false;
            self.open_loop
                .fit(&self.omegas, self.n_z, &mut self.snapshot.open_loop);
        }
        &self.snapshot
    }

    /// Per tone and channel: its frequency and suppression so far, dB (`None` when either
    /// level is not measured yet), as the verdict takes them.
    pub fn suppression_db(&mut self) -> Vec<(f64, Option<f64>)> {
        let n_z = self.n_z.min(MAX_Z);
        let s = self.snapshot();
        let mut out = Vec::new();
        for i in 0..s.n_tones as usize {
            for j in 0..n_z {
                let (open, now) = (s.open_loop[i][j], s.amplitude[i][j]);
                let db = (open.is_finite() && now.is_finite() && open > 0.0 && now > 0.0)
                    .then(|| control::tones::suppression_db(open, now));
                out.push((s.hz[i], db));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn z_of(v: f64) -> [f64; MAX_Z] {
        let mut z = [0.0; MAX_Z];
        z[0] = v;
        z
    }

    #[test]
    fn a_tone_ten_times_smaller_after_the_open_loop_phase_is_suppressed_by_20_db() {
        let period = 1.0 / 8000.0;
        let hz = 500.0;
        let mut fit = ToneFit::new(&[hz], 1, period, 800);
        let w = 2.0 * std::f64::consts::PI * hz * period;
        for k in 0..800u64 {
            fit.push(k, &z_of((w * k as f64).sin()), actuation_status::OPEN_LOOP);
        }
        for k in 800..1600u64 {
            fit.push(k, &z_of(0.1 * (w * k as f64).sin()), actuation_status::OK);
        }
        let s = fit.snapshot();
        assert!((s.open_loop[0][0] - 1.0).abs() < 1e-9);
        assert!((s.amplitude[0][0] - 0.1).abs() < 1e-9);
        let db = fit.suppression_db();
        assert_eq!(db.len(), 1);
        assert!((db[0].1.unwrap() - 20.0).abs() < 1e-6);
    }

    #[test]
    fn without_an_open_loop_phase_the_suppression_is_not_measured() {
        let mut fit = ToneFit::new(&[100.0], 1, 1e-3, 100);
        for k in 0..200u64 {
            fit.push(k, &z_of((0.3 * k as f64).sin()), actuation_status::OK);
        }
        assert_eq!(fit.suppression_db(), vec![(100.0, None)]);
        assert!(fit.snapshot().open_loop[0][0].is_nan());
    }
}
