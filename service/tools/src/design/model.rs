//! The discrete model of a scenario plant, exactly as plant-proxy simulates it, and its
//! frequency response.
//!
//! plant-proxy discretizes the continuous plant with an ideal zero-order hold at `T_s`
//! (`Φ = e^{A T_s}`, `Γ = ∫ e^{A s} ds B`), delays control input `j` by `d_j` samples, and
//! samples `y_k` just before `u_k` is applied, so a feedthrough `D` acts one sample late.
//! The discrete transfer matrix from `u` to `y` (or `z`) is therefore
//!
//! ```text
//! G_d(z)_{:, j} = z^{−d_j} [ C (zI − Φ)^{−1} Γ_{:, j} + D_{:, j} z^{−1} ]
//! ```
//!
//! which is what [`DiscreteModel`] holds and [`DiscreteModel::frf`] evaluates on
//! `z = e^{jθ}`.

use super::{C64, Frf};
use nalgebra::DMatrix;
use plant_proxy::lti::{LtiError, StateSpace};
use plant_proxy::scenario::Scenario;

/// Which outputs of the plant a response is taken to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputSet {
    /// The measurements `y`.
    Y,
    /// The performance outputs `z`.
    Z,
}

/// The discrete model from the control inputs `u` to one output set.
#[derive(Debug, Clone)]
pub struct DiscreteModel {
    /// `(Φ, Γ, C, D)` at `ts` (the `D` acting one sample late, see the module docs).
    pub ss: StateSpace,
    /// Pure delay of each input, samples.
    pub delays: Vec<usize>,
    /// Sample period, s.
    pub ts: f64,
}

/// A scenario's plant that cannot be modelled, naming the scenario (or the frequency).
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The plant's state-space matrices are refused.
    #[error("{origin}: plant: {source}")]
    Plant {
        /// The scenario.
        origin: String,
        /// Why.
        #[source]
        source: LtiError,
    },
    /// The plant cannot be discretized.
    #[error("{origin}: discretizing the plant: {source}")]
    Discretize {
        /// The scenario.
        origin: String,
        /// Why.
        #[source]
        source: LtiError,
    },
    /// The response at a frequency cannot be computed.
    #[error("model response at θ = {theta}: {source}")]
    Response {
        /// The frequency, rad/sample.
        theta: f64,
        /// Why.
        #[source]
        source: LtiError,
    },
}

message_from!(ModelError);

impl DiscreteModel {
    /// The model of `scenario`'s plant from `u` to `outputs`, discretized at the
    /// scenario's sample period.
    pub fn from_scenario(scenario: &Scenario, outputs: OutputSet) -> Result<Self, ModelError> {
        let p = &scenario.plant.model;
        let (c, d) = match outputs {
            OutputSet::Y => (p.c_y.clone(), p.d_yu.clone()),
            OutputSet::Z => (p.c_z.clone(), p.d_zu.clone()),
        };
        let ts = scenario.rig.sample_period;
        let cont = StateSpace::new(p.a.clone(), p.b_u.clone(), c, d).map_err(|source| {
            ModelError::Plant {
                origin: scenario.origin.clone(),
                source,
            }
        })?;
        let ss = cont.c2d_zoh(ts).map_err(|source| ModelError::Discretize {
            origin: scenario.origin.clone(),
            source,
        })?;
        Ok(Self {
            ss,
            delays: scenario.plant.input_delays.clone(),
            ts,
        })
    }

    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.ss.n_inputs()
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.ss.n_outputs()
    }

    /// `G_d(e^{jθ})` on the grid `theta` (rad/sample).
    pub fn frf(&self, theta: &[f64]) -> Result<Frf, ModelError> {
        let (p, m) = (self.n_outputs(), self.n_inputs());
        Frf::try_from_fn(self.ts, theta, (p, m), |th| {
            let z = C64::from_polar(1.0, th);
            let g = self
                .ss
                .freq_response(z)
                .map_err(|source| ModelError::Response { theta: th, source })?;
            let zinv = z.inv();
            Ok(DMatrix::from_fn(p, m, |o, i| {
                let v = g[(o, i)] - C64::new(self.ss.d[(o, i)], 0.0)
                    + C64::new(self.ss.d[(o, i)], 0.0) * zinv;
                v * zinv.powu(self.delays[i] as u32)
            }))
        })
    }

    /// The first `count` Markov parameters of the delayed model, `H_0 … H_{count−1}`
    /// (`p × m` each): the response `y_k` to a unit pulse `u_0 = e_j` from rest, delays
    /// and the late feedthrough included.
    pub fn markov(&self, count: usize) -> Vec<DMatrix<f64>> {
        let (p, m) = (self.n_outputs(), self.n_inputs());
        // Undelayed: H_0 = 0, H_1 = D + CΓ, H_i = C Φ^{i−1} Γ.
        let base = self.ss.markov_parameters(count + 1);
        let mut out = vec![DMatrix::zeros(p, m); count];
        for j in 0..m {
            let d = self.delays[j];
            for i in 1..count {
                if i < d + 1 {
                    continue;
                }
                let k = i - d; // k ≥ 1
                for o in 0..p {
                    let mut v = base[k][(o, j)];
                    if k == 1 {
                        v += self.ss.d[(o, j)];
                    }
                    out[i][(o, j)] = v;
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_proxy::scenario;

    /// Two inputs with delays 3 and 5 and a feedthrough on the first: a 2-state plant.
    const PLANT: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/fixtures/design/state-space-two-delayed-inputs.toml"
    ));

    #[test]
    fn the_response_is_the_sum_of_the_markov_parameters() {
        let sc = scenario::parse(PLANT, "test").unwrap();
        let m = DiscreteModel::from_scenario(&sc, OutputSet::Y).unwrap();
        let h = m.markov(3000);
        // Delays: nothing before sample d_j + 1; the late feedthrough shows at d_0 + 1.
        for k in 0..=3 {
            assert_eq!(h[k][(0, 0)], 0.0);
        }
        for k in 0..=5 {
            assert_eq!(h[k][(0, 1)], 0.0);
        }
        assert!(h[4][(0, 0)].abs() > 0.4 && h[6][(0, 1)] != 0.0);
        let theta = [0.05, 0.2, 0.7, 2.0, 3.1];
        let g = m.frf(&theta).unwrap();
        for (k, &t) in theta.iter().enumerate() {
            for j in 0..2 {
                let fir: C64 = h
                    .iter()
                    .enumerate()
                    .map(|(i, hi)| C64::from_polar(hi[(0, j)], -t * i as f64))
                    .sum();
                let exact = g.channel(0, j)[k];
                assert!(
                    (fir - exact).norm() < 1e-9 * exact.norm(),
                    "θ = {t}, input {j}"
                );
            }
        }
    }
}
