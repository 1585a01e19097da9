//! A sound card under JACK as the rig's DAQ.
//!
//! - [`daq`]: the plant side of the contract as a JACK client (`plant-jack run`): one
//!   input port per microphone, one output port per loudspeaker, the sample rate and the
//!   period taken from the server, each period's frames published in order and the
//!   service's answers applied with the contract's late policy and watchdog per sample,
//!   within a budget of the period.
//! - [`room`]: a scenario's simulated plant as another JACK client (`plant-jack room`),
//!   so that the whole loop (service, iceoryx2, the JACK plant side, the JACK server, the
//!   room) runs through a real audio server without a card, e.g. on `jackd -d dummy`.
//! - [`jack_config`]: the scenario's `[jack]` table; [`jack_server`]: opening a client
//!   and wiring ports, with errors that name the server and the port; [`jack_report`]:
//!   what a run reports besides the contract's counters.
//!
//! The delay a card adds: the plant the controller sees through JACK is the room (or the
//! structure) delayed by the capture and playback latencies of the ports (a period in, the
//! server's periods out, the converters). The design path identifies it from a logged run
//! through the card, so the FIR target model (3.39) of the dissertation carries it in its
//! leading zero Markov parameters (docs/connect-hardware.md, "A sound card").

pub mod daq;
pub mod jack_config;
pub mod jack_report;
pub mod jack_server;
pub mod room;
