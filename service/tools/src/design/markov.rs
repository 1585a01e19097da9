//! The FIR target model (3.39) built from the Markov parameters of the discrete model.
//!
//! Section 3.1.4 of the dissertation: with `H_i` the `i`th Markov parameter of
//! `G_{zu,d}(q)` (the response at sample `i` to a unit pulse at sample 0, delays included,
//! so `H_0 = 0` for this plant because a feedthrough acts one sample late),
//!
//! ```text
//! G_f(q) = Σ_{i=0}^{n_f} H_i q^{−i}                                        (3.39)
//! ```
//!
//! is a truncated Laurent expansion of `G_{zu,d}`: it has the structure's relative degree
//! and leading numerator coefficient, and for `n_f` large enough its zeros approximate the
//! nonminimum-phase (NMP) zeros of the structure. [`FirTarget::from_model`] builds it.
//!
//! When the structure is minimum phase and asymptotically stable "only the first nonzero
//! Markov parameter is used in the summation": `G_f(q) = H_d q^{−d}`, `d` the smallest index
//! with `H_d ≠ 0` ([`first_nonzero`], [`FirTarget::first_nonzero`]). For a MIMO plant this
//! is done **matrix-wise**: `d` is the first index at which the *matrix* `H_d` has an entry
//! above `rel_tol · max_{i, o, j} |H_i(o, j)|`, and the whole `H_d` is kept (channels whose
//! own first nonzero parameter comes later are zero in it). [`first_nonzero_per_channel`]
//! gives each channel's own index and value, for a caller that wants a per-channel
//! (diagonal-delay) target instead.
//!
//! `G_f(e^{jθ}) = Σ H_i e^{−jiθ}` is evaluated by [`FirTarget::frf`].

use super::model::DiscreteModel;
use super::{C64, Frf};
use nalgebra::DMatrix;

/// The FIR target model `G_f(q) = Σ_{i=0}^{n_f} H_i q^{−i}` of (3.39).
#[derive(Debug, Clone, PartialEq)]
pub struct FirTarget {
    /// `H_0 … H_{n_f}`, each `p × m` (outputs × inputs); zero matrices are kept so that
    /// `markov[i]` is always the coefficient of `q^{−i}`.
    pub markov: Vec<DMatrix<f64>>,
    /// Sample period of the model, s.
    pub ts: f64,
}

/// How many Markov parameters are enough to decide that a model is zero: past the largest
/// input delay, `n` further parameters (`n` states) being zero makes every later one zero
/// (Cayley–Hamilton), and one more covers the late feedthrough.
fn search_length(model: &DiscreteModel) -> usize {
    model.delays.iter().copied().max().unwrap_or(0) + model.ss.n_states() + 2
}

/// The largest `|H_i(o, j)|` over the Markov parameters `h`.
fn largest_entry(h: &[DMatrix<f64>]) -> f64 {
    h.iter()
        .flat_map(|m| m.iter())
        .fold(0.0_f64, |acc, v| acc.max(v.abs()))
}

/// Markov parameters that cannot be taken as a target model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MarkovError {
    /// A relative tolerance outside `[0, 1)`.
    #[error("relative tolerance {0} must be in [0, 1)")]
    Tolerance(f64),
    /// Every Markov parameter is zero.
    #[error("every Markov parameter of the model is zero")]
    AllZero,
    /// None exceeds the tolerance.
    #[error("no Markov parameter exceeds the tolerance")]
    BelowTolerance,
    /// Every channel is zero.
    #[error("the model is zero")]
    ZeroModel,
    /// Not one delay per input.
    #[error("{delays} delays for {inputs} inputs")]
    Delays {
        /// The delays given.
        delays: usize,
        /// The inputs.
        inputs: usize,
    },
    /// The measured response has no impulse response.
    #[error(transparent)]
    Impulse(#[from] super::welch::ImpulseError),
    /// More Markov parameters than the impulse response holds reliably.
    #[error(
        "{count} Markov parameters from an impulse response of {samples} samples: use 1 … {} \
         (or a longer Welch segment)",
        samples - samples / 4
    )]
    Count {
        /// The parameters asked for.
        count: usize,
        /// The impulse response's length.
        samples: usize,
    },
}

message_from!(MarkovError);

/// The first nonzero Markov parameter of `model`, matrix-wise (see the module docs):
/// the smallest `d` such that some entry of `H_d` exceeds `rel_tol` times the largest entry
/// of `H_0 … H_{d_max + n + 1}` (`d_max` the largest input delay, `n` the number of states),
/// and `H_d` itself. An error when the model is zero to that tolerance or `rel_tol` is not
/// in `[0, 1)`.
pub fn first_nonzero(
    model: &DiscreteModel,
    rel_tol: f64,
) -> Result<(usize, DMatrix<f64>), MarkovError> {
    check_tol(rel_tol)?;
    let h = model.markov(search_length(model));
    let scale = largest_entry(&h);
    if scale == 0.0 {
        return Err(MarkovError::AllZero);
    }
    let threshold = rel_tol * scale;
    h.into_iter()
        .enumerate()
        .find(|(_, m)| m.iter().any(|v| v.abs() > threshold))
        .ok_or(MarkovError::BelowTolerance)
}

/// The first nonzero Markov parameter of each channel, channel-major
/// (`c = output · n_inputs + input`): `Some((d, H_d(o, j)))` with `d` the smallest index
/// where `|H_d(o, j)|` exceeds `rel_tol` times the channel's largest entry, `None` for a
/// channel that is zero. An error when `rel_tol` is not in `[0, 1)`.
pub fn first_nonzero_per_channel(
    model: &DiscreteModel,
    rel_tol: f64,
) -> Result<Vec<Option<(usize, f64)>>, MarkovError> {
    check_tol(rel_tol)?;
    let h = model.markov(search_length(model));
    let (p, m) = (model.n_outputs(), model.n_inputs());
    let mut out = Vec::with_capacity(p * m);
    for o in 0..p {
        for j in 0..m {
            let scale = h.iter().fold(0.0_f64, |acc, x| acc.max(x[(o, j)].abs()));
            out.push(if scale == 0.0 {
                None
            } else {
                h.iter()
                    .enumerate()
                    .find(|(_, x)| x[(o, j)].abs() > rel_tol * scale)
                    .map(|(i, x)| (i, x[(o, j)]))
            });
        }
    }
    Ok(out)
}

fn check_tol(rel_tol: f64) -> Result<(), MarkovError> {
    if (0.0..1.0).contains(&rel_tol) {
        Ok(())
    } else {
        Err(MarkovError::Tolerance(rel_tol))
    }
}

impl FirTarget {
    /// The minimum-phase case of (3.39) channel by channel: entry `(o, j)` of `G_f` is the
    /// channel's own first nonzero Markov parameter at its own delay,
    /// `G_f(q)_{o,j} = H_{d_oj}(o, j) q^{−d_oj}` (see [`first_nonzero_per_channel`]); for a
    /// MIMO plant whose inputs have different delays this keeps every channel, where the
    /// matrix-wise rule keeps only the earliest ones.
    pub fn first_nonzero_per_channel(
        model: &DiscreteModel,
        rel_tol: f64,
    ) -> Result<Self, MarkovError> {
        let firsts = first_nonzero_per_channel(model, rel_tol)?;
        let (p, m) = (model.n_outputs(), model.n_inputs());
        let last = firsts
            .iter()
            .flatten()
            .map(|(d, _)| *d)
            .max()
            .ok_or(MarkovError::ZeroModel)?;
        let mut markov = vec![DMatrix::zeros(p, m); last + 1];
        for (c, f) in firsts.iter().enumerate() {
            if let Some((d, h)) = f {
                markov[*d][(c / m, c % m)] = *h;
            }
        }
        Ok(Self {
            markov,
            ts: model.ts,
        })
    }

    /// (3.39) from measured data: `H_0 … H_{count−1}` are the first samples of the impulse
    /// response of a Welch estimate ([`super::welch::impulse_response`]), with `H_i(·, j)`
    /// set to zero for `i ≤ d_j` (the pure delay of input `j` and the sample of the hold,
    /// where the estimate is noise). `count` must leave the last quarter of the impulse
    /// response out (that part is estimation noise for a causal plant).
    pub fn from_measured(frf: &Frf, delays: &[usize], count: usize) -> Result<Self, MarkovError> {
        let (p, m) = (frf.n_outputs, frf.n_inputs);
        if delays.len() != m {
            return Err(MarkovError::Delays {
                delays: delays.len(),
                inputs: m,
            });
        }
        let h = super::welch::impulse_response(frf)?;
        let l = h.first().map_or(0, |c| c.len());
        if count == 0 || count > l - l / 4 {
            return Err(MarkovError::Count { count, samples: l });
        }
        let markov = (0..count)
            .map(|i| {
                DMatrix::from_fn(
                    p,
                    m,
                    |o, j| if i <= delays[j] { 0.0 } else { h[o * m + j][i] },
                )
            })
            .collect();
        Ok(Self { markov, ts: frf.ts })
    }

    /// (3.39) with order `n_f`: `H_0 … H_{n_f}` of `model` (delays included).
    pub fn from_model(model: &DiscreteModel, n_f: usize) -> Self {
        Self {
            markov: model.markov(n_f + 1),
            ts: model.ts,
        }
    }

    /// The minimum-phase case of (3.39): only the first nonzero Markov parameter
    /// (matrix-wise, see [`first_nonzero`]) is kept, `G_f(q) = H_d q^{−d}`; `markov` holds
    /// `d` zero matrices followed by `H_d`.
    pub fn first_nonzero(model: &DiscreteModel, rel_tol: f64) -> Result<Self, MarkovError> {
        let (d, hd) = first_nonzero(model, rel_tol)?;
        let mut markov = vec![DMatrix::zeros(hd.nrows(), hd.ncols()); d];
        markov.push(hd);
        Ok(Self {
            markov,
            ts: model.ts,
        })
    }

    /// The order `n_f` (the number of Markov parameters minus one).
    pub fn order(&self) -> usize {
        self.markov.len().saturating_sub(1)
    }

    /// Number of outputs `p`.
    pub fn n_outputs(&self) -> usize {
        self.markov.first().map_or(0, |m| m.nrows())
    }

    /// Number of inputs `m`.
    pub fn n_inputs(&self) -> usize {
        self.markov.first().map_or(0, |m| m.ncols())
    }

    /// `G_f(e^{jθ}) = Σ_i H_i e^{−jiθ}`, a `p × m` matrix.
    pub fn eval(&self, theta: f64) -> DMatrix<C64> {
        let (p, m) = (self.n_outputs(), self.n_inputs());
        let step = C64::from_polar(1.0, -theta);
        let mut zi = C64::new(1.0, 0.0);
        let mut g = DMatrix::from_element(p, m, C64::new(0.0, 0.0));
        for h in &self.markov {
            for o in 0..p {
                for j in 0..m {
                    g[(o, j)] += zi * h[(o, j)];
                }
            }
            zi *= step;
        }
        g
    }

    /// `G_f(e^{jθ_k})` on the grid `theta` (rad/sample), as an [`Frf`].
    pub fn frf(&self, theta: &[f64]) -> Frf {
        let size = (self.n_outputs(), self.n_inputs());
        Frf::from_fn(self.ts, theta, size, |th| self.eval(th))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::model::OutputSet;
    use plant_proxy::scenario::parse;
    use plant_proxy::sim::PlantSim;

    /// Two modes, two inputs delayed by 3 and 5 samples, two measurements (one of them a
    /// velocity) and one performance output.
    const TWO_MODES: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/fixtures/design/two-modes-two-delayed-inputs.toml"
    ));

    fn scenario() -> plant_proxy::scenario::Scenario {
        parse(TWO_MODES, "markov-test").expect("the test scenario parses")
    }

    /// `y_k` of the simulator for a unit pulse on input `j` at `k = 0`, from rest.
    fn simulated_pulse(j: usize, count: usize) -> Vec<Vec<f64>> {
        let sc = scenario();
        let mut sim = PlantSim::new(&sc.plant, sc.rig.sample_period).unwrap();
        let (mut y, mut z) = (vec![0.0; sim.n_y()], vec![0.0; sim.n_z()]);
        let mut out = Vec::new();
        for k in 0..count {
            sim.sample_noiseless(&mut y, &mut z).unwrap();
            out.push(y.clone());
            let mut u = vec![0.0; sim.n_u()];
            if k == 0 {
                u[j] = 1.0;
            }
            sim.advance(&u).unwrap();
        }
        out
    }

    #[test]
    fn markov_parameters_equal_the_simulated_pulse_response() {
        let model = DiscreteModel::from_scenario(&scenario(), OutputSet::Y).unwrap();
        let count = 200;
        let h = FirTarget::from_model(&model, count - 1).markov;
        assert_eq!(h.len(), count);
        for j in 0..2 {
            let y = simulated_pulse(j, count);
            let scale = y.iter().flatten().fold(0.0_f64, |a, v| a.max(v.abs()));
            assert!(scale > 1e-3, "the pulse response is not trivially zero");
            for k in 0..count {
                for o in 0..2 {
                    let err = (h[k][(o, j)] - y[k][o]).abs();
                    assert!(
                        err <= 1e-12 * scale,
                        "H_{k}({o},{j}) = {} but the simulation gives {} (scale {scale})",
                        h[k][(o, j)],
                        y[k][o]
                    );
                }
            }
            // Input j is delayed by 3 or 5 samples, and the plant has no feedthrough:
            // the first nonzero sample is d_j + 1.
            let d = [3, 5][j];
            assert!(y[..=d].iter().flatten().all(|&v| v == 0.0));
            assert!(y[d + 1].iter().any(|&v| v != 0.0));
        }
    }

    #[test]
    fn first_nonzero_is_matrix_wise_and_per_channel_sees_each_delay() {
        let model = DiscreteModel::from_scenario(&scenario(), OutputSet::Y).unwrap();
        let (d, hd) = first_nonzero(&model, 1e-9).unwrap();
        assert_eq!(d, 4, "input 0 delayed 3 samples plus one of the hold");
        assert_eq!(hd, model.markov(5)[4]);
        assert!(
            hd.column(1).iter().all(|&v| v == 0.0),
            "input 1 is still delayed"
        );
        let per = first_nonzero_per_channel(&model, 1e-9).unwrap();
        let idx: Vec<usize> = per.iter().map(|c| c.unwrap().0).collect();
        assert_eq!(idx, vec![4, 6, 4, 6]);
        let fir = FirTarget::first_nonzero(&model, 1e-9).unwrap();
        assert_eq!(fir.order(), 4);
        assert!(fir.markov[..4].iter().all(|m| m.iter().all(|&v| v == 0.0)));
        // Per channel: every channel keeps its own first parameter at its own delay.
        let fir = FirTarget::first_nonzero_per_channel(&model, 1e-9).unwrap();
        let h = model.markov(7);
        assert_eq!(fir.order(), 6);
        for (i, m) in fir.markov.iter().enumerate() {
            for o in 0..2 {
                for j in 0..2 {
                    let want = if i == [4, 6][j] { h[i][(o, j)] } else { 0.0 };
                    assert_eq!(m[(o, j)], want, "H_{i}({o}, {j})");
                }
            }
        }
        assert!(first_nonzero(&model, 1.0).is_err());
    }

    #[test]
    fn the_fir_response_converges_to_the_model_response() {
        let model = DiscreteModel::from_scenario(&scenario(), OutputSet::Z).unwrap();
        let theta = crate::design::grid(0.01, 3.1, 50, true).unwrap();
        let exact = model.frf(&theta).unwrap();
        // The slowest mode (3 Hz, ζ = 0.02) decays by e^{−2π·3·0.02·0.01 k}: 3000 samples
        // leave e^{−11}.
        let fir = FirTarget::from_model(&model, 3000).frf(&theta);
        let short = FirTarget::from_model(&model, 30).frf(&theta);
        for j in 0..2 {
            let (e, f, s) = (exact.channel(0, j), fir.channel(0, j), short.channel(0, j));
            let peak = e.iter().fold(0.0_f64, |a, v| a.max(v.norm()));
            let err_long = e
                .iter()
                .zip(f)
                .fold(0.0_f64, |a, (x, y)| a.max((x - y).norm()));
            let err_short = e
                .iter()
                .zip(s)
                .fold(0.0_f64, |a, (x, y)| a.max((x - y).norm()));
            assert!(
                err_long < 1e-3 * peak,
                "channel {j}: {err_long} vs peak {peak}"
            );
            assert!(
                err_short > 0.1 * peak,
                "a 30-tap FIR cannot hold a lightly damped mode"
            );
        }
    }
}
