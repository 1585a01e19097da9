"""The controller side of the contract: answers each measurement, compute-first or
send-ahead.

The controller connects as the service of a rig (``role = service``, ``timing`` stated),
waits for measurement ``k`` of the pinned plant and calls its law
``law(measurement) -> list of n_u inputs``:

- ``Timing.COMPUTE_FIRST`` (the default): the law gives ``u_k`` from ``y_k``, published as
  ``Actuation{seq k, reply_to k}``;
- ``Timing.SEND_AHEAD``: the law gives ``u_{k+1}`` from the data up to ``y_k`` (a law with
  a delay of one sample, as RCAC's (2.16) is), published as
  ``Actuation{seq k + 1, reply_to k}`` as soon as ``M_k`` is in; this is the timing a plant
  that latches its DAC at the sample clock (``deadline = 0``, ``at-sample``) requires. A
  sample that nothing was sent ahead for (the first one) is first answered with
  ``initial_input`` (zeros by default) as ``Actuation{seq k, reply_to k}``, as the Rust
  service answers it from its controller's initial state.

Each answer carries the echoed sample time, its publish time and the time the law took,
then the controller notifies the plant. A sample flagged ``INJECTED_STALL`` is
acknowledged (``STALL_ACK``) and not answered. It stops after the sample flagged
``LAST_SAMPLE``.

Use::

    ctl = Controller(rig, ChannelCounts.new(1, 1, 0, 1), period_ns=1_000_000)
    ctl.serve(lambda m: [-2.0 * m.y[0]])
"""

import math
import sys
import time

from . import timing_rules
from .contract import Actuation, Timing, actuation_status, measurement_flags
from .peer import NEW_PEER
from .ports import ContractInfo, Ports, Side, connect


def _now_ns() -> int:
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC)


class Controller:
    """The service side of one rig, compute-first or send-ahead; see the module docs."""

    def __init__(
        self,
        rig: str,
        counts,
        period_ns: int,
        peer_timeout_s: float = 30.0,
        node_name: str = "adaptive-rig-service",
        contract_version: "int | None" = None,
        verbose: bool = True,
        timing: int = Timing.COMPUTE_FIRST,
        initial_input=None,
    ):
        """Connects as the service of rig ``rig`` (raises ``ConnectError``) with ``timing``
        (``Timing.COMPUTE_FIRST`` or ``Timing.SEND_AHEAD``)."""
        if timing not in (Timing.COMPUTE_FIRST, Timing.SEND_AHEAD):
            raise ValueError(f"timing {timing}: the Python controller answers compute-first or send-ahead")
        self.counts = counts
        self.timing = timing
        self.initial_input = list(initial_input) if initial_input is not None else [0.0] * counts.n_u
        #: Send-ahead: the sample the latest answer was sent ahead for.
        self._sent_ahead_for = None
        own = ContractInfo(Side.SERVICE, counts, int(period_ns), timing=self.timing)
        if contract_version is not None:
            own.version = contract_version
        self.verbose = verbose
        self.ports: Ports = connect(
            rig,
            own,
            node_name,
            peer_timeout_s,
            listen=True,
            waiting_message=f"[python controller] waiting for the plant on rig '{rig}' ..." if verbose else None,
        )
        self.answered = 0
        self.stall_acks = 0
        self.new_plants = 0
        #: Response time of every answer, ns: its publish time minus the sample time.
        self.responses_ns = []

    def answer(self, m, u, status: int = actuation_status.OK, compute_ns: int = 0) -> None:
        """Publishes the actuation answering measurement ``m`` with input ``u`` and notifies."""
        n_u = self.counts.n_u
        a = Actuation.zeroed(self.counts)
        a.seq = timing_rules.answer_seq(m.seq, self.timing)
        a.reply_to = m.seq
        a.t_sample_ns = m.t_sample_ns
        a.compute_ns = compute_ns
        a.timing = int(self.timing)
        a.status = status
        a.u[:n_u] = [float(v) for v in u[:n_u]]
        a.t_publish_ns = _now_ns()
        self.ports.send(a)
        self.responses_ns.append(a.t_publish_ns - m.t_sample_ns)

    def _answer_now(self, m, u) -> None:
        """Send-ahead: answers sample ``m`` itself (nothing was sent ahead for it)."""
        a = Actuation.zeroed(self.counts)
        a.seq = m.seq
        a.reply_to = m.seq
        a.t_sample_ns = m.t_sample_ns
        a.timing = int(self.timing)
        a.u[: self.counts.n_u] = [float(v) for v in u[: self.counts.n_u]]
        a.t_publish_ns = _now_ns()
        self.ports.send(a)

    def response_percentiles(self, *ps) -> list:
        """The given percentiles (0-100) of the response times so far, ns (nearest rank)."""
        r = sorted(self.responses_ns)
        if not r:
            return [None for _ in ps]
        return [r[min(len(r) - 1, max(0, -(-p * len(r) // 100) - 1))] for p in ps]

    def acknowledge_stall(self, m) -> None:
        """Acknowledges a sample flagged ``INJECTED_STALL`` without answering it."""
        a = Actuation.zeroed(self.counts)
        a.seq = m.seq
        a.reply_to = m.seq
        a.t_sample_ns = m.t_sample_ns
        a.status = actuation_status.STALL_ACK
        a.t_publish_ns = _now_ns()
        self.ports.send(a)

    def measurements(self, idle_timeout_s: float = 30.0):
        """Yields the pinned plant's measurements as they arrive; ends after ``LAST_SAMPLE``
        or when none came for ``idle_timeout_s``."""
        last_seen = time.monotonic()
        while True:
            got = self.ports.receive()
            for origin, m in got:
                if origin == NEW_PEER:
                    self.new_plants += 1
                yield m
                if m.flags & measurement_flags.LAST_SAMPLE:
                    return
            if got:
                last_seen = time.monotonic()
            elif time.monotonic() - last_seen > idle_timeout_s:
                return
            else:
                self.ports.wait(0.01)

    def serve(self, law, idle_timeout_s: float = 30.0) -> int:
        """Answers every measurement with ``law(m)`` until the plant's last sample; returns
        how many were answered. A non-finite input is not sent (the plant holds)."""
        for m in self.measurements(idle_timeout_s):
            if m.flags & measurement_flags.INJECTED_STALL:
                self.acknowledge_stall(m)
                self.stall_acks += 1
                continue
            if timing_rules.answers_sample_itself(self.timing, self._sent_ahead_for == m.seq):
                self._answer_now(m, self.initial_input)
            t0 = _now_ns()
            u = list(law(m))
            dt = _now_ns() - t0
            if len(u) != self.counts.n_u or not all(math.isfinite(v) for v in u):
                print(f"[python controller] seq {m.seq}: law gave {u}, not sent", file=sys.stderr)
                continue
            self.answer(m, u, compute_ns=dt)
            if self.timing == Timing.SEND_AHEAD:
                self._sent_ahead_for = timing_rules.answer_seq(m.seq, self.timing)
            self.answered += 1
        return self.answered

    def close(self) -> None:
        """Releases the ports."""
        self.ports.close()
