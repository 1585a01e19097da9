//! Opening a client on a JACK server and wiring its ports, with errors that name the
//! server, the port and the fix.
//!
//! libjack is loaded at run time (the `jack` crate's `dynamic_loading`): a box without it
//! gets an error that says which package brings it. A client never starts a server
//! (`JackNoStartServer`): the server, its sample rate and its period are the user's
//! choice (`jackd -n NAME -R -d alsa -r 8000 -p 64`, or `-d dummy` without a card), and the
//! client checks them against the scenario.

use jack::{Client, ClientOptions, ClientStatus, Port, PortFlags, Unowned};
use std::fmt;

/// Why a JACK client could not be set up.
#[derive(Debug, Clone, PartialEq)]
pub struct JackError(pub String);

impl fmt::Display for JackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for JackError {}

/// The name of the server a client of `server` talks to: the given name, else
/// `$JACK_DEFAULT_SERVER`, else `default` (libjack's own rule).
pub fn server_name(server: Option<&str>) -> String {
    server
        .map(str::to_string)
        .or_else(|| std::env::var("JACK_DEFAULT_SERVER").ok())
        .unwrap_or_else(|| "default".to_string())
}

/// Opens client `name` on server `server` (see [`server_name`]) without starting a server.
///
/// libjack reads the server's name from `$JACK_DEFAULT_SERVER` (the `jack` crate does not
/// pass `JackServerName`'s argument), so a named server is selected by setting that
/// variable for this process first: call it before any other thread reads the environment.
pub fn open_client(server: Option<&str>, name: &str) -> Result<Client, JackError> {
    if let Some(s) = server {
        // SAFETY: called by the binaries' set-up, before they start any thread of their own
        // (libjack's threads start with the client, after this).
        unsafe { std::env::set_var("JACK_DEFAULT_SERVER", s) };
    }
    let server = server_name(server);
    let opts = ClientOptions::NO_START_SERVER | ClientOptions::USE_EXACT_NAME;
    match Client::new(name, opts) {
        Ok((client, _)) => Ok(client),
        Err(jack::Error::LibraryError(m)) => Err(JackError(format!(
            "libjack could not be loaded ({m}): install JACK (Debian: apt-get install jackd2, which brings libjack.so.0)"
        ))),
        Err(jack::Error::ClientError(status)) => {
            Err(JackError(describe_open_failure(&server, name, status)))
        }
        Err(e) => Err(JackError(format!(
            "JACK client '{name}' on server '{server}': {e}"
        ))),
    }
}

/// The message of a refused `jack_client_open`.
fn describe_open_failure(server: &str, name: &str, status: ClientStatus) -> String {
    if status.contains(ClientStatus::NAME_NOT_UNIQUE) {
        format!(
            "JACK server '{server}' already has a client named '{name}' (another plant side or room still running?): stop it or choose another jack.client"
        )
    } else if status.contains(ClientStatus::SERVER_FAILED)
        || status.contains(ClientStatus::SERVER_ERROR)
    {
        format!(
            "no JACK server named '{server}' is running (JACK client '{name}' could not connect): start one, e.g. `jackd -n {server} -R -d alsa -r 8000 -p 64` with a card or `jackd -n {server} -d dummy -r 8000 -p 64` without, or set jack.server"
        )
    } else {
        format!("JACK server '{server}' refused client '{name}' (status {status:?})")
    }
}

/// Checks that the server runs at the scenario's rate (`period_ns` per sample, from
/// `origin`) and, when given, with `period_frames` frames per period.
pub fn check_timing(
    client: &Client,
    server: &str,
    period_ns: u64,
    period_frames: Option<u32>,
    origin: &str,
) -> Result<(), JackError> {
    let rate = client.sample_rate() as u64;
    let server_period_ns = (1_000_000_000 + rate / 2) / rate.max(1);
    if server_period_ns != period_ns {
        let want = 1e9 / period_ns as f64;
        return Err(JackError(format!(
            "JACK server '{server}' runs at {rate} Hz, but {origin}'s rig.sample-period ({} s) is {want} Hz: start the server with -r {} or change the scenario's rate",
            period_ns as f64 * 1e-9,
            want.round()
        )));
    }
    let frames = client.buffer_size();
    if let Some(p) = period_frames
        && p != frames
    {
        return Err(JackError(format!(
            "JACK server '{server}' runs with periods of {frames} frames, but {origin}'s jack.period-frames is {p}: start the server with -p {p} (or `jack_bufsize {p}`) or change jack.period-frames"
        )));
    }
    Ok(())
}

/// What a port of ours is connected to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Our input, fed from another client's output (a capture port).
    Capture,
    /// Our output, driving another client's input (a playback port).
    Playback,
}

/// Checks that `other` exists on the server and can be connected to one of our ports of
/// `direction`; `field` names the scenario field that listed it (`jack.u[1]`).
pub fn find_peer_port(
    client: &Client,
    server: &str,
    other: &str,
    direction: Direction,
    field: &str,
) -> Result<Port<Unowned>, JackError> {
    let Some(port) = client.port_by_name(other) else {
        let wanted = match direction {
            Direction::Capture => PortFlags::IS_OUTPUT,
            Direction::Playback => PortFlags::IS_INPUT,
        };
        let mut known = client.ports(None, Some("audio"), wanted);
        known.truncate(12);
        return Err(JackError(format!(
            "{field}: JACK server '{server}' has no port '{other}'; its audio {} ports are: {}",
            match direction {
                Direction::Capture => "output (capture)",
                Direction::Playback => "input (playback)",
            },
            if known.is_empty() {
                "none".to_string()
            } else {
                known.join(", ")
            }
        )));
    };
    let flags = port.flags();
    match direction {
        Direction::Capture if !flags.contains(PortFlags::IS_OUTPUT) => Err(JackError(format!(
            "{field}: '{other}' is an input (playback) port; a measurement is read from an output port (a capture port, or another client's output)"
        ))),
        Direction::Playback if !flags.contains(PortFlags::IS_INPUT) => Err(JackError(format!(
            "{field}: '{other}' is an output (capture) port; an input u drives an input port (a playback port, or another client's input)"
        ))),
        _ => Ok(port),
    }
}

/// Connects `from` (an output) to `to` (an input), naming both on failure.
pub fn connect(client: &Client, from: &str, to: &str, field: &str) -> Result<(), JackError> {
    match client.connect_ports_by_name(from, to) {
        Ok(()) | Err(jack::Error::PortAlreadyConnected(..)) => Ok(()),
        Err(e) => Err(JackError(format!(
            "{field}: connecting '{from}' to '{to}' failed: {e}"
        ))),
    }
}

/// Sets the server's freewheel mode: the graph runs as fast as its clients allow, without
/// the driver's clock and without real-time deadlines (libjack's `jack_set_freewheel`).
pub fn set_freewheel(client: &Client, on: bool) -> Result<(), JackError> {
    // SAFETY: the client is open (it outlives this call); the library is loaded (a client
    // could only be opened through it).
    let rc = unsafe { jack_sys::jack_set_freewheel(client.raw(), i32::from(on)) };
    if rc == 0 {
        Ok(())
    } else {
        Err(JackError(format!(
            "the JACK server refused to {} freewheeling (jack_set_freewheel returned {rc})",
            if on { "start" } else { "stop" }
        )))
    }
}
