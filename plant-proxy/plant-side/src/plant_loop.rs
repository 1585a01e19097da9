//! The plant's loop over a small I/O trait: what a DAQ process (or a simulation) writes to
//! become a plant of the contract.
//!
//! [`PlantIo`] is the device: read the sensors for sample `k`, apply an input, apply the
//! safe output. [`run`] is the loop around it, on a connected [`PlantSide`]:
//!
//! - **real time**: sample `k` is due at `t_k = t_0 + kT` on `CLOCK_MONOTONIC`
//!   ([`SampleClock`]; `overrun` says what happens when the loop itself wakes more than a
//!   period late). With a deadline `d > 0` the loop reads and publishes at `t_k`, then decides
//!   the input at `t_k + dT` and applies it. With `d = 0` the input is latched at the sample
//!   clock, as a DAC driven by the ADC clock does: at `t_k` the loop decides the input for
//!   `k` from what it holds, then reads and publishes `M_k`, then applies it.
//! - **lockstep**: after publishing `M_k` the loop waits until the service has answered
//!   `M_k` (or `lockstep-timeout`), then applies the input for `k`. A run is as fast as
//!   possible and bit-for-bit deterministic for a deterministic device.
//!
//! A device whose own hardware clock paces the samples (an ADC clock) does not use [`run`]:
//! it calls [`PlantSide::publish`] and [`PlantSide::take`] from its own loop (the C and
//! Python interfaces offer exactly that).
//!
//! ```no_run
//! use plant_side::{Input, PlantIo, PlantPolicy, PlantSide, PlantSideOptions, Sensors};
//! use ipc_types::ChannelCounts;
//!
//! /// A wire from the DAC back to the ADC: y_k = u_{k-1}.
//! struct Loopback(f64);
//!
//! impl PlantIo for Loopback {
//!     type Error = std::convert::Infallible;
//!     fn read(&mut self, _k: u64, s: Sensors<'_>) -> Result<(), Self::Error> {
//!         s.y[0] = self.0;
//!         s.z[0] = self.0;
//!         Ok(())
//!     }
//!     fn apply(&mut self, _k: u64, input: &Input) -> Result<(), Self::Error> {
//!         self.0 = input.u[0];
//!         Ok(())
//!     }
//! }
//!
//! let counts = ChannelCounts::new(1, 1, 0, 1).unwrap();
//! let mut side = PlantSide::connect(
//!     "loopback",
//!     counts,
//!     1_000_000,
//!     PlantPolicy::new(1),
//!     PlantSideOptions::new("loopback"),
//! )
//! .unwrap();
//! plant_side::run(&mut side, &mut Loopback(0.0), 1000, None).unwrap();
//! println!("{}", side.finish().summary_line());
//! ```

use crate::plant_side::{Input, InputKind, PlantError, PlantSide, Wait};
use crate::policy::Mode;
use crate::sample_clock::SampleClock;
use ipc_types::clock::monotonic_ns;
use ipc_types::ports::Applies;
use ipc_types::timing_rules::application_instant;
use ipc_types::{MAX_R, MAX_Y, MAX_Z, measurement_flags};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};

/// Blocks of the loop thread's allocation pool (iceoryx2 holds one or two at once).
const RT_POOL_BLOCKS: usize = 64;

/// The sensor values of one sample, to be filled by [`PlantIo::read`]: exactly the
/// connected counts of `y`, `z` and `r`.
#[derive(Debug)]
pub struct Sensors<'s> {
    /// The measured outputs `y_k`.
    pub y: &'s mut [f64],
    /// The performance variables `z_k`.
    pub z: &'s mut [f64],
    /// The commands `r_k`.
    pub r: &'s mut [f64],
}

/// A plant's I/O device: what [`run`] asks of it once per sample.
pub trait PlantIo {
    /// A failure of the device, which ends the run with [`PlantError::Io`].
    type Error: fmt::Display;

    /// Reads the sensors of sample `k` (at its sample instant).
    fn read(&mut self, k: u64, sensors: Sensors<'_>) -> Result<(), Self::Error>;

    /// Applies the input of sample `k` (the service's answer, a plan entry, or the held or
    /// safe input of a miss; `input.kind` says which).
    fn apply(&mut self, k: u64, input: &Input) -> Result<(), Self::Error>;

    /// Applies the watchdog's safe output for sample `k` (`input.u` is the policy's safe
    /// input). By default the same as [`PlantIo::apply`]; a device with a hardware safe state
    /// (a brake, an amplifier's disable line) engages it here.
    fn apply_safe(&mut self, k: u64, input: &Input) -> Result<(), Self::Error> {
        self.apply(k, input)
    }

    /// Lockstep test runs: whether sample `k` is published with `INJECTED_STALL`. No device
    /// stalls by default.
    fn stalled(&self, _k: u64) -> bool {
        false
    }

    /// Lockstep test runs: whether sample `k` is lost (measured and applied, never
    /// published). No device loses samples by default.
    fn lost(&self, _k: u64) -> bool {
        false
    }
}

/// Runs `steps` samples of `io` on the connected `side` (see the [module
/// documentation](self)), until the last or until `shutdown` is set. In real time the
/// thread is first set up as `side.policy().rt` asks (pinning, `SCHED_FIFO`, `mlockall`),
/// and the outcome is put in the report. The thread then gets its allocation pool
/// ([`ipc_types::rt_alloc`]; install `RtAwareAllocator` as the process's global allocator
/// for it to serve), and its allocations during the loop go into the report
/// (`rt_allocations`), as do the clock's slips.
pub fn run<Io: PlantIo>(
    side: &mut PlantSide<'_>,
    io: &mut Io,
    steps: u64,
    shutdown: Option<&AtomicBool>,
) -> Result<(), PlantError> {
    let policy = side.policy().clone();
    let label = side.label().to_string();
    let c = side.counts();
    let (n_y, n_z, n_r) = (c.n_y as usize, c.n_z as usize, c.n_r as usize);
    side.report_mut().rt_setup = if policy.mode == Mode::RealTime {
        let s = ipc_types::rt::setup_current_thread(&policy.rt);
        if s.any_refused() {
            eprintln!(
                "[{label}] WARNING: real-time set-up incomplete: {}",
                s.describe()
            );
        }
        s.describe()
    } else {
        "lockstep: none requested".to_string()
    };
    let period_ns = side.period_ns();
    let mut clock = SampleClock::new(
        monotonic_ns() + 2 * period_ns.max(1_000_000),
        period_ns,
        policy.overrun,
    );
    let latch_at_sample = policy.applies() == Applies::AtSample;
    let deadline_ns = side.deadline_offset_ns();
    let (mut y, mut z, mut r) = ([0.0; MAX_Y], [0.0; MAX_Z], [0.0; MAX_R]);
    let io_err = |what: &str, k: u64, e: &dyn fmt::Display| {
        PlantError::Io(format!("{what} at sample {k}: {e}"))
    };
    // iceoryx2 allocates a small state per published sample: from a private pool when the
    // process installed `ipc_types::rt_alloc::RtAwareAllocator`, counted either way.
    ipc_types::rt_alloc::enter_rt_thread(RT_POOL_BLOCKS);
    let allocations_before = ipc_types::rt_alloc::thread_stats();
    let result = (|| {
        let mut previous_published = false;
        for k in 0..steps {
            if shutdown.is_some_and(|s| s.load(Ordering::Relaxed)) {
                break;
            }
            let (t_k, early) = match policy.mode {
                Mode::RealTime => {
                    let t = clock.wait(k);
                    let early = if latch_at_sample {
                        side.take(k, Wait::Now)?
                    } else {
                        None
                    };
                    (t, early)
                }
                Mode::Lockstep => (monotonic_ns(), None),
            };
            io.read(
                k,
                Sensors {
                    y: &mut y[..n_y],
                    z: &mut z[..n_z],
                    r: &mut r[..n_r],
                },
            )
            .map_err(|e| io_err("reading the sensors", k, &e))?;
            let mut extra = 0;
            if k + 1 == steps {
                extra |= measurement_flags::LAST_SAMPLE;
            }
            if policy.mode == Mode::Lockstep && io.stalled(k) {
                extra |= measurement_flags::INJECTED_STALL;
            }
            // The last sample is always published: it tells the service the run ended.
            let lost = policy.mode == Mode::Lockstep && k + 1 != steps && io.lost(k);
            let flags = if lost {
                0
            } else {
                side.publish(k, t_k, [&y[..n_y], &z[..n_z], &r[..n_r]], extra)?
            };
            let input = match (early, policy.mode) {
                // Never published: its input is decided as at a deadline, from what the
                // service had sent for it by its answer to the previous sample.
                (_, Mode::Lockstep) if lost && previous_published => {
                    side.take(k, Wait::LockstepAhead)?
                }
                (_, Mode::Lockstep) if lost => side.take(k, Wait::Now)?,
                (Some(mut i), _) => {
                    i.published_flags = flags;
                    Some(i)
                }
                (None, Mode::RealTime) if latch_at_sample => None,
                (None, Mode::RealTime) => {
                    side.take(k, Wait::At(application_instant(t_k, deadline_ns)))?
                }
                (None, Mode::Lockstep) => side.take(k, Wait::Lockstep)?,
            };
            previous_published = !lost;
            let Some(input) = input else { break };
            match input.kind {
                InputKind::WatchdogSafe => io.apply_safe(k, &input),
                _ => io.apply(k, &input),
            }
            .map_err(|e| io_err("applying the input", k, &e))?;
        }
        Ok(())
    })();
    let report = side.report_mut();
    report.rt_allocations = ipc_types::rt_alloc::thread_stats().since(&allocations_before);
    report.clock_slips = clock.slips();
    report.slipped_s = clock.slipped_ns() as f64 * 1e-9;
    match result {
        Err(PlantError::GaveUp {
            message,
            report: mut r,
        }) => {
            r.clock_slips = clock.slips();
            r.slipped_s = clock.slipped_ns() as f64 * 1e-9;
            Err(PlantError::GaveUp { message, report: r })
        }
        other => other,
    }
}
