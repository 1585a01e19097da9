//! Cost of one PCAC step, beside clarabel on the same quadratic programs.
//!
//! ## Workloads
//!
//! Two closed loops ([`Workload`]), both with F-test forgetting (τ_n = 40, τ_d = 200,
//! η = 0.1, α = 0.001) and the shared-covariance identification kernel:
//!
//! | workload | controller | `n̂` | `p` | `m` | `θ` | `ℓ` | timing | bounds | plant |
//! | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |
//! | [`Workload::Truss`] (chapter 6) | [`Pcac`], [`truss_params`] (`C_t = [0 0 0 1]`, `Q = 10⁶`, `R = 1`, `θ_0 = 10⁻¹⁰ 1`) | 25 | 4 | 2 | 600 | 40 | next step | `\|u\| ≤ 10` | `scenarios/truss/broadband-25hz.toml` at 50 Hz |
//! | [`Workload::Arm`] (chapter 7) | `sampling-arm` of [`ARM_CONTROLLER`] | 1 | 5 | 2 | 35 | 50 | same step | `\|u_aug\| ≤ 100`, `\|Δu_aug\| ≤ 20` | [`ARM_SCENARIO`] at 2 kHz |
//!
//! The truss is driven by `plant_proxy::sim::PlantSim` on the scenario's plant (its 25 Hz
//! band-limited disturbance of 1 N RMS at node 1, 40 dB sensor noise), so that the active
//! sets are those of a real closed loop: with the truss's outputs in millimetres and the
//! §6.2 weights, the planned input often sits on its ±10 N bound once the model is
//! identified (the bench reports the share of such steps and the distribution of the
//! active-set size).
//!
//! The arm is chapter 7's loop as `rig launch scenarios/arm/linear.toml --controller
//! scenarios/arm/pcac.toml` runs it: the plant `PlantSim` of the Figure 7.4 surface
//! (Kelvin–Voigt, `k_s = 2·10⁵` N/m, `c_s = 5` N s/m, noiseless sensors), the controller
//! read by `service::config::ServiceConfig::load_with_controller` (kind `sampling-arm`, its
//! robust gain from `scenarios/arm/robust-gain.toml`) and built as
//! `control::arm::controller::ArmController`. Its step is Algorithm 3: the feedback
//! linearization (7.31), `u_robust = K χ` and PCAC augmenting `K̄ = [0 K]`
//! (identification on `τ_f`, the closed-loop realization (7.56)–(7.57), condensing, the
//! QP), then the torques. Only the samples of the contact phase (`r = F_d > 0`: from the
//! touch-down at ≈ 2 s for 2 s, 4000 samples) are counted and timed; the joint hold of
//! the descent is stepped but not timed. When a contact phase ends, plant and controller
//! are reset and the maneuver runs again, so that `steps` beyond 4000 time further
//! touch-downs from the prior `w_0` (the plant is noiseless: every maneuver is the same
//! run, and what varies is the machine).
//!
//! ## Method
//!
//! Two copies of the loop run in lockstep, in blocks of [`BLOCK`] samples, on the calling
//! thread (which the bench pins on the RT core under `SCHED_FIFO`):
//!
//! 1. **Timed.** `Controller::step` between two `CLOCK_MONOTONIC` readings and nothing
//!    else: the plant's sample is taken before the first reading and the input applied
//!    after the second. Its output `u_k` and PCAC's planned first move `u_{1|k}` are kept
//!    for the block.
//! 2. **Reference.** A second controller and plant, built from the same files and seeds,
//!    step through the same samples untimed (the bench checks that they produce
//!    bit-identical inputs, so that they solve the same QPs). After each counted step:
//!    - **the pieces**: the step's PCAC part taken apart into the public kernels of
//!      `control`, each timed alone on the data the reference PCAC just used:
//!      `IoModel::update` on a copy of its model taken before the step (identification;
//!      the copy's coefficients are checked equal to PCAC's, untimed), `HorizonPrediction` on
//!      the identified model (truss, `compute` from `u_k`) or on PCAC's closed-loop model
//!      `Pcac::closed_loop_model` (arm, `compute_from_state`) (realization: state, Markov
//!      parameters, free response; with the fast path and no output constraint, the arm,
//!      the state and the head only, `HorizonPrediction::defer_horizon`, as `Pcac`
//!      does), where PCAC's `fast-path` setting chooses it (the arm)
//!      `FastPath::solve` (the Riccati minimizer and the constraint check, on the
//!      realization the prediction used), and where that minimizer is not the solution
//!      (or without the fast path) `HorizonPrediction::complete` (the rest of a deferred
//!      prediction) with `Condenser::build` (condensing) and
//!      `DenseQpSolver::solve` (warm-started from its own shifted active set, emptied by a
//!      fast-path step, as `Pcac` does); each piece is recorded at the steps that run it.
//!      Its first move is compared with the timed controller's, which checks that
//!      the pieces are the step. Not timed as pieces: the arm's linearization and robust
//!      gain, and PCAC's bookkeeping (the difference between the step and the sum of the
//!      pieces). The arm's first contact sample of a phase only primes PCAC's regressor
//!      and has no pieces.
//!    - **clarabel**: `solve_with_clarabel(&qp, 1e-8)` — clarabel's set-up and solve,
//!      allocating — on the reference PCAC's QP `qp = Pcac::condensed_problem()` (the arm's
//!      through `ArmController::pcac_mut`; condensed there, untimed, when the step took the
//!      fast path), and its first move is compared with the step's (the fast path's
//!      minimizer, or the dense solver's solution) where both report *solved*. The active-set size and the iteration count of the dense solver
//!      are read here from `Controller::internals` (`qp_active`, `qp_iterations`).
//!    - **OSQP**: [`OsqpAnchor::solve`] on the same QP at [`OSQP_TOL`] with polishing,
//!      set up once per workload (at its first timed step) and afterwards updated with the
//!      step's values and warm-started from its previous solution, as a user of OSQP runs
//!      a parametric QP (see [`crate::osqp_anchor`]); timed from the dense data to the
//!      solution (copying the values into OSQP's sparse arrays, the updates with OSQP's
//!      numeric refactorization, the solve). Its first move is compared as clarabel's.
//!
//! Running the copies in blocks rather than interleaved per step keeps the anchors'
//! allocations and caches out of the timed controller's cache except at block starts: the first
//! [`REWARM`] counted steps of each block run but are recorded apart
//! ([`PcacCost::cold`]), as in [`crate::rls_cost`]. Timing starts after `warmup` counted
//! samples ([`Workload::default_warmup`]: the truss needs a few hundred samples before
//! its model means anything; the arm none).

use crate::hist::new_histogram;
use crate::osqp_anchor::{OsqpAnchor, OsqpStatus};
use control::arm::controller::{ArmController, ArmControllerParams, ArmMode};
use control::bocf::{DataWindow, IdentifiedModel};
use control::mpc::condense::{Condenser, MpcSpec};
use control::mpc::fast_path::{FastPath, FastPathMode};
use control::mpc::qp::{
    ConstraintId, DenseQpSolver, QpProblem, QpSettings, QpStatus, WarmStart, solve_with_clarabel,
};
use control::pcac::{HorizonPrediction, IoModel, Pcac, PcacCounters, PcacParams, PcacTiming};
use control::status;
use control::{Controller, MAX_INTERNALS, StepInput};
use hdrhistogram::Histogram;
use ipc_types::ChannelCounts;
use ipc_types::clock::monotonic_ns;
use plant_proxy::sim::PlantSim;
use service::config::{ControllerConfig, ServiceConfig};

/// Samples per block of each copy of the loop (see the module docs).
pub const BLOCK: u64 = 256;

/// Timed steps at the start of each block that are run but recorded apart (cold cache).
pub const REWARM: u64 = 2;

/// clarabel's gap and feasibility tolerance in the comparison (its default).
pub const CLARABEL_TOL: f64 = 1e-8;

/// The agreement the issue asks for between the two solvers' first moves.
pub const AGREE_TOL: f64 = 1e-6;

/// OSQP's `eps_abs = eps_rel` in the comparison (with polishing), as clarabel's
/// [`CLARABEL_TOL`].
pub const OSQP_TOL: f64 = 1e-8;

/// clarabel's tolerance when a step disagrees by more than [`AGREE_TOL`] and is re-solved
/// to tell which solver is off.
pub const CLARABEL_TIGHT_TOL: f64 = 1e-11;

/// The truss scenario the truss workload runs (plant tables only are read).
const TRUSS_SCENARIO: &str = include_str!("../../scenarios/truss/broadband-25hz.toml");

/// The arm workload's plant scenario: Figure 7.4's surface (`k_s = 2·10⁵`, `c_s = 5`).
pub const ARM_SCENARIO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/arm/linear.toml");

/// The arm workload's controller file (Algorithm 3 with the PCAC augmentation); its
/// robust-gain file is found from its folder.
pub const ARM_CONTROLLER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/arm/pcac.toml");

/// A PCAC size to time (see the module docs for the full parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Workload {
    /// Chapter 6's truss: `n̂ = 25`, `p = 4`, `m = 2` (600 coefficients), `ℓ = 40`, 50 Hz.
    Truss,
    /// Chapter 7's sampling arm: the controller of `scenarios/arm/pcac.toml` (feedback
    /// linearization, robust gain, PCAC augmentation with `n̂ = 1`, `p = 5`, `m = 2`,
    /// `ℓ = 50`) on the plant of `scenarios/arm/linear.toml`, timed in the contact phases.
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

    /// The p99 target for one step, ns: 2 ms for the truss (50 Hz), 500 µs for
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

    /// Untimed samples before timing starts by default: 500 for the truss (10 s; its loop
    /// rides its bound from about sample 200 on), none for the arm (its contact phases
    /// start from the prior `w_0`, and the touch-down's first steps are part of the
    /// real-time load).
    pub fn default_warmup(self) -> u64 {
        match self {
            Workload::Truss => 500,
            Workload::Arm => 0,
        }
    }
}

/// The truss workload's PCAC (module docs): §6.2's ([`PcacParams::chapter_6`]) with
/// `|u| ≤ 10` and the next-step timing.
pub fn truss_params() -> PcacParams {
    PcacParams::chapter_6()
        .input_bounds(vec![-10.0; 2], vec![10.0; 2])
        .timing(PcacTiming::NextStep)
        .build()
}

/// The truss workload's plant: the plant tables of `scenarios/truss/broadband-25hz.toml`
/// (module docs), from its start.
///
/// # Errors
///
/// The scenario's plant is refused (a broken build).
pub fn truss_plant() -> Result<PlantSim, String> {
    let sc = plant_proxy::scenario::parse(TRUSS_SCENARIO, "broadband-25hz.toml")
        .map_err(|e| e.to_string())?;
    PlantSim::new(&sc.plant, sc.rig.sample_period).map_err(|e| format!("truss plant: {e}"))
}

/// The controller of a closed loop: PCAC alone (truss) or the arm's Algorithm 3 with PCAC
/// inside.
enum Ctrl {
    Truss(Box<Pcac>),
    Arm(Box<ArmController>),
}

/// One copy of a workload's closed loop: the plant, the controller and the sample's data.
struct ClosedLoop {
    ctrl: Ctrl,
    /// PCAC's MPC as the controller runs it.
    mpc: MpcSpec,
    /// PCAC's fast-path setting.
    fast_path: FastPathMode,
    plant: Box<PlantSim>,
    y: Vec<f64>,
    z: Vec<f64>,
    r: Vec<f64>,
    u: Vec<f64>,
    /// The arm: the last sample was in a contact phase.
    in_contact: bool,
    /// The arm: the controller was in contact before the last step (PCAC identified).
    identifies: bool,
}

impl ClosedLoop {
    /// The workload's plant and controller, as the service and plant-proxy build them.
    fn new(w: Workload) -> Result<Self, String> {
        let (plant, ctrl, mpc, fast_path, n_u) = match w {
            Workload::Truss => {
                let sim = truss_plant()?;
                let params = truss_params();
                let (p, m) = (params.model.p, params.model.m);
                let counts = ChannelCounts::new(p, p, 0, m).map_err(|e| e.to_string())?;
                let c = Pcac::new(&params, service::wire::dimensions(counts))
                    .map_err(|e| e.to_string())?;
                (
                    sim,
                    Ctrl::Truss(Box::new(c)),
                    params.mpc,
                    params.fast_path,
                    m,
                )
            }
            Workload::Arm => {
                let (sim, params, counts) = arm_loop()?;
                let pcac = params
                    .augmented_pcac()
                    .map_err(|e| format!("{ARM_CONTROLLER}: {}", e.message))?;
                let c = ArmController::new(&params, service::wire::dimensions(counts))
                    .map_err(|e| format!("{ARM_CONTROLLER}: {}", e.message))?;
                let n_u = counts.n_u as usize;
                (sim, Ctrl::Arm(Box::new(c)), pcac.mpc, pcac.fast_path, n_u)
            }
        };
        Ok(Self {
            y: vec![0.0; plant.n_y()],
            z: vec![0.0; plant.n_z()],
            r: vec![0.0; plant.n_r()],
            u: vec![0.0; n_u],
            in_contact: false,
            identifies: true,
            ctrl,
            mpc,
            fast_path,
            plant: Box::new(plant),
        })
    }

    /// PCAC, alone or inside the arm's controller.
    fn pcac(&self) -> &Pcac {
        match &self.ctrl {
            Ctrl::Truss(c) => c,
            Ctrl::Arm(c) => c.pcac().expect("the arm workload is built with PCAC"),
        }
    }

    /// [`Self::pcac`], mutable (for [`Pcac::condensed_problem`]).
    fn pcac_mut(&mut self) -> &mut Pcac {
        match &mut self.ctrl {
            Ctrl::Truss(c) => c,
            Ctrl::Arm(c) => c.pcac_mut().expect("the arm workload is built with PCAC"),
        }
    }

    /// Samples the plant; returns whether the sample is one the bench times (truss: all;
    /// arm: the contact phase, `r > 0`). After a contact phase the arm's maneuver starts
    /// again: plant and controller back to their start (a fresh run of Figure 7.4).
    fn sample(&mut self) -> Result<bool, String> {
        self.plant
            .sample(&mut self.y, &mut self.z, &mut self.r)
            .map_err(|e| e.to_string())?;
        let Ctrl::Arm(c) = &mut self.ctrl else {
            return Ok(true);
        };
        let contact = self.r.first().is_some_and(|f| *f > 0.0);
        if self.in_contact && !contact {
            self.plant.reset();
            c.reset();
            self.in_contact = false;
            return self.sample();
        }
        self.in_contact = contact;
        self.identifies = contact && c.mode() == ArmMode::Contact;
        Ok(contact)
    }

    /// One step of the controller on the sample `seq` just taken, timed alone by two
    /// `CLOCK_MONOTONIC` readings; returns the status bits and the duration, ns.
    fn step(&mut self, seq: u64) -> (u32, u64) {
        let input = StepInput {
            seq,
            y: &self.y,
            z: &self.z,
            r: &self.r,
            ..Default::default()
        };
        let (status, t0, t1) = match &mut self.ctrl {
            Ctrl::Truss(c) => {
                let t0 = monotonic_ns();
                let s = c.step(&input, &mut self.u);
                (s, t0, monotonic_ns())
            }
            Ctrl::Arm(c) => {
                let t0 = monotonic_ns();
                let s = c.step(&input, &mut self.u);
                (s, t0, monotonic_ns())
            }
        };
        (status, t1.saturating_sub(t0))
    }

    /// PCAC's output of the step (truss: `u_k`; arm: `u_aug,k`).
    fn pcac_output(&self) -> [f64; 2] {
        match &self.ctrl {
            Ctrl::Truss(_) => [self.u[0], self.u[1]],
            Ctrl::Arm(c) => c.augmentation_input(),
        }
    }

    /// Applies the step's input and moves the plant to the next sample.
    fn advance(&mut self) -> Result<(), String> {
        self.plant.advance(&self.u).map_err(|e| e.to_string())
    }
}

/// The arm workload's plant, the controller's parameters and the rig's channel counts,
/// from [`ARM_SCENARIO`] with the controller tables of [`ARM_CONTROLLER`] (as
/// `rig launch <scenario> --controller <file>` reads them).
fn arm_loop() -> Result<(PlantSim, ArmControllerParams, ChannelCounts), String> {
    let text = std::fs::read_to_string(ARM_SCENARIO)
        .map_err(|e| format!("{ARM_SCENARIO}: cannot read the file: {e}"))?;
    let sc = plant_proxy::scenario::parse(&text, ARM_SCENARIO).map_err(|e| e.to_string())?;
    let sim = PlantSim::new(&sc.plant, sc.rig.sample_period)
        .map_err(|e| format!("{ARM_SCENARIO}: arm plant: {e}"))?;
    let cfg = ServiceConfig::load_with_controller(
        std::path::Path::new(ARM_SCENARIO),
        std::path::Path::new(ARM_CONTROLLER),
    )
    .map_err(|e| e.to_string())?;
    let ControllerConfig::SamplingArm { params } = cfg.controller else {
        return Err(format!("{ARM_CONTROLLER}: kind is not \"sampling-arm\""));
    };
    if params.pcac.is_none() {
        return Err(format!("{ARM_CONTROLLER}: controller.pcac: missing"));
    }
    Ok((sim, *params, cfg.counts))
}

/// The PCAC step taken apart into its kernels (module docs, copy 2), each on the data the
/// reference controller's PCAC just stepped with.
struct Pieces {
    model: IoModel,
    pred: HorizonPrediction,
    cond: Condenser,
    solver: DenseQpSolver,
    /// The unconstrained fast path, when PCAC's setting chooses it.
    fast: Option<FastPath>,
    /// The last step's first move is the fast path's.
    fast_taken: bool,
    active: Vec<ConstraintId>,
    shifted: Vec<ConstraintId>,
    n_shifted: usize,
    reference: Vec<f64>,
    u_ref: Vec<f64>,
}

impl Pieces {
    fn new(pcac: &Pcac, mpc: &MpcSpec, fast_path: FastPathMode) -> Result<Self, String> {
        let model = pcac.model().clone();
        let mut pred = HorizonPrediction::new(&model, mpc.horizon)?;
        let cond = Condenser::new(mpc).map_err(|e| e.to_string())?;
        let settings = QpSettings::default();
        let solver = DenseQpSolver::new(cond.n(), cond.n_ineq(), settings);
        let fast = FastPath::new(mpc, model.n_hat(), settings.feasibility_tol, fast_path)
            .map_err(|e| e.to_string())?;
        // As `Pcac`: with the fast path and no output constraint, the prediction's horizon
        // waits until a QP is condensed.
        pred.defer_horizon(fast.as_ref().is_some_and(|f| !f.reads_prediction()));
        let ids = cond.n() + cond.n_ineq();
        Ok(Self {
            reference: vec![0.0; mpc.horizon * mpc.n_tracked],
            u_ref: vec![0.0; mpc.n_inputs],
            active: vec![ConstraintId::Row(0); ids],
            shifted: vec![ConstraintId::Row(0); ids],
            n_shifted: 0,
            model,
            pred,
            cond,
            solver,
            fast,
            fast_taken: false,
        })
    }

    /// Before the reference step: PCAC's model as it stands (the identification piece
    /// repeats the step's update on this copy).
    fn before(&mut self, pcac: &Pcac) {
        self.model.clone_from(pcac.model());
    }

    /// After the reference step, which identified: the kernels on its data, timed into `t`
    /// (ns, in the order of [`PIECES`]; `None` for a kernel the step did not run: the
    /// fast path without one, condensing and the QP when the fast path's minimizer was
    /// the solution). Returns the QP's status (`None`: not built; `Solved` by the fast
    /// path) and the largest difference between the copy's coefficients and PCAC's.
    /// `u_k` is the controller's output at the step.
    fn step(
        &mut self,
        pcac: &Pcac,
        u_k: &[f64],
        t: &mut [Option<u64>; 5],
    ) -> (Option<QpStatus>, f64) {
        self.fast_taken = false;
        *t = [None; 5];
        let m = pcac.model();
        let (y, tau) = (m.last_y(), m.past_input(1));
        let t0 = monotonic_ns();
        let _ = self.model.update(y, tau);
        let t1 = monotonic_ns();
        let coef_diff = self
            .model
            .coefficients()
            .iter()
            .zip(m.coefficients())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // The prediction's time starts after that check, which is not part of a step.
        let t1b = monotonic_ns();
        // Same-step timing with the augmentation (the arm): the closed-loop model from its
        // state, moves from u_aug,k−1; next-step timing (the truss): from the model and
        // u_k, moves from u_k (`Pcac::solve_mpc`).
        let t2;
        let cl = pcac.closed_loop_model();
        let predicted = match &cl {
            Some(cl) => {
                let r = self.pred.compute_from_state(cl);
                t2 = monotonic_ns();
                self.u_ref.copy_from_slice(cl.past_input(1));
                r
            }
            None => {
                let m = self.u_ref.len();
                self.u_ref.copy_from_slice(&u_k[..m]);
                let r = self.pred.compute(&self.model, &self.u_ref);
                t2 = monotonic_ns();
                r
            }
        };
        if predicted.is_err() {
            self.n_shifted = 0;
            return (None, coef_diff);
        }
        // The fast path (as `Pcac::solve_mpc`): on the realization the prediction used.
        if let Some(fast) = &mut self.fast {
            let t5 = monotonic_ns();
            let (x0, free, markov) = (
                self.pred.one_step_state(),
                self.pred.free_response(),
                self.pred.markov(),
            );
            let taken = match &cl {
                Some(cl) => {
                    let real = cl.realization();
                    fast.solve(&real, x0, &self.u_ref, &self.reference, free, markov)
                }
                None => {
                    let real = self.model.realization();
                    fast.solve(&real, x0, &self.u_ref, &self.reference, free, markov)
                }
            };
            t[4] = Some(monotonic_ns() - t5);
            if taken {
                self.fast_taken = true;
                self.n_shifted = 0;
                t[0] = Some(t1 - t0);
                t[1] = Some(t2 - t1b);
                return (Some(QpStatus::Solved), coef_diff);
            }
        }
        let warm = if self.n_shifted > 0 {
            WarmStart::ActiveSet(&self.shifted[..self.n_shifted])
        } else {
            WarmStart::Cold
        };
        let t2b = monotonic_ns();
        // The rest of a deferred prediction, on the realization it used.
        let completed = match &cl {
            Some(cl) => self.pred.complete(&cl.realization()),
            None => self.pred.complete(&self.model.realization()),
        };
        if completed.is_err() {
            self.n_shifted = 0;
            return (None, coef_diff);
        }
        let Ok(problem) = self.cond.build(
            self.pred.markov(),
            self.pred.free_response(),
            &self.u_ref,
            &self.reference,
        ) else {
            self.n_shifted = 0;
            return (None, coef_diff);
        };
        let t3 = monotonic_ns();
        let status = self.solver.solve(&problem, warm);
        let t4 = monotonic_ns();
        t[..4].copy_from_slice(&[Some(t1 - t0), Some(t2 - t1b), Some(t3 - t2b), Some(t4 - t3)]);
        if status == QpStatus::Solved {
            let na = self.solver.active_set_into(&mut self.active);
            self.n_shifted = self
                .cond
                .shift_active_set(&self.active[..na], &mut self.shifted);
        } else {
            self.n_shifted = 0;
        }
        (Some(status), coef_diff)
    }

    /// A step the pieces do not follow (no identification): the warm start is dropped.
    fn skip(&mut self) {
        self.n_shifted = 0;
    }

    fn first_move(&self) -> &[f64] {
        match &self.fast {
            Some(fast) if self.fast_taken => self.cond.first_move(fast.u()),
            _ => self.cond.first_move(self.solver.x()),
        }
    }
}

/// Names of the pieces, in the order of [`PcacCost::pieces`]. Condensing and the QP
/// solve are timed at the steps that run them: all without the fast path; with it, those
/// whose unconstrained minimizer violates a constraint. The fast path (the Riccati
/// minimizer and the constraint check) runs at every step when PCAC's setting chooses it
/// (never on the truss).
pub const PIECES: [&str; 5] = [
    "identification (IoModel::update)",
    "realization + prediction (HorizonPrediction)",
    "condensing (HorizonPrediction::complete + Condenser::build)",
    "QP solve, warm (DenseQpSolver::solve)",
    "fast path (Riccati + constraint check)",
];

/// The result of [`measure`].
pub struct PcacCost {
    /// The workload.
    pub workload: Workload,
    /// PCAC has move bounds ([`PcacCost::at_move_bound`] is meaningful).
    pub move_bounds: bool,
    /// The controller's step, ns (warm: the first [`REWARM`] steps of each block excluded).
    pub step: Histogram<u64>,
    /// The timed steps at block starts, after the other copies ran, ns.
    pub cold: Histogram<u64>,
    /// The steps of [`Self::step`] split by their QP's solution: no active constraint
    /// (`[0]`) and at least one (`[1]`), ns.
    pub step_by_active: [Histogram<u64>; 2],
    /// clarabel on the same QPs: `solve_with_clarabel` (set-up and solve) timed, and its
    /// first move against the dense solver's.
    pub clarabel: AnchorCost,
    /// OSQP on the same QPs: [`OsqpAnchor::solve`] (update, warm start and solve) timed,
    /// and its first move against the dense solver's.
    pub osqp: AnchorCost,
    /// OSQP's ADMM iterations per solve.
    pub osqp_iterations: Histogram<u64>,
    /// OSQP solves that set it up rather than updating it (1 when the workload's QPs keep
    /// one size and sparsity).
    pub osqp_setups: u64,
    /// Of [`AnchorCost::unsolved`] for OSQP: the solves OSQP reported `SolvedInaccurate`
    /// and those that reached its iteration cap.
    pub osqp_inaccurate_or_capped: [u64; 2],
    /// OSQP solves reported `Solved` whose polishing did not succeed (the point is then
    /// ADMM's, accurate only to [`OSQP_TOL`]).
    pub osqp_unpolished: u64,
    /// The step's kernels timed alone, ns, in the order of [`PIECES`] (each at the steps
    /// that run it).
    pub pieces: [Histogram<u64>; 5],
    /// Active constraints of the dense solver's solution per timed step (`qp_active`).
    pub active: Histogram<u64>,
    /// The dense solver's iterations (active-set changes) per timed step.
    pub iterations: Histogram<u64>,
    /// Of the compared steps where clarabel's first move differs by more than
    /// [`AGREE_TOL`], the largest first-move difference against clarabel re-solved
    /// (untimed) with the tighter tolerance [`CLARABEL_TIGHT_TOL`], where that re-solve
    /// reports `Solved`.
    pub tight_diff: f64,
    /// Re-solves at [`CLARABEL_TIGHT_TOL`] that did not report `Solved`.
    pub tight_unsolved: u64,
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

/// An anchor solver's figures on the timed QPs: its time, and its first move against the
/// dense solver's where both solved.
pub struct AnchorCost {
    /// The anchor's solve (what is timed is the anchor's: see the module docs), ns.
    pub time: Histogram<u64>,
    /// Steps where both solvers reported solved and the first moves were compared.
    pub compared: u64,
    /// Steps where the dense solver solved and the anchor did not report solved.
    pub unsolved: u64,
    /// Largest `max_j |u_{1|k,j} − u^anchor_{1|k,j}|` over the compared steps.
    pub max_first_move_diff: f64,
    /// Compared steps whose first moves differ by more than [`AGREE_TOL`].
    pub over_tol: u64,
    /// `max_j |u_{1|k,j} − u^anchor_{1|k,j}|` of every compared step.
    pub first_move_diffs: Vec<f64>,
    /// At the steps beyond [`AGREE_TOL`], the smallest `ρ = (J(U_a) − J(U)) / (½ eᵀHe)`,
    /// `e = U_a − U`, of the objective `J = ½ UᵀHU + fᵀU` at the dense solver's `U` and
    /// the anchor's `U_a` (`+∞` when no step disagreed). For feasible points of this
    /// strictly convex QP, `ρ ≥ 1` when `U` is the minimizer and `ρ ≤ −1` when `U_a` is;
    /// evaluated as `1 + eᵀ(HU + f) / (½ eᵀHe)`, so without the cancellation of two large
    /// objectives.
    pub optimality_ratio: f64,
    /// [`Self::optimality_ratio`] at the steps whose `U` came from PCAC's unconstrained
    /// fast path (the Riccati minimizer, not the dense solver's solution of this QP).
    pub optimality_ratio_fast: f64,
    /// At those steps, the largest constraint violation of the anchor's point.
    pub violation: f64,
}

impl AnchorCost {
    fn new(steps: u64) -> Self {
        Self {
            time: new_histogram(),
            compared: 0,
            unsolved: 0,
            max_first_move_diff: 0.0,
            over_tol: 0,
            first_move_diffs: Vec::with_capacity(steps as usize),
            optimality_ratio: f64::INFINITY,
            optimality_ratio_fast: f64::INFINITY,
            violation: 0.0,
        }
    }

    /// Compares the anchor's solution `x_a` of `qp` with the dense solver's `x` on the
    /// first `m` entries (the first move); beyond [`AGREE_TOL`] also `ρ` and the anchor's
    /// violation. Returns the first-move difference.
    fn compare(&mut self, qp: &QpProblem, x: &[f64], x_a: &[f64], m: usize, fast: bool) -> f64 {
        let d = x[..m]
            .iter()
            .zip(x_a)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        self.max_first_move_diff = self.max_first_move_diff.max(d);
        self.first_move_diffs.push(d);
        self.compared += 1;
        if d > AGREE_TOL {
            self.over_tol += 1;
            let rho = optimality_ratio(qp, x, x_a);
            if fast {
                self.optimality_ratio_fast = self.optimality_ratio_fast.min(rho);
            } else {
                self.optimality_ratio = self.optimality_ratio.min(rho);
            }
            self.violation = self.violation.max(violation(qp, x_a));
        }
        d
    }

    /// The first-move difference at quantile `q` of the compared steps (NaN if none).
    pub fn first_move_diff_quantile(&self, q: f64) -> f64 {
        let mut d = self.first_move_diffs.clone();
        d.sort_by(f64::total_cmp);
        if d.is_empty() {
            f64::NAN
        } else {
            d[((q * d.len() as f64) as usize).min(d.len() - 1)]
        }
    }
}

/// Which anchor solvers [`measure`] runs on the timed QPs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Anchors {
    /// clarabel (`solve_with_clarabel`).
    pub clarabel: bool,
    /// OSQP ([`OsqpAnchor`]).
    pub osqp: bool,
}

impl Anchors {
    /// Both anchors.
    pub const BOTH: Anchors = Anchors {
        clarabel: true,
        osqp: true,
    };
}

/// Per-block storage of the timed copy, read by the reference copy.
struct BlockLog {
    /// The step's duration, ns (`None`: not recorded in [`PcacCost::step`]).
    dt: Vec<Option<u64>>,
    /// The sample counts (truss: all; arm: contact phases).
    counted: Vec<bool>,
    /// The controller's output `u_k`.
    u: Vec<f64>,
    /// PCAC's planned first move `u_{1|k}`.
    first: Vec<f64>,
}

/// `ρ` of [`AnchorCost::optimality_ratio`] for the dense solver's `x` and an anchor's `x_cl`.
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
/// ones (the arm: samples of its contact phases); the `anchors` solve the reference
/// copy's QP at every timed step.
pub fn measure(w: Workload, warmup: u64, steps: u64, anchors: Anchors) -> Result<PcacCost, String> {
    let mut timed = ClosedLoop::new(w)?;
    let mut reference = ClosedLoop::new(w)?;
    let mpc = reference.mpc.clone();
    let mut pieces = Pieces::new(reference.pcac(), &mpc, reference.fast_path)?;
    let (m, n_u) = (mpc.n_inputs, timed.u.len());
    let names = reference.pcac().internal_names();
    let du_max = mpc.move_bounds.as_ref().map(|b| b.max.clone());
    let block = BLOCK as usize;
    let mut log = BlockLog {
        dt: vec![None; block],
        counted: vec![false; block],
        u: vec![0.0; block * n_u],
        first: vec![0.0; block * m],
    };
    let mut u_prev = vec![0.0; m];
    let mut x_buf = Vec::with_capacity(mpc.horizon * m);
    let mut buf = [0.0; MAX_INTERNALS];
    let mut osqp = OsqpAnchor::new(OSQP_TOL);
    let mut r = PcacCost {
        workload: w,
        move_bounds: du_max.is_some(),
        step: new_histogram(),
        cold: new_histogram(),
        step_by_active: [new_histogram(), new_histogram()],
        clarabel: AnchorCost::new(steps),
        osqp: AnchorCost::new(steps),
        osqp_iterations: new_histogram(),
        osqp_setups: 0,
        osqp_unpolished: 0,
        osqp_inaccurate_or_capped: [0; 2],
        pieces: std::array::from_fn(|_| new_histogram()),
        active: new_histogram(),
        iterations: new_histogram(),
        pieces_diff: 0.0,
        tight_diff: 0.0,
        tight_unsolved: 0,
        replica_mismatches: 0,
        saturated: 0,
        at_move_bound: 0,
        fallback_steps: 0,
        counters: PcacCounters::default(),
        max_abs_u: 0.0,
    };
    let total = warmup + steps;
    // `seq` counts every sample, `counted` the samples that count (all for the truss, the
    // contact phases for the arm): timing starts at counted = warmup.
    let (mut seq, mut counted) = (0u64, 0u64);
    while counted < total {
        // 1. The timed copy, until the block is full or enough steps are counted.
        let (start_seq, start_counted) = (seq, counted);
        let mut n = 0usize;
        let mut in_block = 0u64;
        while n < block && counted < total {
            let counts = timed.sample()?;
            let (status, dt) = timed.step(seq);
            timed.advance()?;
            log.dt[n] = None;
            log.counted[n] = counts;
            if counts {
                if counted >= warmup {
                    if in_block < REWARM {
                        r.cold.saturating_record(dt);
                    } else {
                        r.step.saturating_record(dt);
                        log.dt[n] = Some(dt);
                    }
                    in_block += 1;
                    if status & status::SATURATED != 0 {
                        r.saturated += 1;
                    }
                    if status & status::FALLBACK != 0 {
                        r.fallback_steps += 1;
                    }
                    let u = timed.pcac_output();
                    if let Some(dmax) = &du_max
                        && u.iter()
                            .zip(&u_prev)
                            .zip(dmax)
                            .any(|((a, b), d)| (a - b).abs() >= d - 1e-9)
                    {
                        r.at_move_bound += 1;
                    }
                    r.max_abs_u = timed.u.iter().fold(r.max_abs_u, |acc, v| acc.max(v.abs()));
                }
                counted += 1;
            }
            u_prev.copy_from_slice(&timed.pcac_output()[..m]);
            log.u[n * n_u..(n + 1) * n_u].copy_from_slice(&timed.u);
            log.first[n * m..(n + 1) * m].copy_from_slice(&timed.pcac().planned_inputs()[..m]);
            seq += 1;
            n += 1;
        }
        // 2. The reference copy: clarabel and the pieces on its QPs.
        let mut c = start_counted;
        for (i, j) in (start_seq..seq).enumerate() {
            let counts = reference.sample()?;
            pieces.before(reference.pcac());
            reference.step(j);
            reference.advance()?;
            if counts != log.counted[i] || reference.u[..] != log.u[i * n_u..(i + 1) * n_u] {
                r.replica_mismatches += 1;
            }
            if !counts {
                pieces.skip();
                continue;
            }
            let measured = c >= warmup;
            c += 1;
            let pcac = reference.pcac();
            // The pieces (only where PCAC identified: not the first sample of a contact).
            if reference.identifies {
                let mut t = [None; 5];
                let (st, coef_diff) = pieces.step(pcac, &reference.u, &mut t);
                r.pieces_diff = r.pieces_diff.max(coef_diff);
                if st == Some(QpStatus::Solved) {
                    let d = pieces
                        .first_move()
                        .iter()
                        .zip(&log.first[i * m..(i + 1) * m])
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max);
                    r.pieces_diff = r.pieces_diff.max(d);
                }
                if measured && log.dt[i].is_some() && st.is_some() {
                    for (h, v) in r.pieces.iter_mut().zip(t) {
                        if let Some(v) = v {
                            h.saturating_record(v);
                        }
                    }
                }
            } else {
                pieces.skip();
            }
            if !measured {
                continue;
            }
            let active = internal_of(pcac, &names, "qp_active", &mut buf);
            let iters = internal_of(pcac, &names, "qp_iterations", &mut buf);
            if active.is_finite() {
                r.active.saturating_record(active as u64);
                if let Some(dt) = log.dt[i] {
                    r.step_by_active[usize::from(active > 0.0)].saturating_record(dt);
                }
            }
            if iters.is_finite() {
                r.iterations.saturating_record(iters as u64);
            }
            let ours_solved = pcac.last_qp_status() == Some(QpStatus::Solved);
            let fast = pcac.fast_path_taken();
            // The step's QP and its solution (the fast path's when the step took it; its
            // QP is then condensed here, untimed, for the anchors).
            x_buf.clear();
            x_buf.extend_from_slice(pcac.planned_inputs());
            let x = &x_buf[..];
            let Some(qp) = reference.pcac_mut().condensed_problem() else {
                return Err(format!(
                    "{}: the step's QP could not be condensed",
                    w.slug()
                ));
            };
            if anchors.clarabel {
                let t0 = monotonic_ns();
                let sol = solve_with_clarabel(&qp, CLARABEL_TOL);
                let t1 = monotonic_ns();
                r.clarabel.time.saturating_record(t1.saturating_sub(t0));
                if ours_solved {
                    match sol {
                        Some(s) if s.status == clarabel::solver::SolverStatus::Solved => {
                            if r.clarabel.compare(&qp, x, &s.x, m, fast) > AGREE_TOL {
                                match solve_with_clarabel(&qp, CLARABEL_TIGHT_TOL) {
                                    Some(t)
                                        if t.status == clarabel::solver::SolverStatus::Solved =>
                                    {
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
                        _ => r.clarabel.unsolved += 1,
                    }
                }
            }
            if anchors.osqp {
                let t0 = monotonic_ns();
                let out = osqp.solve(&qp);
                let t1 = monotonic_ns();
                r.osqp.time.saturating_record(t1.saturating_sub(t0));
                let out = out.map_err(|e| format!("{}: {e}", w.slug()))?;
                r.osqp_iterations
                    .saturating_record(u64::from(out.iterations));
                if out.set_up {
                    r.osqp_setups += 1;
                }
                if ours_solved {
                    if out.status == OsqpStatus::Solved {
                        if !out.polished {
                            r.osqp_unpolished += 1;
                        }
                        r.osqp.compare(&qp, x, osqp.x(), m, fast);
                    } else {
                        r.osqp.unsolved += 1;
                        match out.status {
                            OsqpStatus::SolvedInaccurate => r.osqp_inaccurate_or_capped[0] += 1,
                            OsqpStatus::MaxIterations => r.osqp_inaccurate_or_capped[1] += 1,
                            _ => {}
                        }
                    }
                }
            }
        }
    }
    r.counters = timed.pcac().counts_of();
    if timed.u.iter().any(|v| !v.is_finite()) {
        return Err(format!("{}: the input is not finite", w.slug()));
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The truss workload runs a real closed loop: its QPs are solved (few fallbacks), the
    /// inputs reach ±10 N, neither clarabel's nor OSQP's point is better than the dense
    /// solver's where their first moves differ by more than 10⁻⁶, OSQP is set up once, the
    /// reference copy replays the timed one exactly and the pieces are the step.
    #[test]
    fn the_truss_workload_solves_its_qps_and_no_anchor_is_better() {
        let w = Workload::Truss;
        let r = measure(w, w.default_warmup(), 400, Anchors::BOTH).unwrap();
        check_common(&r, 400);
        assert_eq!(
            r.counters.fast_path, 0,
            "the fast path does not pay at the truss's size"
        );
        assert!(r.active.max() > 0);
        assert!(r.saturated > 0, "the inputs never reach ±10 N");
    }

    /// The arm workload builds from the scenario files (plant of `linear.toml`, the
    /// `sampling-arm` controller of `pcac.toml` through the service's configuration),
    /// times only contact samples, and on its first contact steps the dense solver's first
    /// move agrees with clarabel's and OSQP's (or their points are not better), the
    /// reference copy replays the timed one and the pieces are PCAC's step.
    #[test]
    fn the_arm_workload_runs_the_chapter_7_loop_and_agrees_with_the_anchors() {
        let (sim, params, counts) = arm_loop().unwrap();
        assert_eq!(
            (sim.n_y(), sim.n_r(), sim.n_u()),
            (7, 1, 2),
            "the arm's wire contract"
        );
        assert_eq!(counts.n_y, 7);
        assert!(params.pcac.is_some());
        let r = measure(Workload::Arm, 0, 300, Anchors::BOTH).unwrap();
        check_common(&r, 300);
        assert!(r.move_bounds);
        // PCAC stepped only in the contact samples: the 300 timed ones; the unconstrained
        // fast path solved most of them.
        assert_eq!(r.counters.steps, 300);
        assert!(
            r.counters.fast_path >= 250,
            "fast path at {} steps",
            r.counters.fast_path
        );
    }

    /// On the QPs of the arm workload's first 40 contact steps (`n = 100` moves, 200
    /// move-bound rows), OSQP at 10⁻⁹ with polishing, set up on the first and updated
    /// after, agrees with the dense solver to its tolerance: where it reports solved (most
    /// steps), its point is feasible and its objective within 10⁻⁹ relative of ours and
    /// not below it beyond round-off (ours is the minimizer); and once the touch-down's
    /// transient is over (contact step 30) the two `U` agree to 10⁻⁸. (At the touch-down,
    /// `|J| ≈ 10¹³`, and the first moves may differ by several units at the same
    /// objective to 10⁻¹¹ relative: flat directions of `H`.)
    #[test]
    fn osqp_agrees_with_the_dense_solver_on_the_arm_workloads_qps() {
        let mut arm = ClosedLoop::new(Workload::Arm).unwrap();
        let mut osqp = OsqpAnchor::new(1e-9);
        let (mut seq, mut contact, mut solved, mut with_rows) = (0u64, 0, 0, 0);
        while contact < 40 {
            let counts = arm.sample().unwrap();
            arm.step(seq);
            arm.advance().unwrap();
            seq += 1;
            if !counts {
                continue;
            }
            contact += 1;
            let pcac = arm.pcac_mut();
            if pcac.last_qp_status() != Some(QpStatus::Solved) {
                continue;
            }
            // Ours: the fast path's minimizer where the step took it, else the solver's.
            let ours = pcac.planned_inputs().to_vec();
            let ours = &ours[..];
            let qp = pcac.condensed_problem().unwrap();
            assert_eq!((qp.f.len(), qp.h.len()), (100, 200));
            let out = osqp.solve(&qp).unwrap();
            if out.status != OsqpStatus::Solved {
                continue;
            }
            solved += 1;
            let n = ours.len();
            let j = |u: &[f64]| -> f64 {
                (0..n)
                    .map(|i| {
                        let hu: f64 = (0..n).map(|k| qp.hess[i * n + k] * u[k]).sum();
                        u[i] * (0.5 * hu + qp.f[i])
                    })
                    .sum()
            };
            let (j_ours, j_osqp) = (j(ours), j(osqp.x()));
            let gap = (j_osqp - j_ours) / (1.0 + j_ours.abs());
            assert!(
                (-1e-12..=1e-9).contains(&gap),
                "contact step {contact}: relative objective gap {gap:e}"
            );
            assert!(violation(&qp, osqp.x()) <= 1e-9, "contact step {contact}");
            if contact >= 30 {
                let d = ours
                    .iter()
                    .zip(osqp.x())
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(d < 1e-8, "contact step {contact}: |U − U_osqp| = {d:e}");
            }
            let active_rows =
                qp.g.chunks(n)
                    .zip(qp.h)
                    .filter(|(row, h)| {
                        let gx: f64 = row.iter().zip(ours).map(|(a, b)| a * b).sum();
                        (gx - *h).abs() < 1e-9
                    })
                    .count();
            with_rows += usize::from(active_rows > 0);
        }
        assert!(solved >= 30, "OSQP solved {solved} of 40");
        assert_eq!(osqp.setups(), 1);
        assert!(with_rows > 0, "no move bound was active on these steps");
    }

    fn check_common(r: &PcacCost, steps: u64) {
        let name = r.workload.slug();
        assert_eq!(r.step.len() + r.cold.len(), steps, "{name}");
        assert_eq!(r.replica_mismatches, 0, "{name}");
        assert!(
            r.fallback_steps * 100 <= steps,
            "{name}: {} fallbacks in {steps} steps",
            r.fallback_steps
        );
        for (anchor, a) in [("clarabel", &r.clarabel), ("osqp", &r.osqp)] {
            assert_eq!(a.time.len(), steps, "{name} {anchor}");
            // clarabel solves 9 in 10 of these QPs to 1e-8; OSQP's ADMM does not on a
            // quarter of the truss's (SolvedInaccurate or the iteration cap).
            let share = if anchor == "clarabel" { 9 } else { 6 };
            assert!(
                a.compared * 10 >= steps * share,
                "{name} {anchor}: {} compared",
                a.compared
            );
            // Where the anchor (tol 1e-8) differs by more than 1e-6, its point is feasible
            // and uphill from ours: ours is the minimizer (ρ ≥ 1, with a margin for
            // round-off).
            assert!(
                a.max_first_move_diff <= AGREE_TOL || a.optimality_ratio >= 0.9,
                "{name} {anchor}: differs by {} and ρ = {}",
                a.max_first_move_diff,
                a.optimality_ratio
            );
        }
        assert!(r.clarabel.violation <= 1e-7, "{name}: clarabel's violation");
        // OSQP's tolerance is relative to the data's scale (‖H U‖ reaches 10⁷ here).
        assert!(
            r.osqp.violation <= 1e-6,
            "{name}: OSQP's violation {}",
            r.osqp.violation
        );
        // One size and sparsity per workload: OSQP is set up once and updated after.
        assert_eq!(r.osqp_setups, 1, "{name}");
        assert!(
            r.pieces_diff <= 1e-12,
            "{name}: pieces differ by {}",
            r.pieces_diff
        );
        // Identification and prediction at every step; the fast path where PCAC's setting
        // chooses it (the arm, not the truss); without it, condensing and the QP at every
        // step (with it, only where a constraint is active, which a short run may miss).
        let fast = r.counters.fast_path > 0;
        assert!(!r.pieces[0].is_empty() && !r.pieces[1].is_empty(), "{name}");
        assert_eq!(!r.pieces[4].is_empty(), fast, "{name}");
        if !fast {
            assert!(!r.pieces[2].is_empty() && !r.pieces[3].is_empty(), "{name}");
        }
        assert!(r.max_abs_u.is_finite() && r.max_abs_u > 0.0, "{name}");
    }
}
