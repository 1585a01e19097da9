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
//! Each value contains one `clock_gettime` (vDSO) call's worth of overhead;
//! [`timer_overhead`] measures it (two back-to-back readings) so that the smallest step
//! costs can be read against it.

use crate::configs::StepCase;
use crate::hist::new_histogram;
use hdrhistogram::Histogram;
use ipc_types::clock::monotonic_ns;
use ipc_types::{MAX_R, MAX_U, MAX_Y, MAX_Z};
use service::config::ServiceConfig;
use service::controller::StepInput;

/// Length of the precomputed input table.
const TABLE: usize = 1024;

/// Builds `case` through the service's configuration path and times `steps` steps after
/// `warmup` untimed ones. Returns the histogram of step durations (ns) and the controller
/// kind.
pub fn measure(
    case: &StepCase,
    warmup: u64,
    steps: u64,
) -> Result<(Histogram<u64>, &'static str), String> {
    let cfg = ServiceConfig::parse(&case.toml, "bench").map_err(|e| e.to_string())?;
    let mut controller = cfg.controller.build(cfg.counts)?;
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
    let z = [0.0; MAX_Z];
    let r = [0.0; MAX_R];
    let mut u = [0.0; MAX_U];
    let mut h = new_histogram();
    for k in 0..warmup + steps {
        let y = &ys[(k as usize) % TABLE];
        let input = StepInput {
            seq: k,
            y: &y[..n_y],
            z: &z[..n_z],
            r: &r[..n_r],
        };
        let t0 = monotonic_ns();
        let status = controller.step(&input, &mut u[..n_u]);
        let t1 = monotonic_ns();
        core::hint::black_box((status, &u));
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
    Ok((h, controller.kind()))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_configuration_can_be_stepped_and_timed() {
        for case in crate::configs::step_cases() {
            let (h, kind) = measure(&case, 10, 100).unwrap();
            assert_eq!(h.len(), 100, "{}", case.name);
            assert_eq!(kind, "lti");
        }
        assert_eq!(timer_overhead(50).len(), 50);
    }
}
