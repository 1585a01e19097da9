//! The sensitivity of claims 7.3–7.6 to the robust gain: the experiments behind them
//! (Figure 7.4's and Figure 7.6's single runs and the Hunt–Crossley grid of Figure 7.5,
//! both controllers) run again with each alternative gain file of `scenarios/arm/`
//! ([`ALTERNATIVES`], written by `rig-design robust-gain --objective …`), and checked with
//! the same criteria ([`super::claims::claims`]).
//!
//! The claims' verdicts stay the committed gain's (`robust-gain.toml`, the margin design);
//! this says which design, if any, shows the chapter's robust behaviour (a robust
//! controller that takes most of the contact period, or never reaches 25 N). Each gain is
//! also checked independently, as `rig-design` does: the largest spectral radius of
//! `A_d + B_d K` over a log grid of its box against `e^{−λ T_s}` (Figure 7.2's model).

use std::fmt::Write as _;
use std::path::Path;

use rayon::prelude::*;

use crate::design::robust_gain_file::RobustGainFile;
use crate::file_error::{FileError, FileOp};
use crate::study::arm::ArmError;
use crate::study::arm::claims::{self, Evidence};
use crate::study::arm::closed_loop::{self, ContactStats, Law, Maneuver, Model, Record, Setup};
use crate::study::arm::grid::{self, Grid};
use crate::study::reproduction::{Claim, Verdict};

/// The alternative gains: `(objective, file in scenarios/arm/)`.
pub const ALTERNATIVES: [(&str, &str); 2] = [
    ("min-gain", "robust-gain-min-gain.toml"),
    ("lqr", "robust-gain-lqr.toml"),
];

/// The ids of the claims re-run.
pub const CLAIMS: [&str; 4] = ["7.3", "7.4", "7.5", "7.6"];

/// Grid points per axis of the independent spectral-radius check.
pub const CHECK_GRID: usize = 60;

/// One gain's results.
#[derive(Debug, Clone)]
pub struct GainResult {
    /// The objective's name (`margin` for the committed gain).
    pub name: String,
    /// The file, relative to `scenarios/arm/`.
    pub file: String,
    /// `K` (row-major).
    pub gain: [f64; 6],
    /// The certified margin `s` the file records.
    pub margin: f64,
    /// The decay rate it is certified for, 1/s.
    pub decay_rate: f64,
    /// The worst spectral radius over the box's grid and its bound `e^{−λ T_s}`.
    pub radius: (f64, f64),
    /// Claims 7.3–7.6 with this gain.
    pub claims: Vec<Claim>,
}

fn load(dir: &Path, name: &str, file: &str) -> Result<GainResult, ArmError> {
    let path = dir.join(file);
    let f = RobustGainFile::load(&path).map_err(|e| ArmError::Gain {
        file: path.display().to_string(),
        message: e.to_string(),
    })?;
    let check = f.design.check_gain(&f.gain, CHECK_GRID);
    let mut gain = [0.0; 6];
    for (i, g) in gain.iter_mut().enumerate() {
        *g = f.gain[(i / 3, i % 3)];
    }
    Ok(GainResult {
        name: name.into(),
        file: file.into(),
        gain,
        margin: f.margin,
        decay_rate: f.design.decay_rate,
        radius: (
            check.worst_grid.radius.max(check.worst_vertex.radius),
            check.bound,
        ),
        claims: Vec::new(),
    })
}

fn first(o: &closed_loop::Outcome) -> ContactStats {
    o.contacts.first().copied().unwrap_or(ContactStats {
        first: 0,
        samples: 0,
        median: f64::NAN,
        settling: f64::NAN,
    })
}

/// Claims 7.3–7.6 of the committed run's claims `all`.
pub fn committed(dir: &Path, all: &[Claim]) -> Result<GainResult, ArmError> {
    let mut r = load(dir, "margin", "robust-gain.toml")?;
    r.claims = all
        .iter()
        .filter(|c| CLAIMS.contains(&c.id.as_str()))
        .cloned()
        .collect();
    Ok(r)
}

/// Runs claims 7.3–7.6's experiments with the gain of `file` (in `dir`) on an `n × n`
/// Hunt–Crossley grid.
pub fn run_gain(
    setup: &Setup,
    dir: &Path,
    (name, file): (&str, &str),
    n: usize,
) -> Result<GainResult, ArmError> {
    let mut r = load(dir, name, file)?;
    let setup = setup.with_gain(r.gain);
    let singles = [
        Maneuver::Single(Model::Linear, 2.0e5, 5.0),
        Maneuver::Single(Model::HuntCrossley, 2.0e5, 0.9),
    ];
    let jobs: Vec<(Maneuver, Law)> = singles
        .iter()
        .flat_map(|&m| Law::ALL.map(|l| (m, l)))
        .collect();
    let outs: Vec<ContactStats> = jobs
        .par_iter()
        .map(|&(m, law)| {
            let sc = setup.scenario(m)?;
            closed_loop::run(&setup, &sc, law, Record::FirstContact).map(|o| first(&o))
        })
        .collect::<Result<_, ArmError>>()?;
    let points = grid::sweep(&setup, &[Grid::new(Model::HuntCrossley, n)?]);
    let evidence = Evidence {
        grid: &points,
        fig_7_4: (outs[0], outs[1]),
        fig_7_6: (outs[2], outs[3]),
        doubles: Vec::new(),
    };
    r.claims = claims::claims(&evidence)
        .into_iter()
        .filter(|c| CLAIMS.contains(&c.id.as_str()))
        .collect();
    Ok(r)
}

/// The sentence appended to claim `id`'s "ours": each alternative's verdict and evidence.
pub fn reading(id: &str, alternatives: &[GainResult]) -> String {
    let parts: Vec<String> = alternatives
        .iter()
        .filter_map(|g| {
            g.claims.iter().find(|c| c.id == id).map(|c| {
                format!(
                    "{} gain ({}): {} — {}",
                    g.name,
                    g.file,
                    c.verdict.word(),
                    c.ours
                )
            })
        })
        .collect();
    if parts.is_empty() {
        String::new()
    } else {
        format!(
            " With the other robust gains (the verdict is the committed margin design's): {}.",
            parts.join("; ")
        )
    }
}

/// Which designs pass all of claims 7.3, 7.4 and 7.6 (the robust controller's behaviour).
pub fn reproducing(results: &[GainResult]) -> Vec<&str> {
    results
        .iter()
        .filter(|g| {
            ["7.3", "7.4", "7.6"].iter().all(|id| {
                g.claims
                    .iter()
                    .any(|c| c.id == *id && c.verdict == Verdict::Pass)
            })
        })
        .map(|g| g.name.as_str())
        .collect()
}

fn k_text(k: &[f64; 6]) -> String {
    format!(
        "[[{:.4e}, {:.3e}, {:.3e}], [{:.3e}, {:.4e}, {:.4e}]]",
        k[0], k[1], k[2], k[3], k[4], k[5]
    )
}

/// The Markdown section of the summary.
pub fn markdown(results: &[GainResult]) -> String {
    let mut md = String::from("## Sensitivity of claims 7.3–7.6 to the robust gain\n\n");
    md += "Each gain file is a design of `rig-design robust-gain --objective …` over the same box and \
           decay-rate inequalities (7.40) (docs/design-tools.md); the runs of claims 7.3–7.6 (Figures 7.4 \
           and 7.6, the Hunt–Crossley grid of Figure 7.5) are repeated with it in both controllers, with the \
           same criteria. The claims' verdicts above are the committed (margin) gain's.\n\n";
    md += "| gain | file | K | certified s at λ | worst ρ (bound) | 7.3 | 7.4 | 7.5 | 7.6 |\n";
    md += "|---|---|---|---:|---:|---|---|---|---|\n";
    for g in results {
        let _ = write!(
            md,
            "| {} | {} | {} | {:.3e} (λ = {}) | {:.9} ({:.9}) |",
            g.name,
            g.file,
            k_text(&g.gain),
            g.margin,
            g.decay_rate,
            g.radius.0,
            g.radius.1
        );
        for id in CLAIMS {
            let c = g.claims.iter().find(|c| c.id == id);
            let _ = write!(
                md,
                " {} |",
                c.map_or("-".into(), |c| format!(
                    "{}: {}",
                    c.verdict.word(),
                    c.ours.replace('|', "\\|")
                ))
            );
        }
        md.push('\n');
    }
    let rep = reproducing(results);
    let _ = writeln!(
        md,
        "\nThe chapter's robust behaviour (claims 7.3, 7.4 and 7.6 all PASS): {}.\n",
        if rep.is_empty() {
            "no design".to_string()
        } else {
            rep.join(", ")
        }
    );
    md
}

/// Writes `gain_sensitivity.csv`: `gain, file, k11 … k23, margin, decay_rate,
/// worst_radius, radius_bound, claim, verdict, ours`.
pub fn write_csv(path: &Path, results: &[GainResult]) -> Result<(), ArmError> {
    let mut s = String::from(
        "gain,file,k11,k12,k13,k21,k22,k23,margin,decay_rate,worst_radius,radius_bound,claim,verdict,ours\n",
    );
    for g in results {
        for c in &g.claims {
            let _ = write!(s, "{},{}", g.name, g.file);
            for k in g.gain {
                let _ = write!(s, ",{k:e}");
            }
            let _ = writeln!(
                s,
                ",{:e},{},{:.12},{:.12},{},{},\"{}\"",
                g.margin,
                g.decay_rate,
                g.radius.0,
                g.radius.1,
                c.id,
                c.verdict.word(),
                c.ours.replace('"', "\"\"")
            );
        }
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}
