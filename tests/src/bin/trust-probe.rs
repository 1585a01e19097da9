//! `trust-probe`: a foreign local process for the trust tests (`tests/tests/trust_*.rs`).
//!
//! It plays what a rogue process on the same machine could try against a rig, with plain
//! iceoryx2 calls and none of the checks of `ipc_types::ports::connect`:
//!
//! ```text
//! trust-probe publish <rig> <seconds>    open adaptive-rig/<rig>/actuation, create a publisher,
//!                                        publish u = 50 every millisecond for <seconds>
//! trust-probe subscribe <rig> <seconds>  open adaptive-rig/<rig>/measurement, create a
//!                                        subscriber, hold it for <seconds>
//! ```
//!
//! It prints `trust-probe: pid N` first, then `trust-probe: refused: …` and exits with 3
//! when iceoryx2 refuses the port, or `trust-probe: publishing` / `trust-probe: subscribed`
//! and exits with 0 after `<seconds>`. Exit status 2: bad arguments or the service did not
//! appear within 20 s.

use iceoryx2::prelude::*;
use ipc_types::{Actuation, ChannelCounts, Measurement};
use std::process::ExitCode;
use std::time::{Duration, Instant};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (Some(mode), Some(rig), Some(secs)) = (args.get(1), args.get(2), args.get(3)) else {
        eprintln!("usage: trust-probe publish|subscribe <rig> <seconds>");
        return ExitCode::from(2);
    };
    let Ok(secs) = secs.parse::<f64>() else {
        eprintln!("trust-probe: '{secs}' is not a number of seconds");
        return ExitCode::from(2);
    };
    eprintln!("trust-probe: pid {}", std::process::id());
    set_log_level(LogLevel::Fatal);
    let node = match NodeBuilder::new()
        .name(&"trust-probe".try_into().expect("a valid node name"))
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
    {
        Ok(n) => n,
        Err(e) => {
            eprintln!("trust-probe: refused: creating a node: {e:?}");
            return ExitCode::from(3);
        }
    };
    let hold = Duration::from_secs_f64(secs.max(0.0));
    match mode.as_str() {
        "publish" => publish(&node, rig, hold),
        "subscribe" => subscribe(&node, rig, hold),
        other => {
            eprintln!("trust-probe: unknown mode '{other}'");
            ExitCode::from(2)
        }
    }
}

/// Opens the publish-subscribe service `name` of payload `T` as it is, retrying for 20 s.
fn open<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Option<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>> {
    let name: ServiceName = name.try_into().ok()?;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(20) {
        if let Ok(f) = node.service_builder(&name).publish_subscribe::<T>().open() {
            return Some(f);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    eprintln!("trust-probe: the service did not appear within 20 s");
    None
}

fn publish(node: &Node<ipc::Service>, rig: &str, hold: Duration) -> ExitCode {
    let Some(f) = open::<Actuation>(node, &format!("adaptive-rig/{rig}/actuation")) else {
        return ExitCode::from(2);
    };
    let publisher = match f.publisher_builder().create() {
        Ok(p) => p,
        Err(e) => {
            eprintln!("trust-probe: refused: creating a publisher: {e:?}");
            return ExitCode::from(3);
        }
    };
    eprintln!("trust-probe: publishing");
    let mut a = Actuation::zeroed(ChannelCounts::new(1, 1, 0, 1).expect("valid counts"));
    a.u[0] = 50.0;
    let start = Instant::now();
    let mut k = 0;
    while start.elapsed() < hold {
        a.seq = k;
        let _ = publisher.send_copy(a);
        k += 1;
        std::thread::sleep(Duration::from_millis(1));
    }
    ExitCode::SUCCESS
}

fn subscribe(node: &Node<ipc::Service>, rig: &str, hold: Duration) -> ExitCode {
    let Some(f) = open::<Measurement>(node, &format!("adaptive-rig/{rig}/measurement")) else {
        return ExitCode::from(2);
    };
    let subscriber = match f.subscriber_builder().create() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("trust-probe: refused: creating a subscriber: {e:?}");
            return ExitCode::from(3);
        }
    };
    eprintln!("trust-probe: subscribed");
    let start = Instant::now();
    while start.elapsed() < hold {
        while let Ok(Some(_)) = subscriber.receive() {}
        std::thread::sleep(Duration::from_millis(5));
    }
    ExitCode::SUCCESS
}
