//! The configurations the bench runs, written as the same TOML a user writes, so that every
//! measurement goes through the service's own configuration path
//! (`service::config::ServiceConfig::parse`, then `ControllerConfig::build`).
//!
//! - [`service_toml`]: the file given to the service child process in the round-trip and
//!   wake-up measurements: a `[rig]` with a name unique to the run, the 8 kHz period, the
//!   channel counts, a policy that never goes to the safe state nor declares the plant
//!   silent during a bench (so that the loop does the same work on every sample), and a
//!   small controller ([`loop_controller`]).
//! - [`step_cases`]: the named controller configurations whose step cost is measured: LTI
//!   controllers, and RCAC at the acoustic rig's size ([`acoustic_rcac_toml`]) run in the
//!   closed loop of a [`LoopPlant`]. Later controllers (PCAC, …) add entries to that list.
//! - [`timing_cases`]: the controllers whose response time the service measures with
//!   `timing = "compute-first"` and with `timing = "answer-first"` (written by
//!   [`service_toml_with`]), each with the loop its paced plant closes ([`PacedPlant`]).
//!
//! Test matrices are random with a fixed seed (ChaCha8 from `rand_chacha`); the state matrix of a
//! dynamic controller is scaled to spectral radius 0.9 so the controller is stable and its
//! state stays finite over hundreds of thousands of steps (a diverging state would make the
//! controller take its reset path and time something else).

use ipc_types::Timing;
use nalgebra::DMatrix;
pub use plant_proxy::lti::StateSpace;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;

/// A static gain `u = D e` (no state).
pub fn static_gain(d: DMatrix<f64>) -> StateSpace {
    let (n_u, n_e) = d.shape();
    StateSpace {
        a: DMatrix::zeros(0, 0),
        b: DMatrix::zeros(0, n_e),
        c: DMatrix::zeros(n_u, 0),
        d,
    }
}

/// A random controller with `n` states, `n_e` inputs and `n_u` outputs, `A` scaled to
/// spectral radius `rho`, the other matrices uniform in `[-scale, scale)`.
pub fn random_controller(
    n: usize,
    n_e: usize,
    n_u: usize,
    rho: f64,
    scale: f64,
    seed: u64,
) -> StateSpace {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let a = random_stable(n, rho, &mut rng);
    let mut m =
        |r: usize, c: usize| DMatrix::from_fn(r, c, |_, _| scale * rng.random_range(-1.0..1.0));
    StateSpace {
        a,
        b: m(n, n_e),
        c: m(n_u, n),
        d: m(n_u, n_e),
    }
}

/// The `[controller]` table of an `lti` controller with input `y`.
pub fn controller_toml(ss: &StateSpace) -> String {
    let mut s = String::from("[controller]\nkind = \"lti\"\ninput = \"y\"\n[controller.ss]\n");
    for (name, m) in [("a", &ss.a), ("b", &ss.b), ("c", &ss.c), ("d", &ss.d)] {
        let _ = writeln!(s, "{name} = {}", toml_matrix(m));
    }
    s
}

/// A matrix as a TOML array of rows; `[]` when it has no rows or no columns (the service
/// reads the missing dimension from the channel counts). Floats are written with Rust's
/// `{:?}`, which round-trips exactly and always reads back as a TOML float.
pub fn toml_matrix(m: &DMatrix<f64>) -> String {
    if m.nrows() == 0 || m.ncols() == 0 {
        return "[]".to_string();
    }
    let rows: Vec<String> = (0..m.nrows())
        .map(|i| {
            let row: Vec<String> = (0..m.ncols()).map(|j| format!("{:?}", m[(i, j)])).collect();
            format!("[{}]", row.join(", "))
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

/// Spectral radius (largest eigenvalue modulus) of a square matrix; 0 for an empty one.
pub fn spectral_radius(a: &DMatrix<f64>) -> f64 {
    plant_proxy::lti::eigenvalues(a)
        .map(|ls| ls.iter().map(|l| l.norm()).fold(0.0, f64::max))
        .unwrap_or(f64::NAN)
}

/// A random `n × n` matrix (entries uniform in `[-1, 1)`) scaled to spectral radius `rho`.
pub fn random_stable(n: usize, rho: f64, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let r = spectral_radius(&a);
    if r > 0.0 { a * (rho / r) } else { a }
}

/// Channel counts of a bench configuration, as `[service.channels]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Channels {
    /// Measurements `y` (the controller inputs, `input = "y"`).
    pub y: usize,
    /// Performance channels `z`.
    pub z: usize,
    /// Actuation channels `u`.
    pub u: usize,
}

/// The small controller the service runs in the round-trip and wake-up measurements: two
/// states, SISO.
pub fn loop_controller() -> StateSpace {
    StateSpace {
        a: DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.0, 0.3]),
        b: DMatrix::from_row_slice(2, 1, &[1.0, 0.5]),
        c: DMatrix::from_row_slice(1, 2, &[-0.2, 0.1]),
        d: DMatrix::from_row_slice(1, 1, &[0.0]),
    }
}

/// A complete service configuration for rig `rig` at the 8 kHz period, with the LTI
/// controller `controller`, answering compute-first; see [`service_toml_with`].
///
/// The timing is written out, not left to the service's default: the round trip and the
/// wake-up phase wait for the answer carrying `k`, and a service that sent ahead (which
/// [`loop_controller`], without feedthrough, can) would have published it a sample
/// earlier, at sample `k − 1`.
pub fn service_toml(rig: &str, channels: Channels, controller: &StateSpace, log: bool) -> String {
    service_toml_with(
        rig,
        crate::PERIOD_NS,
        channels,
        &controller_toml(controller),
        Some(Timing::ComputeFirst),
        log,
    )
}

/// A complete service configuration for rig `rig` sampled every `period_ns` around the
/// `[controller]` table `controller` (any kind, as text), answering with `timing`
/// (`service.timing`; `None` leaves the key out, so the service takes its default).
///
/// The wait mode and the RT core are not in the file: the bench passes them in
/// `RunOptions`. `SCHED_FIFO` at [`crate::RT_PRIORITY`] and `mlockall` are requested but
/// not required, so the bench also runs (and says so) where the OS refuses them.
pub fn service_toml_with(
    rig: &str,
    period_ns: u64,
    channels: Channels,
    controller: &str,
    timing: Option<Timing>,
    log: bool,
) -> String {
    let timing = timing
        .map(|t| format!("timing = \"{}\"\n", t.name()))
        .unwrap_or_default();
    format!(
        r#"# Written by latency-bench for one measurement.
[rig]
name = "{rig}"
sample-period = {period:?}

[service]
{timing}fifo-priority = {prio}
mlockall = true
require-rt = false
grace-periods = 100
# A bench measures the loop doing its normal work on every sample: never go to the safe
# state, never declare the plant silent (misses are still counted).
max-consecutive-misses = 1000000000
silent-periods = 1000000000
peer-timeout = 30.0
histogram-interval = 1.0
channels = {{ y = {y}, z = {z}, u = {u} }}

{controller}
[log]
enabled = {log}
"#,
        prio = crate::RT_PRIORITY,
        period = period_ns as f64 / 1e9,
        y = channels.y,
        z = channels.z,
        u = channels.u,
    )
}

/// One controller configuration whose step cost is measured.
#[derive(Debug, Clone)]
pub struct StepCase {
    /// Name in the table and in file names (`step-<slug>.hgrm`).
    pub name: String,
    /// File-name form of the name.
    pub slug: String,
    /// The configuration text, parsed by `ServiceConfig::parse`.
    pub toml: String,
    /// Least number of untimed steps before timing starts, whatever the bench's warm-up
    /// setting (an adaptive controller's `k_w` and its start of adaptation).
    pub min_warmup: u64,
    /// A plant closing the loop around the controller during the measurement, or `None`
    /// (then `y_k` comes from a fixed table of sines and `z_k = 0`). See [`LoopPlant`].
    pub plant: Option<LoopPlant>,
    /// The command `r_k = Σ cos(ω_i k)` of a controller that follows one (the chapter-4
    /// controllers; the rig then has `n_r = 1`): the frequencies `ω_i`, rad/sample. Empty:
    /// no command channel.
    pub command: Vec<f64>,
}

/// An FIR plant that closes the loop in the step-cost phase of an adaptive controller, so
/// that it adapts on the data of a real loop:
///
/// ```text
/// z_k = d_k + Σ_{i=1}^{n} H_i u_{k−i},   y_k = z_k   (H_0 is ignored: z_k is sampled before u_k)
/// ```
///
/// with `d_k` a tone plus white Gaussian noise from a seeded generator. Computed outside
/// the timed region.
#[derive(Debug, Clone)]
pub struct LoopPlant {
    /// `H_0 … H_n`, `l_z × l_u` each (`H_0 = 0`).
    pub markov: Vec<DMatrix<f64>>,
    /// Amplitude of the disturbance tone in `z`.
    pub tone: f64,
    /// Frequency of the tone, rad/sample.
    pub tone_w: f64,
    /// Standard deviation of the white noise in `z`.
    pub noise_std: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl StepCase {
    /// A case named `name` for an `lti` controller `ss` on `channels`.
    pub fn lti(name: &str, slug: &str, channels: Channels, ss: &StateSpace) -> Self {
        Self {
            name: name.to_string(),
            slug: slug.to_string(),
            toml: service_toml("bench-step", channels, ss, false),
            min_warmup: 0,
            plant: None,
            command: Vec::new(),
        }
    }

    /// A case named `name` for the `[controller]` table `controller` (any kind) on
    /// `channels`, in the loop of `plant`, timed after at least `min_warmup` steps.
    pub fn in_loop(
        name: &str,
        slug: &str,
        channels: Channels,
        controller: &str,
        min_warmup: u64,
        plant: LoopPlant,
    ) -> Self {
        Self {
            name: name.to_string(),
            slug: slug.to_string(),
            toml: step_toml(channels, controller),
            min_warmup,
            plant: Some(plant),
            command: Vec::new(),
        }
    }

    /// A SISO case named `name` for a controller that follows the command
    /// `r_k = Σ cos(ω_i k)` (`command`: the `ω_i`), in the loop of `plant`.
    pub fn following(
        name: &str,
        slug: &str,
        controller: &str,
        min_warmup: u64,
        plant: LoopPlant,
        command: &[f64],
    ) -> Self {
        Self {
            name: name.to_string(),
            slug: slug.to_string(),
            toml: step_toml(Channels { y: 1, z: 1, u: 1 }, controller)
                .replace("u = 1 }", "r = 1, u = 1 }"),
            min_warmup,
            plant: Some(plant),
            command: command.to_vec(),
        }
    }
}

/// A service configuration at the 8 kHz period around a `[controller]` table given as text.
pub fn step_toml(channels: Channels, controller: &str) -> String {
    format!(
        "[rig]\nname = \"bench-step\"\nsample-period = 1.25e-4\n\n[service]\n\
         channels = {{ y = {}, z = {}, u = {} }}\n\n{controller}\n[log]\nenabled = false\n",
        channels.y, channels.z, channels.u
    )
}

/// RCAC's `k_w` in the bench cases: `n_c = 50` plus the largest delay (16) plus margin.
pub const RCAC_KW: u64 = 100;

/// The acoustic rig's dereverberated target model (3.49): one output, two inputs, delays 9
/// and 16 samples, 6th-order `Ĝ_d` per channel, β = 0.9, as `rig-design dtf --method
/// average` wrote it from the identification run (`runs/design/acoustic/target-model.toml`).
pub const ACOUSTIC_TARGET: &str = r#"[controller.target-model]
form = "transfer-function"
sample-period = 1.25e-4
outputs = 1
inputs = 2
beta = 0.9
source = "rig-design dtf --method average (acoustic rig identification)"
[[controller.target-model.channel]]
output = 0
input = 0
delay = 9
num = [-0.05016012400620995, 0.08879620055185959, -0.0618694748412579, 0.029814566814328886, -0.004406028155685372, -0.002605765254407065]
den = [1.0, -3.194107638430421, 4.768417404012421, -4.846782004116789, 3.62870254105471, -1.7504295726667782, 0.3952646368383396]
[[controller.target-model.channel]]
output = 0
input = 1
delay = 16
num = [0.11576027354482188, -0.22579935458178954, 0.11015674914149816, 0.11387417860468606, -0.1876151403933193, 0.07705850541881361]
den = [1.0, -3.5234543531271285, 5.658553373179581, -5.368039876629378, 3.1444112020561565, -1.1249541511812335, 0.2185537812604875]
"#;

/// The `[controller]` table of an RCAC controller of the acoustic rig's size (`n_c = 50`,
/// `l_u = 2`, `l_y = l_z = 1`, so `l_θ = 300`) with [`ACOUSTIC_TARGET`]; `update` holds
/// the keys of the update law (and any `[controller.forgetting]` table comes after).
pub fn acoustic_rcac_toml(update: &str, tables: &str) -> String {
    format!(
        "[controller]\nkind = \"rcac\"\ninput = \"y\"\nnc = 50\nkw = {RCAC_KW}\nrz = 1.0\n\
         u-min = -2.0\nu-max = 2.0\n{update}\n{ACOUSTIC_TARGET}{tables}"
    )
}

/// The loop of the RCAC cases: the plant is the target model itself (its first 400 Markov
/// parameters, 50 ms), the disturbance a 400 Hz tone of amplitude 0.5 plus white noise of
/// σ = 0.1.
pub fn acoustic_plant() -> LoopPlant {
    let target = <control::target::TargetModel as service::config::TargetModelFile>::parse(
        &ACOUSTIC_TARGET.replace("controller.target-model", "target-model"),
        "acoustic target",
    )
    .expect("the acoustic target model is valid");
    LoopPlant {
        markov: target.markov(400),
        tone: 0.5,
        tone_w: 2.0 * std::f64::consts::PI * 400.0 * 1.25e-4,
        noise_std: 0.1,
        seed: 5,
    }
}

/// The plant of chapter 4's Example 1 (4.83) at `ρ = 0.5`, `ν = π/4`,
/// `y = (q⁻¹ − 0.5 q⁻²)/(1 − 2ρ cos ν q⁻¹ + ρ² q⁻²) u`, as its first 64 Markov parameters
/// (the rest are below 10⁻¹⁸), with a little noise: the loop of the APPC and RC-MRAC cases.
pub fn mrac_example1_plant() -> LoopPlant {
    let (rho, nu) = (0.5_f64, std::f64::consts::FRAC_PI_4);
    let (d1, d2) = (-2.0 * rho * nu.cos(), rho * rho);
    let num = [0.0, 1.0, -0.5];
    // The impulse response h_k of N/D: h_k = N_k − d1 h_{k−1} − d2 h_{k−2}.
    let mut h = vec![0.0; 64];
    for k in 0..h.len() {
        let n_k = num.get(k).copied().unwrap_or(0.0);
        let a = if k >= 1 { d1 * h[k - 1] } else { 0.0 };
        let b = if k >= 2 { d2 * h[k - 2] } else { 0.0 };
        h[k] = n_k - a - b;
    }
    LoopPlant {
        markov: h.iter().map(|v| DMatrix::from_element(1, 1, *v)).collect(),
        tone: 0.0,
        tone_w: 0.0,
        noise_std: 1e-3,
        seed: 4,
    }
}

/// The frequencies of chapter 4's four-harmonic command
/// `r_k = cos k + cos(k/2) + cos(k/4) + cos(k/8)` (§4.5), rad/sample: the command of the
/// APPC and RC-MRAC cases.
pub const MRAC_COMMAND: [f64; 4] = [1.0, 0.5, 0.25, 0.125];

/// The controller configurations the bench knows, in table order. Add new controllers
/// (PCAC, …) here.
pub fn step_cases() -> Vec<StepCase> {
    let siso = Channels { y: 1, z: 1, u: 1 };
    let two_in = Channels { y: 2, z: 2, u: 1 };
    let acoustic = Channels { y: 1, z: 1, u: 2 };
    let warm = 2 * RCAC_KW;
    vec![
        StepCase::lti(
            "lti static gain (SISO)",
            "lti-static-gain",
            siso,
            &static_gain(DMatrix::from_element(1, 1, -0.5)),
        ),
        StepCase::lti(
            "lti 10-state SISO",
            "lti-10-state",
            siso,
            &random_controller(10, 1, 1, 0.9, 0.5, 10),
        ),
        StepCase::lti(
            "lti 50-state 2-in/1-out",
            "lti-50-state-2x1",
            two_in,
            &random_controller(50, 2, 1, 0.9, 0.5, 50),
        ),
        StepCase::in_loop(
            "rcac gradient exp, nc 50, 2u/1y (lθ 300)",
            "rcac-gradient-exp-300",
            acoustic,
            &acoustic_rcac_toml(
                "update = \"gradient\"\nstep-size = \"exp\"\nalpha = 0.05\nr = 0.0",
                "",
            ),
            warm,
            acoustic_plant(),
        ),
        StepCase::in_loop(
            "rcac RLS λ=1, nc 50, 2u/1y (lθ 300, p 1)",
            "rcac-rls-300x1",
            acoustic,
            &acoustic_rcac_toml("update = \"rls\"\np0 = 1.0\nlambda = 1.0\nru = 0.0", ""),
            warm,
            acoustic_plant(),
        ),
        StepCase::in_loop(
            "rcac RLS F-test, Ru>0, nc 50, 2u/1y (lθ 300, p 3)",
            "rcac-rls-ftest-300x3",
            acoustic,
            &acoustic_rcac_toml(
                "update = \"rls\"\np0 = 1.0\nru = 1e-3",
                "[controller.forgetting]\nrule = \"f-test\"\ntau-n = 10\ntau-d = 80\neta = 1.0\nalpha = 0.001\n",
            ),
            warm,
            acoustic_plant(),
        ),
        StepCase::following(
            "appc, n 2 (lθ 8), Example 1 of ch. 4",
            "appc-n2",
            include_str!("../../scenarios/mrac/appc.toml"),
            0,
            mrac_example1_plant(),
            &MRAC_COMMAND,
        ),
        StepCase::following(
            "rc-mrac, n 2, n_s 1 (lθ 6), Example 1 of ch. 4",
            "rc-mrac-n2",
            include_str!("../../scenarios/mrac/rc-mrac.toml"),
            0,
            mrac_example1_plant(),
            &MRAC_COMMAND,
        ),
    ]
}

/// What the paced plant of the response-time phase ([`crate::timing_phase`]) puts in its
/// measurements, and what it does with the answers.
#[derive(Debug, Clone)]
pub enum PacedPlant {
    /// `y_0` is the bench's test signal, every other channel 0; the answers are not fed
    /// back (a fixed controller does the same work on any data).
    Signal,
    /// The closed loop of a [`LoopPlant`] (`y = z`), as in the step-cost phase: the input
    /// answered for sample `k` enters the FIR for the next samples.
    Fir(LoopPlant),
    /// The closed loop of [`crate::synthetic_arm::ArmPlant`] with this noise seed (`y = z = x + v`).
    Arm(u64),
}

/// One controller of the response-time phase: the service runs it once with
/// `timing = "compute-first"` and once with `timing = "answer-first"`.
#[derive(Debug, Clone)]
pub struct TimingCase {
    /// Name in the table (`response: <name> — <timing>`).
    pub name: String,
    /// File-name form of the name (the folder `timing/<slug>-<timing>/`).
    pub slug: String,
    /// Channel counts.
    pub channels: Channels,
    /// The `[controller]` table (any kind, as text); the controller must have an ahead
    /// form (`Controller::ahead()`), or the service refuses `answer-first`.
    pub controller: String,
    /// The loop the paced plant closes around it.
    pub plant: PacedPlant,
    /// The sample period of the paced loop, ns: [`crate::PERIOD_NS`] (8 kHz) but for a
    /// controller whose step does not fit it.
    pub period_ns: u64,
}

impl TimingCase {
    /// The complete service configuration of this case for rig `rig`, answering with
    /// `timing`.
    pub fn service_toml(&self, rig: &str, timing: Timing, log: bool) -> String {
        service_toml_with(
            rig,
            self.period_ns,
            self.channels,
            &self.controller,
            Some(timing),
            log,
        )
    }
}

/// The controllers of the response-time phase, in table order: those of
/// [`step_cases`] that answer ahead, at the same sizes and on the same loops, and PCAC at
/// the sampling arm's size in its next-step timing on the synthetic plant of
/// [`crate::synthetic_arm`] (the real arm controller answers in the same step and has no
/// ahead form).
///
/// - the 50-state 2-in/1-out LTI controller of the step cost with `D = 0` (with `D ≠ 0`
///   its `u_k` needs `y_k`, so it has no ahead form), 8 kHz;
/// - RCAC gradient with the exp step size, and RCAC RLS with λ = 1, both `n_c = 50`, 2
///   inputs, 1 output, in the loop of [`acoustic_plant`], 8 kHz;
/// - PCAC arm, `timing = "next-step"`, at [`ARM_PERIOD_NS`] (2 kHz, the arm's rate), not
///   8 kHz, because it cannot meet that period: its steady step (no QP iteration) takes
///   65–90 µs, more than the `T/2 = 62.5 µs` deadline of compute-first, and every dual
///   active-set step of its QP (100 variables) adds ~10 µs, so that a change of the
///   active set (the first samples of the identification: 160–230 dual steps, ~2 ms)
///   spans many periods; the plant holds its input meanwhile, the next QP changes as
///   much, and answer-first falls behind for good. The replay of
///   `examples/arm_catch_up.rs` (`loop 125`: 65 µs + 10 µs per QP iteration) answers
///   1256 of 8000 samples at 8 kHz, 860 in time, 71 QP iterations per step; at 2 kHz
///   7939 in time, 2.3 per step. In that replay the 2 kHz loop that falls behind now
///   recovers: the samples caught up keep PCAC's warm start (moved along the horizon,
///   `Pcac::observe`); with the warm start dropped the same replay answered 900 of 8000
///   in time. Each round of the bench is 1 s from a cold start, so most of it is that
///   identification transient, with the inputs at their bounds on many steps; the
///   service's figures (docs/results/latency-bench.md, "response by timing") are
///   therefore below the replay's, compute-first's most (its deadline is `T/2`, so more
///   of its answers are late, the plant holds more inputs, and the next problems move
///   further from their warm starts).
pub fn timing_cases() -> Vec<TimingCase> {
    let two_in = Channels { y: 2, z: 2, u: 1 };
    let acoustic = Channels { y: 1, z: 1, u: 2 };
    let arm = Channels {
        y: crate::synthetic_arm::ARM_P,
        z: crate::synthetic_arm::ARM_P,
        u: crate::synthetic_arm::ARM_M,
    };
    let mut lti = random_controller(50, 2, 1, 0.9, 0.5, 50);
    lti.d.fill(0.0);
    let case = |name: &str, slug: &str, channels, controller: String, plant| TimingCase {
        name: name.to_string(),
        slug: slug.to_string(),
        channels,
        controller,
        plant,
        period_ns: crate::PERIOD_NS,
    };
    vec![
        case(
            "lti 50-state 2-in/1-out D=0",
            "lti-50-state-2x1-d0",
            two_in,
            controller_toml(&lti),
            PacedPlant::Signal,
        ),
        case(
            "rcac gradient exp nc 50",
            "rcac-gradient-exp-300",
            acoustic,
            acoustic_rcac_toml(
                "update = \"gradient\"\nstep-size = \"exp\"\nalpha = 0.05\nr = 0.0",
                "",
            ),
            PacedPlant::Fir(acoustic_plant()),
        ),
        case(
            "rcac RLS λ=1 nc 50",
            "rcac-rls-300x1",
            acoustic,
            acoustic_rcac_toml("update = \"rls\"\np0 = 1.0\nlambda = 1.0\nru = 0.0", ""),
            PacedPlant::Fir(acoustic_plant()),
        ),
        TimingCase {
            period_ns: ARM_PERIOD_NS,
            ..case(
                "pcac arm next-step 2 kHz",
                "pcac-arm-next-step-2khz",
                arm,
                crate::synthetic_arm::arm_controller_toml(),
                PacedPlant::Arm(7),
            )
        },
    ]
}

/// The sample period of the PCAC arm case of [`timing_cases`]: 500 µs (2 kHz, §7.3).
pub const ARM_PERIOD_NS: u64 = 500_000;

#[cfg(test)]
mod tests {
    use super::*;
    use service::config::ServiceConfig;

    #[test]
    fn random_state_matrices_have_the_requested_spectral_radius() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for n in [1, 10, 50] {
            let a = random_stable(n, 0.9, &mut rng);
            assert!((spectral_radius(&a) - 0.9).abs() < 1e-9, "n = {n}");
        }
    }

    #[test]
    fn every_step_case_is_accepted_by_the_service_configuration() {
        for case in step_cases() {
            let cfg = ServiceConfig::parse(&case.toml, "bench")
                .unwrap_or_else(|e| panic!("{}: {e}\n{}", case.name, case.toml));
            cfg.controller.build(cfg.counts).unwrap();
        }
        let text = service_toml(
            "bench-1",
            Channels { y: 1, z: 1, u: 1 },
            &loop_controller(),
            true,
        );
        let cfg = ServiceConfig::parse(&text, "bench").unwrap();
        assert_eq!(cfg.sample_period_ns, crate::PERIOD_NS);
        assert_eq!(cfg.rig, "bench-1");
        assert!(cfg.log.enabled);
        // The round trip and the wake-up phase wait for the answer carrying k.
        assert_eq!(cfg.answer.timing, Timing::ComputeFirst);
    }

    #[test]
    fn every_timing_case_is_accepted_in_both_timings_and_answers_ahead() {
        for case in timing_cases() {
            for timing in [Timing::ComputeFirst, Timing::AnswerFirst] {
                let text = case.service_toml("bench-t", timing, false);
                let cfg = ServiceConfig::parse(&text, "bench")
                    .unwrap_or_else(|e| panic!("{} {}: {e}\n{text}", case.name, timing.name()));
                assert_eq!(cfg.answer.timing, timing, "{}", case.name);
                assert_eq!(cfg.sample_period_ns, case.period_ns, "{}", case.name);
                let mut c = cfg.controller.build(cfg.counts).unwrap();
                assert!(c.ahead().is_some(), "{}", case.name);
            }
        }
        // The LTI case is the step cost's 50-state controller with D zeroed.
        let lti = random_controller(50, 2, 1, 0.9, 0.5, 50);
        let case = &timing_cases()[0];
        assert!(case.controller.contains(&toml_matrix(&lti.a)));
        assert!(
            case.controller.contains("d = [[0.0, 0.0]]"),
            "{}",
            case.controller
        );
    }

    #[test]
    fn matrices_are_written_as_toml_floats() {
        let m = DMatrix::from_row_slice(2, 2, &[1.0, -2.5, 1e-7, 0.0]);
        assert_eq!(toml_matrix(&m), "[[1.0, -2.5], [1e-7, 0.0]]");
        assert_eq!(toml_matrix(&DMatrix::zeros(0, 3)), "[]");
    }
}
