//! The robust-gain file: the `[robust-gain]` table that `rig-design robust-gain` writes
//! (the LMI design of (7.39)–(7.41)) and the sampling-arm controller's configuration
//! reads.
//!
//! ```toml
//! [robust-gain]
//! k = [[k11, k12, k13], [k21, k22, k23]]   # τ_f = K χ, χ = [ẋ, ẏ, e], e = F_c − F_d
//! sample-period = 0.0005                   # s: the T_s of the design; must equal the rig's
//! decay-rate = 0.05                        # λ (1/s) of (7.40)
//! stiffness = [300.0, 270000.0]            # [k1, k2] (N/m), the box of (7.40)
//! damping = [0.35, 1000.0]                 # [c1, c2] (N s/m)
//! margin = 1.2e-3                          # the optimal s of (7.41)
//! source = "rig-design robust-gain …"      # free text
//! ```
//!
//! `k` and `sample-period` are required; the design's other values are optional and only
//! reported. Errors name the file and the field (`robust-gain.k`).

use serde::{Deserialize, Serialize};
use std::path::Path;

/// One robust gain as the file holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct RobustGainFile {
    /// `K`, two rows of three: `τ_f = K χ`.
    pub k: Vec<Vec<f64>>,
    /// The sample period the gain was designed for, s.
    pub sample_period: f64,
    /// The decay rate `λ` of (7.40), 1/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decay_rate: Option<f64>,
    /// The stiffness range `[k_1, k_2]`, N/m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<[f64; 2]>,
    /// The damping range `[c_1, c_2]`, N s/m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<[f64; 2]>,
    /// The optimal `s` of (7.41).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub margin: Option<f64>,
    /// How the gain was made (free text).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

#[derive(Serialize, Deserialize)]
struct RawFile {
    #[serde(rename = "robust-gain")]
    robust_gain: RobustGainFile,
}

impl RobustGainFile {
    /// Reads and checks the file at `path`.
    ///
    /// # Errors
    ///
    /// `<path>: …` when it cannot be read, or as [`RobustGainFile::parse`].
    pub fn load(path: &Path) -> Result<Self, String> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{origin}: cannot read the robust gain: {e}"))?;
        Self::parse(&text, &origin)
    }

    /// Parses and checks the text of a robust-gain file; `origin` names it in errors.
    ///
    /// # Errors
    ///
    /// `<origin>: …` for text that is not TOML or has no `[robust-gain]` table, and
    /// `<origin>: field 'robust-gain.<field>': …` for an unknown field, a `k` that is not
    /// 2 × 3 or not finite, or a sample period that is not positive and finite.
    pub fn parse(text: &str, origin: &str) -> Result<Self, String> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| format!("{origin}: not valid TOML: {e}"))?;
        let value = table
            .get("robust-gain")
            .ok_or_else(|| format!("{origin}: the [robust-gain] table is missing"))?;
        let field = |name: &str, m: String| format!("{origin}: field 'robust-gain{name}': {m}");
        for range in ["stiffness", "damping"] {
            if let Some(n) = value.get(range).and_then(|v| v.as_array()).map(Vec::len)
                && n != 2
            {
                return Err(field(
                    &format!(".{range}"),
                    format!("has {n} entries, expected [lower, upper]"),
                ));
            }
        }
        let file: RobustGainFile = value
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| field("", e.message().to_string()))?;
        if file.k.len() != 2 || file.k.iter().any(|row| row.len() != 3) {
            let shape: Vec<usize> = file.k.iter().map(Vec::len).collect();
            return Err(field(
                ".k",
                format!("rows of lengths {shape:?}: K must be 2 × 3 (τ_f = K [ẋ, ẏ, e])"),
            ));
        }
        if file.k.iter().flatten().any(|v| !v.is_finite()) {
            return Err(field(".k", "must be finite".into()));
        }
        if !(file.sample_period.is_finite() && file.sample_period > 0.0) {
            return Err(field(
                ".sample-period",
                format!("{} s is not a sample period", file.sample_period),
            ));
        }
        Ok(file)
    }

    /// `K` row-major (`[k11, k12, k13, k21, k22, k23]`).
    pub fn gain(&self) -> [f64; 6] {
        let mut k = [0.0; 6];
        for (i, v) in self.k.iter().flatten().take(6).enumerate() {
            k[i] = *v;
        }
        k
    }

    /// The file text (a `[robust-gain]` table) that [`RobustGainFile::parse`] reads back.
    pub fn to_toml(&self) -> String {
        let raw = RawFile {
            robust_gain: self.clone(),
        };
        toml::to_string(&raw).expect("a robust gain always serializes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "[robust-gain]\nk = [[-1.0, 0.0, 0.0], [0.0, -2.0, 0.01]]\n\
                        sample-period = 0.0005\ndecay-rate = 0.05\nstiffness = [300.0, 270000.0]\n\
                        damping = [0.35, 1000.0]\nmargin = 0.001\n";

    #[test]
    fn a_robust_gain_file_reads_back_what_it_writes() {
        let f = RobustGainFile::parse(GOOD, "g.toml").unwrap();
        assert_eq!(f.gain(), [-1.0, 0.0, 0.0, 0.0, -2.0, 0.01]);
        assert_eq!(f.stiffness, Some([300.0, 270000.0]));
        assert_eq!(
            RobustGainFile::parse(&f.to_toml(), "again.toml").unwrap(),
            f
        );
        let minimal =
            "[robust-gain]\nk = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]\nsample-period = 0.001\n";
        let m = RobustGainFile::parse(minimal, "m.toml").unwrap();
        assert_eq!((m.decay_rate, m.margin), (None, None));
    }

    #[test]
    fn a_bad_robust_gain_file_is_refused_naming_the_file_and_field() {
        let cases = [
            (
                "k = [[-1.0, 0.0, 0.0], [0.0, -2.0, 0.01]]",
                "k = [[-1.0, 0.0]]",
                "robust-gain.k",
            ),
            ("-2.0, 0.01", "-2.0, nan", "robust-gain.k"),
            (
                "sample-period = 0.0005",
                "sample-period = -1.0",
                "robust-gain.sample-period",
            ),
            ("margin = 0.001", "margn = 0.001", "robust-gain"),
            ("sample-period = 0.0005\n", "", "robust-gain"),
        ];
        for (from, to, field) in cases {
            let e = RobustGainFile::parse(&GOOD.replace(from, to), "g.toml").unwrap_err();
            assert!(
                e.starts_with(&format!("g.toml: field '{field}'")),
                "{to}: {e}"
            );
        }
        let e = RobustGainFile::parse("[gain]\n", "g.toml").unwrap_err();
        assert!(e.contains("[robust-gain] table is missing"), "{e}");
    }
}
