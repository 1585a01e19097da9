//! # mpc: the receding-horizon optimization of PCAC (section 2.3.2.2)
//!
//! PCAC predicts the outputs over a horizon of `ℓ` steps as
//! `Y = Γ x + T U` (2.43)–(2.46), with `T` block Toeplitz in the Markov parameters
//! `H_i = C A^{i−1} B`, and at every step minimizes the tracking and move-size cost (2.48)
//! subject to output constraints (2.49), input bounds (2.50) and move bounds (2.51).
//! Condensed in the future inputs `U ∈ R^{ℓm}` this is a dense, strictly convex quadratic
//! program with box bounds and general inequality rows.
//!
//! - [`qp`]: the allocation-free dense QP solver for that problem (a dual active-set method
//!   of Goldfarb–Idnani type, warm-startable) and the clarabel reference it is checked
//!   against.
//! - [`condense`]: builds that QP's `H, f`, bounds and rows from the Markov parameters, the
//!   free response, `u_k` and the command, allocation-free and exploiting the Toeplitz
//!   structure of `T`; the first move and the safe fallback input; optionally the
//!   internal model's tone-notch and level input cost (2.47')–(2.48').
//! - [`riccati`]: the unconstrained minimizer of (2.48) by a backward Riccati recursion on
//!   the realization, `O(ℓ N n̂p (p + m))` (`N = n̂p + m`) instead of condensing and
//!   factorizing the dense `H`.
//! - [`constraint_check`]: whether a plan satisfies (2.49)–(2.51) as the QP solver judges it.
//! - [`fast_path`]: the two together: when the unconstrained minimizer meets every
//!   constraint it is the QP's solution (the problem is strictly convex), and the step
//!   needs neither condensing nor the solver; when the recursion pays for a problem.

pub mod condense;
pub mod constraint_check;
pub mod fast_path;
pub mod qp;
pub mod riccati;
