//! How a coefficient of restitution `c_r` becomes the damping of a Hunt–Crossley surface:
//! the hysteresis factor `χ(c_r)` of
//!
//! ```text
//! F_c = k_s (−y)^n (1 + χ(c_r) ẏ/ẏ_0),        i.e. damping λ = χ k_s / |ẏ_0| on (−y)^n ẏ,
//! ```
//!
//! (7.28) prints Hunt and Crossley's original mapping `χ = 3(1 − c_r)/2`, derived for
//! small losses; the contact models the chapter cites [85–87] also use two later ones,
//! derived from the energy lost in a collision of given restitution:
//!
//! | mapping | `χ(c_r)` | `c_r = 1` | `c_r = 0.5` | `c_r → 0` |
//! | --- | --- | --- | --- | --- |
//! | Hunt–Crossley (7.28) | `3(1 − c_r)/2` | 0 | 0.75 | 1.5 |
//! | Lankarani–Nikravesh | `3(1 − c_r²)/4` | 0 | 0.5625 | 0.75 |
//! | Flores et al. | `8(1 − c_r)/(5 c_r)` | 0 | 1.6 | `∞` |
//!
//! All are elastic at `c_r = 1`; they part at low restitution, where Flores et al.'s
//! damping grows without bound (at the grid's `c_r = 0.1` it is 9.6 times (7.28)'s).

/// A mapping of the coefficient of restitution to the Hunt–Crossley hysteresis factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Restitution {
    /// Hunt and Crossley's `χ = 3(1 − c_r)/2`, as (7.28) prints it.
    HuntCrossley,
    /// Lankarani and Nikravesh's `χ = 3(1 − c_r²)/4`.
    LankaraniNikravesh,
    /// Flores et al.'s `χ = 8(1 − c_r)/(5 c_r)`.
    Flores,
}

impl Restitution {
    /// The mapping's name, as the sensitivity table shows it.
    pub fn name(self) -> &'static str {
        match self {
            Restitution::HuntCrossley => "Hunt–Crossley 3(1 − c_r)/2",
            Restitution::LankaraniNikravesh => "Lankarani–Nikravesh 3(1 − c_r²)/4",
            Restitution::Flores => "Flores et al. 8(1 − c_r)/(5 c_r)",
        }
    }

    /// `χ(c_r)` for `c_r` in `(0, 1]` (module documentation).
    pub fn hysteresis(self, c_r: f64) -> f64 {
        match self {
            Restitution::HuntCrossley => 1.5 * (1.0 - c_r),
            Restitution::LankaraniNikravesh => 0.75 * (1.0 - c_r * c_r),
            Restitution::Flores => 1.6 * (1.0 - c_r) / c_r,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_mapping_gives_its_published_damping_at_known_restitutions() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        for m in [
            Restitution::HuntCrossley,
            Restitution::LankaraniNikravesh,
            Restitution::Flores,
        ] {
            assert_eq!(m.hysteresis(1.0), 0.0, "{}", m.name());
        }
        assert!(close(Restitution::HuntCrossley.hysteresis(0.5), 0.75));
        assert!(close(Restitution::HuntCrossley.hysteresis(0.0), 1.5));
        assert!(close(
            Restitution::LankaraniNikravesh.hysteresis(0.5),
            0.5625
        ));
        assert!(close(Restitution::LankaraniNikravesh.hysteresis(0.0), 0.75));
        assert!(close(Restitution::Flores.hysteresis(0.5), 1.6));
        assert!(close(Restitution::Flores.hysteresis(0.1), 14.4));
        // Near c_r = 1 the slopes of −χ are 3/2 (Hunt–Crossley, Lankarani–Nikravesh)
        // and 8/5 (Flores et al.).
        let e = 1e-6;
        assert!((Restitution::LankaraniNikravesh.hysteresis(1.0 - e) / e - 1.5).abs() < 1e-5);
        assert!((Restitution::Flores.hysteresis(1.0 - e) / e - 1.6).abs() < 1e-5);
    }
}
