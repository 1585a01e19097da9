//! Predictive cost adaptive control (PCAC), dissertation §2.3.2 and chapter 6.
//!
//! PCAC identifies an input–output model online and uses its state-space realization in a
//! receding-horizon problem. This module holds the identification and the realization
//! ([`model`]) and the controller that joins them with the QP of (2.48)–(2.51) in
//! [`crate::mpc`] ([`Pcac`]: one step, timing, fallback and commands are documented there).
//!
//! # The model and its identification (2.24)–(2.35)
//!
//! ```text
//! ŷ_k = − Σ_{i=1}^{n̂} F̂_i y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i u_{k−i}                    (2.24)
//! z_k = y_k − φ_k θ,   θ = vec[F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂] ∈ ℝ^{n̂p(p+m)}       (2.26)–(2.29)
//! φ_k = ψ_k ⊗ I_p,     ψ_k = [−y_{k−1}ᵀ … −y_{k−n̂}ᵀ u_{k−1}ᵀ … u_{k−n̂}ᵀ]   (2.28)
//! ```
//!
//! with RLS (2.30)–(2.32) and the F-test variable-rate forgetting (2.33)–(2.35) (or any
//! other [`ForgettingRule`](crate::forgetting::ForgettingRule)) fed with the
//! `p`-dimensional prior errors `z_k`. Because `φ_k = ψ_k ⊗ I_p` and `P_0 = p0 I`, the
//! covariance keeps the form `P_k = P̃_k ⊗ I_p` with one `N×N` matrix `P̃_k`,
//! `N = n̂(p+m)`, and the identification is a scalar-row RLS with `p` right-hand sides
//! (derivation in [`model`]); [`model::IdKernel::Shared`] uses this, [`model::IdKernel::Full`]
//! runs the crate's [`Rls`](crate::rls::Rls) on the full Kronecker rows as a reference.
//!
//! # The block observable canonical realization (2.36)–(2.42)
//!
//! ```text
//! x_{1|k} = Â_k x̂_k + B̂_k u_k,   y_k = Ĉ x̂_k                                  (2.36)–(2.37)
//! x̂_{1,k} = y_k                                                                 (2.38)
//! x̂_{i,k} = Σ_{j=1}^{n̂−i+1} (−F̂_{i+j−1,k+1} y_{k−j} + Ĝ_{i+j−1,k+1} u_{k−j}),  i ≥ 2  (2.39)
//! Â_k: −F̂_{i,k+1} in block column 1, I_p on the block superdiagonal               (2.40)
//! B̂_k = [Ĝ_{1,k+1}; …; Ĝ_{n̂,k+1}],   Ĉ = [I_p 0 … 0]                        (2.41)–(2.42)
//! ```
//!
//! and the Markov parameters `Ĥ_{k,i} = Ĉ Â_k^{i−1} B̂_k` and free response
//! `Ĉ Â_k^{i−1} x_{1|k}` that build `T̂_{k,ℓ}` (2.46) and `Γ̂_{k,ℓ} x_{1|k}` (2.45) of the
//! `ℓ`-step prediction (2.43), all from the companion structure without forming powers of
//! `Â_k` ([`model::HorizonPrediction`] computes them together for the condensing in
//! [`crate::mpc`]). The call order per sample is documented on [`model::IoModel`].

mod controller;
pub mod model;

pub use controller::{Pcac, PcacCounters, PcacParams, PcacTiming};
pub use model::{DimError, HorizonPrediction, IdKernel, IoModel, IoModelParams};

#[cfg(test)]
mod tests;
