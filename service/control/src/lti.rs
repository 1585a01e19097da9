//! [`LtiController`] is a discrete-time linear time-invariant controller
//!
//! ```text
//!   x_{k+1} = A x_k + B e_k,      u_k = sat(C x_k + D e_k),
//! ```
//!
//! whose input `e_k` is `y_k`, the tracking error `r_k − y_k`, or the stack `[y_k; r_k]`
//! ([`ControllerInput`]), given as a matrix of discrete transfer functions or in state space.
//!
//! # Ahead form (`D = 0`)
//!
//! With `D = 0` the input `u_k = sat(C x_k)` does not depend on `e_k`, so it is known as
//! soon as sample `k − 1` is in, and [`Controller::ahead`] is `Some`
//! ([`LtiParams::answers_ahead`]). [`Ahead::advance`] takes sample `k` in exactly as
//! [`Controller::step`] does, `x_{k+1} = A x_k + B e_k` (a diverging state is reset to
//! `x_0` with [`status::CONTROLLER_FAULT`]), and prepares the ready input
//! `u_{k+1} = sat(C x_{k+1})`; the input the plant applied does not enter the state, and
//! there is nothing to adapt. So the inputs of `ready; advance` per sample equal those of
//! `step`, bit for bit up to the sign of an exact zero (`step` adds `D e_k = 0`). After a
//! reset the ready input is `sat(C x_0)`.
//!
//! **The plan** ([`Ahead::plan`]) is the controller's response with its input predicted
//! at its set point: `e = 0` for `input = "y"` (regulation: `y` predicted at 0) and for
//! `"error"` (`y` predicted at `r`), and `e = [0; r_k]` for `"y-and-r"` (`y` predicted
//! at 0, `r` held at `r_k`):
//!
//! ```text
//! x̂_{k+2+j} = A x̂_{k+1+j} + B ê,   x̂_{k+1} = x_{k+1},   row j = sat(C x̂_{k+2+j})
//! ```
//!
//! exact as far as the measurements stay at their set point; it ends early if the
//! predicted state leaves the finite numbers.
//!

use crate::ParamError;
use crate::ahead::Ahead;
use crate::controller::{Controller, Dimensions, MAX_INTERNALS, OutputLimits, StepInput, status};
use crate::output_limits::limit_output;
use nalgebra::{DMatrix, DVector};

pub mod builder;

pub use builder::LtiBuilder;

/// What feeds an [`LtiController`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ControllerInput {
    /// `e_k = y_k` (disturbance rejection, regulation); the default, as in the service's
    /// configuration.
    #[default]
    Y,
    /// `e_k = r_k − y_k` (tracking; needs `n_r = n_y`).
    Error,
    /// `e_k = [y_k; r_k]` (two-degree-of-freedom).
    YAndR,
}

impl ControllerInput {
    /// Every kind of controller input.
    pub const ALL: [ControllerInput; 3] = [
        ControllerInput::Y,
        ControllerInput::Error,
        ControllerInput::YAndR,
    ];
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
    counts: Dimensions,
    limits: Option<OutputLimits>,
    /// [`LtiParams::answers_ahead`], computed once at construction.
    ahead: bool,
    /// The ahead form's ready input `sat(C x_{k+1})` and its status bits.
    ready_u: Vec<f64>,
    ready_status: u32,
    /// Plan scratch: the predicted state, its successor, the predicted controller input
    /// and output.
    x_plan: DVector<f64>,
    x_plan_next: DVector<f64>,
    e_plan: DVector<f64>,
    u_plan: DVector<f64>,
}

/// The parameters of an [`LtiController`]: its discrete state-space matrices, initial
/// state, input and saturation.
#[derive(Debug, Clone, PartialEq)]
pub struct LtiParams {
    /// `A` (`n × n`).
    pub a: DMatrix<f64>,
    /// `B` (`n × n_e`, `n_e` the number of controller inputs).
    pub b: DMatrix<f64>,
    /// `C` (`n_u × n`).
    pub c: DMatrix<f64>,
    /// `D` (`n_u × n_e`).
    pub d: DMatrix<f64>,
    /// Initial state (also the state [`Controller::reset`] returns to); `None`: zero.
    pub x0: Option<DVector<f64>>,
    /// What feeds the controller.
    pub input: ControllerInput,
    /// Output saturation.
    pub limits: Option<OutputLimits>,
}

impl LtiParams {
    /// Whether the controller answers ahead ([`Controller::ahead`] is `Some`, module docs
    /// "Ahead form"): when `D` is all zeros, so that `u_k = C x_k` does not depend on
    /// `e_k`. The service's configuration check calls this to decide whether the loop may
    /// answer first or send ahead.
    pub fn answers_ahead(&self) -> bool {
        self.d.iter().all(|v| *v == 0.0)
    }

    /// The number of controller inputs `n_e` for a rig with `counts`: `n_y`, or
    /// `n_y + n_r` for [`ControllerInput::YAndR`].
    pub fn input_len(input: ControllerInput, counts: Dimensions) -> usize {
        match input {
            ControllerInput::YAndR => counts.n_y + counts.n_r,
            ControllerInput::Y | ControllerInput::Error => counts.n_y,
        }
    }

    /// Checks the parameters against the rig's channels without building anything.
    ///
    /// # Errors
    ///
    /// `"input"`: `input = "error"` without one command per measurement; `"a"`, `"b"`,
    /// `"c"`, `"d"`: a matrix of the wrong size (the message names the sizes) or with a
    /// non-finite entry; `"x0"`: an initial state of the wrong length;
    /// `"u-min"`: limits of the wrong length or with `min > max`.
    pub fn validate(&self, counts: Dimensions) -> Result<(), ParamError> {
        let n = self.a.nrows();
        let (n_y, n_r, n_u) = (counts.n_y, counts.n_r, counts.n_u);
        if self.input == ControllerInput::Error && n_r != n_y {
            return Err(ParamError::new(
                "input",
                format!(
                    "input = \"error\" needs as many commands as measurements (r: {n_r}, y: {n_y})"
                ),
            ));
        }
        let n_e = Self::input_len(self.input, counts);
        let shape = |name: &'static str, m: &DMatrix<f64>, r: usize, c: usize| {
            if m.nrows() != r || m.ncols() != c {
                Err(ParamError::new(
                    name,
                    format!(
                        "{name} is {}×{}, expected {r}×{c} ({n} states, {n_e} controller inputs, {n_u} outputs u)",
                        m.nrows(),
                        m.ncols()
                    ),
                ))
            } else if m.iter().any(|v| !v.is_finite()) {
                Err(ParamError::new(
                    name,
                    format!("{name} has a non-finite entry"),
                ))
            } else {
                Ok(())
            }
        };
        shape("a", &self.a, n, n)?;
        shape("b", &self.b, n, n_e)?;
        shape("c", &self.c, n_u, n)?;
        shape("d", &self.d, n_u, n_e)?;
        if let Some(x0) = &self.x0
            && x0.len() != n
        {
            return Err(ParamError::new(
                "x0",
                format!(
                    "initial state has {} entries, the controller has {n} states",
                    x0.len()
                ),
            ));
        }
        if let Some(l) = &self.limits {
            l.validate(n_u)?;
        }
        Ok(())
    }
}

impl LtiController {
    /// Builds the controller from its discrete state-space matrices for a rig with
    /// `counts` (zero initial state; see [`LtiController::from_params`]).
    ///
    /// # Errors
    ///
    /// Those of [`LtiParams::validate`].
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        input: ControllerInput,
        counts: Dimensions,
        limits: Option<OutputLimits>,
    ) -> Result<Self, ParamError> {
        let params = LtiParams::builder(a, b, c, d)
            .input(input)
            .limits(limits)
            .build(counts)?;
        Self::from_params(&params, counts)
    }

    /// Builds the controller for a rig with `counts` (allocating), after
    /// [`LtiParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`LtiParams::validate`].
    pub fn from_params(params: &LtiParams, counts: Dimensions) -> Result<Self, ParamError> {
        params.validate(counts)?;
        let n = params.a.nrows();
        let n_e = LtiParams::input_len(params.input, counts);
        let x0 = params.x0.clone().unwrap_or_else(|| DVector::zeros(n));
        let mut c = Self {
            x: x0.clone(),
            x0,
            x_next: DVector::zeros(n),
            e: DVector::zeros(n_e),
            u: DVector::zeros(counts.n_u),
            a: params.a.clone(),
            b: params.b.clone(),
            c: params.c.clone(),
            d: params.d.clone(),
            input: params.input,
            counts,
            limits: params.limits.clone(),
            ahead: params.answers_ahead(),
            ready_u: vec![0.0; counts.n_u],
            ready_status: status::OK,
            x_plan: DVector::zeros(n),
            x_plan_next: DVector::zeros(n),
            e_plan: DVector::zeros(n_e),
            u_plan: DVector::zeros(counts.n_u),
        };
        c.reset();
        Ok(c)
    }

    /// Number of controller states.
    pub fn order(&self) -> usize {
        self.x.len()
    }

    /// The controller input `e_k` of sample `k` (module docs); entries whose signal is
    /// missing keep their previous value.
    fn take_e(&mut self, input: &StepInput<'_>) {
        let n_y = self.counts.n_y;
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
                    let v = match i.checked_sub(n_y) {
                        None => input.y.get(i),
                        Some(j) => input.r.get(j),
                    };
                    if let Some(v) = v {
                        *e = *v;
                    }
                }
            }
        }
    }

    /// `x_{k+1} = A x_k + B e_k`; a diverging state is reset to `x_0` and reported as
    /// `CONTROLLER_FAULT`.
    fn advance_state(&mut self) -> u32 {
        self.x_next.gemv(1.0, &self.a, &self.x, 0.0);
        self.x_next.gemv(1.0, &self.b, &self.e, 1.0);
        if self.x_next.iter().all(|v| v.is_finite()) {
            core::mem::swap(&mut self.x, &mut self.x_next);
            status::OK
        } else {
            // A diverging controller state is reset rather than propagated.
            self.x.copy_from(&self.x0);
            status::CONTROLLER_FAULT
        }
    }

    /// The ready input `sat(C x)` of the current state; returns its saturation bits.
    fn prepare_ready(&mut self) -> u32 {
        self.u.gemv(1.0, &self.c, &self.x, 0.0);
        for (dst, src) in self.ready_u.iter_mut().zip(self.u.iter()) {
            *dst = *src;
        }
        limit_output(self.limits.as_ref(), &mut self.ready_u)
    }
}

/// The ahead form for `D = 0` (module docs).
impl Ahead for LtiController {
    /// `sat(C x_{k+1})` as prepared by the last [`Ahead::advance`] (`sat(C x_0)` after a
    /// reset).
    fn ready(&self, u: &mut [f64]) -> u32 {
        for (d, s) in u.iter_mut().zip(&self.ready_u) {
            *d = *s;
        }
        self.ready_status
    }

    /// `x_{k+1} = A x_k + B e_k` as in [`Controller::step`], then the ready input
    /// `sat(C x_{k+1})`. `applied` and `adapt` are not used: the state holds no input and
    /// nothing is learned.
    fn advance(&mut self, input: &StepInput<'_>, _applied: &[f64], _adapt: bool) -> u32 {
        self.take_e(input);
        let status = self.advance_state();
        self.ready_status = status | self.prepare_ready();
        self.ready_status
    }

    /// The response with the controller input at its set point (module docs): `e = 0`,
    /// or `[0; r_k]` for `"y-and-r"`.
    fn plan(&mut self, out: &mut [f64]) -> usize {
        let n_u = self.counts.n_u;
        if n_u == 0 {
            return 0;
        }
        let n_y = self.counts.n_y;
        for (i, (d, s)) in self.e_plan.iter_mut().zip(self.e.iter()).enumerate() {
            *d = if self.input == ControllerInput::YAndR && i >= n_y {
                *s
            } else {
                0.0
            };
        }
        self.x_plan.copy_from(&self.x);
        let mut rows = 0;
        for row in out.chunks_exact_mut(n_u) {
            self.x_plan_next.gemv(1.0, &self.a, &self.x_plan, 0.0);
            self.x_plan_next.gemv(1.0, &self.b, &self.e_plan, 1.0);
            if !self.x_plan_next.iter().all(|v| v.is_finite()) {
                break;
            }
            core::mem::swap(&mut self.x_plan, &mut self.x_plan_next);
            self.u_plan.gemv(1.0, &self.c, &self.x_plan, 0.0);
            for (dst, src) in row.iter_mut().zip(self.u_plan.iter()) {
                *dst = *src;
            }
            let _ = limit_output(self.limits.as_ref(), row);
            rows += 1;
        }
        rows
    }

    fn plan_source(&self) -> &'static str {
        "u_{k+1} = C x_{k+1} exact; beyond it the controller's response with y predicted at \
         its set point (e = 0; r held for y-and-r)"
    }
}

impl Controller for LtiController {
    fn kind(&self) -> &'static str {
        "lti"
    }

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        self.take_e(input);
        // u = C x + D e
        self.u.gemv(1.0, &self.c, &self.x, 0.0);
        self.u.gemv(1.0, &self.d, &self.e, 1.0);
        // x+ = A x + B e
        let mut status = self.advance_state();
        for (dst, src) in u.iter_mut().zip(self.u.iter()) {
            *dst = *src;
        }
        status |= limit_output(self.limits.as_ref(), u);
        status
    }

    /// Returns to `x_0`; the ready input is `sat(C x_0)`.
    fn reset(&mut self) {
        self.x.copy_from(&self.x0);
        self.ready_status = self.prepare_ready();
    }

    /// `Some` when `D = 0` ([`LtiParams::answers_ahead`]).
    fn ahead(&mut self) -> Option<&mut dyn Ahead> {
        if self.ahead { Some(self) } else { None }
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

    fn counts(n_y: usize, n_r: usize, n_u: usize) -> Dimensions {
        Dimensions {
            n_y,
            n_z: n_y,
            n_r,
            n_u,
        }
    }

    /// Sample `seq` with the measurements `y` (also the performance `z`) and commands `r`.
    fn sample<'a>(seq: usize, y: &'a [f64], r: &'a [f64]) -> StepInput<'a> {
        StepInput {
            seq: seq as u64,
            y,
            z: y,
            r,
            ..Default::default()
        }
    }

    fn step(c: &mut LtiController, y: &[f64], r: &[f64], u: &mut [f64]) -> u32 {
        c.step(&sample(0, y, r), u)
    }

    /// The static gain `u = d e` (no states) of one input to one output.
    fn static_gain(
        d: f64,
        input: ControllerInput,
        counts: Dimensions,
        limits: Option<OutputLimits>,
    ) -> LtiController {
        LtiController::new(
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, 1),
            DMatrix::zeros(1, 0),
            DMatrix::from_element(1, 1, d),
            input,
            counts,
            limits,
        )
        .unwrap()
    }

    #[test]
    fn the_builder_starts_at_the_defaults_and_names_a_refused_field() {
        let one = || DMatrix::from_element(1, 1, 1.0);
        let p = LtiParams::builder(one(), one(), one(), one())
            .build(counts(1, 0, 1))
            .unwrap();
        assert_eq!((p.x0, p.input, p.limits), (None, ControllerInput::Y, None));
        let refused = LtiParams::builder(one(), one(), one(), one())
            .x0(Some(DVector::zeros(2)))
            .build(counts(1, 0, 1));
        assert_eq!(refused.unwrap_err().field, "x0");
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
        let limits = OutputLimits::symmetric(1.0, 1);
        let mut c = static_gain(10.0, ControllerInput::Error, counts(1, 1, 1), Some(limits));
        let mut u = [0.0];
        assert_eq!(step(&mut c, &[0.0], &[0.05], &mut u), status::OK);
        assert!((u[0] - 0.5).abs() < 1e-15);
        let s = step(&mut c, &[0.0], &[1.0], &mut u);
        assert_eq!(u[0], 1.0);
        assert_ne!(s & status::SATURATED, 0);
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
        assert_eq!(err.field, "d");
        assert!(err.message.contains("d is 2×1, expected 1×1"), "{err}");
    }

    #[test]
    fn a_non_finite_output_never_leaves_the_controller() {
        let mut c = static_gain(1.0, ControllerInput::Y, counts(1, 0, 1), None);
        let mut u = [0.0];
        let s = step(&mut c, &[f64::NAN], &[], &mut u);
        assert!(u[0].is_finite());
        assert_ne!(s & status::CONTROLLER_FAULT, 0);
    }

    #[test]
    fn a_non_finite_output_within_limits_is_a_fault_not_a_saturation() {
        let limits = OutputLimits::symmetric(1.0, 1);
        let mut c = static_gain(1.0, ControllerInput::Y, counts(1, 0, 1), Some(limits));
        let mut u = [0.0];
        let s = step(&mut c, &[f64::NAN], &[], &mut u);
        assert_eq!(u, [0.0]);
        assert_eq!(s & status::CONTROLLER_FAULT, status::CONTROLLER_FAULT);
        assert_eq!(s & status::SATURATED, 0);
    }

    /// A second-order controller with `D = 0`, saturated to ±1, fed by `input`.
    fn strictly_proper(input: ControllerInput, counts: Dimensions) -> LtiController {
        let n_e = LtiParams::input_len(input, counts);
        let params = LtiParams::builder(
            DMatrix::from_row_slice(2, 2, &[0.9, 0.2, -0.1, 0.7]),
            DMatrix::from_fn(2, n_e, |i, j| 0.5 - 0.3 * i as f64 + 0.2 * j as f64),
            DMatrix::from_row_slice(1, 2, &[1.5, -0.8]),
            DMatrix::zeros(1, n_e),
        )
        .x0(Some(DVector::from_vec(vec![0.1, -0.2])))
        .input(input)
        .limits(Some(OutputLimits::symmetric(1.0, 1)))
        .build(counts)
        .unwrap();
        assert!(params.answers_ahead());
        LtiController::from_params(&params, counts).unwrap()
    }

    /// Two equal [`strictly_proper`] controllers fed by `input`, on a rig with one
    /// measurement, command and input.
    fn twins(input: ControllerInput) -> (LtiController, LtiController) {
        let dims = counts(1, 1, 1);
        (strictly_proper(input, dims), strictly_proper(input, dims))
    }

    /// A deterministic test signal.
    fn wave(k: usize, f: f64) -> f64 {
        (f * k as f64).sin() + 0.3 * (2.7 * f * k as f64).cos()
    }

    /// For `D = 0` the inputs of `ready; advance` per sample equal those of `step` bit for
    /// bit, with the same status bits, for every kind of controller input, saturation
    /// included.
    #[test]
    fn the_ahead_inputs_equal_the_step_inputs_for_a_strictly_proper_controller() {
        for input in ControllerInput::ALL {
            let (mut stepped, mut ahead) = twins(input);
            let (mut u, mut v) = ([0.0], [0.0]);
            let mut saturated = 0;
            for k in 0..500 {
                let (y, r) = ([wave(k, 0.11)], [0.5 * wave(k, 0.03)]);
                let sample = sample(k, &y, &r);
                let s = stepped.step(&sample, &mut u);
                let a = ahead.ahead().expect("D = 0 answers ahead");
                let t = a.ready(&mut v);
                a.advance(&sample, &v, true);
                assert_eq!(
                    (u[0].to_bits(), s),
                    (v[0].to_bits(), t),
                    "{input:?}, sample {k}"
                );
                saturated += usize::from(s & status::SATURATED != 0);
            }
            assert!(saturated > 0, "{input:?}: saturation must be exercised");
        }
    }

    #[test]
    fn a_controller_with_a_feedthrough_does_not_answer_ahead() {
        let mut c = static_gain(0.5, ControllerInput::Y, counts(1, 0, 1), None);
        assert!(c.ahead().is_none());
        let mut c = static_gain(0.0, ControllerInput::Y, counts(1, 0, 1), None);
        assert!(c.ahead().is_some());
    }

    /// The plan is the response with the controller input at its set point: after 50
    /// samples, its rows equal, bit for bit, the ready inputs of a second controller with
    /// the same history fed `y = 0` (`"y"`, and `"y-and-r"` with `r` held) or `y = r`
    /// (`"error"`); and they leave the ready input (the response is not trivial). A
    /// predicted state that overflows ends the plan early.
    #[test]
    fn the_plan_is_the_response_with_the_controller_input_at_its_set_point() {
        for input in ControllerInput::ALL {
            let (mut planner, mut follower) = twins(input);
            let mut u = [0.0];
            let r_k = [0.4];
            for k in 0..50 {
                let (y, r) = ([wave(k, 0.11)], if k == 49 { r_k } else { [0.1] });
                let sample = sample(k, &y, &r);
                for c in [&mut planner, &mut follower] {
                    c.ready(&mut u);
                    c.advance(&sample, &u, true);
                }
            }
            let mut plan = [f64::NAN; 30];
            assert_eq!(planner.plan(&mut plan), 30);
            let mut ready = [0.0];
            planner.ready(&mut ready);
            assert!(plan.iter().any(|v| *v != ready[0]), "{input:?}");
            let y = if input == ControllerInput::Error {
                r_k
            } else {
                [0.0]
            };
            for (j, row) in plan.iter().enumerate() {
                let sample = StepInput {
                    seq: 50 + j as u64,
                    y: &y,
                    z: &y,
                    r: &r_k,
                    ..Default::default()
                };
                follower.advance(&sample, &u, true);
                follower.ready(&mut u);
                assert_eq!(row.to_bits(), u[0].to_bits(), "{input:?}, row {j}");
            }
        }
        let mut wild = LtiController::from_params(
            &LtiParams {
                a: DMatrix::from_element(1, 1, 1e100),
                b: DMatrix::zeros(1, 1),
                c: DMatrix::from_element(1, 1, 1.0),
                d: DMatrix::zeros(1, 1),
                x0: Some(DVector::from_element(1, 1.0)),
                input: ControllerInput::Y,
                limits: None,
            },
            counts(1, 0, 1),
        )
        .unwrap();
        // x̂ = 1e100, 1e200, 1e300, then ∞: three rows.
        assert_eq!(wild.plan(&mut [0.0; 8]), 3);
    }
}
