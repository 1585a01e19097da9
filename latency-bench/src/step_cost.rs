//! Controller step cost per configuration.
//!
//! ## Method
//!
//! Each [`StepCase`] is parsed with `ServiceConfig::parse(text, "bench")` and built with
//! `cfg.controller.build(cfg.counts)` — the path the service takes — then stepped on the
//! calling thread, which the bench pins on the RT core with `SCHED_FIFO`:
//!
//! ```text
//!  y_k from a precomputed table (no arithmetic in the timed region)
//!  t0 = monotonic_ns(); controller.step(y_k, z_k, r_k → u_k); t1 = monotonic_ns()
//!  record t1 − t0 for k ≥ warm-up
//! ```
//!
//! An adaptive controller (RCAC) is measured in a closed loop instead, so that its update
//! runs on the data of a loop: the case's [`LoopPlant`] (an FIR model, a tone plus white
//! noise as disturbance) gives `z_k` and `y_k = z_k` before the timer starts and takes the
//! applied `u_k` after it stops. The warm-up is at least the case's `min_warmup` (past
//! RCAC's `k_w`, which gates the update), so that only updating steps are timed, and a run
//! in which RCAC's guard reset `θ` is refused.
//!
//! Each value contains one `clock_gettime` (vDSO) call's worth of overhead;
//! [`timer_overhead`] measures it (two back-to-back readings) so that the smallest step
//! costs can be read against it. [`step_phase`] runs every case and the overhead on the
//! pinned RT core.

use crate::cli::Settings;
use crate::configs::{LoopPlant, StepCase};
use crate::hist::new_histogram;
use crate::hist::{self, Summary};
use crate::report::Measured;
use crate::{PERIOD_NS, timed_on_rt_core};
use control::{Controller, MAX_INTERNALS, StepInput};
use hdrhistogram::Histogram;
use ipc_types::clock::monotonic_ns;
use ipc_types::{MAX_R, MAX_U, MAX_Y, MAX_Z};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use service::config::ServiceConfig;
use std::path::Path;

/// Length of the precomputed input table.
const TABLE: usize = 1024;

/// Length of the precomputed disturbance table of a case with a [`LoopPlant`] (longer than
/// any controller's memory, so that the noise cannot be learned as a periodic signal).
const NOISE_TABLE: usize = 1 << 15;

/// The loop of a case with a [`LoopPlant`]: the applied inputs' history and the
/// disturbance table. The response-time phase's paced plant closes the same loop around
/// the service ([`crate::timing_phase`]).
pub struct Loop {
    markov: Vec<DMatrix<f64>>,
    /// `d_k` per `z` channel, `NOISE_TABLE` rows of `n_z`.
    d: Vec<f64>,
    /// Applied inputs, newest first: `hist[i]` is `u_{k−1−i}` (`n_u` each).
    hist: Vec<f64>,
    n_z: usize,
    n_u: usize,
}

impl Loop {
    /// The loop of `plant` with `n_z` performance channels and `n_u` inputs, at rest.
    pub fn new(plant: &LoopPlant, n_z: usize, n_u: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(plant.seed);
        let mut d = vec![0.0; NOISE_TABLE * n_z];
        for (k, row) in d.chunks_mut(n_z.max(1)).enumerate() {
            for v in row.iter_mut() {
                // Box–Muller.
                let (a, b): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
                let g = (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos();
                *v = plant.tone * (plant.tone_w * k as f64).sin() + plant.noise_std * g;
            }
        }
        Self {
            markov: plant.markov.clone(),
            d,
            hist: vec![0.0; plant.markov.len() * n_u],
            n_z,
            n_u,
        }
    }

    /// `z_k` from the disturbance and the applied inputs `u_{k−1}, u_{k−2}, …`.
    pub fn output(&self, k: u64, z: &mut [f64]) {
        let row = (k as usize) % NOISE_TABLE;
        for (o, zo) in z.iter_mut().enumerate().take(self.n_z) {
            let mut v = self.d[row * self.n_z + o];
            for (i, h) in self.markov.iter().enumerate().skip(1) {
                let u = &self.hist[(i - 1) * self.n_u..i * self.n_u];
                for (j, uj) in u.iter().enumerate() {
                    v += h[(o, j)] * uj;
                }
            }
            *zo = v;
        }
    }

    /// Records the applied `u_k` (`n_u` values).
    pub fn apply(&mut self, u: &[f64]) {
        let n = self.n_u;
        self.hist.rotate_right(n);
        self.hist[..n].copy_from_slice(&u[..n]);
    }
}

/// Builds `case` through the service's configuration path and times `steps` steps after
/// `max(warmup, case.min_warmup)` untimed ones. Returns the histogram of step durations
/// (ns) and the controller kind.
///
/// A case without a plant gets `y_k` from a table of sines and `z_k = 0`. A case with a
/// [`LoopPlant`] runs in its loop: `z_k` from the plant (computed before the timer
/// starts), `y_k = z_k` (the first `min(n_y, n_z)` channels), and the applied `u_k` fed
/// back. A controller that reports a `resets` internal (RCAC's guard resets of `θ`) must
/// end the run with none, or the timings would include its reset path: that is an error.
pub fn measure(
    case: &StepCase,
    warmup: u64,
    steps: u64,
) -> Result<(Histogram<u64>, &'static str), String> {
    let cfg = ServiceConfig::parse(&case.toml, "bench").map_err(|e| e.to_string())?;
    let mut controller = cfg.controller.build(cfg.counts)?;
    let warmup = warmup.max(case.min_warmup);
    let n_y = cfg.counts.n_y as usize;
    let n_z = cfg.counts.n_z as usize;
    let n_r = cfg.counts.n_r as usize;
    let n_u = cfg.counts.n_u as usize;
    // Inputs: a few incommensurate sines per channel, small enough never to saturate.
    let mut ys = vec![[0.0; MAX_Y]; TABLE];
    for (k, y) in ys.iter_mut().enumerate() {
        for (i, v) in y.iter_mut().enumerate().take(n_y) {
            let t = k as f64;
            *v = 0.3 * (0.05 * t * (i + 1) as f64).sin() + 0.1 * (0.31 * t + i as f64).cos();
        }
    }
    let mut plant = case.plant.as_ref().map(|p| Loop::new(p, n_z, n_u));
    let mut y_loop = [0.0; MAX_Y];
    let mut z = [0.0; MAX_Z];
    let mut r = [0.0; MAX_R];
    let mut u = [0.0; MAX_U];
    let mut h = new_histogram();
    for k in 0..warmup + steps {
        let y = match plant.as_ref() {
            Some(p) => {
                p.output(k, &mut z[..n_z]);
                let m = n_y.min(n_z);
                y_loop[..m].copy_from_slice(&z[..m]);
                &y_loop
            }
            None => &ys[(k as usize) % TABLE],
        };
        if n_r > 0 {
            r[0] = case.command.iter().map(|w| (w * k as f64).cos()).sum();
        }
        let input = StepInput {
            seq: k,
            y: &y[..n_y],
            z: &z[..n_z],
            r: &r[..n_r],
            ..Default::default()
        };
        let t0 = monotonic_ns();
        let status = controller.step(&input, &mut u[..n_u]);
        let t1 = monotonic_ns();
        core::hint::black_box((status, &u));
        if let Some(p) = plant.as_mut() {
            p.apply(&u[..n_u]);
        }
        if k >= warmup {
            h.saturating_record(t1.saturating_sub(t0));
        }
    }
    if u[..n_u].iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "{}: the controller output is not finite",
            case.name
        ));
    }
    if let Some(resets) = internal(controller.as_ref(), "resets")
        && resets != 0.0
    {
        return Err(format!(
            "{}: {resets} guard resets during the measurement (the timings include the reset path)",
            case.name
        ));
    }
    Ok((h, controller.kind()))
}

/// The internal signal `name` of `controller`, if it logs one.
pub fn internal(controller: &dyn Controller, name: &str) -> Option<f64> {
    let i = controller.internal_names().iter().position(|n| n == name)?;
    let mut out = [0.0; MAX_INTERNALS];
    let n = controller.internals(&mut out);
    (i < n).then(|| out[i])
}

/// Two back-to-back `monotonic_ns()` readings, `n` times: the timing overhead inside every
/// step-cost value.
pub fn timer_overhead(n: u64) -> Histogram<u64> {
    let mut h = new_histogram();
    for _ in 0..n {
        let t0 = monotonic_ns();
        let t1 = monotonic_ns();
        h.saturating_record(t1.saturating_sub(t0));
    }
    h
}

/// The step-cost phase: every case of [`crate::configs::step_cases`] measured by
/// [`measure`] on the pinned RT core, then [`timer_overhead`]; the rows (one per case, with
/// its share of the period, and the timer overhead's), distributions written into `dir`.
pub fn step_phase(s: &Settings, dir: &Path) -> Vec<Measured> {
    let cases = crate::configs::step_cases();
    let (warmup, steps) = (s.step_warmup, s.steps);
    let run = match timed_on_rt_core(
        s.rt_core,
        dir,
        "bench-step",
        ("step-cost", "step cost"),
        move || {
            let results: Vec<_> = cases
                .iter()
                .map(|c| (c.clone(), measure(c, warmup, steps)))
                .collect();
            (results, timer_overhead(steps))
        },
    ) {
        Ok(run) => run,
        Err(failed) => return vec![*failed],
    };
    let (setup, (results, overhead)) = (run.setup, run.value);
    let (start, elapsed) = (run.start, run.elapsed);
    let mut out = Vec::new();
    for (case, r) in results {
        let id = format!("step-{}", case.slug);
        let label = format!("step: {}", case.name);
        match r {
            Ok((h, _kind)) => {
                let files =
                    hist::write_files(dir, &case.slug, &h, start, elapsed).unwrap_or_default();
                let sum = Summary::of(&h);
                let mut m = Measured::from_summary(&id, &label, sum, files);
                let pct = |ns: u64| 100.0 * ns as f64 / PERIOD_NS as f64;
                m.note = format!(
                    "of 125 µs: p99 {:.2} %, max {:.1} %",
                    pct(sum.p99_ns),
                    pct(sum.max_ns)
                );
                out.push(m);
            }
            Err(e) => out.push(Measured::failed(&id, &label, e)),
        }
    }
    let files =
        hist::write_files(dir, "timer-overhead", &overhead, start, elapsed).unwrap_or_default();
    let mut m = Measured::from_summary(
        "timer-overhead",
        "  timer overhead (2× clock_gettime)",
        Summary::of(&overhead),
        files,
    );
    m.note = format!("inside every step value; step thread: {}", setup.describe());
    out.push(m);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_configuration_can_be_stepped_and_timed() {
        for case in crate::configs::step_cases() {
            let (h, kind) = measure(&case, 10, 100).unwrap();
            assert_eq!(h.len(), 100, "{}", case.name);
            let expected = ["rcac", "appc", "rc-mrac"]
                .into_iter()
                .find(|k| case.slug.starts_with(&format!("{k}-")))
                .unwrap_or("lti");
            assert_eq!(kind, expected, "{}", case.name);
        }
        assert_eq!(timer_overhead(50).len(), 50);
    }

    /// The RCAC cases are timed past `k_w` (the warm-up is raised to `min_warmup` even
    /// when the bench asks for less), on steps where the update runs: `θ` has moved
    /// from `θ_0 = 0` and the applied input is nonzero.
    #[test]
    fn rcac_cases_are_timed_on_updating_steps() {
        let cases: Vec<_> = crate::configs::step_cases()
            .into_iter()
            .filter(|c| c.slug.starts_with("rcac"))
            .collect();
        assert_eq!(cases.len(), 3);
        for case in cases {
            let cfg = ServiceConfig::parse(&case.toml, "bench").unwrap();
            let mut c = cfg.controller.build(cfg.counts).unwrap();
            assert!(case.min_warmup > crate::configs::RCAC_KW);
            let plant = case.plant.as_ref().unwrap();
            let mut lp = Loop::new(plant, 1, 2);
            let (mut z, mut u) = ([0.0; 1], [0.0; 2]);
            for k in 0..case.min_warmup {
                lp.output(k, &mut z);
                c.step(
                    &StepInput {
                        seq: k,
                        y: &z,
                        z: &z,
                        r: &[],
                        ..Default::default()
                    },
                    &mut u,
                );
                lp.apply(&u);
            }
            let norm = internal(c.as_ref(), "theta_norm").unwrap();
            assert!(
                norm > 0.0 && norm.is_finite(),
                "{}: |θ| = {norm}",
                case.name
            );
            assert!(u.iter().any(|v| *v != 0.0), "{}", case.name);
            assert_eq!(internal(c.as_ref(), "resets"), Some(0.0), "{}", case.name);
        }
    }
}
