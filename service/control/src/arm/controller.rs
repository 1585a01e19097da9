//! Algorithm 3, adaptive force control augmentation for the sampling arm, as a
//! [`Controller`] ([`ArmController`], kind `"sampling-arm"`).
//!
//! # Channels (the arm rig's contract)
//!
//! - `y` (`n_y = 7`): `[θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`;
//! - `r` (`n_r = 1`): the desired contact force `F_d` while the plant's guidance is in a
//!   contact phase, `0` otherwise;
//! - `u` (`n_u = 2`): the joint torques `[τ_1, τ_2]`; `z` is not read.
//!
//! # Contact (`r_k > 0`): Algorithm 3
//!
//! With `F_d = r_k`, `e_k = F_c − F_d` (7.32), `ζ_k = [θ̇_1 θ̇_2 ẋ ẏ e_k]ᵀ` (7.34) and
//! `χ_k = [ẋ ẏ e_k]ᵀ`:
//!
//! ```text
//! u_robust,k = K χ_k                                   (7.39)–(7.41), K from the LMI design
//! u_aug,k    = PCAC(ζ_k)                                (7.42)–(7.61), K̄ = [0_{2×2} K]
//! τ_{f,k}    = u_robust,k + u_aug,k
//! τ_k        = L⁻¹ (h(θ̄, q̇, F_c) + N(θ̄) τ_{f,k})        (7.31), [`super::feedback_linearization`]
//! ```
//!
//! PCAC is [`Pcac`] augmenting the output feedback `K̄ = [0_{2×2} K]`
//! ([`crate::pcac::augmentation`]): `K̄ ζ_k = K χ_k`, so it identifies the plant from
//! `y = ζ` and its input `τ_f = K̄ ζ + u_aug` (7.42)–(7.52) and plans `u_aug` with the
//! closed-loop realization (7.53)–(7.57). Its step is given `y = ζ_k`, no command (it
//! regulates `C_t ζ` to 0, `𝓡 = 0` in §7.3), the samples lost since its last step, and as
//! the applied input the `u_aug` the plant really received over the last period: the
//! torques the plant reports (`u_applied`, else this controller's, after the torque
//! limits) mapped back through the last sample's linearization, `τ_f = N⁻¹ (L τ − h)`,
//! minus that sample's `u_robust`. Without `[controller.pcac]` (robust only) `u_aug = 0`.
//!
//! # Out of contact (`r_k = 0`): joint hold
//!
//! ```text
//! τ_k = L⁻¹ (−K_p (θ̄_k − θ̄_hold) − K_d θ̄̇_k)
//! ```
//!
//! (`K_p`, `K_d` diagonal, [`JointHold`]), `θ̄_hold` latched at the first sample of each
//! hold phase (the first sample of the run when it starts out of contact): the arm keeps
//! its shape during descent, departure and ascent while the guidance moves the bus.
//!
//! # Phases
//!
//! Entering a contact phase restarts PCAC's data histories ([`Pcac::restart_histories`]):
//! its first sample only primes the regressor, so that identification never regresses
//! across the gap, while the estimate `θ`, `P` and the F-test's error windows are kept, so
//! that at a second contact with another surface the new errors, compared with the last
//! phase's, make `λ_k` drop at once (§7.3.3, Figure 7.7). Between the phases PCAC is not
//! stepped.
//!
//! # Faults
//!
//! A sample with a non-finite measurement or command, or at which the linearization does
//! not exist (`M_2` singular: the arm stretched) or gives non-finite torques, is answered
//! with the last torques held and [`status::CONTROLLER_FAULT`]; nothing is learned from
//! it, and PCAC's next step counts it as a lost sample (bridged, identification
//! suspended until it has left the regressor). With `u-min`/`u-max` the torques are
//! clipped ([`status::SATURATED`]); PCAC's own bits ([`status::FALLBACK`], and
//! [`status::SATURATED`] when `u_aug` is at its bound) are passed on.
//!
//! # Real time
//!
//! Every buffer is sized in [`ArmController::new`]; [`Controller::step`] does not
//! allocate, lock, do I/O or panic (the conformance tests count the allocations).

use nalgebra::{Matrix2x3, Vector2, Vector3, Vector4};

use super::dynamics::ArmParams;
use super::feedback_linearization::{FeedbackLinearization, FlTerms, TORQUE_MAP_INV};
use crate::ParamError;
use crate::controller::{Controller, Dimensions, MAX_INTERNALS, OutputLimits, StepInput, status};
use crate::output_limits::limit_output;
use crate::pcac::{OutputFeedback, Pcac, PcacParams};

/// The measurements the controller reads (`n_y`).
pub const N_Y: usize = 7;
/// The inputs it writes, the joint torques (`n_u`).
pub const N_U: usize = 2;
/// The command it reads, `F_d` (`n_r`).
pub const N_R: usize = 1;
/// PCAC's outputs `ζ` (`p`).
pub const P_ZETA: usize = 5;

/// The joint hold out of contact: `τ = L⁻¹ (−K_p (θ̄ − θ̄_hold) − K_d θ̄̇)`, diagonal gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHold {
    /// `K_p` per joint, N m/rad.
    pub kp: [f64; 2],
    /// `K_d` per joint, N m s/rad.
    pub kd: [f64; 2],
}

impl JointHold {
    /// `K_p = 1000` N m/rad, `K_d = 200` N m s/rad per joint (not in the chapter, whose
    /// descent and ascent control follows its reference 83): with the bus free, the arm of
    /// §7.3 at the contact angles has a joint inertia `M_1 − M_2 M_2ᵀ / m_0` with
    /// principal values of about 22 and 2.3 kg m², so the slower mode of the hold settles
    /// in about 0.9 s with a damping ratio near 0.7 and the faster one is overdamped.
    pub const DEFAULT: JointHold = JointHold {
        kp: [1000.0, 1000.0],
        kd: [200.0, 200.0],
    };
}

/// Everything an [`ArmController`] needs.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmControllerParams {
    /// The nominal spacecraft the linearization (7.31) uses.
    pub arm: ArmParams,
    /// The robust gain `K` of `u_robust = K χ` (7.39)–(7.41), `2 × 3` row-major.
    pub robust_gain: [f64; 6],
    /// The joint hold out of contact.
    pub hold: JointHold,
    /// The PCAC augmentation (§7.2.3): `p = 5` outputs `ζ`, `m = 2` inputs `u_aug`; its
    /// [`PcacParams::augmentation`] is set to `[0_{2×2} K]` by [`ArmController::new`].
    /// `None`: the robust controller alone.
    pub pcac: Option<PcacParams>,
    /// Optional limits on the joint torques (`u-min`, `u-max`).
    pub limits: Option<OutputLimits>,
}

impl ArmControllerParams {
    /// The robust controller alone with the spacecraft of §7.3 ([`ArmParams::CHAPTER_7`]),
    /// the default hold ([`JointHold::DEFAULT`]) and no torque limits: the defaults of the
    /// service's `[controller]` table for `kind = "sampling-arm"`. Change them with the
    /// struct update syntax (`ArmControllerParams { pcac, ..robust_only(k) }`); the
    /// controller checks them ([`ArmControllerParams::validate`]).
    pub fn robust_only(robust_gain: [f64; 6]) -> Self {
        Self {
            arm: ArmParams::CHAPTER_7,
            robust_gain,
            hold: JointHold::DEFAULT,
            pcac: None,
            limits: None,
        }
    }

    /// PCAC's parameters as the controller runs them: `augmentation = [0_{2×2} K]`.
    ///
    /// # Errors
    ///
    /// `"pcac"` when there is no PCAC.
    pub fn augmented_pcac(&self) -> Result<PcacParams, ParamError> {
        let mut p = self
            .pcac
            .clone()
            .ok_or_else(|| ParamError::new("pcac", "no PCAC augmentation is configured"))?;
        let fb = OutputFeedback::on_last_outputs(N_U, P_ZETA, 3, &self.robust_gain)
            .map_err(|e| ParamError::new("robust-gain", e))?;
        p.augmentation = Some(fb);
        Ok(p)
    }

    /// The channels PCAC sees: `y = ζ` (5), no `z`, no command, `u_aug` (2).
    pub fn pcac_dimensions() -> Dimensions {
        Dimensions::new(P_ZETA, 0, 0, N_U)
    }

    /// Checks the parameters for a rig with `counts` without building anything.
    ///
    /// # Errors
    ///
    /// The first refused field: the empty field for channels other than `n_y = 7`,
    /// `n_r = 1`, `n_u = 2`; `"arm.<parameter>"` (not finite and positive, as
    /// [`ArmParams::invalid_field`] names it); `"robust-gain"` (not finite);
    /// `"hold.kp"`, `"hold.kd"` (not finite and `≥ 0`); `"u-min"` (the limits);
    /// `"pcac"` with PCAC's own field and reason in the message.
    pub fn validate(&self, counts: Dimensions) -> Result<(), ParamError> {
        if counts.n_y != N_Y || counts.n_r != N_R || counts.n_u != N_U {
            return Err(ParamError::new(
                "",
                format!(
                    "sampling-arm: the rig has {} measurements y, {} commands r and {} inputs \
                     u; the arm controller reads y = [θ1, θ2, θ̇1, θ̇2, ẋ, ẏ, F_c] (7), \
                     r = F_d (1) and writes the two joint torques (2)",
                    counts.n_y, counts.n_r, counts.n_u
                ),
            ));
        }
        if let Some(name) = self.arm.invalid_field() {
            return Err(ParamError::new(
                arm_field(name),
                "every spacecraft parameter must be finite and positive",
            ));
        }
        if self.robust_gain.iter().any(|v| !v.is_finite()) {
            return Err(ParamError::new("robust-gain", "K must be finite"));
        }
        for (field, gains) in [("hold.kp", self.hold.kp), ("hold.kd", self.hold.kd)] {
            if gains.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(ParamError::new(
                    field,
                    format!("{gains:?}: the gains must be finite and ≥ 0"),
                ));
            }
        }
        if let Some(l) = &self.limits {
            l.validate(N_U)?;
        }
        if self.pcac.is_some() {
            self.augmented_pcac()?
                .validate(Self::pcac_dimensions())
                .map_err(|e| ParamError::new("pcac", e.to_string()))?;
        }
        Ok(())
    }
}

/// `"arm."` and the field [`ArmParams::invalid_field`] names.
fn arm_field(name: &str) -> &'static str {
    match name {
        "m-sc" => "arm.m-sc",
        "m1" => "arm.m1",
        "m2" => "arm.m2",
        "m-s" => "arm.m-s",
        "l1" => "arm.l1",
        "l2" => "arm.l2",
        "r1" => "arm.r1",
        "r2" => "arm.r2",
        "i1" => "arm.i1",
        "i2" => "arm.i2",
        _ => "arm",
    }
}

/// Which law the controller ran at its last sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmMode {
    /// No sample yet (after construction or a reset).
    Start,
    /// Joint hold (`r = 0`).
    Hold,
    /// Algorithm 3 (`r > 0`).
    Contact,
}

impl ArmMode {
    /// The mode as the signal log shows it: −1, 0 (hold), 1 (contact).
    pub fn code(self) -> f64 {
        match self {
            ArmMode::Start => -1.0,
            ArmMode::Hold => 0.0,
            ArmMode::Contact => 1.0,
        }
    }
}

/// What the controller counted (see [`Controller::counters`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ArmCounters {
    /// Contact phases entered.
    pub contact_phases: u64,
    /// Hold phases entered.
    pub hold_phases: u64,
    /// Samples answered with the last torques held (non-finite data, no linearization).
    pub faults: u64,
    /// Of those, samples at which the linearization did not exist or was not finite.
    pub singular: u64,
    /// Samples whose torques were clipped to the limits.
    pub saturated: u64,
}

/// Algorithm 3 of chapter 7 with the joint hold out of contact (module docs).
pub struct ArmController {
    counts: Dimensions,
    fl: FeedbackLinearization,
    k: Matrix2x3<f64>,
    hold: JointHold,
    limits: Option<OutputLimits>,
    pcac: Option<Pcac>,
    mode: ArmMode,
    theta_hold: Vector2<f64>,
    /// The torques of the last answer (held on a fault).
    tau: [f64; 2],
    /// `ζ_k` of the last contact sample.
    zeta: [f64; P_ZETA],
    /// `e_k = F_c − F_d` of the last sample.
    force_error: f64,
    u_robust: Vector2<f64>,
    u_aug: [f64; 2],
    tau_f: Vector2<f64>,
    /// The linearization of the last contact sample, for mapping the applied torques back
    /// to `τ_f` (valid while `continuous`).
    prev_terms: Option<FlTerms>,
    /// The `u_aug` the plant received over the last period as far as this controller knows
    /// (its own, after the torque limits).
    aug_applied: [f64; 2],
    /// Scratch: the `u_aug` handed to PCAC as applied.
    aug_reported: [f64; 2],
    /// The last contact sample was answered by Algorithm 3 (no fault, no hold since).
    continuous: bool,
    /// Samples PCAC has not seen since its last step within this contact phase.
    pending_lost: u64,
    /// PCAC took in the current sample (a fault after it must not count it as lost).
    pcac_stepped: bool,
    counters: ArmCounters,
}

impl ArmController {
    /// Builds the controller (allocating PCAC's workspaces) for a rig with `counts`,
    /// after [`ArmControllerParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`ArmControllerParams::validate`].
    pub fn new(params: &ArmControllerParams, counts: Dimensions) -> Result<Self, ParamError> {
        params.validate(counts)?;
        let pcac = match &params.pcac {
            None => None,
            Some(_) => Some(
                Pcac::new(
                    &params.augmented_pcac()?,
                    ArmControllerParams::pcac_dimensions(),
                )
                .map_err(|e| ParamError::new("pcac", e.to_string()))?,
            ),
        };
        Ok(Self {
            counts,
            fl: FeedbackLinearization::new(params.arm),
            k: Matrix2x3::from_row_slice(&params.robust_gain),
            hold: params.hold,
            limits: params.limits.clone(),
            pcac,
            mode: ArmMode::Start,
            theta_hold: Vector2::zeros(),
            tau: [0.0; 2],
            zeta: [0.0; P_ZETA],
            force_error: 0.0,
            u_robust: Vector2::zeros(),
            u_aug: [0.0; 2],
            tau_f: Vector2::zeros(),
            prev_terms: None,
            aug_applied: [0.0; 2],
            aug_reported: [0.0; 2],
            continuous: false,
            pending_lost: 0,
            pcac_stepped: false,
            counters: ArmCounters::default(),
        })
    }

    /// The law of the last sample.
    pub fn mode(&self) -> ArmMode {
        self.mode
    }

    /// The PCAC augmentation (its identified model: [`Pcac::model`], the coefficients
    /// `F̂_1`, `Ĝ_1` of (7.42), `λ_k`, `tr P_k`), if configured.
    pub fn pcac(&self) -> Option<&Pcac> {
        self.pcac.as_ref()
    }

    /// [`ArmController::pcac`], mutable: for benchmarks and comparisons that need
    /// [`Pcac::condensed_problem`]. Changing PCAC's state between steps changes this
    /// controller's.
    pub fn pcac_mut(&mut self) -> Option<&mut Pcac> {
        self.pcac.as_mut()
    }

    /// The robust gain `K`.
    pub fn robust_gain(&self) -> &Matrix2x3<f64> {
        &self.k
    }

    /// The feedback linearization in use.
    pub fn linearization(&self) -> &FeedbackLinearization {
        &self.fl
    }

    /// `e_k = F_c − F_d` of the last sample (`F_c` in hold).
    pub fn force_error(&self) -> f64 {
        self.force_error
    }

    /// `ζ_k` of the last contact sample (7.34).
    pub fn zeta(&self) -> &[f64; P_ZETA] {
        &self.zeta
    }

    /// `τ_{f,k} = u_robust,k + u_aug,k` of the last contact sample (zero in hold).
    pub fn virtual_input(&self) -> [f64; 2] {
        [self.tau_f[0], self.tau_f[1]]
    }

    /// `u_robust,k = K χ_k` of the last contact sample.
    pub fn robust_input(&self) -> [f64; 2] {
        [self.u_robust[0], self.u_robust[1]]
    }

    /// `u_aug,k`, PCAC's output at the last contact sample (zero without PCAC).
    pub fn augmentation_input(&self) -> [f64; 2] {
        self.u_aug
    }

    /// The `u_aug` the plant receives with the last answer: `u_aug,k`, or with clipped
    /// torques what they amount to, `N⁻¹ (L τ − h) − u_robust,k`; PCAC is told it as the
    /// applied input at the next contact sample (unless the plant reports its own).
    pub fn applied_augmentation(&self) -> [f64; 2] {
        self.aug_applied
    }

    /// The forgetting factor `λ_k` of PCAC's last identification step.
    pub fn forgetting_factor(&self) -> Option<f64> {
        self.pcac.as_ref().map(|p| p.model().last_step().lambda)
    }

    /// `tr P_k` of PCAC's identification.
    pub fn covariance_trace(&self) -> Option<f64> {
        self.pcac.as_ref().map(|p| p.model().trace_p())
    }

    /// PCAC's model coefficients `Θ̃ = [F̂_1 … Ĝ_n̂]` (`5 × n̂·7`, row-major), the
    /// identified plant of (7.42).
    pub fn model_coefficients(&self) -> Option<&[f64]> {
        self.pcac.as_ref().map(|p| p.model().coefficients())
    }

    /// What was counted so far.
    pub fn counts_of(&self) -> ArmCounters {
        self.counters
    }

    /// A sample that cannot be answered: the last torques, held.
    fn fault(&mut self, u: &mut [f64], singular: bool) -> u32 {
        self.counters.faults += 1;
        if singular {
            self.counters.singular += 1;
        }
        if self.mode == ArmMode::Contact && !self.pcac_stepped {
            self.pending_lost += 1;
        }
        self.continuous = false;
        self.write(u);
        status::CONTROLLER_FAULT
    }

    fn write(&self, u: &mut [f64]) {
        for (d, s) in u.iter_mut().zip(&self.tau) {
            *d = *s;
        }
    }

    /// Bounds `tau` by the output-limiting rule ([`limit_output`]) into `self.tau`; returns
    /// its status bits.
    fn limit(&mut self, tau: Vector2<f64>) -> u32 {
        self.tau = [tau[0], tau[1]];
        let st = limit_output(self.limits.as_ref(), &mut self.tau);
        if st & status::SATURATED != 0 {
            self.counters.saturated += 1;
        }
        st
    }

    /// The joint hold (module docs).
    fn hold_step(&mut self, theta: Vector2<f64>, theta_d: Vector2<f64>, f_c: f64) -> Option<u32> {
        if self.mode != ArmMode::Hold {
            self.mode = ArmMode::Hold;
            self.theta_hold = theta;
            self.counters.hold_phases += 1;
        }
        self.continuous = false;
        self.force_error = f_c;
        self.u_robust = Vector2::zeros();
        self.u_aug = [0.0; 2];
        self.tau_f = Vector2::zeros();
        let (kp, kd) = (self.hold.kp, self.hold.kd);
        let dq = theta - self.theta_hold;
        let q_theta = Vector2::new(
            -kp[0] * dq[0] - kd[0] * theta_d[0],
            -kp[1] * dq[1] - kd[1] * theta_d[1],
        );
        let tau = TORQUE_MAP_INV * q_theta;
        tau.iter().all(|v| v.is_finite()).then(|| self.limit(tau))
    }

    /// Algorithm 3 at one contact sample (module docs); `None` for a fault.
    fn contact_step(
        &mut self,
        input: &StepInput<'_>,
        theta: Vector2<f64>,
        qd: Vector4<f64>,
        f_c: f64,
        f_d: f64,
    ) -> Option<u32> {
        if self.mode != ArmMode::Contact {
            self.mode = ArmMode::Contact;
            self.counters.contact_phases += 1;
            self.continuous = false;
            self.pending_lost = 0;
            if let Some(p) = &mut self.pcac {
                p.restart_histories();
            }
        }
        let terms = self.fl.terms(&theta, &qd, f_c)?;
        let e = f_c - f_d;
        self.force_error = e;
        self.zeta = [qd[0], qd[1], qd[2], qd[3], e];
        let u_robust = self.k * Vector3::new(qd[2], qd[3], e);
        let mut bits = status::OK;
        if let Some(p) = &mut self.pcac {
            // The u_aug the plant received over the last period.
            let reported = if self.continuous {
                let from_plant = input
                    .u_applied
                    .filter(|ua| ua.len() >= N_U && ua[..N_U].iter().all(|v| v.is_finite()))
                    .and_then(|ua| {
                        let prev = self.prev_terms?;
                        let tau_f = prev.virtual_input(&Vector2::new(ua[0], ua[1]))?;
                        Some(tau_f - self.u_robust)
                    });
                match from_plant {
                    Some(v) => self.aug_reported = [v[0], v[1]],
                    None => self.aug_reported = self.aug_applied,
                }
                Some(&self.aug_reported[..])
            } else {
                None
            };
            let lost = if self.continuous || self.pending_lost > 0 {
                self.pending_lost + input.lost
            } else {
                0
            };
            let inner = StepInput {
                seq: input.seq,
                y: &self.zeta,
                z: &[],
                r: &[],
                u_applied: reported,
                lost,
            };
            bits |= p.step(&inner, &mut self.u_aug);
            self.pending_lost = 0;
            self.pcac_stepped = true;
        }
        let tau_f = u_robust + Vector2::new(self.u_aug[0], self.u_aug[1]);
        let tau = terms.torques(&tau_f);
        if !tau.iter().all(|v| v.is_finite()) {
            return None;
        }
        self.u_robust = u_robust;
        self.tau_f = tau_f;
        let clipped = self.limit(tau);
        bits |= clipped;
        // What the plant will receive: u_aug, or what the clipped torques amount to.
        self.aug_applied = self.u_aug;
        if clipped != status::OK
            && let Some(eff) = terms.virtual_input(&Vector2::new(self.tau[0], self.tau[1]))
        {
            let v = eff - u_robust;
            self.aug_applied = [v[0], v[1]];
        }
        self.prev_terms = Some(terms);
        self.continuous = true;
        Some(bits)
    }
}

impl Controller for ArmController {
    fn kind(&self) -> &'static str {
        "sampling-arm"
    }

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        self.pcac_stepped = false;
        let (y, r) = (input.y, input.r);
        if y.len() < N_Y || r.is_empty() {
            return self.fault(u, false);
        }
        let f_d = r[0];
        if !f_d.is_finite() || y[..N_Y].iter().any(|v| !v.is_finite()) {
            return self.fault(u, false);
        }
        let theta = Vector2::new(y[0], y[1]);
        let qd = Vector4::new(y[2], y[3], y[4], y[5]);
        let f_c = y[6];
        let bits = if f_d > 0.0 {
            self.contact_step(input, theta, qd, f_c, f_d)
        } else {
            self.hold_step(theta, Vector2::new(y[2], y[3]), f_c - f_d)
        };
        match bits {
            Some(b) => {
                self.write(u);
                b
            }
            None => self.fault(u, true),
        }
    }

    fn reset(&mut self) {
        if let Some(p) = &mut self.pcac {
            p.reset();
        }
        self.restart_state();
    }

    /// PCAC forgets its histories and forgetting windows and keeps `θ`, `P`; the modes
    /// start again.
    fn restart_data(&mut self) {
        if let Some(p) = &mut self.pcac {
            p.restart_data();
        }
        self.restart_state();
    }

    fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        if let Some(p) = &self.pcac {
            p.learned(visit);
        }
    }

    fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        match &mut self.pcac {
            Some(p) => p.restore_learned(saved),
            None if saved.is_empty() => Ok(()),
            None => Err("the sampling-arm controller without PCAC learns nothing".into()),
        }
    }

    fn prepare_thread(&mut self) {
        if let Some(p) = &mut self.pcac {
            p.prepare_thread();
        }
    }

    /// PCAC's identification over the steps it ran (the contact phases).
    fn adaptation(&self) -> Option<crate::controller::Adaptation> {
        self.pcac.as_ref().and_then(Controller::adaptation)
    }

    /// Freezes or resumes the PCAC augmentation's identification; false without it.
    fn set_adaptation(&mut self, on: bool) -> bool {
        self.pcac.as_mut().is_some_and(|p| p.set_adaptation(on))
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let c = &self.counters;
        let mut v = vec![
            ("contact phases", c.contact_phases),
            ("hold phases", c.hold_phases),
            ("faults", c.faults),
            ("no linearization", c.singular),
            ("torques saturated", c.saturated),
        ];
        if let Some(p) = &self.pcac {
            v.extend(p.counters());
        }
        v
    }

    fn internal_names(&self) -> Vec<String> {
        let mut names: Vec<String> = [
            "mode",
            "force_error",
            "tau_f1",
            "tau_f2",
            "u_robust1",
            "u_robust2",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        if let Some(p) = &self.pcac {
            names.push("u_aug1".into());
            names.push("u_aug2".into());
            names.extend(p.internal_names());
        }
        names.truncate(MAX_INTERNALS);
        names
    }

    fn internals(&self, out: &mut [f64]) -> usize {
        let own = [
            self.mode.code(),
            self.force_error,
            self.tau_f[0],
            self.tau_f[1],
            self.u_robust[0],
            self.u_robust[1],
            self.u_aug[0],
            self.u_aug[1],
        ];
        let n_own = if self.pcac.is_some() { 8 } else { 6 };
        let limit = out.len().min(MAX_INTERNALS);
        let n = n_own.min(limit);
        out[..n].copy_from_slice(&own[..n]);
        match &self.pcac {
            Some(p) if limit > n => n + p.internals(&mut out[n..limit]),
            _ => n,
        }
    }
}

impl ArmController {
    /// The modes, latches and held values back to their start.
    fn restart_state(&mut self) {
        self.mode = ArmMode::Start;
        self.theta_hold = Vector2::zeros();
        self.tau = [0.0; 2];
        self.zeta = [0.0; P_ZETA];
        self.force_error = 0.0;
        self.u_robust = Vector2::zeros();
        self.u_aug = [0.0; 2];
        self.tau_f = Vector2::zeros();
        self.prev_terms = None;
        self.aug_applied = [0.0; 2];
        self.aug_reported = [0.0; 2];
        self.continuous = false;
        self.pending_lost = 0;
        self.pcac_stepped = false;
    }
}
