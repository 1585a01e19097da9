//! The optimization DTF (3.44)–(3.47) of §3.2.2; the method is described on
//! [`optimize_with`].

use super::{C64, Dtf, DtfError, MAX_ROOT, Problem, check_response, log_weights, poly_from_roots};
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use rayon::prelude::*;

/// Default number of log-spaced cells the search stage of [`optimize_with`] evaluates the
/// cost (3.44) on ([`OptimizeOptions::cells`]).
///
/// 320 cells over the 2.7 decades of a 1024-bin FFT grid are ≈ 0.02 in `ln θ` wide (2 % in
/// frequency); a DTF with real roots inside `|r| ≤ 0.999` hardly changes across such a
/// cell, so the cell cost differs from the full-grid cost by far less than the differences
/// between structures, and the final polish is done on the full grid anyway.
pub const DEFAULT_COST_CELLS: usize = 320;

/// Default [`OptimizeOptions::min_gain`]: a structure with more parameters must lower the
/// relative cost by 2 % of itself to be preferred.
pub const DEFAULT_MIN_GAIN: f64 = 0.02;

/// Absolute floor of the gain a larger structure must bring, in units of the relative cost:
/// below it a difference is optimizer noise (an exact low-order fit reaches `10⁻¹²`).
pub const COST_GAIN_FLOOR: f64 = 1e-9;

/// Default [`OptimizeOptions::min_separation`]: real poles (and real zeros) closer than
/// 0.05 to each other are penalized.
pub const DEFAULT_MIN_SEPARATION: f64 = 0.05;

/// Default [`OptimizeOptions::max_iters_per_parameter`].
pub const DEFAULT_MAX_ITERS_PER_PARAMETER: u64 = 250;

/// Nelder–Mead stops the search stage when the standard deviation of the (relative) costs
/// on its simplex falls below this.
pub const SEARCH_SD_TOLERANCE: f64 = 1e-9;

/// The same for the polish on the full grid.
pub const POLISH_SD_TOLERANCE: f64 = 1e-14;

/// Edge (in `s = atanh(a/ρ)`) of the initial simplex of a search from a starting point.
const SEARCH_STEP: f64 = 0.4;

/// Edge of the initial simplex of the polish on the full grid.
const POLISH_STEP: f64 = 0.05;

/// Weight of the separation penalty, in units of the relative cost.
const SEPARATION_WEIGHT: f64 = 1.0;

/// Pole (or zero) positions, in `z`, where a continuation start puts a new root; tried in
/// this order, skipping those within `2 ×` [`OptimizeOptions::min_separation`] of a root
/// already there.
const NEW_ROOT_AT: [f64; 9] = [0.9, 0.5, 0.0, -0.5, 0.7, 0.25, -0.25, 0.97, -0.8];

/// New-pole positions tried per continuation from a structure with as many zeros.
const NEW_POLES: usize = 3;

/// New pole–zero pairs tried per continuation from a structure with one zero fewer.
const NEW_PAIRS: usize = 2;

/// How many zeros `m̂` [`optimize`] gives the DTF of each order `n̂`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZeroCount {
    /// Exactly `m̂` zeros (orders `n̂ < m̂` are skipped).
    Fixed(usize),
    /// `m̂ = n̂ − r`: the relative degree is `r`, e.g. that of the structure (orders
    /// `n̂ < r` are skipped).
    RelativeDegree(usize),
    /// Every `m̂ = 0 … n̂`; the cost decides.
    Choose,
}

impl ZeroCount {
    /// The zero counts `m̂` allowed with `n` poles.
    fn counts(self, n: usize) -> Vec<usize> {
        match self {
            ZeroCount::Fixed(m) if m <= n => vec![m],
            ZeroCount::RelativeDegree(r) if r <= n => vec![n - r],
            ZeroCount::Choose => (0..=n).collect(),
            _ => Vec::new(),
        }
    }
}

/// Settings of [`optimize_with`]; [`Default`] gives the `DEFAULT_*` constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OptimizeOptions {
    /// Number of log-spaced cells of the search stage (see [`DEFAULT_COST_CELLS`]); a grid
    /// with at most this many points is used as it is.
    pub cells: usize,
    /// A structure with more parameters (higher `n̂`, or more zeros at the same `n̂`) is
    /// preferred only when its relative cost is lower by `min_gain ×` the current one (and
    /// by at least [`COST_GAIN_FLOOR`]); the first order whose best structure does not
    /// achieve that ends the search. 0 tries every order up to `n̂_max`.
    pub min_gain: f64,
    /// Real poles closer than this to each other, and likewise zeros, are penalized
    /// (see [`optimize_with`]); 0 disables the penalty.
    pub min_separation: f64,
    /// Nelder–Mead iteration cap per run: this many iterations per parameter.
    pub max_iters_per_parameter: u64,
}

impl Default for OptimizeOptions {
    fn default() -> Self {
        Self {
            cells: DEFAULT_COST_CELLS,
            min_gain: DEFAULT_MIN_GAIN,
            min_separation: DEFAULT_MIN_SEPARATION,
            max_iters_per_parameter: DEFAULT_MAX_ITERS_PER_PARAMETER,
        }
    }
}

/// One `(n̂, m̂)` structure tried by [`optimize_all`].
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Number of poles `n̂`.
    pub poles: usize,
    /// Number of zeros `m̂`.
    pub zeros: usize,
    /// The best DTF of that structure.
    pub dtf: Dtf,
    /// Its cost (3.44) on the full grid, divided by `∫ |G_d|² d(log θ)` on the same grid
    /// (without the separation penalty; the measure of [`log_cost`]).
    pub relative_cost: f64,
    /// Cost evaluations spent on this structure (search and polish).
    pub evaluations: u64,
}

/// The result of [`optimize_all`]: the winner and every structure tried.
#[derive(Debug, Clone, PartialEq)]
pub struct Optimized {
    /// The selected DTF (see [`OptimizeOptions::min_gain`]).
    pub best: Dtf,
    /// Its relative cost (see [`Candidate::relative_cost`]).
    pub relative_cost: f64,
    /// Every structure tried, in order of increasing `n̂` then `m̂`.
    pub candidates: Vec<Candidate>,
    /// Cost evaluations in all (each on the cells or on the full grid).
    pub evaluations: u64,
    /// Number of points (cells) of the search stage.
    pub cells: usize,
    /// The highest order tried (`n̂_max`, or lower when the search stopped early).
    pub max_order_tried: usize,
}

/// The points of one discretization of (3.44): `Σ_k w_k |g_k − k φ(z_k)|²`.
struct Points {
    z: Vec<C64>,
    g: Vec<C64>,
    w: Vec<f64>,
}

/// The grid itself.
fn full_points(theta: &[f64], g: &[C64], w: &[f64]) -> Points {
    Points {
        z: theta.iter().map(|&t| C64::from_polar(1.0, t)).collect(),
        g: g.to_vec(),
        w: w.to_vec(),
    }
}

/// The grid lumped into at most `cells` cells of equal width in `ln θ`: cell `c` holds the
/// weight `W_c = Σ w_k`, the weighted mean response `Ḡ_c = Σ w_k g_k / W_c` and sits at
/// the weighted mean frequency `θ̄_c = Σ w_k θ_k / W_c`. With `φ` constant across a cell,
/// `Σ_k w_k conj(φ_k) g_k = W_c conj(φ_c) Ḡ_c` and `Σ_k w_k |φ_k|² = W_c |φ_c|²`
/// (to first order in the cell width, thanks to `θ̄_c`), so the cost on the cells plus
/// the constant within-cell variance of `g` is the full cost: every bin counts (a
/// resonance between two cells is not skipped, as a subsample of bins would be).
fn lumped_points(theta: &[f64], g: &[C64], w: &[f64], cells: usize) -> Points {
    if theta.len() <= cells.max(1) {
        return full_points(theta, g, w);
    }
    let l0 = theta[0].ln();
    let width = (theta[theta.len() - 1].ln() - l0) / cells as f64;
    let mut acc = vec![(0.0, C64::new(0.0, 0.0), 0.0); cells];
    for k in 0..theta.len() {
        let c = (((theta[k].ln() - l0) / width) as usize).min(cells - 1);
        acc[c].0 += w[k];
        acc[c].1 += g[k] * w[k];
        acc[c].2 += w[k] * theta[k];
    }
    let mut p = Points {
        z: Vec::with_capacity(cells),
        g: Vec::with_capacity(cells),
        w: Vec::with_capacity(cells),
    };
    for (wc, gc, tc) in acc {
        if wc > 0.0 {
            p.z.push(C64::from_polar(1.0, tc / wc));
            p.g.push(gc / wc);
            p.w.push(wc);
        }
    }
    p
}

/// The root `ρ tanh(s)` of a parameter: the factor is `z + a`, so the pole (or zero) sits
/// at `−a`.
fn coefficient(s: f64) -> f64 {
    MAX_ROOT * s.tanh()
}

/// The parameter that puts a pole (or zero) at `root` (clamped inside the bound).
fn parameter(root: f64) -> f64 {
    (-root / MAX_ROOT).clamp(-0.9999, 0.9999).atanh()
}

/// `Σ (1 − d/δ)²` over neighbouring roots closer than `δ` (`roots` is sorted in place).
fn crowding(roots: &mut [f64], delta: f64) -> f64 {
    if delta <= 0.0 {
        return 0.0;
    }
    roots.sort_by(f64::total_cmp);
    roots
        .windows(2)
        .map(|r| (1.0 - (r[1] - r[0]) / delta).max(0.0).powi(2))
        .sum()
}

/// The cost (3.44) of a structure `(n̂, m̂)` as a function of the unconstrained parameters
/// `[s_1 … s_n̂, t_1 … t_m̂]`, `a_i = ρ tanh(s_i)`, `b_i = ρ tanh(t_i)`, the gain `k` in
/// closed form; relative to `∫ |G_d|² d(log θ)` of the full grid, plus the separation
/// penalty.
#[derive(Clone, Copy)]
struct LogCost<'a> {
    points: &'a Points,
    poles: usize,
    /// `Σ w |g|²` on the full grid.
    norm: f64,
    min_separation: f64,
}

impl LogCost<'_> {
    /// The optimal gain and the relative cost without penalty.
    fn gain_and_cost(&self, p: &[f64]) -> (f64, f64) {
        let (s, t) = p.split_at(self.poles);
        let a: Vec<f64> = s.iter().map(|&v| coefficient(v)).collect();
        let b: Vec<f64> = t.iter().map(|&v| coefficient(v)).collect();
        let pts = self.points;
        let (mut cross, mut power) = (0.0, 0.0);
        for k in 0..pts.z.len() {
            let z = pts.z[k];
            let num = b.iter().fold(C64::new(1.0, 0.0), |acc, &v| acc * (z + v));
            let den = a.iter().fold(C64::new(1.0, 0.0), |acc, &v| acc * (z + v));
            let phi = num / den;
            let g = pts.g[k];
            cross += pts.w[k] * (phi.re * g.re + phi.im * g.im);
            power += pts.w[k] * phi.norm_sqr();
        }
        if !(power > 0.0 && power.is_finite()) {
            return (0.0, 1.0);
        }
        let gain = cross / power;
        // Σ w |g − kφ|² = Σ w |g|² − cross²/power at the optimal k.
        (gain, (1.0 - cross * cross / (power * self.norm)).max(0.0))
    }

    /// The separation penalty of the parameters `p`.
    fn penalty(&self, p: &[f64]) -> f64 {
        if self.min_separation <= 0.0 {
            return 0.0;
        }
        let (s, t) = p.split_at(self.poles);
        let mut a: Vec<f64> = s.iter().map(|&v| coefficient(v)).collect();
        let mut b: Vec<f64> = t.iter().map(|&v| coefficient(v)).collect();
        SEPARATION_WEIGHT
            * (crowding(&mut a, self.min_separation) + crowding(&mut b, self.min_separation))
    }
}

impl CostFunction for LogCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, p: &Self::Param) -> Result<Self::Output, ArgminError> {
        Ok(self.gain_and_cost(p).1 + self.penalty(p))
    }
}

/// One Nelder–Mead run: the best point, its (penalized) cost and the evaluations spent.
struct Run {
    x: Vec<f64>,
    cost: f64,
    evaluations: u64,
}

/// argmin's Nelder–Mead from `x0`, initial simplex of edge `step` along the axes,
/// stopped when the costs on the simplex agree to `sd_tolerance` or after `max_iters`
/// iterations. Expansion and shrink coefficients adapted to the dimension `d`
/// (`γ = 1 + 2/d`, `σ = 1 − 1/d`; Gao and Han, 2012), which helps for `d ≥ 4`.
fn nelder_mead(
    problem: LogCost<'_>,
    x0: &[f64],
    step: f64,
    sd_tolerance: f64,
    max_iters: u64,
) -> Result<Run, DtfError> {
    let d = x0.len();
    let mut simplex = vec![x0.to_vec()];
    for i in 0..d {
        let mut v = x0.to_vec();
        v[i] += step;
        simplex.push(v);
    }
    let df = d.max(2) as f64;
    let nm_err = |e: ArgminError| DtfError::NelderMead(e.to_string());
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(sd_tolerance)
        .and_then(|s| s.with_gamma(1.0 + 2.0 / df))
        .and_then(|s| s.with_sigma(1.0 - 1.0 / df))
        .map_err(nm_err)?;
    let res = Executor::new(problem, solver)
        .configure(|s| s.max_iters(max_iters).counting(true))
        .run()
        .map_err(nm_err)?;
    let state = res.state();
    let x = state.get_best_param().cloned().ok_or(DtfError::NoPoint)?;
    let evaluations = state
        .get_func_counts()
        .get("cost_count")
        .copied()
        .unwrap_or(0);
    Ok(Run {
        x,
        cost: state.get_best_cost(),
        evaluations,
    })
}

/// A solved structure, in root space (`z`-plane positions of the poles and zeros).
#[derive(Clone)]
struct Solved {
    zeros: usize,
    pole_roots: Vec<f64>,
    zero_roots: Vec<f64>,
    relative_cost: f64,
}

/// Parameters of the roots.
fn to_parameters(pole_roots: &[f64], zero_roots: &[f64]) -> Vec<f64> {
    pole_roots
        .iter()
        .chain(zero_roots)
        .map(|&r| parameter(r))
        .collect()
}

/// `count` roots spread evenly over `[lo, hi]` (cell midpoints).
fn spread(count: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..count)
        .map(|i| lo + (hi - lo) * (i as f64 + 0.5) / count as f64)
        .collect()
}

/// Up to `count` positions of [`NEW_ROOT_AT`] at least `2δ` away from every root of
/// every list in `away_from`.
fn new_roots(count: usize, away_from: &[&[f64]], delta: f64) -> Vec<f64> {
    NEW_ROOT_AT
        .iter()
        .copied()
        .filter(|&r| {
            away_from
                .iter()
                .all(|list| list.iter().all(|&q| (q - r).abs() >= 2.0 * delta))
        })
        .take(count)
        .collect()
}

/// The starting points of structure `(n, m)`: for the first order tried, a small grid of
/// spread-out roots; above it, continuations of the structures of the previous order
/// (`parents`), namely `(n − 1, m)` plus a new pole at [`NEW_POLES`] positions and
/// `(n − 1, m − 1)` plus a pole–zero pair (a cancelling pair, so the start costs what the
/// parent does) at [`NEW_PAIRS`] positions, and two cold starts with spread-out roots.
fn starts(n: usize, m: usize, parents: &[Solved], delta: f64) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    if parents.is_empty() {
        let pole_sets: Vec<Vec<f64>> = if n == 1 {
            [-0.5, 0.0, 0.5, 0.8, 0.95]
                .iter()
                .map(|&r| vec![r])
                .collect()
        } else {
            vec![
                spread(n, -0.3, 0.9),
                spread(n, 0.2, 0.95),
                spread(n, -0.8, 0.8),
            ]
        };
        let zero_sets: Vec<Vec<f64>> = if m == 0 {
            vec![Vec::new()]
        } else if m == 1 {
            [-0.8, 0.0, 0.8].iter().map(|&r| vec![r]).collect()
        } else {
            vec![
                spread(m, -0.9, 0.9),
                spread(m, -0.9, 0.0),
                spread(m, 0.0, 0.9),
            ]
        };
        for p in &pole_sets {
            for q in &zero_sets {
                out.push(to_parameters(p, q));
            }
        }
        return out;
    }
    for parent in parents {
        if parent.zeros == m {
            let (p, q) = (&parent.pole_roots, &parent.zero_roots);
            for r in new_roots(NEW_POLES, &[p], delta) {
                let mut poles = p.clone();
                poles.push(r);
                out.push(to_parameters(&poles, q));
            }
        } else if parent.zeros + 1 == m {
            let (p, q) = (&parent.pole_roots, &parent.zero_roots);
            for r in new_roots(NEW_PAIRS, &[p, q], delta) {
                let (mut poles, mut zeros) = (p.clone(), q.clone());
                poles.push(r);
                zeros.push(r);
                out.push(to_parameters(&poles, &zeros));
            }
        }
    }
    out.push(to_parameters(&spread(n, -0.3, 0.9), &spread(m, -0.9, 0.9)));
    out.push(to_parameters(&spread(n, 0.2, 0.95), &spread(m, -0.9, 0.0)));
    out
}

/// Whether `cost` improves on `incumbent` enough to replace it (see
/// [`OptimizeOptions::min_gain`]).
fn improves(cost: f64, incumbent: f64, min_gain: f64) -> bool {
    cost < incumbent - (min_gain * incumbent).max(COST_GAIN_FLOOR)
}

/// The DTF of least cost (3.44)–(3.47) with `n̂ ≤ n_max` and zeros per `zeros`, with the
/// default [`OptimizeOptions`]; the response `g` is given on `theta_log_grid`
/// (increasing, `θ_0 > 0`, e.g. [`super::default_log_grid`] or the bins of an FFT without
/// `θ = 0`). See [`optimize_with`] for the method.
pub fn optimize(
    theta_log_grid: &[f64],
    g: &[C64],
    n_max: usize,
    zeros: ZeroCount,
) -> Result<Dtf, DtfError> {
    optimize_all(theta_log_grid, g, n_max, zeros).map(|o| o.best)
}

/// [`optimize`], returning every structure tried, the costs and the effort.
pub fn optimize_all(
    theta_log_grid: &[f64],
    g: &[C64],
    n_max: usize,
    zeros: ZeroCount,
) -> Result<Optimized, DtfError> {
    optimize_with(theta_log_grid, g, n_max, zeros, &OptimizeOptions::default())
}

/// The optimization DTF (3.44)–(3.47) of §3.2.2:
///
/// ```text
///  min_{k, a, b, n̂, m̂} ∫_0^π |G_d(e^{jθ}) − Ĝ_d(e^{jθ})|² d(log θ)                 (3.44)
///  subject to  Ĝ_d(z) = k Π_{i=1}^{m̂} (z + b_i) / Π_{i=1}^{n̂} (z + a_i),            (3.45)
///              m̂ ≤ n̂ ≤ n̂_max,  Ĝ_d asymptotically stable,                   (3.46), (3.47)
/// ```
///
/// with real `a_i`, `b_i`, on the grid `theta_log_grid` (any increasing grid with
/// `θ_0 > 0`; the trapezoid weights in `log θ` of [`log_weights`] make the sum approximate
/// the integral, so a linear FFT grid is fine too).
///
/// **Parametrization.** `a_i = ρ tanh(s_i)`, `b_i = ρ tanh(t_i)`, `ρ =` [`MAX_ROOT`]: real
/// poles and zeros strictly inside the unit circle, so (3.47) holds by construction (and
/// the zeros are minimum phase). For given `a`, `b` the gain minimizes the weighted cost in
/// closed form, `k = Σ w Re(φ̄ G) / Σ w |φ|²` with `φ = Π(z + b)/Π(z + a)`, leaving
/// `n̂ + m̂` parameters for argmin's Nelder–Mead simplex method.
///
/// **Two grids.** The search runs on the grid lumped into at most
/// [`OptimizeOptions::cells`] cells of equal width in `log θ` (weighted mean response per
/// cell, see [`DEFAULT_COST_CELLS`]); a grid of 1024 FFT bins costs a third per evaluation
/// and its many bins per octave near Nyquist count as much as they should, no more. The
/// best point of each structure is then polished by Nelder–Mead on the full grid (small
/// simplex, tolerance [`POLISH_SD_TOLERANCE`]), and every cost reported is the full-grid
/// one.
///
/// **Order by order, with continuation.** Orders `n̂ = 1, 2, …` in turn, every zero count
/// `m̂` allowed by `zeros` at each. The first order starts from a small grid of spread-out
/// roots; order `n̂ + 1` starts from the polished order-`n̂` solutions plus a new pole
/// (three positions, away from the poles already there) or plus a cancelling pole–zero
/// pair (two positions; such a start costs exactly what its parent does, so more zeros
/// never do worse than the parent), and from two spread-out cold starts. All runs of one
/// order go in parallel (rayon). Each run stops when the relative costs on its simplex
/// agree to [`SEARCH_SD_TOLERANCE`] or after [`OptimizeOptions::max_iters_per_parameter`]
/// iterations per parameter, so the evaluations are bounded (reported in
/// [`Optimized::evaluations`]).
///
/// **Parsimony.** Structures are compared in order of increasing `n̂`, then `m̂`; one with
/// more parameters replaces the incumbent only if its relative cost is lower by
/// [`OptimizeOptions::min_gain`] (2 %) of the incumbent's, at least [`COST_GAIN_FLOOR`].
/// The first order whose best structure does not replace the incumbent is the last one
/// tried: once another pole buys nothing, more poles seldom do, and a lightly damped
/// response (whose resonances no real-rooted DTF can follow) otherwise spends most of the
/// time on orders that fit noise.
///
/// **No clusters of real roots.** The real-root constraint is often active: a best fit
/// would like a complex pair, and the optimizer then drives several real poles onto
/// nearly the same point (a near-repeated, ill-conditioned cluster that buys a sliver of
/// cost). The search cost therefore adds `Σ (1 − d/δ)²` over neighbouring poles (and
/// neighbouring zeros) at distance `d < δ =` [`OptimizeOptions::min_separation`]
/// (0.05), weighted like the relative cost itself; the starting points are spread out as
/// well. The penalty is zero for roots `δ` apart, so well-separated optima (such as (3.48))
/// are unchanged; [`Candidate::relative_cost`] is reported without it.
pub fn optimize_with(
    theta_log_grid: &[f64],
    g: &[C64],
    n_max: usize,
    zeros: ZeroCount,
    options: &OptimizeOptions,
) -> Result<Optimized, DtfError> {
    let what = "DTF optimization";
    let bad = |problem| DtfError::Input { what, problem };
    let theta = theta_log_grid;
    check_response(theta, g, what)?;
    let w = log_weights(theta).map_err(|e| DtfError::In {
        what,
        source: Box::new(e),
    })?;
    if n_max == 0 {
        return Err(bad(Problem::NoOrder));
    }
    if !(options.min_gain >= 0.0 && options.min_separation >= 0.0) {
        return Err(bad(Problem::Options(format!("{options:?}"))));
    }
    let norm: f64 = (0..g.len()).map(|k| w[k] * g[k].norm_sqr()).sum();
    if norm == 0.0 {
        return Err(bad(Problem::ZeroResponse));
    }
    let full = full_points(theta, g, &w);
    let cells = lumped_points(theta, g, &w, options.cells);
    let cost_on = |points, poles| LogCost {
        points,
        poles,
        norm,
        min_separation: options.min_separation,
    };
    let max_iters = |d: usize| options.max_iters_per_parameter.max(1) * d as u64;

    let mut candidates: Vec<Candidate> = Vec::new();
    let mut evaluations = 0;
    let mut parents: Vec<Solved> = Vec::new();
    let mut incumbent: Option<usize> = None;
    let mut max_order_tried = 0;
    for n in 1..=n_max {
        let ms = zeros.counts(n);
        if ms.is_empty() {
            continue;
        }
        max_order_tried = n;
        // Search on the cells: every (m̂, start) of this order in parallel.
        let jobs: Vec<(usize, Vec<f64>)> = ms
            .iter()
            .flat_map(|&m| {
                starts(n, m, &parents, options.min_separation)
                    .into_iter()
                    .map(move |x0| (m, x0))
            })
            .collect();
        let runs = jobs
            .par_iter()
            .map(|(m, x0)| {
                nelder_mead(
                    cost_on(&cells, n),
                    x0,
                    SEARCH_STEP,
                    SEARCH_SD_TOLERANCE,
                    max_iters(n + m),
                )
                .map(|r| (*m, r))
            })
            .collect::<Result<Vec<_>, DtfError>>()?;
        // Polish the best run of each structure on the full grid, in parallel.
        let polished = ms
            .par_iter()
            .map(|&m| {
                let mine = runs.iter().filter(|(rm, _)| *rm == m);
                let spent: u64 = mine.clone().map(|(_, r)| r.evaluations).sum();
                let (_, best) = mine
                    .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost))
                    .expect("every structure has a start");
                let problem = cost_on(&full, n);
                let run = nelder_mead(
                    problem,
                    &best.x,
                    POLISH_STEP,
                    POLISH_SD_TOLERANCE,
                    max_iters(n + m),
                )?;
                let (gain, _) = problem.gain_and_cost(&run.x);
                let (s, t) = run.x.split_at(n);
                let pole_roots: Vec<f64> = s.iter().map(|&v| -coefficient(v)).collect();
                let zero_roots: Vec<f64> = t.iter().map(|&v| -coefficient(v)).collect();
                let as_c = |r: &[f64]| r.iter().map(|&v| C64::new(v, 0.0)).collect::<Vec<_>>();
                let num: Vec<f64> = poly_from_roots(&as_c(&zero_roots))
                    .iter()
                    .map(|c| c * gain)
                    .collect();
                let dtf = Dtf::new(num, poly_from_roots(&as_c(&pole_roots)))?;
                // Reported directly (the closed form above loses digits near 0).
                let relative_cost = (0..full.z.len())
                    .map(|k| {
                        full.w[k]
                            * (full.g[k] - super::eval_tf(&dtf.num, &dtf.den, full.z[k])).norm_sqr()
                    })
                    .sum::<f64>()
                    / norm;
                Ok((
                    Candidate {
                        poles: n,
                        zeros: m,
                        dtf,
                        relative_cost,
                        evaluations: spent + run.evaluations + 1,
                    },
                    Solved {
                        zeros: m,
                        pole_roots,
                        zero_roots,
                        relative_cost,
                    },
                ))
            })
            .collect::<Result<Vec<_>, DtfError>>()?;
        // Parsimony: the incumbent changes only for a clear gain.
        let mut replaced = incumbent.is_none();
        for (c, _) in &polished {
            evaluations += c.evaluations;
            candidates.push(c.clone());
            let i = candidates.len() - 1;
            match incumbent {
                None => incumbent = Some(i),
                Some(b)
                    if improves(
                        c.relative_cost,
                        candidates[b].relative_cost,
                        options.min_gain,
                    ) =>
                {
                    incumbent = Some(i);
                    replaced = true;
                }
                Some(_) => {}
            }
        }
        parents = polished.into_iter().map(|(_, s)| s).collect();
        parents.sort_by(|a, b| a.relative_cost.total_cmp(&b.relative_cost));
        if !replaced {
            break;
        }
    }
    let best = incumbent.map(|i| candidates[i].clone()).ok_or_else(|| {
        bad(Problem::NoStructure {
            n_max,
            zeros: format!("{zeros:?}"),
        })
    })?;
    Ok(Optimized {
        best: best.dtf,
        relative_cost: best.relative_cost,
        candidates,
        evaluations,
        cells: cells.z.len(),
        max_order_tried,
    })
}

/// The relative cost (3.44) of any `dtf` against `g` on a logarithmic grid (the measure of
/// [`Candidate::relative_cost`]), to compare a printed DTF with an optimized one.
pub fn log_cost(theta_log_grid: &[f64], g: &[C64], dtf: &Dtf) -> Result<f64, DtfError> {
    check_response(theta_log_grid, g, "log cost")?;
    let w = log_weights(theta_log_grid)?;
    let (mut e, mut n) = (0.0, 0.0);
    for (k, &t) in theta_log_grid.iter().enumerate() {
        e += w[k] * (g[k] - dtf.eval(t)).norm_sqr();
        n += w[k] * g[k].norm_sqr();
    }
    Ok(e / n)
}
