//! The settings §7.2–7.3 leave open, each moved to alternatives, and the verdicts of
//! claims 7.2–7.6 under each (the study's sensitivity record,
//! [`crate::study::reproduction::sensitivity`]).
//!
//! The chapter prints the spacecraft (m_sc, m_1, m_2, m_s, L, R, Ī, θ̄_0, μ), the approach
//! (0.2 m at 0.1 m/s), the contact period (2 s), F_d = 25 N, the robust design's box and
//! λ, PCAC's settings, the force laws (7.27)–(7.29) and the grids' ranges, but not
//! everything a simulation needs, and some of what it prints can be read more than one
//! way. Each [`Change`] moves one choice from the study's value to an alternative, all
//! else as the study runs it:
//!
//! | choice | study | alternatives | why open | claims |
//! | --- | --- | --- | --- | --- |
//! | robust gain `K` (7.41) | margin design, λ = 0.025 | min-gain, LQR designs; the margin design with its force-error column × 0.1 ([`FORCE_GAIN_SCALE`], below its certificate) | (7.41) as printed (min s, s ≥ 0) is met by `Q = 0, Y = 0`; `K` is not printed | 7.2–7.6 |
//! | `c_r` → damping of (7.28) | Hunt–Crossley `3(1 − c_r)/2` | Lankarani–Nikravesh, Flores et al. ([`super::restitution`]) | (7.28) cites [85–87], which use all three; Figure 7.5's caption says "damping c_s" | 7.4–7.6 |
//! | sign of `ẏ_0` in (7.28) | the signed onset velocity (< 0): dissipative | the onset speed `\|ẏ_0\|`: `χ → −χ` | "initial contact velocity", no sign convention | 7.4–7.6 |
//! | Hunt–Crossley exponent `n` | 3/2 (7.28) | 1 | (7.28) prints 3/2 but §7.3.2 gives `k_s` in N/m, the unit of `n = 1` | 7.4–7.6 |
//! | `c_r` spacing of the grid | log | linear | Figure 7.5's axes are not in the text | 7.4–7.5 |
//! | `k_s` spacing of the grid | log | linear | the same | 7.4–7.5 |
//! | link inertias `Ī_1 = Ī_2` | 1/3 kg m² (centroidal) | 4/3 kg m² (about the joint), plant and controller | printed as "1/3 kg/m²", whose unit is garbled | 7.2–7.6 |
//! | the linearization's `m_sc` (7.31) | the plant's 420 kg | 0.9×, 1.1× (plant 420 kg) | not said whether (7.31)'s model is exact | 7.2–7.6 |
//! | force sensor noise | none | σ = 1 N on the measured `F_c` | "seven sensors", no noise given | 7.2–7.6 |
//! | joint torque limits | none | `\|τ_i\| ≤ 100` N m | not given | 7.2–7.6 |
//! | PCAC move bounds `Δu` (7.61) | `\|Δu_aug\| ≤ 50` | none | (7.61) has them, no values printed | 7.2, 7.3, 7.5, 7.6 |
//! | the band of "reaches 25 N" | ±5 % | ±2 %, ±10 % | read off Figures 7.3–7.6; no rule stated | 7.2, 7.3, 7.5, 7.6 |
//!
//! Not moved, because the study's value is forced: `ẏ_0` itself (the onset velocity is the
//! printed 0.1 m/s: everything coasts at it onto the surface), the contact period (2 s,
//! printed), the approach (printed), PCAC's printed settings.
//!
//! # The experiment under each alternative
//!
//! Each claim is read with its own criterion ([`super::claims::claims_in_band`]) on the
//! runs it needs, with the changed setting in both controllers and the plant: Figure 7.4's
//! and Figure 7.6's single runs, the Hunt–Crossley grid of Figure 7.5, and the row of the
//! linear grid at the lowest stiffness (claim 7.2). The grids have
//! [`SENSITIVITY_GRID`]` × `[`SENSITIVITY_GRID`] points (every third point of the
//! study's 10 × 10 grid), so the study's own row is read on the same points of its own
//! grid, without a run; runs a change cannot alter (the robust controller's under PCAC's
//! move bounds, the linear surfaces under a Hunt–Crossley change, the points a linearly
//! spaced grid shares with the study's) are the study's. Which runs are the study's is
//! told from the options alone ([`Plan`]); all runs of all alternatives are one sharded
//! stage of the study (about 500 runs at the default, the study's 400 grid runs' cost),
//! read with the study's own after it gathers its runs ([`Plan::outcomes`]).

use std::fmt::Write as _;
use std::path::Path;

use control::OutputLimits;
use plant_proxy::arm::ContactModel;

use crate::file_error::{FileError, FileOp};
use crate::study::arm::ArmError;
use crate::study::arm::claims::{self, Evidence};
use crate::study::arm::closed_loop::{self, BAND, ContactStats, Law, Model, Record, Setup, Trace};
use crate::study::arm::gain_sensitivity;
use crate::study::arm::grid::{self, Grid, GridPoint};
use crate::study::arm::restitution::Restitution;
use crate::study::reproduction::sensitivity::{Alternative, Reading};
use crate::study::reproduction::{Claim, Verdict};

/// The factor of [`Change::ForceGain`]. In (7.39) with `τ_f = K χ`, the force loop's two
/// modes solve `s² − (K_22 − c_s K_23) s + k_s K_23 = 0`; with the committed gain
/// (`K_22 ≈ −194`, `K_23 ≈ 0.028`) at Figure 7.4's `k_s = 2·10⁵`, `c_s = 5` the slow
/// one is about 35 /s, and `k_s K_23 / |K_22|` when overdamped. Scaling `K_23` by 0.1
/// brings it to about 2.9 /s, where settling within 5 % from `e = −F_d` takes about
/// `ln 20 / 2.9 ≈ 1` s: claim 7.3's "most of the 2 second contact period". Chosen from
/// claim 7.3's words and the committed gain, before any run with it.
pub const FORCE_GAIN_SCALE: f64 = 0.1;

/// Points per axis of the alternatives' grids: every third point of the 10 × 10 grid.
pub const SENSITIVITY_GRID: usize = 4;

/// The spacing of a grid axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// `k_s`.
    Stiffness,
    /// `c_r`.
    Restitution,
}

/// One alternative choice (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    /// The study's choices.
    Study,
    /// The robust gain of `scenarios/arm/<file>`, designed for `objective`.
    Gain {
        /// `rig-design robust-gain --objective`.
        objective: &'static str,
        /// The file in `scenarios/arm/`.
        file: &'static str,
    },
    /// The committed gain with its force-error column (`K_13`, `K_23`) times this factor,
    /// in both controllers: a force loop this much slower, below its certificate.
    ForceGain(f64),
    /// Another mapping of `c_r` to the Hunt–Crossley damping.
    Mapping(Restitution),
    /// (7.28) with the onset speed `|ẏ_0|`: `χ = −3(1 − c_r)/2`.
    OnsetSpeed,
    /// The Hunt–Crossley exponent `n`.
    Exponent(f64),
    /// A linearly spaced axis of the Hunt–Crossley grid.
    Linear(Axis),
    /// `Ī_1 = Ī_2`, kg m², in the plant and both controllers.
    Inertia(f64),
    /// The linearization's `m_sc` as a multiple of the plant's.
    BusModel(f64),
    /// White noise of this σ, N, on the measured `F_c` (y₇).
    ForceNoise(f64),
    /// `|τ_i| ≤` this, N m, in both controllers.
    TorqueLimit(f64),
    /// PCAC without move bounds.
    NoMoveBounds,
    /// "Reaches 25 N": within `F_d (1 ± band)`.
    Band(f64),
}

/// The claims a change in every run bears on.
const ALL: &[&str] = &["7.2", "7.3", "7.4", "7.5", "7.6"];
/// The claims of the Hunt–Crossley runs.
const HUNT_CROSSLEY: &[&str] = &["7.4", "7.5", "7.6"];
/// The claims of the Hunt–Crossley grid.
const HC_GRID: &[&str] = &["7.4", "7.5"];
/// The claims of PCAC's runs.
const AUGMENTED: &[&str] = &["7.2", "7.3", "7.5", "7.6"];

impl Change {
    /// The choice it moves, as the table names it.
    pub fn choice(self) -> &'static str {
        match self {
            Change::Study => "the study's choices",
            Change::Gain { .. } | Change::ForceGain(_) => "robust gain K (7.41)",
            Change::Mapping(_) => "c_r → damping of (7.28)",
            Change::OnsetSpeed => "sign of ẏ_0 in (7.28)",
            Change::Exponent(_) => "Hunt–Crossley exponent n",
            Change::Linear(Axis::Stiffness) => "k_s spacing of the Hunt–Crossley grid",
            Change::Linear(Axis::Restitution) => "c_r spacing of the Hunt–Crossley grid",
            Change::Inertia(_) => "link inertias Ī_1 = Ī_2",
            Change::BusModel(_) => "m_sc of the linearization (7.31)",
            Change::ForceNoise(_) => "force sensor noise",
            Change::TorqueLimit(_) => "joint torque limits",
            Change::NoMoveBounds => "PCAC move bounds Δu (7.61)",
            Change::Band(_) => "band of \"reaches 25 N\"",
        }
    }

    /// Why §7.2–7.3 leave it open.
    pub fn why_open(self) -> &'static str {
        match self {
            Change::Study => "",
            Change::Gain { .. } | Change::ForceGain(_) => {
                "K is not printed, and (7.41) as printed (min s, s ≥ 0) is met by Q = 0, Y = 0"
            }
            Change::Mapping(_) => {
                "(7.28) cites [85–87], which use several mappings; Figure 7.5's caption says \"damping c_s\""
            }
            Change::OnsetSpeed => "\"initial contact velocity\" without a sign convention",
            Change::Exponent(_) => {
                "(7.28) prints 3/2, but §7.3.2 gives k_s in N/m, the unit of n = 1"
            }
            Change::Linear(_) => "Figure 7.5's axes are not in the text",
            Change::Inertia(_) => "printed as \"1/3 kg/m²\", a garbled unit",
            Change::BusModel(_) => "not said whether the model of (7.31) is the plant's",
            Change::ForceNoise(_) => "\"seven sensors\", no noise given",
            Change::TorqueLimit(_) => "not given",
            Change::NoMoveBounds => "(7.61) has them, no values printed",
            Change::Band(_) => "read off Figures 7.3–7.6; no rule is stated",
        }
    }

    /// The study's value of the choice it moves.
    pub fn ours(self) -> String {
        match self {
            Change::Study => "–",
            Change::Gain { .. } | Change::ForceGain(_) => "margin design (robust-gain.toml)",
            Change::Mapping(_) => Restitution::HuntCrossley.name(),
            Change::OnsetSpeed => "signed ẏ_0 < 0 (dissipative)",
            Change::Exponent(_) => "3/2",
            Change::Linear(_) => "log",
            Change::Inertia(_) => "1/3 kg m² (centroidal)",
            Change::BusModel(_) => "the plant's (420 kg)",
            Change::ForceNoise(_) => "none",
            Change::TorqueLimit(_) => "none",
            Change::NoMoveBounds => "|Δu_aug| ≤ 50",
            Change::Band(_) => "±5 %",
        }
        .into()
    }

    /// Its value, as text.
    pub fn value(self) -> String {
        match self {
            Change::Study => "–".into(),
            Change::Gain { objective, file } => format!("{objective} design ({file})"),
            Change::ForceGain(f) => {
                format!("margin design, force-error column × {f} (not certified)")
            }
            Change::Mapping(m) => m.name().into(),
            Change::OnsetSpeed => "onset speed |ẏ_0| (χ → −χ)".into(),
            Change::Exponent(n) => format!("{n}"),
            Change::Linear(_) => "linear".into(),
            Change::Inertia(i) => format!("{i:.4} kg m² (both)"),
            Change::BusModel(f) => format!("{f}× (plant 420 kg)"),
            Change::ForceNoise(s) => format!("σ = {s} N"),
            Change::TorqueLimit(t) => format!("|τ_i| ≤ {t} N m"),
            Change::NoMoveBounds => "none".into(),
            Change::Band(b) => format!("±{} %", b * 100.0),
        }
    }

    /// The claims it bears on.
    pub fn claims(self) -> &'static [&'static str] {
        match self {
            Change::Mapping(_) | Change::OnsetSpeed | Change::Exponent(_) => HUNT_CROSSLEY,
            Change::Linear(_) => HC_GRID,
            Change::NoMoveBounds | Change::Band(_) => AUGMENTED,
            _ => ALL,
        }
    }

    /// Whether it changes the runs of `law` on `model`'s surfaces (else they are the
    /// study's, wherever the study's grid has the point).
    fn reruns(self, law: Law, model: Model) -> bool {
        match self {
            // A grid's spacing changes its points, not the runs at points it shares.
            Change::Study | Change::Band(_) | Change::Linear(_) => false,
            Change::Mapping(_) | Change::OnsetSpeed | Change::Exponent(_) => {
                model == Model::HuntCrossley
            }
            Change::NoMoveBounds => law == Law::Augmented,
            _ => true,
        }
    }

    /// The study's setup with this change (`dir`: the gain files).
    pub fn setup(self, base: &Setup, dir: &Path) -> Result<Setup, ArmError> {
        let mut s = base.clone();
        s.single.plant.arm_mut().ok_or(ArmError::NotArm)?;
        match self {
            Change::Gain { objective, file } => {
                s = s.with_gain(gain_sensitivity::load(dir, objective, file)?.gain);
            }
            Change::ForceGain(f) => {
                let mut k = base.robust.robust_gain;
                k[2] *= f;
                k[5] *= f;
                s = s.with_gain(k);
            }
            Change::Inertia(i) => {
                if let Some(a) = s.single.plant.arm_mut() {
                    a.spacecraft.i1 = i;
                    a.spacecraft.i2 = i;
                }
                for p in [&mut s.robust, &mut s.augmented] {
                    p.arm.i1 = i;
                    p.arm.i2 = i;
                }
            }
            Change::BusModel(f) => {
                for p in [&mut s.robust, &mut s.augmented] {
                    p.arm.m_sc *= f;
                }
            }
            Change::ForceNoise(sigma) => {
                if let Some(v) = s.single.plant.noise.y_std.get_mut(6) {
                    *v = sigma;
                }
            }
            Change::TorqueLimit(t) => {
                for p in [&mut s.robust, &mut s.augmented] {
                    p.limits = Some(OutputLimits::symmetric(t, 2));
                }
            }
            Change::NoMoveBounds => {
                if let Some(p) = s.augmented.pcac.as_mut() {
                    p.mpc.move_bounds = None;
                }
            }
            Change::Study
            | Change::Mapping(_)
            | Change::OnsetSpeed
            | Change::Exponent(_)
            | Change::Linear(_)
            | Change::Band(_) => {}
        }
        Ok(s)
    }

    /// The normal-force law of the surface `model(k_s, c)` under this change.
    pub fn surface(self, model: Model, k_s: f64, c: f64) -> Result<ContactModel, ArmError> {
        let family = |n: f64, chi: f64| {
            ContactModel::hysteretic(k_s, n, chi).map_err(|source| ArmError::Surface {
                model,
                k_s,
                c,
                source,
            })
        };
        match (model, self) {
            (Model::HuntCrossley, Change::Mapping(m)) => family(1.5, m.hysteresis(c)),
            (Model::HuntCrossley, Change::OnsetSpeed) => {
                family(1.5, -Restitution::HuntCrossley.hysteresis(c))
            }
            (Model::HuntCrossley, Change::Exponent(n)) => {
                family(n, Restitution::HuntCrossley.hysteresis(c))
            }
            _ => model.surface(k_s, c),
        }
    }

    /// The grid of `model` with `n` points per axis under this change.
    pub fn grid(self, model: Model, n: usize) -> Result<Grid, ArmError> {
        let mut g = Grid::new(model, n)?;
        let lin = |(lo, hi): (f64, f64)| -> Vec<f64> {
            (0..n)
                .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
                .collect()
        };
        match (model, self) {
            (Model::HuntCrossley, Change::Linear(Axis::Stiffness)) => g.k_s = lin(grid::STIFFNESS),
            (Model::HuntCrossley, Change::Linear(Axis::Restitution)) => {
                g.c = lin(grid::RESTITUTION)
            }
            _ => {}
        }
        Ok(g)
    }

    /// The band of "reaches 25 N" under this change.
    pub fn band(self) -> f64 {
        match self {
            Change::Band(b) => b,
            _ => BAND,
        }
    }
}

/// The alternatives, the study's choices first (module documentation).
pub fn alternatives() -> Vec<Change> {
    let mut v = vec![Change::Study];
    v.extend(
        gain_sensitivity::ALTERNATIVES
            .iter()
            .map(|&(objective, file)| Change::Gain { objective, file }),
    );
    v.extend([
        Change::ForceGain(FORCE_GAIN_SCALE),
        Change::Mapping(Restitution::LankaraniNikravesh),
        Change::Mapping(Restitution::Flores),
        Change::OnsetSpeed,
        Change::Exponent(1.0),
        Change::Linear(Axis::Restitution),
        Change::Linear(Axis::Stiffness),
        Change::Inertia(4.0 / 3.0),
        Change::BusModel(0.9),
        Change::BusModel(1.1),
        Change::ForceNoise(1.0),
        Change::TorqueLimit(100.0),
        Change::NoMoveBounds,
        Change::Band(0.02),
        Change::Band(0.1),
    ]);
    v
}

/// What the study itself ran, on which the study's row and every run an alternative does
/// not change are read.
#[derive(Debug, Clone, Copy)]
pub struct StudyRuns<'a> {
    /// The study's grid points (both models, both laws).
    pub grid: &'a [GridPoint],
    /// Figure 7.4's runs `(robust, augmented)`.
    pub fig_7_4: (&'a Trace, &'a Trace),
    /// Figure 7.6's runs `(robust, augmented)`.
    pub fig_7_6: (&'a Trace, &'a Trace),
    /// The sample period, s.
    pub ts: f64,
}

impl StudyRuns<'_> {
    /// The first contact of a study's single run, settling in `band`.
    fn first(&self, t: &Trace, band: f64) -> ContactStats {
        closed_loop::contact_stats_within(&t.r, &t.force, self.ts, band)
            .first()
            .copied()
            .unwrap_or(ContactStats {
                first: 0,
                samples: 0,
                median: f64::NAN,
                settling: f64::NAN,
            })
    }

    /// The study's point `(model, law, k_s, c)`, if its grid has it.
    fn point(&self, model: Model, law: Law, k_s: f64, c: f64) -> Option<&GridPoint> {
        let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
        self.grid
            .iter()
            .find(|p| p.model == model && p.law == law && same(p.k_s, k_s) && same(p.c, c))
    }
}

/// One run an alternative needs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Job {
    /// A grid point.
    Point(Model, Law, f64, f64),
    /// Figure 7.4's (linear) or 7.6's (Hunt–Crossley) single run.
    Single(Model, Law),
}

/// The surfaces of Figures 7.4 and 7.6.
fn figure(model: Model) -> (f64, f64) {
    match model {
        Model::Linear => (2.0e5, 5.0),
        Model::HuntCrossley => (2.0e5, 0.9),
    }
}

/// The runs of `change` with `n` points per grid axis: the linear grid's lowest-stiffness
/// row, the Hunt–Crossley grid, and both single runs, each for both laws.
fn jobs(change: Change, n: usize) -> Result<Vec<Job>, ArmError> {
    let lin = change.grid(Model::Linear, n)?;
    let hc = change.grid(Model::HuntCrossley, n)?;
    let mut v = Vec::new();
    for law in Law::ALL {
        v.extend(
            lin.c
                .iter()
                .map(|&c| Job::Point(Model::Linear, law, lin.k_s[0], c)),
        );
        v.extend(
            hc.points()
                .into_iter()
                .map(|(k, c)| Job::Point(Model::HuntCrossley, law, k, c)),
        );
        v.extend(Model::ALL.map(|m| Job::Single(m, law)));
    }
    Ok(v)
}

/// The outcome of one run: its first contact and why it failed, if it did.
pub type Run = (ContactStats, Option<String>);

fn run_job(change: Change, setup: &Setup, job: Job) -> Run {
    let (model, law, k_s, c) = match job {
        Job::Point(m, l, k, c) => (m, l, k, c),
        Job::Single(m, l) => {
            let (k, c) = figure(m);
            (m, l, k, c)
        }
    };
    let out = change
        .surface(model, k_s, c)
        .and_then(|law_| setup.single_with(law_))
        .and_then(|sc| closed_loop::run(setup, &sc, law, Record::FirstContact));
    let none = ContactStats {
        first: 0,
        samples: 0,
        median: f64::NAN,
        settling: f64::NAN,
    };
    match out {
        Ok(o) => (o.contacts.first().copied().unwrap_or(none), o.failure),
        Err(e) => (none, Some(e.to_string())),
    }
}

/// One alternative's claims: the change and claims 7.1–7.6 on its runs (7.1 and the
/// claims it does not bear on are dropped by [`record`]).
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The change.
    pub change: Change,
    /// The claims on its runs.
    pub claims: Vec<Claim>,
}

/// One run of the sensitivity record that the study does not have: a job of the
/// alternative `changes[change]` ([`Plan::items`], a sharded stage of the study).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Item {
    /// The alternative's index in [`alternatives`].
    change: usize,
    /// The alternative.
    what: Change,
    /// The run.
    job: Job,
}

/// The runs of every alternative with `n` points per grid axis, told apart before any run:
/// the study's result when the change cannot alter it and the study has the run (its
/// single runs, the points of its grid), else a run of its own ([`Plan::items`]).
#[derive(Debug)]
pub struct Plan {
    changes: Vec<Change>,
    setups: Vec<Setup>,
    /// Every job of every change, `(change, job)`.
    all: Vec<(usize, Job)>,
    /// Whether `all[i]` is read on the study's runs.
    from_study: Vec<bool>,
    /// The jobs that run, in the order of `all`.
    items: Vec<Item>,
}

/// Whether the study's grid points `grid` (`(model, law, k_s, c)`) hold `(model, law,
/// k_s, c)`; its index if so.
fn find_point(
    grid: &[(Model, Law, f64, f64)],
    model: Model,
    law: Law,
    k_s: f64,
    c: f64,
) -> Option<usize> {
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
    grid.iter()
        .position(|&(m, l, k, cc)| m == model && l == law && same(k, k_s) && same(cc, c))
}

impl Plan {
    /// The plan of every alternative with `n` points per grid axis on the study's `setup`
    /// (`dir`: the gain files), whose grids run `grid` (the study's grid runs, known from
    /// its options alone).
    pub fn new(base: &Setup, dir: &Path, grid: &[grid::Job], n: usize) -> Result<Self, ArmError> {
        let changes = alternatives();
        let setups: Vec<Setup> = changes
            .iter()
            .map(|c| c.setup(base, dir))
            .collect::<Result<_, _>>()?;
        let grid: Vec<(Model, Law, f64, f64)> =
            grid.iter().map(|j| (j.model, j.law, j.k_s, j.c)).collect();
        let mut all: Vec<(usize, Job)> = Vec::new();
        for (i, &c) in changes.iter().enumerate() {
            for j in jobs(c, n)? {
                all.push((i, j));
            }
        }
        let from_study: Vec<bool> = all
            .iter()
            .map(|&(i, job)| {
                let c = changes[i];
                match job {
                    Job::Point(m, l, k, cc) => {
                        !c.reruns(l, m) && find_point(&grid, m, l, k, cc).is_some()
                    }
                    Job::Single(m, l) => !c.reruns(l, m),
                }
            })
            .collect();
        let items = all
            .iter()
            .zip(&from_study)
            .filter(|(_, s)| !**s)
            .map(|(&(i, job), _)| Item {
                change: i,
                what: changes[i],
                job,
            })
            .collect();
        Ok(Self {
            changes,
            setups,
            all,
            from_study,
            items,
        })
    }

    /// The runs the study does not have, in the order of the alternatives and their jobs.
    pub fn items(&self) -> &[Item] {
        &self.items
    }

    /// Runs `item` (one of [`Plan::items`]).
    pub fn run(&self, item: &Item) -> Run {
        run_job(item.what, &self.setups[item.change], item.job)
    }

    /// Every alternative's claims: its runs `ran` (those of [`Plan::items`], in their
    /// order) and, for the rest, the study's runs `study`.
    pub fn outcomes(&self, study: &StudyRuns<'_>, ran: Vec<Run>) -> Result<Vec<Outcome>, ArmError> {
        let changes = &self.changes;
        let all = &self.all;
        let from_study = |i: usize, job: Job| -> Option<Run> {
            let c = changes[i];
            match job {
                Job::Point(m, l, k, cc) => study
                    .point(m, l, k, cc)
                    .map(|p| (stats_of(p), p.failure.clone())),
                Job::Single(m, l) => {
                    let t = match (m, l) {
                        (Model::Linear, Law::Robust) => study.fig_7_4.0,
                        (Model::Linear, Law::Augmented) => study.fig_7_4.1,
                        (Model::HuntCrossley, Law::Robust) => study.fig_7_6.0,
                        (Model::HuntCrossley, Law::Augmented) => study.fig_7_6.1,
                    };
                    Some((study.first(t, c.band()), None))
                }
            }
        };
        let mut ran = ran.into_iter();
        let runs: Vec<Run> = all
            .iter()
            .zip(&self.from_study)
            .map(|(&(i, job), &s)| {
                if s { from_study(i, job) } else { ran.next() }.ok_or(ArmError::MissingRun)
            })
            .collect::<Result<_, _>>()?;
        if ran.next().is_some() {
            return Err(ArmError::MissingRun);
        }
        let mut out = Vec::new();
        for (i, &change) in changes.iter().enumerate() {
            let mut points = Vec::new();
            let single = |m: Model, l: Law| -> ContactStats {
                all.iter()
                    .zip(&runs)
                    .find(|((ii, j), _)| *ii == i && *j == Job::Single(m, l))
                    .map_or(
                        ContactStats {
                            first: 0,
                            samples: 0,
                            median: f64::NAN,
                            settling: f64::NAN,
                        },
                        |(_, r)| r.0,
                    )
            };
            let fig_7_4 = (
                single(Model::Linear, Law::Robust),
                single(Model::Linear, Law::Augmented),
            );
            let fig_7_6 = (
                single(Model::HuntCrossley, Law::Robust),
                single(Model::HuntCrossley, Law::Augmented),
            );
            for ((ii, job), (stats, failure)) in all.iter().zip(&runs) {
                if let (true, Job::Point(model, law, k_s, c)) = (*ii == i, *job) {
                    points.push(GridPoint {
                        model,
                        law,
                        k_s,
                        c,
                        median: stats.median,
                        settling: stats.settling,
                        failure: failure.clone(),
                    });
                }
            }
            let evidence = Evidence {
                grid: &points,
                fig_7_4,
                fig_7_6,
                doubles: Vec::new(),
            };
            out.push(Outcome {
                change,
                claims: claims::claims_in_band(&evidence, change.band()),
            });
        }
        Ok(out)
    }
}

fn stats_of(p: &GridPoint) -> ContactStats {
    ContactStats {
        first: 0,
        samples: 0,
        median: p.median,
        settling: p.settling,
    }
}

/// The sensitivity rows of the study: each alternative with the verdicts, under it, of the
/// claims it bears on ([`Change::claims`]), on `n × n` grids; the study's own row (one per
/// setting) read on the same grid points.
pub fn record(outcomes: &[Outcome], n: usize) -> Vec<Alternative> {
    let study = outcomes.iter().find(|o| o.change == Change::Study);
    let readings = |o: &Outcome, ids: &[&str]| -> Vec<Reading> {
        ids.iter()
            .filter_map(|id| o.claims.iter().find(|c| c.id == *id))
            .map(|c| {
                Reading::of(
                    &c.id,
                    c.verdict == Verdict::Pass,
                    format!("{n}×{n} grids: {}", c.ours),
                )
            })
            .collect()
    };
    let mut rows = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for o in outcomes.iter().filter(|o| o.change != Change::Study) {
        let c = o.change;
        if let Some(s) = study.filter(|_| !seen.contains(&c.choice())) {
            seen.push(c.choice());
            rows.push(Alternative::new(
                c.choice(),
                c.why_open(),
                c.ours(),
                c.ours(),
                readings(s, c.claims()),
            ));
        }
        rows.push(Alternative::new(
            c.choice(),
            c.why_open(),
            c.ours(),
            c.value(),
            readings(o, c.claims()),
        ));
    }
    rows
}

/// The sentence appended to claim `id`'s "ours": how many alternatives give PASS, and the
/// fewer side by name (those that give PASS, or those that do not).
pub fn reading(id: &str, rows: &[Alternative]) -> String {
    let alts: Vec<(&Alternative, &Reading)> = rows
        .iter()
        .filter(|r| !r.is_ours())
        .filter_map(|r| r.readings.iter().find(|x| x.claim == id).map(|x| (r, x)))
        .collect();
    if alts.is_empty() {
        return String::new();
    }
    let named = |pass: bool| -> Vec<String> {
        alts.iter()
            .filter(|(_, x)| (x.verdict == Verdict::Pass) == pass)
            .map(|(r, _)| format!("{} = {}", r.setting, r.value))
            .collect()
    };
    let (pass, fail) = (named(true), named(false));
    let which = if pass.is_empty() {
        String::new()
    } else if pass.len() <= fail.len() {
        format!(" — {}", pass.join("; "))
    } else if fail.is_empty() {
        " — all".to_string()
    } else {
        format!(" — all but {}", fail.join("; "))
    };
    format!(
        " (Verdict under the study's readings; PASS under {} of {} alternatives of the open settings{which}: the sensitivity table.)",
        pass.len(),
        alts.len(),
    )
}

/// Writes `sensitivity.csv`: `setting, value, ours, claim, verdict, measured`.
pub fn write_csv(path: &Path, rows: &[Alternative]) -> Result<(), ArmError> {
    let q = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let mut s = String::from("setting,value,ours,claim,verdict,measured\n");
    for r in rows {
        for x in &r.readings {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{}",
                q(&r.setting),
                q(&r.value),
                q(&r.ours),
                x.claim,
                x.verdict.word(),
                q(&x.measured)
            );
        }
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> Setup {
        Setup::load(&closed_loop::scenario_dir()).unwrap()
    }

    #[test]
    fn the_plan_runs_only_what_the_studys_options_do_not_give() {
        let base = setup();
        let dir = closed_loop::scenario_dir();
        let grids = Model::ALL.map(|m| Grid::new(m, super::super::DEFAULT_GRID).unwrap());
        let plan = Plan::new(&base, &dir, &grid::jobs(&grids), SENSITIVITY_GRID).unwrap();
        let changes = |c: Change| plan.items().iter().filter(move |i| i.what == c);
        // The study's row, the bands and the spacings' shared points: the study's runs.
        assert_eq!(changes(Change::Study).count(), 0);
        assert_eq!(changes(Change::Band(0.02)).count(), 0);
        let shared = |c: Change| changes(c).count();
        // A linear c_r axis shares its ends with the log axis (2 of 4 values).
        assert_eq!(shared(Change::Linear(Axis::Restitution)), 2 * 4 * 2);
        // PCAC without move bounds: only PCAC's runs, all of them.
        assert!(changes(Change::NoMoveBounds).all(|i| !matches!(
            i.job,
            Job::Point(_, Law::Robust, ..) | Job::Single(_, Law::Robust)
        )));
        assert_eq!(changes(Change::NoMoveBounds).count(), 4 + 16 + 2);
        // Every item is the change it names, and the plan is the same plan every time.
        assert!(
            plan.items()
                .iter()
                .all(|i| plan.changes[i.change] == i.what)
        );
        let again = Plan::new(&base, &dir, &grid::jobs(&grids), SENSITIVITY_GRID).unwrap();
        assert_eq!(again.items(), plan.items());
    }

    #[test]
    fn a_run_survives_its_record_bit_for_bit() {
        let r: Run = (
            ContactStats {
                first: 3,
                samples: 4000,
                median: f64::NAN,
                settling: f64::INFINITY,
            },
            Some("plant at sample 7: diverged".into()),
        );
        let back: Run = postcard::from_bytes(&postcard::to_stdvec(&r).unwrap()).unwrap();
        assert_eq!((back.0.first, back.0.samples), (3, 4000));
        assert_eq!(back.0.median.to_bits(), r.0.median.to_bits());
        assert_eq!(back.0.settling, f64::INFINITY);
        assert_eq!(back.1, r.1);
    }

    #[test]
    fn each_change_reaches_the_plant_or_the_controllers() {
        let base = setup();
        let dir = closed_loop::scenario_dir();
        let s = Change::Inertia(4.0 / 3.0).setup(&base, &dir).unwrap();
        let arm = s.single.plant.arm.as_ref().unwrap();
        assert_eq!(arm.spacecraft.i1, 4.0 / 3.0);
        assert_eq!(
            (s.robust.arm.i2, s.augmented.arm.i1),
            (4.0 / 3.0, 4.0 / 3.0)
        );
        let s = Change::ForceGain(0.1).setup(&base, &dir).unwrap();
        let (k0, k) = (base.robust.robust_gain, s.augmented.robust_gain);
        assert_eq!((k[0], k[1], k[3], k[4]), (k0[0], k0[1], k0[3], k0[4]));
        assert!((k[5] - 0.1 * k0[5]).abs() <= 1e-15 * k0[5].abs());
        assert_eq!(s.robust.robust_gain, k);
        let s = Change::BusModel(0.9).setup(&base, &dir).unwrap();
        assert!((s.robust.arm.m_sc - 378.0).abs() < 1e-9);
        assert_eq!(s.single.plant.arm.as_ref().unwrap().spacecraft.m_sc, 420.0);
        let s = Change::ForceNoise(1.0).setup(&base, &dir).unwrap();
        assert_eq!(s.single.plant.noise.y_std[6], 1.0);
        let s = Change::TorqueLimit(100.0).setup(&base, &dir).unwrap();
        assert_eq!(s.augmented.limits.as_ref().unwrap().max, vec![100.0; 2]);
        let s = Change::NoMoveBounds.setup(&base, &dir).unwrap();
        assert!(s.augmented.pcac.as_ref().unwrap().mpc.move_bounds.is_none());
        assert!(
            base.augmented
                .pcac
                .as_ref()
                .unwrap()
                .mpc
                .move_bounds
                .is_some()
        );
        let (objective, file) = gain_sensitivity::ALTERNATIVES[0];
        let s = Change::Gain { objective, file }.setup(&base, &dir).unwrap();
        assert_ne!(s.robust.robust_gain, base.robust.robust_gain);
        assert_eq!(s.robust.robust_gain, s.augmented.robust_gain);
    }

    #[test]
    fn the_surface_changes_reach_the_hunt_crossley_law_only() {
        let hc = |c: Change| c.surface(Model::HuntCrossley, 2e5, 0.5).unwrap();
        assert_eq!(
            hc(Change::Study),
            ContactModel::hunt_crossley(2e5, 0.5).unwrap()
        );
        assert_eq!(
            hc(Change::Mapping(Restitution::Flores)),
            ContactModel::hysteretic(2e5, 1.5, 1.6).unwrap()
        );
        assert_eq!(
            hc(Change::OnsetSpeed),
            ContactModel::hysteretic(2e5, 1.5, -0.75).unwrap()
        );
        assert_eq!(
            hc(Change::Exponent(1.0)),
            ContactModel::hysteretic(2e5, 1.0, 0.75).unwrap()
        );
        let kv = Change::OnsetSpeed.surface(Model::Linear, 2e5, 5.0).unwrap();
        assert_eq!(kv, ContactModel::kelvin_voigt(2e5, 5.0).unwrap());
        let g = Change::Linear(Axis::Restitution)
            .grid(Model::HuntCrossley, 4)
            .unwrap();
        assert_eq!(g.c, vec![0.1, 0.4, 0.7, 1.0]);
        assert_eq!(g.k_s, Grid::new(Model::HuntCrossley, 4).unwrap().k_s);
        let g = Change::Linear(Axis::Stiffness)
            .grid(Model::HuntCrossley, 4)
            .unwrap();
        assert_eq!((g.k_s[0], g.k_s[3]), grid::STIFFNESS);
        assert!((g.k_s[1] - 90_200.0).abs() < 1e-6);
    }

    #[test]
    fn the_sensitivity_grid_is_a_subset_of_the_studys() {
        for model in Model::ALL {
            let big = Grid::new(model, super::super::DEFAULT_GRID).unwrap();
            let small = Grid::new(model, SENSITIVITY_GRID).unwrap();
            for (k, c) in small.points() {
                let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
                assert!(
                    big.points()
                        .iter()
                        .any(|&(kk, cc)| same(k, kk) && same(c, cc)),
                    "{model:?} {k} {c}"
                );
            }
        }
    }

    #[test]
    fn the_record_repeats_the_studys_row_once_per_setting_and_reads_only_its_claims() {
        let claim = |id: &str, ok: bool| {
            let s = claims::STATEMENTS.iter().find(|s| s.id == id).unwrap();
            s.check(ok, "x")
        };
        let all = |ok: bool| ["7.1", "7.2", "7.3", "7.4", "7.5", "7.6"].map(|i| claim(i, ok));
        let outcomes = vec![
            Outcome {
                change: Change::Study,
                claims: all(false).to_vec(),
            },
            Outcome {
                change: Change::BusModel(0.9),
                claims: all(true).to_vec(),
            },
            Outcome {
                change: Change::BusModel(1.1),
                claims: all(false).to_vec(),
            },
            Outcome {
                change: Change::Linear(Axis::Stiffness),
                claims: all(true).to_vec(),
            },
        ];
        let rows = record(&outcomes, 4);
        let names: Vec<(&str, bool)> = rows
            .iter()
            .map(|r| (r.setting.as_str(), r.is_ours()))
            .collect();
        assert_eq!(
            names,
            vec![
                ("m_sc of the linearization (7.31)", true),
                ("m_sc of the linearization (7.31)", false),
                ("m_sc of the linearization (7.31)", false),
                ("k_s spacing of the Hunt–Crossley grid", true),
                ("k_s spacing of the Hunt–Crossley grid", false),
            ]
        );
        assert_eq!(rows[1].readings.len(), 5);
        assert_eq!(rows[4].readings.len(), 2);
        assert_eq!(rows[0].readings[0].verdict, Verdict::Fail);
        let s = reading("7.4", &rows);
        assert!(
            s.contains(
                "PASS under 2 of 3 alternatives of the open settings — all but m_sc of the linearization (7.31) = 1.1×"
            ),
            "{s}"
        );
        let s = reading("7.2", &rows);
        assert!(
            s.contains("PASS under 1 of 2 alternatives of the open settings — m_sc of the linearization (7.31) = 0.9×"),
            "{s}"
        );
        assert!(reading("7.1", &rows).is_empty());
    }
}
