//! What the two RCAC studies of chapter 3 (`rcac-siso`, §3.3.1, and `rcac-miso`, §3.3.2)
//! share: the dereverberated target models (DTMs) built from a scenario's discretized
//! `G_{zu,d}`, the RCAC settings, one sampled-data run with its measurements, and the
//! error-plane figure of Figures 3.5, 3.8, 3.12 and 3.15.
//!
//! ## Target models, §3.2 and (3.49)
//!
//! `G_{zu,d}(e^{jθ})` is the exact ZOH model of the scenario's plant
//! ([`DiscreteModel::from_scenario`] with [`OutputSet::Z`]), as plant-proxy simulates it.
//!
//! - [`Method::Average`]: the complex windowed average (3.40) with half-width
//!   `Δ = 8π rad/s` (`Δ T_s` rad/sample) of `G_{zu,d}` on a uniform grid of
//!   [`AVERAGE_POINTS`] points over `[0, π]`, fitted with `n̂ = 2` poles and one zero (the
//!   relative degree 1 of `G_{zu,d}`) by [`dtf::averaged_dtfs`].
//! - [`Method::Optimize`]: (3.44)–(3.47) with `n̂_max = 2` and `m̂ = n̂ − 1` (the relative
//!   degree of `G_{zu,d}`, as §3.2.2 suggests) on a logarithmic grid of
//!   [`OPTIMIZE_POINTS`] points from [`dtf::DEFAULT_THETA_LO`] to π, by
//!   [`dtf::optimized_dtfs`].
//!
//! Either gives `Ĝ_d` per channel and the target model `G_f = β Ĝ_d` (3.49) (the plants
//! here have no pure delay).
//!
//! ## RCAC, (2.15)–(2.23) and (3.51)–(3.63)
//!
//! `n_c = 20`, `θ_0 = 0`, `k_w = 5 n_c` (RCAC starts at 1 s), `R_z = 1`, `R_u = 0`, and
//! either the gradient update (3.53) with `μ_Exp = α/‖Φ_{f,k}‖_F²` (3.63) and `R = 0`, the
//! update §3.3 describes by its parameters `α` and `R`, or full RLS (2.22)–(2.23) with
//! `P_0 = p_0 I` ([`RLS_P0`]) and `λ = 1`.
//!
//! ## Measurements
//!
//! One run is [`RUN_SECONDS`] of the sampled-data loop ([`simulate::closed_loop`]); the
//! asymptotic error at the sample times is measured on the last [`WINDOW_SECONDS`]: the
//! amplitude of each disturbance tone in `z` (joint least squares,
//! [`control::tones::tone_amplitudes`]) and the peak `|z_k|`. The open loop is measured the same
//! way on the same window; suppression is `20 log10(open / closed)`. The tone amplitude on
//! the window before the last ([`Window::amp_prev`]) shows whether the run had
//! settled.

use crate::study::rcac::RcacError;
use std::path::Path;

use crate::design::dtf::{self, Dtf, ZeroCount};
use crate::design::model::{DiscreteModel, OutputSet};
use crate::design::{C64, grid};
use crate::plot::{Mark, Panel, Series};
use crate::simulate::{self, Trace};
use control::forgetting::ForgettingRule;
use control::target::{TargetChannel, TargetForm, TargetModel};
use control::{Rcac, RcacParams, RcacUpdate, StepSize};
use plant_proxy::scenario::Scenario;
use plotters::style::RGBColor;
use service::config::TargetModelFile;

/// Sample period `T_s` of both structures (§3.3), s.
pub const TS: f64 = 0.01;

/// Uniform grid points over `[0, π]` for the windowed average (3.40).
pub const AVERAGE_POINTS: usize = 8192;

/// Logarithmic grid points for the optimization (3.44).
pub const OPTIMIZE_POINTS: usize = 2000;

/// Half-width `Δ` of the windowed average, rad/s (`8π`, §3.3.1.1 and §3.3.2.1).
pub const DELTA_RAD_S: f64 = 8.0 * std::f64::consts::PI;

/// `n̂` (average) and `n̂_max` (optimization) of both studies.
pub const DTF_ORDER: usize = 2;

/// Controller order `n_c`.
pub const NC: usize = 20;

/// `k_w = 5 n_c`: RCAC applies `u_k = 0` and does not update for the first `k_w` steps.
pub const KW: usize = 5 * NC;

/// `P_0 = p_0 I` of the RLS variant.
pub const RLS_P0: f64 = 1.0;

/// Constant forgetting factor of the RLS variant.
pub const RLS_LAMBDA: f64 = 1.0;

/// Length of every run, s.
pub const RUN_SECONDS: f64 = 120.0;

/// The late window on which the asymptotic error is measured, s.
pub const WINDOW_SECONDS: f64 = 10.0;

/// A run whose `|z_k|` exceeds this is counted as diverged.
pub const DIVERGED: f64 = 1e6;

/// Settling threshold: the peak `|z|` of every later 1 s window stays below the open-loop
/// peak times `10^(−SETTLE_DB/20)`.
pub const SETTLE_DB: f64 = 40.0;

/// How the dereverberated transfer function is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Method {
    /// Complex windowed average (3.40) and a fixed-order fit, §3.2.1.
    Average,
    /// Optimization (3.44)–(3.47), §3.2.2.
    Optimize,
}

impl Method {
    /// Both methods.
    pub const ALL: [Method; 2] = [Method::Average, Method::Optimize];

    /// Short name for files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Average => "average",
            Method::Optimize => "optimize",
        }
    }

    /// Label for figures and tables.
    pub fn label(self) -> &'static str {
        match self {
            Method::Average => "windowed average DTM",
            Method::Optimize => "optimization DTM",
        }
    }

    /// The label and the method's `β` ([`beta`]), as the figures' titles name a DTM:
    /// `windowed average DTM (β = 1)`.
    pub fn label_with_beta(self) -> String {
        format!("{} (β = {})", self.label(), beta(self))
    }
}

/// Which RCAC update law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Update {
    /// Gradient (3.53) with `μ_Exp` (3.63), `R = 0`.
    Gradient,
    /// RLS (2.22)–(2.23), `P_0 = p_0 I`, `λ = 1`.
    Rls,
}

impl Update {
    /// Short name for files and tables.
    pub fn name(self) -> &'static str {
        match self {
            Update::Gradient => "gradient",
            Update::Rls => "rls",
        }
    }

    /// The `--update` choice: `gradient`, `rls` or `both`.
    pub fn parse_set(s: &str) -> Result<Vec<Update>, RcacError> {
        match s {
            "gradient" => Ok(vec![Update::Gradient]),
            "rls" => Ok(vec![Update::Rls]),
            "both" => Ok(vec![Update::Gradient, Update::Rls]),
            other => Err(RcacError::Update(other.into())),
        }
    }
}

/// A dereverberated target model and the DTFs it was made of.
#[derive(Debug, Clone)]
pub struct Dtm {
    /// `G_f = β Ĝ_d` (3.49).
    pub target: TargetModel,
    /// `Ĝ_d` per channel (channel-major).
    pub dtfs: Vec<Dtf>,
}

/// The DTM of `method` among `dtms`.
pub fn dtm_of(dtms: &[(Method, Dtm)], method: Method) -> Result<&Dtm, RcacError> {
    Ok(&dtms
        .iter()
        .find(|d| d.0 == method)
        .ok_or(RcacError::MissingDtm)?
        .1)
}

/// `β` of each method in both studies (§3.3.1.1, §3.3.1.2 and §3.3.2.1; the caption of
/// Figure 3.13 says 0.8 for the windowed average of §3.3.2.1, its text `β = γ = 1`).
pub fn beta(method: Method) -> f64 {
    match method {
        Method::Average => 1.0,
        Method::Optimize => 0.8,
    }
}

/// The DTM of `sc`'s `G_{zu,d}` by `method` with scaling `beta` (see the module docs).
pub fn design_dtm(sc: &Scenario, method: Method, beta: f64) -> Result<Dtm, RcacError> {
    let model = DiscreteModel::from_scenario(sc, OutputSet::Z)?;
    if model.delays.iter().any(|&d| d != 0) {
        return Err(RcacError::InputDelay);
    }
    let ts = model.ts;
    let pi = std::f64::consts::PI;
    let dtfs = match method {
        Method::Average => {
            let th = grid(0.0, pi, AVERAGE_POINTS, false)?;
            let frf = model.frf(&th)?;
            dtf::averaged_dtfs(&frf, DELTA_RAD_S * ts, DTF_ORDER, DTF_ORDER - 1)?
        }
        Method::Optimize => {
            let th = grid(dtf::DEFAULT_THETA_LO, pi, OPTIMIZE_POINTS, true)?;
            let frf = model.frf(&th)?;
            dtf::optimized_dtfs(&frf, DTF_ORDER, ZeroCount::RelativeDegree(1))?
        }
    };
    let m = model.n_inputs();
    let channels = dtfs
        .iter()
        .enumerate()
        .map(|(c, d)| TargetChannel {
            output: c / m,
            input: c % m,
            delay: 0,
            num: d.num.clone(),
            den: d.den.clone(),
        })
        .collect();
    let target = TargetModel {
        sample_period: ts,
        outputs: model.n_outputs(),
        inputs: m,
        beta,
        source: format!("study {}: {}", method.name(), sc.origin),
        form: TargetForm::TransferFunction(channels),
    };
    // The file form must read back: the same checks as RCAC's configuration.
    TargetModel::parse(&target.to_toml(), "generated target model").map_err(RcacError::Target)?;
    Ok(Dtm { target, dtfs })
}

/// RCAC's parameters for the studies: `n_c = 20`, `k_w = 5 n_c`, `θ_0 = 0`, `R_z = I`,
/// `R_u = 0`, the gradient update with `μ_Exp` and step factor `alpha` or RLS.
pub fn rcac_params(target: &TargetModel, update: Update, alpha: f64) -> RcacParams {
    let (lz, lu) = (target.outputs, target.inputs);
    RcacParams {
        nc: NC,
        kw: Some(KW),
        target: target.clone(),
        rz: nalgebra::DMatrix::identity(lz, lz),
        ru: nalgebra::DMatrix::zeros(lu, lu),
        theta0: None,
        update: match update {
            Update::Gradient => RcacUpdate::Gradient {
                step_size: StepSize::Exp,
                alpha,
                r: 0.0,
            },
            Update::Rls => RcacUpdate::Rls {
                p0: RLS_P0,
                rule: ForgettingRule::Constant { lambda: RLS_LAMBDA },
                trace_limit: f64::INFINITY,
            },
        },
        limits: None,
        sample_period: target.sample_period,
        gap_rule: RcacParams::DEFAULT_GAP_RULE,
    }
}

/// `G_f / G_{zu,d}` at `θ` as (magnitude error dB, phase error degrees in `(−180, 180]`).
pub fn model_error(g: C64, gf: C64) -> (f64, f64) {
    let r = gf / g;
    (20.0 * r.norm().log10(), r.arg().to_degrees())
}

/// Measurements of one run on the late window (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct Window {
    /// Amplitude of each tone in `z_0` on the last window.
    pub amp: Vec<f64>,
    /// The same on the window before it.
    pub amp_prev: Vec<f64>,
    /// Largest `|z_{0,k}|` on the last window.
    pub peak: f64,
}

/// Measures `z_0` of `t` on the last `window` samples (and the `window` before them).
pub fn measure(t: &Trace, omegas: &[f64], window: usize) -> Result<Window, RcacError> {
    let z = &t.z[0];
    let n = z.len();
    if n < 2 * window {
        return Err(RcacError::Short(n));
    }
    let last = &z[n - window..];
    let prev = &z[n - 2 * window..n - window];
    Ok(Window {
        amp: control::tones::tone_amplitudes(last, n - window, omegas).map_err(RcacError::Tones)?,
        amp_prev: control::tones::tone_amplitudes(prev, n - 2 * window, omegas)
            .map_err(RcacError::Tones)?,
        peak: last.iter().fold(0.0_f64, |a, v| a.max(v.abs())),
    })
}

/// One closed-loop run and its measurements.
#[derive(Debug, Clone)]
pub struct Point {
    /// Measurements on the late windows (`None` when the run diverged).
    pub closed: Option<Window>,
    /// Guard resets of `θ`.
    pub resets: u64,
    /// `‖θ‖` at the end.
    pub theta_norm: f64,
    /// Time from the start of RCAC (`k_w T_s`) to the start of the first 1 s window after
    /// which every 1 s window's peak `|z|` stays below the reference amplitude
    /// `−SETTLE_DB` dB; `None` when it never does.
    pub settle: Option<f64>,
    /// The traces, when asked for.
    pub trace: Option<Trace>,
}

impl Point {
    /// True when the run stayed finite and bounded with no guard reset.
    pub fn finite(&self) -> bool {
        self.closed.is_some() && self.resets == 0 && self.theta_norm.is_finite()
    }
}

/// The settling time of `z` (see [`Point::settle`]) against the open-loop peak
/// `reference`, with RCAC starting at sample `start`.
pub fn settle_time(z: &[f64], ts: f64, start: usize, reference: f64) -> Option<f64> {
    let w = (1.0 / ts).round() as usize;
    let limit = reference * 10f64.powf(-SETTLE_DB / 20.0);
    let mut settled = None;
    for (i, chunk) in z.chunks(w).enumerate() {
        let peak = chunk.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if peak.is_nan() || peak > limit {
            settled = None;
        } else if settled.is_none() {
            settled = Some(i * w);
        }
    }
    settled.map(|k| k.saturating_sub(start) as f64 * ts)
}

/// Runs RCAC with `params` against `sc`'s plant for `steps` samples and measures the tones
/// `omegas` (rad/sample) on the last `window` samples and the settling time against the
/// open-loop peak `reference`; `theta_every > 0` records `θ` every that many samples into
/// the kept trace (`keep`).
#[allow(clippy::too_many_arguments)]
pub fn run_closed(
    sc: &Scenario,
    params: &RcacParams,
    steps: usize,
    window: usize,
    omegas: &[f64],
    reference: f64,
    keep: bool,
    theta_every: usize,
) -> Result<Point, RcacError> {
    let p = &sc.plant;
    let mut c = Rcac::new(params, simulate::plant_dimensions(p))?;
    let probe = |c: &Rcac| c.theta().to_vec();
    let theta = (theta_every > 0).then_some((&probe as &dyn Fn(&Rcac) -> Vec<f64>, theta_every));
    let run = simulate::closed_loop(p, sc.rig.sample_period, Some(&mut c), steps, theta);
    let resets = c.resets();
    let theta_norm = c.theta().iter().map(|v| v * v).sum::<f64>().sqrt();
    let trace = match run {
        Ok(t) => t,
        // The plant refuses non-finite input or state: the loop diverged.
        Err(_) => {
            return Ok(Point {
                closed: None,
                resets,
                theta_norm: f64::INFINITY,
                settle: None,
                trace: None,
            });
        }
    };
    let bounded = trace.z[0]
        .iter()
        .all(|v| v.is_finite() && v.abs() < DIVERGED);
    let closed = if bounded {
        Some(measure(&trace, omegas, window)?)
    } else {
        None
    };
    let start = params.kw.unwrap_or(0);
    Ok(Point {
        settle: settle_time(&trace.z[0], trace.sample_period, start, reference),
        closed,
        resets,
        theta_norm,
        trace: keep.then_some(trace),
    })
}

/// Open-loop run of `sc` measured like [`run_closed`].
pub fn run_open(
    sc: &Scenario,
    steps: usize,
    window: usize,
    omegas: &[f64],
) -> Result<(Window, Trace), RcacError> {
    let t = simulate::open_loop(&sc.plant, sc.rig.sample_period, steps)?;
    Ok((measure(&t, omegas, window)?, t))
}

/// Colors of the asymptotic-error decades of the error-plane figures, from small (dark
/// blue) to large (red).
const DECADE_COLORS: [RGBColor; 7] = [
    RGBColor(40, 30, 120),
    RGBColor(40, 90, 200),
    RGBColor(30, 160, 190),
    RGBColor(60, 170, 60),
    RGBColor(230, 170, 0),
    RGBColor(230, 90, 20),
    RGBColor(190, 0, 0),
];

/// Lowest decade of the color scale: `|e| < 10^DECADE_LO` takes the first color.
const DECADE_LO: i32 = -6;

/// One point of an error plane: `(magnitude error dB, phase error °)` and its asymptotic
/// error (`None`: diverged).
#[derive(Debug, Clone, Copy)]
pub struct PlanePoint {
    /// `20 log10 |G_f/G_{zu,d}|`.
    pub mag_db: f64,
    /// `∠(G_f/G_{zu,d})`, degrees.
    pub phase_deg: f64,
    /// Asymptotic error (tone amplitude or peak), `None` when the run diverged.
    pub error: Option<f64>,
}

/// A labelled marker of an error plane (ends of a sweep, damped frequencies).
#[derive(Debug, Clone)]
pub struct PlaneMark {
    /// Legend text.
    pub label: String,
    /// `(phase error °, magnitude error dB)`.
    pub at: (f64, f64),
    /// Drawn as a cross or a circle.
    pub mark: Mark,
    /// Color.
    pub color: RGBColor,
}

/// A panel in the manner of Figures 3.5/3.8/3.12/3.15: phase error (x, degrees) against
/// magnitude error (y, dB) of `G_f` to `G_{zu,d}`, each run as a circle colored by the
/// decade of its asymptotic error (diverged runs black crosses), the error locus `locus`
/// over the sweep as a grey line, and `marks`.
pub fn error_plane_panel(
    title: &str,
    points: &[PlanePoint],
    locus: &[(f64, f64)],
    marks: &[PlaneMark],
) -> Panel {
    // The locus, split where the phase wraps at ±180°.
    let mut series = Vec::new();
    let mut piece: Vec<(f64, f64)> = Vec::new();
    for &p in locus {
        if piece.last().is_some_and(|q| (p.0 - q.0).abs() > 180.0) {
            series.push(Series {
                label: String::new(),
                points: std::mem::take(&mut piece),
                color: RGBColor(170, 170, 170),
                mark: Mark::Line,
            });
        }
        piece.push(p);
    }
    series.push(Series {
        label: String::new(),
        points: piece,
        color: RGBColor(170, 170, 170),
        mark: Mark::Line,
    });
    let n = DECADE_COLORS.len();
    let mut bins: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n];
    let mut diverged = Vec::new();
    for p in points {
        match p.error {
            Some(e) if e.is_finite() => {
                let d = if e > 0.0 {
                    e.log10().floor() as i32
                } else {
                    DECADE_LO - 1
                };
                let i = (d - DECADE_LO + 1).clamp(0, n as i32 - 1) as usize;
                bins[i].push((p.phase_deg, p.mag_db));
            }
            _ => diverged.push((p.phase_deg, p.mag_db)),
        }
    }
    for (i, b) in bins.into_iter().enumerate() {
        if b.is_empty() {
            continue;
        }
        let lo = DECADE_LO + i as i32 - 1;
        let label = if i == 0 {
            format!("error < 1e{}", DECADE_LO)
        } else if i == n - 1 {
            format!("error ≥ 1e{lo}")
        } else {
            format!("1e{lo} ≤ error < 1e{}", lo + 1)
        };
        series.push(Series {
            label,
            points: b,
            color: DECADE_COLORS[i],
            mark: Mark::Circle,
        });
    }
    if !diverged.is_empty() {
        series.push(Series {
            label: "diverged".into(),
            points: diverged,
            color: RGBColor(0, 0, 0),
            mark: Mark::Cross,
        });
    }
    for m in marks {
        series.push(Series {
            label: m.label.clone(),
            points: vec![m.at],
            color: m.color,
            mark: m.mark,
        });
    }
    Panel {
        title: title.into(),
        x_label: "phase error ∠(G_f/G_zu,d), degrees".into(),
        y_label: "magnitude error, dB".into(),
        series,
        ..Default::default()
    }
}

pub use crate::stats::median;

/// `f64` as TOML text that reads back to the same value.
pub fn toml_f64(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

/// A list of `f64` as a TOML array.
pub fn toml_list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| toml_f64(*x)).collect();
    format!("[{}]", items.join(", "))
}

/// Product of two polynomials in descending powers.
pub fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// The single run of Figures 3.7/3.10 (SISO) and 3.14/3.17 (MISO): `z` open and closed,
/// `u`, every coefficient (recorded every `every` samples), and the PSDs of the last
/// two windows, RCAC starting at `k_w`.
pub fn single_run_figure(
    path: &Path,
    title: String,
    open: &Trace,
    closed: &Trace,
    every: usize,
) -> Result<(), RcacError> {
    use crate::figures::{AdaptiveRun, Coefficients, adaptive_run_figure, theta_series};
    Ok(adaptive_run_figure(
        path,
        &AdaptiveRun {
            title,
            open: Some(open),
            closed,
            coefficients: Coefficients {
                title: format!(
                    "coefficients θ ({} entries)",
                    closed.theta.first().map_or(0, Vec::len)
                ),
                y_label: "θ".into(),
                series: theta_series(closed, every),
            },
            psd_from: RUN_SECONDS - 2.0 * WINDOW_SECONDS,
            open_psd_from: None,
            psd_segment: 512,
            start: Some(KW as f64 * TS),
        },
    )?)
}
