//! Model reference adaptive control of chapter 4: APPC (§4.2) and RC-MRAC (§4.3), as
//! pure SISO controllers.
//!
//! The plant (4.1)–(4.3) and the reference model (4.4)–(4.6):
//!
//! ```text
//! y_k     = N(q⁻¹) / D(q⁻¹) u_k,    N = Σ_{i=n_r}^{n} N_i q⁻ⁱ,  D = 1 + Σ_{i=1}^{n} D_i q⁻ⁱ   (4.1)–(4.3)
//! y_{m,k} = N_m(q⁻¹) / D_m(q⁻¹) r_k                                                  (4.4)
//! e_k     = y_k − y_{m,k}
//! ```
//!
//! - [`Appc`] ([`AppcParams`]): the controller (4.10) `u = N_c y + D_c u + H r`, the
//!   overparameterized regression (4.37)–(4.41) on `[θ_1; θ_2]` (controller and Bezout
//!   coefficients, `4n` entries), RLS on (4.42), the input (4.43). Only the plant order
//!   is needed.
//! - [`RcMrac`] ([`RcMracParams`]): the controller (4.47) `u = N_c y + D_c u + R_c F r`,
//!   the factorization (4.46) of the known part of `N` (`N_{n_r}`, `n_r`, `N_u`), the
//!   filtered regression (4.68)–(4.75) (`2n + n_s + 1` entries), RLS on (4.76), the input
//!   (4.77).
//! - [`MracBuilder`]: either method's parameters with the estimation settings at the
//!   chapter's defaults, checked when built.
//! - [`ReferenceModel`]: (4.4) as a difference equation.
//! - [`poly`]: polynomials in `q⁻¹` (products, Schur–Cohn stability, roots, division),
//!   for the parameter checks and tests.
//!
//! Proposition 4.4.1 (tested in `tests/mrac.rs`): with `H = N_s F` and `N_m = N`, the
//! identities (4.65) of RC-MRAC and (4.32) of APPC hold with the same `N_c*`, `D_c*`.
//!
//! # Conventions
//!
//! A polynomial is the slice of its coefficients of `q⁰, q⁻¹, q⁻², …` ([`poly`]); "monic"
//! and "stable" refer to it as a function of `q` (coefficient of `q⁰` equal to 1; roots of
//! `zᵈ + p_1 zᵈ⁻¹ + … + p_d` inside the unit circle). All signals are zero before the first
//! sample. `R_θ` is diagonal (the `r-theta` entries).
//!
//! # Timing
//!
//! Both controllers step compute-first: at sample `k` they take `y_k` and `r_k`, update
//! the estimate with the regression of index `k`, and return `u_k` ((4.43), (4.77) with
//! the index shifted by one). The plant's relative degree `n_r ≥ 1` means `y_k` depends on
//! `u_{k−1}` and older, as in the service's loop. `z_k` is not read (the performance is
//! `e_k`, formed inside), so a rig may configure `z = y` or none.
//!
//! # RLS with `R_θ`
//!
//! Both minimize `Σ λ^{k−i} ẑ_i² + λ^k (θ̂ − θ̂_0)ᵀ R_θ (θ̂ − θ̂_0)` ((4.42), (4.76)) with
//! the crate's [`Rls`](crate::rls::Rls) kernel, which starts from `P_0 = p0 I`. A diagonal
//! `R_θ = diag(r_1, …, r_N)` is taken by the change of variables `θ̂ = S θ̂'`,
//! `S = diag(r_i^{−1/2})`: the regularization becomes `|θ̂' − θ̂'_0|²` and the regressor
//! `φ S`, so RLS with `P'_0 = I` minimizes the same cost exactly. The forgetting factor
//! comes from any [`ForgettingRule`](crate::forgetting::ForgettingRule) (constant `λ` in
//! the dissertation). The kernel's guard (non-finite values, `tr(R_θ^{1/2} P R_θ^{1/2})`
//! above `trace-limit`) resets `θ̂, P` to `θ̂_0, P_0`; the checkpoint blocks
//! ([`crate::Controller::learned`]) are the kernel's, in the scaled coordinates.
//!
//! # Bad and missing samples
//!
//! - A non-finite `y_k` or `r_k` (or a command so large that `y_{m,k}` or `e_k` is not
//!   finite) makes the sample bad: the input `u_{k−1}` is held, the status is
//!   [`crate::status::CONTROLLER_FAULT`], the last finite `y`, `r` (and `e`) are pushed
//!   into the histories in its place (so they stay aligned with the plant's samples), and
//!   the estimator's update is suspended until the substituted values have left every
//!   window the regression reads.
//! - A regression that is not finite (huge measurements) skips the update with
//!   `CONTROLLER_FAULT`; a guard reset of the estimator also reports `CONTROLLER_FAULT`.
//!   A non-finite input is replaced by 0 (clipped into the limits) with `CONTROLLER_FAULT`.
//! - [`StepInput::u_applied`](crate::StepInput::u_applied), when finite, replaces the
//!   stored `u_{k−1}` before anything reads it.
//! - `m` lost samples ([`StepInput::lost`](crate::StepInput::lost)) are bridged by as many
//!   history entries (at most the history length) with the held `y`, `r` and `u` (the
//!   plant held its input), and the update is suspended while they are in the windows.
//! - [`crate::Controller::observe`] is the trait's default (the sample is stepped and the
//!   output discarded); neither controller has an ahead form (`u_k` needs `r_k`).
//!
//! # Real time
//!
//! Every buffer is sized in the constructors; [`crate::Controller::step`] does not
//! allocate (checked by `tests/conformance.rs` under a counting allocator), and does not
//! panic (slices are read with `get`, histories return 0 beyond their length).

mod adaptive;
pub mod appc;
pub mod builder;
mod checks;
mod estimator;
mod history;
pub mod poly;
pub mod rc_mrac;
pub mod reference;
mod signals;

pub use appc::{Appc, AppcParams};
pub use builder::{MracBuilder, MracParams};
pub use rc_mrac::{RcMrac, RcMracParams};
pub use reference::ReferenceModel;

use crate::controller::MAX_INTERNALS;

/// The names of the internals: `{prefix}_y_m`, `{prefix}_e`, `{prefix}_zhat`,
/// `theta_norm`, `trace_p`, `lambda`, `resets`, then `theta[i]` for as many coefficients
/// as fit in [`MAX_INTERNALS`].
fn internal_names(prefix: &str, theta_len: usize) -> Vec<String> {
    let mut v: Vec<String> = ["y_m", "e", "zhat"]
        .iter()
        .map(|s| format!("{prefix}_{s}"))
        .collect();
    v.extend(
        ["theta_norm", "trace_p", "lambda", "resets"]
            .iter()
            .map(|s| s.to_string()),
    );
    let room = MAX_INTERNALS - v.len();
    v.extend((0..theta_len.min(room)).map(|i| format!("theta[{i}]")));
    v
}

/// Writes `head` then the first entries of `theta` into `out` (at most
/// [`MAX_INTERNALS`] and `out.len()`); returns how many.
fn write_internals(head: &[f64], theta: &[f64], out: &mut [f64]) -> usize {
    let mut n = 0;
    for (d, v) in out
        .iter_mut()
        .take(MAX_INTERNALS)
        .zip(head.iter().chain(theta))
    {
        *d = *v;
        n += 1;
    }
    n
}
