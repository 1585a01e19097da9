//! The frequency response of an RCAC target model `G_f` (3.39), (3.49), for the design
//! tools' figures and checks.

use super::{C64, Frf, horner};
use control::target::{TargetForm, TargetModel};
use nalgebra::DMatrix;

/// `G_f(e^{jθ})` of a target model.
pub trait TargetResponse {
    /// `G_f(e^{jθ})` of every channel on the grid `theta` (β and delays included).
    fn frf(&self, theta: &[f64]) -> Frf;
}

impl TargetResponse for TargetModel {
    fn frf(&self, theta: &[f64]) -> Frf {
        let (p, m) = (self.outputs, self.inputs);
        Frf::from_fn(self.sample_period, theta, (p, m), |th| {
            let zinv = C64::from_polar(1.0, -th);
            let mut g = DMatrix::from_element(p, m, C64::new(0.0, 0.0));
            match &self.form {
                TargetForm::TransferFunction(ch) => {
                    let z = zinv.inv();
                    for c in ch {
                        let h = horner(&c.num, z) / horner(&c.den, z);
                        g[(c.output, c.input)] = h * zinv.powu(c.delay as u32) * self.beta;
                    }
                }
                TargetForm::Markov(hs) => {
                    for o in 0..p {
                        for i in 0..m {
                            let mut acc = C64::new(0.0, 0.0);
                            for h in hs.iter().rev() {
                                acc = acc * zinv + h[(o, i)];
                            }
                            g[(o, i)] = acc * self.beta;
                        }
                    }
                }
            }
            g
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use service::config::TargetModelFile;

    fn tf_model() -> TargetModel {
        let text = include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../tests/fixtures/target-model/two-input-transfer-function.toml"
        ));
        TargetModel::parse(text, "two-input-transfer-function.toml").unwrap()
    }

    #[test]
    fn the_response_of_the_markov_form_equals_the_transfer_functions() {
        let m = tf_model();
        // The FIR form built from 400 Markov parameters has the same response (the poles
        // are well inside the unit circle, so the tail is negligible).
        let fir = TargetModel {
            form: TargetForm::Markov(m.markov(400)),
            beta: 1.0,
            ..m.clone()
        };
        let th = [0.01, 0.3, 1.0, 2.5];
        let (a, b) = (m.frf(&th), fir.frf(&th));
        for c in 0..2 {
            for k in 0..th.len() {
                assert!((a.response[c][k] - b.response[c][k]).norm() < 1e-9);
            }
        }
    }
}
