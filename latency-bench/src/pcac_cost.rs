//! Cost of one PCAC step, beside clarabel on the same quadratic programs.
//!
//! ## Workloads
//!
//! Two sizes of [`control::pcac::Pcac`] ([`Workload`]), both with the
//! dissertation's next-step timing ([`PcacTiming::NextStep`]), F-test forgetting
//! (τ_n = 40, τ_d = 200, η = 0.1, α = 0.001), `θ_0 = 10⁻¹⁰ 1` and the shared-covariance
//! identification kernel:
//!
//! | workload | `n̂` | `p` | `m` | `θ` | `ℓ` | `C_t` | `Q`, `R` | bounds | plant |
//! | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |
//! | [`Workload::Truss`] (chapter 6) | 25 | 4 | 2 | 600 | 40 | `[0 0 0 1]` | `10⁶`, `1` | `\|u\| ≤ 10` | the truss of `scenarios/truss/broadband-25hz.toml` at 50 Hz |
//! | [`Workload::Arm`] (chapter 7) | 1 | 5 | 2 | 35 | 50 | `[0₃ₓ₂ I₃]` | `diag(1000, 100, 1)`, `1` | `\|u\| ≤ 100`, `\|Δu\| ≤ 5` | [`ArmPlant`], synthetic |
//!
//! The truss is driven by `plant_proxy::sim::PlantSim` on the scenario's plant (its 25 Hz
//! band-limited disturbance of 1 N RMS at node 1, 40 dB sensor noise), so that the active
//! sets are those of a real closed loop: with the truss's outputs in millimetres and the
//! §6.2 weights, the planned input often sits on its ±10 N bound once the model is
//! identified (the bench reports the share of such steps and the distribution of the
//! active-set size). The sampling-arm plant of chapter 7 does not exist yet; [`ArmPlant`]
//! stands in for it at the controller's size (its design is on the type).
//!
//! ## Method
//!
//! Three copies of the loop run in lockstep, in blocks of [`BLOCK`] samples, on the
//! calling thread (which the bench pins on the RT core under `SCHED_FIFO`):
//!
//! 1. **Timed.** `Pcac::step` between two `CLOCK_MONOTONIC` readings and nothing else: the
//!    plant's sample is taken before the first reading and the input applied after the
//!    second. Its outputs `u_k`, its planned first move `u_{1|k}` and `y_k` are kept for
//!    the block.
//! 2. **Reference.** A second controller and plant, built from the same parameters and
//!    seeds, step through the same samples untimed (the bench checks that they produce
//!    bit-identical inputs, so that they solve the same QPs). After each step
//!    `solve_with_clarabel(&pcac.last_problem(), 1e-8)` — clarabel's set-up and solve,
//!    allocating — is timed, and the first move of both solvers is compared where both
//!    report *solved*. The active-set size and the iteration count of the dense solver are
//!    read here from `Controller::internals` (`qp_active`, `qp_iterations`).
//! 3. **Pieces.** The step taken apart into the public kernels of `service`, fed with the
//!    timed loop's `y_k` and `u_k`, each timed alone: `IoModel::update` (identification),
//!    `HorizonPrediction::compute` (realization: state, Markov parameters, free response),
//!    `Condenser::build` (condensing) and `DenseQpSolver::solve` (warm-started from the
//!    shifted active set, as `Pcac` does). Its first move is compared with the timed
//!    controller's, which checks that the pieces are the step.
//!
//! Running the copies in blocks rather than interleaved per step keeps clarabel's
//! allocations out of the timed controller's cache except at block starts: the first
//! [`REWARM`] timed steps of each block run but are recorded apart ([`PcacCost::cold`]),
//! as in [`crate::rls_cost`]. Timing starts after `warmup` samples (identification from
//! `θ_0` first; the truss needs a few hundred samples before its model means anything).

use crate::hist::new_histogram;
use control::forgetting::ForgettingRule;
use control::mpc::condense::{Condenser, MoveBounds, MpcSpec, Weight};
use control::mpc::qp::{
    ConstraintId, DenseQpSolver, QpProblem, QpSettings, QpStatus, WarmStart, solve_with_clarabel,
};
use control::pcac::{
    HorizonPrediction, IdKernel, IoModel, IoModelParams, Pcac, PcacCounters, PcacParams, PcacTiming,
};
use control::status;
use control::{Controller, MAX_INTERNALS, StepInput};
use hdrhistogram::Histogram;
use ipc_types::ChannelCounts;
use ipc_types::clock::monotonic_ns;
use plant_proxy::sim::PlantSim;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Samples per block of each copy of the loop (see the module docs).
pub const BLOCK: u64 = 256;

/// Timed steps at the start of each block that are run but recorded apart (cold cache).
pub const REWARM: u64 = 2;

/// clarabel's gap and feasibility tolerance in the comparison (its default).
pub const CLARABEL_TOL: f64 = 1e-8;

/// The agreement the issue asks for between the two solvers' first moves.
pub const AGREE_TOL: f64 = 1e-6;

/// clarabel's tolerance when a step disagrees by more than [`AGREE_TOL`] and is re-solved
/// to tell which solver is off.
pub const CLARABEL_TIGHT_TOL: f64 = 1e-11;

/// The truss scenario the truss workload runs (plant tables only are read).
const TRUSS_SCENARIO: &str = include_str!("../../scenarios/truss/broadband-25hz.toml");

/// A PCAC size to time (see the module docs for the full parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Workload {
    /// Chapter 6's truss: `n̂ = 25`, `p = 4`, `m = 2` (600 coefficients), `ℓ = 40`, 50 Hz.
    Truss,
    /// Chapter 7's sampling arm at its size: `n̂ = 1`, `p = 5`, `m = 2`, `ℓ = 50`, input
    /// and move bounds, on [`ArmPlant`].
    Arm,
}

impl Workload {
    /// Both workloads.
    pub const ALL: [Workload; 2] = [Workload::Truss, Workload::Arm];

    /// Short name for file names and ids.
    pub fn slug(self) -> &'static str {
        match self {
            Workload::Truss => "pcac-truss",
            Workload::Arm => "pcac-arm",
        }
    }

    /// The size as the table prints it.
    pub fn label(self) -> &'static str {
        match self {
            Workload::Truss => "pcac truss (n̂ 25, p 4, m 2, ℓ 40)",
            Workload::Arm => "pcac arm (n̂ 1, p 5, m 2, ℓ 50)",
        }
    }

    /// The issue's p99 target for one step, ns: 2 ms for the truss (50 Hz), 500 µs for
    /// the arm (the 2 kHz rate of §7.3).
    pub fn target_ns(self) -> u64 {
        match self {
            Workload::Truss => 2_000_000,
            Workload::Arm => 500_000,
        }
    }

    /// The stretch target for the arm, ns: the 8 kHz period (none for the truss).
    pub fn stretch_ns(self) -> Option<u64> {
        match self {
            Workload::Truss => None,
            Workload::Arm => Some(125_000),
        }
    }

    /// Untimed samples before timing starts by default: 500 (10 s of the truss, 0.25 s of
    /// the arm). The truss loop rides its bound from about sample 200 on; the arm's 35
    /// coefficients converge within the first few hundred samples.
    pub fn default_warmup(self) -> u64 {
        500
    }

    /// The rig's channel counts: `n_y = n_z = p`, no command, `m` inputs.
    pub fn counts(self) -> ChannelCounts {
        let p = self.params();
        ChannelCounts::new(p.model.p, p.model.p, 0, p.model.m).expect("within capacity")
    }

    /// The controller's parameters.
    pub fn params(self) -> PcacParams {
        let rule = ForgettingRule::FTest {
            tau_n: 40,
            tau_d: 200,
            eta: 0.1,
            alpha: 0.001,
        };
        let (n_hat, p, m, p0) = match self {
            Workload::Truss => (25, 4, 2, 1.0),
            Workload::Arm => (1, 5, 2, 10.0),
        };
        let n_theta = n_hat * p * (p + m);
        let model = IoModelParams {
            n_hat,
            p,
            m,
            theta0: vec![1e-10; n_theta],
            p0,
            rule,
            trace_limit: 1e6 * n_theta as f64 * p0,
            kernel: IdKernel::Shared,
        };
        let mpc = match self {
            Workload::Truss => MpcSpec {
                horizon: 40,
                n_inputs: m,
                n_outputs: p,
                n_tracked: 1,
                tracking: vec![0.0, 0.0, 0.0, 1.0],
                q: Weight::Scalar(1e6),
                r: Weight::Scalar(1.0),
                u_min: vec![-10.0; m],
                u_max: vec![10.0; m],
                move_bounds: None,
                output_constraints: None,
            },
            Workload::Arm => {
                // C_t = [0_{3×2} I_3].
                let mut tracking = vec![0.0; 3 * p];
                for i in 0..3 {
                    tracking[i * p + 2 + i] = 1.0;
                }
                MpcSpec {
                    horizon: 50,
                    n_inputs: m,
                    n_outputs: p,
                    n_tracked: 3,
                    tracking,
                    q: Weight::PerChannel(vec![1000.0, 100.0, 1.0]),
                    r: Weight::Scalar(1.0),
                    u_min: vec![-ARM_U_MAX; m],
                    u_max: vec![ARM_U_MAX; m],
                    move_bounds: Some(MoveBounds {
                        min: vec![-ARM_DU_MAX; m],
                        max: vec![ARM_DU_MAX; m],
                    }),
                    output_constraints: None,
                }
            }
        };
        PcacParams {
            model,
            mpc,
            timing: PcacTiming::NextStep,
            qp: QpSettings::default(),
            warm_start: true,
            augmentation: None,
        }
    }
}

/// The arm workload's input bound `|u| ≤ 100` (§7.3's `u_max`).
pub const ARM_U_MAX: f64 = 100.0;

/// The arm workload's move bound `|Δu| ≤ 5` per sample, a slew limit of 10⁴ per second
/// at 2 kHz (not in §7.3; the issue asks for move bounds at this size).
pub const ARM_DU_MAX: f64 = 5.0;

/// The `[controller]` table of [`Workload::Arm`]'s parameters, for a service run (the
/// response-time phase, [`crate::timing_phase`]): the rig must have `n_y = 5`, `n_u = 2`
/// and no command. A unit test checks that `ServiceConfig::parse` reads it into exactly
/// `Workload::Arm.params()`.
pub fn arm_controller_toml() -> String {
    format!(
        "[controller]\nkind = \"pcac\"\nn-hat = 1\np0 = 10.0\ntheta0 = 1e-10\nhorizon = 50\n\
         tracking = [[0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]]\n\
         q = [1000.0, 100.0, 1.0]\nr = 1.0\nu-min = {umin:?}\nu-max = {umax:?}\n\
         du-min = {dumin:?}\ndu-max = {dumax:?}\ntiming = \"next-step\"\n\
         [controller.forgetting]\nrule = \"f-test\"\ntau-n = 40\ntau-d = 200\neta = 0.1\nalpha = 0.001\n",
        umin = -ARM_U_MAX,
        umax = ARM_U_MAX,
        dumin = -ARM_DU_MAX,
        dumax = ARM_DU_MAX,
    )
}

/// A synthetic stand-in for the sampling arm at PCAC's chapter 7 size: 5 outputs, 2
/// inputs, sampled at 2 kHz.
///
/// ```text
/// x_{k+1} = A x_k + B u_k + e w_k,   y_k = x_k + v_k
/// A = S · blkdiag(ρ₁ R(ω₁), ρ₂ R(ω₂), a₅) · S,   S = I − 2 s sᵀ / sᵀs
/// ```
///
/// `R(ω)` is the 2×2 rotation; `ρ₁ = 0.9995`, `ω₁ = 2π · 6 Hz / 2 kHz` and `ρ₂ = 0.998`,
/// `ω₂ = 2π · 45 Hz / 2 kHz` are two lightly damped modes (ζ ≈ 3 % and 1.4 %), `a₅ = 0.99`
/// a slow real pole, and the Householder reflection `S` (`s` fixed) mixes them into every
/// output, so that the plant is coupled and `A` is not normal. With `y = x` the plant is
/// exactly a first-order ARX model in 5 outputs, the `n̂ = 1` model PCAC identifies.
/// The disturbance `w_k` (gain `e`) is a 6 Hz tone of amplitude 12 near the first mode
/// plus white Gaussian noise of σ 6, the measurement noise `v_k` white (σ 0.01); all
/// seeded. Its level is chosen so that, under the arm workload's MPC, the inputs ride
/// their ±100 bound and the moves their ±5 bound part of the time (the unit tests check
/// that both bounds are reached; the bench reports how often).
#[derive(Debug, Clone)]
pub struct ArmPlant {
    a: [[f64; ARM_P]; ARM_P],
    b: [[f64; ARM_M]; ARM_P],
    e: [f64; ARM_P],
    x: [f64; ARM_P],
    next: [f64; ARM_P],
    v: [f64; ARM_P],
    w: f64,
    k: u64,
    rng: ChaCha8Rng,
}

/// Outputs of [`ArmPlant`].
pub const ARM_P: usize = 5;
/// Inputs of [`ArmPlant`].
pub const ARM_M: usize = 2;

/// Amplitude of the arm disturbance's tone.
const ARM_TONE: f64 = 12.0;
/// Standard deviation of the arm disturbance's white part.
const ARM_WHITE: f64 = 6.0;
/// Standard deviation of the arm's measurement noise.
const ARM_NOISE: f64 = 0.01;

/// A standard normal draw (Box–Muller, one of the pair).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let (a, b): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
    (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
}

impl ArmPlant {
    /// The plant at rest, its noise drawn from `seed`.
    pub fn new(seed: u64) -> Self {
        let fs = 2_000.0;
        let modes = [(0.9995, 6.0), (0.998, 45.0)];
        let mut d = [[0.0; ARM_P]; ARM_P];
        for (i, (rho, hz)) in modes.iter().enumerate() {
            let w: f64 = 2.0 * std::f64::consts::PI * hz / fs;
            let (c, s) = (rho * w.cos(), rho * w.sin());
            d[2 * i][2 * i] = c;
            d[2 * i][2 * i + 1] = -s;
            d[2 * i + 1][2 * i] = s;
            d[2 * i + 1][2 * i + 1] = c;
        }
        d[4][4] = 0.99;
        let s = [1.0, -0.5, 0.3, 0.8, -0.2];
        let ss: f64 = s.iter().map(|v| v * v).sum();
        let mut h = [[0.0; ARM_P]; ARM_P];
        for i in 0..ARM_P {
            for j in 0..ARM_P {
                h[i][j] = f64::from(u8::from(i == j)) - 2.0 * s[i] * s[j] / ss;
            }
        }
        let mut hd = [[0.0; ARM_P]; ARM_P];
        let mut a = [[0.0; ARM_P]; ARM_P];
        for i in 0..ARM_P {
            for j in 0..ARM_P {
                hd[i][j] = (0..ARM_P).map(|l| h[i][l] * d[l][j]).sum();
            }
        }
        for i in 0..ARM_P {
            for j in 0..ARM_P {
                a[i][j] = (0..ARM_P).map(|l| hd[i][l] * h[l][j]).sum();
            }
        }
        let b = [
            [2.0e-3, 0.5e-3],
            [-1.0e-3, 1.5e-3],
            [1.5e-3, -1.0e-3],
            [0.5e-3, 2.0e-3],
            [1.0e-3, 1.0e-3],
        ];
        let e = [0.02, 0.01, -0.015, 0.01, 0.012];
        let mut p = Self {
            a,
            b,
            e,
            x: [0.0; ARM_P],
            next: [0.0; ARM_P],
            v: [0.0; ARM_P],
            w: 0.0,
            k: 0,
            rng: ChaCha8Rng::seed_from_u64(seed),
        };
        p.draw();
        p
    }

    /// Draws this sample's measurement noise and disturbance.
    fn draw(&mut self) {
        for i in 0..ARM_P {
            self.v[i] = ARM_NOISE * gauss(&mut self.rng);
        }
        let w1 = 2.0 * std::f64::consts::PI * 6.0 / 2_000.0;
        self.w = ARM_TONE * (w1 * self.k as f64).sin() + ARM_WHITE * gauss(&mut self.rng);
    }

    /// `y_k` (5 values).
    pub fn sample(&self, y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate().take(ARM_P) {
            *yi = self.x[i] + self.v[i];
        }
    }

    /// Applies `u_k` (2 values) and steps to `k + 1`.
    pub fn advance(&mut self, u: &[f64]) {
        for i in 0..ARM_P {
            let mut v = self.e[i] * self.w;
            for j in 0..ARM_P {
                v += self.a[i][j] * self.x[j];
            }
            for j in 0..ARM_M {
                v += self.b[i][j] * u.get(j).copied().unwrap_or(0.0);
            }
            self.next[i] = v;
        }
        self.x = self.next;
        self.k += 1;
        self.draw();
    }
}

/// The plant of a workload.
enum Driver {
    Truss(Box<PlantSim>),
    Arm(Box<ArmPlant>),
}

impl Driver {
    fn new(w: Workload) -> Result<Self, String> {
        match w {
            Workload::Truss => {
                let sc = plant_proxy::scenario::parse(TRUSS_SCENARIO, "broadband-25hz.toml")
                    .map_err(|e| e.to_string())?;
                let sim = PlantSim::new(&sc.plant, sc.rig.sample_period)
                    .map_err(|e| format!("truss plant: {e}"))?;
                Ok(Driver::Truss(Box::new(sim)))
            }
            Workload::Arm => Ok(Driver::Arm(Box::new(ArmPlant::new(7)))),
        }
    }

    /// `y_k` into `y`; `z` and `r` are scratch of the plant's sizes.
    fn sample(&self, y: &mut [f64], z: &mut [f64]) -> Result<(), String> {
        match self {
            Driver::Truss(s) => s.sample(y, z, &mut []).map_err(|e| e.to_string()),
            Driver::Arm(a) => {
                a.sample(y);
                Ok(())
            }
        }
    }

    /// Samples `y_k` into `y` (`z` as in [`Self::sample`]) and returns the controller's
    /// input of sample `seq` (no command).
    fn sampled_input<'a>(
        &self,
        seq: u64,
        y: &'a mut [f64],
        z: &'a mut [f64],
    ) -> Result<StepInput<'a>, String> {
        self.sample(y, z)?;
        Ok(StepInput {
            seq,
            y,
            z,
            r: &[],
            ..Default::default()
        })
    }

    fn advance(&mut self, u: &[f64]) -> Result<(), String> {
        match self {
            Driver::Truss(s) => s.advance(u).map_err(|e| e.to_string()),
            Driver::Arm(a) => {
                a.advance(u);
                Ok(())
            }
        }
    }
}

/// The PCAC step taken apart into its kernels (copy 3 of the module docs).
struct Pieces {
    model: IoModel,
    pred: HorizonPrediction,
    cond: Condenser,
    solver: DenseQpSolver,
    active: Vec<ConstraintId>,
    shifted: Vec<ConstraintId>,
    n_shifted: usize,
    reference: Vec<f64>,
    u_prev: Vec<f64>,
}

impl Pieces {
    fn new(params: &PcacParams) -> Result<Self, String> {
        let model = IoModel::new(&params.model)?;
        let pred = HorizonPrediction::new(&model, params.mpc.horizon)?;
        let cond = Condenser::new(&params.mpc).map_err(|e| e.to_string())?;
        let solver = DenseQpSolver::new(cond.n(), cond.n_ineq(), params.qp);
        let ids = cond.n() + cond.n_ineq();
        Ok(Self {
            reference: vec![0.0; params.mpc.horizon * params.mpc.n_tracked],
            u_prev: vec![0.0; params.model.m],
            active: vec![ConstraintId::Row(0); ids],
            shifted: vec![ConstraintId::Row(0); ids],
            n_shifted: 0,
            model,
            pred,
            cond,
            solver,
        })
    }

    /// One next-step-timing step with `y_k` and the applied `u_k`; records the four
    /// durations (ns) into `t` and returns the QP's status (`None`: not built).
    fn step(&mut self, y: &[f64], u_k: &[f64], t: &mut [u64; 4]) -> Option<QpStatus> {
        let t0 = monotonic_ns();
        let _ = self.model.update(y, &self.u_prev);
        let t1 = monotonic_ns();
        let predicted = self.pred.compute(&self.model, u_k);
        let t2 = monotonic_ns();
        self.u_prev.copy_from_slice(u_k);
        if predicted.is_err() {
            self.n_shifted = 0;
            return None;
        }
        let warm = if self.n_shifted > 0 {
            WarmStart::ActiveSet(&self.shifted[..self.n_shifted])
        } else {
            WarmStart::Cold
        };
        let Ok(problem) = self.cond.build(
            self.pred.markov(),
            self.pred.free_response(),
            u_k,
            &self.reference,
        ) else {
            self.n_shifted = 0;
            return None;
        };
        let t3 = monotonic_ns();
        let status = self.solver.solve(&problem, warm);
        let t4 = monotonic_ns();
        *t = [t1 - t0, t2 - t1, t3 - t2, t4 - t3];
        if status == QpStatus::Solved {
            let na = self.solver.active_set_into(&mut self.active);
            self.n_shifted = self
                .cond
                .shift_active_set(&self.active[..na], &mut self.shifted);
        } else {
            self.n_shifted = 0;
        }
        Some(status)
    }

    fn first_move(&self) -> &[f64] {
        self.cond.first_move(self.solver.x())
    }
}

/// Names of the four pieces, in the order of [`PcacCost::pieces`].
pub const PIECES: [&str; 4] = [
    "identification (IoModel::update)",
    "realization + prediction (HorizonPrediction::compute)",
    "condensing (Condenser::build)",
    "QP solve, warm (DenseQpSolver::solve)",
];

/// The result of [`measure`].
pub struct PcacCost {
    /// The workload.
    pub workload: Workload,
    /// `Pcac::step`, ns (warm: the first [`REWARM`] steps of each block excluded).
    pub step: Histogram<u64>,
    /// The timed steps at block starts, after the other copies ran, ns.
    pub cold: Histogram<u64>,
    /// The steps of [`Self::step`] split by their QP's solution: no active constraint
    /// (`[0]`) and at least one (`[1]`), ns.
    pub step_by_active: [Histogram<u64>; 2],
    /// `solve_with_clarabel` on the same QPs (set-up and solve), ns.
    pub clarabel: Histogram<u64>,
    /// The step's kernels timed alone, ns, in the order of [`PIECES`].
    pub pieces: [Histogram<u64>; 4],
    /// Active constraints of the dense solver's solution per timed step (`qp_active`).
    pub active: Histogram<u64>,
    /// The dense solver's iterations (active-set changes) per timed step.
    pub iterations: Histogram<u64>,
    /// Steps where both solvers reported solved and the first moves were compared.
    pub compared: u64,
    /// Steps where the dense solver solved and clarabel did not report `Solved`.
    pub clarabel_unsolved: u64,
    /// Largest `max_j |u_{1|k,j} − u^clarabel_{1|k,j}|` over the compared steps.
    pub max_first_move_diff: f64,
    /// Compared steps whose first moves differ by more than [`AGREE_TOL`].
    pub over_tol: u64,
    /// At those steps, the largest first-move difference against clarabel re-solved
    /// (untimed) with the tighter tolerance [`CLARABEL_TIGHT_TOL`], where that re-solve
    /// reports `Solved`.
    pub tight_diff: f64,
    /// Re-solves at [`CLARABEL_TIGHT_TOL`] that did not report `Solved`.
    pub tight_unsolved: u64,
    /// `max_j |u_{1|k,j} − u^clarabel_{1|k,j}|` of every compared step.
    pub first_move_diffs: Vec<f64>,
    /// At those steps, the smallest `ρ = (J(U_cl) − J(U)) / (½ eᵀHe)`, `e = U_cl − U`, of
    /// the objective `J = ½ UᵀHU + fᵀU` at the dense solver's `U` and clarabel's `U_cl`
    /// (`+∞` when no step disagreed). For feasible points of this strictly convex QP,
    /// `ρ ≥ 1` when `U` is the minimizer and `ρ ≤ −1` when `U_cl` is; evaluated as
    /// `1 + eᵀ(HU + f) / (½ eᵀHe)`, so without the cancellation of two large objectives.
    pub optimality_ratio: f64,
    /// At those steps, the largest constraint violation of clarabel's point.
    pub clarabel_violation: f64,
    /// Largest difference between the pieces' first move and the timed controller's.
    pub pieces_diff: f64,
    /// Steps at which the reference copy's input differed from the timed copy's (must be 0).
    pub replica_mismatches: u64,
    /// Timed steps whose planned input is at an input bound (status `SATURATED`).
    pub saturated: u64,
    /// Timed steps whose applied move `|u_k − u_{k−1}|` reached a move bound.
    pub at_move_bound: u64,
    /// Timed steps with status `FALLBACK`.
    pub fallback_steps: u64,
    /// The timed controller's counters at the end (whole run, warm-up included).
    pub counters: PcacCounters,
    /// Largest `|u|` applied during the timed steps.
    pub max_abs_u: f64,
}

/// Per-block storage of the timed copy, read by the other two.
struct BlockLog {
    /// The step's duration, ns (`None`: not recorded in [`PcacCost::step`]).
    dt: Vec<Option<u64>>,
    y: Vec<f64>,
    u: Vec<f64>,
    first: Vec<f64>,
}

/// `ρ` of [`PcacCost::optimality_ratio`] for the dense solver's `x` and clarabel's `x_cl`.
fn optimality_ratio(p: &QpProblem, x: &[f64], x_cl: &[f64]) -> f64 {
    let n = p.f.len();
    let e: Vec<f64> = x_cl.iter().zip(x).map(|(a, b)| a - b).collect();
    let (mut eg, mut ehe) = (0.0, 0.0);
    for i in 0..n {
        let row = &p.hess[i * n..(i + 1) * n];
        let hx: f64 = row.iter().zip(x).map(|(h, v)| h * v).sum();
        let he: f64 = row.iter().zip(&e).map(|(h, v)| h * v).sum();
        eg += e[i] * (hx + p.f[i]);
        ehe += e[i] * he;
    }
    1.0 + eg / (0.5 * ehe)
}

/// The largest violation of `lb ≤ x ≤ ub`, `G x ≤ h` at `x`.
fn violation(p: &QpProblem, x: &[f64]) -> f64 {
    let n = p.f.len();
    let mut v = 0.0f64;
    for ((xi, lb), ub) in x.iter().zip(p.lb).zip(p.ub) {
        v = v.max(lb - xi).max(xi - ub);
    }
    for (row, hj) in p.g.chunks(n.max(1)).zip(p.h) {
        if hj.is_finite() {
            let gx: f64 = row.iter().zip(x).map(|(g, xi)| g * xi).sum();
            v = v.max(gx - hj);
        }
    }
    v
}

/// The internal signal `name` of `c`, read into `buf`.
fn internal_of(c: &Pcac, names: &[String], name: &str, buf: &mut [f64; MAX_INTERNALS]) -> f64 {
    let n = c.internals(buf);
    names
        .iter()
        .position(|s| s == name)
        .filter(|i| *i < n)
        .map(|i| buf[i])
        .unwrap_or(f64::NAN)
}

/// The measurement of the module docs: `warmup` untimed samples, then `steps` timed
/// ones; clarabel solves the reference copy's QP at every timed step when
/// `with_clarabel`.
pub fn measure(
    w: Workload,
    warmup: u64,
    steps: u64,
    with_clarabel: bool,
) -> Result<PcacCost, String> {
    let params = w.params();
    let counts = w.counts();
    let (p, m) = (params.model.p, params.model.m);
    let mut timed =
        Pcac::new(&params, service::wire::dimensions(counts)).map_err(|e| e.to_string())?;
    let mut reference =
        Pcac::new(&params, service::wire::dimensions(counts)).map_err(|e| e.to_string())?;
    let mut pieces = Pieces::new(&params)?;
    let mut plant_t = Driver::new(w)?;
    let mut plant_r = Driver::new(w)?;
    let names = reference.internal_names();
    let du_max = params.mpc.move_bounds.as_ref().map(|b| b.max.clone());
    let block = BLOCK as usize;
    let mut log = BlockLog {
        dt: vec![None; block],
        y: vec![0.0; block * p],
        u: vec![0.0; block * m],
        first: vec![0.0; block * m],
    };
    let (mut y, mut z) = (vec![0.0; p], vec![0.0; p]);
    let (mut u, mut u_prev) = (vec![0.0; m], vec![0.0; m]);
    let mut ur = vec![0.0; m];
    let mut buf = [0.0; MAX_INTERNALS];
    let mut r = PcacCost {
        workload: w,
        step: new_histogram(),
        cold: new_histogram(),
        step_by_active: [new_histogram(), new_histogram()],
        clarabel: new_histogram(),
        pieces: std::array::from_fn(|_| new_histogram()),
        active: new_histogram(),
        iterations: new_histogram(),
        compared: 0,
        clarabel_unsolved: 0,
        max_first_move_diff: 0.0,
        pieces_diff: 0.0,
        over_tol: 0,
        tight_diff: 0.0,
        tight_unsolved: 0,
        first_move_diffs: Vec::with_capacity(steps as usize),
        optimality_ratio: f64::INFINITY,
        clarabel_violation: 0.0,
        replica_mismatches: 0,
        saturated: 0,
        at_move_bound: 0,
        fallback_steps: 0,
        counters: PcacCounters::default(),
        max_abs_u: 0.0,
    };
    let total = warmup + steps;
    let mut k = 0u64;
    while k < total {
        let end = (k + BLOCK).min(total);
        // 1. The timed copy.
        for j in k..end {
            let i = (j - k) as usize;
            let input = plant_t.sampled_input(j, &mut y, &mut z)?;
            let t0 = monotonic_ns();
            let status = timed.step(&input, &mut u);
            let t1 = monotonic_ns();
            plant_t.advance(&u)?;
            let dt = t1.saturating_sub(t0);
            log.dt[i] = None;
            if j >= warmup {
                if j - k < REWARM {
                    r.cold.saturating_record(dt);
                } else {
                    r.step.saturating_record(dt);
                    log.dt[i] = Some(dt);
                }
                if status & status::SATURATED != 0 {
                    r.saturated += 1;
                }
                if status & status::FALLBACK != 0 {
                    r.fallback_steps += 1;
                }
                if let Some(dmax) = &du_max
                    && u.iter()
                        .zip(&u_prev)
                        .zip(dmax)
                        .any(|((a, b), d)| (a - b).abs() >= d - 1e-9)
                {
                    r.at_move_bound += 1;
                }
                r.max_abs_u = u.iter().fold(r.max_abs_u, |acc, v| acc.max(v.abs()));
            }
            u_prev.copy_from_slice(&u);
            log.y[i * p..(i + 1) * p].copy_from_slice(&y);
            log.u[i * m..(i + 1) * m].copy_from_slice(&u);
            log.first[i * m..(i + 1) * m].copy_from_slice(&timed.planned_inputs()[..m]);
        }
        // 2. The reference copy and clarabel.
        for j in k..end {
            let i = (j - k) as usize;
            let input = plant_r.sampled_input(j, &mut y, &mut z)?;
            reference.step(&input, &mut ur);
            plant_r.advance(&ur)?;
            if ur[..] != log.u[i * m..(i + 1) * m] {
                r.replica_mismatches += 1;
            }
            if j < warmup {
                continue;
            }
            let active = internal_of(&reference, &names, "qp_active", &mut buf);
            let iters = internal_of(&reference, &names, "qp_iterations", &mut buf);
            if active.is_finite() {
                r.active.saturating_record(active as u64);
                if let Some(dt) = log.dt[i] {
                    r.step_by_active[usize::from(active > 0.0)].saturating_record(dt);
                }
            }
            if iters.is_finite() {
                r.iterations.saturating_record(iters as u64);
            }
            if !with_clarabel {
                continue;
            }
            let t0 = monotonic_ns();
            let sol = solve_with_clarabel(&reference.last_problem(), CLARABEL_TOL);
            let t1 = monotonic_ns();
            r.clarabel.saturating_record(t1.saturating_sub(t0));
            if reference.last_qp_status() == Some(QpStatus::Solved) {
                match sol {
                    Some(s) if s.status == clarabel::solver::SolverStatus::Solved => {
                        let ours = &reference.planned_inputs()[..m];
                        let d = ours
                            .iter()
                            .zip(&s.x)
                            .map(|(a, b)| (a - b).abs())
                            .fold(0.0, f64::max);
                        r.max_first_move_diff = r.max_first_move_diff.max(d);
                        r.first_move_diffs.push(d);
                        r.compared += 1;
                        if d > AGREE_TOL {
                            r.over_tol += 1;
                            let qp = reference.last_problem();
                            let x = reference.planned_inputs();
                            r.optimality_ratio =
                                r.optimality_ratio.min(optimality_ratio(&qp, x, &s.x));
                            r.clarabel_violation = r.clarabel_violation.max(violation(&qp, &s.x));
                            match solve_with_clarabel(&qp, CLARABEL_TIGHT_TOL) {
                                Some(t) if t.status == clarabel::solver::SolverStatus::Solved => {
                                    let d = x[..m]
                                        .iter()
                                        .zip(&t.x)
                                        .map(|(a, b)| (a - b).abs())
                                        .fold(0.0, f64::max);
                                    r.tight_diff = r.tight_diff.max(d);
                                }
                                _ => r.tight_unsolved += 1,
                            }
                        }
                    }
                    _ => r.clarabel_unsolved += 1,
                }
            }
        }
        // 3. The pieces, on the timed copy's data.
        let mut t = [0u64; 4];
        for j in k..end {
            let i = (j - k) as usize;
            let st = pieces.step(
                &log.y[i * p..(i + 1) * p],
                &log.u[i * m..(i + 1) * m],
                &mut t,
            );
            if st == Some(QpStatus::Solved) {
                let d = pieces
                    .first_move()
                    .iter()
                    .zip(&log.first[i * m..(i + 1) * m])
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                r.pieces_diff = r.pieces_diff.max(d);
            }
            if j >= warmup && j - k >= REWARM && st.is_some() {
                for (h, v) in r.pieces.iter_mut().zip(t) {
                    h.saturating_record(v);
                }
            }
        }
        k = end;
    }
    r.counters = timed.counts_of();
    if u.iter().any(|v| !v.is_finite()) {
        return Err(format!("{}: the input is not finite", w.slug()));
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The truss workload runs a real closed loop: its QPs are solved (few fallbacks), the
    /// inputs reach ±10 N, clarabel's point is never better than the dense solver's where
    /// their first moves differ by more than 10⁻⁶, the reference copy replays the timed
    /// one exactly and the pieces are the step.
    #[test]
    fn the_truss_workload_solves_its_qps_and_clarabel_is_never_better() {
        let w = Workload::Truss;
        let r = measure(w, w.default_warmup(), 400, true).unwrap();
        check_common(&r, 400);
        assert!(r.active.max() > 0);
        assert!(r.saturated > 0, "the inputs never reach ±10 N");
    }

    /// The arm workload hits its input bound and its move bound, and the same checks as
    /// the truss's hold (clarabel at tolerance 1e-8 differs from the dense solver's first
    /// move by up to 3e-2 at this size; its points are feasible and never lower).
    #[test]
    fn the_arm_workload_hits_its_bounds_and_clarabel_is_never_better() {
        let r = measure(Workload::Arm, 500, 1000, true).unwrap();
        check_common(&r, 1000);
        assert!(r.saturated > 0, "the inputs never reach ±{ARM_U_MAX}");
        assert!(r.at_move_bound > 0, "the moves never reach ±{ARM_DU_MAX}");
        assert!(r.active.max() > 0);
    }

    /// The service reads the arm's `[controller]` table into exactly the parameters the
    /// step-cost phase times (only the form of the scalar `R` differs).
    #[test]
    fn the_arm_controller_table_is_the_arm_workload() {
        let text = crate::configs::service_toml_with(
            "bench-arm",
            crate::configs::ARM_PERIOD_NS,
            crate::configs::Channels {
                y: ARM_P,
                z: ARM_P,
                u: ARM_M,
            },
            &arm_controller_toml(),
            None,
            false,
        );
        let cfg = service::config::ServiceConfig::parse(&text, "bench").unwrap();
        let service::config::ControllerConfig::Pcac { params } = cfg.controller else {
            panic!("not pcac");
        };
        let mut parsed = *params;
        let expected = Workload::Arm.params();
        assert_eq!(parsed.mpc.r, Weight::PerChannel(vec![1.0; ARM_M]));
        parsed.mpc.r = expected.mpc.r.clone();
        assert_eq!(parsed, expected);
        assert_eq!(cfg.counts, Workload::Arm.counts());
    }

    fn check_common(r: &PcacCost, steps: u64) {
        let name = r.workload.slug();
        assert_eq!(r.step.len() + r.cold.len(), steps, "{name}");
        assert_eq!(r.clarabel.len(), steps, "{name}");
        assert_eq!(r.replica_mismatches, 0, "{name}");
        assert!(
            r.fallback_steps * 100 <= steps,
            "{name}: {} fallbacks in {steps} steps",
            r.fallback_steps
        );
        assert!(
            r.compared * 10 >= steps * 9,
            "{name}: {} compared",
            r.compared
        );
        // Where clarabel (tol 1e-8) differs by more than 1e-6, its point is feasible and
        // uphill from ours: ours is the minimizer (ρ ≥ 1, with a margin for round-off).
        assert!(
            r.max_first_move_diff <= AGREE_TOL || r.optimality_ratio >= 0.9,
            "{name}: clarabel differs by {} and ρ = {}",
            r.max_first_move_diff,
            r.optimality_ratio
        );
        assert!(r.clarabel_violation <= 1e-7, "{name}");
        assert!(
            r.pieces_diff <= 1e-12,
            "{name}: pieces differ by {}",
            r.pieces_diff
        );
        for h in &r.pieces {
            assert!(!h.is_empty(), "{name}");
        }
        assert!(r.max_abs_u.is_finite() && r.max_abs_u > 0.0, "{name}");
    }
}
