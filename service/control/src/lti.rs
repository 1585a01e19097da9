//! [`LtiController`] is a discrete-time linear time-invariant controller
//!
//! ```text
//!   x_{k+1} = A x_k + B e_k,      u_k = sat(C x_k + D e_k),
//! ```
//!
//! whose input `e_k` is `y_k`, the tracking error `r_k − y_k`, or the stack `[y_k; r_k]`
//! ([`ControllerInput`]), given as a matrix of discrete transfer functions or in state space.
//!

use crate::ParamError;
use crate::controller::{Controller, Dimensions, MAX_INTERNALS, OutputLimits, StepInput, status};
use nalgebra::{DMatrix, DVector};

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
    counts: Dimensions,
    limits: Option<OutputLimits>,
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
        let params = LtiParams {
            a,
            b,
            c,
            d,
            x0: None,
            input,
            limits,
        };
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
        Ok(Self {
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
        })
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

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
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
        let mut status = status::OK;
        if self.x_next.iter().all(|v| v.is_finite()) {
            core::mem::swap(&mut self.x, &mut self.x_next);
        } else {
            // A diverging controller state is reset rather than propagated.
            self.x.copy_from(&self.x0);
            status |= status::CONTROLLER_FAULT;
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
                    status |= status::CONTROLLER_FAULT;
                }
                false
            }
        };
        if clipped {
            status |= status::SATURATED;
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

    fn counts(n_y: usize, n_r: usize, n_u: usize) -> Dimensions {
        Dimensions {
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
        let limits = OutputLimits {
            min: vec![-1.0],
            max: vec![1.0],
        };
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
}
