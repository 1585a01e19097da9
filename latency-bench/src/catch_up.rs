//! The service's answer-first loop around [`ArmPlant`] with the PCAC of
//! [`pcac_params`], replayed in virtual time: what falling behind and catching up costs
//! the PCAC arm case of the response-time phase, deterministic (the clock is the QP
//! iteration count).
//!
//! At period `T` each answered step costs [`STEP_US`] plus [`ITERATION_US`] per QP
//! iteration (the steady step and one dual active-set step at this size on this
//! machine), each caught-up sample 1 µs. Samples that arrive during a step are caught up
//! (`Ahead::advance` without adaptation, the newest [`BUFFER`], as the service's
//! subscriber keeps them; older ones lost and bridged), and the plant holds its input
//! when an answer misses `T/2`. Used by the unit test that the loop recovers and by the
//! example `arm_catch_up`.

use crate::synthetic_arm::{ARM_M, ARM_P, ArmPlant, pcac_params};
use control::pcac::Pcac;
use control::{Controller, MAX_INTERNALS, StepInput};

/// Cost model: a step without dual steps, µs.
pub const STEP_US: f64 = 65.0;
/// Cost model: one dual active-set step, µs.
pub const ITERATION_US: f64 = 10.0;
/// Samples the service's subscriber keeps.
pub const BUFFER: usize = 4;
/// Index of `qp_iterations` in PCAC's internals.
const ITERATIONS: usize = 5;
/// Index of `qp_active` in PCAC's internals.
const ACTIVE: usize = 6;

/// One answered step of a [`Replay`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answered {
    /// The sample answered.
    pub sample: usize,
    /// Samples lost just before it.
    pub lost: u64,
    /// Samples caught up just before it.
    pub caught_up: usize,
    /// Its QP iterations.
    pub iterations: f64,
    /// Its active constraints.
    pub active: f64,
    /// Its cost in the model, µs.
    pub cost_us: f64,
}

/// What [`replay`] saw.
pub struct Replay {
    /// Every answered step, in order.
    pub answered: Vec<Answered>,
    /// Answers published within `T/2` of their sample.
    pub in_time: u64,
    /// Samples caught up without an answer.
    pub observed: u64,
    /// Samples lost.
    pub lost: u64,
    /// The controller after the replay.
    pub controller: Pcac,
}

impl Replay {
    /// The mean QP iterations of the answered steps.
    pub fn mean_iterations(&self) -> f64 {
        let sum: f64 = self.answered.iter().map(|a| a.iterations).sum();
        sum / self.answered.len() as f64
    }
}

/// The loop (module docs) at period `period_us` over `n` samples.
pub fn replay(period_us: f64, n: usize) -> Replay {
    let counts = ipc_types::ChannelCounts::new(ARM_P, ARM_P, 0, ARM_M).expect("counts");
    let mut c = Pcac::new(&pcac_params(), service::wire::dimensions(counts)).expect("the arm PCAC");
    let mut plant = ArmPlant::new(7);
    let mut ys: Vec<[f64; ARM_P]> = Vec::with_capacity(n);
    let mut applied: Vec<[f64; ARM_M]> = Vec::with_capacity(n);
    // The answer to each sample and when it was published, µs.
    let mut answers: Vec<Option<([f64; ARM_M], f64)>> = vec![None; n];
    let mut internals = [0.0; MAX_INTERNALS];
    let (mut t, mut next) = (0.0f64, 0usize);
    let (mut lost_total, mut observed, mut in_time) = (0u64, 0u64, 0u64);
    let mut answered = Vec::new();
    let mut last_sent = [0.0; ARM_M];
    while next < n {
        t = t.max(next as f64 * period_us);
        let newest = ((t / period_us).floor() as usize).min(n - 1);
        let first = newest.saturating_sub(BUFFER - 1).max(next);
        let lost = (first - next) as u64;
        lost_total += lost;
        while ys.len() <= newest {
            let i = ys.len();
            if i > 0 {
                let held = if i > 1 { applied[i - 2] } else { [0.0; ARM_M] };
                let a = match answers[i - 1] {
                    Some((u, tp)) if tp <= (i - 1) as f64 * period_us + period_us / 2.0 => u,
                    _ => held,
                };
                applied.push(a);
                plant.advance(&a);
            }
            let mut y = [0.0; ARM_P];
            plant.sample(&mut y);
            ys.push(y);
        }
        for j in first..=newest {
            let input = StepInput {
                seq: j as u64,
                y: &ys[j],
                z: &ys[j],
                r: &[],
                u_applied: j.checked_sub(1).map(|p| &applied[p][..]),
                lost: if j == first { lost } else { 0 },
            };
            let ahead = c.ahead().expect("next-step PCAC answers ahead");
            if j < newest {
                ahead.advance(&input, &last_sent, false);
                observed += 1;
                t += 1.0;
                continue;
            }
            let mut ready = [0.0; ARM_M];
            ahead.ready(&mut ready);
            answers[j] = Some((ready, t + 1.0));
            last_sent = ready;
            in_time += u64::from(t + 1.0 <= j as f64 * period_us + period_us / 2.0);
            ahead.advance(&input, &ready, true);
            c.internals(&mut internals);
            let cost_us = STEP_US + ITERATION_US * internals[ITERATIONS];
            t += 1.0 + cost_us;
            answered.push(Answered {
                sample: j,
                lost,
                caught_up: newest - first,
                iterations: internals[ITERATIONS],
                active: internals[ACTIVE],
                cost_us,
            });
        }
        next = newest + 1;
    }
    Replay {
        answered,
        in_time,
        observed,
        lost: lost_total,
        controller: c,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PCAC loop at 2 kHz that falls behind (the first steps of the identification
    /// solve QPs of over 100 dual steps, ~1 ms) recovers: the samples caught up meanwhile
    /// keep the QP's warm start (moved along the horizon), so the steps after the gap are
    /// steady steps again. With the warm start dropped at every caught-up sample the same
    /// replay never recovered (514 of 4000 answers in time, 536 samples lost, 202 QP
    /// iterations per step).
    #[test]
    fn a_pcac_loop_that_falls_behind_recovers() {
        let n = 4000;
        let r = replay(500.0, n);
        let (in_time, lost, iterations) = (r.in_time, r.lost, r.mean_iterations());
        assert!(
            in_time as f64 >= 0.95 * n as f64,
            "{in_time} of {n} answers in time, {lost} samples lost, {iterations:.1} QP iterations per step"
        );
        assert!(iterations < 5.0, "{iterations:.1} QP iterations per step");
    }
}
