//! The settings of chapter 4's examples (§4.5–4.7) for `study mrac`: which plant, which
//! command, which controller, built with the crates' own types.
//!
//! - Plants: [`MracExample`] of plant-proxy, (4.83) (zero at 0.5) for Examples 1 and 3,
//!   (4.88) (zero at 1.5) for Example 2, poles at `ρ e^{±jν}`.
//! - Reference model (4.84)/(4.89): `N_m = N`, `D_m = (1 − 0.5j q⁻¹)(1 + 0.5j q⁻¹) =
//!   1 + 0.25 q⁻²`.
//! - Commands (plant-proxy's [`Command`]): the unit step, the two-harmonic
//!   `cos(k) + cos(k/8)` and the four-harmonic `cos(k) + cos(k/2) + cos(k/4) + cos(k/8)`.
//! - APPC (Examples 1a, 2a): `n = 2`, `H = 1 − 0.25 q⁻²` ((4.86), (4.90)), `θ̂_0 = 0`,
//!   `R_θ = 10⁻⁵ I_8`, `λ = 1`.
//! - RC-MRAC (Examples 1b, 2b): `n = 2`, `n_r = 1`, `N_1 = 1`; Example 1b `N_u = 1`,
//!   `n_s = 1`, `F = 1 + 0.5 q⁻¹` (4.87), `R_θ = 10⁻⁵ I_6`; Example 2b `N_u = 1 − 1.5 q⁻¹`,
//!   `n_s = 0`, `F = 1 − 0.25 q⁻²` (4.91), `R_θ = 10⁻⁵ I_5`; `θ̂_0 = 0`, `λ = 1`.
//! - Example 3 (§4.7): the plant (4.83) with the input disturbance
//!   `d_k = cos(0.35 k)` (amplitude 1 and phase 0, as `scenarios/mrac/example3.toml`: the
//!   chapter states only the frequency), the unit step, RC-MRAC with `n = 4`, `n_s = 3`,
//!   `F` (4.87), `R_θ = 10⁻⁵ I_12`, `λ = 1` ([`Method::RcMrac`]); and, as the comparison
//!   without room for the disturbance's model, Example 1b's RC-MRAC (`n = 2`, `n_s = 1`)
//!   on the same disturbed plant ([`Method::RcMracPlain`]).
//!
//! No trace limit and no saturation: the controllers run as in the chapter.

use control::mrac::{Appc, AppcParams, RcMrac, RcMracParams};
use control::{Controller, Dimensions, StepInput};
use plant_proxy::command::{Command, FOUR_HARMONIC, TWO_HARMONIC};
use plant_proxy::harmonic::Harmonic;
use plant_proxy::mrac_examples::{EXAMPLE_3_DISTURBANCE_RAD_STEP, MracExample};

use crate::study::mrac::{ArgError, MracError};

/// One input, one output, one command.
const SISO: Dimensions = Dimensions {
    n_y: 1,
    n_z: 1,
    n_r: 1,
    n_u: 1,
};

/// `D_m` of (4.84) and (4.89): poles `0.5 e^{±jπ/2}`.
pub const D_M: [f64; 3] = [1.0, 0.0, 0.25];

/// `H` of (4.86) and (4.90), and `F` of (4.91): `1 − 0.25 q⁻²`.
pub const H: [f64; 3] = [1.0, 0.0, -0.25];

/// `F` of (4.87): `1 + 0.5 q⁻¹`.
pub const F_MINIMUM_PHASE: [f64; 2] = [1.0, 0.5];

/// One of the chapter's three examples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Example {
    /// §4.5: the minimum-phase plant (4.83).
    One,
    /// §4.6: the nonminimum-phase plant (4.88).
    Two,
    /// §4.7: (4.83) with an unknown input harmonic at 0.35 rad/step.
    Three,
}

impl Example {
    /// All three, in order.
    pub const ALL: [Example; 3] = [Example::One, Example::Two, Example::Three];

    /// 1, 2 or 3.
    pub fn number(self) -> u8 {
        match self {
            Example::One => 1,
            Example::Two => 2,
            Example::Three => 3,
        }
    }

    /// The plant of plant-proxy it runs.
    pub fn plant(self) -> MracExample {
        match self {
            Example::One | Example::Three => MracExample::MinimumPhase,
            Example::Two => MracExample::NonminimumPhase,
        }
    }

    /// `N(q⁻¹) = q⁻¹ − c q⁻²` (also `N_m`).
    pub fn numerator(self) -> Vec<f64> {
        vec![0.0, 1.0, -self.plant().zero()]
    }

    /// The methods the study compares on it.
    pub fn methods(self) -> &'static [Method] {
        match self {
            Example::One | Example::Two => &[Method::Appc, Method::RcMrac],
            Example::Three => &[Method::RcMrac, Method::RcMracPlain],
        }
    }

    /// The commands the chapter runs on it (Example 3: the step only).
    pub fn commands(self) -> &'static [CommandKind] {
        match self {
            Example::One | Example::Two => &CommandKind::ALL,
            Example::Three => &[CommandKind::Step],
        }
    }

    /// The input disturbance `d_k` (Example 3 only).
    pub fn disturbance(self) -> Option<Harmonic> {
        match self {
            Example::Three => Some(Harmonic::unit(EXAMPLE_3_DISTURBANCE_RAD_STEP)),
            _ => None,
        }
    }

    /// Parses `1`, `2`, `3` (`all` is handled by the caller).
    pub fn parse(s: &str) -> Result<Self, ArgError> {
        match s.trim() {
            "1" => Ok(Example::One),
            "2" => Ok(Example::Two),
            "3" => Ok(Example::Three),
            other => Err(ArgError::Unknown {
                option: "--example",
                value: other.into(),
                known: "1, 2, 3 or all",
            }),
        }
    }
}

/// The command `r_k`, in the order of increasing persistency.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CommandKind {
    /// The unit step.
    Step,
    /// `cos(k) + cos(k/8)`.
    Two,
    /// `cos(k) + cos(k/2) + cos(k/4) + cos(k/8)`.
    Four,
}

impl CommandKind {
    /// All three, in order of persistency.
    pub const ALL: [CommandKind; 3] = [CommandKind::Step, CommandKind::Two, CommandKind::Four];

    /// The name used in files and on the command line: `step`, `two`, `four`.
    pub fn name(self) -> &'static str {
        match self {
            CommandKind::Step => "step",
            CommandKind::Two => "two",
            CommandKind::Four => "four",
        }
    }

    /// A label for figures and tables.
    pub fn label(self) -> &'static str {
        match self {
            CommandKind::Step => "unit step",
            CommandKind::Two => "two harmonics",
            CommandKind::Four => "four harmonics",
        }
    }

    /// The plant-proxy command.
    pub fn command(self) -> Command {
        match self {
            CommandKind::Step => Command::Step {
                amplitude: 1.0,
                start: 0,
            },
            CommandKind::Two => Command::harmonics_at(&TWO_HARMONIC),
            CommandKind::Four => Command::harmonics_at(&FOUR_HARMONIC),
        }
    }

    /// Parses `step`, `two`, `four` (`all` is handled by the caller).
    pub fn parse(s: &str) -> Result<Self, ArgError> {
        match s.trim() {
            "step" => Ok(CommandKind::Step),
            "two" => Ok(CommandKind::Two),
            "four" => Ok(CommandKind::Four),
            other => Err(ArgError::Unknown {
                option: "--command",
                value: other.into(),
                known: "step, two, four or all",
            }),
        }
    }
}

/// The adaptive controller of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Method {
    /// APPC (§4.2) with the example's `H`.
    Appc,
    /// RC-MRAC (§4.3) with the example's settings (Example 3: `n = 4`, `n_s = 3`).
    RcMrac,
    /// Example 3's comparison: RC-MRAC of Example 1b (`n = 2`, `n_s = 1`), which has no
    /// room for the disturbance's model.
    RcMracPlain,
}

impl Method {
    /// The name used in files: `appc`, `rc-mrac`, `rc-mrac-n2`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Appc => "appc",
            Method::RcMrac => "rc-mrac",
            Method::RcMracPlain => "rc-mrac-n2",
        }
    }

    /// A label for figures and tables (Example 3's orders spelled out).
    pub fn label(self, example: Example) -> &'static str {
        match (self, example) {
            (Method::Appc, _) => "APPC",
            (Method::RcMrac, Example::Three) => "RC-MRAC n=4, n_s=3",
            (Method::RcMrac, _) => "RC-MRAC",
            (Method::RcMracPlain, _) => "RC-MRAC n=2, n_s=1",
        }
    }
}

/// The controller of one run: the crate's kernel, with its accessors.
#[derive(Debug)]
pub enum Kernel {
    /// APPC; `θ̂ = [θ̂_1; θ̂_2]` (controller, then Bezout coefficients).
    Appc(Appc),
    /// RC-MRAC; `θ̂ = [N_c, D_c, R_c]`.
    RcMrac(RcMrac),
}

impl Kernel {
    /// The controller of `method` on `example`, as the chapter sets it.
    pub fn new(example: Example, method: Method) -> Result<Self, MracError> {
        Self::with_r_theta(example, method, RcMracParams::DEFAULT_R_THETA)
    }

    /// As [`Kernel::new`] with `R_θ = r_theta · I` (the chapter's is `10⁻⁵ I`).
    pub fn with_r_theta(example: Example, method: Method, r_theta: f64) -> Result<Self, MracError> {
        let num = example.numerator();
        let fail = |source| MracError::Controller {
            example,
            method,
            source,
        };
        match method {
            Method::Appc => {
                let mut p = AppcParams::new(2, D_M.to_vec(), num, H.to_vec());
                p.r_theta.iter_mut().for_each(|r| *r = r_theta);
                Appc::new(&p, SISO).map(Kernel::Appc).map_err(fail)
            }
            Method::RcMrac | Method::RcMracPlain => {
                let mut p = rc_mrac_params(example, method, num);
                p.r_theta.iter_mut().for_each(|r| *r = r_theta);
                RcMrac::new(&p, SISO).map(Kernel::RcMrac).map_err(fail)
            }
        }
    }

    /// `u_k` from `y_k`, `r_k`; returns the status bits.
    pub fn step(&mut self, k: u64, y: f64, r: f64, u: &mut f64) -> u32 {
        let input = StepInput {
            seq: k,
            y: &[y],
            z: &[y],
            r: &[r],
            u_applied: None,
            lost: 0,
        };
        let out = std::slice::from_mut(u);
        match self {
            Kernel::Appc(c) => c.step(&input, out),
            Kernel::RcMrac(c) => c.step(&input, out),
        }
    }

    /// `θ̂_k`.
    pub fn theta(&self) -> &[f64] {
        match self {
            Kernel::Appc(c) => c.theta(),
            Kernel::RcMrac(c) => c.theta(),
        }
    }

    /// `y_{m,k}`.
    pub fn y_m(&self) -> f64 {
        match self {
            Kernel::Appc(c) => c.y_m(),
            Kernel::RcMrac(c) => c.y_m(),
        }
    }

    /// `e_k = y_k − y_{m,k}`.
    pub fn e(&self) -> f64 {
        match self {
            Kernel::Appc(c) => c.e(),
            Kernel::RcMrac(c) => c.e(),
        }
    }
}

/// The RC-MRAC parameters of `method` on `example` (see the module documentation).
fn rc_mrac_params(example: Example, method: Method, num: Vec<f64>) -> RcMracParams {
    let (n, n_u, n_s, f) = match (example, method) {
        (Example::Two, _) => (2, vec![1.0, -1.5], 0, H.to_vec()),
        (Example::Three, Method::RcMrac) => (4, vec![1.0], 3, F_MINIMUM_PHASE.to_vec()),
        _ => (2, vec![1.0], 1, F_MINIMUM_PHASE.to_vec()),
    };
    RcMracParams::new(n, 1, 1.0, n_u, n_s, f, D_M.to_vec(), num)
}

/// The names of the entries of `θ̂` for `method` on `example`: APPC `nc1…, dc1…, b1…, c1…`
/// ((4.35)–(4.36)); RC-MRAC `nc1…, dc1…, rc0…` (4.68).
pub fn theta_names(example: Example, method: Method) -> Vec<String> {
    let (n, tail): (usize, Vec<String>) = match (example, method) {
        (_, Method::Appc) => (
            2,
            (1..=2)
                .map(|i| format!("b{i}"))
                .chain((1..=2).map(|i| format!("c{i}")))
                .collect(),
        ),
        (Example::Three, Method::RcMrac) => (4, (0..=3).map(|i| format!("rc{i}")).collect()),
        (Example::Two, _) => (2, vec!["rc0".into()]),
        _ => (2, (0..=1).map(|i| format!("rc{i}")).collect()),
    };
    (1..=n)
        .map(|i| format!("nc{i}"))
        .chain((1..=n).map(|i| format!("dc{i}")))
        .chain(tail)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_proxy::mrac_examples::pole_polynomial;

    #[test]
    fn the_reference_model_has_its_poles_at_one_half_e_to_the_plus_minus_j_pi_over_two() {
        let d = pole_polynomial(0.5, std::f64::consts::FRAC_PI_2);
        for (a, b) in d.iter().zip(D_M) {
            assert!((a - b).abs() < 1e-15, "{d:?}");
        }
    }

    #[test]
    fn every_example_and_method_builds_with_the_chapters_number_of_coefficients() {
        let expect = [
            (Example::One, Method::Appc, 8),
            (Example::One, Method::RcMrac, 6),
            (Example::Two, Method::Appc, 8),
            (Example::Two, Method::RcMrac, 5),
            (Example::Three, Method::RcMrac, 12),
            (Example::Three, Method::RcMracPlain, 6),
        ];
        for (ex, m, len) in expect {
            let k = Kernel::new(ex, m).expect("valid");
            assert_eq!(k.theta().len(), len, "{ex:?} {m:?}");
            assert_eq!(theta_names(ex, m).len(), len, "{ex:?} {m:?}");
        }
    }

    #[test]
    fn bad_names_are_refused_naming_the_argument() {
        assert!(
            Example::parse("4")
                .unwrap_err()
                .to_string()
                .contains("--example")
        );
        assert!(
            CommandKind::parse("ramp")
                .unwrap_err()
                .to_string()
                .contains("--command")
        );
        assert_eq!(CommandKind::parse("two"), Ok(CommandKind::Two));
    }
}
