//! # condense: PCAC's receding-horizon problem as a dense QP
//!
//! ## The problem (section 2.3.2.2 of the dissertation)
//!
//! Over a horizon of `ℓ` steps the outputs are predicted as
//!
//! ```text
//! Y = Γ̂ x_{1|k} + T̂ U                                              (2.43)
//! Y = [y_{1|k}; …; y_{ℓ|k}] ∈ R^{ℓp},   U = [u_{1|k}; …; u_{ℓ|k}] ∈ R^{ℓm}   (2.44)
//! Γ̂ = [Ĉ; Ĉ Â; …; Ĉ Â^{ℓ−1}]                                        (2.45)
//!
//!      ⎡ 0        0        ⋯   0   0 ⎤
//!      ⎢ H_1      0        ⋯   0   0 ⎥
//! T̂ =  ⎢ H_2      H_1      ⋯   0   0 ⎥      H_i = Ĉ Â^{i−1} B̂ ∈ R^{p×m}   (2.46)
//!      ⎢ ⋮                 ⋱       ⋮ ⎥
//!      ⎣ H_{ℓ−1}  H_{ℓ−2}  ⋯  H_1  0 ⎦
//! ```
//!
//! (block `(i, j)` of `T̂` is `H_{i−j}` for `i > j` and zero otherwise: `y_{1|k}` does not
//! depend on `U`, and `u_{ℓ|k}` affects no predicted output). The moves are taken relative
//! to the current input `u_k`,
//!
//! ```text
//! ΔU = [u_{1|k} − u_k; u_{2|k} − u_{1|k}; …; u_{ℓ|k} − u_{ℓ−1|k}] = D U − E u_k      (2.47)
//! ```
//!
//! with `D` the block difference operator (`I` on the block diagonal, `−I` below it) and
//! `E = [I; 0; …; 0]`. The receding-horizon problem is
//!
//! ```text
//! min_U  (Y_t − 𝓡)ᵀ Q (Y_t − 𝓡) + ΔUᵀ R ΔU,    Y_t = (I_ℓ ⊗ C_t) Y        (2.48)
//! s.t.   C_ℓ Y + 𝓓_ℓ ≤ 0,   C_ℓ = I_ℓ ⊗ C_c,   𝓓_ℓ = 1_ℓ ⊗ 𝓓                 (2.49)
//!        U_min ≤ U ≤ U_max,   U_min = 1_ℓ ⊗ u_min,   U_max = 1_ℓ ⊗ u_max        (2.50)
//!        ΔU_min ≤ ΔU ≤ ΔU_max,   ΔU_min = 1_ℓ ⊗ Δu_min, …                     (2.51)
//! ```
//!
//! where `C_t ∈ R^{p_t×p}` picks the tracked outputs of each `y_{i|k}` (e.g. node 8 of the
//! truss's four sensors: `C_t = [0 0 0 1]`) and `C_c ∈ R^{n_c×p}` the constrained ones
//! (the dissertation writes `C_ℓ = I_ℓ ⊗ (C C_c)`; here [`OutputConstraints::c`] is that
//! per-step product). `Q = diag(Q_1, …, Q_ℓ)` and `R = diag(R_1, …, R_ℓ)` are block
//! diagonal with diagonal blocks ([`Weight`]).
//!
//! ## The condensed QP
//!
//! With `T_t = (I_ℓ ⊗ C_t) T̂` (block `(i, j)` is `G_{i−j} = C_t H_{i−j} ∈ R^{p_t×m}`) and the
//! free tracking error `e = (I_ℓ ⊗ C_t) Γ̂ x_{1|k} − 𝓡`, the cost (2.48) is exactly
//!
//! ```text
//! J(U) = ½ Uᵀ H U + fᵀ U + c,
//! H = 2 (T_tᵀ Q T_t + Dᵀ R D),
//! f = 2 (T_tᵀ Q e − Dᵀ R E u_k) = 2 T_tᵀ Q e − 2 [R_1 u_k; 0; …; 0],
//! c = eᵀ Q e + u_kᵀ R_1 u_k
//! ```
//!
//! (the factor 2 keeps the solver's objective equal to (2.48) minus `c`; the minimizer does
//! not depend on it), which is the [`QpProblem`] `min ½ Uᵀ H U + fᵀ U` s.t. `lb ≤ U ≤ ub`,
//! `G U ≤ h` of [`super::qp`], with
//!
//! - `lb = U_min`, `ub = U_max` (2.50);
//! - if move bounds are given, `2ℓm` rows (2.51): row `i·m + j` is `ΔU_{i,j} ≤ Δu_max,j`
//!   (`+1` at `(i, j)`, `−1` at `(i−1, j)`, `h = Δu_max,j + u_k,j` for `i = 0`), row
//!   `ℓm + i·m + j` is `−ΔU_{i,j} ≤ −Δu_min,j`; an infinite bound gives `h = +∞` (the
//!   solver drops the row);
//! - if output constraints are given, `ℓ n_c` rows (2.49) after those: row `i·n_c + r` is
//!   `(C_c T̂)_{(i,r)} U ≤ −𝓓_r − (C_c Γ̂ x_{1|k})_{(i,r)}`, i.e. `G U − h = C_ℓ Y + 𝓓_ℓ`.
//!   The rows of the first step are zero (`y_{1|k}` is already decided): when the
//!   predicted `y_{1|k}` violates its constraint the QP is infeasible
//!   ([`super::qp::QpStatus::Infeasible`]) and the caller falls back ([`fallback_input`]).
//!
//! Steps are numbered `0..ℓ` in the code (`i = 0` is `y_{1|k}` / `u_{1|k}`).
//!
//! ## The tone-notch input cost (2.47')–(2.48')
//!
//! With [`MpcSpec::input_notch`] (PCAC's internal model of known tones,
//! [`crate::internal_model`]; an extension beyond the dissertation) the cost is (2.48)
//! plus `Vᵀ R_v V + Uᵀ R_u U`, `V = 𝒲 U + v_free` (2.47'), `𝒲` the lower triangular
//! block Toeplitz matrix with blocks `w_{i−j} I_m` of the notch's impulse response
//! ([`NotchInputCost`]). Then
//!
//! ```text
//! H += 2 (𝒲ᵀ R_v 𝒲 + R_u),   f += 2 𝒲ᵀ R_v v_free,   c += v_freeᵀ R_v v_free
//! ```
//!
//! The first term is constant, formed once in [`Condenser::new`] and added to every `H`
//! (`(ℓm)²` additions); the second costs `O(ℓ² m / 2)` per build
//! ([`Condenser::build_notched`]). Since `w_0 = 1`, `𝒲ᵀ R_v 𝒲` is positive definite for
//! `R_v > 0`, so `R` may then be 0.
//!
//! ## The structure exploited
//!
//! - **Tracking first.** Only `Y_t` enters the cost, so the Markov parameters are
//!   projected once, `G_s = C_t H_s` (`p_t × m`, `s = 1..ℓ−1`, `O(ℓ p_t p m)`), and all
//!   products are done in `p_t` rows instead of `p` (a quarter of the work for the truss's
//!   `p = 4`, `p_t = 1`).
//! - **`T_tᵀ Q T_t` by blocks.** Block `(a, b)` (steps `0..ℓ`) is
//!   `Σ_{i = max(a,b)+1}^{ℓ−1} G_{i−a}ᵀ Q_i G_{i−b}`. With a step-independent `Q` the
//!   blocks along a diagonal differ by one term,
//!
//!   ```text
//!   block(a, b) = block(a+1, b+1) + G_{ℓ−1−a}ᵀ Q G_{ℓ−1−b},      block(·, ℓ−1) = block(ℓ−1, ·) = 0,
//!   ```
//!
//!   (the sum for `(a+1, b+1)` is the sum for `(a, b)` shifted by one step, which loses
//!   its last term `i = ℓ−1`), so each of the `ℓ(ℓ+1)/2` upper blocks costs one
//!   `m × p_t × m` product: `O(ℓ² m² p_t)` in all, against `O(ℓ³ m² p)` for the dense
//!   triple product. (Walking the recursion backward from the zero last block row and
//!   column needs no first row to be summed directly, and it adds the terms in the same
//!   order as the direct sum.) With a per-step `Q` ([`Weight::PerStep`]) the recursion
//!   runs with the `Q` that most steps share, and each step `i` whose `Q_i` differs adds
//!   `G_{i−a}ᵀ (Q_i − Q) G_{i−b}` to the blocks `a ≤ b < i` (`O(i² m² p_t / 2)`): a terminal
//!   weight costs one such correction. When more than a third of the steps differ, the
//!   blocks are summed directly instead, `O(ℓ³ m² p_t / 6)`.
//! - **`Dᵀ R D`** is block tridiagonal with diagonal blocks (`R` diagonal): diagonal
//!   `R_i + R_{i+1}` (`R_ℓ` on the last block), off-diagonal `−R_{i+1}`; it is added entry
//!   by entry.
//! - **Constant parts are built once.** `lb`, `ub`, the move-bound rows of `G` and their
//!   `h` (except the first step's, which carries `u_k`), and the zero blocks of the output
//!   rows are set in [`Condenser::new`]; [`Condenser::build`] rewrites only what depends on
//!   the model, the free response, `u_k` and `𝓡`.
//!
//! ## Real-time use
//!
//! [`Condenser::new`] checks the [`MpcSpec`] (refusing bad ones with a [`SpecError`]
//! saying what is wrong) and allocates every buffer; [`Condenser::build`] allocates
//! nothing (checked with a `malloc` uprobe over the end-to-end test's 61 builds, warm-start
//! shifts and solves: no allocation under `build`), never panics, and returns a [`QpProblem`] borrowing the condenser, ready for
//! [`super::qp::DenseQpSolver::solve`] on a solver made with
//! `DenseQpSolver::new(condenser.n(), condenser.n_ineq(), …)`. The applied input is
//! [`Condenser::first_move`] of the solution (`u_{1|k}`; the rest of `U` is discarded, or
//! shifted into the next warm start: [`Condenser::shift_active_set`] moves the solver's
//! active set one step forward for [`WarmStart::ActiveSet`](super::qp::WarmStart)).
//!
//! **Fallback policy.** When the solver does not return
//! [`Solved`](super::qp::QpStatus::Solved) (infeasible, iteration cap, numerical error) or
//! `build` refuses its inputs, the caller applies [`Condenser::fallback_input`]: hold the
//! current input `u_k`, clipped into the input bounds (2.50), moving towards them by no
//! more than the move bounds (2.51) allow. That input is always within `[u_min, u_max]`,
//! and it satisfies the move bounds whenever `u_k` could reach the box in one bounded move
//! (always when `u_k` was itself inside). A non-finite `u_k` is replaced by `0` clipped
//! into the box.
//!
//! ## Cost
//!
//! With a constant `Q` a whole [`Condenser::build`] (`H`, `f`, `h` and the output rows of
//! `G`) costs about as much as filling and mirroring the `n × n` Hessian and the output
//! rows, because the Toeplitz structure of `T` is used instead of the dense product
//! `2 TᵀC̄ᵀQ̄C̄T`; a weight that differs at every step of the horizon loses that. The
//! ignored test `condense_timing` (`cargo test --release -p control --lib condense_timing
//! -- --ignored --nocapture`) times it against the dense product.

use super::qp::{ConstraintId, QpData, QpProblem};
use crate::linalg::dot_in_order as dot;

/// One row of the `T_tᵀ Q T_t` recursion ([`Condenser::build_hessian`]) with `PT`
/// tracked outputs: `dst[(b − a)·m + β] = from[(b − a)·m + β] + (Q G_{ℓ−1−a})ᵀ_α ·
/// G_{ℓ−1−b}[β]` for `b = a..ℓ−1` (`dst` and `from` cover those blocks, `q_ga` is row `α`
/// of `(2 Q G_{ℓ−1−a})ᵀ`, `gt` holds the `G_sᵀ`, `m × PT` each, from `s = 1`), each sum
/// over `t = 0..PT` in order.
#[inline(always)]
fn recursion_row<const PT: usize>(
    dst: &mut [f64],
    from: &[f64],
    gt: &[f64],
    q_ga: &[f64],
    m: usize,
) {
    let Ok(q): Result<[f64; PT], _> = q_ga.try_into() else {
        return;
    };
    let blocks = dst.len() / m;
    for (k, (dst, from)) in dst
        .chunks_exact_mut(m)
        .zip(from.chunks_exact(m))
        .enumerate()
    {
        // Block b = a + k reads G_s with s = ℓ−1−b = blocks − k.
        let s = blocks - k;
        let g = &gt[(s - 1) * PT * m..s * PT * m];
        for ((d, f), gcol) in dst.iter_mut().zip(from).zip(g.chunks_exact(PT)) {
            let sum: f64 = q.iter().zip(gcol).map(|(x, y)| x * y).sum();
            *d = f + sum;
        }
    }
}

#[cfg(test)]
mod tests;

/// A diagonal weight of the cost (2.48): on the tracked outputs (`Q`) or on the moves of
/// the inputs (`R`).
#[derive(Clone, Debug, PartialEq)]
pub enum Weight {
    /// The same scalar on every channel and step (`q I`).
    Scalar(f64),
    /// One value per channel (`p_t` tracked outputs for `Q`, `m` inputs for `R`), the same
    /// at every step.
    PerChannel(Vec<f64>),
    /// One value per channel and step, step-major (`ℓ·p_t` for `Q`, `ℓ·m` for `R`;
    /// entry `i·channels + j` weighs channel `j` at step `i`), e.g. a terminal weight.
    PerStep(Vec<f64>),
}

/// The move bounds (2.51) `Δu_min ≤ u_{i|k} − u_{i−1|k} ≤ Δu_max` (per input; `±∞` for none).
#[derive(Clone, Debug, PartialEq)]
pub struct MoveBounds {
    /// `Δu_min` (`m`), each `≤ 0` (holding the input must be allowed).
    pub min: Vec<f64>,
    /// `Δu_max` (`m`), each `≥ 0`.
    pub max: Vec<f64>,
}

impl MoveBounds {
    /// `|Δu_i| ≤ bound` on each of `m` inputs.
    pub fn symmetric(bound: f64, m: usize) -> Self {
        Self {
            min: vec![-bound; m],
            max: vec![bound; m],
        }
    }
}

/// The output constraints (2.49) `C_c y_{i|k} + 𝓓 ≤ 0` at every step `i = 1..ℓ`.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputConstraints {
    /// `C_c` (`n_c × p`, row-major; the dissertation's `C C_c`).
    pub c: Vec<f64>,
    /// `𝓓` (`n_c`).
    pub d: Vec<f64>,
}

/// The shape and the fixed data of the receding-horizon problem (2.43)–(2.51).
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSpec {
    /// The horizon `ℓ ≥ 1`.
    pub horizon: usize,
    /// The number of inputs `m ≥ 1`.
    pub n_inputs: usize,
    /// The number of outputs `p ≥ 1`.
    pub n_outputs: usize,
    /// The number of tracked outputs `p_t ≥ 1`.
    pub n_tracked: usize,
    /// `C_t` (`p_t × p`, row-major): the tracked outputs `C_t y_{i|k}` of every step.
    pub tracking: Vec<f64>,
    /// The tracking weight `Q` (finite, `≥ 0`).
    pub q: Weight,
    /// The move weight `R` (finite, `> 0`, so that `H` is positive definite).
    pub r: Weight,
    /// `u_min` (`m`; `−∞` for none).
    pub u_min: Vec<f64>,
    /// `u_max` (`m`; `+∞` for none), `u_min ≤ u_max`.
    pub u_max: Vec<f64>,
    /// The move bounds (2.51), if any.
    pub move_bounds: Option<MoveBounds>,
    /// The output constraints (2.49), if any.
    pub output_constraints: Option<OutputConstraints>,
    /// The internal-model law's input cost (2.47')–(2.48') added to (2.48), if any; with
    /// it `R` may be `0` (module docs, "The tone-notch input cost").
    pub input_notch: Option<NotchInputCost>,
}

/// The input cost `Vᵀ R_v V + Uᵀ R_u U` of (2.48'), `V = 𝒲 U + v_free` (2.47')
/// ([`crate::internal_model`]), added to (2.48).
#[derive(Clone, Debug, PartialEq)]
pub struct NotchInputCost {
    /// `w_0 = 1, w_1, …, w_{ℓ−1}`: the impulse response of the notch `W(q)` over the
    /// horizon ([`crate::internal_model::ToneAnnihilator::notch_impulse_response`]).
    pub impulse_response: Vec<f64>,
    /// `R_v` per input (`m`, finite, `> 0`): the weight on the notched input.
    pub r_notch: Vec<f64>,
    /// `R_u` per input (`m`, finite, `≥ 0`): the weight on the input's level.
    pub r_level: Vec<f64>,
}

/// Why [`Condenser::new`] refused an [`MpcSpec`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SpecError(pub String);

impl core::fmt::Display for SpecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "invalid MPC spec: {}", self.0)
    }
}

impl std::error::Error for SpecError {}

/// Why [`Condenser::build`] refused its inputs (no allocation: static descriptions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildError {
    /// A slice has the wrong length.
    Length {
        /// Which argument.
        what: &'static str,
        /// The length expected.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// An argument holds a NaN or an infinity.
    NonFinite {
        /// Which argument.
        what: &'static str,
    },
}

impl core::fmt::Display for BuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BuildError::Length {
                what,
                expected,
                got,
            } => {
                write!(f, "{what}: expected length {expected}, got {got}")
            }
            BuildError::NonFinite { what } => write!(f, "{what}: not finite"),
        }
    }
}

impl std::error::Error for BuildError {}

/// Builds the condensed QP of (2.43)–(2.51) at every step, allocation-free.
///
/// ```
/// use control::mpc::condense::{Condenser, MpcSpec, Weight};
/// use control::mpc::qp::{DenseQpSolver, QpSettings, QpStatus, WarmStart};
/// // y_{i+1} = 0.5 y_i + u_i: H_s = 0.5^{s−1}; horizon 3, track r = 1, |u| ≤ 1.
/// let spec = MpcSpec {
///     horizon: 3, n_inputs: 1, n_outputs: 1, n_tracked: 1, tracking: vec![1.0],
///     q: Weight::Scalar(1.0), r: Weight::Scalar(0.01),
///     u_min: vec![-1.0], u_max: vec![1.0], move_bounds: None, output_constraints: None, input_notch: None,
/// };
/// let mut c = Condenser::new(&spec).unwrap();
/// let mut solver = DenseQpSolver::new(c.n(), c.n_ineq(), QpSettings::default());
/// let y1 = 0.0; // y_{1|k}, the free response starts from it
/// let problem = c.build(&[1.0, 0.5], &[y1, 0.5 * y1, 0.25 * y1], &[0.0], &[1.0; 3]).unwrap();
/// assert_eq!(solver.solve(&problem, WarmStart::Cold), QpStatus::Solved);
/// let u = c.first_move(solver.x())[0];
/// assert!(u > 0.5 && u <= 1.0);
/// ```
#[derive(Clone, Debug)]
pub struct Condenser {
    ell: usize,
    m: usize,
    p: usize,
    pt: usize,
    nc: usize,
    n: usize,
    n_move_rows: usize,
    n_ineq: usize,
    /// `C_t` (`p_t × p`).
    ct: Vec<f64>,
    /// `2 Q`, expanded per step (`ℓ·p_t`).
    q2: Vec<f64>,
    /// `2 Q` of the Toeplitz recursion (`p_t`): the one shared by most steps `1..ℓ−1`.
    q_base: Vec<f64>,
    /// The steps `i ≥ 1` whose `Q_i` differs from it (each adds a rank-`p_t` correction).
    q_fix: Vec<usize>,
    /// Too many such steps: sum the blocks of `T_tᵀ Q T_t` directly instead.
    q_direct: bool,
    /// `R`, expanded per step (`ℓ·m`).
    r: Vec<f64>,
    /// `C_c` (`n_c × p`) and `𝓓` (`n_c`).
    cc: Vec<f64>,
    dd: Vec<f64>,
    u_min: Vec<f64>,
    u_max: Vec<f64>,
    du_min: Vec<f64>,
    du_max: Vec<f64>,
    /// `G_sᵀ = (C_t H_s)ᵀ`, `s = 1..ℓ−1`, at `(s−1)·m·p_t` (`m × p_t` row-major, so that
    /// the `p_t`-long sums of the block products run over contiguous memory).
    gt: Vec<f64>,
    /// `(2 Q G_s)ᵀ` likewise, with the `Q` of the recursion (`q_base`).
    qgt: Vec<f64>,
    /// `K_s = C_c H_s`, `s = 1..ℓ−1`, by constraint rows in reverse step order: row `r` of
    /// `K_s` at `r·(ℓ−1)·m + (ℓ−1−s)·m`, so that row `(i, r)` of `C_c T̂` is the contiguous
    /// `[K_i[r]; …; K_1[r]]`.
    kc: Vec<f64>,
    /// `2 Q_i e_i` (`ℓ·p_t`).
    qe: Vec<f64>,
    cost_const: f64,
    /// The condensed problem.
    qp: QpData,
    /// The tone-notch input cost (2.47')–(2.48'), when the spec has one.
    notch: Option<CondensedNotch>,
}

/// The constant parts of the tone-notch input cost (2.47')–(2.48') in the condensed QP.
#[derive(Clone, Debug)]
struct CondensedNotch {
    /// `w_0 … w_{ℓ−1}`, the impulse response of `W(q)`.
    w: Vec<f64>,
    /// `R_v` per input (`m`).
    r_v: Vec<f64>,
    /// `2 (𝒲ᵀ R_v 𝒲 + R_u)`, `ℓm × ℓm` row-major: constant, added to every `H`.
    hess: Vec<f64>,
}

impl CondensedNotch {
    /// Checks the cost for `ℓ` steps and `m` inputs and forms its constant Hessian.
    fn new(cost: &NotchInputCost, ell: usize, m: usize) -> Result<Self, SpecError> {
        check_len(
            &cost.impulse_response,
            ell,
            "input_notch.impulse_response (ℓ)",
        )?;
        check_len(&cost.r_notch, m, "input_notch.r_notch (m)")?;
        check_len(&cost.r_level, m, "input_notch.r_level (m)")?;
        let w = &cost.impulse_response;
        if w.iter().any(|x| !x.is_finite()) || w[0] != 1.0 {
            return Err(SpecError(
                "input_notch.impulse_response: must be finite with w_0 = 1".into(),
            ));
        }
        if cost.r_notch.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(SpecError(
                "input_notch.r_notch: every weight must be finite and > 0".into(),
            ));
        }
        if cost.r_level.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(SpecError(
                "input_notch.r_level: every weight must be finite and ≥ 0".into(),
            ));
        }
        let n = ell * m;
        // Block (a, b) of 𝒲ᵀ R_v 𝒲 is Σ_{i ≥ max(a,b)} w_{i−a} w_{i−b} R_v (diagonal).
        let mut hess = vec![0.0; n * n];
        for a in 0..ell {
            for b in 0..ell {
                let s: f64 = (a.max(b)..ell).map(|i| w[i - a] * w[i - b]).sum();
                for j in 0..m {
                    hess[(a * m + j) * n + b * m + j] = 2.0 * s * cost.r_notch[j];
                }
            }
            for j in 0..m {
                hess[(a * m + j) * n + a * m + j] += 2.0 * cost.r_level[j];
            }
        }
        Ok(Self {
            w: w.clone(),
            r_v: cost.r_notch.clone(),
            hess,
        })
    }
}

/// A weight expanded per step (`ℓ·channels`, step-major) and checked (finite, `≥ 0`, or
/// `> 0` when `positive`), with whether it is the same at every step.
pub(super) fn expand_weight(
    w: &Weight,
    name: &str,
    channels: usize,
    ell: usize,
    positive: bool,
) -> Result<(Vec<f64>, bool), SpecError> {
    let (v, constant) = match w {
        Weight::Scalar(s) => (vec![*s; ell * channels], true),
        Weight::PerChannel(c) => {
            if c.len() != channels {
                return Err(SpecError(format!(
                    "{name}: PerChannel needs {channels} values, got {}",
                    c.len()
                )));
            }
            (
                c.iter().copied().cycle().take(ell * channels).collect(),
                true,
            )
        }
        Weight::PerStep(c) => {
            if c.len() != ell * channels {
                return Err(SpecError(format!(
                    "{name}: PerStep needs horizon × {channels} = {} values, got {}",
                    ell * channels,
                    c.len()
                )));
            }
            (c.clone(), false)
        }
    };
    for &x in &v {
        if !x.is_finite() || x < 0.0 || (positive && x == 0.0) {
            let need = if positive {
                "finite and > 0"
            } else {
                "finite and ≥ 0"
            };
            return Err(SpecError(format!(
                "{name}: every weight must be {need}, got {x}"
            )));
        }
    }
    Ok((v, constant))
}

fn check_len(v: &[f64], len: usize, name: &str) -> Result<(), SpecError> {
    if v.len() != len {
        return Err(SpecError(format!(
            "{name}: expected {len} values, got {}",
            v.len()
        )));
    }
    Ok(())
}

impl Condenser {
    /// Checks the spec and allocates every buffer (`O(ℓ²m² + n_ineq·ℓm)`).
    ///
    /// Refused: a zero horizon or dimension, slices of the wrong length, non-finite
    /// `C_t`, `C_c` or `𝓓`, negative (or, for `R`, zero) or non-finite weights, NaN bounds,
    /// `u_min > u_max`, `u_min = +∞` or `u_max = −∞`, and move bounds that forbid holding
    /// the input (`Δu_min > 0` or `Δu_max < 0`) or are NaN.
    pub fn new(spec: &MpcSpec) -> Result<Self, SpecError> {
        let (ell, m, p, pt) = (spec.horizon, spec.n_inputs, spec.n_outputs, spec.n_tracked);
        if ell == 0 {
            return Err(SpecError("horizon must be at least 1, got 0".into()));
        }
        if m == 0 || p == 0 || pt == 0 {
            return Err(SpecError(format!(
                "n_inputs, n_outputs and n_tracked must be at least 1, got {m}, {p}, {pt}"
            )));
        }
        check_len(
            &spec.tracking,
            pt * p,
            "tracking (C_t, n_tracked × n_outputs)",
        )?;
        if spec.tracking.iter().any(|x| !x.is_finite()) {
            return Err(SpecError("tracking (C_t): entries must be finite".into()));
        }
        let (q, q_const) = expand_weight(&spec.q, "q (tracking weight Q)", pt, ell, false)?;
        // With the tone-notch cost, whose 𝒲ᵀ R_v 𝒲 is positive definite, R may be 0.
        let (r, _) = expand_weight(
            &spec.r,
            "r (move weight R)",
            m,
            ell,
            spec.input_notch.is_none(),
        )?;
        let notch = match &spec.input_notch {
            None => None,
            Some(cost) => Some(CondensedNotch::new(cost, ell, m)?),
        };
        check_len(&spec.u_min, m, "u_min")?;
        check_len(&spec.u_max, m, "u_max")?;
        for j in 0..m {
            let (lo, hi) = (spec.u_min[j], spec.u_max[j]);
            if lo.is_nan() || hi.is_nan() || lo == f64::INFINITY || hi == f64::NEG_INFINITY {
                return Err(SpecError(format!(
                    "input {j}: bounds must be numbers, u_min < +∞ and u_max > −∞, got [{lo}, {hi}]"
                )));
            }
            if lo > hi {
                return Err(SpecError(format!("input {j}: u_min = {lo} > u_max = {hi}")));
            }
        }
        let (du_min, du_max) = match &spec.move_bounds {
            None => (Vec::new(), Vec::new()),
            Some(mb) => {
                check_len(&mb.min, m, "move_bounds.min")?;
                check_len(&mb.max, m, "move_bounds.max")?;
                for j in 0..m {
                    let (lo, hi) = (mb.min[j], mb.max[j]);
                    if lo.is_nan() || hi.is_nan() || lo > 0.0 || hi < 0.0 {
                        return Err(SpecError(format!(
                            "input {j}: move bounds must satisfy Δu_min ≤ 0 ≤ Δu_max (holding the \
                             input must be allowed), got [{lo}, {hi}]"
                        )));
                    }
                }
                (mb.min.clone(), mb.max.clone())
            }
        };
        let (cc, dd) = match &spec.output_constraints {
            None => (Vec::new(), Vec::new()),
            Some(oc) => {
                if oc.d.is_empty() {
                    return Err(SpecError(
                        "output_constraints: 𝓓 is empty (give None for no output constraints)"
                            .into(),
                    ));
                }
                let nc = oc.d.len();
                check_len(&oc.c, nc * p, "output_constraints.c (C_c, n_c × n_outputs)")?;
                if oc.c.iter().chain(&oc.d).any(|x| !x.is_finite()) {
                    return Err(SpecError(
                        "output_constraints: C_c and 𝓓 must be finite".into(),
                    ));
                }
                (oc.c.clone(), oc.d.clone())
            }
        };
        let nc = dd.len();
        let n = ell * m;
        // The Q of the recursion: the one most steps 1..ℓ−1 share (step 0's, y_{1|k}'s, does
        // not enter H).
        let q2: Vec<f64> = q.iter().map(|x| 2.0 * x).collect();
        let step_q = |i: usize| &q2[i * pt..(i + 1) * pt];
        let (q_base, q_fix, q_direct) = if q_const || ell < 2 {
            (step_q(0).to_vec(), Vec::new(), false)
        } else {
            let best = (1..ell)
                .max_by_key(|&i| (1..ell).filter(|&j| step_q(j) == step_q(i)).count())
                .unwrap_or(1);
            let fix: Vec<usize> = (1..ell).filter(|&j| step_q(j) != step_q(best)).collect();
            let direct = 3 * fix.len() > ell;
            (step_q(best).to_vec(), fix, direct)
        };
        let n_move_rows = if du_min.is_empty() { 0 } else { 2 * n };
        let n_ineq = n_move_rows + ell * nc;

        let mut s = Self {
            ell,
            m,
            p,
            pt,
            nc,
            n,
            n_move_rows,
            n_ineq,
            ct: spec.tracking.clone(),
            q2,
            q_base,
            q_fix,
            q_direct,
            r,
            cc,
            dd,
            u_min: spec.u_min.clone(),
            u_max: spec.u_max.clone(),
            du_min,
            du_max,
            gt: vec![0.0; ell.saturating_sub(1) * pt * m],
            qgt: vec![0.0; ell.saturating_sub(1) * pt * m],
            kc: vec![0.0; ell.saturating_sub(1) * nc * m],
            qe: vec![0.0; ell * pt],
            cost_const: 0.0,
            qp: QpData::zeros(n, n_ineq),
            notch,
        };
        // Input bounds (2.50).
        for i in 0..ell {
            s.qp.lb[i * m..(i + 1) * m].copy_from_slice(&s.u_min);
            s.qp.ub[i * m..(i + 1) * m].copy_from_slice(&s.u_max);
        }
        // Move-bound rows (2.51): the rows of D and −D; h without u_k.
        if n_move_rows > 0 {
            for k in 0..n {
                let j = k % m;
                let up = k * n;
                let lo = (n + k) * n;
                s.qp.g[up + k] = 1.0;
                s.qp.g[lo + k] = -1.0;
                if k >= m {
                    s.qp.g[up + k - m] = -1.0;
                    s.qp.g[lo + k - m] = 1.0;
                }
                s.qp.h[k] = s.du_max[j];
                s.qp.h[n + k] = -s.du_min[j];
            }
        }
        Ok(s)
    }

    /// The number of QP variables `n = ℓ·m`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The number of inequality rows: `2ℓm` move-bound rows (if any) then `ℓ·n_c` output rows.
    pub fn n_ineq(&self) -> usize {
        self.n_ineq
    }

    /// The horizon `ℓ`.
    pub fn horizon(&self) -> usize {
        self.ell
    }

    /// The number of tracked outputs `p_t`.
    pub fn n_tracked(&self) -> usize {
        self.pt
    }

    /// Row `i` of `C_t` (`p` entries; empty for `i ≥ p_t`).
    pub fn tracking_row(&self, i: usize) -> &[f64] {
        self.ct.get(i * self.p..(i + 1) * self.p).unwrap_or(&[])
    }

    /// Clips `u` (`m` entries) into the input bounds (2.50); a non-finite entry becomes
    /// `0` clipped.
    pub fn clip_to_input_bounds(&self, u: &mut [f64]) {
        for ((v, lo), hi) in u.iter_mut().zip(&self.u_min).zip(&self.u_max) {
            let x = if v.is_finite() { *v } else { 0.0 };
            *v = x.max(*lo).min(*hi);
        }
    }

    /// True when an entry of `u` lies on its input bound (2.50), to `1e-9` relative.
    pub fn at_input_bound(&self, u: &[f64]) -> bool {
        let near = |a: f64, b: f64| b.is_finite() && (a - b).abs() <= 1e-9 * (1.0 + b.abs());
        u.iter()
            .zip(&self.u_min)
            .zip(&self.u_max)
            .any(|((v, lo), hi)| near(*v, *lo) || near(*v, *hi))
    }

    /// The index in `G` of the first output-constraint row (`2ℓm` with move bounds, else
    /// 0); row `i·n_c + r` after it is constraint `r` at step `i` (`y_{i+1|k}`).
    pub fn output_rows_start(&self) -> usize {
        self.n_move_rows
    }

    /// The constant `c` of `J(U) = ½ Uᵀ H U + fᵀ U + c` for the last [`build`](Self::build):
    /// the cost (2.48) of a solution is the solver's objective plus this.
    pub fn cost_constant(&self) -> f64 {
        self.cost_const
    }

    /// The condensed problem of the last [`build`](Self::build) (all zero before the first).
    pub fn problem(&self) -> QpProblem<'_> {
        self.qp.problem()
    }

    /// Builds the QP for the current step; allocation-free.
    ///
    /// - `markov`: `H_1, …, H_{ℓ−1}` (each `p × m`, row-major, concatenated), `(ℓ−1)·p·m`
    ///   values; `H_1, …, H_ℓ` (`ℓ·p·m`) is accepted too, `H_ℓ` does not enter (2.46).
    /// - `free_response`: `Γ̂ x_{1|k}` (`ℓ·p`), the predicted outputs `y_{1|k}, …, y_{ℓ|k}`
    ///   with `U = 0`.
    /// - `u_k`: the current input (`m`), the reference of the first move (2.47).
    /// - `reference`: `𝓡 = [r_{k+1}; …; r_{k+ℓ}]` (`ℓ·p_t`).
    ///
    /// Every value must be finite. A spec with the tone-notch cost needs
    /// [`Condenser::build_notched`].
    pub fn build(
        &mut self,
        markov: &[f64],
        free_response: &[f64],
        u_k: &[f64],
        reference: &[f64],
    ) -> Result<QpProblem<'_>, BuildError> {
        self.build_notched(markov, free_response, u_k, reference, &[])
    }

    /// Whether the spec has the tone-notch input cost (2.47')–(2.48').
    pub fn has_input_notch(&self) -> bool {
        self.notch.is_some()
    }

    /// [`Condenser::build`] with the tone-notch input cost (2.47')–(2.48') of the spec:
    /// `v_free` (`ℓ·m`, step-major) is `W(q)`'s response over the horizon to the past
    /// inputs with `U = 0`, so that `V = 𝒲 U + v_free`; then
    ///
    /// ```text
    /// H += 2 (𝒲ᵀ R_v 𝒲 + R_u)   (constant, formed once),
    /// f += 2 𝒲ᵀ R_v v_free,      c += v_freeᵀ R_v v_free
    /// ```
    ///
    /// `v_free` must be empty without that cost. Allocation-free.
    pub fn build_notched(
        &mut self,
        markov: &[f64],
        free_response: &[f64],
        u_k: &[f64],
        reference: &[f64],
        v_free: &[f64],
    ) -> Result<QpProblem<'_>, BuildError> {
        self.build_quadratic(markov)?;
        self.build_linear(free_response, u_k, reference, v_free)
    }

    /// The first half of [`Condenser::build_notched`], what depends on the Markov
    /// parameters only: `G_s = C_t H_s`, the output rows' `K_s = C_c H_s` and the Hessian
    /// `H` (with the notch cost's constant part). [`Condenser::build_linear`] completes
    /// the QP. Allocation-free.
    ///
    /// # Errors
    ///
    /// [`BuildError`] for Markov parameters of the wrong length or not finite.
    pub fn build_quadratic(&mut self, markov: &[f64]) -> Result<(), BuildError> {
        let (ell, m, p, pt, nc) = (self.ell, self.m, self.p, self.pt, self.nc);
        let blk = p * m;
        let n_markov = ell - 1;
        if markov.len() != n_markov * blk && markov.len() != ell * blk {
            return Err(BuildError::Length {
                what: "markov",
                expected: n_markov * blk,
                got: markov.len(),
            });
        }
        if markov.iter().any(|x| !x.is_finite()) {
            return Err(BuildError::NonFinite { what: "markov" });
        }
        let markov = &markov[..n_markov * blk];

        // G_s = C_t H_s and K_s = C_c H_s.
        for ((hs, gs), qgs) in markov
            .chunks_exact(blk)
            .zip(self.gt.chunks_exact_mut(m * pt))
            .zip(self.qgt.chunks_exact_mut(m * pt))
        {
            for t in 0..pt {
                let crow = &self.ct[t * p..(t + 1) * p];
                for be in 0..m {
                    let v: f64 = (0..p).map(|k| crow[k] * hs[k * m + be]).sum();
                    gs[be * pt + t] = v;
                    qgs[be * pt + t] = self.q_base[t] * v;
                }
            }
        }
        // K_s row r at r·(ℓ−1)m + (ℓ−1−s)m: each row of C_c T̂ is then one contiguous copy.
        for (s_idx, hs) in markov.chunks_exact(blk).enumerate() {
            let pos = (ell - 2 - s_idx) * m;
            for r in 0..nc {
                let crow = &self.cc[r * p..(r + 1) * p];
                let out = &mut self.kc[r * (ell - 1) * m + pos..r * (ell - 1) * m + pos + m];
                for (be, o) in out.iter_mut().enumerate() {
                    *o = (0..p).map(|k| crow[k] * hs[k * m + be]).sum();
                }
            }
        }

        self.build_hessian();
        if let Some(notch) = &self.notch {
            for (h, c) in self.qp.hess.iter_mut().zip(&notch.hess) {
                *h += c;
            }
        }
        Ok(())
    }

    /// The second half of [`Condenser::build_notched`], after
    /// [`Condenser::build_quadratic`] with this horizon's Markov parameters: the gradient
    /// `f`, the constant, the move rows' and output rows' `h` and the output rows of `G`.
    /// Allocation-free.
    ///
    /// # Errors
    ///
    /// [`BuildError`] for data of the wrong length or not finite.
    pub fn build_linear(
        &mut self,
        free_response: &[f64],
        u_k: &[f64],
        reference: &[f64],
        v_free: &[f64],
    ) -> Result<QpProblem<'_>, BuildError> {
        let (ell, m, p, pt, nc, n) = (self.ell, self.m, self.p, self.pt, self.nc, self.n);
        let expected_v = if self.notch.is_some() { n } else { 0 };
        if v_free.len() != expected_v {
            return Err(BuildError::Length {
                what: "v_free",
                expected: expected_v,
                got: v_free.len(),
            });
        }
        if v_free.iter().any(|x| !x.is_finite()) {
            return Err(BuildError::NonFinite { what: "v_free" });
        }
        let lens = [
            ("free_response", free_response.len(), ell * p),
            ("u_k", u_k.len(), m),
            ("reference", reference.len(), ell * pt),
        ];
        for (what, got, expected) in lens {
            if got != expected {
                return Err(BuildError::Length {
                    what,
                    expected,
                    got,
                });
            }
        }
        let finite = |v: &[f64]| v.iter().fold(true, |ok, x| ok & x.is_finite());
        for (what, v) in [
            ("free_response", free_response),
            ("u_k", u_k),
            ("reference", reference),
        ] {
            if !finite(v) {
                return Err(BuildError::NonFinite { what });
            }
        }
        // Free tracking error e_i = C_t y_i − r_i; qe = 2 Q e; c = eᵀ Q e + u_kᵀ R_1 u_k.
        let mut c = 0.0;
        for i in 0..ell {
            let y = &free_response[i * p..(i + 1) * p];
            for t in 0..pt {
                let e = dot(&self.ct[t * p..(t + 1) * p], y) - reference[i * pt + t];
                let q2 = self.q2[i * pt + t];
                self.qe[i * pt + t] = q2 * e;
                c += 0.5 * q2 * e * e;
            }
        }
        for (r, u) in self.r.iter().zip(u_k) {
            c += r * u * u;
        }
        self.cost_const = c;

        // f_a = Σ_{i>a} G_{i−a}ᵀ (2 Q_i e_i) − [a = 0] 2 R_1 u_k.
        self.qp.f.fill(0.0);
        for a in 0..ell {
            let fa = &mut self.qp.f[a * m..(a + 1) * m];
            for i in a + 1..ell {
                let gs = &self.gt[(i - a - 1) * pt * m..(i - a) * pt * m];
                let w = &self.qe[i * pt..(i + 1) * pt];
                for (fj, gcol) in fa.iter_mut().zip(gs.chunks_exact(pt)) {
                    *fj += dot(gcol, w);
                }
            }
        }
        for ((fj, r), u) in self.qp.f.iter_mut().zip(&self.r).zip(u_k) {
            *fj -= 2.0 * r * u;
        }
        if let Some(notch) = &self.notch {
            // f_(a, j) += 2 Σ_{i ≥ a} w_{i−a} R_v,j v_free(i, j); c += Σ R_v v_free².
            for a in 0..ell {
                for j in 0..m {
                    let mut s = 0.0;
                    for i in a..ell {
                        s += notch.w[i - a] * v_free[i * m + j];
                    }
                    self.qp.f[a * m + j] += 2.0 * notch.r_v[j] * s;
                }
            }
            for (i, v) in v_free.iter().enumerate() {
                self.cost_const += notch.r_v[i % m] * v * v;
            }
        }

        // Move-bound rows: only the first step's h carries u_k.
        if self.n_move_rows > 0 {
            for (j, u) in u_k.iter().enumerate() {
                self.qp.h[j] = self.du_max[j] + u;
                self.qp.h[n + j] = -self.du_min[j] - u;
            }
        }

        // Output rows (i, r): G from the Toeplitz rows of K, h = −𝓓_r − C_c y_i.
        let base = self.n_move_rows;
        for i in 0..ell {
            let y = &free_response[i * p..(i + 1) * p];
            for r in 0..nc {
                let row_idx = base + i * nc + r;
                let row = &mut self.qp.g[row_idx * n..(row_idx + 1) * n];
                // Blocks j < i: K_{i−j}[r, :], i.e. [K_i[r]; …; K_1[r]] (the rest stays zero).
                let krev = &self.kc[r * (ell - 1) * m..(r + 1) * (ell - 1) * m];
                row[..i * m].copy_from_slice(&krev[(ell - 1 - i) * m..]);
                self.qp.h[row_idx] = -self.dd[r] - dot(&self.cc[r * p..(r + 1) * p], y);
            }
        }
        Ok(self.problem())
    }

    /// `H = 2 (T_tᵀ Q T_t + Dᵀ R D)` into `self.qp.hess` from `self.gt`.
    fn build_hessian(&mut self) {
        let (ell, m, pt, n) = (self.ell, self.m, self.pt, self.n);
        let (gt, qgt) = (&self.gt, &self.qgt);
        let q2 = &self.q2;
        let hess = &mut self.qp.hess;
        // G_sᵀ with s = 1..ℓ−1 lives at (s−1)·m·p_t.
        let g_of = |s: usize| &gt[(s - 1) * pt * m..s * pt * m];
        let qg_of = |s: usize| &qgt[(s - 1) * pt * m..s * pt * m];
        if !self.q_direct {
            // Block rows from the last (zero) one up: block(a, b) = block(a+1, b+1) +
            // G_{ℓ−1−a}ᵀ Q G_{ℓ−1−b}, b = a..ℓ−1, with block(a, ℓ−1) = 0. Entry (a m + α,
            // b m + β) reads entry (a m + α + m, b m + β + m): the row m rows below, m columns
            // on, so both rows are walked contiguously.
            for a in (0..ell).rev() {
                let (top, below) = hess.split_at_mut((a + 1) * m * n);
                for al in 0..m {
                    let row = &mut top[(a * m + al) * n..(a * m + al + 1) * n];
                    row[(ell - 1) * m..].fill(0.0);
                    if a + 1 == ell {
                        continue;
                    }
                    let src = &below[al * n..(al + 1) * n];
                    let qga = &qg_of(ell - 1 - a)[al * pt..(al + 1) * pt];
                    let dst = &mut row[a * m..(ell - 1) * m];
                    let from = &src[(a + 1) * m..ell * m];
                    // The tracked-output counts of the examples get a loop unrolled at
                    // compile time; the sums are the same, term by term, in the same order.
                    match pt {
                        1 => recursion_row::<1>(dst, from, gt, qga, m),
                        2 => recursion_row::<2>(dst, from, gt, qga, m),
                        3 => recursion_row::<3>(dst, from, gt, qga, m),
                        4 => recursion_row::<4>(dst, from, gt, qga, m),
                        _ => {
                            for (b, (dst, from)) in dst
                                .chunks_exact_mut(m)
                                .zip(from.chunks_exact(m))
                                .enumerate()
                            {
                                let gb = g_of(ell - 1 - a - b);
                                for ((d, f), gcol) in
                                    dst.iter_mut().zip(from).zip(gb.chunks_exact(pt))
                                {
                                    *d = f + dot(qga, gcol);
                                }
                            }
                        }
                    }
                }
            }
            // Steps whose Q_i differs from the recursion's: block(a, b) += G_{i−a}ᵀ (Q_i − Q)
            // G_{i−b} for a ≤ b < i.
            let qb = &self.q_base;
            for &i in &self.q_fix {
                let qi = &q2[i * pt..(i + 1) * pt];
                for a in 0..i {
                    let ga = g_of(i - a);
                    for al in 0..m {
                        let ca = &ga[al * pt..(al + 1) * pt];
                        let row = &mut hess[(a * m + al) * n..(a * m + al + 1) * n];
                        for b in a..i {
                            let gb = g_of(i - b);
                            for (d, cb) in
                                row[b * m..(b + 1) * m].iter_mut().zip(gb.chunks_exact(pt))
                            {
                                let mut s = 0.0;
                                for t in 0..pt {
                                    s += ca[t] * (qi[t] - qb[t]) * cb[t];
                                }
                                *d += s;
                            }
                        }
                    }
                }
            }
        } else {
            // block(a, b) = Σ_{i = b+1}^{ℓ−1} G_{i−a}ᵀ Q_i G_{i−b} (b ≥ a), summed backward.
            for a in 0..ell {
                for b in a..ell {
                    for al in 0..m {
                        for be in 0..m {
                            let mut s = 0.0;
                            for i in (b + 1..ell).rev() {
                                let (ga, gb) = (g_of(i - a), g_of(i - b));
                                let (ca, cb) =
                                    (&ga[al * pt..(al + 1) * pt], &gb[be * pt..(be + 1) * pt]);
                                let qi = &q2[i * pt..(i + 1) * pt];
                                for t in 0..pt {
                                    s += ca[t] * qi[t] * cb[t];
                                }
                            }
                            hess[(a * m + al) * n + b * m + be] = s;
                        }
                    }
                }
            }
        }
        // 2 Dᵀ R D: diagonal 2(R_i + R_{i+1}), off-diagonal −2 R_{i+1}.
        for k in 0..n {
            let next = if k + m < n { self.r[k + m] } else { 0.0 };
            hess[k * n + k] += 2.0 * (self.r[k] + next);
            if k + m < n {
                hess[k * n + k + m] -= 2.0 * next;
            }
        }
        // Mirror the upper triangle, in 8 × 8 tiles (a column walk of the whole matrix
        // would miss the cache on every read).
        const TILE: usize = 8;
        for ib in (0..n).step_by(TILE) {
            for jb in (0..=ib).step_by(TILE) {
                for i in ib..(ib + TILE).min(n) {
                    for j in jb..(jb + TILE).min(i) {
                        hess[i * n + j] = hess[j * n + i];
                    }
                }
            }
        }
    }

    /// The active set of this step's solution (from
    /// [`DenseQpSolver::active_set_into`](super::qp::DenseQpSolver::active_set_into)) moved
    /// one step forward, as the guess for the next step's
    /// [`WarmStart::ActiveSet`](super::qp::WarmStart): a bound or row of step `i ≥ 1`
    /// becomes the same bound or row of step `i − 1`, those of step 0 are dropped, ids out
    /// of range too. Writes at most `out.len()` ids and returns how many; allocation-free.
    /// [`Condenser::shift_active_set_by`] with one step.
    pub fn shift_active_set(&self, active: &[ConstraintId], out: &mut [ConstraintId]) -> usize {
        self.shift_active_set_by(active, 1, out)
    }

    /// [`Condenser::shift_active_set`] by `steps` samples at once: a bound or row of step
    /// `i ≥ steps` becomes the same bound or row of step `i − steps`, the others are
    /// dropped (none is left when `steps ≥ ℓ`; `steps = 0` keeps every id in range). This
    /// is the warm start of a QP solved `steps` samples after the one that produced
    /// `active`, when the samples between were taken in without a solve (caught up or
    /// lost): the horizon (2.44) has moved on by that many steps. `O(|active|)` whatever
    /// `steps`; allocation-free.
    pub fn shift_active_set_by(
        &self,
        active: &[ConstraintId],
        steps: usize,
        out: &mut [ConstraintId],
    ) -> usize {
        let (m, n, nc, base) = (self.m, self.n, self.nc, self.n_move_rows);
        if steps >= self.ell {
            return 0;
        }
        // steps < ℓ: neither product overflows (they are at most n and ℓ n_c).
        let (dm, dc) = (steps * m, steps * nc);
        let mut k = 0;
        for &id in active {
            if k == out.len() {
                break;
            }
            let shifted = match id {
                ConstraintId::Upper(i) if i >= dm && i < n => Some(ConstraintId::Upper(i - dm)),
                ConstraintId::Lower(i) if i >= dm && i < n => Some(ConstraintId::Lower(i - dm)),
                // Move rows: i·m + j within each sign block of n rows.
                ConstraintId::Row(j) if j < base && j % n >= dm => Some(ConstraintId::Row(j - dm)),
                // Output rows: base + i·n_c + r.
                ConstraintId::Row(j) if j >= base + dc && j < self.n_ineq => {
                    Some(ConstraintId::Row(j - dc))
                }
                _ => None,
            };
            if let Some(s) = shifted {
                out[k] = s;
                k += 1;
            }
        }
        k
    }

    /// The applied input `u_{1|k}`: the first `m` entries of a solution `U`.
    pub fn first_move<'s>(&self, solution: &'s [f64]) -> &'s [f64] {
        &solution[..self.m.min(solution.len())]
    }

    /// The safe input when the QP is not solved: [`fallback_input`] with this spec's input
    /// and move bounds. `u_k` and `out` have `m` entries (extra entries are ignored).
    pub fn fallback_input(&self, u_k: &[f64], out: &mut [f64]) {
        let mv = if self.du_min.is_empty() {
            None
        } else {
            Some((&self.du_min[..], &self.du_max[..]))
        };
        fallback_input(u_k, &self.u_min, &self.u_max, mv, out);
    }
}

/// The safe input to apply when the receding-horizon QP is infeasible or not solved.
///
/// Per input `j`: hold `u_k,j`, clipped into `[lb_j, ub_j]`; with move bounds
/// `(Δu_min, Δu_max)` the clipping move is limited to them, and the input bounds win if the
/// limited move does not reach the box. So the result is always within `[lb, ub]` (for
/// `lb ≤ ub`), and equals `u_k` when `u_k` is already inside. A non-finite `u_k,j` is
/// replaced by `0` clipped into the bounds. Allocation-free; uses the shortest of the
/// slices.
pub fn fallback_input(
    u_k: &[f64],
    lb: &[f64],
    ub: &[f64],
    move_bounds: Option<(&[f64], &[f64])>,
    out: &mut [f64],
) {
    for (j, o) in out.iter_mut().enumerate() {
        let (Some(&u), Some(&lo), Some(&hi)) = (u_k.get(j), lb.get(j), ub.get(j)) else {
            break;
        };
        let clip = |x: f64| x.max(lo).min(hi);
        if !u.is_finite() {
            *o = clip(0.0);
            continue;
        }
        let mut v = clip(u);
        if let Some((dmin, dmax)) = move_bounds
            && let (Some(&dl), Some(&dh)) = (dmin.get(j), dmax.get(j))
        {
            v = u + (v - u).max(dl).min(dh);
            v = clip(v);
        }
        *o = v;
    }
}
