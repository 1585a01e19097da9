//! Answering ahead: the input for a sample prepared before the sample arrives, and a plan
//! for the samples after it.
//!
//! # Causality
//!
//! A controller of the dissertation mostly does not need the newest measurement to give
//! the input that answers it:
//!
//! ```text
//! RCAC   u_k = Φ_k θ_k,  Φ_k from u_{k−1}, …, y_{k−1}, …             (2.15)–(2.17)
//! LTI    u_k = C x_k,    x_{k+1} = A x_k + B e_k                      (D = 0)
//! PCAC   u_{k+1} = u_{1|k}, the first move of the MPC solution at k   (§2.3.2.2)
//! ```
//!
//! so `u_{k+1}` is known as soon as sample `k` has been taken in. A controller that can
//! work this way returns its [`Ahead`] form from
//! [`Controller::ahead`](crate::Controller::ahead); one whose `u_k` needs `y_k` (an LTI
//! controller with `D ≠ 0`, PCAC's same-step timing, the feedback linearization of
//! chapter 7) returns `None` and is run compute-first through
//! [`Controller::step`](crate::Controller::step).
//!
//! # The ahead cycle
//!
//! ```text
//!  ready()                    → u_k    (prepared from the data up to k − 1; publish it)
//!  advance(k, applied, adapt) → takes y_k, z_k in with the input applied for sample k,
//!                               adapts when asked (θ_k → θ_{k+1}), prepares u_{k+1}
//!  ready()                    → u_{k+1}
//!  plan()                     → û_{k+2}, …, û_{k+1+H}
//! ```
//!
//! `applied` is the input the plant applies for sample `k` as far as the loop knows: what
//! it published for `k` (the ready input, or the safe input in the safe state), or, when it
//! published nothing for `k`, the plan entry or held input the plant falls back to. When
//! the plant reports another ([`StepInput::u_applied`] of sample `k + 1`), the controller
//! replaces it in its history, as in the compute-first step. `adapt = false` takes a sample
//! in without adaptation (a sample the loop took in too late to answer, or one of the safe
//! state or the open-loop phase, as [`Controller::observe`](crate::Controller::observe)
//! does in compute-first) and still prepares the next input. After a reset or a new data
//! stream [`Ahead::ready`] gives the start-up input.
//!
//! # Plans
//!
//! [`Ahead::plan`] writes the inputs the controller expects to give for the `H` samples
//! after the ready one. A plant applies them only when an answer is late
//! (`proxy.late-policy = "plan"`), so a plan is a prediction, never a promise: each kind
//! says in [`Ahead::plan_source`] how far it is exact and what it does beyond.
//!
//! Everything here follows [`Controller::step`](crate::Controller::step)'s real-time rules:
//! no allocation, lock, I/O or panic, bounded loops.

use crate::controller::StepInput;

/// The most rows a plan holds: [`Ahead::plan`] writes at most this many (the contract's
/// `ipc_types::MAX_PLAN`, which the service checks against it).
pub const MAX_PLAN_ROWS: usize = 64;

/// The ahead form of a controller (see the module docs).
pub trait Ahead {
    /// Writes the input ready for the next sample (`u` has length `n_u`, finite) and
    /// returns its [`status`](crate::status) bits.
    fn ready(&self, u: &mut [f64]) -> u32;

    /// Takes sample `k` in with `applied` (length `n_u`), the input the plant applies for
    /// it, adapts when `adapt`, and prepares the input for sample `k + 1`; returns the
    /// [`status`](crate::status) bits of that input (what [`Ahead::ready`] then returns).
    fn advance(&mut self, input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u32;

    /// Writes up to `out.len() / n_u` plan entries (at most [`MAX_PLAN_ROWS`]), row `j` (`out[j n_u .. (j+1) n_u]`)
    /// being the input expected for the `(j + 2)`-th sample after the last one taken in
    /// (the first is the ready input itself); returns how many it wrote.
    fn plan(&mut self, out: &mut [f64]) -> usize;

    /// What the plan holds, one line for the run report.
    fn plan_source(&self) -> &'static str;
}
