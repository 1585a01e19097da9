//! # The plant part of a scenario file
//!
//! A scenario TOML file carries tables for several programs. plant-proxy reads `[rig]` and
//! `[plant]` (with its sub-tables) and ignores every other top-level table (`[service]`,
//! `[controller]`, `[log]`, `[proxy]`, …). Inside `[rig]` and `[plant]` an unknown key is an
//! error, so a typo never goes unnoticed. The file is read once into raw serde structures,
//! then validated into typed parameters ([`Scenario`], [`RigParams`], [`PlantParams`]); every
//! error names the file, the field as a dotted path (`plant.tf.yu[0][1].den`) and what is
//! wrong ([`ScenarioError`]).
//!
//! ```toml
//! [rig]
//! name = "acoustic-rig"     # ASCII letters, digits, '-', '_' (1 to 64): iceoryx2 service names
//! sample-period = 1.25e-4   # s; or sample-rate-hz = 8000.0 (exactly one of the two)
//! duration = 10.0           # s of the default run
//!
//! [plant]
//! kind = "transfer-function"   # or "state-space", "modal", "truss", "discrete",
//!                              # "mrac-example", "sampling-arm"
//! inputs = 2                   # control inputs u
//! disturbances = 1             # disturbance inputs w (may be 0)
//! outputs-y = 1                # measurements y
//! outputs-z = 1                # performance outputs z
//! input-delays = [9, 16]       # optional: pure delay in samples per control input (default 0)
//! initial-state = [0.0, …]     # optional: continuous state at t = 0 (default zeros)
//! commands = 0                 # optional: command channels r (default 0) …
//! command = []                 # … held at this constant vector (default zeros), or the
//!                              # table [plant.command] below (one channel)
//!
//! [plant.tf]                   # kind = "transfer-function": continuous-time G(s) matrices
//! yu = [[ { num = [..], den = [..] }, 0 ]]   # outputs-y × inputs; 0 or a missing row = zero
//! yw = [[ .. ]]                # outputs-y × disturbances
//! zu = [[ .. ]]                # outputs-z × inputs
//! zw = [[ .. ]]                # outputs-z × disturbances
//!
//! [plant.ss]                   # kind = "state-space": row-major arrays of rows
//! a = [[..]]
//! b-u = [[..]]                 # also b-w, c-y, c-z; d-yu, d-yw, d-zu, d-zw optional (zero)
//!
//! [plant.modal]                # kind = "modal": q̈ + 2ζω q̇ + ω² q = b_u·u + b_w·w
//! modes = [ { frequency-hz = 520.0, damping = 0.02, b-u = [..], b-w = [..],
//!             c-y = [..], c-z = [..] } ]     # also frequency-rad-s, c-y-vel, c-z-vel
//!
//! [plant.truss]                # kind = "truss": a planar truss of pinned members, see
//! …                            # crate::truss for its fields (nodes, members, ports, SNR)
//!
//! [plant.discrete]             # kind = "discrete": N(q⁻¹)/D(q⁻¹), per step (crate::discrete)
//! num = [0.0, 1.0, -0.5]       # b_0 = 0, b_1, …: ascending powers of q⁻¹
//! den = [1.0, -0.7071, 0.25]   # a_0 ≠ 0, a_1, …
//!
//! [plant.mrac-example]         # kind = "mrac-example": (4.83) or (4.88) (crate::mrac_examples)
//! example = 1                  # 1: (4.83), zero 0.5; 2: (4.88), zero 1.5
//! rho = 0.5                    # pole radius in (0, 1)
//! nu = 0.7853981633974483      # pole angle in [0, π] rad
//!
//! [plant.surface]              # kind = "sampling-arm": the arm of chapter 7 (crate::arm);
//! model = "kelvin-voigt"       # (7.27), or "hunt-crossley" (7.28) with restitution = c_r
//! stiffness = 2.0e5            # k_s
//! damping = 5.0                # c_s
//!                              # optional, the chapter's defaults: [plant.sampling-arm]
//!                              # (spacecraft, initial angles, height, descent speed),
//!                              # [plant.guidance], [plant.second-sampling] (with its own
//!                              # .surface: the double maneuver), [plant.integrator]
//!
//! [plant.input-disturbance]    # discrete kinds only: d_k added to the input u_k
//! harmonics = [ { amplitude = 1.0, frequency-rad-step = 0.35, phase-rad = 0.0 } ]
//!
//! [plant.command]              # a generated command r_k, one channel (crate::command)
//! kind = "step"                # r_k = amplitude (default 1) for k ≥ start (default 0)
//! amplitude = 1.0
//! start = 0
//! # or kind = "harmonics" with preset = "two-harmonic" | "four-harmonic", or with
//! # terms = [ { amplitude, frequency-rad-step, phase-rad } ]: Σ a_i cos(ω_i k + φ_i)
//!
//! [plant.disturbance]
//! tones = [ { input = 0, amplitude = 1.0, frequency-hz = 800.0, phase-deg = 0.0 } ]
//! white-std = [0.0]            # per disturbance input (or one scalar): ZOH white noise
//! band-limited = [ { input = 0, rms = 1.0, cutoff-hz = 25.0, order = 4 } ]
//!                              # continuous white noise through a Butterworth low-pass
//!
//! [plant.noise]
//! y-std = 0.0                  # white measurement noise: scalar or one per channel
//! z-std = 0.0
//! seed = 1
//! ```
//!
//! Meaning of the plant (see [`crate::lti::generalized`] and [`crate::sim`]):
//! `ẋ = A x + B_u u + B_w w`, `y = C_y x + D_yu u + D_yw w + v_y`,
//! `z = C_z x + D_zu u + D_zw w + v_z`; the tones give `w_i(t) = Σ A sin(2π f t + φ)` on
//! their input, the white part adds a new `N(0, σ_i²)` value each sample held over the
//! period, and `v_y`, `v_z` are white `N(0, σ²)` measurement noises. For
//! `kind = "transfer-function"` the states are those of the column-wise realization of
//! `[[G_yu, G_yw], [G_zu, G_zw]]` ([`crate::lti::realize_tf_matrix_sized`]); for
//! `kind = "modal"` they are `[q_1, q̇_1, q_2, q̇_2, …]`; for `kind = "truss"` they are the
//! modal coordinates `[η_1, η̇_1, …]` of the truss ([`crate::truss`]).
//!
//! The discrete kinds (`"discrete"`, `"mrac-example"`) are run by their difference
//! equation `y_k = Σ_j b_j u_{k−j} − Σ_i a_i y_{k−i}`, one step per sample, with no
//! discretization ([`crate::discrete`]); they have one input, no `w`, one `y` and `z = y`
//! (`inputs`, `disturbances`, `outputs-y`, `outputs-z` may be omitted, and must be 1, 0,
//! 1, 1 when given), start at rest (no `initial-state`), and take their disturbance in
//! `[plant.input-disturbance]` (`u_k + d_k`, after the input delay) instead of
//! `[plant.disturbance]`. `[plant.noise]` adds measurement noise as for the other kinds.
//!
//! The sampling arm (`"sampling-arm"`, [`crate::arm`]) is nonlinear and integrated between
//! samples; its channel counts are its wire contract (2 `u`, no `w`, 7 `y`, 1 `z`, one
//! command `r = F_d` made by its guidance), which may be omitted; it takes no
//! `plant.command`, `initial-state` or `[plant.disturbance]`.
//!
//! A band-limited disturbance is `w_i(t) += y_f(t)`, the output of a Butterworth low-pass
//! of order `order` and cutoff `cutoff-hz` (unit DC gain) driven by continuous-time white
//! noise whose intensity makes the stationary RMS of `y_f` equal to `rms`. It is defined in
//! continuous time, independently of the sample period, and simulated exactly
//! ([`crate::sim`], "Band-limited disturbances").

use crate::arm::ArmPlantParams;
use crate::command::Command;
use crate::discrete::DiscretePlant;
use crate::lti::{ChannelDims, GeneralizedPlant, LtiError, Mode, Tf};
use nalgebra::DMatrix;
use rig_scenario::FieldError;
use rig_scenario::rig::{RawRig, RigTable};
use serde::Deserialize;
use std::f64::consts::PI;
use std::fmt;
use std::path::Path;

/// The largest accepted input delay, in samples (the ring buffers are allocated up front).
pub const MAX_INPUT_DELAY: usize = 1 << 20;

pub use rig_scenario::bounds::{MAX_DURATION_S, MAX_SAMPLE_PERIOD_S, MIN_SAMPLE_PERIOD_S};

/// The largest number of disturbance inputs `w` (`plant.disturbances`).
pub const MAX_DISTURBANCES: usize = 64;

/// The largest number of continuous states of the plant (its matrices are dense and
/// discretized by a matrix exponential at load time).
pub const MAX_STATES: usize = 1000;

/// The largest number of disturbance tones (each adds two exosystem states).
pub const MAX_TONES: usize = 128;

/// The largest number of band-limited disturbances (each adds up to
/// [`MAX_BAND_LIMITED_ORDER`] states).
pub const MAX_BAND_LIMITED: usize = 64;

/// The largest angular frequency, rad/s, of a mode, a tone or a band-limited cutoff: far
/// beyond any rig, and small enough that `ω²` and the filters' powers of `ω` stay finite.
pub const MAX_FREQUENCY_RAD_S: f64 = 1e12;

/// The largest standard deviation of a white disturbance or measurement noise: beyond it
/// the samples and their squares stop being meaningful numbers.
pub const MAX_NOISE_STD: f64 = 1e9;

/// Why a scenario file was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum ScenarioError {
    /// The file could not be read.
    Io {
        /// The file.
        origin: String,
        /// The operating system's message.
        message: String,
    },
    /// The text is not valid TOML, or a value has the wrong type (the message shows the
    /// line, the column and the key).
    Toml {
        /// The file.
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// A field has a missing, inconsistent or out-of-range value.
    Field {
        /// The file.
        origin: String,
        /// Dotted path of the field, e.g. `plant.tf.yu[0][1].den`.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

impl ScenarioError {
    /// The dotted path of the offending field, when the error is about one field.
    pub fn field(&self) -> Option<&str> {
        match self {
            ScenarioError::Field { field, .. } => Some(field),
            _ => None,
        }
    }
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScenarioError::Io { origin, message } => {
                write!(f, "{origin}: cannot read the file: {message}")
            }
            ScenarioError::Toml { origin, message } => {
                write!(f, "{origin}: not valid TOML: {}", message.trim_end())
            }
            ScenarioError::Field {
                origin,
                field,
                problem,
            } => {
                write!(f, "{origin}: field '{field}': {problem}")
            }
        }
    }
}

impl std::error::Error for ScenarioError {}

/// A validated scenario: the rig and the plant.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The file it was read from (or the origin given to [`parse`]).
    pub origin: String,
    /// The `[rig]` table.
    pub rig: RigParams,
    /// The `[plant]` table and its sub-tables.
    pub plant: PlantParams,
}

/// The `[rig]` table.
#[derive(Debug, Clone, PartialEq)]
pub struct RigParams {
    /// Rig name, used in the iceoryx2 service names.
    pub name: String,
    /// Sample period `T_s`, s.
    pub sample_period: f64,
    /// Duration of the default run, s.
    pub duration: f64,
}

/// How the plant was described in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlantKind {
    /// `kind = "transfer-function"`: `[plant.tf]`.
    TransferFunction,
    /// `kind = "state-space"`: `[plant.ss]`.
    StateSpace,
    /// `kind = "modal"`: `[plant.modal]`.
    Modal,
    /// `kind = "truss"`: `[plant.truss]` ([`crate::truss`]).
    Truss,
    /// `kind = "discrete"`: `[plant.discrete]`, a discrete-time `N(q⁻¹)/D(q⁻¹)` run by its
    /// difference equation ([`crate::discrete`]).
    Discrete,
    /// `kind = "mrac-example"`: `[plant.mrac-example]`, the plant (4.83) or (4.88) of
    /// chapter 4 from `(ρ, ν)` ([`crate::mrac_examples`]), run like `Discrete`.
    MracExample,
    /// `kind = "sampling-arm"`: the spacecraft with a two-link sampling arm of chapter 7
    /// (`[plant.sampling-arm]`, `[plant.surface]`, …), a nonlinear plant integrated between
    /// samples ([`crate::arm`]).
    SamplingArm,
}

impl PlantKind {
    /// The name used in the file.
    pub fn name(self) -> &'static str {
        match self {
            PlantKind::TransferFunction => "transfer-function",
            PlantKind::StateSpace => "state-space",
            PlantKind::Modal => "modal",
            PlantKind::Truss => "truss",
            PlantKind::Discrete => "discrete",
            PlantKind::MracExample => "mrac-example",
            PlantKind::SamplingArm => "sampling-arm",
        }
    }

    /// True for the discrete-time kinds (`"discrete"`, `"mrac-example"`).
    pub fn is_discrete(self) -> bool {
        matches!(self, PlantKind::Discrete | PlantKind::MracExample)
    }
}

/// One harmonic disturbance tone `w_input(t) += amplitude · sin(omega t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tone {
    /// Index of the disturbance input it drives.
    pub input: usize,
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency, rad/s (≥ 0).
    pub omega: f64,
    /// Phase at `t = 0`, rad.
    pub phase: f64,
}

/// One band-limited disturbance: `w_input(t) += y_f(t)`, the output of a Butterworth
/// low-pass filter driven by continuous-time white noise (see [`crate::sim`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandLimited {
    /// Index of the disturbance input it drives.
    pub input: usize,
    /// Stationary RMS of `y_f`.
    pub rms: f64,
    /// Cutoff (−3 dB) angular frequency `ω_c` of the filter, rad/s (> 0).
    pub omega_c: f64,
    /// Order of the Butterworth filter, 1 to [`MAX_BAND_LIMITED_ORDER`].
    pub order: usize,
}

/// The largest order of a band-limited disturbance's Butterworth filter.
pub const MAX_BAND_LIMITED_ORDER: usize = 12;

/// The `[plant.disturbance]` table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DisturbanceParams {
    /// Harmonic tones, integrated exactly through an exosystem.
    pub tones: Vec<Tone>,
    /// Standard deviation of the white, sample-and-hold part of each disturbance input
    /// (`n_w` entries).
    pub white_std: Vec<f64>,
    /// Band-limited disturbances (continuous white noise through low-pass filters).
    pub band_limited: Vec<BandLimited>,
}

/// The `[plant.noise]` table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NoiseParams {
    /// Standard deviation of the white measurement noise on each `y` (`n_y` entries).
    pub y_std: Vec<f64>,
    /// Standard deviation of the white noise on each `z` (`n_z` entries).
    pub z_std: Vec<f64>,
    /// Seed of the random generator (ChaCha8).
    pub seed: u64,
}

/// The validated `[plant]` table: the continuous-time generalized plant (or the
/// discrete-time one) and what drives it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantParams {
    /// How the plant was described.
    pub kind: PlantKind,
    /// The continuous-time model (realized for `kind = "transfer-function"`). For the
    /// discrete kinds it has no state, one input `u`, no `w`, one `y` and one `z` (all
    /// matrices zero): the plant is [`PlantParams::discrete`].
    pub model: GeneralizedPlant,
    /// The discrete-time plant of `kind = "discrete"` or `"mrac-example"`, run by its
    /// difference equation instead of `model` ([`crate::discrete`]).
    pub discrete: Option<DiscretePlant>,
    /// The sampling arm of `kind = "sampling-arm"`, simulated instead of `model` (which
    /// then has no state, 2 inputs `u`, no `w`, 7 `y` and 1 `z`) ([`crate::arm`]).
    pub arm: Option<ArmPlantParams>,
    /// Pure delay of each control input, samples (`n_u` entries).
    pub input_delays: Vec<usize>,
    /// State at `t = 0` (`n_x` entries).
    pub initial_state: Vec<f64>,
    /// The command `r`: constant (`n_r` entries) or generated (one channel)
    /// ([`crate::command`]).
    pub command: Command,
    /// Disturbances.
    pub disturbance: DisturbanceParams,
    /// Measurement noise.
    pub noise: NoiseParams,
}

impl PlantParams {
    /// Parameters for `model` with no delay, a zero initial state, no command, no
    /// disturbance and no noise (seed 0); `kind` is [`PlantKind::StateSpace`].
    pub fn new(model: GeneralizedPlant) -> Self {
        let d = model.dims();
        Self {
            kind: PlantKind::StateSpace,
            discrete: None,
            arm: None,
            input_delays: vec![0; d.n_u],
            initial_state: vec![0.0; model.n_x()],
            command: Command::default(),
            disturbance: DisturbanceParams {
                tones: Vec::new(),
                white_std: vec![0.0; d.n_w],
                band_limited: Vec::new(),
            },
            noise: NoiseParams {
                y_std: vec![0.0; d.n_y],
                z_std: vec![0.0; d.n_z],
                seed: 0,
            },
            model,
        }
    }

    /// Number of control inputs `u`.
    pub fn n_u(&self) -> usize {
        self.model.dims().n_u
    }

    /// Number of disturbance inputs `w`.
    pub fn n_w(&self) -> usize {
        self.model.dims().n_w
    }

    /// Number of measurements `y`.
    pub fn n_y(&self) -> usize {
        self.model.dims().n_y
    }

    /// Number of performance outputs `z`.
    pub fn n_z(&self) -> usize {
        self.model.dims().n_z
    }

    /// Number of command channels `r`.
    pub fn n_r(&self) -> usize {
        self.command.n_r()
    }

    /// Number of states of the continuous plant (without the exosystem of the tones); for
    /// a discrete plant, the length `n + m` of its difference equation's state.
    pub fn n_x(&self) -> usize {
        match (&self.discrete, &self.arm) {
            (Some(d), _) => d.tf.n_states(),
            (None, Some(_)) => crate::arm::N_STATES,
            (None, None) => self.model.n_x(),
        }
    }

    /// Parameters for the discrete-time plant `plant` (`kind = "discrete"`): one input, no
    /// `w`, `z = y`, no delay, no command and no noise (seed 0).
    pub fn new_discrete(plant: DiscretePlant) -> Self {
        let dims = ChannelDims {
            n_u: 1,
            n_w: 0,
            n_y: 1,
            n_z: 1,
        };
        Self {
            kind: PlantKind::Discrete,
            discrete: Some(plant),
            initial_state: Vec::new(),
            ..Self::new(GeneralizedPlant::zeros(0, dims))
        }
    }

    /// Parameters for the sampling arm `arm` (`kind = "sampling-arm"`): 2 inputs, no `w`,
    /// 7 `y`, 1 `z`, the command channel `r = F_d` of the guidance, no delay and no noise
    /// (seed 0).
    pub fn new_arm(arm: ArmPlantParams) -> Self {
        let dims = crate::arm::dims();
        Self {
            kind: PlantKind::SamplingArm,
            arm: Some(arm),
            initial_state: Vec::new(),
            command: Command::Constant(vec![0.0; crate::arm::N_R]),
            ..Self::new(GeneralizedPlant::zeros(0, dims))
        }
    }

    /// The sampling arm's parameters, to change before building a simulation (a study's
    /// surface: `params.arm_mut().unwrap().surface.model = ContactModel::kelvin_voigt(k, c)?`);
    /// `None` for other kinds. [`crate::sim::PlantSim::new`] validates them again.
    pub fn arm_mut(&mut self) -> Option<&mut ArmPlantParams> {
        self.arm.as_mut()
    }
}

/// Reads and validates the scenario file at `path`.
pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ScenarioError::Io {
        origin: origin.clone(),
        message: e.to_string(),
    })?;
    parse(&text, &origin)
}

/// Validates the text of a scenario file; `origin` names it in errors.
pub fn parse(text: &str, origin: &str) -> Result<Scenario, ScenarioError> {
    let raw: RawFile = toml::from_str(text).map_err(|e| ScenarioError::Toml {
        origin: origin.to_string(),
        message: e.to_string(),
    })?;
    let cx = Cx { origin };
    let rig = raw
        .rig
        .ok_or_else(|| cx.err("rig", "the [rig] table is missing"))?;
    let rig = validate_rig(&cx, rig)?;
    let plant = raw
        .plant
        .ok_or_else(|| cx.err("plant", "the [plant] table is missing"))?;
    let plant = validate_plant(&cx, plant)?;
    check_discretizable(&cx, &plant, rig.sample_period)?;
    Ok(Scenario {
        origin: origin.to_string(),
        rig,
        plant,
    })
}

// ---------------------------------------------------------------------------------------
// Raw file structure.

#[derive(Deserialize)]
struct RawFile {
    rig: Option<RawRig>,
    plant: Option<RawPlant>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawPlant {
    kind: Option<String>,
    inputs: Option<usize>,
    disturbances: Option<usize>,
    outputs_y: Option<usize>,
    outputs_z: Option<usize>,
    input_delays: Option<Vec<usize>>,
    initial_state: Option<Vec<f64>>,
    commands: Option<usize>,
    command: Option<toml::Value>,
    tf: Option<RawTf>,
    ss: Option<RawSs>,
    modal: Option<RawModal>,
    truss: Option<toml::Value>,
    discrete: Option<discrete_tables::RawDiscrete>,
    mrac_example: Option<discrete_tables::RawMracExample>,
    input_disturbance: Option<discrete_tables::RawInputDisturbance>,
    sampling_arm: Option<arm_tables::RawSamplingArm>,
    surface: Option<arm_tables::RawSurface>,
    guidance: Option<arm_tables::RawGuidance>,
    second_sampling: Option<arm_tables::RawSecondSampling>,
    integrator: Option<arm_tables::RawIntegrator>,
    disturbance: Option<RawDisturbance>,
    noise: Option<RawNoise>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTf {
    yu: Option<toml::Value>,
    yw: Option<toml::Value>,
    zu: Option<toml::Value>,
    zw: Option<toml::Value>,
}

type Rows = Vec<Vec<f64>>;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawSs {
    a: Option<Rows>,
    b_u: Option<Rows>,
    b_w: Option<Rows>,
    c_y: Option<Rows>,
    c_z: Option<Rows>,
    d_yu: Option<Rows>,
    d_yw: Option<Rows>,
    d_zu: Option<Rows>,
    d_zw: Option<Rows>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawModal {
    modes: Option<Vec<RawMode>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawMode {
    frequency_hz: Option<f64>,
    frequency_rad_s: Option<f64>,
    damping: Option<f64>,
    b_u: Option<Vec<f64>>,
    b_w: Option<Vec<f64>>,
    c_y: Option<Vec<f64>>,
    c_y_vel: Option<Vec<f64>>,
    c_z: Option<Vec<f64>>,
    c_z_vel: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawDisturbance {
    tones: Option<Vec<RawTone>>,
    white_std: Option<toml::Value>,
    band_limited: Option<Vec<RawBandLimited>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawBandLimited {
    input: Option<usize>,
    rms: Option<f64>,
    cutoff_hz: Option<f64>,
    cutoff_rad_s: Option<f64>,
    order: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTone {
    input: Option<usize>,
    amplitude: Option<f64>,
    frequency_hz: Option<f64>,
    frequency_rad_s: Option<f64>,
    phase_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawNoise {
    y_std: Option<toml::Value>,
    z_std: Option<toml::Value>,
    seed: Option<u64>,
}

// ---------------------------------------------------------------------------------------
// Validation.

/// Error context: the file name.
struct Cx<'a> {
    origin: &'a str,
}

impl Cx<'_> {
    fn err(&self, field: impl Into<String>, problem: impl Into<String>) -> ScenarioError {
        ScenarioError::Field {
            origin: self.origin.to_string(),
            field: field.into(),
            problem: problem.into(),
        }
    }

    /// A refusal of the schema crate, with the file.
    fn field(&self, e: FieldError) -> ScenarioError {
        self.err(e.field, e.problem)
    }

    fn required<T>(&self, v: Option<T>, field: &str) -> Result<T, ScenarioError> {
        v.ok_or_else(|| self.err(field, "is missing"))
    }

    fn finite(&self, v: f64, field: &str) -> Result<f64, ScenarioError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(field, format!("{v} is not finite")))
        }
    }

    fn positive(&self, v: f64, field: &str) -> Result<f64, ScenarioError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(field, format!("{v} is not positive and finite")))
        }
    }

    /// An angular frequency in rad/s from `frequency-hz` or `frequency-rad-s` (exactly one),
    /// positive (or, with `allow_zero`, non-negative); `f` makes the field path.
    fn frequency(
        &self,
        hz: Option<f64>,
        rad_s: Option<f64>,
        f: &dyn Fn(&str) -> String,
        allow_zero: bool,
    ) -> Result<f64, ScenarioError> {
        let check = |v: f64, key: &str| {
            if allow_zero {
                self.non_negative(v, &f(key))
            } else {
                self.positive(v, &f(key))
            }
        };
        match (hz, rad_s) {
            (Some(hz), None) => self
                .at_most_max_frequency(2.0 * PI * check(hz, "frequency-hz")?, &f("frequency-hz")),
            (None, Some(w)) => {
                self.at_most_max_frequency(check(w, "frequency-rad-s")?, &f("frequency-rad-s"))
            }
            (Some(_), Some(_)) => Err(self.err(
                f("frequency-hz"),
                "give frequency-hz or frequency-rad-s, not both",
            )),
            (None, None) => {
                Err(self.err(f("frequency-hz"), "is missing (or give frequency-rad-s)"))
            }
        }
    }

    /// A list length `n` (of `what`) between `min` and `max`.
    fn count(
        &self,
        n: usize,
        min: usize,
        max: usize,
        field: &str,
        what: &str,
    ) -> Result<(), ScenarioError> {
        if (min..=max).contains(&n) {
            Ok(())
        } else {
            Err(self.err(field, format!("has {n} {what}, expected {min} to {max}")))
        }
    }

    /// An angular frequency `w` (rad/s) of at most [`MAX_FREQUENCY_RAD_S`].
    fn at_most_max_frequency(&self, w: f64, field: &str) -> Result<f64, ScenarioError> {
        if w <= MAX_FREQUENCY_RAD_S {
            Ok(w)
        } else {
            Err(self.err(
                field,
                format!("{w} rad/s is above the bound {MAX_FREQUENCY_RAD_S} rad/s"),
            ))
        }
    }

    fn non_negative(&self, v: f64, field: &str) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.err(field, format!("{v} is negative or not finite")))
        }
    }

    fn vector(&self, v: &[f64], len: usize, field: &str, what: &str) -> Result<(), ScenarioError> {
        if v.len() != len {
            return Err(self.err(
                field,
                format!("has {} entries, expected {len} (one per {what})", v.len()),
            ));
        }
        for (i, x) in v.iter().enumerate() {
            self.finite(*x, &format!("{field}[{i}]"))?;
        }
        Ok(())
    }

    /// A row-major matrix of `rows × cols`; `[]` stands for an empty matrix.
    fn matrix(
        &self,
        m: &[Vec<f64>],
        rows: usize,
        cols: usize,
        field: &str,
    ) -> Result<DMatrix<f64>, ScenarioError> {
        if m.is_empty() && (rows == 0 || cols == 0) {
            return Ok(DMatrix::zeros(rows, cols));
        }
        if m.len() != rows {
            return Err(self.err(field, format!("has {} rows, expected {rows}", m.len())));
        }
        for (i, r) in m.iter().enumerate() {
            if r.len() != cols {
                return Err(self.err(
                    format!("{field}[{i}]"),
                    format!("has {} entries, expected {cols}", r.len()),
                ));
            }
            for (j, x) in r.iter().enumerate() {
                self.finite(*x, &format!("{field}[{i}][{j}]"))?;
            }
        }
        Ok(DMatrix::from_fn(rows, cols, |i, j| m[i][j]))
    }

    /// A scalar (applied to every channel) or one non-negative value per channel.
    fn per_channel(
        &self,
        v: Option<&toml::Value>,
        n: usize,
        field: &str,
        what: &str,
    ) -> Result<Vec<f64>, ScenarioError> {
        let out = match v {
            None => vec![0.0; n],
            Some(v) => match (number(v), v.as_array()) {
                (Some(x), _) => vec![x; n],
                (None, Some(a)) => {
                    let xs: Option<Vec<f64>> = a.iter().map(number).collect();
                    let xs = xs.ok_or_else(|| {
                        self.err(field, "must be a number or an array of numbers")
                    })?;
                    if xs.len() != n {
                        return Err(self.err(
                            field,
                            format!(
                                "has {} entries, expected {n} (one per {what}) or one scalar",
                                xs.len()
                            ),
                        ));
                    }
                    xs
                }
                (None, None) => {
                    return Err(self.err(field, "must be a number or an array of numbers"));
                }
            },
        };
        for (i, x) in out.iter().enumerate() {
            let f = format!("{field}[{i}]");
            if self.non_negative(*x, &f)? > MAX_NOISE_STD {
                return Err(self.err(f, format!("{x} is above the bound {MAX_NOISE_STD}")));
            }
        }
        Ok(out)
    }
}

fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Integer(i) => Some(*i as f64),
        toml::Value::Float(x) => Some(*x),
        _ => None,
    }
}

/// The `[rig]` table through the schema's reader ([`RigTable`]); the plant needs its
/// duration.
fn validate_rig(cx: &Cx<'_>, raw: RawRig) -> Result<RigParams, ScenarioError> {
    let t = RigTable::parse(raw).map_err(|e| cx.field(e))?;
    Ok(RigParams {
        name: t.name,
        sample_period: t.sample_period,
        duration: cx.required(t.duration, "rig.duration")?,
    })
}

/// The largest `n_x max|[A B]| T` of the continuous model, and `ω T` of a tone or a cutoff:
/// the matrix exponential of the discretization scales the matrix down by `2^s` with
/// `s ≈ log₂` of this and squares back `s` times, so the bound keeps `s` near 330 and every
/// power finite. Realizations of high-order transfer functions have large entries (the
/// acoustic rig's MISO model reaches 1.4e14), so the bound is on the exponent, not on the
/// entries' size.
pub const MAX_NORM_TIMES_PERIOD: f64 = 1e100;

/// Refuses a plant whose dynamics, scaled by the period `ts`, are beyond what the exact
/// discretization can evaluate ([`MAX_NORM_TIMES_PERIOD`]).
fn check_discretizable(cx: &Cx<'_>, p: &PlantParams, ts: f64) -> Result<(), ScenarioError> {
    let m = &p.model;
    let norm = |x: &DMatrix<f64>| x.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let scaled = norm(&m.a).max(norm(&m.b_u)).max(norm(&m.b_w)) * ts * (m.n_x().max(1) as f64);
    let field = format!(
        "plant.{}",
        p.kind
            .name()
            .replace("transfer-function", "tf")
            .replace("state-space", "ss")
    );
    if scaled > MAX_NORM_TIMES_PERIOD {
        return Err(cx.err(
            field,
            format!(
                "the model's entries times the period ({scaled:.3e}) exceed {MAX_NORM_TIMES_PERIOD:e}: \
                 it cannot be discretized at this sample period"
            ),
        ));
    }
    let d = &p.disturbance;
    let mut fast = d
        .tones
        .iter()
        .map(|t| t.omega)
        .chain(d.band_limited.iter().map(|b| b.omega_c));
    if let Some(w) = fast.find(|w| w * ts > MAX_NORM_TIMES_PERIOD) {
        return Err(cx.err(
            "plant.disturbance",
            format!("{w} rad/s times the period exceeds {MAX_NORM_TIMES_PERIOD:e}"),
        ));
    }
    Ok(())
}

/// [`rig_scenario::rig::check_duration`] with the file named.
fn check_duration(cx: &Cx<'_>, d: f64, how: &str) -> Result<f64, ScenarioError> {
    rig_scenario::rig::check_duration(d, how).map_err(|e| cx.field(e))
}

impl Scenario {
    /// The scenario with `rig.duration` replaced by `duration` (the `--duration` option),
    /// checked as the file's value is.
    ///
    /// # Errors
    ///
    /// A duration that is not positive, finite and at most [`MAX_DURATION_S`], naming
    /// `rig.duration`.
    pub fn with_duration(mut self, duration: f64) -> Result<Self, ScenarioError> {
        let cx = Cx {
            origin: &self.origin,
        };
        self.rig.duration = check_duration(&cx, duration, " (--duration)")?;
        Ok(self)
    }

    /// The number of samples of a run: `steps` (the `--steps` option) when given, else
    /// `rig.duration` over the sample period; at most [`MAX_DURATION_S`] of samples.
    ///
    /// # Errors
    ///
    /// `steps = 0`, or more samples than [`MAX_DURATION_S`] holds, naming `rig.duration`.
    pub fn run_steps(&self, steps: Option<u64>) -> Result<u64, ScenarioError> {
        let ts = self.rig.sample_period;
        let Some(n) = steps else {
            return Ok((self.rig.duration / ts).round() as u64);
        };
        let cx = Cx {
            origin: &self.origin,
        };
        check_duration(&cx, n as f64 * ts, &format!(" (--steps {n} × {ts} s)"))?;
        Ok(n)
    }
}

fn validate_plant(cx: &Cx<'_>, raw: RawPlant) -> Result<PlantParams, ScenarioError> {
    let kind = match cx.required(raw.kind, "plant.kind")?.as_str() {
        "transfer-function" => PlantKind::TransferFunction,
        "state-space" => PlantKind::StateSpace,
        "modal" => PlantKind::Modal,
        "truss" => PlantKind::Truss,
        "discrete" => PlantKind::Discrete,
        "mrac-example" => PlantKind::MracExample,
        "sampling-arm" => PlantKind::SamplingArm,
        other => {
            return Err(cx.err(
                "plant.kind",
                format!(
                    "'{other}' is not one of \"transfer-function\", \"state-space\", \"modal\", \"truss\", \"discrete\", \"mrac-example\", \"sampling-arm\""
                ),
            ));
        }
    };
    // A discrete plant has one u, no w, one y and z = y; the sampling arm has its wire
    // contract (2, 0, 7, 1): the counts may be omitted.
    let fixed = |v: Option<usize>, field: &str, n: usize| match v {
        Some(v) if v != n => Err(cx.err(
            field,
            format!(
                "{v}, but a plant of plant.kind = \"{}\" has {n}: give {n} or omit it",
                kind.name()
            ),
        )),
        _ => Ok(Some(n)),
    };
    let (inputs, disturbances, outputs_y, outputs_z) = if kind.is_discrete() {
        (
            fixed(raw.inputs, "plant.inputs", 1)?,
            fixed(raw.disturbances, "plant.disturbances", 0)?,
            fixed(raw.outputs_y, "plant.outputs-y", 1)?,
            fixed(raw.outputs_z, "plant.outputs-z", 1)?,
        )
    } else if kind == PlantKind::SamplingArm {
        (
            fixed(raw.inputs, "plant.inputs", crate::arm::N_U)?,
            fixed(raw.disturbances, "plant.disturbances", 0)?,
            fixed(raw.outputs_y, "plant.outputs-y", crate::arm::N_Y)?,
            fixed(raw.outputs_z, "plant.outputs-z", crate::arm::N_Z)?,
        )
    } else {
        (raw.inputs, raw.disturbances, raw.outputs_y, raw.outputs_z)
    };
    let count =
        |v: Option<usize>, field: &str, max: Option<usize>| -> Result<usize, ScenarioError> {
            let n = cx.required(v, field)?;
            match max {
                Some(max) if n > max => Err(cx.err(field, format!("{n} channels, at most {max}"))),
                _ => Ok(n),
            }
        };
    let dims = ChannelDims {
        n_u: count(inputs, "plant.inputs", Some(ipc_types::MAX_U))?,
        n_w: count(disturbances, "plant.disturbances", Some(MAX_DISTURBANCES))?,
        n_y: count(outputs_y, "plant.outputs-y", Some(ipc_types::MAX_Y))?,
        n_z: count(outputs_z, "plant.outputs-z", Some(ipc_types::MAX_Z))?,
    };
    let command = if kind == PlantKind::SamplingArm {
        fixed(raw.commands, "plant.commands", crate::arm::N_R)?;
        if raw.command.is_some() {
            return Err(cx.err(
                "plant.command",
                "the sampling arm's command r = F_d comes from its guidance \
                 ([plant.guidance] force-set-point): remove plant.command",
            ));
        }
        Command::Constant(vec![0.0; crate::arm::N_R])
    } else {
        let n_r = count(
            raw.commands.or(Some(0)),
            "plant.commands",
            Some(ipc_types::MAX_R),
        )?;
        discrete_tables::command(cx, raw.command, raw.commands.map(|_| n_r))?
    };

    let arm_tables = arm_tables::RawArmTables {
        sampling_arm: raw.sampling_arm,
        surface: raw.surface,
        guidance: raw.guidance,
        second_sampling: raw.second_sampling,
        integrator: raw.integrator,
    };
    let mut given = vec![
        ("tf", raw.tf.is_some()),
        ("ss", raw.ss.is_some()),
        ("modal", raw.modal.is_some()),
        ("truss", raw.truss.is_some()),
        ("discrete", raw.discrete.is_some()),
        ("mrac-example", raw.mrac_example.is_some()),
    ];
    given.extend(arm_tables.present());
    let wanted: &[&str] = match kind {
        PlantKind::TransferFunction => &["tf"],
        PlantKind::StateSpace => &["ss"],
        PlantKind::Modal => &["modal"],
        PlantKind::Truss => &["truss"],
        PlantKind::Discrete => &["discrete"],
        PlantKind::MracExample => &["mrac-example"],
        PlantKind::SamplingArm => &arm_tables::TABLES,
    };
    for (table, present) in given {
        if present && !wanted.contains(&table) {
            return Err(cx.err(
                format!("plant.{table}"),
                format!(
                    "given, but plant.kind = \"{}\" reads {}",
                    kind.name(),
                    wanted
                        .iter()
                        .map(|w| format!("[plant.{w}]"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
    }
    if kind == PlantKind::SamplingArm {
        if raw.disturbance.is_some() {
            return Err(cx.err(
                "plant.disturbance",
                "the sampling arm has no disturbance input w",
            ));
        }
        if raw.initial_state.is_some() {
            return Err(cx.err(
                "plant.initial-state",
                "the sampling arm starts as [plant.sampling-arm] says (theta1, theta2, \
                 initial-height, descent-speed)",
            ));
        }
    }
    if kind.is_discrete() {
        if raw.disturbance.is_some() {
            return Err(cx.err(
                "plant.disturbance",
                "a discrete plant has no disturbance input w: give its input disturbance in \
                 [plant.input-disturbance]",
            ));
        }
        if raw.initial_state.is_some() {
            return Err(cx.err(
                "plant.initial-state",
                "a discrete plant starts at rest (every u_k and y_k with k < 0 is zero)",
            ));
        }
    } else if raw.input_disturbance.is_some() {
        return Err(cx.err(
            "plant.input-disturbance",
            format!(
                "is for the discrete kinds; plant.kind = \"{}\" takes its disturbances in \
                 [plant.disturbance]",
                kind.name()
            ),
        ));
    }
    let mut discrete = None;
    if kind.is_discrete() {
        let (tf, example) = match kind {
            PlantKind::MracExample => {
                let t = cx.required(raw.mrac_example, "plant.mrac-example")?;
                let (tf, ex) = discrete_tables::mrac_example(cx, t)?;
                (tf, Some(ex))
            }
            _ => {
                let t = cx.required(raw.discrete, "plant.discrete")?;
                (discrete_tables::discrete_tf(cx, t)?, None)
            }
        };
        let input_disturbance = match raw.input_disturbance {
            Some(d) => discrete_tables::input_disturbance(cx, d)?,
            None => Vec::new(),
        };
        discrete = Some(DiscretePlant {
            tf,
            input_disturbance,
            example,
        });
    }
    let arm = if kind == PlantKind::SamplingArm {
        Some(arm_tables::arm_params(cx, arm_tables)?)
    } else {
        None
    };
    let mut truss_y_std = None;
    let model = match kind {
        PlantKind::Discrete | PlantKind::MracExample | PlantKind::SamplingArm => {
            GeneralizedPlant::zeros(0, dims)
        }
        PlantKind::TransferFunction => {
            let tf = cx.required(raw.tf, "plant.tf")?;
            tf_model(cx, tf, dims)?
        }
        PlantKind::StateSpace => {
            let ss = cx.required(raw.ss, "plant.ss")?;
            ss_model(cx, ss, dims)?
        }
        PlantKind::Modal => {
            let modal = cx.required(raw.modal, "plant.modal")?;
            modal_model(cx, modal, dims)?
        }
        PlantKind::Truss => {
            let t = cx.required(raw.truss.as_ref(), "plant.truss")?;
            let tp = crate::truss::from_toml(t, dims).map_err(|e| cx.err(e.field, e.problem))?;
            truss_y_std = tp.y_noise_std;
            tp.model
        }
    };
    let n_x = match (&discrete, &arm) {
        (Some(d), _) => d.tf.n_states(),
        (None, Some(_)) => crate::arm::N_STATES,
        (None, None) => model.n_x(),
    };
    if n_x > MAX_STATES {
        return Err(cx.err(
            format!("plant.{}", wanted[0]),
            format!("the plant has {n_x} states, at most {MAX_STATES}"),
        ));
    }
    let matrices = [
        &model.a,
        &model.b_u,
        &model.b_w,
        &model.c_y,
        &model.c_z,
        &model.d_yu,
        &model.d_yw,
        &model.d_zu,
        &model.d_zw,
    ];
    if matrices.iter().any(|m| m.iter().any(|x| !x.is_finite())) {
        return Err(cx.err(
            format!("plant.{}", wanted[0]),
            "the continuous model has entries beyond the range of f64 (a value too large)",
        ));
    }

    let input_delays = raw.input_delays.unwrap_or_else(|| vec![0; dims.n_u]);
    if input_delays.len() != dims.n_u {
        return Err(cx.err(
            "plant.input-delays",
            format!(
                "has {} entries, expected {} (one per input)",
                input_delays.len(),
                dims.n_u
            ),
        ));
    }
    if let Some(i) = input_delays.iter().position(|&d| d > MAX_INPUT_DELAY) {
        return Err(cx.err(
            format!("plant.input-delays[{i}]"),
            format!(
                "{} samples exceeds the limit of {MAX_INPUT_DELAY}",
                input_delays[i]
            ),
        ));
    }
    let initial_state = raw.initial_state.unwrap_or_else(|| vec![0.0; model.n_x()]);
    let what = match kind {
        PlantKind::TransferFunction => "state of the column-wise realization",
        PlantKind::StateSpace => "state",
        PlantKind::Modal => "state [q, q̇] of each mode",
        PlantKind::Truss => "state [η, η̇] of each mode of the truss",
        PlantKind::Discrete | PlantKind::MracExample | PlantKind::SamplingArm => "state",
    };
    cx.vector(&initial_state, model.n_x(), "plant.initial-state", what)?;

    let disturbance = match raw.disturbance {
        None => DisturbanceParams {
            tones: Vec::new(),
            white_std: vec![0.0; dims.n_w],
            band_limited: Vec::new(),
        },
        Some(d) => disturbance(cx, d, dims.n_w)?,
    };
    let mut noise = match raw.noise {
        None => NoiseParams {
            y_std: vec![0.0; dims.n_y],
            z_std: vec![0.0; dims.n_z],
            seed: 0,
        },
        Some(n) => NoiseParams {
            y_std: cx.per_channel(n.y_std.as_ref(), dims.n_y, "plant.noise.y-std", "output y")?,
            z_std: cx.per_channel(n.z_std.as_ref(), dims.n_z, "plant.noise.z-std", "output z")?,
            seed: n.seed.unwrap_or(0),
        },
    };
    if let Some(sigma) = truss_y_std {
        if noise.y_std.iter().any(|&s| s != 0.0) {
            return Err(cx.err(
                "plant.noise.y-std",
                "given, but [plant.truss.noise-snr] sets the noise on y; give one of the two",
            ));
        }
        noise.y_std = vec![sigma; dims.n_y];
    }
    Ok(PlantParams {
        kind,
        model,
        discrete,
        arm,
        input_delays,
        initial_state,
        command,
        disturbance,
        noise,
    })
}

/// One `[plant.tf]` block: an array of rows of entries (`0` or `{ num, den }`).
fn tf_block(
    cx: &Cx<'_>,
    v: Option<&toml::Value>,
    rows: usize,
    cols: usize,
    field: &str,
) -> Result<Vec<Vec<Option<Tf>>>, ScenarioError> {
    let Some(v) = v else { return Ok(Vec::new()) };
    let shape = format!(
        "an array of rows ({rows} × {cols}) whose entries are 0 or {{ num = [..], den = [..] }}"
    );
    let arr = v
        .as_array()
        .ok_or_else(|| cx.err(field, format!("must be {shape}")))?;
    if arr.len() > rows {
        return Err(cx.err(
            field,
            format!("has {} rows, expected at most {rows}", arr.len()),
        ));
    }
    let mut out = Vec::with_capacity(arr.len());
    for (i, row) in arr.iter().enumerate() {
        let rf = format!("{field}[{i}]");
        let row = match row {
            toml::Value::Array(r) => r,
            other if number(other) == Some(0.0) => {
                out.push(vec![None; cols]);
                continue;
            }
            _ => return Err(cx.err(rf, format!("must be an array of {cols} entries"))),
        };
        if row.is_empty() {
            out.push(vec![None; cols]);
            continue;
        }
        if row.len() != cols {
            return Err(cx.err(rf, format!("has {} entries, expected {cols}", row.len())));
        }
        let mut r = Vec::with_capacity(cols);
        for (j, e) in row.iter().enumerate() {
            let ef = format!("{field}[{i}][{j}]");
            r.push(tf_entry(cx, e, &ef)?);
        }
        out.push(r);
    }
    Ok(out)
}

fn tf_entry(cx: &Cx<'_>, e: &toml::Value, field: &str) -> Result<Option<Tf>, ScenarioError> {
    if let Some(x) = number(e) {
        return if x == 0.0 {
            Ok(None)
        } else {
            Err(cx.err(
                field,
                format!("{x}: an entry is 0 or {{ num = [..], den = [..] }}"),
            ))
        };
    }
    let t = e
        .as_table()
        .ok_or_else(|| cx.err(field, "an entry is 0 or { num = [..], den = [..] }"))?;
    if let Some(k) = t.keys().find(|k| *k != "num" && *k != "den") {
        return Err(cx.err(format!("{field}.{k}"), "unknown key (expected num and den)"));
    }
    let coeffs = |key: &str| -> Result<Vec<f64>, ScenarioError> {
        let f = format!("{field}.{key}");
        let v = t.get(key).ok_or_else(|| cx.err(&f, "is missing"))?;
        let a = v
            .as_array()
            .ok_or_else(|| cx.err(&f, "must be an array of numbers"))?;
        let xs: Option<Vec<f64>> = a.iter().map(number).collect();
        let xs = xs.ok_or_else(|| cx.err(&f, "must be an array of numbers"))?;
        if xs.len() > MAX_STATES + 1 {
            return Err(cx.err(
                &f,
                format!(
                    "has {} coefficients, at most {} (the plant has at most {MAX_STATES} states)",
                    xs.len(),
                    MAX_STATES + 1
                ),
            ));
        }
        for (i, x) in xs.iter().enumerate() {
            cx.finite(*x, &format!("{f}[{i}]"))?;
        }
        Ok(xs)
    };
    let (num, den) = (coeffs("num")?, coeffs("den")?);
    match Tf::new(num, den) {
        Ok(g) => Ok(Some(g).filter(|g| !g.is_zero())),
        Err(e @ (LtiError::EmptyDenominator | LtiError::ZeroLeadingDenominator)) => {
            Err(cx.err(format!("{field}.den"), e.to_string()))
        }
        Err(e) => Err(cx.err(field, e.to_string())),
    }
}

fn tf_model(cx: &Cx<'_>, tf: RawTf, d: ChannelDims) -> Result<GeneralizedPlant, ScenarioError> {
    let yu = tf_block(cx, tf.yu.as_ref(), d.n_y, d.n_u, "plant.tf.yu")?;
    let yw = tf_block(cx, tf.yw.as_ref(), d.n_y, d.n_w, "plant.tf.yw")?;
    let zu = tf_block(cx, tf.zu.as_ref(), d.n_z, d.n_u, "plant.tf.zu")?;
    let zw = tf_block(cx, tf.zw.as_ref(), d.n_z, d.n_w, "plant.tf.zw")?;
    GeneralizedPlant::from_tf_blocks(&yu, &yw, &zu, &zw, d)
        .map_err(|e| cx.err("plant.tf", e.to_string()))
}

fn ss_model(cx: &Cx<'_>, ss: RawSs, d: ChannelDims) -> Result<GeneralizedPlant, ScenarioError> {
    let a_rows = cx.required(ss.a, "plant.ss.a")?;
    let n = a_rows.len();
    let a = cx.matrix(&a_rows, n, n, "plant.ss.a")?;
    // A matrix may be absent when it has no entry (zero inputs or outputs); `D`s are zero
    // when absent.
    let needed =
        |m: Option<Rows>, r: usize, c: usize, f: &str| -> Result<DMatrix<f64>, ScenarioError> {
            match m {
                Some(m) => cx.matrix(&m, r, c, f),
                None if r == 0 || c == 0 => Ok(DMatrix::zeros(r, c)),
                None => Err(cx.err(f, format!("is missing ({r} × {c})"))),
            }
        };
    let optional =
        |m: Option<Rows>, r: usize, c: usize, f: &str| -> Result<DMatrix<f64>, ScenarioError> {
            match m {
                Some(m) => cx.matrix(&m, r, c, f),
                None => Ok(DMatrix::zeros(r, c)),
            }
        };
    let p = GeneralizedPlant {
        a,
        b_u: needed(ss.b_u, n, d.n_u, "plant.ss.b-u")?,
        b_w: needed(ss.b_w, n, d.n_w, "plant.ss.b-w")?,
        c_y: needed(ss.c_y, d.n_y, n, "plant.ss.c-y")?,
        c_z: needed(ss.c_z, d.n_z, n, "plant.ss.c-z")?,
        d_yu: optional(ss.d_yu, d.n_y, d.n_u, "plant.ss.d-yu")?,
        d_yw: optional(ss.d_yw, d.n_y, d.n_w, "plant.ss.d-yw")?,
        d_zu: optional(ss.d_zu, d.n_z, d.n_u, "plant.ss.d-zu")?,
        d_zw: optional(ss.d_zw, d.n_z, d.n_w, "plant.ss.d-zw")?,
    };
    p.validate()
        .map_err(|e| cx.err("plant.ss", e.to_string()))?;
    Ok(p)
}

fn modal_model(
    cx: &Cx<'_>,
    m: RawModal,
    d: ChannelDims,
) -> Result<GeneralizedPlant, ScenarioError> {
    let raw_modes = cx.required(m.modes, "plant.modal.modes")?;
    cx.count(
        raw_modes.len(),
        1,
        MAX_STATES / 2,
        "plant.modal.modes",
        "modes",
    )?;
    let mut modes = Vec::with_capacity(raw_modes.len());
    for (r, rm) in raw_modes.into_iter().enumerate() {
        let f = |k: &str| format!("plant.modal.modes[{r}].{k}");
        let omega = cx.frequency(rm.frequency_hz, rm.frequency_rad_s, &f, false)?;
        let zeta = cx.non_negative(cx.required(rm.damping, &f("damping"))?, &f("damping"))?;
        let vector = |v: Option<Vec<f64>>,
                      n: usize,
                      key: &str,
                      what: &str|
         -> Result<Vec<f64>, ScenarioError> {
            let v = v.unwrap_or_else(|| vec![0.0; n]);
            cx.vector(&v, n, &f(key), what)?;
            Ok(v)
        };
        modes.push(Mode {
            omega,
            zeta,
            b_u: vector(rm.b_u, d.n_u, "b-u", "input u")?,
            b_w: vector(rm.b_w, d.n_w, "b-w", "disturbance input w")?,
            c_y: vector(rm.c_y, d.n_y, "c-y", "output y")?,
            c_y_vel: vector(rm.c_y_vel, d.n_y, "c-y-vel", "output y")?,
            c_z: vector(rm.c_z, d.n_z, "c-z", "output z")?,
            c_z_vel: vector(rm.c_z_vel, d.n_z, "c-z-vel", "output z")?,
        });
    }
    GeneralizedPlant::from_modes(&modes, d).map_err(|e| cx.err("plant.modal.modes", e.to_string()))
}

fn disturbance(
    cx: &Cx<'_>,
    d: RawDisturbance,
    n_w: usize,
) -> Result<DisturbanceParams, ScenarioError> {
    let raw_tones = d.tones.unwrap_or_default();
    cx.count(
        raw_tones.len(),
        0,
        MAX_TONES,
        "plant.disturbance.tones",
        "tones",
    )?;
    let mut tones = Vec::new();
    for (i, t) in raw_tones.into_iter().enumerate() {
        let f = |k: &str| format!("plant.disturbance.tones[{i}].{k}");
        let input = cx.required(t.input, &f("input"))?;
        if input >= n_w {
            return Err(cx.err(
                f("input"),
                format!("{input} is not a disturbance input (plant.disturbances = {n_w})"),
            ));
        }
        let omega = cx.frequency(t.frequency_hz, t.frequency_rad_s, &f, true)?;
        let amplitude = cx.finite(cx.required(t.amplitude, &f("amplitude"))?, &f("amplitude"))?;
        let phase = cx
            .finite(t.phase_deg.unwrap_or(0.0), &f("phase-deg"))?
            .to_radians();
        tones.push(Tone {
            input,
            amplitude,
            omega,
            phase,
        });
    }
    let white_std = cx.per_channel(
        d.white_std.as_ref(),
        n_w,
        "plant.disturbance.white-std",
        "disturbance input",
    )?;
    let raw_band = d.band_limited.unwrap_or_default();
    let field = "plant.disturbance.band-limited";
    cx.count(raw_band.len(), 0, MAX_BAND_LIMITED, field, "entries")?;
    let mut band_limited = Vec::new();
    for (i, b) in raw_band.into_iter().enumerate() {
        let f = |k: &str| format!("plant.disturbance.band-limited[{i}].{k}");
        let input = cx.required(b.input, &f("input"))?;
        if input >= n_w {
            return Err(cx.err(
                f("input"),
                format!("{input} is not a disturbance input (plant.disturbances = {n_w})"),
            ));
        }
        let rms = cx.non_negative(cx.required(b.rms, &f("rms"))?, &f("rms"))?;
        let omega_c = match (b.cutoff_hz, b.cutoff_rad_s) {
            (Some(hz), None) => cx.at_most_max_frequency(
                2.0 * PI * cx.positive(hz, &f("cutoff-hz"))?,
                &f("cutoff-hz"),
            )?,
            (None, Some(w)) => {
                cx.at_most_max_frequency(cx.positive(w, &f("cutoff-rad-s"))?, &f("cutoff-rad-s"))?
            }
            (Some(_), Some(_)) => {
                return Err(cx.err(f("cutoff-hz"), "give cutoff-hz or cutoff-rad-s, not both"));
            }
            (None, None) => {
                return Err(cx.err(f("cutoff-hz"), "is missing (or give cutoff-rad-s)"));
            }
        };
        let order = cx.required(b.order, &f("order"))?;
        if !(1..=MAX_BAND_LIMITED_ORDER).contains(&order) {
            return Err(cx.err(
                f("order"),
                format!("{order} is not between 1 and {MAX_BAND_LIMITED_ORDER}"),
            ));
        }
        band_limited.push(BandLimited {
            input,
            rms,
            omega_c,
            order,
        });
    }
    Ok(DisturbanceParams {
        tones,
        white_std,
        band_limited,
    })
}

mod arm_tables;
mod discrete_tables;

#[cfg(test)]
mod tests;
