//! A DAQ process in a page: a loopback device (the DAC output wired back to the ADC input)
//! as a plant of the contract.
//!
//! ```text
//! cargo run --release -p plant-side --example loopback_daq -- RIG [STEPS] [lockstep|real-time] [PERIOD_US] [INITIAL]
//! ```
//!
//! The device has one input and one output: `y_k = z_k = u_{k−1}`, the value its DAC held
//! over the previous period, read back by its ADC at the sample instant; the DAC starts at
//! `INITIAL` (default 0). A real driver puts
//! its own calls where this one reads and writes `dac`: read the ADC channels in
//! [`PlantIo::read`], write the DAC in [`PlantIo::apply`], engage a hardware safe state in
//! [`PlantIo::apply_safe`]. Everything else (the clock, the contract, deadlines, late
//! answers, the watchdog, the report) is the plant side's.
//!
//! Start it, then the service on a scenario with the same rig name, counts and period.

use ipc_types::ChannelCounts;
use plant_side::{Input, Mode, PlantIo, PlantPolicy, PlantSide, PlantSideOptions, Sensors};
use std::process::ExitCode;

/// The RT-aware allocator: the loop thread's allocations (iceoryx2's per-sample loan state)
/// come from a private pool, with no lock and no system call.
#[global_allocator]
static ALLOCATOR: ipc_types::rt_alloc::RtAwareAllocator = ipc_types::rt_alloc::RtAwareAllocator;

/// The loopback device: what its DAC holds.
struct Loopback {
    dac: f64,
}

impl PlantIo for Loopback {
    type Error = std::convert::Infallible;

    fn read(&mut self, _k: u64, s: Sensors<'_>) -> Result<(), Self::Error> {
        s.y[0] = self.dac;
        s.z[0] = self.dac;
        Ok(())
    }

    fn apply(&mut self, _k: u64, input: &Input) -> Result<(), Self::Error> {
        self.dac = input.u[0];
        Ok(())
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(rig) = args.first() else {
        eprintln!("usage: loopback_daq RIG [STEPS] [lockstep|real-time] [PERIOD_US] [INITIAL]");
        return ExitCode::from(2);
    };
    let parse = |i: usize, default: u64, what: &str| -> Result<u64, String> {
        args.get(i).map_or(Ok(default), |s| {
            s.parse()
                .map_err(|_| format!("{what}: '{s}' is not a whole number"))
        })
    };
    let (steps, period_us) = match (parse(1, 1000, "STEPS"), parse(3, 1000, "PERIOD_US")) {
        (Ok(s), Ok(p)) if p > 0 => (s, p),
        (Err(e), _) | (_, Err(e)) => {
            eprintln!("loopback_daq: {e}");
            return ExitCode::from(2);
        }
        _ => {
            eprintln!("loopback_daq: PERIOD_US must be positive");
            return ExitCode::from(2);
        }
    };
    let initial = match args.get(4).map(|s| s.parse::<f64>()) {
        None => 0.0,
        Some(Ok(v)) if v.is_finite() => v,
        Some(_) => {
            eprintln!(
                "loopback_daq: INITIAL: '{}' is not a finite number",
                args[4]
            );
            return ExitCode::from(2);
        }
    };
    let mut policy = PlantPolicy::new(1);
    policy.mode = match args.get(2).map(String::as_str) {
        None | Some("lockstep") => Mode::Lockstep,
        Some("real-time") => Mode::RealTime,
        Some(other) => {
            eprintln!("loopback_daq: mode '{other}' is neither lockstep nor real-time");
            return ExitCode::from(2);
        }
    };
    let counts = ChannelCounts::new(1, 1, 0, 1).expect("one channel each is a valid count");
    let mut opts = PlantSideOptions::new("loopback-daq");
    opts.verbose = true;
    let result =
        PlantSide::connect(rig, counts, period_us * 1000, policy, opts).and_then(|mut side| {
            plant_side::run(&mut side, &mut Loopback { dac: initial }, steps, None)?;
            Ok(side.finish())
        });
    match result {
        Ok(report) => {
            println!("done: {}", report.summary_line());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("loopback_daq: {e}");
            ExitCode::FAILURE
        }
    }
}
