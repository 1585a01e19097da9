//! What APPC and RC-MRAC share: the loop of one adaptive step around a regression and a
//! law that differ. At sample `k`:
//!
//! 1. the signals take `y_k`, `r_k` in (the reference model gives `y_{m,k}`, `e_k`; a bad or
//!    lost sample is bridged, [`Signals`]);
//! 2. the method fills its regressor `φ_k` and gives `b_k`, the target of
//!    `ẑ_k(θ̂) = φ_k θ̂ − b_k` (APPC: (4.39)–(4.41), `φ = [Φ_k Φ_{f,k}]`, `b = −u_{f,k}`;
//!    RC-MRAC: (4.72)–(4.75), `φ = Φ_{f,k}`, `b = u_{f,k} − z_{f,k}`);
//! 3. RLS updates `θ̂` on (4.42) / (4.76) when the windows hold only measured data;
//! 4. the method's law gives `u_k` ((4.43), (4.77)) from `θ̂_{k+1}`, saturated.
//!
//! A step (closed loop) counts whether step 3 ran or why it did not (a bridged gap or a
//! bad sample in the windows); a sample taken in by [`Adaptive::observe`] runs the same
//! four steps and is not counted.
//!
//! No allocation after construction, no panic.

use super::estimator::Estimator;
use super::signals::{Signals, Suspension};
use crate::controller::{OutputLimits, StepInput, status};
use crate::output_limits::limit_output;

/// The accessors that APPC and RC-MRAC share over their [`Adaptive`] (the field
/// `core`): `θ̂_k` (the method's ordering given as the first argument), `y_{m,k}`, `e_k`,
/// `ẑ_k` (its equation the second), the regressor (its equations the third) and the
/// estimator's resets.
macro_rules! adaptive_accessors {
    ($theta:literal, $zhat:literal, $regressor:literal) => {
        #[doc = concat!("`θ̂_k` ", $theta, ".")]
        pub fn theta(&self) -> &[f64] {
            self.core.est.theta()
        }

        /// `y_{m,k}` of the last sample (NaN after a bad one).
        pub fn y_m(&self) -> f64 {
            self.core.sig.y_m
        }

        /// `e_k = y_k − y_{m,k}` of the last sample (NaN after a bad one).
        pub fn e(&self) -> f64 {
            self.core.sig.e_k
        }

        #[doc = concat!("`ẑ_k(θ̂_k)` ", $zhat, " of the last sample, with the updated estimate.")]
        pub fn zhat(&self) -> f64 {
            self.core.zhat
        }

        #[doc = concat!($regressor, " of the last sample.")]
        pub fn regressor(&self) -> &[f64] {
            &self.core.phi
        }

        /// Guard resets of the estimator since construction.
        pub fn resets(&self) -> u64 {
            self.core.est.resets()
        }
    };
}
pub(super) use adaptive_accessors;

/// What a closed-loop step did with its update (the index of its counter).
#[derive(Debug, Clone, Copy)]
enum Outcome {
    Updated = 0,
    Gap = 1,
    BadSample = 2,
    /// Frozen by the operator: counted apart, not as a suspension.
    Frozen = 3,
}

/// The part of a method that differs: its regression and its law.
pub(super) trait Law {
    /// Fills `phi` (the regressor `φ_k`) from the signals and returns `b_k`, the target of
    /// `ẑ_k(θ̂) = φ_k θ̂ − b_k`.
    fn regression(&self, sig: &Signals, phi: &mut [f64]) -> f64;
    /// The input `u_k` from the signals and `θ̂`.
    fn law(&self, sig: &Signals, theta: &[f64]) -> f64;
}

/// The signals, the estimator and the step's outputs (module docs).
#[derive(Debug, Clone)]
pub(super) struct Adaptive {
    /// Histories, the reference model, `y_m`, `e`.
    pub sig: Signals,
    /// RLS with `R_θ`.
    pub est: Estimator,
    /// The regressor of the last sample.
    pub phi: Vec<f64>,
    limits: Option<OutputLimits>,
    /// `ẑ_k(θ̂_{k+1})` of the last sample.
    pub zhat: f64,
    /// λ of the last update.
    pub lambda: f64,
    /// `‖θ̂‖`.
    pub theta_norm: f64,
    /// Closed-loop steps: updated, suspended for a gap, suspended for a bad sample (indexed
    /// by [`Outcome`]).
    adapted: [u64; 3],
    /// The operator froze the update ([`Controller::set_adaptation`]).
    pub frozen: bool,
    /// Closed-loop steps while frozen.
    frozen_steps: u64,
}

impl Adaptive {
    /// At rest, `θ̂ = θ̂_0`.
    pub fn new(sig: Signals, est: Estimator, limits: Option<OutputLimits>) -> Self {
        let phi = vec![0.0; est.theta().len()];
        let mut s = Self {
            sig,
            est,
            phi,
            limits,
            zhat: 0.0,
            lambda: 1.0,
            theta_norm: 0.0,
            adapted: [0; 3],
            frozen: false,
            frozen_steps: 0,
        };
        s.reset();
        s
    }

    /// One closed-loop step of `method` (module docs); writes `u_k` into `u[0]`, returns
    /// the status.
    pub fn step(&mut self, method: &impl Law, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        self.run(method, input, u, true)
    }

    /// A sample taken in without an answer: the step, not counted in [`Self::adaptation`].
    pub fn observe(&mut self, method: &impl Law, input: &StepInput<'_>, u: &mut [f64]) {
        let _ = self.run(method, input, u, false);
    }

    /// Closed-loop steps updated and suspended per cause.
    pub fn adaptation(&self) -> crate::controller::Adaptation {
        use crate::controller::Adaptation;
        let [updated, gap, bad] = self.adapted;
        Adaptation {
            updated,
            suspended: vec![
                (Adaptation::BRIDGED_GAP, gap),
                (Adaptation::BAD_SAMPLE, bad),
            ],
            frozen: self.frozen_steps,
        }
    }

    fn run(
        &mut self,
        method: &impl Law,
        input: &StepInput<'_>,
        u: &mut [f64],
        closed_loop: bool,
    ) -> u32 {
        let mut st = status::OK;
        let mut outcome = Outcome::BadSample;
        self.sig.absorb(input);
        let ok = self.sig.take_in(input);
        let mut out = self.sig.u_last();
        if ok {
            let b = method.regression(&self.sig, &mut self.phi);
            let finite = b.is_finite() && self.phi.iter().all(|v| v.is_finite());
            if !finite {
                st |= status::CONTROLLER_FAULT;
                self.zhat = f64::NAN;
            } else {
                let learn = self.sig.learn() && !self.frozen;
                outcome = match self.sig.suspension {
                    _ if self.frozen => Outcome::Frozen,
                    _ if learn => Outcome::Updated,
                    Suspension::Gap => Outcome::Gap,
                    Suspension::BadSample => Outcome::BadSample,
                };
                if learn {
                    let r = self.est.update(&self.phi, b);
                    self.lambda = r.lambda;
                    if r.reset {
                        st |= status::CONTROLLER_FAULT;
                    }
                    self.note_theta();
                }
                self.zhat = crate::linalg::dot(&self.phi, self.est.theta()) - b;
            }
            out = method.law(&self.sig, self.est.theta());
        } else {
            st |= status::CONTROLLER_FAULT;
            self.zhat = f64::NAN;
        }
        if closed_loop {
            match outcome {
                Outcome::Frozen => self.frozen_steps += 1,
                o => self.adapted[o as usize] += 1,
            }
        }
        st |= limit_output(self.limits.as_ref(), std::slice::from_mut(&mut out));
        self.sig.push_u(out);
        if let Some(d) = u.first_mut() {
            *d = out;
        }
        st
    }

    /// Back to `θ̂_0`, `P_0` and rest.
    pub fn reset(&mut self) {
        self.est.reset();
        self.note_theta();
        self.restart_data();
    }

    /// Forgets the histories, the reference model's state and the forgetting windows;
    /// keeps `θ̂_k` and `P_k`.
    pub fn restart_data(&mut self) {
        self.sig.clear();
        self.est.restart_data();
        self.phi.fill(0.0);
        self.zhat = 0.0;
        self.lambda = 1.0;
    }

    /// Takes a checkpoint's RLS blocks.
    pub fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let r = self.est.restore_learned(saved);
        self.note_theta();
        r
    }

    /// The report's counters.
    pub fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("coefficient resets", self.est.resets()),
            ("gaps bridged", self.sig.gaps()),
        ]
    }

    /// The internals in the order of [`super::internal_names`].
    pub fn internals(&self, out: &mut [f64]) -> usize {
        let head = [
            self.sig.y_m,
            self.sig.e_k,
            self.zhat,
            self.theta_norm,
            self.est.trace(),
            self.lambda,
            self.est.resets() as f64,
        ];
        super::write_internals(&head, self.est.theta(), out)
    }

    fn note_theta(&mut self) {
        self.theta_norm = self.est.theta().iter().map(|t| t * t).sum::<f64>().sqrt();
    }
}

/// The [`Controller`](crate::Controller) impl of a method built on [`Adaptive`]: a struct
/// with the fields `counts: Dimensions`, `law` (its [`Law`]) and `core: Adaptive`, and the
/// methods `e()` and `theta()`. `$kind` is the kind's name, `$prefix` that of its
/// internals.
macro_rules! adaptive_controller {
    ($ty:ty, $kind:literal, $prefix:literal) => {
        impl Controller for $ty {
            fn kind(&self) -> &'static str {
                $kind
            }

            fn counts(&self) -> Dimensions {
                self.counts
            }

            fn model_following_error(&self) -> Option<f64> {
                Some(self.e())
            }

            fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
                self.core.step(&self.law, input, u)
            }

            fn observe(&mut self, input: &StepInput<'_>, u: &mut [f64]) {
                self.core.observe(&self.law, input, u)
            }

            fn adaptation(&self) -> Option<crate::controller::Adaptation> {
                Some(self.core.adaptation())
            }

            fn set_adaptation(&mut self, on: bool) -> bool {
                self.core.frozen = !on;
                true
            }

            fn reset(&mut self) {
                self.core.reset();
            }

            /// Forgets the histories, the reference model's state, the filtered command and
            /// the forgetting windows; keeps `θ̂_k` and `P_k`.
            fn restart_data(&mut self) {
                self.core.restart_data();
            }

            /// The RLS blocks (in the scaled coordinates `R_θ^{1/2} θ̂`).
            fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
                self.core.est.learned(visit);
            }

            fn restore_learned(
                &mut self,
                saved: &crate::learned::Learned<'_>,
            ) -> Result<(), String> {
                self.core.restore_learned(saved)
            }

            fn counters(&self) -> Vec<(&'static str, u64)> {
                self.core.counters()
            }

            fn internal_names(&self) -> Vec<String> {
                super::internal_names($prefix, self.theta().len())
            }

            fn internals(&self, out: &mut [f64]) -> usize {
                self.core.internals(out)
            }
        }
    };
}
pub(super) use adaptive_controller;
