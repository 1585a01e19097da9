//! What a fault does to what the controller learned.
//!
//! The loop can call `Controller::reset` (back to the initial state: for RCAC θ = 0,
//! P = P₀, ‖θ‖ drops to 0) at three moments, each a [`ResetCause`]:
//!
//! | cause                                    | kind of fault | reset when                       |
//! | ---------------------------------------- | ------------- | -------------------------------- |
//! | [`ResetCause::LeftSafeState`]            | timing        | `on_timing_fault = ResetController` |
//! | [`ResetCause::StallResumed`]             | timing        | `on_timing_fault = ResetController` |
//! | [`ResetCause::NewPlantSession`]          | new plant     | `reset_on_resume` (else only the data history) |
//!
//! The safe state is entered only by deadline misses (see [`super::deadline`]) and a stall
//! is a silence after which the plant's sequence continues (see [`super::session`]):
//! neither is the controller's fault, so with the default
//! [`TimingFaultReset::KeepLearned`] the controller keeps its parameters, covariance and
//! regressor across them (it observed the plant during the safe state, and after a stall
//! it is told how many samples were lost). [`TimingFaultReset::ResetController`] resets
//! it on leaving the safe state and on a resumed stall.
//!
//! A new plant session (another publisher, a sequence restarted after silence, a
//! consistent new numbering: a restarted or replaced plant process) is not the
//! controller's fault either, and the structure it controls is normally the same one: by
//! default (`reset-on-resume = false`) the controller keeps what it learned (θ, P) and
//! forgets only its data history (`Controller::restart_data`: regressor, filters, held
//! input), which belonged to the old stream. `reset-on-resume = true` resets it instead,
//! for a rig where a new session may mean another structure. A refused sample (a
//! duplicate, a backward number, an unexplained jump) never reaches the controller and
//! resets nothing; nor does a controller fault (the `CONTROLLER_FAULT` status bit), which
//! is counted.

pub use crate::config::TimingFaultReset;

/// A moment at which the loop may reset the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResetCause {
    /// The safe state was left after enough on-time answers.
    LeftSafeState,
    /// Samples came back after silence and the sequence continued: a stall.
    StallResumed,
    /// The sequence number did not advance: a new plant session.
    NewPlantSession,
}

/// The table of the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControllerResetPolicy {
    /// What a timing fault does.
    pub on_timing_fault: TimingFaultReset,
    /// `service.reset-on-resume`: reset at a new plant session; otherwise a new session
    /// only restarts the controller's data history.
    pub reset_on_resume: bool,
}

impl ControllerResetPolicy {
    /// True when `cause` resets the controller.
    pub fn resets(&self, cause: ResetCause) -> bool {
        let timing = self.on_timing_fault == TimingFaultReset::ResetController;
        match cause {
            ResetCause::LeftSafeState => timing,
            ResetCause::StallResumed => timing,
            ResetCause::NewPlantSession => self.reset_on_resume,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ResetCause::*;
    use TimingFaultReset::*;
    use serde::Deserialize;

    #[test]
    fn nothing_resets_the_controller_by_default() {
        let p = ControllerResetPolicy {
            on_timing_fault: TimingFaultReset::default(),
            reset_on_resume: false,
        };
        assert_eq!(
            [LeftSafeState, StallResumed, NewPlantSession].map(|c| p.resets(c)),
            [false, false, false]
        );
    }

    #[test]
    fn the_reset_decisions_follow_the_table() {
        #[rustfmt::skip]
        let table = [
            // on timing fault, reset-on-resume: left safe state, stall resumed, new session
            (KeepLearned,     true,  [false, false, true]),
            (KeepLearned,     false, [false, false, false]),
            (ResetController, true,  [true,  true,  true]),
            (ResetController, false, [true,  true,  false]),
        ];
        for (on_timing_fault, reset_on_resume, expected) in table {
            let p = ControllerResetPolicy {
                on_timing_fault,
                reset_on_resume,
            };
            assert_eq!(
                [LeftSafeState, StallResumed, NewPlantSession].map(|c| p.resets(c)),
                expected,
                "{p:?}"
            );
        }
    }

    #[test]
    fn the_configuration_values_are_kebab_case() {
        #[derive(Deserialize)]
        struct Doc {
            v: TimingFaultReset,
        }
        let parse = |s: &str| toml::from_str::<Doc>(&format!("v = \"{s}\"")).map(|d| d.v);
        assert_eq!(parse("keep-learned").unwrap(), KeepLearned);
        assert_eq!(parse("reset-controller").unwrap(), ResetController);
        assert!(parse("reset").is_err());
    }
}
