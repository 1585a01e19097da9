//! The reference model (4.4) and the model-following error.
//!
//! ```text
//! y_{m,k} = N_m(q⁻¹) / D_m(q⁻¹) r_k                                                 (4.4)
//! N_m(q⁻¹) = Σ_{i=0}^{n} N_{m,i} q⁻ⁱ   ((4.5): N_{m,i} = 0 for i < n_r)
//! D_m(q⁻¹) = 1 + Σ_{i=1}^{n} D_{m,i} q⁻ⁱ                                             (4.6)
//! e_k      = y_k − y_{m,k}
//! ```
//!
//! run as the difference equation `y_{m,k} = Σ_i N_{m,i} r_{k−i} − Σ_{i≥1} D_{m,i} y_{m,k−i}`
//! from zero initial conditions.

use super::history::History;

/// The reference model `N_m/D_m` (4.4) as a difference equation; allocation-free after
/// [`ReferenceModel::new`].
#[derive(Debug, Clone)]
pub struct ReferenceModel {
    num: Vec<f64>,
    den: Vec<f64>,
    r: History,
    ym: History,
}

impl ReferenceModel {
    /// The model with numerator `N_m` and monic denominator `D_m` (coefficients of
    /// `q⁰, q⁻¹, …`); the controllers' parameter checks validate them (`D_m` monic and
    /// asymptotically stable).
    pub fn new(n_m: &[f64], d_m: &[f64]) -> Self {
        Self {
            num: n_m.to_vec(),
            den: d_m.to_vec(),
            r: History::new(n_m.len()),
            ym: History::new(d_m.len()),
        }
    }

    /// Takes `r_k` and returns `y_{m,k}` (4.4). A non-finite result (a huge or
    /// non-finite command) clears the model's state and returns NaN.
    pub fn step(&mut self, r: f64) -> f64 {
        self.r.push(r);
        let mut y = self.r.fir(&self.num, 0);
        for (i, d) in self.den.iter().enumerate().skip(1) {
            y -= d * self.ym.get(i - 1);
        }
        if y.is_finite() {
            self.ym.push(y);
            y
        } else {
            self.reset();
            f64::NAN
        }
    }

    /// Back to zero initial conditions.
    pub fn reset(&mut self) {
        self.r.clear();
        self.ym.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_step_response_follows_the_difference_equation() {
        // N_m/D_m = (q⁻¹ − 0.5 q⁻²)/(1 + 0.25 q⁻²) (4.84), unit step.
        let mut m = ReferenceModel::new(&[0.0, 1.0, -0.5], &[1.0, 0.0, 0.25]);
        let y: Vec<f64> = (0..5).map(|_| m.step(1.0)).collect();
        // y_k = r_{k−1} − 0.5 r_{k−2} − 0.25 y_{k−2}.
        assert_eq!(y, vec![0.0, 1.0, 0.5, 0.25, 0.375]);
        assert!(m.step(f64::INFINITY).is_nan());
        assert_eq!(m.step(0.0), 0.0);
    }
}
