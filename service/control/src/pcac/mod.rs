//! Predictive cost adaptive control (PCAC), dissertation §2.3.2 and chapter 6.
//!
//! PCAC identifies an input–output model online and uses its state-space realization in a
//! receding-horizon problem. This module holds the identification ([`model`]) and the
//! controller that joins it and the realization ([`crate::bocf`]) with the QP of
//! (2.48)–(2.51) in [`crate::mpc`] ([`Pcac`]: one step, timing, fallback and commands are
//! documented there).
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
//! # The realization and the prediction (2.36)–(2.46)
//!
//! The block observable canonical realization `(Â_k, B̂_k, Ĉ)` of `θ_{k+1}` (2.36)–(2.42),
//! the state estimate `x̂_k` (2.38)–(2.39), the Markov parameters `Ĥ_{k,i} = Ĉ Â_k^{i−1} B̂_k`
//! that build `T̂_{k,ℓ}` (2.46) and the free response `Γ̂_{k,ℓ} x_{1|k}` (2.45) of the
//! `ℓ`-step prediction (2.43) are their own concept, [`crate::bocf`]
//! ([`IoModel::realization`], [`HorizonPrediction`], re-exported here). The call order
//! per sample is documented on [`model::IoModel`].
//!
//! # Augmenting a fixed output feedback (7.53)–(7.57)
//!
//! With [`PcacParams::augmentation`] `= Some(K̄)` the plant's input is `K̄ y_k + u_k`:
//! identification regresses on that input (the open-loop plant (7.42)), and the MPC plans
//! `u_k` with the closed-loop realization `Â + B̂ K̄ Ĉ`, `B̂`, `Ĉ` (7.56)–(7.57), realized
//! as the input–output model with `F̂_i − Ĝ_i K̄` ([`augmentation`], where the equivalence
//! is derived). Chapter 7 augments the robust force controller of the sampling arm this
//! way ([`crate::arm`]).
//!
//! # The internal model of known tones (2.47')–(2.48'), beyond the dissertation
//!
//! With [`PcacParams::internal_model`] the identification runs on data filtered by the
//! tones' annihilator `D(q)`, the prediction uses the product model `D·F̂`, `D·Ĝ`, and the
//! cost penalizes the tone-notched input and the input's level instead of (or besides)
//! the moves ([`tone_model`], [`crate::internal_model`]).

pub mod augmentation;
pub mod builder;
mod controller;
pub mod model;
pub mod replan;
pub mod tone_model;

pub use augmentation::{AugmentedModel, OutputFeedback};
pub use builder::PcacBuilder;
pub use controller::{Pcac, PcacCounters, PcacParams, PcacTiming};
pub use model::{DimError, HorizonPrediction, IdKernel, IoModel, IoModelParams};
pub use tone_model::{InternalModel, ToneProductModel};

#[cfg(test)]
mod tests;
