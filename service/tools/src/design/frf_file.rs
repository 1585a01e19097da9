//! A frequency response on disk: the hand-off between `rig-design frf`/`model-frf` and
//! `rig-design dtf`.
//!
//! ```text
//! # frequency-response sample-period=0.000125 outputs=1 inputs=2 delays=9,16 source=…
//! hz,theta,re_0_0,im_0_0,re_0_1,im_0_1,coherence_0
//! 0,0,…
//! ```
//!
//! The response is the plant's own (delays included); `delays` are the pure input delays
//! (samples) that the design step removes before fitting and adds back in the target
//! model (3.49). The coherence columns are present for a measured response.

use super::{C64, Frf};
use crate::file_error::{FileError, FileOp};
use std::fmt::Write as _;
use std::path::Path;

/// A response with its delays and, for measured data, the multiple coherence per output.
#[derive(Debug, Clone, PartialEq)]
pub struct FrfFile {
    /// The response (delays included).
    pub frf: Frf,
    /// Pure delay of each input, samples.
    pub delays: Vec<usize>,
    /// Multiple coherence per output (measured data only).
    pub coherence: Option<Vec<Vec<f64>>>,
    /// Where it came from.
    pub source: String,
}

/// A frequency-response file that cannot be written, read or parsed, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum FrfFileError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The file cannot be read.
    #[error("{origin}: cannot read the frequency response: {source}")]
    Read {
        /// The file.
        origin: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file's content is not a frequency response.
    #[error("{origin}: {problem}")]
    Content {
        /// The file.
        origin: String,
        /// What is wrong, and where.
        problem: FrfProblem,
    },
}

message_from!(FrfFileError);

/// What is wrong in a frequency-response file, with its line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrfProblem {
    /// No line at all.
    #[error("empty file")]
    Empty,
    /// The first line is not the file's header.
    #[error("line 1: not a frequency-response file (written by rig-design frf or model-frf)")]
    NotFrf,
    /// A header value of the wrong kind.
    #[error("line 1: {key} = '{value}' is not {what}")]
    Bad {
        /// The header key.
        key: String,
        /// Its value.
        value: String,
        /// What it must be.
        what: &'static str,
    },
    /// A header key is missing.
    #[error("line 1: {0}= is missing")]
    Missing(&'static str),
    /// The sample period or a count is not positive.
    #[error("line 1: sample-period, outputs and inputs must be positive")]
    NotPositive,
    /// Not one delay per input.
    #[error("line 1: {delays} delays for {inputs} inputs")]
    Delays {
        /// The delays given.
        delays: usize,
        /// The inputs.
        inputs: usize,
    },
    /// No column header.
    #[error("the column header is missing")]
    NoColumns,
    /// The column header does not fit the counts.
    #[error(
        "line 2: {found} columns, expected {} (or {} with coherence) for {outputs} outputs × {inputs} inputs",
        2 + 2 * outputs * inputs,
        2 + 2 * outputs * inputs + outputs
    )]
    Columns {
        /// The columns there are.
        found: usize,
        /// The outputs.
        outputs: usize,
        /// The inputs.
        inputs: usize,
    },
    /// A value that is not a number.
    #[error("line {0}: a value is not a number")]
    NotANumber(usize),
    /// A row of the wrong length.
    #[error("line {line}: {found} values, expected {expected}")]
    Values {
        /// The line.
        line: usize,
        /// Its values.
        found: usize,
        /// The columns.
        expected: usize,
    },
    /// A NaN or infinite value.
    #[error("line {0}: NaN or infinite value")]
    NotFinite(usize),
    /// Fewer than 2 rows.
    #[error("fewer than 2 frequencies")]
    TooFew,
    /// The frequencies do not increase within `[0, π]`.
    #[error("theta must increase within [0, π]")]
    Theta,
}

impl FrfFile {
    /// Writes the CSV file.
    pub fn save(&self, path: &Path) -> Result<(), FrfFileError> {
        let f = &self.frf;
        let (p, m) = (f.n_outputs, f.n_inputs);
        let delays: Vec<String> = self.delays.iter().map(|d| d.to_string()).collect();
        let mut s = format!(
            "# frequency-response sample-period={:e} outputs={p} inputs={m} delays={} source={}\nhz,theta",
            f.ts,
            delays.join(","),
            self.source.replace(['\n', ' '], "_")
        );
        for o in 0..p {
            for i in 0..m {
                let _ = write!(s, ",re_{o}_{i},im_{o}_{i}");
            }
        }
        if self.coherence.is_some() {
            for o in 0..p {
                let _ = write!(s, ",coherence_{o}");
            }
        }
        s.push('\n');
        let hz = f.hz();
        for k in 0..f.theta.len() {
            let _ = write!(s, "{},{}", hz[k], f.theta[k]);
            for c in &f.response {
                let _ = write!(s, ",{},{}", c[k].re, c[k].im);
            }
            if let Some(coh) = &self.coherence {
                for c in coh {
                    let _ = write!(s, ",{}", c[k]);
                }
            }
            s.push('\n');
        }
        std::fs::write(path, s)
            .map_err(|source| FileError::new(FileOp::Writing, path.to_path_buf(), source).into())
    }

    /// Reads a file written by [`FrfFile::save`].
    pub fn load(path: &Path) -> Result<Self, FrfFileError> {
        let origin = path.display().to_string();
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(source) => return Err(FrfFileError::Read { origin, source }),
        };
        Self::parse(&text, &origin)
    }

    /// Parses the text of a frequency-response file; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, FrfFileError> {
        let fail = |problem| FrfFileError::Content {
            origin: origin.into(),
            problem,
        };
        let mut lines = text.lines().enumerate();
        let (_, head) = lines.next().ok_or_else(|| fail(FrfProblem::Empty))?;
        let head = head
            .strip_prefix("# frequency-response")
            .ok_or_else(|| fail(FrfProblem::NotFrf))?;
        let (mut ts, mut p, mut m, mut delays, mut source) =
            (None, None, None, Vec::new(), String::new());
        for kv in head.split_whitespace() {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            let bad = |what| {
                fail(FrfProblem::Bad {
                    key: k.into(),
                    value: v.into(),
                    what,
                })
            };
            match k {
                "sample-period" => ts = Some(v.parse::<f64>().map_err(|_| bad("a number"))?),
                "outputs" => p = Some(v.parse::<usize>().map_err(|_| bad("a count"))?),
                "inputs" => m = Some(v.parse::<usize>().map_err(|_| bad("a count"))?),
                "delays" if !v.is_empty() => {
                    delays = v
                        .split(',')
                        .map(|d| d.parse::<usize>())
                        .collect::<Result<_, _>>()
                        .map_err(|_| bad("a list of sample counts"))?
                }
                "source" => source = v.to_string(),
                _ => {}
            }
        }
        let missing = |k| fail(FrfProblem::Missing(k));
        let ts = ts.ok_or_else(|| missing("sample-period"))?;
        let (p, m) = (
            p.ok_or_else(|| missing("outputs"))?,
            m.ok_or_else(|| missing("inputs"))?,
        );
        if !(ts > 0.0 && ts.is_finite()) || p == 0 || m == 0 {
            return Err(fail(FrfProblem::NotPositive));
        }
        if delays.is_empty() {
            delays = vec![0; m];
        } else if delays.len() != m {
            return Err(fail(FrfProblem::Delays {
                delays: delays.len(),
                inputs: m,
            }));
        }
        let (_, cols) = lines.next().ok_or_else(|| fail(FrfProblem::NoColumns))?;
        let ncol = cols.split(',').count();
        let with_coh = match ncol {
            n if n == 2 + 2 * p * m => false,
            n if n == 2 + 2 * p * m + p => true,
            n => {
                return Err(fail(FrfProblem::Columns {
                    found: n,
                    outputs: p,
                    inputs: m,
                }));
            }
        };
        let mut theta = Vec::new();
        let mut response = vec![Vec::new(); p * m];
        let mut coherence = vec![Vec::new(); if with_coh { p } else { 0 }];
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let v: Vec<f64> = line
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| fail(FrfProblem::NotANumber(i + 1)))?;
            if v.len() != ncol {
                return Err(fail(FrfProblem::Values {
                    line: i + 1,
                    found: v.len(),
                    expected: ncol,
                }));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(fail(FrfProblem::NotFinite(i + 1)));
            }
            theta.push(v[1]);
            for c in 0..p * m {
                response[c].push(C64::new(v[2 + 2 * c], v[3 + 2 * c]));
            }
            for (o, c) in coherence.iter_mut().enumerate() {
                c.push(v[2 + 2 * p * m + o]);
            }
        }
        if theta.len() < 2 {
            return Err(fail(FrfProblem::TooFew));
        }
        if theta.windows(2).any(|w| w[1] <= w[0])
            || theta[0] < 0.0
            || *theta.last().unwrap() > std::f64::consts::PI + 1e-12
        {
            return Err(fail(FrfProblem::Theta));
        }
        Ok(Self {
            frf: Frf {
                ts,
                theta,
                n_outputs: p,
                n_inputs: m,
                response,
            },
            delays,
            coherence: with_coh.then_some(coherence),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_response_reads_back_bit_for_bit() {
        let theta = vec![0.0, 0.1, 1.0, std::f64::consts::PI];
        let response = (0..2)
            .map(|c| {
                theta
                    .iter()
                    .map(|t| C64::new(t.cos() + c as f64, -t.sin() / 3.0))
                    .collect()
            })
            .collect();
        let f = FrfFile {
            frf: Frf {
                ts: 1.25e-4,
                theta,
                n_outputs: 1,
                n_inputs: 2,
                response,
            },
            delays: vec![9, 16],
            coherence: Some(vec![vec![0.1, 0.5, 0.99, 1.0]]),
            source: "unit test".into(),
        };
        let dir = std::env::temp_dir().join(format!("frf-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frf.csv");
        f.save(&path).unwrap();
        let back = FrfFile::load(&path).unwrap();
        assert_eq!(back.frf, f.frf);
        assert_eq!(back.delays, f.delays);
        assert_eq!(back.coherence, f.coherence);
        assert_eq!(back.source, "unit_test");
        let text = std::fs::read_to_string(&path).unwrap();
        let e = FrfFile::parse(&text.replace("delays=9,16", "delays=9"), "x.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("x.csv") && e.contains("1 delays for 2 inputs"),
            "{e}"
        );
        let e = FrfFile::parse(&text.replacen("0.5", "NaN", 1), "x.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 4"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
