//! The empty squares of Figures 4.8a–4.10a counted on a reading of the pole grid: per
//! command, where APPC on Example 2's NMP plant (4.88) diverges, and where it diverges
//! while RC-MRAC on the same plant does not (Figures 4.11a–4.13a, same axes, show no
//! empty square).
//!
//! A **reading** is a set of pole grids standing for the figures' axes: the chapter's
//! range inside the unit circle ([`crate::study::mrac::grid`]), or the outward grid with
//! the patch around the zero ([`crate::study::mrac::outward`]). A reading
//! **reproduces** the captions when, for each of the three commands (Figures 4.8a, 4.9a
//! and 4.10a all carry "Empty squares represent regions where the system became
//! unstable"), APPC diverges at one point at least and at one point at least APPC
//! diverges while RC-MRAC does not.

use std::fmt::Write as _;

use crate::study::mrac::grid::Sweep;
use crate::study::mrac::setup::{CommandKind, Example, Method};

/// The counts of one command on one reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandSquares {
    /// The command.
    pub command: CommandKind,
    /// Grid points (each run by both methods).
    pub points: usize,
    /// Points where APPC diverged.
    pub appc_unstable: usize,
    /// Points where RC-MRAC diverged.
    pub rc_unstable: usize,
    /// Points where APPC diverged and RC-MRAC did not.
    pub appc_only: usize,
    /// Points with `ρ ≥ 1` (open-loop unstable plants).
    pub outside_circle: usize,
    /// Of those, where APPC diverged.
    pub appc_unstable_outside: usize,
    /// The smallest `ρ` at which APPC diverged.
    pub smallest_unstable_rho: Option<f64>,
}

impl CommandSquares {
    /// True when APPC diverges somewhere and somewhere RC-MRAC does not.
    pub fn shows_empty_squares(&self) -> bool {
        self.appc_unstable > 0 && self.appc_only > 0
    }
}

/// Why two sweeps cannot be compared point by point.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ReadingError {
    /// The sweeps are not APPC and RC-MRAC on Example 2 with one command.
    #[error("empty squares: expected APPC and RC-MRAC on Example 2 with one command")]
    NotAPair,
    /// The sweeps' points differ.
    #[error("empty squares: the APPC and RC-MRAC sweeps are not on the same poles")]
    OtherPoles,
}

/// One reading of the figures' axes and its counts per command.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// What the reading is, e.g. "inside the unit circle (15 × 15)".
    pub name: String,
    /// Per command, in the order of [`CommandKind::ALL`].
    pub commands: Vec<CommandSquares>,
}

impl Reading {
    /// Counts the pairs `(APPC sweep, RC-MRAC sweep)` of Example 2, each pair on one grid
    /// with one command; pairs of the same command (e.g. the outward grid and the patch)
    /// add up.
    pub fn of(name: &str, pairs: &[(&Sweep, &Sweep)]) -> Result<Self, ReadingError> {
        let mut commands: Vec<CommandSquares> = Vec::new();
        for &(a, r) in pairs {
            let pair_ok = a.example == Example::Two
                && r.example == Example::Two
                && a.method == Method::Appc
                && r.method == Method::RcMrac
                && a.command == r.command;
            if !pair_ok {
                return Err(ReadingError::NotAPair);
            }
            let same = a.points.len() == r.points.len()
                && a.points
                    .iter()
                    .zip(&r.points)
                    .all(|(p, q)| p.rho == q.rho && p.nu == q.nu);
            if !same {
                return Err(ReadingError::OtherPoles);
            }
            let i = match commands.iter().position(|c| c.command == a.command) {
                Some(i) => i,
                None => {
                    commands.push(CommandSquares {
                        command: a.command,
                        points: 0,
                        appc_unstable: 0,
                        rc_unstable: 0,
                        appc_only: 0,
                        outside_circle: 0,
                        appc_unstable_outside: 0,
                        smallest_unstable_rho: None,
                    });
                    commands.len() - 1
                }
            };
            let c = &mut commands[i];
            for (p, q) in a.points.iter().zip(&r.points) {
                c.points += 1;
                c.appc_unstable += usize::from(p.unstable());
                c.rc_unstable += usize::from(q.unstable());
                c.appc_only += usize::from(p.unstable() && !q.unstable());
                c.outside_circle += usize::from(p.rho >= 1.0);
                c.appc_unstable_outside += usize::from(p.unstable() && p.rho >= 1.0);
                if p.unstable() {
                    c.smallest_unstable_rho =
                        Some(c.smallest_unstable_rho.map_or(p.rho, |s| s.min(p.rho)));
                }
            }
        }
        commands.sort_by_key(|c| c.command);
        Ok(Self {
            name: name.into(),
            commands,
        })
    }

    /// True when every command of [`CommandKind::ALL`] was run.
    pub fn complete(&self) -> bool {
        CommandKind::ALL
            .iter()
            .all(|k| self.commands.iter().any(|c| c.command == *k))
    }

    /// True when the reading is complete and every command shows empty squares (the
    /// module documentation).
    pub fn reproduces(&self) -> bool {
        self.complete()
            && self
                .commands
                .iter()
                .all(CommandSquares::shows_empty_squares)
    }

    /// The counts as one line of text.
    pub fn text(&self) -> String {
        let mut s = format!("{}: APPC unstable", self.name);
        for c in &self.commands {
            let _ = write!(s, " {} {}/{}", c.command.name(), c.appc_unstable, c.points);
            if c.outside_circle > 0 {
                let _ = write!(
                    s,
                    " ({} of {} with ρ ≥ 1",
                    c.appc_unstable_outside, c.outside_circle
                );
                if let Some(r) = c.smallest_unstable_rho {
                    let _ = write!(s, ", from ρ = {r:.3}");
                }
                s.push(')');
            }
            s.push(',');
        }
        s.pop();
        let _ = write!(
            s,
            "; RC-MRAC unstable {}; APPC-only {}",
            self.commands
                .iter()
                .map(|c| format!("{} {}", c.command.name(), c.rc_unstable))
                .collect::<Vec<_>>()
                .join(", "),
            self.commands
                .iter()
                .map(|c| format!("{} {}", c.command.name(), c.appc_only))
                .collect::<Vec<_>>()
                .join(", ")
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::mrac::closed_loop::Divergence;
    use crate::study::mrac::grid::GridPoint;

    /// A sweep on the poles `(ρ, 1.0)`, `unstable[i]` marking point i as diverged.
    fn sweep(command: CommandKind, method: Method, rho: &[f64], unstable: &[bool]) -> Sweep {
        Sweep {
            example: Example::Two,
            command,
            method,
            points: rho
                .iter()
                .zip(unstable)
                .map(|(&rho, &u)| GridPoint {
                    rho,
                    nu: 1.0,
                    e_norm: if u { f64::INFINITY } else { 0.1 },
                    diverged: u.then_some((Divergence::Large, 20)),
                    peak_y: 1.0,
                    theta_settle: (!u).then_some(30),
                })
                .collect(),
        }
    }

    #[test]
    fn a_reading_reproduces_only_when_appc_alone_diverges_with_every_command() {
        let rho = [0.5, 1.2, 1.8];
        let mut sweeps = Vec::new();
        for c in CommandKind::ALL {
            // APPC diverges at 1.2 and 1.8, RC-MRAC at 1.8 only.
            sweeps.push(sweep(c, Method::Appc, &rho, &[false, true, true]));
            sweeps.push(sweep(c, Method::RcMrac, &rho, &[false, false, true]));
        }
        let pairs: Vec<(&Sweep, &Sweep)> = sweeps.chunks(2).map(|p| (&p[0], &p[1])).collect();
        let r = Reading::of("outward", &pairs).expect("pairs");
        assert!(r.complete() && r.reproduces());
        let step = r.commands[0];
        assert_eq!(
            (
                step.points,
                step.appc_unstable,
                step.rc_unstable,
                step.appc_only,
                step.outside_circle,
                step.appc_unstable_outside,
                step.smallest_unstable_rho
            ),
            (3, 2, 1, 1, 2, 2, Some(1.2))
        );
        assert!(
            r.text()
                .contains("step 2/3 (2 of 2 with ρ ≥ 1, from ρ = 1.200)"),
            "{}",
            r.text()
        );

        // Where RC-MRAC diverges too, no square is APPC's alone: not reproduced.
        sweeps[5] = sweep(
            CommandKind::Four,
            Method::RcMrac,
            &rho,
            &[false, true, true],
        );
        let pairs: Vec<(&Sweep, &Sweep)> = sweeps.chunks(2).map(|p| (&p[0], &p[1])).collect();
        assert!(!Reading::of("x", &pairs).expect("pairs").reproduces());

        // Without the four-harmonic command the reading is incomplete.
        let r = Reading::of("x", &pairs[..2]).expect("pairs");
        assert!(!r.complete() && !r.reproduces());
    }

    #[test]
    fn the_same_command_on_two_grids_adds_up_and_a_stable_reading_does_not_reproduce() {
        let a1 = sweep(CommandKind::Step, Method::Appc, &[0.5], &[false]);
        let r1 = sweep(CommandKind::Step, Method::RcMrac, &[0.5], &[false]);
        let a2 = sweep(CommandKind::Step, Method::Appc, &[1.4, 1.6], &[false, true]);
        let r2 = sweep(
            CommandKind::Step,
            Method::RcMrac,
            &[1.4, 1.6],
            &[false, false],
        );
        let r = Reading::of("two grids", &[(&a1, &r1), (&a2, &r2)]).expect("pairs");
        assert_eq!(r.commands.len(), 1);
        assert_eq!((r.commands[0].points, r.commands[0].appc_only), (3, 1));
        let r = Reading::of("inside", &[(&a1, &r1)]).expect("pairs");
        assert!(!r.commands[0].shows_empty_squares());
    }

    #[test]
    fn mismatched_sweeps_are_refused() {
        let a = sweep(CommandKind::Step, Method::Appc, &[0.5], &[false]);
        let r = sweep(CommandKind::Step, Method::RcMrac, &[0.6], &[false]);
        assert_eq!(Reading::of("x", &[(&a, &r)]), Err(ReadingError::OtherPoles));
        assert_eq!(Reading::of("x", &[(&r, &a)]), Err(ReadingError::NotAPair));
        let t = sweep(CommandKind::Two, Method::RcMrac, &[0.5], &[false]);
        assert_eq!(Reading::of("x", &[(&a, &t)]), Err(ReadingError::NotAPair));
    }
}
