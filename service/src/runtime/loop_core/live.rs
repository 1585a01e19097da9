//! What the loop gives the live view ([`super::super::live_tap`]).

use super::super::live_tap::{LiveItem, LiveSample, LiveState};
use super::LoopCore;
use ipc_types::Measurement;
use ipc_types::telemetry::{MAX_TUNABLES, live_flags};

impl LoopCore {
    /// The live view's state bits now.
    pub fn live_flags(&self) -> u32 {
        let mut f = 0;
        let mut set = |on: bool, bit: u32| {
            if on {
                f |= bit;
            }
        };
        set(
            self.deadline.in_safe_state() || self.operator_safe,
            live_flags::SAFE_STATE,
        );
        set(self.operator_safe, live_flags::OPERATOR_SAFE_STATE);
        set(self.adaptation_frozen, live_flags::ADAPTATION_FROZEN);
        set(
            self.session.last_seq().is_some()
                && self.session.session_cycle() <= self.open_loop_cycles,
            live_flags::OPEN_LOOP,
        );
        set(self.session.is_silent(), live_flags::PLANT_SILENT);
        set(self.lockstep, live_flags::LOCKSTEP);
        set(self.operator.is_some(), live_flags::COMMANDS_ENABLED);
        f
    }

    /// `‖θ‖` of the controller's `theta` block ([`control::Controller::learned`]); NaN
    /// without one.
    fn theta_norm(&self) -> f64 {
        let mut norm = f64::NAN;
        self.controller.learned(&mut |name, values| {
            if name == "theta" {
                norm = values.iter().map(|v| v * v).sum::<f64>().sqrt();
            }
        });
        norm
    }

    /// Queues sample `m` with the input given for it and, when due, the loop's state.
    pub(super) fn push_live_sample(
        &mut self,
        m: &Measurement,
        u: &[f64; ipc_types::MAX_U],
        status: u32,
    ) {
        self.lockstep = m.flags & ipc_types::measurement_flags::LOCKSTEP != 0;
        let Some(live) = self.live.as_mut() else {
            return;
        };
        let point = live.next_is_point();
        let state_due = live.state_due();
        let theta_norm = if point { self.theta_norm() } else { f64::NAN };
        let item = LiveItem::Sample(LiveSample {
            seq: m.seq,
            t_sample_ns: m.t_sample_ns,
            status,
            flags: m.flags,
            point,
            theta_norm,
            z: m.z,
            u: *u,
        });
        self.push_live(item);
        if state_due {
            self.push_live_state();
        }
    }

    /// Queues the loop's state now.
    pub(super) fn push_live_state(&mut self) {
        if self.live.is_none() {
            return;
        }
        let mut tunables = [f64::NAN; MAX_TUNABLES];
        for (i, t) in tunables.iter_mut().enumerate() {
            *t = self.controller.tunable(i).unwrap_or(f64::NAN);
        }
        let item = LiveItem::State(LiveState {
            stats: self.stats,
            flags: self.live_flags(),
            last_seq: self.session.last_seq().unwrap_or(0),
            safe_state: self.safe_state_at_end(),
            tunables,
        });
        self.push_live(item);
    }

    fn push_live(&mut self, item: LiveItem) {
        if let Some(live) = self.live.as_mut()
            && !live.push(item)
        {
            self.stats.telemetry_dropped += 1;
        }
    }
}
