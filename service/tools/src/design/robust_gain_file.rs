//! The robust gain file `scenarios/arm/robust-gain.toml`: the gain `K` of (7.41) with the
//! box it was designed for, as `rig-design robust-gain` writes it and the arm
//! controller's configuration reads it.
//!
//! ```toml
//! [robust-gain]
//! k = [[k11, k12, k13], [k21, k22, k23]]   # τ_f = K χ, χ = [ẋ, ẏ, e], e = F_c − F_d
//! sample-period = 0.0005                   # T_s (s)
//! decay-rate = 0.025                       # λ (1/s) the gain is certified for
//! stiffness = [300.0, 270000.0]            # [k_1, k_2] (N/m)
//! damping = [0.35, 1000.0]                 # [c_1, c_2] (N s/m)
//! margin = 1.0e-6                          # the optimal s of the normalized SDP
//! ```
//!
//! Comments above the table say how the file was produced and what its verification
//! printed; they are not read back.

use crate::file_error::{FileError, FileOp};
use control::arm::robust::RobustBox;
use nalgebra::Matrix2x3;
use std::path::Path;

/// A robust gain file that cannot be read, parsed or written, naming the file and the
/// field.
#[derive(Debug, thiserror::Error)]
pub enum RobustGainFileError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The service's reader refused the file (its message names the file).
    #[error("{0}")]
    Config(String),
    /// A field a designed gain records is missing.
    #[error("{origin}: field 'robust-gain.{field}': missing (a designed gain records it)")]
    Missing {
        /// The file.
        origin: String,
        /// The field.
        field: &'static str,
    },
    /// The recorded box is refused.
    #[error("{origin}: [robust-gain] {message}")]
    Box {
        /// The file.
        origin: String,
        /// `RobustBox::validate`'s message.
        message: String,
    },
    /// The recorded margin is not finite.
    #[error("{origin}: [robust-gain] margin {margin} is not finite")]
    Margin {
        /// The file.
        origin: String,
        /// The margin.
        margin: f64,
    },
}

message_from!(RobustGainFileError);

/// The contents of a robust gain file.
#[derive(Debug, Clone, PartialEq)]
pub struct RobustGainFile {
    /// `K` (2×3) of `τ_f = K χ`.
    pub gain: Matrix2x3<f64>,
    /// The box (sample period, decay rate, stiffness and damping ranges).
    pub design: RobustBox,
    /// The optimal `s` of the normalized SDP.
    pub margin: f64,
}

impl RobustGainFile {
    /// Parses the TOML text of a robust gain file with the service's reader
    /// ([`service::config::RobustGainFile`]), then requires what a designed gain records:
    /// its box (a valid [`RobustBox`]) and a finite margin. `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<RobustGainFile, RobustGainFileError> {
        let f = service::config::RobustGainFile::parse(text, origin)
            .map_err(RobustGainFileError::Config)?;
        let need = |field| RobustGainFileError::Missing {
            origin: origin.into(),
            field,
        };
        let design = RobustBox {
            sample_period: f.sample_period,
            decay_rate: f.decay_rate.ok_or_else(|| need("decay-rate"))?,
            stiffness: f.stiffness.ok_or_else(|| need("stiffness"))?,
            damping: f.damping.ok_or_else(|| need("damping"))?,
        };
        design
            .validate()
            .map_err(|message| RobustGainFileError::Box {
                origin: origin.into(),
                message,
            })?;
        let margin = f.margin.ok_or_else(|| need("margin"))?;
        if !margin.is_finite() {
            return Err(RobustGainFileError::Margin {
                origin: origin.into(),
                margin,
            });
        }
        let k = f.gain();
        Ok(RobustGainFile {
            gain: Matrix2x3::from_row_slice(&k),
            design,
            margin,
        })
    }

    /// Reads and parses `path`.
    pub fn load(path: &Path) -> Result<RobustGainFile, RobustGainFileError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| FileError::new(FileOp::Reading, path.to_path_buf(), source))?;
        Self::parse(&text, &path.display().to_string())
    }

    /// The TOML text: `comment` (each line prefixed with `# `), then the table. Numbers are
    /// written in Rust's shortest round-trip form, so parsing gives back the same values.
    pub fn to_toml(&self, comment: &str) -> String {
        let mut s = String::new();
        for line in comment.lines() {
            if line.is_empty() {
                s += "#\n";
            } else {
                s += &format!("# {line}\n");
            }
        }
        let row = |r: usize| {
            let v: Vec<String> = (0..3).map(|c| format!("{:?}", self.gain[(r, c)])).collect();
            format!("[{}]", v.join(", "))
        };
        let d = &self.design;
        s += "[robust-gain]\n";
        s += &format!(
            "k = [{}, {}]   # τ_f = K χ, χ = [ẋ, ẏ, e], e = F_c − F_d\n",
            row(0),
            row(1)
        );
        s += &format!("sample-period = {:?}   # T_s (s)\n", d.sample_period);
        s += &format!("decay-rate = {:?}   # λ (1/s)\n", d.decay_rate);
        s += &format!(
            "stiffness = [{:?}, {:?}]   # [k_1, k_2] (N/m)\n",
            d.stiffness[0], d.stiffness[1]
        );
        s += &format!(
            "damping = [{:?}, {:?}]   # [c_1, c_2] (N s/m)\n",
            d.damping[0], d.damping[1]
        );
        s += &format!(
            "margin = {:?}   # the optimal s of the normalized SDP\n",
            self.margin
        );
        s
    }

    /// Writes [`RobustGainFile::to_toml`] to `path` (creating its folder).
    pub fn save(&self, path: &Path, comment: &str) -> Result<(), RobustGainFileError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|source| FileError::new(FileOp::Creating, dir.to_path_buf(), source))?;
        }
        std::fs::write(path, self.to_toml(comment))
            .map_err(|source| FileError::new(FileOp::Writing, path.to_path_buf(), source).into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> RobustGainFile {
        RobustGainFile {
            gain: Matrix2x3::new(-1999.9, 1e-9, -3.0e-12, 2.5e-13, -193.02, 0.027621),
            design: RobustBox {
                decay_rate: 0.025,
                ..RobustBox::CHAPTER_7
            },
            margin: 2.2e-6,
        }
    }

    #[test]
    fn what_is_written_reads_back_exactly() {
        let f = sample();
        let text = f.to_toml("made by a test\n\nsecond paragraph");
        assert!(text.starts_with("# made by a test\n#\n# second paragraph\n[robust-gain]\n"));
        assert_eq!(RobustGainFile::parse(&text, "t.toml").unwrap(), f);
    }

    #[test]
    fn errors_name_the_file_and_the_field() {
        let text = sample().to_toml("");
        let bad = text.replace("damping = [0.35, 1000.0]", "damping = [1000.0, 0.35]");
        let e = RobustGainFile::parse(&bad, "g.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("g.toml") && e.contains("damping"), "{e}");
        let bad = text.replace("margin", "margn");
        let e = RobustGainFile::parse(&bad, "g.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("g.toml") && e.contains("margn"), "{e}");
        let bad = text.replace("k = [[", "k = [[1.0, ");
        let e = RobustGainFile::parse(&bad, "g.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("g.toml") && e.contains("K must be 2 × 3"), "{e}");
        let bad = text.replace("stiffness = [300.0,", "stiffness = [1.0, 300.0,");
        let e = RobustGainFile::parse(&bad, "g.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("g.toml") && e.contains("stiffness"), "{e}");
        let e = RobustGainFile::load(Path::new("/nonexistent/robust-gain.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/robust-gain.toml"), "{e}");
    }
}
