//! The open-loop comparison of a changed controller with the logged one: one CSV row per
//! actuation (`seq`, `u` logged, `u` replayed, their difference) and the statistics of the
//! summary (RMS and largest difference, the first sample where they diverge).

use ipc_types::Actuation;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// What the open-loop comparison found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ComparisonStats {
    /// The CSV file.
    pub path: PathBuf,
    /// Actuations paired (logged and replayed).
    pub pairs: u64,
    /// Pairs whose status bits differ.
    pub status_differs: u64,
    /// Actuations the replay published that the record does not have at that point.
    pub only_replayed: u64,
    /// Actuations of the record the replay did not publish.
    pub only_logged: u64,
    /// RMS over every pair and input channel of `u replayed − u logged`.
    pub rms_difference: f64,
    /// Largest `|u replayed − u logged|`.
    pub max_difference: f64,
    /// The first pair whose `u` differs in any bit: (actuation seq, answered sample).
    pub first_divergence: Option<(u64, u64)>,
}

/// Writes the comparison CSV as pairs come and accumulates [`ComparisonStats`].
pub struct Comparison {
    out: BufWriter<File>,
    n_u: usize,
    sum_sq: f64,
    values: u64,
    stats: ComparisonStats,
    error: Option<String>,
}

impl Comparison {
    /// Creates the CSV at `path` with its header for `n_u` inputs.
    ///
    /// # Errors
    ///
    /// The file cannot be created, naming it.
    pub fn create(path: &Path, n_u: usize) -> Result<Self, String> {
        let file = File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut out = BufWriter::new(file);
        let mut head = String::from("seq,reply_to,status_logged,status_replayed");
        for which in ["logged", "replayed", "difference"] {
            for i in 0..n_u {
                head += &format!(",u{i}_{which}");
            }
        }
        writeln!(out, "{head}").map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self {
            out,
            n_u,
            sum_sq: 0.0,
            values: 0,
            stats: ComparisonStats {
                path: path.to_path_buf(),
                ..ComparisonStats::default()
            },
            error: None,
        })
    }

    /// Adds the pair of a logged and a replayed actuation.
    pub fn pair(&mut self, logged: &Actuation, replayed: &Actuation) {
        let s = &mut self.stats;
        s.pairs += 1;
        if logged.status != replayed.status {
            s.status_differs += 1;
        }
        let n = self.n_u;
        let mut row = format!(
            "{},{},{},{}",
            replayed.seq, replayed.reply_to, logged.status, replayed.status
        );
        for v in logged.u[..n].iter().chain(&replayed.u[..n]) {
            row += &format!(",{v:?}");
        }
        let mut diverged = false;
        for i in 0..n {
            let d = replayed.u[i] - logged.u[i];
            diverged |= replayed.u[i].to_bits() != logged.u[i].to_bits();
            row += &format!(",{d:?}");
            self.sum_sq += d * d;
            self.values += 1;
            if d.abs() > s.max_difference || d.is_nan() {
                s.max_difference = d.abs();
            }
        }
        if diverged && s.first_divergence.is_none() {
            s.first_divergence = Some((replayed.seq, replayed.reply_to));
        }
        if self.error.is_none()
            && let Err(e) = writeln!(self.out, "{row}")
        {
            self.error = Some(format!("{}: {e}", self.stats.path.display()));
        }
    }

    /// Counts an actuation only the replay published.
    pub fn only_replayed(&mut self) {
        self.stats.only_replayed += 1;
    }

    /// Counts an actuation only the record has.
    pub fn only_logged(&mut self) {
        self.stats.only_logged += 1;
    }

    /// Flushes the CSV and returns the statistics.
    ///
    /// # Errors
    ///
    /// The first write error of the CSV, naming it.
    pub fn finish(mut self) -> Result<ComparisonStats, String> {
        if self.error.is_none()
            && let Err(e) = self.out.flush()
        {
            self.error = Some(format!("{}: {e}", self.stats.path.display()));
        }
        if let Some(e) = self.error {
            return Err(e);
        }
        self.stats.rms_difference = if self.values > 0 {
            (self.sum_sq / self.values as f64).sqrt()
        } else {
            0.0
        };
        Ok(self.stats)
    }
}
