//! [`LtiController`] is a discrete-time linear time-invariant controller
//!
//! ```text
//!   x_{k+1} = A x_k + B e_k,      u_k = sat(C x_k + D e_k),
//! ```
//!
//! whose input `e_k` is `y_k`, the tracking error `r_k − y_k`, or the stack `[y_k; r_k]`
//! ([`ControllerInput`]), given as a matrix of discrete transfer functions or in state space.
//!

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

impl LtiController {
    /// Builds the controller from its discrete state-space matrices. `counts` gives the
    /// channels of the rig; the matrix sizes must agree with them and with `input`.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        input: ControllerInput,
        counts: Dimensions,
        limits: Option<OutputLimits>,
    ) -> Result<Self, String> {
        let n = a.nrows();
        let n_y = counts.n_y;
        let n_r = counts.n_r;
        let n_u = counts.n_u;
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
        assert_ne!(s & status::CONTROLLER_FAULT, 0);
    }
}
