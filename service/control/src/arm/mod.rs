//! The spacecraft sampling arm of chapter 7: the model the controller linearizes, the
//! feedback linearization (7.30)–(7.38), the robust gain of (7.39)–(7.41) and the
//! adaptive force controller of Algorithm 3 (robust gain plus PCAC augmentation
//! (7.42)–(7.61)).
//!
//! - [`dynamics`]: `M(q)`, `D(q, q̇)`, the generalized forces (7.1)–(7.26), shared with the
//!   simulated plant in plant-proxy.
//! - [`feedback_linearization`]: the torques (7.31) and the linearized error dynamics
//!   (7.33)–(7.38) with their zero-order-hold model (the PCAC prior `w_0`).
//! - [`robust`]: the robust state feedback `τ_f = K χ`: the polytopic model (7.39) at the
//!   vertices of the surface box, its zero-order-hold discretization and the independent
//!   check of a gain (spectral radii at the vertices and over a grid).
//! - [`controller`]: Algorithm 3 as a [`Controller`](crate::Controller).

pub mod controller;
pub mod dynamics;
pub mod feedback_linearization;
pub mod robust;
