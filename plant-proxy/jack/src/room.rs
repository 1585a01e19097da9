//! The simulated room as a JACK client: plant-proxy's simulation of a scenario's plant
//! (the acoustic enclosure, the truss, any LTI plant) behind JACK ports, so that a loop
//! through a real audio server can be closed without a card.
//!
//! The client has one input port per plant input (`speaker-u0`, …: what a loudspeaker
//! plays) and one output port per measured output and performance variable (`mic-y0`, …,
//! `mic-z0`, …: what a microphone picks up). Each frame of each period is one sample
//! `k` of the simulation ([`plant_proxy::sim::PlantSim`], the same discretization as
//! plant-proxy's): the room writes `y_k`, `z_k` (with the scenario's disturbance and
//! noise) to the microphones, scaled by `1 / jack.y-full-scale` and clipped to `[−1, 1]`
//! as an ADC clips, then advances one period under the loudspeakers' frame `k` times
//! `jack.u-full-scale`, delayed by `jack.room.converter-delay` frames (a card's
//! converters).
//!
//! The room's time is the server's frames, as a real room's is the card's clock: it
//! advances one sample per frame of the server's clock, whether the server runs on its
//! driver's clock or freewheels. Frames the server's clock passed without calling the room
//! (an xrun) are simulated with silent loudspeakers, as a card's DAC plays silence when a
//! period is missed; so an xrun shifts neither the room against the plant side nor the
//! loop's delay. Its sample 0 is the first period in which every loudspeaker port is
//! connected; until then its microphones are silent. The plant side starts its samples
//! in that same period (it connects the loudspeakers last), so the room's sample `k` is
//! the plant side's sample `k`, and a lockstep run through the server (freewheeling) is
//! the same run every time.
//!
//! **Its latency.** The room sits in a loop with the plant side: the plant side's inputs
//! feed the loudspeakers and the microphones feed the plant side. JACK runs such a loop
//! with one of its connections a period late (the plant side connects the microphones
//! first, so the loudspeakers' is that one), which is what a card's playback does too. The
//! room states it: the playback latency of each loudspeaker port is one period plus the
//! converter delay (a latency callback, `jack_set_latency_callback`), so the plant side
//! reports the delay the loop through the server adds, as it does for a card's ports.
//!
//! `--xrun-at S` injects a fault for tests: at simulated second `S` the callback sleeps
//! for three periods, which makes the server miss its deadline (an xrun every client is
//! told of).

use crate::jack_config::JackConfig;
use ipc_types::{MAX_R, MAX_U, MAX_Y, MAX_Z};
use jack::{AudioIn, AudioOut, Client, Control, Port, ProcessScope};
use plant_proxy::sim::PlantSim;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The most frames one callback simulates to catch up with the server's clock (1 s at
/// 8 kHz): a longer gap is a stopped server, not an xrun.
pub const MAX_CATCH_UP: u32 = 8000;

/// What the room's callback counts, read by its main thread.
#[derive(Debug, Default)]
pub struct RoomCounters {
    /// Samples simulated.
    pub samples: AtomicU64,
    /// Microphone samples beyond full scale (written clipped to ±1).
    pub clipped: AtomicU64,
    /// Xruns the server notified.
    pub xruns: AtomicU64,
    /// Injected stalls done.
    pub stalls: AtomicU64,
    /// Frames the server's clock passed without the room's callback, simulated with
    /// silent loudspeakers.
    pub frames_caught_up: AtomicU64,
    /// Frames beyond [`MAX_CATCH_UP`] in one gap, not simulated (the room's time fell
    /// behind the server's by that much).
    pub frames_dropped: AtomicU64,
    /// The simulation failed, or the server went away: why.
    pub failure: Mutex<Option<String>>,
    /// Set with `failure`.
    pub failed: AtomicBool,
}

/// The room's process handler.
pub struct RoomProcess {
    sim: PlantSim,
    speakers: Vec<Port<AudioIn>>,
    mic_y: Vec<Port<AudioOut>>,
    mic_z: Vec<Port<AudioOut>>,
    u_scale: [f64; MAX_U],
    y_scale: [f64; MAX_Y],
    z_scale: [f64; MAX_Z],
    /// The converters' delay line: `delay + 1` inputs, `head` the newest.
    line: Vec<[f64; MAX_U]>,
    head: usize,
    /// Samples at which the callback stalls (sorted), and the next one.
    stalls: Vec<u64>,
    next_stall: usize,
    period_ns: u64,
    /// Every loudspeaker port is connected: the simulation runs.
    running: bool,
    /// The frame time and size of the latest period simulated.
    last_frame: Option<(jack::Frames, jack::Frames)>,
    counters: Arc<RoomCounters>,
}

impl RoomProcess {
    /// One sample of the room: the microphones' `y_k`, `z_k`, then a period under the
    /// loudspeakers' input `u` (`None`: a frame the server skipped, silence), through the
    /// converters' delay line.
    fn step(&mut self, u: Option<&[f64; MAX_U]>) -> Result<([f64; MAX_Y], [f64; MAX_Z]), String> {
        let k = self.counters.samples.load(Ordering::Relaxed);
        let (n_y, n_z, n_u, n_r) = (
            self.sim.n_y(),
            self.sim.n_z(),
            self.sim.n_u(),
            self.sim.n_r(),
        );
        let (mut y, mut z, mut r) = ([0.0; MAX_Y], [0.0; MAX_Z], [0.0; MAX_R]);
        let failed = |e| format!("the room's simulation failed at sample {k}: {e}");
        self.sim
            .sample(&mut y[..n_y], &mut z[..n_z], &mut r[..n_r])
            .map_err(failed)?;
        let depth = self.line.len();
        self.head = (self.head + 1) % depth;
        self.line[self.head] = u.copied().unwrap_or([0.0; MAX_U]);
        let oldest = self.line[(self.head + 1) % depth];
        self.sim.advance(&oldest[..n_u]).map_err(failed)?;
        self.counters.samples.fetch_add(1, Ordering::Relaxed);
        Ok((y, z))
    }

    fn fail(&self, why: String) {
        if let Ok(mut f) = self.counters.failure.lock() {
            f.get_or_insert(why);
        }
        self.counters.failed.store(true, Ordering::Release);
    }
}

impl jack::ProcessHandler for RoomProcess {
    fn process(&mut self, _: &Client, ps: &ProcessScope) -> Control {
        let n = ps.n_frames() as usize;
        let k0 = self.counters.samples.load(Ordering::Relaxed);
        if self.running
            && let Some(&at) = self.stalls.get(self.next_stall)
            && at < k0 + n as u64
        {
            self.next_stall += 1;
            self.counters.stalls.fetch_add(1, Ordering::Relaxed);
            // The injected fault itself: three periods asleep in the audio thread.
            std::thread::sleep(Duration::from_nanos(3 * n as u64 * self.period_ns));
        }
        if !self.running {
            self.running = self
                .speakers
                .iter()
                .all(|p| p.connected_count().is_ok_and(|c| c > 0));
        }
        if !self.running || self.counters.failed.load(Ordering::Relaxed) {
            for p in self.mic_y.iter_mut().chain(self.mic_z.iter_mut()) {
                p.as_mut_slice(ps).fill(0.0);
            }
            return Control::Continue;
        }
        // Frames the server's clock passed without this callback (an xrun): the room's
        // time goes on, with silent loudspeakers and nobody listening.
        let frame = ps.last_frame_time();
        let gap = match self.last_frame {
            Some((prev, prev_n)) => frame.wrapping_sub(prev).wrapping_sub(prev_n),
            None => 0,
        };
        self.last_frame = Some((frame, n as u32));
        if gap > 0 && gap < u32::MAX / 2 {
            let simulated = gap.min(MAX_CATCH_UP);
            for _ in 0..simulated {
                if let Err(e) = self.step(None) {
                    self.fail(e);
                    return Control::Continue;
                }
            }
            self.counters
                .frames_caught_up
                .fetch_add(u64::from(simulated), Ordering::Relaxed);
            self.counters
                .frames_dropped
                .fetch_add(u64::from(gap - simulated), Ordering::Relaxed);
        }
        let mut u = [0.0; MAX_U];
        for i in 0..n {
            for (j, p) in self.speakers.iter().enumerate() {
                u[j] = f64::from(p.as_slice(ps)[i]) * self.u_scale[j];
            }
            let (y, z) = match self.step(Some(&u)) {
                Ok(out) => out,
                Err(e) => {
                    self.fail(e);
                    return Control::Continue;
                }
            };
            let mut clipped = 0;
            for (j, p) in self.mic_y.iter_mut().enumerate() {
                let s = y[j] / self.y_scale[j];
                clipped += u64::from(s.abs() > 1.0);
                p.as_mut_slice(ps)[i] = s.clamp(-1.0, 1.0) as f32;
            }
            for (j, p) in self.mic_z.iter_mut().enumerate() {
                let s = z[j] / self.z_scale[j];
                clipped += u64::from(s.abs() > 1.0);
                p.as_mut_slice(ps)[i] = s.clamp(-1.0, 1.0) as f32;
            }
            if clipped > 0 {
                self.counters.clipped.fetch_add(clipped, Ordering::Relaxed);
            }
        }
        Control::Continue
    }
}

/// The room's notifications: xruns, and a server that goes away.
pub struct RoomNotifications {
    counters: Arc<RoomCounters>,
}

impl jack::NotificationHandler for RoomNotifications {
    unsafe fn shutdown(&mut self, _status: jack::ClientStatus, reason: &str) {
        if let Ok(mut f) = self.counters.failure.lock() {
            f.get_or_insert(format!("the JACK server shut the room down: {reason}"));
        }
        self.counters.failed.store(true, Ordering::Release);
    }

    fn xrun(&mut self, _: &Client) -> Control {
        self.counters.xruns.fetch_add(1, Ordering::Relaxed);
        Control::Continue
    }
}

/// A running room: its client and its counters.
pub type ActiveRoom = jack::AsyncClient<RoomNotifications, RoomProcess>;

/// Opens the room's client on the server of `jack`, checks the server's rate against the
/// simulation's period, registers the ports and starts the simulation; `stall_at`: the
/// samples at which to inject an xrun. The room connects nothing: the plant side
/// connects to its ports.
pub fn start(
    sim: PlantSim,
    jack: &JackConfig,
    origin: &str,
    stall_at: &[u64],
) -> Result<(ActiveRoom, Arc<RoomCounters>), String> {
    let server = crate::jack_server::server_name(jack.server.as_deref());
    let client = crate::jack_server::open_client(jack.server.as_deref(), &jack.room.client)
        .map_err(|e| e.0)?;
    let period_ns = (sim.sample_period() * 1e9).round() as u64;
    crate::jack_server::check_timing(&client, &server, period_ns, jack.period_frames, origin)
        .map_err(|e| e.0)?;
    let reg_in = |name: String| {
        client
            .register_port(&name, AudioIn::default())
            .map_err(|e| format!("registering the room's port {name}: {e}"))
    };
    let speakers = (0..sim.n_u())
        .map(|j| reg_in(format!("speaker-u{j}")))
        .collect::<Result<Vec<_>, _>>()?;
    let reg_out = |name: String| {
        client
            .register_port(&name, AudioOut::default())
            .map_err(|e| format!("registering the room's port {name}: {e}"))
    };
    let mic_y = (0..sim.n_y())
        .map(|j| reg_out(format!("mic-y{j}")))
        .collect::<Result<Vec<_>, _>>()?;
    let mic_z = (0..sim.n_z())
        .map(|j| reg_out(format!("mic-z{j}")))
        .collect::<Result<Vec<_>, _>>()?;
    let mut u_scale = [1.0; MAX_U];
    for (j, s) in u_scale.iter_mut().enumerate().take(sim.n_u()) {
        *s = JackConfig::scale(&jack.u_full_scale, j);
    }
    let mut y_scale = [1.0; MAX_Y];
    for (j, s) in y_scale.iter_mut().enumerate().take(sim.n_y()) {
        *s = JackConfig::scale(&jack.y_full_scale, j);
    }
    let mut z_scale = [1.0; MAX_Z];
    for (j, s) in z_scale.iter_mut().enumerate().take(sim.n_z()) {
        *s = JackConfig::scale(&jack.z_full_scale, j);
    }
    let mut stalls = stall_at.to_vec();
    stalls.sort_unstable();
    let counters = Arc::new(RoomCounters::default());
    let process = RoomProcess {
        sim,
        speakers,
        mic_y,
        mic_z,
        u_scale,
        y_scale,
        z_scale,
        line: vec![[0.0; MAX_U]; jack.room.converter_delay as usize + 1],
        head: 0,
        stalls,
        next_stall: 0,
        period_ns,
        running: false,
        last_frame: None,
        counters: counters.clone(),
    };
    let notifications = RoomNotifications {
        counters: counters.clone(),
    };
    let latency: &'static SpeakerLatency = Box::leak(Box::new(SpeakerLatency {
        client: client.raw(),
        speakers: process.speakers.iter().map(|p| p.raw()).collect(),
        converter_delay: jack.room.converter_delay,
    }));
    // SAFETY: the client is open and not yet active (the callback must be set before
    // activation); `latency` lives for the rest of the process, longer than the client.
    let rc = unsafe {
        jack_sys::jack_set_latency_callback(
            client.raw(),
            Some(speaker_latency),
            std::ptr::from_ref(latency).cast_mut().cast(),
        )
    };
    if rc != 0 {
        return Err(format!(
            "the JACK server refused the room's latency callback (jack_set_latency_callback returned {rc})"
        ));
    }
    let active = client.activate_async(notifications, process).map_err(|e| {
        format!(
            "activating the room's JACK client '{}': {e}",
            jack.room.client
        )
    })?;
    Ok((active, counters))
}

/// What the room's latency callback states: one period plus the converter delay on each
/// loudspeaker port (module documentation).
struct SpeakerLatency {
    client: *mut jack_sys::jack_client_t,
    speakers: Vec<*mut jack_sys::jack_port_t>,
    converter_delay: u32,
}

// SAFETY: the pointers are the room's open client and its ports, which JACK's own threads
// use; the callback only reads the period and sets the ports' ranges, as libjack allows
// from any of its threads.
unsafe impl Sync for SpeakerLatency {}

/// `JackLatencyCallback`: in playback mode, sets each loudspeaker port's playback latency.
unsafe extern "C" fn speaker_latency(
    mode: jack_sys::jack_latency_callback_mode_t,
    arg: *mut libc::c_void,
) {
    if mode != jack_sys::JackPlaybackLatency || arg.is_null() {
        return;
    }
    // SAFETY: `arg` is the leaked `SpeakerLatency` given at registration.
    let l = unsafe { &*arg.cast::<SpeakerLatency>() };
    // SAFETY: the client is open while its callbacks run.
    let period = unsafe { jack_sys::jack_get_buffer_size(l.client) };
    let frames = period + l.converter_delay;
    let mut range = jack_sys::Struct__jack_latency_range {
        min: frames,
        max: frames,
    };
    for &p in &l.speakers {
        // SAFETY: a port of this client, registered before activation and never removed.
        unsafe {
            jack_sys::jack_port_set_latency_range(p, jack_sys::JackPlaybackLatency, &mut range)
        };
    }
}
