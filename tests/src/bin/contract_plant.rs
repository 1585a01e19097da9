//! `contract_plant`: a Rust plant side that states a contract of its choosing, for the
//! cross-language refusal tests (`tests/tests/python_peers.rs`).
//!
//! ```text
//! contract_plant <rig> [--contract-version V] [--n-y N] [--period-ns P] [--at-sample] [--peer-timeout S]
//! ```
//!
//! It connects to rig `<rig>` as the plant with `ipc_types::ports::connect` (the code path
//! of plant-proxy, node name `adaptive-rig-plant`), one `z`, no `r`, one `u`, `N`
//! measurement channels (1 by default), a period of `P` ns (1 ms by default), stating
//! contract version `V` (this build's by default) and inputs applied in lockstep (with
//! `--at-sample`: at the sample instant, as a real-time plant with deadline 0). A refused
//! connection prints `contract_plant: <the ConnectError>` and exits with 1; a connection
//! made prints `contract_plant: connected` and exits with 0. Exit status 2: bad arguments.

use ipc_types::ports::{Applies, ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::{CONTRACT_VERSION, ChannelCounts};
use std::process::ExitCode;
use std::time::Duration;

/// The value after `--name` in `args`, parsed; `default` when absent.
fn option<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> Result<T, String> {
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{name} needs a number")),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(rig) = args.first().cloned() else {
        eprintln!(
            "usage: contract_plant <rig> [--contract-version V] [--n-y N] [--period-ns P] \
             [--at-sample] [--peer-timeout S]"
        );
        return ExitCode::from(2);
    };
    let parsed = (|| {
        Ok::<_, String>((
            option(&args, "--contract-version", CONTRACT_VERSION)?,
            option(&args, "--n-y", 1usize)?,
            option(&args, "--period-ns", 1_000_000u64)?,
            option(&args, "--peer-timeout", 30.0f64)?,
        ))
    })();
    let (version, n_y, period_ns, timeout) = match parsed {
        Ok(p) => p,
        Err(e) => {
            eprintln!("contract_plant: {e}");
            return ExitCode::from(2);
        }
    };
    let counts = match ChannelCounts::new(n_y, 1, 0, 1) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("contract_plant: {e}");
            return ExitCode::from(2);
        }
    };
    let applies = if args.iter().any(|a| a == "--at-sample") {
        Applies::AtSample
    } else {
        Applies::Lockstep
    };
    let mut own = ContractInfo::new(Side::Plant, counts, period_ns).with_applies(applies);
    own.version = version;
    let opts = ConnectOptions::new(Duration::from_secs_f64(timeout))
        .with_listener(true)
        .with_waiting_message("[contract_plant] waiting for the service ...");
    let ports: Result<PlantPorts, _> =
        ipc_types::ports::connect(&rig, own, "adaptive-rig-plant", opts);
    match ports {
        Ok(_) => {
            eprintln!("contract_plant: connected");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("contract_plant: {e}");
            ExitCode::FAILURE
        }
    }
}
