//! The plant side as a JACK client: a sound card is the rig's DAQ.
//!
//! The client has one input port per measured output and performance variable (`y0`, …,
//! `z0`, …) and one output port per input (`u0`, …); the sample rate and the period come
//! from the server. JACK calls the process callback once per period with a block of `P`
//! frames; frame `i` of the block that starts at contract sample `k_0` is sample
//! `k = k_0 + i`. For each frame, in order, the callback
//!
//! 1. reads `y_k`, `z_k` from its input ports (times `jack.y-full-scale`,
//!    `jack.z-full-scale`),
//! 2. publishes `M_k` and takes the input of sample `k` through [`plant_side::PlantSide`]
//!    as the scenario's `[proxy]` policy says: with `deadline = 0` (a DAC latched at the
//!    sample clock, a service that sends ahead) it takes `u_k` first (the answer to
//!    `M_{k−1}`) and then publishes `M_k`; otherwise it publishes `M_k` and then takes
//!    `u_k` (the answer to `M_k`),
//! 3. writes `u_k / u-full-scale` to frame `i` of its output ports, clipped to `[−1, 1]`.
//!
//! **The budget.** In real time the callback waits for each answer by polling, never
//! sleeping ([`Wait::Spin`]), and never past `t_0 + b·P·T`, where `t_0` is the callback's
//! start, `b` is `jack.budget` and `P·T` the period: a sample whose answer is not there by
//! then is a miss, and so is every later sample of the block (they are decided at once).
//! A miss gets the contract's late policy per sample: the newest plan's entry, else
//! `plan-fallback` (hold or safe); after `watchdog-periods` consecutive misses, the safe
//! output. The service's answers therefore cost `P` round trips per period: the block
//! holds only when the mean round trip stays below `b·T`.
//!
//! **The samples' time.** `t_sample_ns` of `M_k` is the instant the callback presents the
//! sample to the contract, not the instant the card captured it: JACK hands over a block a
//! period after its first frame was captured, and a stamp that old would make every answer
//! look late to the service. The capture instant is earlier by a constant, which the
//! report gives: the ports' latencies, in frames.
//!
//! **The latency the card adds.** An input `u_k` reaches the loudspeaker `L_p` frames
//! after its frame (the playback latency of the port it drives: the server's periods out
//! plus the DAC's delay), and a microphone's sample is `L_c` frames old when it is read
//! (the capture latency: a period in plus the ADC's delay). The plant the controller sees
//! is the room delayed by `L_c + L_p` samples. The report gives both as the server states
//! them (`jack_port_get_latency_range`); on a real card the converters' part is measured
//! with `jack_iodelay` and given to the server (`jackd -I`, `-O`). The design path
//! identifies the whole delay from a logged run ([`crate`] documentation), so the target
//! model includes it.
//!
//! **Xruns.** A period the server skips (an xrun) is counted. In real time the samples
//! are the card's frames: the samples of the skipped frames are lost, each decided as a
//! miss without being published, and the next measurement carries the frame count, so the
//! service sees a gap (which its controller bridges, e.g. RCAC's gap rule) and the loop's
//! delay in samples stays what the card's clock makes it.
//!
//! **Lockstep.** With `proxy.mode = "lockstep"` the plant side puts the server into
//! freewheel mode (no driver clock, no deadlines: every client's callback runs as soon as
//! the previous cycle ended) and waits for each answer ([`Wait::Lockstep`]); the loop then
//! runs as fast as the service answers, through the same server and ports.
//!
//! The callback does not allocate (iceoryx2's per-sample state comes from the thread's
//! pool, [`ipc_types::rt_alloc`]), takes no lock and does no I/O; it counts, and the main
//! thread reports.

use crate::jack_config::JackConfig;
use crate::jack_report::{CallbackTimes, JackReport, PortReport};
use crate::jack_server::{self, Direction, JackError};
use hdrhistogram::Histogram;
use ipc_types::clock::monotonic_ns;
use ipc_types::rt_alloc::RtAllocStats;
use ipc_types::{ChannelCounts, MAX_U, MAX_Y, MAX_Z, measurement_flags};
use jack::{AudioIn, AudioOut, Client, Control, Frames, Port, ProcessScope};
use plant_side::{Mode, PlantError, PlantPolicy, PlantReport, PlantSide, Wait};
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Blocks of the process thread's allocation pool (iceoryx2 holds one or two at once).
const RT_POOL_BLOCKS: usize = 64;

/// The most lost samples one callback decides one by one (1 s at 8 kHz); the rest of a
/// longer gap (a server stopped for seconds) is skipped without a decision each.
pub const MAX_LOST_DECIDED: u64 = 8000;

/// What the process callback and the notifications count, read by the main thread.
#[derive(Debug, Default)]
pub struct Counters {
    /// Set by the main thread once the ports are connected: the run starts.
    armed: AtomicBool,
    /// The run ended: last sample, stop, or an error.
    done: AtomicBool,
    callbacks: AtomicU64,
    xruns: AtomicU64,
    over_period: AtomicU64,
    budget_exhausted: AtomicU64,
    frames_skipped: AtomicU64,
    samples_lost: AtomicU64,
    u_clipped: AtomicU64,
    /// The server shut the client down, or changed the rate: why.
    gone: Mutex<Option<String>>,
    /// The process thread's id (0: not started), for its scheduling at the end.
    thread: AtomicI32,
}

impl Counters {
    fn add(c: &AtomicU64, n: u64) {
        c.fetch_add(n, Ordering::Relaxed);
    }

    fn get(c: &AtomicU64) -> u64 {
        c.load(Ordering::Relaxed)
    }
}

/// The connected plant side, moved into the process callback.
struct SendSide(PlantSide<'static>);

// SAFETY: iceoryx2's `ipc::Service` ports are `!Send` only because they share their state
// through non-atomic `Rc`s (its `SingleThreaded` policy; no thread-local state, no thread
// identity). Every clone of those `Rc`s lives inside this `PlantSide` (node, services,
// ports; no sample is held between calls), so it moves as a whole: from the main thread
// into the JACK callback at activation, and back at deactivation, used by one thread at a
// time.
unsafe impl Send for SendSide {}

/// The process handler: one block of frames per call (module documentation).
pub struct DaqProcess {
    side: SendSide,
    y: Vec<Port<AudioIn>>,
    z: Vec<Port<AudioIn>>,
    u: Vec<Port<AudioOut>>,
    y_scale: [f64; MAX_Y],
    z_scale: [f64; MAX_Z],
    u_scale: [f64; MAX_U],
    safe: [f32; MAX_U],
    steps: u64,
    next_k: u64,
    lockstep: bool,
    latch: bool,
    budget: f64,
    period_ns: u64,
    counters: Arc<Counters>,
    /// The inputs are to be connected (`jack.u` lists ports): wait for them to start.
    wired_u: bool,
    /// The run started (and has not necessarily ended: [`DaqProcess::idle`]).
    running: bool,
    error: Option<PlantError>,
    last_frame: Option<(Frames, Frames)>,
    callback_ns: Histogram<u64>,
    allocs_base: Option<RtAllocStats>,
    allocs_now: Option<RtAllocStats>,
}

impl DaqProcess {
    /// The run has ended (or not started): the ports carry the safe input.
    fn idle(&self) -> bool {
        !self.running || self.counters.done.load(Ordering::Relaxed)
    }

    /// Starts the run at the first cycle that is armed and sees every input port
    /// connected (any when none is to be connected): see [`run`].
    fn start_when_wired(&mut self) {
        if self.running || !self.counters.armed.load(Ordering::Acquire) {
            return;
        }
        self.running = !self.wired_u
            || self
                .u
                .iter()
                .all(|p| p.connected_count().is_ok_and(|n| n > 0));
    }

    /// The server skipped `frames` frames (an xrun): their samples are lost. Each is
    /// decided without being published (a miss: the plan's entry, else `plan-fallback`, and
    /// the watchdog counts it), at most [`MAX_LOST_DECIDED`] of them, and the samples go on
    /// from the card's frame count; the last sample of the run is never skipped, so that the
    /// service hears the run's end.
    fn lose(&mut self, frames: u32) {
        let last = self.steps.saturating_sub(1);
        let resume = (self.next_k + u64::from(frames)).min(last).max(self.next_k);
        let decided = (resume - self.next_k).min(MAX_LOST_DECIDED);
        for k in self.next_k..self.next_k + decided {
            match self.side.0.take(k, Wait::Now) {
                Ok(Some(_)) => {}
                Ok(None) => {
                    self.counters.done.store(true, Ordering::Release);
                    return;
                }
                Err(e) => {
                    self.error = Some(e);
                    self.counters.done.store(true, Ordering::Release);
                    return;
                }
            }
        }
        Counters::add(&self.counters.samples_lost, resume - self.next_k);
        self.next_k = resume;
    }

    /// Decides sample `k` (module documentation, steps 1 and 2); `None`: stopped.
    fn sample(
        &mut self,
        k: u64,
        [y, z]: [&[f64]; 2],
        budget_end: u64,
    ) -> Result<Option<plant_side::Input>, PlantError> {
        let extra = if k + 1 == self.steps {
            measurement_flags::LAST_SAMPLE
        } else {
            0
        };
        let side = &mut self.side.0;
        let signals = [y, z, &[][..]];
        if self.lockstep {
            side.publish(k, monotonic_ns(), signals, extra)?;
            return side.take(k, Wait::Lockstep);
        }
        if self.latch {
            // u_k was sent ahead with the answer to M_{k-1}; none exists before sample 0.
            let wait = if k == 0 {
                Wait::Now
            } else {
                Wait::Spin(budget_end)
            };
            let input = side.take(k, wait)?;
            let flags = side.publish(k, monotonic_ns(), signals, extra)?;
            Ok(input.map(|mut i| {
                i.published_flags = flags;
                i
            }))
        } else {
            side.publish(k, monotonic_ns(), signals, extra)?;
            side.take(k, Wait::Spin(budget_end))
        }
    }
}

impl jack::ProcessHandler for DaqProcess {
    fn process(&mut self, _: &Client, ps: &ProcessScope) -> Control {
        let t0 = monotonic_ns();
        let n = ps.n_frames();
        if Counters::get(&self.counters.callbacks) == 0 {
            // Which thread the server runs the callback on (its scheduling is reported at
            // the end): one system call, on the first callback only.
            // SAFETY: a plain query of the calling thread's id.
            let tid = unsafe { libc::gettid() };
            self.counters.thread.store(tid, Ordering::Relaxed);
        }
        Counters::add(&self.counters.callbacks, 1);
        let frame = ps.last_frame_time();
        let mut skipped = 0;
        if let Some((prev, prev_n)) = self.last_frame {
            let gap = frame.wrapping_sub(prev);
            // A freewheeling server's clock is not the card's: only real time counts.
            if !self.lockstep && gap > prev_n && gap < u32::MAX / 2 {
                skipped = gap - prev_n;
                Counters::add(&self.counters.frames_skipped, u64::from(skipped));
            }
        }
        self.last_frame = Some((frame, n));
        if skipped > 0 && !self.idle() {
            self.lose(skipped);
        }
        self.start_when_wired();
        let budget_end = t0 + (self.budget * f64::from(n) * self.period_ns as f64) as u64;
        let (n_y, n_z, n_u) = (self.y.len(), self.z.len(), self.u.len());
        let mut y_in: [&[f32]; MAX_Y] = [&[]; MAX_Y];
        let mut z_in: [&[f32]; MAX_Z] = [&[]; MAX_Z];
        // Own copies of the port slices: `self` is borrowed mutably below.
        for (dst, p) in y_in.iter_mut().zip(&self.y) {
            *dst = unsafe_extend(p.as_slice(ps));
        }
        for (dst, p) in z_in.iter_mut().zip(&self.z) {
            *dst = unsafe_extend(p.as_slice(ps));
        }
        let mut u_out: [&mut [f32]; MAX_U] = std::array::from_fn(|_| &mut [][..]);
        for (dst, p) in u_out.iter_mut().zip(self.u.iter_mut()) {
            *dst = unsafe_extend_mut(p.as_mut_slice(ps));
        }
        let sampled = !self.idle();
        if sampled && self.allocs_base.is_none() {
            self.allocs_base = Some(ipc_types::rt_alloc::thread_stats());
        }
        let (mut y, mut z) = ([0.0; MAX_Y], [0.0; MAX_Z]);
        let mut exhausted = false;
        for i in 0..n as usize {
            if self.idle() {
                for (j, out) in u_out[..n_u].iter_mut().enumerate() {
                    out[i] = self.safe[j];
                }
                continue;
            }
            for j in 0..n_y {
                y[j] = f64::from(y_in[j][i]) * self.y_scale[j];
            }
            for j in 0..n_z {
                z[j] = f64::from(z_in[j][i]) * self.z_scale[j];
            }
            let k = self.next_k;
            match self.sample(k, [&y[..n_y], &z[..n_z]], budget_end) {
                Ok(Some(input)) => {
                    self.next_k += 1;
                    if input.kind.is_miss() && !self.lockstep && monotonic_ns() >= budget_end {
                        exhausted = true;
                    }
                    // The watchdog's safe output is `input.u` too (the policy's safe input).
                    for (j, out) in u_out[..n_u].iter_mut().enumerate() {
                        let s = input.u[j] / self.u_scale[j];
                        if s.abs() > 1.0 {
                            Counters::add(&self.counters.u_clipped, 1);
                        }
                        out[i] = s.clamp(-1.0, 1.0) as f32;
                    }
                    if self.next_k == self.steps {
                        self.counters.done.store(true, Ordering::Release);
                    }
                }
                Ok(None) => self.counters.done.store(true, Ordering::Release),
                Err(e) => {
                    self.error = Some(e);
                    self.counters.done.store(true, Ordering::Release);
                }
            }
            if self.idle() {
                for (j, out) in u_out[..n_u].iter_mut().enumerate() {
                    if self.next_k < self.steps || self.error.is_some() {
                        out[i] = self.safe[j];
                    }
                }
            }
        }
        if exhausted {
            Counters::add(&self.counters.budget_exhausted, 1);
        }
        if self.allocs_base.is_some() {
            self.allocs_now = Some(ipc_types::rt_alloc::thread_stats());
        }
        if sampled {
            // Freewheeling has no period to overrun.
            let spent = monotonic_ns().saturating_sub(t0);
            if !self.lockstep && spent > u64::from(n) * self.period_ns {
                Counters::add(&self.counters.over_period, 1);
            }
            self.callback_ns.saturating_record(spent.max(1));
        }
        Control::Continue
    }
}

/// A port buffer's slice for the rest of the callback, detached from the borrow of its
/// port (the buffer belongs to the server for the cycle, not to the `Port` value).
fn unsafe_extend<'a>(s: &[f32]) -> &'a [f32] {
    // SAFETY: JACK's buffer for this cycle stays valid until the process callback
    // returns; the slices never leave it.
    unsafe { std::slice::from_raw_parts(s.as_ptr(), s.len()) }
}

/// As [`unsafe_extend`], for an output port's buffer (each port's buffer is distinct).
fn unsafe_extend_mut<'a>(s: &mut [f32]) -> &'a mut [f32] {
    // SAFETY: as above; each output port has its own buffer, so the slices do not alias.
    unsafe { std::slice::from_raw_parts_mut(s.as_mut_ptr(), s.len()) }
}

/// The notification handler: counts xruns, notices a server that goes away or changes
/// its rate, and sets up the process thread.
pub struct DaqNotifications {
    counters: Arc<Counters>,
    core: Option<usize>,
    sample_rate: u32,
}

impl jack::NotificationHandler for DaqNotifications {
    fn thread_init(&self, _: &Client) {
        if let Some(c) = self.core {
            core_affinity::set_for_current(core_affinity::CoreId { id: c });
        }
        ipc_types::rt_alloc::enter_rt_thread(RT_POOL_BLOCKS);
    }

    unsafe fn shutdown(&mut self, _status: jack::ClientStatus, reason: &str) {
        if let Ok(mut g) = self.counters.gone.lock() {
            *g = Some(format!("the JACK server shut the client down: {reason}"));
        }
        self.counters.done.store(true, Ordering::Release);
    }

    fn sample_rate(&mut self, _: &Client, srate: Frames) -> Control {
        if srate != self.sample_rate {
            if let Ok(mut g) = self.counters.gone.lock() {
                *g = Some(format!(
                    "the JACK server changed its sample rate from {} Hz to {srate} Hz during the run",
                    self.sample_rate
                ));
            }
            self.counters.done.store(true, Ordering::Release);
        }
        Control::Continue
    }

    fn xrun(&mut self, _: &Client) -> Control {
        Counters::add(&self.counters.xruns, 1);
        Control::Continue
    }
}

/// How thread `tid` is scheduled (policy, priority) and the core it was pinned to; `None`
/// when it is gone or never started.
fn describe_thread(tid: i32, core: Option<usize>) -> Option<String> {
    if tid == 0 {
        return None;
    }
    // SAFETY: plain queries of a thread of this process; a thread that ended gives -1.
    let (policy, prio) = unsafe {
        let mut param: libc::sched_param = std::mem::zeroed();
        let policy = libc::sched_getscheduler(tid);
        libc::sched_getparam(tid, &mut param);
        (policy, param.sched_priority)
    };
    if policy < 0 {
        return None;
    }
    // The server may start its clients' threads with SCHED_RESET_ON_FORK.
    let policy = match policy & !libc::SCHED_RESET_ON_FORK {
        libc::SCHED_FIFO => format!("SCHED_FIFO {prio}"),
        libc::SCHED_RR => format!("SCHED_RR {prio}"),
        _ => "SCHED_OTHER (the server runs without -R, or could not raise its clients)".to_string(),
    };
    Some(match core {
        Some(c) => format!("JACK process thread: {policy} (set by the server), pinned to core {c}"),
        None => format!("JACK process thread: {policy} (set by the server), not pinned"),
    })
}

/// What [`run`] needs besides the scenario's tables.
#[derive(Debug, Clone)]
pub struct DaqRun<'a> {
    /// The scenario file, for messages.
    pub origin: &'a str,
    /// The rig's name.
    pub rig: &'a str,
    /// Channel counts.
    pub counts: ChannelCounts,
    /// Sample period, ns.
    pub period_ns: u64,
    /// The plant side's policy (the scenario's `[proxy]`).
    pub policy: PlantPolicy,
    /// The `[jack]` table.
    pub jack: JackConfig,
    /// Samples to run.
    pub steps: u64,
    /// Print progress.
    pub verbose: bool,
}

/// The outcome of [`run`]: the plant side's report and the JACK part; the error that
/// ended the run, if any.
#[derive(Debug)]
pub struct DaqOutcome {
    /// The contract's counters.
    pub plant: PlantReport,
    /// The server, the ports, the callbacks.
    pub jack: JackReport,
    /// What ended the run early (the plant side's error, the server going away).
    pub failure: Option<String>,
}

/// The port list of one kind: `{prefix}{i}`.
fn register<PS: jack::PortSpec + Default>(
    client: &Client,
    prefix: &str,
    n: usize,
) -> Result<Vec<Port<PS>>, JackError> {
    (0..n)
        .map(|i| {
            client
                .register_port(&format!("{prefix}{i}"), PS::default())
                .map_err(|e| JackError(format!("registering port {prefix}{i}: {e}")))
        })
        .collect()
}

/// Runs the plant side through JACK: opens the client, checks the server against the
/// scenario, connects to the service (waiting up to `proxy.peer-timeout`), wires the
/// ports, runs `steps` samples (or until `stop` is set), and reports. A refusal before the
/// run (no server, a wrong rate or period, a missing or wrong port, no service) is an
/// `Err`; a run that ended early is an `Ok` whose `failure` says why.
pub fn run(d: DaqRun<'_>, stop: &'static AtomicBool) -> Result<DaqOutcome, String> {
    let cfg = &d.jack;
    let server = jack_server::server_name(cfg.server.as_deref());
    let client = jack_server::open_client(cfg.server.as_deref(), &cfg.client).map_err(|e| e.0)?;
    jack_server::check_timing(&client, &server, d.period_ns, cfg.period_frames, d.origin)
        .map_err(|e| e.0)?;
    let (n_y, n_z, n_u) = (
        d.counts.n_y as usize,
        d.counts.n_z as usize,
        d.counts.n_u as usize,
    );
    // The peers first: a missing port is refused before anything is connected.
    let mut wiring = Vec::new();
    for (name, list, dir) in [
        ("y", &cfg.y, Direction::Capture),
        ("z", &cfg.z, Direction::Capture),
        ("u", &cfg.u, Direction::Playback),
    ] {
        for (i, other) in list.iter().enumerate() {
            let field = format!("{}: field 'jack.{name}[{i}]'", d.origin);
            jack_server::find_peer_port(&client, &server, other, dir, &field).map_err(|e| e.0)?;
            let own = format!("{}:{name}{i}", client.name());
            wiring.push(match dir {
                Direction::Capture => (other.clone(), own, field, false),
                Direction::Playback => (own, other.clone(), field, true),
            });
        }
    }
    let y = register::<AudioIn>(&client, "y", n_y).map_err(|e| e.0)?;
    let z = register::<AudioIn>(&client, "z", n_z).map_err(|e| e.0)?;
    let u = register::<AudioOut>(&client, "u", n_u).map_err(|e| e.0)?;
    let sample_rate = client.sample_rate();
    let lockstep = d.policy.mode == Mode::Lockstep;
    let latch = d.policy.applies() == ipc_types::ports::Applies::AtSample;
    let core = d.policy.rt.core;
    let mut safe = [0.0f32; MAX_U];
    let mut u_scale = [1.0; MAX_U];
    for j in 0..n_u {
        u_scale[j] = JackConfig::scale(&cfg.u_full_scale, j);
        safe[j] = (d.policy.safe_input[j] / u_scale[j]).clamp(-1.0, 1.0) as f32;
    }
    let mut y_scale = [1.0; MAX_Y];
    for (j, s) in y_scale.iter_mut().enumerate().take(n_y) {
        *s = JackConfig::scale(&cfg.y_full_scale, j);
    }
    let mut z_scale = [1.0; MAX_Z];
    for (j, s) in z_scale.iter_mut().enumerate().take(n_z) {
        *s = JackConfig::scale(&cfg.z_full_scale, j);
    }

    let side_opts = plant_side::PlantSideOptions {
        label: "plant-jack",
        node_name: "adaptive-rig-plant",
        verbose: d.verbose,
        shutdown: Some(stop),
    };
    let mut side = PlantSide::connect(d.rig, d.counts, d.period_ns, d.policy.clone(), side_opts)
        .map_err(|e| e.to_string())?;
    side.report_mut().rt_setup = "JACK process thread (see jack.thread)".to_string();
    let counters = Arc::new(Counters::default());
    let process = DaqProcess {
        side: SendSide(side),
        y,
        z,
        u,
        y_scale,
        z_scale,
        u_scale,
        safe,
        steps: d.steps,
        next_k: 0,
        lockstep,
        latch,
        budget: cfg.budget,
        period_ns: d.period_ns,
        counters: counters.clone(),
        wired_u: !cfg.u.is_empty(),
        running: false,
        error: None,
        last_frame: None,
        callback_ns: Histogram::new_with_bounds(1, 10_000_000_000, 3)
            .map_err(|e| format!("callback histogram: {e}"))?,
        allocs_base: None,
        allocs_now: None,
    };
    let notifications = DaqNotifications {
        counters: counters.clone(),
        core,
        sample_rate,
    };
    let started = Instant::now();
    let active = client
        .activate_async(notifications, process)
        .map_err(|e| format!("activating JACK client '{}': {e}", cfg.client))?;
    let finish = |active: jack::AsyncClient<DaqNotifications, DaqProcess>,
                  failure: Option<String>|
     -> Result<DaqOutcome, String> {
        let ports = port_report(active.as_client(), &cfg.y, &cfg.z, &cfg.u);
        if lockstep {
            let _ = jack_server::set_freewheel(active.as_client(), false);
        }
        let period_frames = active.as_client().buffer_size();
        let thread = describe_thread(counters.thread.load(Ordering::Relaxed), core);
        let (_, _, p) = active
            .deactivate()
            .map_err(|e| format!("deactivating the JACK client: {e}"))?;
        let failure = failure.or_else(|| p.error.as_ref().map(|e| e.to_string()));
        let mut plant = match p.error {
            Some(PlantError::GaveUp { report, .. }) => *report,
            _ => p.side.0.finish(),
        };
        if let (Some(a), Some(b)) = (p.allocs_now, p.allocs_base) {
            plant.rt_allocations = a.since(&b);
        }
        plant.wall_time_s = started.elapsed().as_secs_f64();
        let c = &counters;
        let jack = JackReport {
            server: server.clone(),
            client: cfg.client.clone(),
            sample_rate,
            period_frames,
            budget: cfg.budget,
            freewheel: lockstep,
            thread,
            callbacks: Counters::get(&c.callbacks),
            xruns: Counters::get(&c.xruns),
            frames_skipped: Counters::get(&c.frames_skipped),
            samples_lost: Counters::get(&c.samples_lost),
            callbacks_over_period: Counters::get(&c.over_period),
            callbacks_budget_exhausted: Counters::get(&c.budget_exhausted),
            u_clipped: Counters::get(&c.u_clipped),
            callback_time: CallbackTimes::of(&p.callback_ns),
            added_delay_frames: JackReport::added_delay(&ports),
            ports,
        };
        Ok(DaqOutcome {
            plant,
            jack,
            failure,
        })
    };
    // Measurements first, then freewheeling (lockstep) and arming, then the inputs. When
    // the two close a loop through another client (the room), the server makes the
    // inputs' connection the feedback one (a period late), and the callback starts at the
    // first cycle that sees the inputs connected, the cycle the room starts in too: a
    // lockstep run through the server is the same run every time.
    let refuse = |active, e: JackError| {
        finish(active, Some(e.0)).and_then(|o| Err(o.failure.unwrap_or_default()))
    };
    for (from, to, field, _) in wiring.iter().filter(|w| !w.3) {
        if let Err(e) = jack_server::connect(active.as_client(), from, to, field) {
            return refuse(active, e);
        }
    }
    if lockstep && let Err(e) = jack_server::set_freewheel(active.as_client(), true) {
        return refuse(active, e);
    }
    counters.armed.store(true, Ordering::Release);
    for (from, to, field, _) in wiring.iter().filter(|w| w.3) {
        if let Err(e) = jack_server::connect(active.as_client(), from, to, field) {
            return refuse(active, e);
        }
    }
    if d.verbose {
        eprintln!(
            "[plant-jack] connected to JACK server '{server}' ({sample_rate} Hz, {} frames per period{}) and to the service; {} samples",
            active.as_client().buffer_size(),
            if lockstep { ", freewheeling" } else { "" },
            d.steps
        );
    }
    while !counters.done.load(Ordering::Acquire) {
        if stop.load(Ordering::Relaxed) {
            // The callback sees the flag at its next wait and ends the run; a server that
            // stopped calling it would not, so give it a second.
            let until = Instant::now() + Duration::from_secs(1);
            while !counters.done.load(Ordering::Acquire) && Instant::now() < until {
                std::thread::sleep(Duration::from_millis(5));
            }
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let gone = counters.gone.lock().ok().and_then(|g| g.clone());
    finish(active, gone)
}

/// Each connected port of ours with its peer and the latencies the server states.
fn port_report(client: &Client, y: &[String], z: &[String], u: &[String]) -> Vec<PortReport> {
    let mut out = Vec::new();
    for (name, list, playback) in [("y", y, false), ("z", z, false), ("u", u, true)] {
        for (i, peer) in list.iter().enumerate() {
            let own = format!("{}:{name}{i}", client.name());
            let Some(port) = client.port_by_name(&own) else {
                continue;
            };
            let mode = if playback {
                jack::LatencyType::Playback
            } else {
                jack::LatencyType::Capture
            };
            let (min, max) = port.get_latency_range(mode);
            out.push(PortReport {
                channel: format!("{name}{i}"),
                port: own,
                peer: peer.clone(),
                direction: if playback { "playback" } else { "capture" }.to_string(),
                latency_frames: [min, max],
            });
        }
    }
    out
}
