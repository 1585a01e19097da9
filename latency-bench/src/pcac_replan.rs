//! Cost per sample period of PCAC re-planning every `N` samples
//! (`control::pcac::PcacParams::replan_every`), against a solve at every sample in the
//! same run.
//!
//! ## What is timed
//!
//! The truss workload of [`crate::pcac_cost`] (its plant, [`truss_params`], next-step
//! timing) is run once per re-planning period `N` of the list, each from the same start
//! and seeds, and `Controller::step` is timed alone between two `CLOCK_MONOTONIC` readings
//! at every sample, as there. With `N = 1` every sample carries a whole solve
//! (identification, prediction, condensing, QP); with `N > 1` a sample carries the
//! identification and at most one unit of the solve spread over the cycle
//! (`control::pcac::replan`: prediction at position 0, condensing at 1, the QP at 2; with
//! `N = 2` prediction and condensing at 0), so the figure of merit is the **worst period**
//! (p99, max) against the single-rate step. Each period is also recorded by its position
//! in the cycle, so the table shows which unit costs what. The loops take no lost or late
//! samples (the bench has no transport), so every cycle runs to its end and the position
//! is `seq mod N`. With `--qp-share B` each `N ≥ 4` is timed a second time with the QP
//! cut into shares of `B` active-set changes per period
//! (`control::pcac::PcacParams::qp_changes_per_period`): its factorization, start point
//! and first share at position 2, a share at each later position, the rest at `N − 1`.
//!
//! What this does not show: the closed loop's performance with the plan held for `N`
//! samples. That is the controller's tests' and the rigs' business (the acoustic rig's
//! PCAC scenario reports its tones).

use crate::hist::new_histogram;
use crate::pcac_cost::{BLOCK, REWARM, truss_params, truss_plant};
use control::status;
use control::{Controller, StepInput};
use hdrhistogram::Histogram;
use ipc_types::ChannelCounts;
use ipc_types::clock::monotonic_ns;

/// The re-planning periods `latency-bench pcac` times when not told otherwise.
pub const DEFAULT_PERIODS: [usize; 3] = [2, 3, 4];

/// Which re-planning runs to time: each period `N` of `every`, and each `N ≥ 4` a second
/// time with the QP in shares of `qp_share` active-set changes when `qp_share > 0`.
#[derive(Debug, Clone, Copy)]
pub struct Runs<'a> {
    /// The re-planning periods `N`.
    pub every: &'a [usize],
    /// The QP's share per period (`--qp-share`; 0: no second run).
    pub qp_share: usize,
}

/// The periods of one re-planning period `N`.
#[derive(Debug)]
pub struct ReplanCost {
    /// `N`.
    pub every: usize,
    /// The QP's share per period in active-set changes
    /// (`control::pcac::PcacParams::qp_changes_per_period`; 0: the whole QP at position 2).
    pub share: usize,
    /// Every timed period.
    pub period: Histogram<u64>,
    /// The timed periods by their position in the cycle, the last entry for the
    /// positions after the QP's (`min(N, 4)` entries are used).
    pub by_position: [Histogram<u64>; 4],
    /// Periods at the start of a block (recorded apart, as in [`crate::pcac_cost`]).
    pub cold: Histogram<u64>,
    /// Solves started over the whole run (the controller's `mpc steps`).
    pub solves: u64,
    /// Solves that fell back.
    pub fallbacks: u64,
    /// Periods whose input sat on a bound.
    pub saturated: u64,
}

/// Runs the truss workload with re-planning every `every` samples, the QP in shares of
/// `share` active-set changes per period when `share > 0` (`every ≥ 4`): `warmup` untimed
/// samples, then `steps` timed periods (the first [`REWARM`] of each block of [`BLOCK`]
/// recorded apart).
///
/// # Errors
///
/// The plant or the controller could not be built, or the plant refused an input.
pub fn measure(every: usize, share: usize, warmup: u64, steps: u64) -> Result<ReplanCost, String> {
    let mut plant = truss_plant()?;
    let mut params = truss_params();
    params.replan_every = every;
    params.qp_changes_per_period = share;
    let (p, m) = (params.model.p, params.model.m);
    let counts = ChannelCounts::new(p, p, 0, m).map_err(|e| e.to_string())?;
    let mut c = control::pcac::Pcac::new(&params, service::wire::dimensions(counts))
        .map_err(|e| format!("re-planning every {every}: {e}"))?;
    let (mut y, mut z, mut r, mut u) = (
        vec![0.0; plant.n_y()],
        vec![0.0; plant.n_z()],
        vec![0.0; plant.n_r()],
        vec![0.0; m],
    );
    let mut out = ReplanCost {
        every,
        share,
        period: new_histogram(),
        by_position: std::array::from_fn(|_| new_histogram()),
        cold: new_histogram(),
        solves: 0,
        fallbacks: 0,
        saturated: 0,
    };
    for seq in 0..warmup + steps {
        plant
            .sample(&mut y, &mut z, &mut r)
            .map_err(|e| e.to_string())?;
        let input = StepInput {
            seq,
            y: &y,
            z: &z,
            r: &r,
            ..Default::default()
        };
        let t0 = monotonic_ns();
        let st = c.step(&input, &mut u);
        let dt = monotonic_ns().saturating_sub(t0);
        plant.advance(&u).map_err(|e| e.to_string())?;
        if seq < warmup {
            continue;
        }
        let timed = seq - warmup;
        if timed % BLOCK < REWARM {
            out.cold.saturating_record(dt);
            continue;
        }
        out.period.saturating_record(dt);
        let pos = usize::try_from(seq % every as u64).unwrap_or(0).min(3);
        out.by_position[pos].saturating_record(dt);
        if st & status::SATURATED != 0 {
            out.saturated += 1;
        }
    }
    let k = c.counts_of();
    out.solves = k.steps;
    out.fallbacks = k.fallbacks;
    if u.iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "re-planning every {every}: the input is not finite"
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Re-planning every 3 samples solves once per 3 samples, and the periods are
    /// recorded by their position; with a solve at every sample there is one position.
    #[test]
    fn the_solves_and_positions_follow_the_period() {
        let three = measure(3, 0, 30, 300).unwrap();
        assert_eq!(three.solves, 330 / 3);
        assert_eq!(three.fallbacks, 0);
        let recorded: u64 = three.by_position[..3].iter().map(|h| h.len()).sum();
        assert_eq!(recorded, three.period.len());
        assert!(three.by_position.iter().take(3).all(|h| h.len() > 90));
        assert_eq!(three.period.len() + three.cold.len(), 300);
        let one = measure(1, 0, 30, 300).unwrap();
        assert_eq!(one.solves, 330);
        assert_eq!(one.by_position[0].len(), one.period.len());
    }

    /// With the QP in shares (N = 5, 2 changes per period), the run solves as often, with
    /// no fallback, and records all five positions.
    #[test]
    fn the_qp_in_shares_solves_as_often() {
        let shared = measure(5, 2, 30, 300).unwrap();
        assert_eq!(shared.share, 2);
        assert_eq!(shared.solves, 330 / 5);
        assert_eq!(shared.fallbacks, 0);
        let recorded: u64 = shared.by_position.iter().map(|h| h.len()).sum();
        assert_eq!(recorded, shared.period.len());
    }
}
