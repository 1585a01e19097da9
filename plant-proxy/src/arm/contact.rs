//! # The surface: contact force (7.27)–(7.28) and regularized Coulomb friction (7.29)
//!
//! The sampler at height `y` above the surface (`y < 0`: pressed into it), moving at
//! `(ẋ, ẏ)`, feels the normal force `F_c` (positive: pushing it up) of one of the chapter's
//! two models,
//!
//! ```text
//! Kelvin–Voigt (7.27):   F_c = −k_s y − c_s ẏ
//! Hunt–Crossley (7.28):  F_c = k_s (−y)^{3/2} (1 + 3(1 − c_r)/2 · ẏ/ẏ_0)
//! ```
//!
//! and, for the sensitivity of chapter 7's study to how (7.28) is read, the Hunt–Crossley
//! family it belongs to ([`ContactModel::Hysteretic`], not in the scenario's tables),
//!
//! ```text
//! F_c = k_s (−y)^n (1 + χ ẏ/ẏ_0),
//! ```
//!
//! of which (7.28) is `n = 3/2`, `χ = 3(1 − c_r)/2`; other mappings of `c_r` to the
//! hysteresis factor `χ` (Lankarani–Nikravesh, Flores et al.) and other exponents are
//! members, and `χ < 0` is (7.28) read with the contact speed `|ẏ_0|` in place of the
//! velocity,
//!
//! with the stiffness `k_s` (N/m, resp. N/m^{3/2}), the damping `c_s` (N s/m), the
//! coefficient of restitution `c_r ∈ [0, 1]` and the contact velocity `ẏ_0 < 0` recorded
//! at the onset of the maneuver's contact (the "initial contact velocity";
//! [`crate::arm::sim`] keeps it for the maneuver's later re-contacts, if the sampler
//! bounces). Both are the law *while in contact*; the surface never pulls:
//!
//! ```text
//! F_c = max(0, F_raw(y, ẏ))  for y < 0,      F_c = 0  for y ≥ 0,
//! ```
//!
//! so the sampler separates from the surface when the force would become adhesive (for
//! Kelvin–Voigt that happens while `y < 0` when the sampler moves up faster than the
//! surface material recovers, `ẏ > −k_s y / c_s`). The contact is thus active exactly when
//! the switching function
//!
//! ```text
//! s(y, ẏ) = min(−y, F_raw(y, ẏ))
//! ```
//!
//! is positive ([`Surface::switching`]); the integrator locates its zeros as events
//! ([`crate::arm::dopri5`]). `F_raw` is evaluated for any `y` as the smooth extension of
//! the law (Hunt–Crossley's `(−y)^{3/2}` read as 0 for `y ≥ 0`).
//!
//! The friction on `x` (7.29) is Coulomb's `−μ F_c sgn(ẋ)` regularized linearly below
//! `ẋ_reg = 10⁻⁴` m/s:
//!
//! ```text
//! F_f = −μ F_c · clamp(ẋ / ẋ_reg, −1, 1),
//! ```
//!
//! `μ = 0.5` in the chapter. Its slope `μ F_c / ẋ_reg` (1.25·10⁵ N s/m at 25 N) is what
//! makes the contact phase stiff.

use std::fmt;

/// The friction coefficient of §7.3.
pub const CHAPTER_FRICTION: f64 = 0.5;

/// The velocity below which (7.29) is linear, m/s.
pub const CHAPTER_FRICTION_REGULARIZATION: f64 = 1e-4;

/// The smallest magnitude of the recorded contact velocity `ẏ_0` of (7.28), m/s: a
/// contact reached more slowly uses this value (the law divides by `ẏ_0`).
pub const MIN_ONSET_SPEED: f64 = 1e-4;

/// The normal-force law of the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactModel {
    /// Kelvin–Voigt (7.27): `F_c = −k_s y − c_s ẏ`.
    KelvinVoigt {
        /// `k_s`, N/m (> 0).
        stiffness: f64,
        /// `c_s`, N s/m (≥ 0).
        damping: f64,
    },
    /// Hunt–Crossley (7.28): `F_c = k_s (−y)^{3/2} (1 + 3(1 − c_r)/2 · ẏ/ẏ_0)`.
    HuntCrossley {
        /// `k_s`, N/m^{3/2} (> 0).
        stiffness: f64,
        /// `c_r` in `[0, 1]`.
        restitution: f64,
    },
    /// The Hunt–Crossley family: `F_c = k_s (−y)^n (1 + χ ẏ/ẏ_0)` ((7.28) is `n = 3/2`,
    /// `χ = 3(1 − c_r)/2`). Built by programs (the sensitivity of chapter 7's study), not
    /// read from a scenario.
    Hysteretic {
        /// `k_s`, N/m^n (> 0).
        stiffness: f64,
        /// The exponent `n` (> 0).
        exponent: f64,
        /// The hysteresis factor `χ` (finite; negative adds energy while pressing in).
        hysteresis: f64,
    },
}

/// Why a surface was refused: the field (as in the scenario's `[plant.surface]`) and
/// what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceError {
    /// The field: `stiffness`, `damping`, `restitution`, `friction` or
    /// `friction-regularization`.
    pub field: &'static str,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for SurfaceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.problem)
    }
}

impl std::error::Error for SurfaceError {}

fn check(field: &'static str, v: f64, ok: bool, what: &str) -> Result<f64, SurfaceError> {
    if v.is_finite() && ok {
        Ok(v)
    } else {
        Err(SurfaceError {
            field,
            problem: format!("{v} is not {what}"),
        })
    }
}

impl ContactModel {
    /// Kelvin–Voigt with `k_s > 0` and `c_s ≥ 0` (finite).
    pub fn kelvin_voigt(stiffness: f64, damping: f64) -> Result<Self, SurfaceError> {
        Ok(ContactModel::KelvinVoigt {
            stiffness: check("stiffness", stiffness, stiffness > 0.0, "positive")?,
            damping: check("damping", damping, damping >= 0.0, "non-negative")?,
        })
    }

    /// Hunt–Crossley with `k_s > 0` and `c_r ∈ [0, 1]`.
    pub fn hunt_crossley(stiffness: f64, restitution: f64) -> Result<Self, SurfaceError> {
        Ok(ContactModel::HuntCrossley {
            stiffness: check("stiffness", stiffness, stiffness > 0.0, "positive")?,
            restitution: check(
                "restitution",
                restitution,
                (0.0..=1.0).contains(&restitution),
                "a coefficient of restitution in [0, 1]",
            )?,
        })
    }

    /// The Hunt–Crossley family with `k_s > 0`, `n > 0` and a finite `χ`.
    pub fn hysteretic(
        stiffness: f64,
        exponent: f64,
        hysteresis: f64,
    ) -> Result<Self, SurfaceError> {
        Ok(ContactModel::Hysteretic {
            stiffness: check("stiffness", stiffness, stiffness > 0.0, "positive")?,
            exponent: check("exponent", exponent, exponent > 0.0, "positive")?,
            hysteresis: check("hysteresis", hysteresis, true, "finite")?,
        })
    }

    /// The name used in the scenario: `"kelvin-voigt"` or `"hunt-crossley"`
    /// (`"hysteretic"` for the family, which no scenario names).
    pub fn name(&self) -> &'static str {
        match self {
            ContactModel::KelvinVoigt { .. } => "kelvin-voigt",
            ContactModel::HuntCrossley { .. } => "hunt-crossley",
            ContactModel::Hysteretic { .. } => "hysteretic",
        }
    }

    /// `k_s`.
    pub fn stiffness(&self) -> f64 {
        match *self {
            ContactModel::KelvinVoigt { stiffness, .. }
            | ContactModel::HuntCrossley { stiffness, .. }
            | ContactModel::Hysteretic { stiffness, .. } => stiffness,
        }
    }

    /// Checks the values (for parameters built without the constructors).
    pub fn validate(&self) -> Result<(), SurfaceError> {
        match *self {
            ContactModel::KelvinVoigt { stiffness, damping } => {
                Self::kelvin_voigt(stiffness, damping).map(|_| ())
            }
            ContactModel::HuntCrossley {
                stiffness,
                restitution,
            } => Self::hunt_crossley(stiffness, restitution).map(|_| ()),
            ContactModel::Hysteretic {
                stiffness,
                exponent,
                hysteresis,
            } => Self::hysteretic(stiffness, exponent, hysteresis).map(|_| ()),
        }
    }
}

/// A surface: its normal-force law and its friction (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    /// The normal-force law.
    pub model: ContactModel,
    /// `μ` (≥ 0).
    pub friction: f64,
    /// `ẋ_reg`, m/s (> 0): the velocity below which the friction is linear in `ẋ`.
    pub friction_regularization: f64,
}

impl Surface {
    /// The surface `model` with the chapter's friction (`μ = 0.5`, `ẋ_reg = 10⁻⁴` m/s).
    pub fn chapter(model: ContactModel) -> Self {
        Self {
            model,
            friction: CHAPTER_FRICTION,
            friction_regularization: CHAPTER_FRICTION_REGULARIZATION,
        }
    }

    /// Checks every value.
    pub fn validate(&self) -> Result<(), SurfaceError> {
        self.model.validate()?;
        check(
            "friction",
            self.friction,
            self.friction >= 0.0,
            "non-negative",
        )?;
        check(
            "friction-regularization",
            self.friction_regularization,
            self.friction_regularization > 0.0,
            "positive",
        )?;
        Ok(())
    }

    /// `F_raw(y, ẏ)`: the law (7.27) or (7.28) without the clamp (its smooth extension
    /// for `y ≥ 0`), with the recorded contact velocity `yd0` (< 0) for (7.28).
    #[inline]
    pub fn raw_force(&self, y: f64, yd: f64, yd0: f64) -> f64 {
        match self.model {
            ContactModel::KelvinVoigt { stiffness, damping } => -stiffness * y - damping * yd,
            ContactModel::HuntCrossley {
                stiffness,
                restitution,
            } => {
                let pen = (-y).max(0.0);
                let v0 = yd0.min(-MIN_ONSET_SPEED);
                stiffness * pen * pen.sqrt() * (1.0 + 1.5 * (1.0 - restitution) * yd / v0)
            }
            ContactModel::Hysteretic {
                stiffness,
                exponent,
                hysteresis,
            } => {
                let pen = (-y).max(0.0);
                let v0 = yd0.min(-MIN_ONSET_SPEED);
                stiffness * pen.powf(exponent) * (1.0 + hysteresis * yd / v0)
            }
        }
    }

    /// `F_c` (7.27)/(7.28): `max(0, F_raw)` below the surface, 0 above it.
    #[inline]
    pub fn contact_force(&self, y: f64, yd: f64, yd0: f64) -> f64 {
        if y < 0.0 {
            self.raw_force(y, yd, yd0).max(0.0)
        } else {
            0.0
        }
    }

    /// `s = min(−y, F_raw)`: the contact is active exactly when `s > 0`.
    #[inline]
    pub fn switching(&self, y: f64, yd: f64, yd0: f64) -> f64 {
        (-y).min(self.raw_force(y, yd, yd0))
    }

    /// `F_f` (7.29) under the normal force `f_c` at the sliding velocity `xd`.
    #[inline]
    pub fn friction_force(&self, f_c: f64, xd: f64) -> f64 {
        -self.friction * f_c * (xd / self.friction_regularization).clamp(-1.0, 1.0)
    }
}
