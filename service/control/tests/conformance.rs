//! Controller conformance: the properties every [`Controller`] kind must have, checked on
//! every kind by the same generic code (as iceoryx2's conformance tests are generic over
//! the service type).
//!
//! Each kind is a [`Kind`]: a constructor `fn() -> Box<dyn Controller>` with small,
//! realistic parameters and the output limits it was given (if any). The
//! [`conformance!`] macro instantiates every property as one test per kind, in a module
//! named after the kind, so the test names read
//! `rcac_rls::reset_returns_to_the_initial_state`. **Adding a kind is one line** in the
//! `conformance!` invocation at the end of this file, next to its constructor:
//!
//! ```text
//! sampling_arm: Kind { build: sampling_arm, limits: ARM_LIMITS, observe: Observe::AsStep, ahead: false },
//! ```
//!
//! A kind whose channels are not the loop's single-output ones reads the plant's output
//! on every `y` channel (the sampling-arm controller, `n_y = 7`, `n_u = 2`, switching
//! between its joint hold and its contact law with the command).
//!
//! The properties, on a closed loop with a small stable plant ([`Plant`]):
//!
//! - **Bad measurements**: non-finite (NaN, ±∞) and huge (±10³⁰⁰, 10¹⁵⁰) values in `y`,
//!   `z` and `r` leave `u` finite (and within the limits when limits are set), and the
//!   controller keeps giving such inputs on good data afterwards.
//! - **Reset**: after steps on other data and [`Controller::reset`], a replayed input
//!   sequence gives the outputs (and status bits) of a freshly built controller, bit for
//!   bit.
//! - **Observe**: [`Controller::observe`] takes in a sample whose actuation will never
//!   be applied (the plant holds its previous input); both runs are told at `k + 1`
//!   (through [`StepInput::u_applied`]) that the plant held the input of `k − 1`. A kind
//!   declares what its `observe` promises ([`Observe`]): either it equals stepping the
//!   sample and discarding the output, bit for bit (the trait's default), or it records
//!   the sample's data but may skip adaptation for it (RCAC, so that a loop that is behind
//!   catches up sooner), and then a different observed measurement must change the
//!   inputs that follow.
//! - **No allocation**: after [`Controller::prepare_thread`] and a warm-up, 1,000 steps
//!   (with an observed sample every 100 and the internals read every step) make no heap
//!   allocation on the stepping thread, counted by this file's global allocator.
//!
//! And for the ahead form ([`control::Ahead`]), which a kind declares it answers
//! (`ahead: true`; [`Controller::ahead`] must then be `Some`, else `None`), on the same
//! loop run ahead (`ready` gives the input applied for sample `k`, `advance` takes the
//! sample in with it):
//!
//! - **No allocation**: 1,000 cycles of `ready`, `advance` (with `adapt = false` every
//!   100th), a plan of 64 rows and the internals allocate nothing after a warm-up.
//! - **Bad measurements**: the values above leave the ready input and every plan row
//!   finite and within the limits, and the controller goes on afterwards.
//! - **Reset**: after [`Controller::reset`] or [`Controller::restart_data`] the ready
//!   input is the start-up input of a freshly built controller, and after a reset a
//!   replayed sequence gives its ready inputs, statuses and plans bit for bit.
//!
//! The properties of the ahead form pass trivially for a kind that does not answer ahead.

#![allow(clippy::needless_range_loop)]

use control::arm::controller::{ArmController, ArmControllerParams, JointHold};
use control::forgetting::ForgettingRule;
use control::mpc::condense::{MoveBounds, Weight};
use control::mpc::fast_path::FastPathMode;
use control::mrac::{Appc, AppcParams, RcMrac, RcMracParams};
use control::pcac::{OutputFeedback, Pcac, PcacParams, PcacTiming};
use control::rcac::{Rcac, RcacParams, RcacUpdate};
use control::target::{TargetForm, TargetModel};
use control::{
    Controller, ControllerInput, Dimensions, LtiController, MAX_INTERNALS, OutputLimits, StepInput,
};
use nalgebra::DMatrix;

mod arm_support;
mod counting_alloc;
use counting_alloc::allocations_in;

#[test]
fn the_counting_allocator_counts_an_allocation_on_this_thread() {
    let n = allocations_in(|| {
        let v = std::hint::black_box(vec![1.0_f64; 8]);
        drop(v);
    });
    assert_eq!(n, 1);
}

// ---------------------------------------------------------------------------------------
// The kinds.

/// One controller kind under test.
struct Kind {
    /// A freshly built controller (same parameters every call).
    build: fn() -> Box<dyn Controller>,
    /// The output limits it was built with (`min`, `max` per input), if any.
    limits: Option<(&'static [f64], &'static [f64])>,
    /// What its `observe` promises.
    observe: Observe,
    /// Whether it answers ahead ([`Controller::ahead`] is `Some`).
    ahead: bool,
}

/// What a kind's [`Controller::observe`] promises beyond the trait's minimum.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Observe {
    /// Observing sample `k` equals stepping it and discarding the output (the trait's
    /// default; also PCAC, whose identification learns from the observed sample).
    AsStep,
    /// The sample enters the controller's data (regressor, history) but adaptation may
    /// be skipped for it, so that a loop that is behind catches up sooner (RCAC), or the
    /// input it would plan from it is not planned (PCAC in the next-step timing, whose
    /// `observe` holds the input).
    RecordsData,
}

const TS: f64 = 0.01;
const U_MAX: f64 = 1.5;

fn limits() -> Option<OutputLimits> {
    Some(OutputLimits::symmetric(U_MAX, 1))
}

const LIMITS: Option<(&[f64], &[f64])> = Some((&[-U_MAX], &[U_MAX]));

/// A second-order LTI compensator on `e = r − y`, saturated.
fn lti() -> Box<dyn Controller> {
    let c = LtiController::new(
        DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.0, 0.3]),
        DMatrix::from_row_slice(2, 1, &[1.0, 0.5]),
        DMatrix::from_row_slice(1, 2, &[0.2, -0.1]),
        DMatrix::from_element(1, 1, 0.3),
        ControllerInput::Error,
        Dimensions::new(1, 1, 1, 1),
        limits(),
    )
    .expect("valid LTI parameters");
    Box::new(c)
}

/// The compensator of [`lti`] without its feedthrough (`D = 0`), which answers ahead.
fn lti_strictly_proper() -> Box<dyn Controller> {
    let c = LtiController::new(
        DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.0, 0.3]),
        DMatrix::from_row_slice(2, 1, &[1.0, 0.5]),
        DMatrix::from_row_slice(1, 2, &[0.2, -0.1]),
        DMatrix::zeros(1, 1),
        ControllerInput::Error,
        Dimensions::new(1, 1, 1, 1),
        limits(),
    )
    .expect("valid LTI parameters");
    Box::new(c)
}

/// White-noise excitation of σ = 1 against ±1.5 limits.
#[cfg(feature = "excitation")]
fn excitation() -> Box<dyn Controller> {
    let c = control::ExcitationSource::new(Dimensions::new(1, 1, 0, 1), vec![1.0], 42, limits())
        .expect("valid excitation parameters");
    Box::new(c)
}

/// SISO RCAC: `n_c = 4`, target `G_f = 0.1 z^{−1}` (the plant's first Markov
/// parameter), `R_z = 1`, `R_u = 0` (the defaults), with `update` and `limits`.
fn rcac(update: RcacUpdate, limits: Option<OutputLimits>) -> Box<dyn Controller> {
    let target = TargetModel {
        sample_period: TS,
        outputs: 1,
        inputs: 1,
        beta: 1.0,
        source: "conformance".into(),
        form: TargetForm::Markov(vec![DMatrix::zeros(1, 1), DMatrix::from_element(1, 1, 0.1)]),
    };
    let counts = Dimensions::new(1, 1, 0, 1);
    let params = RcacParams::builder(target, 4, update)
        .limits(limits)
        .build(counts)
        .expect("valid RCAC parameters");
    Box::new(Rcac::new(&params, counts).expect("valid RCAC parameters"))
}

/// RCAC with RLS (F-test forgetting), saturated.
fn rcac_rls() -> Box<dyn Controller> {
    let update = RcacUpdate::Rls {
        p0: 10.0,
        rule: ForgettingRule::FTest {
            tau_n: 10,
            tau_d: 100,
            eta: 0.1,
            alpha: 0.001,
        },
        trace_limit: 1e6,
    };
    rcac(update, limits())
}

/// RCAC with the gradient update (`μ_Exp`, α = 0.5), without limits.
fn rcac_gradient() -> Box<dyn Controller> {
    rcac(RcacUpdate::gradient(0.5), None)
}

/// SISO PCAC: `n̂ = 4`, F-test forgetting, horizon 10, input and move bounds, tracking
/// the command; same-step timing.
fn pcac() -> Box<dyn Controller> {
    pcac_timed(PcacTiming::SameStep)
}

/// [`pcac`] in the dissertation's next-step timing, which answers ahead.
fn pcac_next_step() -> Box<dyn Controller> {
    pcac_timed(PcacTiming::NextStep)
}

/// [`pcac`] with the given timing.
fn pcac_timed(timing: PcacTiming) -> Box<dyn Controller> {
    let params = pcac_params(timing);
    let c = Pcac::new(&params, Dimensions::new(1, 1, 1, 1)).expect("valid PCAC parameters");
    Box::new(c)
}

/// The parameters of [`pcac_timed`].
fn pcac_params(timing: PcacTiming) -> PcacParams {
    PcacParams::builder(4, 1, 1, 100.0, 10)
        .theta0(vec![1e-10; 8])
        .forgetting(ForgettingRule::FTest {
            tau_n: 20,
            tau_d: 200,
            eta: 0.1,
            alpha: 0.001,
        })
        .trace_limit(f64::INFINITY)
        .q(Weight::Scalar(1e2))
        .r(Weight::Scalar(1.0))
        .input_bounds(vec![-U_MAX], vec![U_MAX])
        .move_bounds(Some(MoveBounds::symmetric(0.3, 1)))
        .timing(timing)
        .build()
}

/// [`pcac`] with the unconstrained fast path at every step (`control::mpc::fast_path`;
/// at this size the setting's default would not take it): steps whose Riccati minimizer
/// meets the bounds skip condensing and the QP, the others fall back to them.
fn pcac_fast_path() -> Box<dyn Controller> {
    pcac_fast_path_timed(PcacTiming::SameStep)
}

/// [`pcac_fast_path`] in the next-step timing (the ahead form's plan is the fast path's
/// `U` where it was taken).
fn pcac_next_step_fast_path() -> Box<dyn Controller> {
    pcac_fast_path_timed(PcacTiming::NextStep)
}

fn pcac_fast_path_timed(timing: PcacTiming) -> Box<dyn Controller> {
    let mut params = pcac_params(timing);
    params.fast_path = FastPathMode::Always;
    Box::new(Pcac::new(&params, Dimensions::new(1, 1, 1, 1)).expect("valid PCAC parameters"))
}

/// [`pcac`] augmenting the fixed output feedback `K̄ = −0.5` (7.53)–(7.57): the plant's
/// input is `−0.5 y + u`.
fn pcac_augmented() -> Box<dyn Controller> {
    let mut params = pcac_params(PcacTiming::SameStep);
    params.augmentation = Some(OutputFeedback { gain: vec![-0.5] });
    Box::new(Pcac::new(&params, Dimensions::new(1, 1, 1, 1)).expect("valid PCAC parameters"))
}

/// The sampling-arm controller's torque limits in these tests (N m).
const ARM_TAU_MAX: f64 = 1.5;
const ARM_LIMITS: Option<(&[f64], &[f64])> =
    Some((&[-ARM_TAU_MAX, -ARM_TAU_MAX], &[ARM_TAU_MAX, ARM_TAU_MAX]));

/// The sampling-arm controller (Algorithm 3) on the loop's plant: every `y` channel is
/// the plant's output, read as `[θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`, and the command that
/// steps between 0 and 0.5 every 100 samples switches it between the joint hold
/// (`r = 0`) and the contact law (`F_d = 0.5`), so that every property sees both modes,
/// the phase changes and (near `θ_2 = 0`) samples without a linearization. Small gains
/// and torque limits of ±1.5 keep the loop bounded. `pcac`: with the augmentation of
/// §7.3's size (`p = 5`, `m = 2`, `ℓ = 50`, 100 decision variables). With five equal
/// outputs PCAC's identified model is degenerate here and most of its QPs end in the
/// numerical-error fallback; `tests/arm_step.rs` counts the allocations of the solved
/// path on the simulated spacecraft.
fn arm_params(pcac: bool) -> ArmControllerParams {
    let pcac = pcac.then(arm_support::chapter_pcac);
    ArmControllerParams {
        hold: JointHold {
            kp: [0.5, 0.5],
            kd: [0.2, 0.2],
        },
        pcac,
        limits: Some(OutputLimits::symmetric(ARM_TAU_MAX, 2)),
        ..ArmControllerParams::robust_only([-0.3, 0.0, 0.0, 0.0, -0.3, 0.01])
    }
}

/// The robust sampling-arm controller (no PCAC).
fn sampling_arm() -> Box<dyn Controller> {
    Box::new(ArmController::new(&arm_params(false), arm_counts()).expect("valid arm parameters"))
}

/// The sampling-arm controller with the PCAC augmentation.
fn sampling_arm_pcac() -> Box<dyn Controller> {
    Box::new(ArmController::new(&arm_params(true), arm_counts()).expect("valid arm parameters"))
}

/// The arm rig's channels: `n_y = 7`, `n_z = 1`, `n_r = 1`, `n_u = 2`.
fn arm_counts() -> Dimensions {
    Dimensions::new(7, 1, 1, 2)
}

/// APPC (§4.2) for the loop's plant (`n = 2`): `D_m = (1 − 0.5 q⁻¹)²`,
/// `N_m = 0.25 q⁻¹`, `H = 1 − 0.25 q⁻²`, `R_θ = 10⁻³ I`, F-test forgetting, saturated.
fn appc() -> Box<dyn Controller> {
    let mut p = AppcParams::new(
        2,
        vec![1.0, -1.0, 0.25],
        vec![0.0, 0.25],
        vec![1.0, 0.0, -0.25],
    );
    p.r_theta = vec![1e-3; AppcParams::theta_len(2)];
    p.forgetting = ForgettingRule::FTest {
        tau_n: 10,
        tau_d: 100,
        eta: 0.1,
        alpha: 0.001,
    };
    p.trace_limit = 1e9;
    p.limits = limits();
    Box::new(Appc::new(&p, Dimensions::new(1, 1, 1, 1)).expect("valid APPC parameters"))
}

/// RC-MRAC (§4.3) for the loop's plant (`n = 2`, `n_r = 1`, `N_1 = 0.1`, `N_u = 1`,
/// `n_s = 0`): `F = 1 + 0.5 q⁻¹`, `D_m = (1 − 0.5 q⁻¹)²`, `N_m = 0.25 q⁻¹`, `λ = 1`,
/// without limits.
fn rc_mrac() -> Box<dyn Controller> {
    let p = RcMracParams::new(
        2,
        1,
        0.1,
        vec![1.0],
        0,
        vec![1.0, 0.5],
        vec![1.0, -1.0, 0.25],
        vec![0.0, 0.25],
    );
    Box::new(RcMrac::new(&p, Dimensions::new(1, 1, 1, 1)).expect("valid RC-MRAC parameters"))
}

// ---------------------------------------------------------------------------------------
// The loop.

/// A stable plant per output, `y_{k+1} = 1.6 y_k − 0.7 y_{k−1} + 0.1 Σ_j u_{j,k} + d_k`,
/// with a harmonic disturbance and a little deterministic noise; `z = y`, and a command
/// that steps between 0 and 0.5 every 100 samples. Never allocates after [`Plant::new`].
struct Plant {
    counts: Dimensions,
    y: Vec<f64>,
    y_prev: Vec<f64>,
    z: Vec<f64>,
    r: Vec<f64>,
    k: u64,
    noise: u64,
    phase: f64,
}

impl Plant {
    fn new(counts: Dimensions, seed: u64) -> Self {
        Self {
            counts,
            y: vec![0.0; counts.n_y],
            y_prev: vec![0.0; counts.n_y],
            z: vec![0.0; counts.n_z],
            r: vec![0.0; counts.n_r],
            k: 0,
            noise: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            phase: seed as f64,
        }
    }

    /// Uniform in [−1, 1) (xorshift64).
    fn noise(&mut self) -> f64 {
        self.noise ^= self.noise << 13;
        self.noise ^= self.noise >> 7;
        self.noise ^= self.noise << 17;
        (self.noise >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The signals of the current sample.
    fn input(&mut self) -> StepInput<'_> {
        for (i, z) in self.z.iter_mut().enumerate() {
            *z = self.y[i % self.counts.n_y];
        }
        let command = if (self.k / 100) % 2 == 1 { 0.5 } else { 0.0 };
        self.r.fill(command);
        on_time(self.k, &self.y, &self.z, &self.r)
    }

    /// Applies `u` over the period and moves to the next sample.
    fn advance(&mut self, u: &[f64]) {
        let push: f64 = u.iter().sum::<f64>() * 0.1;
        let d = 0.05 * (0.3 * self.k as f64 + self.phase).sin();
        for i in 0..self.y.len() {
            let e = 1e-3 * self.noise();
            let next = 1.6 * self.y[i] - 0.7 * self.y_prev[i] + push + d + e;
            self.y_prev[i] = self.y[i];
            self.y[i] = next;
        }
        self.k += 1;
    }
}

/// The signals of one recorded sample, for replaying it.
#[derive(Clone, Debug)]
struct Sample {
    seq: u64,
    y: Vec<f64>,
    z: Vec<f64>,
    r: Vec<f64>,
}

impl Sample {
    fn input(&self) -> StepInput<'_> {
        on_time(self.seq, &self.y, &self.z, &self.r)
    }
}

/// Runs `steps` closed-loop samples and returns their signals.
fn closed_loop(c: &mut dyn Controller, plant: &mut Plant, steps: usize) -> Vec<Sample> {
    let n_u = c.counts().n_u;
    let mut samples = Vec::new();
    let mut u = vec![0.0; n_u];
    for _ in 0..steps {
        let input = plant.input();
        samples.push(Sample {
            seq: input.seq,
            y: input.y.to_vec(),
            z: input.z.to_vec(),
            r: input.r.to_vec(),
        });
        c.step(&input, &mut u);
        plant.advance(&u);
    }
    samples
}

/// The bad measurement values the properties feed a controller.
const BAD_VALUES: [f64; 6] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e300,
    -1e300,
    1e150,
];

/// The signals `(y, z, r)` of a sample.
type Signals = (Vec<f64>, Vec<f64>, Vec<f64>);

/// `(y, z, r)` with the bad value `v` in every signal (`everywhere`), or in `y` only with
/// good `z` and `r`.
fn bad_signals(counts: Dimensions, v: f64, everywhere: bool) -> Signals {
    if everywhere {
        (
            vec![v; counts.n_y],
            vec![v; counts.n_z],
            vec![v; counts.n_r],
        )
    } else {
        (
            vec![v; counts.n_y],
            vec![0.1; counts.n_z],
            vec![0.0; counts.n_r],
        )
    }
}

/// Sample `i` of the burst after the bad values: 20 NaN samples, then alternating
/// `±10³⁰⁰`, in `y` and `z` (`r = 0`); returns the value and `(y, z, r)`.
fn burst_sample(counts: Dimensions, i: usize) -> (f64, Signals) {
    let v = if i < 20 {
        f64::NAN
    } else if i.is_multiple_of(2) {
        1e300
    } else {
        -1e300
    };
    let signals = (
        vec![v; counts.n_y],
        vec![v; counts.n_z],
        vec![0.0; counts.n_r],
    );
    (v, signals)
}

/// The signals of sample `seq`, answered on time: no sample lost, no applied input
/// reported.
fn on_time<'a>(seq: u64, y: &'a [f64], z: &'a [f64], r: &'a [f64]) -> StepInput<'a> {
    StepInput {
        seq,
        y,
        z,
        r,
        u_applied: None,
        lost: 0,
    }
}

/// `u` is finite and, when the kind has limits, within them.
fn assert_admissible(kind: &Kind, u: &[f64], what: &str) {
    assert!(
        u.iter().all(|v| v.is_finite()),
        "{what}: u = {u:?} is not finite"
    );
    if let Some((lo, hi)) = kind.limits {
        for (j, v) in u.iter().enumerate() {
            assert!(
                lo[j] <= *v && *v <= hi[j],
                "{what}: u[{j}] = {v} is outside [{}, {}]",
                lo[j],
                hi[j]
            );
        }
    }
}

/// Bit patterns, so that comparisons are exact and NaN-safe.
fn bits(u: &[f64]) -> Vec<u64> {
    u.iter().map(|v| v.to_bits()).collect()
}

// ---------------------------------------------------------------------------------------
// The properties.

/// Non-finite and huge measurements leave `u` finite (and within the limits), and the
/// controller keeps giving admissible inputs on good data afterwards.
fn bad_measurements_leave_u_finite(kind: &Kind) {
    let mut c = (kind.build)();
    let counts = c.counts();
    let mut plant = Plant::new(counts, 1);
    closed_loop(c.as_mut(), &mut plant, 150);
    let mut u = vec![0.0; counts.n_u];
    let bad = BAD_VALUES;
    let mut seq = plant.k;
    // Each bad value alone, in every signal at once, then in `y` only with good `z` and `r`.
    for (round, &v) in bad.iter().chain(&bad).enumerate() {
        let (y, z, r) = bad_signals(counts, v, round < bad.len());
        let input = on_time(seq, &y, &z, &r);
        c.step(&input, &mut u);
        assert_admissible(kind, &u, &format!("after y = {v}"));
        seq += 1;
    }
    // A burst of NaN samples, then alternating huge values.
    for i in 0..40 {
        let (v, (y, z, r)) = burst_sample(counts, i);
        c.step(&on_time(seq, &y, &z, &r), &mut u);
        assert_admissible(kind, &u, &format!("burst sample {i} (y = {v})"));
        seq += 1;
    }
    // Good data again: the loop goes on with admissible inputs.
    plant.k = seq;
    for i in 0..300 {
        let input = plant.input();
        c.step(&input, &mut u);
        assert_admissible(kind, &u, &format!("good sample {i} after the bad ones"));
        plant.advance(&u);
    }
}

/// After steps on other data and `reset`, a replayed sequence gives the outputs of a
/// freshly built controller, bit for bit.
fn reset_returns_to_the_initial_state(kind: &Kind) {
    let mut fresh = (kind.build)();
    let counts = fresh.counts();
    let samples = closed_loop(fresh.as_mut(), &mut Plant::new(counts, 3), 300);
    let replay = |c: &mut dyn Controller| -> Vec<(Vec<u64>, u32)> {
        let mut u = vec![0.0; counts.n_u];
        samples
            .iter()
            .map(|s| {
                let st = c.step(&s.input(), &mut u);
                (bits(&u), st)
            })
            .collect()
    };
    let want = replay((kind.build)().as_mut());

    let mut used = (kind.build)();
    used.prepare_thread();
    // Other data, with a bad sample, a lost sample, an observed one and a reported input.
    let mut plant = Plant::new(counts, 5);
    closed_loop(used.as_mut(), &mut plant, 200);
    let mut u = vec![0.0; counts.n_u];
    let (y, z, r) = (
        vec![f64::NAN; counts.n_y],
        vec![0.2; counts.n_z],
        vec![0.5; counts.n_r],
    );
    used.step(&on_time(200, &y, &z, &r), &mut u);
    let ua = vec![0.7; counts.n_u];
    let y = vec![0.3; counts.n_y];
    used.observe(
        &StepInput {
            u_applied: Some(&ua),
            lost: 1,
            ..on_time(202, &y, &z, &r)
        },
        &mut u,
    );
    closed_loop(used.as_mut(), &mut plant, 100);
    used.reset();
    let got = replay(used.as_mut());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(
            g, w,
            "sample {k}: (u bits, status) after reset differ from a fresh controller"
        );
    }
}

/// Observing late samples keeps the controller aligned with the plant. Both runs hear at
/// `k + 1` that the plant held the input of `k − 1`. For [`Observe::AsStep`] observing
/// sample `k` and stepping on equals stepping every sample and discarding the output of
/// `k`, bit for bit. For [`Observe::RecordsData`] the observed sample's data must be
/// taken in: observing a different `y_k` changes the inputs that follow, and they stay
/// finite.
fn observe_keeps_state_aligned(kind: &Kind) {
    let mut reference = (kind.build)();
    let counts = reference.counts();
    let samples = closed_loop(reference.as_mut(), &mut Plant::new(counts, 7), 400);
    let late = [150_usize, 151, 260];
    // `how`: 0 observe, 1 step and discard, 2 observe a perturbed measurement.
    let run = |how: u8| -> Vec<(usize, Vec<u64>)> {
        let mut c = (kind.build)();
        let mut u = vec![0.0; counts.n_u];
        let mut held = vec![0.0; counts.n_u];
        let mut out = Vec::new();
        for (k, s) in samples.iter().enumerate() {
            let mut input = s.input();
            if k > 0 && late.contains(&(k - 1)) {
                // The plant held the input of the last answered sample.
                input.u_applied = Some(&held);
            }
            if late.contains(&k) {
                let perturbed: Vec<f64> = input.y.iter().map(|v| v + 0.25).collect();
                match how {
                    0 => c.observe(&input, &mut u),
                    1 => {
                        let mut discarded = vec![0.0; counts.n_u];
                        c.step(&input, &mut discarded);
                    }
                    _ => {
                        input.y = &perturbed;
                        c.observe(&input, &mut u);
                    }
                }
                continue;
            }
            c.step(&input, &mut u);
            held.copy_from_slice(&u);
            out.push((k, bits(&u)));
        }
        out
    };
    let observed = run(0);
    for (_, b) in &observed {
        assert!(b.iter().all(|v| f64::from_bits(*v).is_finite()));
    }
    match kind.observe {
        Observe::AsStep => {
            let stepped = run(1);
            for ((k, a), (_, b)) in observed.iter().zip(&stepped) {
                assert_eq!(
                    a, b,
                    "sample {k}: observing the late samples {late:?} differs from stepping them"
                );
            }
        }
        Observe::RecordsData => {
            let perturbed = run(2);
            let first_late = late[0];
            let changed = observed
                .iter()
                .zip(&perturbed)
                .any(|((k, a), (_, b))| *k > first_late && a != b);
            assert!(
                changed,
                "observing a different measurement at {late:?} changed nothing that followed: \
                 the observed samples did not enter the controller's data"
            );
        }
    }
}

/// 1,000 steady-state steps (with observed samples and internals read) allocate nothing.
fn steady_state_steps_do_not_allocate(kind: &Kind) {
    let mut c = (kind.build)();
    let counts = c.counts();
    c.prepare_thread();
    let mut plant = Plant::new(counts, 11);
    closed_loop(c.as_mut(), &mut plant, 300);
    let mut u = vec![0.0; counts.n_u];
    let mut internals = [0.0; MAX_INTERNALS];
    let mut finite = true;
    let n = allocations_in(|| {
        for i in 0..1000 {
            let input = plant.input();
            if i % 100 == 99 {
                c.observe(&input, &mut u);
            } else {
                c.step(&input, &mut u);
            }
            let _ = c.internals(&mut internals);
            finite &= u.iter().all(|v| v.is_finite());
            plant.advance(&u);
        }
    });
    assert_eq!(
        n,
        0,
        "{} allocated {n} times in 1,000 steady-state steps",
        c.kind()
    );
    assert!(finite);
}

// ---------------------------------------------------------------------------------------
// The ahead form.

/// Plan rows asked for in every cycle (the contract's capacity).
const PLAN_ROWS: usize = 64;

/// One ahead cycle on sample `input`: the ready input `u` is what the plant applies for
/// the sample, then the controller advances with it and plans; returns the status of the
/// ready input, the status `advance` returned and the number of plan rows.
fn ahead_cycle(
    c: &mut dyn Controller,
    input: &StepInput<'_>,
    adapt: bool,
    u: &mut [f64],
    plan: &mut [f64],
) -> (u32, u32, usize) {
    let a = c.ahead().expect("the kind answers ahead");
    let ready = a.ready(u);
    let advanced = a.advance(input, u, adapt);
    let rows = a.plan(plan);
    (ready, advanced, rows)
}

/// `ahead()` is `Some` exactly when the kind declares that it answers ahead, and then the
/// ready input of a fresh controller (the start-up input) is admissible and the plan's
/// source is one line.
fn ahead_is_given_exactly_when_the_kind_answers_ahead(kind: &Kind) {
    let mut c = (kind.build)();
    let n_u = c.counts().n_u;
    let kind_name = c.kind();
    match c.ahead() {
        None => assert!(!kind.ahead, "{kind_name}: declared to answer ahead"),
        Some(a) => {
            assert!(kind.ahead, "{kind_name}: answers ahead, declared not to");
            let mut u = vec![f64::NAN; n_u];
            a.ready(&mut u);
            assert_admissible(kind, &u, "the start-up input");
            let source = a.plan_source();
            assert!(!source.is_empty() && !source.contains('\n'), "{source:?}");
        }
    }
}

/// 1,000 ahead cycles (ready, advance with `adapt = false` every 100th, a plan of 64 rows,
/// the internals) after a warm-up of 300 allocate nothing.
fn ahead_cycles_do_not_allocate(kind: &Kind) {
    let mut c = (kind.build)();
    if c.ahead().is_none() {
        return;
    }
    let counts = c.counts();
    c.prepare_thread();
    let mut plant = Plant::new(counts, 11);
    let mut u = vec![0.0; counts.n_u];
    let mut plan = vec![0.0; PLAN_ROWS * counts.n_u];
    let mut internals = [0.0; MAX_INTERNALS];
    for _ in 0..300 {
        let input = plant.input();
        ahead_cycle(c.as_mut(), &input, true, &mut u, &mut plan);
        plant.advance(&u);
    }
    let mut finite = true;
    let n = allocations_in(|| {
        for i in 0..1000 {
            let input = plant.input();
            let (_, _, rows) = ahead_cycle(c.as_mut(), &input, i % 100 != 99, &mut u, &mut plan);
            let _ = c.internals(&mut internals);
            finite &= u.iter().all(|v| v.is_finite());
            finite &= plan[..rows * counts.n_u].iter().all(|v| v.is_finite());
            plant.advance(&u);
        }
    });
    assert_eq!(
        n,
        0,
        "{} allocated {n} times in 1,000 ahead cycles",
        c.kind()
    );
    assert!(finite);
}

/// Non-finite and huge measurements leave the ready input and the plan finite and within
/// the limits, and the controller goes on with admissible inputs on good data.
fn bad_measurements_leave_the_ready_input_and_the_plan_finite(kind: &Kind) {
    let mut c = (kind.build)();
    if c.ahead().is_none() {
        return;
    }
    let counts = c.counts();
    let mut plant = Plant::new(counts, 1);
    let mut u = vec![0.0; counts.n_u];
    let mut plan = vec![0.0; PLAN_ROWS * counts.n_u];
    for _ in 0..150 {
        let input = plant.input();
        ahead_cycle(c.as_mut(), &input, true, &mut u, &mut plan);
        plant.advance(&u);
    }
    let check = |c: &mut dyn Controller, plan: &[f64], rows: usize, what: &str| {
        let mut ready = vec![0.0; counts.n_u];
        c.ahead().unwrap().ready(&mut ready);
        assert_admissible(kind, &ready, &format!("ready after {what}"));
        assert!(rows <= PLAN_ROWS);
        for (j, row) in plan.chunks(counts.n_u).take(rows).enumerate() {
            assert_admissible(kind, row, &format!("plan row {j} after {what}"));
        }
    };
    let bad = BAD_VALUES;
    let mut seq = plant.k;
    for (round, &v) in bad.iter().chain(&bad).enumerate() {
        let (y, z, r) = bad_signals(counts, v, round < bad.len());
        let input = on_time(seq, &y, &z, &r);
        let (_, _, rows) = ahead_cycle(c.as_mut(), &input, true, &mut u, &mut plan);
        assert_admissible(kind, &u, &format!("the input applied with y = {v}"));
        check(c.as_mut(), &plan, rows, &format!("y = {v}"));
        seq += 1;
    }
    for i in 0..40 {
        let (v, (y, z, r)) = burst_sample(counts, i);
        let (_, _, rows) = ahead_cycle(
            c.as_mut(),
            &on_time(seq, &y, &z, &r),
            i % 3 != 2,
            &mut u,
            &mut plan,
        );
        check(
            c.as_mut(),
            &plan,
            rows,
            &format!("burst sample {i} (y = {v})"),
        );
        seq += 1;
    }
    plant.k = seq;
    for i in 0..300 {
        let input = plant.input();
        let (_, _, rows) = ahead_cycle(c.as_mut(), &input, true, &mut u, &mut plan);
        assert_admissible(kind, &u, &format!("good sample {i} after the bad ones"));
        check(c.as_mut(), &plan, rows, &format!("good sample {i}"));
        plant.advance(&u);
    }
}

/// After `reset` and after `restart_data` the ready input (and its status) is the start-up
/// input of a freshly built controller, and after `reset` a replayed sequence gives the
/// ready inputs, statuses and plans of a fresh controller, bit for bit.
fn reset_makes_the_ahead_form_give_the_start_up_input(kind: &Kind) {
    let mut fresh = (kind.build)();
    if fresh.ahead().is_none() {
        return;
    }
    let counts = fresh.counts();
    let mut start = vec![0.0; counts.n_u];
    let start_status = fresh.ahead().unwrap().ready(&mut start);
    let samples = closed_loop(fresh.as_mut(), &mut Plant::new(counts, 3), 300);
    let replay = |c: &mut dyn Controller| -> Vec<(Vec<u64>, u32, u32, Vec<u64>)> {
        let mut u = vec![0.0; counts.n_u];
        let mut plan = vec![0.0; 8 * counts.n_u];
        samples
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let (ready, advanced, rows) =
                    ahead_cycle(c, &s.input(), k % 50 != 49, &mut u, &mut plan);
                (bits(&u), ready, advanced, bits(&plan[..rows * counts.n_u]))
            })
            .collect()
    };
    let want = replay((kind.build)().as_mut());

    let mut used = (kind.build)();
    let mut plant = Plant::new(counts, 5);
    let mut u = vec![0.0; counts.n_u];
    let mut plan = vec![0.0; 8 * counts.n_u];
    let mut run = |c: &mut dyn Controller, plant: &mut Plant, steps: usize| {
        for _ in 0..steps {
            let input = plant.input();
            ahead_cycle(c, &input, true, &mut u, &mut plan);
            plant.advance(&u);
        }
    };
    run(used.as_mut(), &mut plant, 200);
    // A bad sample and a lost one with a reported input.
    let (y, z, r) = (
        vec![f64::NAN; counts.n_y],
        vec![0.2; counts.n_z],
        vec![0.5; counts.n_r],
    );
    let held = vec![0.7; counts.n_u];
    let a = used.ahead().unwrap();
    a.advance(&on_time(200, &y, &z, &r), &held, true);
    let y = vec![0.3; counts.n_y];
    a.advance(
        &StepInput {
            u_applied: Some(&held),
            lost: 1,
            ..on_time(202, &y, &z, &r)
        },
        &held,
        true,
    );
    run(used.as_mut(), &mut plant, 100);

    let mut ready = vec![0.0; counts.n_u];
    used.restart_data();
    let st = used.ahead().unwrap().ready(&mut ready);
    assert_eq!(
        (bits(&ready), st),
        (bits(&start), start_status),
        "the ready input after restart_data is not the start-up input"
    );
    run(used.as_mut(), &mut plant, 100);
    used.reset();
    let st = used.ahead().unwrap().ready(&mut ready);
    assert_eq!(
        (bits(&ready), st),
        (bits(&start), start_status),
        "the ready input after reset is not the start-up input"
    );
    let got = replay(used.as_mut());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(
            g, w,
            "sample {k}: (u, ready status, advance status, plan) after reset differ from a \
             fresh controller"
        );
    }
}

/// One module per kind with one test per property; `name: kind,` per line.
macro_rules! conformance {
    ($($(#[$attr:meta])* $name:ident: $kind:expr,)*) => {
        $(
            $(#[$attr])*
            mod $name {
                use super::*;

                const KIND: Kind = $kind;

                #[test]
                fn non_finite_and_huge_measurements_leave_u_finite_and_within_the_limits() {
                    bad_measurements_leave_u_finite(&KIND);
                }

                #[test]
                fn reset_returns_to_the_initial_state() {
                    super::reset_returns_to_the_initial_state(&KIND);
                }

                #[test]
                fn observing_a_late_sample_keeps_the_controller_aligned_with_the_plant() {
                    observe_keeps_state_aligned(&KIND);
                }

                #[test]
                fn steady_state_steps_do_not_allocate() {
                    super::steady_state_steps_do_not_allocate(&KIND);
                }

                #[test]
                fn ahead_is_given_exactly_when_the_kind_answers_ahead() {
                    super::ahead_is_given_exactly_when_the_kind_answers_ahead(&KIND);
                }

                #[test]
                fn ahead_cycles_do_not_allocate() {
                    super::ahead_cycles_do_not_allocate(&KIND);
                }

                #[test]
                fn bad_measurements_leave_the_ready_input_and_the_plan_finite_and_within_the_limits() {
                    bad_measurements_leave_the_ready_input_and_the_plan_finite(&KIND);
                }

                #[test]
                fn reset_makes_the_ahead_form_give_the_start_up_input() {
                    super::reset_makes_the_ahead_form_give_the_start_up_input(&KIND);
                }
            }
        )*
    };
}

conformance! {
    lti: Kind { build: lti, limits: LIMITS, observe: Observe::AsStep, ahead: false },
    lti_strictly_proper: Kind { build: lti_strictly_proper, limits: LIMITS, observe: Observe::AsStep, ahead: true },
    #[cfg(feature = "excitation")]
    excitation: Kind { build: excitation, limits: LIMITS, observe: Observe::AsStep, ahead: true },
    rcac_rls: Kind { build: rcac_rls, limits: LIMITS, observe: Observe::RecordsData, ahead: true },
    rcac_gradient: Kind { build: rcac_gradient, limits: None, observe: Observe::RecordsData, ahead: true },
    pcac: Kind { build: pcac, limits: LIMITS, observe: Observe::AsStep, ahead: false },
    pcac_next_step: Kind { build: pcac_next_step, limits: LIMITS, observe: Observe::RecordsData, ahead: true },
    pcac_augmented: Kind { build: pcac_augmented, limits: LIMITS, observe: Observe::AsStep, ahead: false },
    pcac_fast_path: Kind { build: pcac_fast_path, limits: LIMITS, observe: Observe::AsStep, ahead: false },
    pcac_next_step_fast_path: Kind { build: pcac_next_step_fast_path, limits: LIMITS, observe: Observe::RecordsData, ahead: true },
    sampling_arm: Kind { build: sampling_arm, limits: ARM_LIMITS, observe: Observe::AsStep, ahead: false },
    sampling_arm_pcac: Kind { build: sampling_arm_pcac, limits: ARM_LIMITS, observe: Observe::AsStep, ahead: false },
    appc: Kind { build: appc, limits: LIMITS, observe: Observe::AsStep, ahead: false },
    rc_mrac: Kind { build: rc_mrac, limits: None, observe: Observe::AsStep, ahead: false },
}
