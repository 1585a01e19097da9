//! Per-tone suppression of `z` for the run report.
//!
//! The disturbances of chapter 3 are sums of tones; what a user of the acoustic rig asks
//! after a run is how far each tone fell. [`ToneMeter`] keeps two windows of `z` in
//! buffers sized before the loop starts: the end of the open-loop phase of the session
//! (`service.open-loop`: `u` is the safe input while the controller only observes) and the
//! last samples of the run. The real-time thread only stores into them. After the loop,
//! [`ToneMeter::report`] fits the amplitudes of all tones jointly in each window by least
//! squares ([`control::tones::tone_amplitudes_indexed`], which takes the sequence numbers,
//! so lost samples leave gaps rather than shifting the phase) and gives, per tone and
//! channel, `20 log10(A_open / A_closed)`.
//!
//! A window of `L` samples resolves frequencies `1/(L T)` apart, and what the fit gives at
//! a tone cancelled below the broadband noise is that noise, as it happens to fall in the
//! window. So the report also gives each tone's **noise floor** in the closed-loop window:
//! the median amplitude of the same joint fit at the frequencies `f_i ± k/(L T)`, `k = 2 …
//! 5` (fitted together with the tones, so the tones themselves are removed), and the
//! suppression that floor typically allows, `20 log10(A_open / floor)`. A suppression near
//! or above that limit is the noise's, not the tone's: the noise in the tone's bin is a
//! random draw, often below its median.

use serde::Serialize;

use crate::config::ToneReportConfig;
use control::linalg::percentile;
use control::tones::{suppression_db, tone_amplitudes_indexed};

/// The two windows of `z` (see the module docs).
#[derive(Debug)]
pub struct ToneMeter {
    n_z: usize,
    window: usize,
    open_loop_cycles: u64,
    hz: Vec<f64>,
    source: String,
    period: f64,
    open_seq: Vec<u64>,
    open_z: Vec<f64>,
    ring_seq: Vec<u64>,
    ring_z: Vec<f64>,
    head: usize,
    filled: usize,
}

/// One tone on one channel.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ToneLine {
    /// Frequency in Hz.
    pub hz: f64,
    /// Performance channel.
    pub channel: usize,
    /// Amplitude at the end of the open-loop phase (none without one).
    pub open: Option<f64>,
    /// Amplitude at the end of the run.
    pub closed: f64,
    /// `20 log10(open / closed)`.
    pub suppression_db: Option<f64>,
    /// The closed-loop window's noise floor at the tone (module docs); none when no
    /// offset frequency is below Nyquist or the fit failed.
    pub floor: Option<f64>,
    /// `20 log10(open / floor)`: the suppression the window's noise typically allows.
    pub floor_limit_db: Option<f64>,
}

/// The tone part of the run report.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ToneReport {
    /// Where the tone list came from.
    pub source: String,
    /// Window length in s.
    pub window_s: f64,
    /// Samples in the open-loop and closed-loop windows.
    pub samples: [usize; 2],
    /// Per tone and channel.
    pub tones: Vec<ToneLine>,
    /// Why nothing could be measured, if so.
    pub error: Option<String>,
}

impl ToneMeter {
    /// Sizes the buffers (allocating; before the loop).
    pub fn new(cfg: &ToneReportConfig, open_loop_cycles: u64, n_z: usize, period: f64) -> Self {
        let window = if cfg.tones_hz.is_empty() || n_z == 0 {
            0
        } else {
            cfg.window_cycles as usize
        };
        let open = if open_loop_cycles > 0 { window } else { 0 };
        Self {
            n_z,
            window,
            open_loop_cycles,
            hz: cfg.tones_hz.clone(),
            source: cfg.source.clone(),
            period,
            open_seq: Vec::with_capacity(open),
            open_z: Vec::with_capacity(open * n_z),
            ring_seq: vec![0; window],
            ring_z: vec![0.0; window * n_z],
            head: 0,
            filled: 0,
        }
    }

    /// Stores `z` of the sample `seq`, the `cycle`-th (from 1) of the session. No
    /// allocation: the vectors never grow past their capacity.
    #[inline]
    pub fn record(&mut self, cycle: u64, seq: u64, z: &[f64]) {
        if self.window == 0 {
            return;
        }
        if cycle <= self.open_loop_cycles {
            let w = self.window as u64;
            if cycle + w > self.open_loop_cycles && self.open_seq.len() < self.open_seq.capacity() {
                self.open_seq.push(seq);
                self.open_z.extend(z.iter().take(self.n_z).copied());
            }
            return;
        }
        if let Some(s) = self.ring_seq.get_mut(self.head) {
            *s = seq;
        }
        let at = self.head * self.n_z;
        if let Some(dst) = self.ring_z.get_mut(at..at + self.n_z) {
            for (d, v) in dst.iter_mut().zip(z) {
                *d = *v;
            }
        }
        self.head = (self.head + 1) % self.window;
        self.filled = (self.filled + 1).min(self.window);
    }

    /// Forgets both windows (a new session starts with its own open-loop phase).
    pub fn new_session(&mut self) {
        self.open_seq.clear();
        self.open_z.clear();
        self.head = 0;
        self.filled = 0;
    }

    /// Fits the tones in both windows (after the loop; allocates). `None` when no tones
    /// are configured.
    pub fn report(&self) -> Option<ToneReport> {
        if self.window == 0 {
            return None;
        }
        let omegas: Vec<f64> = self
            .hz
            .iter()
            .map(|f| 2.0 * std::f64::consts::PI * f * self.period)
            .collect();
        // Ring in time order.
        let start = if self.filled < self.window {
            0
        } else {
            self.head
        };
        let order: Vec<usize> = (0..self.filled)
            .map(|i| (start + i) % self.window)
            .collect();
        let closed_seq: Vec<u64> = order.iter().map(|&i| self.ring_seq[i]).collect();
        let mut out = ToneReport {
            source: self.source.clone(),
            window_s: self.window as f64 * self.period,
            samples: [self.open_seq.len(), self.filled],
            tones: Vec::new(),
            error: None,
        };
        let fail = |e: String, out: &mut ToneReport| {
            if out.error.is_none() {
                out.error = Some(e);
            }
        };
        for ch in 0..self.n_z {
            let closed_z: Vec<f64> = order
                .iter()
                .map(|&i| self.ring_z[i * self.n_z + ch])
                .collect();
            let closed = match tone_amplitudes_indexed(&closed_seq, &closed_z, &omegas) {
                Ok(a) => a,
                Err(e) => {
                    fail(format!("closed-loop window: {e}"), &mut out);
                    continue;
                }
            };
            let open = if self.open_seq.is_empty() {
                None
            } else {
                let z: Vec<f64> = (0..self.open_seq.len())
                    .map(|i| self.open_z[i * self.n_z + ch])
                    .collect();
                match tone_amplitudes_indexed(&self.open_seq, &z, &omegas) {
                    Ok(a) => Some(a),
                    Err(e) => {
                        fail(format!("open-loop window: {e}"), &mut out);
                        None
                    }
                }
            };
            let floors = self.floors(&closed_seq, &closed_z, &omegas);
            for (i, hz) in self.hz.iter().enumerate() {
                let o = open.as_ref().map(|a| a[i]);
                let floor = floors[i];
                out.tones.push(ToneLine {
                    hz: *hz,
                    channel: ch,
                    open: o,
                    closed: closed[i],
                    suppression_db: o.map(|o| suppression_db(o, closed[i])),
                    floor,
                    floor_limit_db: o.zip(floor).map(|(o, f)| suppression_db(o, f)),
                });
            }
        }
        Some(out)
    }
}

impl ToneMeter {
    /// Per tone, the median amplitude fitted at `ω_i ± 2πk/L`, `k = 2 … 5` (`L` the
    /// window's length), jointly with the tones (module docs); `None` for a tone with no
    /// offset below Nyquist, or every tone when a fit fails.
    fn floors(&self, seq: &[u64], z: &[f64], omegas: &[f64]) -> Vec<Option<f64>> {
        let step = 2.0 * std::f64::consts::PI / self.window as f64;
        let mut per_tone: Vec<Vec<f64>> = vec![Vec::new(); omegas.len()];
        for k in [-5.0, -4.0, -3.0, -2.0, 2.0, 3.0, 4.0, 5.0] {
            let shifted: Vec<f64> = omegas.iter().map(|w| w + k * step).collect();
            // Only offsets inside (0, π) for every tone; the others are skipped for all.
            if shifted
                .iter()
                .any(|w| !(*w > 0.0 && *w < std::f64::consts::PI))
            {
                continue;
            }
            let both: Vec<f64> = omegas.iter().chain(&shifted).copied().collect();
            let Ok(a) = tone_amplitudes_indexed(seq, z, &both) else {
                return vec![None; omegas.len()];
            };
            for (v, amp) in per_tone.iter_mut().zip(&a[omegas.len()..]) {
                v.push(*amp);
            }
        }
        per_tone
            .into_iter()
            .map(|mut v| (!v.is_empty()).then(|| percentile(&mut v, 0.5)))
            .collect()
    }
}

impl ToneReport {
    /// The human-readable table.
    pub fn render(&self) -> String {
        let mut out = format!(
            "tones of z ({}; windows of {:.3} s: {} samples at the end of the open-loop phase, {} at the end of the run):
",
            self.source, self.window_s, self.samples[0], self.samples[1]
        );
        if let Some(e) = &self.error {
            out += &format!(
                "  could not measure: {e}
"
            );
        }
        out += "  channel   tone Hz    open loop   closed loop   suppression   noise floor   floor's limit\n";
        for t in &self.tones {
            let open = t.open.map_or("-".to_string(), |o| format!("{o:.3e}"));
            let db = |v: Option<f64>| v.map_or("-".to_string(), |d| format!("{d:.1} dB"));
            let floor = t.floor.map_or("-".to_string(), |f| format!("{f:.3e}"));
            out += &format!(
                "  z{:<7} {:>8.1} {:>12} {:>13.3e} {:>13} {:>13} {:>15}\n",
                t.channel,
                t.hz,
                open,
                t.closed,
                db(t.suppression_db),
                floor,
                db(t.floor_limit_db)
            );
        }
        out += "  (the noise floor: the closed-loop window's noise at each tone; a suppression near \
                or above the floor's limit is the noise's, not the tone's)\n";
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tones at 50 and 120 Hz, windows of `window` samples.
    fn config(window: u64) -> ToneReportConfig {
        ToneReportConfig {
            tones_hz: vec![50.0, 120.0],
            source: "test".into(),
            window_cycles: window,
            error_window: None,
            force_regulation: None,
            min_suppression_db: None,
        }
    }

    #[test]
    fn the_meter_compares_the_end_of_the_open_loop_phase_with_the_end_of_the_run() {
        let cfg = config(400);
        let period = 1e-3;
        let mut m = ToneMeter::new(&cfg, 1000, 1, period);
        let tone = |k: u64, a: f64, b: f64| {
            let t = k as f64 * period;
            a * (2.0 * std::f64::consts::PI * 50.0 * t).sin()
                + b * (2.0 * std::f64::consts::PI * 120.0 * t + 1.0).cos()
        };
        for k in 0..3000u64 {
            // 1 and 0.5 open loop, 0.01 and 0.5 closed loop; one sample in 7 lost.
            let z = if k < 1000 {
                tone(k, 1.0, 0.5)
            } else {
                tone(k, 0.01, 0.5)
            };
            if k % 7 != 3 {
                m.record(k + 1, k, &[z]);
            }
        }
        let r = m.report().unwrap();
        assert!(r.error.is_none(), "{:?}", r.error);
        let s: Vec<f64> = r.tones.iter().map(|t| t.suppression_db.unwrap()).collect();
        assert!((s[0] - 40.0).abs() < 1e-6, "{s:?}");
        assert!(s[1].abs() < 1e-6, "{s:?}");
        // The closed window holds the last 400 recorded samples; the open one the last
        // of the open-loop phase.
        assert_eq!(r.samples[1], 400);
        assert!(r.samples[0] <= 400 && r.samples[0] > 300);
    }

    /// The noise floor: with white noise of standard deviation σ in the closed-loop window
    /// and the tone cancelled below it, the fitted tone is at the noise (within a factor 3
    /// of the floor) and the floor near the expected amplitude of noise alone at one
    /// frequency, `σ √(π / L)` (Rayleigh mean, `L` samples); a tone well above the noise
    /// keeps its own amplitude and a floor at the noise; without noise the floor is 0.
    #[test]
    fn the_floor_is_the_closed_loop_windows_noise_at_each_tone() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let cfg = config(2000);
        let period = 1e-3;
        let sigma = 0.01;
        let run = |noise: f64| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
            let mut m = ToneMeter::new(&cfg, 2000, 1, period);
            for k in 0..6000u64 {
                let t = k as f64 * period;
                // 50 Hz: 1 open loop, 1e-5 closed loop (below the noise); 120 Hz: 0.5, 0.1.
                let (a, b) = if k < 2000 { (1.0, 0.5) } else { (1e-5, 0.1) };
                let n: f64 = StandardNormal.sample(&mut rng);
                let z = a * (2.0 * std::f64::consts::PI * 50.0 * t).sin()
                    + b * (2.0 * std::f64::consts::PI * 120.0 * t).cos()
                    + noise * n;
                m.record(k + 1, k, &[z]);
            }
            m.report().unwrap()
        };
        let r = run(sigma);
        let expected = sigma * (std::f64::consts::PI / 2000.0).sqrt();
        for t in &r.tones {
            let floor = t.floor.unwrap();
            assert!(
                floor > 0.5 * expected && floor < 2.0 * expected,
                "{} Hz: floor {floor}, expected about {expected}",
                t.hz
            );
            let limit = t.floor_limit_db.unwrap();
            assert!((limit - suppression_db(t.open.unwrap(), floor)).abs() < 1e-12);
        }
        let (weak, strong) = (&r.tones[0], &r.tones[1]);
        assert!(weak.closed < 3.0 * weak.floor.unwrap(), "{weak:?}");
        assert!((strong.closed - 0.1).abs() < 0.01, "{strong:?}");
        let text = r.render();
        assert!(text.contains("noise floor"), "{text}");
        let clean = run(0.0);
        for t in &clean.tones {
            assert!(t.floor.unwrap() < 1e-9, "{t:?}");
        }
    }
}
