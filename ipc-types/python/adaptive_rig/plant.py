"""The plant side of the contract: the clock master (a small version of plant-proxy's runtime).

At sample ``k`` the plant publishes ``Measurement{seq k}`` (``y_k``, ``z_k``, ``r_k``, the input
it applied for ``k - 1`` with ``U_APPLIED``, ``LOCKSTEP`` in lockstep,
``PREVIOUS_ACTUATION_MISSED`` / ``PLAN_APPLIED`` when the previous input was a miss,
``PLANT_SAFE_OUTPUT`` while the watchdog holds the safe input, ``LAST_SAMPLE`` on the last
one), then takes the input for ``k``:

- **lockstep**: it waits (on the service's event, up to ``lockstep_timeout_s``) until the
  service answered ``k``: a valid actuation with ``reply_to >= k`` (or ``seq - lead``), or a
  ``STALL_ACK`` of ``k``. The input is the actuation with ``seq = k`` if held, else a miss.
- **real time**: samples are paced on ``CLOCK_MONOTONIC`` at ``t_0 + kT``; the input is the
  actuation with ``seq = k`` held at ``t_k + dT`` (``deadline`` = d); with ``d = 0`` it is
  decided at ``t_k`` before the sample is published. Otherwise a miss.

A miss applies the late policy (hold, safe or plan; :mod:`adaptive_rig.book`);
``watchdog_periods`` consecutive misses put the plant into its safe input until a valid
actuation comes; a lockstep plant gives up (``PlantGaveUp``) when no service answered for
``peer_timeout_s`` after the watchdog tripped. Actuations from any publisher but the pinned
service are refused and counted.

Use::

    plant = Plant(rig, ChannelCounts.new(1, 1, 0, 1), period_ns=1_000_000)
    for k in range(steps):
        u = plant.step(y=[x], z=[x], last=(k == steps - 1))
        x = a * x + b * u[0]
    print(plant.report)
"""

import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from . import book as bk
from . import timing_rules
from .contract import Measurement, measurement_flags
from .peer import NEW_PEER
from .ports import Applies, ContractInfo, Ports, Side, cleanup_dead_nodes, connect


@dataclass
class PlantReport:
    """The counters of a plant run (the names of plant-proxy's report)."""

    samples: int = 0
    actuations_applied: int = 0
    misses: int = 0
    plan_entries_applied: int = 0
    misses_held_or_safe: int = 0
    late_discarded: int = 0
    invalid_discarded: int = 0
    ahead_dropped: int = 0
    foreign_discarded: int = 0
    new_services: int = 0
    stall_acks: int = 0
    watchdog_trips: int = 0
    watchdog_recoveries: int = 0
    safe_output_samples: int = 0
    wall_time_s: float = 0.0
    round_trips_ns: list = field(default_factory=list, repr=False)

    def round_trip(self) -> "dict | None":
        """Percentiles (µs) of the round trip from publishing ``M_k`` to holding the
        service's answer to it, over the lockstep samples; ``None`` when none was timed.
        The same figures as the Rust plant side's ``round_trip``."""
        if not self.round_trips_ns:
            return None
        us = np.asarray(self.round_trips_ns, dtype=float) * 1e-3
        return {
            "samples": int(us.size),
            "p50_us": float(np.percentile(us, 50)),
            "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()),
        }

    def as_dict(self) -> dict:
        """The counters as a dict (for JSON), with ``round_trip``."""
        d = asdict(self)
        del d["round_trips_ns"]
        d["round_trip"] = self.round_trip()
        return d


class PlantGaveUp(Exception):
    """Lockstep: no service answered for ``peer_timeout_s`` after the watchdog tripped."""


def _now_ns() -> int:
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC)


class Plant:
    """The plant side of one rig; see the module docs."""

    def __init__(
        self,
        rig: str,
        counts,
        period_ns: int,
        mode: str = "lockstep",
        deadline: float = 0.5,
        late_policy: str = "hold",
        plan_fallback: str = "hold",
        safe_input=None,
        watchdog_periods: int = 100,
        lockstep_timeout_s: float = 1.0,
        peer_timeout_s: float = 30.0,
        node_name: str = "adaptive-rig-plant",
        contract_version: "int | None" = None,
        verbose: bool = True,
    ):
        """Connects to the service of rig ``rig`` (raises ``ConnectError``).

        ``mode`` is ``"lockstep"`` or ``"real-time"``; ``deadline`` the application instant
        as a fraction of the period (real time); ``safe_input`` one value per input (zeros);
        ``contract_version`` overrides the stated version (for tests of the refusal)."""
        if mode not in ("lockstep", "real-time"):
            raise ValueError(f"mode '{mode}' is not lockstep or real-time")
        if not 0.0 <= deadline <= 1.0:
            raise ValueError(f"deadline {deadline} is not in [0, 1]")
        self.counts = counts
        self.n_u = counts.n_u
        self.period_ns = int(period_ns)
        self.mode = mode
        self.safe_input = list(safe_input) if safe_input is not None else [0.0] * self.n_u
        if len(self.safe_input) != self.n_u:
            raise ValueError(f"safe_input needs {self.n_u} values")
        self.watchdog_periods = watchdog_periods
        self.lockstep_timeout_s = lockstep_timeout_s
        self.peer_timeout_s = peer_timeout_s
        self.verbose = verbose
        self.applies = timing_rules.applies(mode == "lockstep", deadline)
        self.deadline_ns = timing_rules.deadline_offset_ns(mode == "lockstep", deadline, self.period_ns)
        own = ContractInfo(Side.PLANT, counts, self.period_ns, applies=self.applies)
        if contract_version is not None:
            own.version = contract_version
        self.ports: Ports = connect(
            rig,
            own,
            node_name,
            peer_timeout_s,
            listen=(mode == "lockstep"),
            waiting_message=f"[python plant] rig '{rig}': waiting for the service ..." if verbose else None,
        )
        self.book = bk.ActuationBook(self.n_u, late_policy, plan_fallback)
        self.report = PlantReport()
        self.u_applied = list(self.safe_input)
        self.k = 0
        self._misses = 0
        self._tripped = False
        self._tripped_at = None
        self._previous = "answered"
        self._t0 = _now_ns() + 2 * max(self.period_ns, 1_000_000)
        self._wall = time.monotonic()
        self.last_status = None

    def _log(self, msg: str) -> None:
        print(f"[python plant] {msg}", file=sys.stderr, flush=True)

    def _drain(self, k: int) -> None:
        for origin, a in self.ports.receive():
            if origin == NEW_PEER:
                self.report.new_services += 1
                self.book.clear()
            r = self.book.offer(a, k)
            if r == bk.KEPT_DROPPING:
                self.report.ahead_dropped += 1
            elif r == bk.LATE:
                self.report.late_discarded += 1
            elif r == bk.INVALID:
                self.report.invalid_discarded += 1
            elif r == bk.STALL_ACK:
                self.report.stall_acks += 1
        self.report.foreign_discarded = self.ports.foreign_samples

    def step(self, y, z=(), r=(), last: bool = False) -> list:
        """Publishes sample ``k`` (``y``, ``z``, ``r``) and returns the input applied for it.

        ``last`` marks the last sample (``LAST_SAMPLE``). Raises ``PlantGaveUp`` in lockstep
        when the service is gone (see the module docs)."""
        k = self.k
        n_y, n_z, n_r, n_u = self.counts.as_tuple()
        if len(y) != n_y or len(z) != n_z or len(r) != n_r:
            raise ValueError(f"sample {k}: expected {n_y} y, {n_z} z, {n_r} r values")
        flags = measurement_flags.LOCKSTEP if self.mode == "lockstep" else 0
        flags |= timing_rules.report_flags(self._previous)
        if last:
            flags |= measurement_flags.LAST_SAMPLE
        decision = None
        if self.mode == "real-time":
            t_k = self._t0 + k * self.period_ns
            while _now_ns() < t_k:
                time.sleep(max((t_k - _now_ns()) * 1e-9, 0.0))
            if self.applies == Applies.AT_SAMPLE:
                self._drain(k)
                decision = self.book.decide(k)
        else:
            t_k = _now_ns()
        m = Measurement.zeroed(self.counts)
        m.seq = k
        m.t_sample_ns = t_k
        m.period_ns = self.period_ns
        m.deadline_ns = self.deadline_ns
        m.flags = flags | measurement_flags.U_APPLIED
        m.y[:n_y] = [float(v) for v in y]
        m.z[:n_z] = [float(v) for v in z]
        m.r[:n_r] = [float(v) for v in r]
        m.u_applied[:n_u] = self.u_applied[:n_u]
        t_sent = _now_ns()
        self.ports.send(m)
        self.report.samples += 1

        if decision is None and self.mode == "real-time":
            t_d = timing_rules.application_instant(t_k, self.deadline_ns)
            while _now_ns() < t_d:
                time.sleep(max((t_d - _now_ns()) * 1e-9, 0.0))
            self._drain(k)
            decision = self.book.decide(k)
        elif decision is None:
            until = time.monotonic() + self.lockstep_timeout_s
            while True:
                self._drain(k)
                if self.book.answers(k):
                    self.report.round_trips_ns.append(_now_ns() - t_sent)
                    break
                left = until - time.monotonic()
                if left <= 0:
                    break
                self.ports.wait(min(max(left, 0.001), 0.01))
            decision = self.book.decide(k)
        self._apply(k, decision)
        self.k += 1
        self.report.wall_time_s = time.monotonic() - self._wall
        return list(self.u_applied[:n_u])

    def _apply(self, k: int, d: "bk.Decision") -> None:
        rep = self.report
        if not d.is_miss:
            rep.actuations_applied += 1
            self._misses = 0
            self._tripped_at = None
            if self._tripped:
                self._tripped = False
                rep.watchdog_recoveries += 1
                self._log(f"valid actuation again at seq {k}: leaving the safe output")
            self.last_status = d.status
        else:
            rep.misses += 1
            self._misses += 1
            self.last_status = None
            if timing_rules.watchdog_trips(self._tripped, self._misses, self.watchdog_periods):
                self._tripped = True
                rep.watchdog_trips += 1
                self._log(
                    f"WATCHDOG: no valid actuation for {self._misses} periods (last at seq "
                    f"{max(k - self._misses, 0)}); applying the safe output"
                )
                cleanup_dead_nodes()
                if self.mode == "lockstep":
                    self._tripped_at = time.monotonic()
        # The watchdog's safe output overrides a plan as it overrides the rest.
        applied = timing_rules.applied(d.miss_input, self._tripped)
        self._previous = applied
        if applied in ("answered", "plan"):
            self.u_applied = list(d.u[: self.n_u])
        elif applied in ("safe", "watchdog-safe"):
            self.u_applied = list(self.safe_input)
        if applied == "plan":
            rep.plan_entries_applied += 1
        elif applied != "answered":
            rep.misses_held_or_safe += 1
        if d.is_miss and self._tripped_at is not None and time.monotonic() - self._tripped_at >= self.peer_timeout_s:
            raise PlantGaveUp(
                f"WATCHDOG: giving up in lockstep at seq {k}: no valid actuation for "
                f"{self._misses} samples, and none for {self.peer_timeout_s:.1f} s since the "
                "watchdog tripped"
            )
        if applied == "watchdog-safe":
            rep.safe_output_samples += 1

    def close(self) -> None:
        """Releases the ports."""
        self.ports.close()

