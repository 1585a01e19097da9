//! The spacecraft of chapter 7 as a table: the bus, the two links and the sampler of
//! §7.3 ((7.1)–(7.26)), read the same way by the plant (`[plant.sampling-arm]`, the true
//! spacecraft) and by the controller (`[controller.arm]`, the nominal one of the feedback
//! linearization (7.31)). Every field is optional; a missing one takes §7.3's value
//! ([`ArmParams::CHAPTER_7`]).
//!
//! ```toml
//! m-sc = 420.0      # bus mass m_sc, kg
//! m1 = 1.0          # link masses m_1, m_2 and the sampler's m_s, kg
//! m2 = 1.0
//! m-s = 1.0
//! l1 = 2.0          # link lengths L_1, L_2, m
//! l2 = 2.0
//! r1 = 1.0          # centre-of-mass distances R_1, R_2, m
//! r2 = 1.0
//! i1 = 0.3333333333333333   # centroidal inertias Ī_1, Ī_2, kg m²
//! i2 = 0.3333333333333333
//! ```

pub use control::arm::dynamics::ArmParams;
use serde::Deserialize;

/// The keys of the table, as written in the file.
pub const KEYS: [&str; 10] = [
    "m-sc", "m1", "m2", "m-s", "l1", "l2", "r1", "r2", "i1", "i2",
];

/// The spacecraft's fields as written; an unknown key is refused by the TOML reader.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct SpacecraftTable {
    m_sc: Option<f64>,
    m1: Option<f64>,
    m2: Option<f64>,
    m_s: Option<f64>,
    l1: Option<f64>,
    l2: Option<f64>,
    r1: Option<f64>,
    r2: Option<f64>,
    i1: Option<f64>,
    i2: Option<f64>,
}

impl SpacecraftTable {
    /// The parameters: each given field, §7.3's value for the others. Whether they make a
    /// physical spacecraft (positive masses and lengths) is checked by the side that
    /// builds its model from them.
    pub fn params(&self) -> ArmParams {
        let d = ArmParams::CHAPTER_7;
        ArmParams {
            m_sc: self.m_sc.unwrap_or(d.m_sc),
            m1: self.m1.unwrap_or(d.m1),
            m2: self.m2.unwrap_or(d.m2),
            m_s: self.m_s.unwrap_or(d.m_s),
            l1: self.l1.unwrap_or(d.l1),
            l2: self.l2.unwrap_or(d.l2),
            r1: self.r1.unwrap_or(d.r1),
            r2: self.r2.unwrap_or(d.r2),
            i1: self.i1.unwrap_or(d.i1),
            i2: self.i2.unwrap_or(d.i2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_fields_take_the_chapter_values() {
        let t: SpacecraftTable = toml::from_str("m-sc = 300.0\ni2 = 0.5").unwrap();
        let p = t.params();
        assert_eq!((p.m_sc, p.i2), (300.0, 0.5));
        assert_eq!(
            ArmParams {
                m_sc: 420.0,
                i2: ArmParams::CHAPTER_7.i2,
                ..p
            },
            ArmParams::CHAPTER_7
        );
    }

    #[test]
    fn every_key_is_known_and_no_other() {
        for k in KEYS {
            let t: Result<SpacecraftTable, _> = toml::from_str(&format!("{k} = 1.0"));
            assert!(t.is_ok(), "{k}");
        }
        assert!(toml::from_str::<SpacecraftTable>("m-cs = 1.0").is_err());
    }
}
