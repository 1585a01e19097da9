//! The controller interface of the service and its first controller.
//!
//! A controller is a pure kernel: it gets the signals of sample `k` (measurement `y_k`,
//! performance `z_k`, command `r_k`, as in Figure 3.1 of the dissertation) and writes the
//! control input `u_k`. It is built (allocating) from the configuration before the real-time
//! thread starts; its [`Controller::step`] must not allocate, lock, do I/O or panic. The
//! runtime around it (waiting, publishing, deadline policy, logging) knows nothing of what
//! is inside, so RCAC, PCAC and the others plug in here.
//!
//! [`LtiController`] is a discrete-time linear time-invariant controller
//!
//! ```text
//!   x_{k+1} = A x_k + B e_k,      u_k = sat(C x_k + D e_k),
//! ```
//!
//! whose input `e_k` is `y_k`, the tracking error `r_k − y_k`, or the stack `[y_k; r_k]`
//! ([`ControllerInput`]), given as a matrix of discrete transfer functions or in state space.
//!
//! [`Rcac`] is retrospective cost adaptive control (2.15)–(2.23) with a target model `G_f`
//! (3.39)/(3.49), updated by RLS or by the instantaneous-cost gradient (3.51)–(3.63).
//!
//! [`ExcitationSource`] is not a feedback law: it drives the inputs with independent white
//! noise for identification experiments (the data of the design tools, section 3.2).

use ipc_types::{ChannelCounts, actuation_status};
use nalgebra::{DMatrix, DVector};

mod excitation;
pub mod pcac;
mod rcac;
pub use excitation::ExcitationSource;
pub use rcac::{Rcac, RcacParams, RcacUpdate, StepSize, TargetFilter};

/// Maximum number of internal signals a controller exposes to the signal log.
pub const MAX_INTERNALS: usize = 16;

/// The signals of sample `k` handed to a controller; slices have the configured lengths.
///
/// `u_applied` and `lost` tell a controller what happened between its calls when the loop
/// is not perfect: the plant may have held an older input because an actuation arrived
/// after its deadline, and samples may never have reached the service. A controller whose
/// state depends on the past inputs (RCAC's regressor and filtered input) uses them to
/// keep that state equal to what the plant saw.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepInput<'a> {
    /// Sample index `k`.
    pub seq: u64,
    /// Measurement `y_k`.
    pub y: &'a [f64],
    /// Performance variable `z_k`.
    pub z: &'a [f64],
    /// Command `r_k`.
    pub r: &'a [f64],
    /// The input the plant actually applied after sample `k − 1` (held over the period
    /// ending at sample `k`), when the plant reports it (contract flag
    /// `measurement_flags::U_APPLIED`); `None` when unknown.
    pub u_applied: Option<&'a [f64]>,
    /// Samples lost between the previous call and this one (`k − k_prev − 1`); 0 normally.
    pub lost: u64,
}

/// A controller the service can run.
pub trait Controller: Send {
    /// A short name for reports ("lti", "rcac", …).
    fn kind(&self) -> &'static str;
    /// The channels it reads (`n_y`, `n_z`, `n_r`) and writes (`n_u`).
    fn counts(&self) -> ChannelCounts;
    /// Computes `u_k` from the signals of sample `k`; `u` has length `n_u`. Returns
    /// [`actuation_status`] bits (`OK`, `SATURATED`, `CONTROLLER_FAULT`).
    ///
    /// Must not allocate, lock, do I/O or panic, and must leave `u` finite.
    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32;
    /// Takes in sample `k` without being asked for an input to apply: the loop received it
    /// too late (a newer sample was already waiting), so no actuation of it will be
    /// applied. A controller with memory must still record it so that its state stays
    /// aligned with the plant's samples; `u` is scratch of length `n_u`.
    ///
    /// The default runs [`Controller::step`] and discards the output. Same real-time rules
    /// as `step`.
    fn observe(&mut self, input: &StepInput<'_>, u: &mut [f64]) {
        let _ = self.step(input, u);
    }
    /// Returns to the initial state (used when a plant comes back after silence).
    fn reset(&mut self);
    /// Called once on the real-time thread before its loop starts (before allocations are
    /// counted there): a controller whose libraries keep lazily created per-thread state
    /// (e.g. the matrix-multiply scratch of PCAC's QP solver) creates it here, so that the
    /// first real-time step does not allocate. The default does nothing.
    fn prepare_thread(&mut self) {}
    /// Names of the internal signals written by [`Controller::internals`].
    fn internal_names(&self) -> Vec<String> {
        Vec::new()
    }
    /// What the controller counted so far, for the run report (e.g. PCAC's solved,
    /// infeasible and unsolved QPs, identification resets). Called outside the real-time
    /// loop; may allocate.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        Vec::new()
    }
    /// Writes up to [`MAX_INTERNALS`] internal signals (for the signal log) and returns how
    /// many. Must not allocate.
    fn internals(&self, _out: &mut [f64]) -> usize {
        0
    }
}

/// Per-channel limits on `u`.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputLimits {
    /// Lower limits, one per input.
    pub min: Vec<f64>,
    /// Upper limits, one per input.
    pub max: Vec<f64>,
}

impl OutputLimits {
    /// Clips `u` in place; returns true when any entry was clipped. Non-finite entries are
    /// replaced by 0 clipped into the limits, so the result is always finite.
    #[inline]
    pub fn apply(&self, u: &mut [f64]) -> bool {
        let mut clipped = false;
        for ((v, lo), hi) in u.iter_mut().zip(&self.min).zip(&self.max) {
            if !v.is_finite() {
                *v = 0.0_f64.clamp(*lo, *hi);
                clipped = true;
            } else if *v < *lo {
                *v = *lo;
                clipped = true;
            } else if *v > *hi {
                *v = *hi;
                clipped = true;
            }
        }
        clipped
    }
}

/// What feeds an [`LtiController`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerInput {
    /// `e_k = y_k` (disturbance rejection, regulation).
    Y,
    /// `e_k = r_k − y_k` (tracking; needs `n_r = n_y`).
    Error,
    /// `e_k = [y_k; r_k]` (two-degree-of-freedom).
    YAndR,
}

/// A discrete-time LTI controller in state space, see the module docs.
pub struct LtiController {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
    x0: DVector<f64>,
    x: DVector<f64>,
    x_next: DVector<f64>,
    e: DVector<f64>,
    u: DVector<f64>,
    input: ControllerInput,
    counts: ChannelCounts,
    limits: Option<OutputLimits>,
}

impl LtiController {
    /// Builds the controller from its discrete state-space matrices. `counts` gives the
    /// channels of the rig; the matrix sizes must agree with them and with `input`.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        input: ControllerInput,
        counts: ChannelCounts,
        limits: Option<OutputLimits>,
    ) -> Result<Self, String> {
        let n = a.nrows();
        let n_y = counts.n_y as usize;
        let n_r = counts.n_r as usize;
        let n_u = counts.n_u as usize;
        let n_e = match input {
            ControllerInput::Y => n_y,
            ControllerInput::Error => {
                if n_r != n_y {
                    return Err(format!(
                        "input = \"error\" needs as many commands as measurements (r: {n_r}, y: {n_y})"
                    ));
                }
                n_y
            }
            ControllerInput::YAndR => n_y + n_r,
        };
        let shape = |name: &str, m: &DMatrix<f64>, r: usize, c: usize| {
            if m.nrows() != r || m.ncols() != c {
                Err(format!(
                    "{name} is {}×{}, expected {r}×{c} ({n} states, {n_e} controller inputs, {n_u} outputs u)",
                    m.nrows(),
                    m.ncols()
                ))
            } else if m.iter().any(|v| !v.is_finite()) {
                Err(format!("{name} has a non-finite entry"))
            } else {
                Ok(())
            }
        };
        shape("a", &a, n, n)?;
        shape("b", &b, n, n_e)?;
        shape("c", &c, n_u, n)?;
        shape("d", &d, n_u, n_e)?;
        if let Some(l) = &limits {
            if l.min.len() != n_u || l.max.len() != n_u {
                return Err(format!("output limits need {n_u} entries for min and max"));
            }
            if l.min.iter().zip(&l.max).any(|(lo, hi)| !(lo <= hi)) {
                return Err("output limits need min ≤ max for every input".into());
            }
        }
        Ok(Self {
            x0: DVector::zeros(n),
            x: DVector::zeros(n),
            x_next: DVector::zeros(n),
            e: DVector::zeros(n_e),
            u: DVector::zeros(n_u),
            a,
            b,
            c,
            d,
            input,
            counts,
            limits,
        })
    }

    /// Sets the initial state (also used by [`Controller::reset`]).
    pub fn with_initial_state(mut self, x0: DVector<f64>) -> Result<Self, String> {
        if x0.len() != self.x.len() {
            return Err(format!(
                "initial state has {} entries, the controller has {} states",
                x0.len(),
                self.x.len()
            ));
        }
        self.x.copy_from(&x0);
        self.x0 = x0;
        Ok(self)
    }

    /// Number of controller states.
    pub fn order(&self) -> usize {
        self.x.len()
    }
}

impl Controller for LtiController {
    fn kind(&self) -> &'static str {
        "lti"
    }

    fn counts(&self) -> ChannelCounts {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        let n_y = self.counts.n_y as usize;
        match self.input {
            ControllerInput::Y => {
                for (e, y) in self.e.iter_mut().zip(input.y) {
                    *e = *y;
                }
            }
            ControllerInput::Error => {
                for ((e, y), r) in self.e.iter_mut().zip(input.y).zip(input.r) {
                    *e = *r - *y;
                }
            }
            ControllerInput::YAndR => {
                for (i, e) in self.e.iter_mut().enumerate() {
                    *e = if i < n_y {
                        input.y[i]
                    } else {
                        input.r[i - n_y]
                    };
                }
            }
        }
        // u = C x + D e
        self.u.gemv(1.0, &self.c, &self.x, 0.0);
        self.u.gemv(1.0, &self.d, &self.e, 1.0);
        // x+ = A x + B e
        self.x_next.gemv(1.0, &self.a, &self.x, 0.0);
        self.x_next.gemv(1.0, &self.b, &self.e, 1.0);
        let mut status = actuation_status::OK;
        if self.x_next.iter().all(|v| v.is_finite()) {
            core::mem::swap(&mut self.x, &mut self.x_next);
        } else {
            // A diverging controller state is reset rather than propagated.
            self.x.copy_from(&self.x0);
            status |= actuation_status::CONTROLLER_FAULT;
        }
        for (dst, src) in u.iter_mut().zip(self.u.iter()) {
            *dst = *src;
        }
        let clipped = match &self.limits {
            Some(l) => l.apply(u),
            None => {
                let mut bad = false;
                for v in u.iter_mut() {
                    if !v.is_finite() {
                        *v = 0.0;
                        bad = true;
                    }
                }
                if bad {
                    status |= actuation_status::CONTROLLER_FAULT;
                }
                false
            }
        };
        if clipped {
            status |= actuation_status::SATURATED;
        }
        status
    }

    fn reset(&mut self) {
        self.x.copy_from(&self.x0);
    }

    fn internal_names(&self) -> Vec<String> {
        (0..self.x.len().min(MAX_INTERNALS))
            .map(|i| format!("x{i}"))
            .collect()
    }

    fn internals(&self, out: &mut [f64]) -> usize {
        let n = self.x.len().min(out.len()).min(MAX_INTERNALS);
        out[..n].copy_from_slice(&self.x.as_slice()[..n]);
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts(n_y: u16, n_r: u16, n_u: u16) -> ChannelCounts {
        ChannelCounts {
            n_y,
            n_z: n_y,
            n_r,
            n_u,
        }
    }

    fn step(c: &mut LtiController, y: &[f64], r: &[f64], u: &mut [f64]) -> u32 {
        c.step(
            &StepInput {
                seq: 0,
                y,
                z: y,
                r,
                ..Default::default()
            },
            u,
        )
    }

    #[test]
    fn a_first_order_controller_follows_its_difference_equation() {
        // x+ = 0.5 x + e, u = 2 x + 0.1 e  ⇒  u_k = 2 Σ 0.5^{k-1-i} e_i + 0.1 e_k
        let mut c = LtiController::new(
            DMatrix::from_element(1, 1, 0.5),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, 2.0),
            DMatrix::from_element(1, 1, 0.1),
            ControllerInput::Y,
            counts(1, 0, 1),
            None,
        )
        .unwrap();
        let e = [1.0, -2.0, 0.5, 3.0];
        let mut x = 0.0;
        let mut u = [0.0];
        for &ek in &e {
            step(&mut c, &[ek], &[], &mut u);
            let expected = 2.0 * x + 0.1 * ek;
            assert!((u[0] - expected).abs() < 1e-15);
            x = 0.5 * x + ek;
        }
    }

    #[test]
    fn the_error_input_uses_r_minus_y_and_limits_clip() {
        let mut c = LtiController::new(
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, 1),
            DMatrix::zeros(1, 0),
            DMatrix::from_element(1, 1, 10.0),
            ControllerInput::Error,
            counts(1, 1, 1),
            Some(OutputLimits {
                min: vec![-1.0],
                max: vec![1.0],
            }),
        )
        .unwrap();
        let mut u = [0.0];
        assert_eq!(step(&mut c, &[0.0], &[0.05], &mut u), actuation_status::OK);
        assert!((u[0] - 0.5).abs() < 1e-15);
        let s = step(&mut c, &[0.0], &[1.0], &mut u);
        assert_eq!(u[0], 1.0);
        assert_ne!(s & actuation_status::SATURATED, 0);
    }

    #[test]
    fn wrong_matrix_sizes_are_refused_with_the_sizes_named() {
        let err = LtiController::new(
            DMatrix::zeros(2, 2),
            DMatrix::zeros(2, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(2, 1),
            ControllerInput::Y,
            counts(1, 0, 1),
            None,
        )
        .err()
        .unwrap();
        assert!(err.contains("d is 2×1, expected 1×1"), "{err}");
    }

    #[test]
    fn a_non_finite_output_never_leaves_the_controller() {
        let mut c = LtiController::new(
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, 1),
            DMatrix::zeros(1, 0),
            DMatrix::from_element(1, 1, 1.0),
            ControllerInput::Y,
            counts(1, 0, 1),
            None,
        )
        .unwrap();
        let mut u = [0.0];
        let s = step(&mut c, &[f64::NAN], &[], &mut u);
        assert!(u[0].is_finite());
        assert_ne!(s & actuation_status::CONTROLLER_FAULT, 0);
    }
}
