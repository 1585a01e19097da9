//! How [`LoopCore`] answers a sample under each `service.timing`: compute-first, answer-first
//! and send-ahead, the ahead controller's advance and plan, publishing through the
//! [`Outbox`], and the bookkeeping that closes a cycle.

use super::{Mode, Published, header, sanitize, step_input};
use crate::runtime::deadline::{Answer, SafeStateChange};
use crate::runtime::reset::ResetCause;
use crate::runtime::{CycleDecision, LoopCore, LoopEvent, Outbox};
use crate::telemetry::CycleTiming;
use control::controller::StepInput;
use ipc_types::clock::monotonic_ns;
use ipc_types::{
    MAX_PLAN, MAX_U, Measurement, Timing, actuation_status, measurement_flags, timing_rules,
};

impl LoopCore {
    /// An ahead controller takes sample `k` in with `applied`, adapting when `adapt`, and
    /// the prepared answer becomes its ready input and, after an adapting step, its plan.
    /// Returns the time it took.
    pub(super) fn advance(&mut self, input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u64 {
        let n_u = self.counts.n_u as usize;
        let t0 = monotonic_ns();
        let Some(ahead) = self.controller.ahead() else {
            return 0;
        };
        let s = ahead.advance(input, applied, adapt);
        let _ = ahead.ready(&mut self.prepared.u[..n_u]);
        // A sample taken in without adaptation (catching up, the safe state) leaves the
        // plan to be made when an answer goes out ([`LoopCore::fill`]).
        self.plan_pending = true;
        if adapt {
            self.make_plan();
        }
        let compute_ns = monotonic_ns().saturating_sub(t0);
        let wire = crate::wire::actuation_status(s);
        self.prepared.status = wire;
        self.prepared.compute_ns = compute_ns;
        sanitize(&mut self.prepared.u[..n_u], &self.safe_input);
        if adapt {
            self.count_status(wire);
        }
        compute_ns
    }

    /// The prepared answer's plan from the controller, up to its first non-finite entry
    /// (the runtime never sends a NaN).
    fn make_plan(&mut self) {
        self.plan_pending = false;
        let n_u = self.counts.n_u as usize;
        let rows = match self.controller.ahead() {
            Some(ahead) if self.plan_length > 0 => {
                let len = (self.plan_length * n_u).min(self.plan_rows.len());
                ahead.plan(&mut self.plan_rows[..len])
            }
            _ => 0,
        };
        let mut len = 0;
        for (j, row) in self
            .plan_rows
            .chunks_exact(n_u.max(1))
            .take(rows)
            .enumerate()
        {
            if n_u == 0 || !row.iter().all(|v| v.is_finite()) {
                break;
            }
            if let Some(dst) = self.prepared.plan.get_mut(j) {
                dst[..n_u].copy_from_slice(row);
                len = j + 1;
            }
        }
        self.prepared.plan_len = len as u32;
    }

    /// An ahead controller takes the sample of an answer of `mode` in: not a rejected one
    /// (the controller never sees it), without adaptation in the safe state and the
    /// open-loop phase. Returns the time it took.
    fn take_in(&mut self, mode: Mode, input: &StepInput<'_>, applied: &[f64]) -> u64 {
        match mode {
            Mode::Rejected => 0,
            Mode::Safe(_) => self.advance(input, applied, false),
            Mode::Control => self.advance(input, applied, true),
        }
    }

    /// Counts a controller step and its status bits.
    fn count_status(&mut self, wire: u32) {
        self.stats.controller_steps += 1;
        if wire & actuation_status::SATURATED != 0 {
            self.stats.saturated_cycles += 1;
        }
        if wire & actuation_status::CONTROLLER_FAULT != 0 {
            self.stats.controller_faults += 1;
        }
        if wire & actuation_status::FALLBACK != 0 {
            self.stats.fallback_cycles += 1;
        }
    }

    /// Publishes the outgoing actuation through `out` and records it.
    pub(super) fn publish(&mut self, out: &mut dyn Outbox) -> (bool, u64) {
        let (ok, t_pub) = out.publish(&mut self.outgoing);
        if let Some(r) = self.recorder.as_mut() {
            r.publish(&self.outgoing, ok, t_pub);
        }
        (ok, t_pub)
    }

    /// Publishes the outgoing actuation as an input: counted, remembered, held.
    fn send(&mut self, out: &mut dyn Outbox, main: bool) -> (bool, u64) {
        let (ok, t_pub) = self.publish(out);
        if ok {
            self.sent.record(&self.outgoing);
            self.last_u = self.outgoing.u;
            if main {
                self.stats.published += 1;
            } else {
                self.stats.published_extra += 1;
            }
        } else {
            self.stats.publish_failures += 1;
        }
        (ok, t_pub)
    }

    /// Writes the input of `mode` for a sample into the outgoing actuation: the held input
    /// (rejected measurement), the safe input (its plan: the safe input again), or the
    /// prepared answer (its plan too).
    fn fill(&mut self, mode: Mode, status: u32) {
        if mode == Mode::Control && self.plan_pending {
            self.make_plan();
        }
        let a = &mut self.outgoing;
        a.plan_len = 0;
        a.compute_ns = 0;
        match mode {
            Mode::Rejected => {
                a.u = self.last_u;
                a.status = status | actuation_status::MEASUREMENT_REJECTED;
            }
            Mode::Safe(bit) => {
                a.u = self.safe_input;
                a.status = status | bit;
                for row in a.plan.iter_mut().take(self.plan_length) {
                    *row = self.safe_input;
                }
                a.plan_len = self.plan_length.min(MAX_PLAN) as u32;
            }
            Mode::Control => {
                let p = &self.prepared;
                a.u = p.u;
                a.status = status | p.status;
                a.compute_ns = p.compute_ns;
                let len = (p.plan_len as usize).min(MAX_PLAN);
                a.plan[..len].copy_from_slice(&p.plan[..len]);
                a.plan_len = len as u32;
            }
        }
    }

    /// Handles measurement `m` received at `t_recv_ns`: the session and gate, the answer by
    /// the loop's timing (published through `out`), then the deadline policy, histograms,
    /// log and checkpoint of the cycle.
    pub fn handle(
        &mut self,
        m: &Measurement,
        t_recv_ns: u64,
        out: &mut dyn Outbox,
    ) -> CycleDecision {
        if let Some(r) = self.recorder.as_mut() {
            r.handle(m, t_recv_ns);
        }
        let last_sample = m.flags & measurement_flags::LAST_SAMPLE != 0;
        if Self::injected_stall(m) {
            self.take_in_stalled(m, out);
            return CycleDecision {
                compute_ns: 0,
                last_sample,
                answer: false,
            };
        }
        let previous_t_sample = self.session.last_sample_time_ns();
        let Some(lost) = self.admit(m) else {
            return CycleDecision {
                compute_ns: 0,
                last_sample: false,
                answer: false,
            };
        };
        self.timestamp_ok =
            m.t_sample_ns != 0 && m.t_sample_ns <= t_recv_ns && m.t_sample_ns >= previous_t_sample;
        if !self.timestamp_ok {
            self.stats.impossible_timestamps += 1;
        }
        self.check_u_applied(m);
        self.count_past_startup(m, lost);
        let cycle = self.session.connection_cycle();
        let flagged = m.flags & measurement_flags::PREVIOUS_ACTUATION_MISSED != 0;
        let covered = m.flags & measurement_flags::PLAN_APPLIED != 0;
        self.deadline.on_sample(flagged, covered, cycle);
        self.sync_stats();
        let jitter = self
            .session
            .answered(t_recv_ns)
            .map(|dt| dt.abs_diff(self.period_ns));

        let status = if self.deadline.in_grace(cycle) {
            actuation_status::STARTING
        } else {
            actuation_status::OK
        };
        let input = step_input(m, lost);
        let mode = if !self.admissible(m) {
            Mode::Rejected
        } else if self.deadline.in_safe_state() || self.operator_safe {
            self.stats.safe_state_cycles += 1;
            Mode::Safe(actuation_status::SAFE_STATE)
        } else if self.session.session_cycle() <= self.open_loop_cycles {
            Mode::Safe(actuation_status::OPEN_LOOP)
        } else {
            Mode::Control
        };
        let answer = match self.timing {
            Timing::ComputeFirst => self.compute_first(m, &input, mode, status, out),
            Timing::AnswerFirst => self.answer_first(m, &input, mode, status, out),
            Timing::SendAhead => self.send_ahead(m, &input, mode, status, out),
        };
        if mode != Mode::Rejected {
            self.accumulate_z(m);
        }
        let n_u = self.counts.n_u as usize;
        if mode == Mode::Control && self.outgoing.u[..n_u] != self.safe_input[..n_u] {
            self.stats.inputs_off_safe += 1;
        }
        self.pending_jitter = jitter;
        self.finish_cycle(m, t_recv_ns, answer);
        CycleDecision {
            compute_ns: answer.compute_ns,
            last_sample,
            answer: true,
        }
    }

    /// Compute-first: `u_k` from the step on `y_k` (or held, or safe), then published.
    fn compute_first(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        let seq = timing_rules::answer_seq(m.seq, self.timing);
        header(&mut self.outgoing, seq, m, self.counts, self.timing);
        let mut compute_ns = 0;
        match mode {
            Mode::Rejected | Mode::Safe(_) => {
                self.fill(mode, status);
                if mode != Mode::Rejected {
                    let t0 = monotonic_ns();
                    self.controller.observe(input, &mut self.scratch_u[..n_u]);
                    compute_ns = monotonic_ns().saturating_sub(t0);
                }
            }
            Mode::Control => {
                let a = &mut self.outgoing;
                a.u = [0.0; MAX_U];
                a.plan_len = 0;
                let t0 = monotonic_ns();
                let s = self.controller.step(input, &mut a.u[..n_u]);
                compute_ns = monotonic_ns().saturating_sub(t0);
                let wire = crate::wire::actuation_status(s);
                // The controller promises finite output; the runtime still never sends a NaN.
                sanitize(&mut a.u[..n_u], &self.safe_input);
                a.status = status | wire;
                self.count_status(wire);
            }
        }
        self.outgoing.compute_ns = compute_ns;
        let (ok, t_pub) = self.send(out, true);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: self.outgoing.status,
        }
    }

    /// Answer-first: the prepared `u_k` published at once, then `advance(k)` prepares
    /// `u_{k+1}`.
    fn answer_first(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        let seq = timing_rules::answer_seq(m.seq, self.timing);
        header(&mut self.outgoing, seq, m, self.counts, self.timing);
        self.fill(mode, status);
        let (ok, t_pub) = self.send(out, true);
        let answered = self.outgoing.status;
        let applied = self.outgoing.u;
        let compute_ns = self.take_in(mode, input, &applied[..n_u]);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: answered,
        }
    }

    /// Send-ahead: sample `k` answered at once when nothing went ahead for it, then
    /// `advance(k)` and the answer for `k + 1` published.
    fn send_ahead(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        if timing_rules::answers_sample_itself(self.timing, self.sent.contains(m.seq)) {
            header(&mut self.outgoing, m.seq, m, self.counts, self.timing);
            self.fill(mode, status);
            let _ = self.send(out, false);
        }
        let mut applied = [0.0; MAX_U];
        self.sent
            .expected_input(m.seq, &self.safe_input[..n_u], &mut applied[..n_u]);
        let compute_ns = self.take_in(mode, input, &applied[..n_u]);
        header(
            &mut self.outgoing,
            timing_rules::answer_seq(m.seq, self.timing),
            m,
            self.counts,
            self.timing,
        );
        self.fill(mode, status);
        self.outgoing.compute_ns = compute_ns;
        let (ok, t_pub) = self.send(out, true);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: self.outgoing.status,
        }
    }

    pub(super) fn accumulate_z(&mut self, m: &Measurement) {
        self.tones
            .record(self.session.session_cycle(), m.seq, m.z());
        if let Some(e) = self.controller.model_following_error() {
            self.following.record(m.seq, e);
        }
        self.force.record(m.seq, m.y(), m.r());
        self.z_count += 1;
        let settled = self.z_count > self.rms_settle_cycles;
        if settled {
            self.z_count_settled += 1;
        }
        for (i, z) in m.z().iter().enumerate() {
            self.z_sum_sq[i] += z * z;
            if settled {
                self.z_sum_sq_settled[i] += z * z;
            }
        }
    }

    /// Completes the cycle of sample `m` after its answer: deadline policy, histograms, log.
    fn finish_cycle(&mut self, m: &Measurement, t_recv_ns: u64, answer: Published) {
        let response_ns = answer.t_pub.saturating_sub(m.t_sample_ns);
        let cycle = self.session.connection_cycle();
        // The plant's deadline for this answer: with send-ahead it is the next sample's.
        let deadline_ns = timing_rules::answer_deadline_ns(
            m.flags & measurement_flags::LOCKSTEP != 0,
            m.deadline_ns,
            m.period_ns,
            self.timing,
        );
        let verdict = self.deadline.on_answer(Answer {
            cycle,
            open_loop: self.session.session_cycle() <= self.open_loop_cycles,
            published: answer.ok,
            timestamp_ok: self.timestamp_ok,
            response_ns,
            deadline_ns,
        });
        self.sync_stats();
        match verdict.change {
            SafeStateChange::Unchanged => {}
            SafeStateChange::Entered { misses } => {
                self.safe_since_seq = m.seq;
                self.event(LoopEvent::SafeStateEntered { seq: m.seq, misses });
            }
            SafeStateChange::Left => {
                self.reset_controller_if(ResetCause::LeftSafeState);
                self.event(LoopEvent::SafeStateLeft { seq: m.seq });
            }
        }
        let jitter = self.pending_jitter.take();
        // The first sample of a connection waited for the connection, not for the loop: it
        // would only pollute the latency figures; so would an impossible sample time.
        if cycle > 1 && self.timestamp_ok {
            self.telemetry.record(&CycleTiming {
                seq: m.seq,
                wakeup_ns: t_recv_ns.saturating_sub(m.t_sample_ns),
                compute_ns: answer.compute_ns,
                response_ns,
                period_jitter_ns: jitter,
            });
        }
        // The row of sample k holds the input the service gave for sample k.
        let (u, status) = match self.sent.input_for(m.seq) {
            Some((u, status)) => (*u, status),
            None => (self.last_u, answer.status),
        };
        self.push_live_sample(m, &u, status);
        if let Some(log) = self.log.as_mut() {
            let r = &mut self.record;
            r.seq = m.seq;
            r.t_sample_ns = m.t_sample_ns;
            r.status = status;
            r.flags = m.flags;
            r.y = m.y;
            r.z = m.z;
            r.u = u;
            let n = self.controller.internals(&mut self.internals);
            r.internals[..n].copy_from_slice(&self.internals[..n]);
            log.push(r);
        }
        self.maybe_checkpoint(m.seq);
        if m.flags & measurement_flags::LAST_SAMPLE != 0 {
            self.event(LoopEvent::PlantEnded { seq: m.seq });
        }
    }
}
