//! The robust gains of the sensitivity record: the committed design
//! (`scenarios/arm/robust-gain.toml`, the margin design) and the alternative designs of
//! `scenarios/arm/` ([`ALTERNATIVES`], written by `rig-design robust-gain --objective …`),
//! loaded and checked independently, as `rig-design` does: the largest spectral radius of
//! `A_d + B_d K` over a log grid of its box against `e^{−λ T_s}` (Figure 7.2's model).
//!
//! The runs with each gain and the verdicts of claims 7.2–7.6 under it are rows of the
//! study's sensitivity record ([`super::sensitivity`], setting "robust gain K"); this
//! module only describes the designs ([`markdown`]).

use std::fmt::Write as _;
use std::path::Path;

use crate::design::robust_gain_file::RobustGainFile;
use crate::study::arm::ArmError;

/// The alternative gains: `(objective, file in scenarios/arm/)`.
pub const ALTERNATIVES: [(&str, &str); 2] = [
    ("min-gain", "robust-gain-min-gain.toml"),
    ("lqr", "robust-gain-lqr.toml"),
];

/// Figure 7.4's surface `(k_s, c_s)`.
const FIG_7_4: (f64, f64) = (2.0e5, 5.0);

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
    /// The slowest decay rate of the force loop, 1/s: `−ln ρ / T_s` of the `(ẏ, e)`
    /// block of `A_d + B_d K` in (7.39) (the loop of the contact force; the `ẋ` mode,
    /// `1 + T_s K_11`, is apart when `K_21 = 0`), at Figure 7.4's surface
    /// (`k_s = 2·10⁵`, `c_s = 5`) and at the box's softest corner (`k_1`, `c_1`). Claim
    /// 7.3's robust controller, which "takes most of the 2 second contact period", needs
    /// the first near `ln 20 / 1 s ≈ 3 /s` or below.
    pub decay: (f64, f64),
}

/// The gain of `file` (in `dir`), named after its objective `name`, with its check.
pub fn load(dir: &Path, name: &str, file: &str) -> Result<GainResult, ArmError> {
    let path = dir.join(file);
    let f = RobustGainFile::load(&path).map_err(|e| ArmError::Gain {
        file: path.display().to_string(),
        message: e.to_string(),
    })?;
    let check = f.design.check_gain(&f.gain, CHECK_GRID);
    let rate = |k: f64, c: f64| force_loop_decay(&f.design, &f.gain, k, c);
    let decay = (
        rate(FIG_7_4.0, FIG_7_4.1),
        rate(f.design.stiffness[0], f.design.damping[0]),
    );
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
        decay,
    })
}

fn k_text(k: &[f64; 6]) -> String {
    format!(
        "[[{:.4e}, {:.3e}, {:.3e}], [{:.3e}, {:.4e}, {:.4e}]]",
        k[0], k[1], k[2], k[3], k[4], k[5]
    )
}

/// The slowest decay rate, 1/s, of the `(ẏ, e)` block of `A_d + B_d K` at `(k_s, c_s)`
/// ([`GainResult::decay`]).
pub fn force_loop_decay(
    design: &control::arm::robust::RobustBox,
    gain: &nalgebra::Matrix2x3<f64>,
    k_s: f64,
    c_s: f64,
) -> f64 {
    let (a, b) = design.model(k_s, c_s);
    let m = a + b * gain;
    let block = m.fixed_view::<2, 2>(1, 1).into_owned();
    let radius = block
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max);
    -radius.ln() / design.sample_period
}

/// The committed design and the alternatives of `dir`, committed first.
pub fn designs(dir: &Path) -> Result<Vec<GainResult>, ArmError> {
    std::iter::once(("margin", "robust-gain.toml"))
        .chain(ALTERNATIVES)
        .map(|(name, file)| load(dir, name, file))
        .collect()
}

/// The Markdown section of the summary: the designs (their verdicts are in the
/// sensitivity table, setting "robust gain K").
pub fn markdown(results: &[GainResult]) -> String {
    let mut md = String::from("## The robust gains of the sensitivity record\n\n");
    md += "Each gain file is a design of `rig-design robust-gain --objective …` over the same box and \
           decay-rate inequalities (7.40) (docs/design-tools.md). The claims' verdicts are the committed \
           (margin) gain's; the runs of claims 7.2–7.6 with each other design, in both controllers, are rows \
           of the sensitivity table (setting \"robust gain K\").\n\n";
    md += "| gain | file | K | certified s at λ | worst ρ (bound) | force loop's slowest decay at k_s = 2e5, c_s = 5 (Figure 7.4) | at k_1, c_1 |\n";
    md += "|---|---|---|---:|---:|---:|---:|\n";
    for g in results {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3e} (λ = {}) | {:.9} ({:.9}) | {:.2} /s | {:.4} /s |",
            g.name,
            g.file,
            k_text(&g.gain),
            g.margin,
            g.decay_rate,
            g.radius.0,
            g.radius.1,
            g.decay.0,
            g.decay.1
        );
    }
    md += "\nThe decay rates are of the force loop of (7.39) in closed loop, `−ln ρ / T_s` of the (ẏ, e) block of \
           `A_d + B_d K` (the ẋ mode apart). Claim 7.3's robust controller, which \"takes most of the 2 second \
           contact period\" at k_s = 2e5, c_s = 5, needs it near ln 20 / 1 s ≈ 3 /s or below.\n\n";
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_design_decays_at_least_at_its_certified_rate_at_the_soft_corner() {
        let dir = crate::study::arm::closed_loop::scenario_dir();
        let designs = designs(&dir).unwrap();
        assert_eq!(designs.len(), 1 + ALTERNATIVES.len());
        assert_eq!(designs[0].name, "margin");
        for g in &designs {
            // ρ ≤ e^{−λ T_s} at every point of the box, so −ln ρ / T_s ≥ λ there.
            assert!(g.radius.0 <= g.radius.1 * (1.0 + 1e-9), "{}", g.name);
            assert!(
                g.decay.1 >= g.decay_rate * (1.0 - 1e-3),
                "{}: {:?}",
                g.name,
                g.decay
            );
            assert!(g.decay.0.is_finite() && g.decay.0 > 0.0, "{}", g.name);
        }
    }

    #[test]
    fn the_force_loops_slow_mode_follows_its_characteristic_polynomial() {
        let dir = crate::study::arm::closed_loop::scenario_dir();
        let g = load(&dir, "margin", "robust-gain.toml").unwrap();
        let f = RobustGainFile::load(&dir.join("robust-gain.toml")).unwrap();
        // Continuous time: s² − (K_22 − c K_23) s + k K_23 = 0; its slow root, against the
        // discrete block at 2 kHz (T_s |s| ≲ 0.1: the two agree to about 2 %), for the
        // gain and for one with a force-error gain ten times smaller.
        let (k, c) = (2.0e5, 5.0);
        for scale in [1.0, 0.1] {
            let mut gain = f.gain;
            gain[(1, 2)] *= scale;
            let (k22, k23) = (gain[(1, 1)], gain[(1, 2)]);
            let p = -(k22 - c * k23);
            let q = k * k23;
            let slow = (p - (p * p - 4.0 * q).sqrt()) / 2.0;
            let decay = force_loop_decay(&f.design, &gain, k, c);
            assert!((decay / slow - 1.0).abs() < 0.02, "{scale}: {decay} {slow}");
            if scale == 1.0 {
                assert_eq!(decay, g.decay.0);
            }
        }
    }
}
