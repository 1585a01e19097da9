"""The rules of the timing protocol, as pure functions: the Python statement of
``ipc_types::timing_rules`` (``ipc-types/src/timing_rules.rs``, where each rule is defined and
documented, with the equations of ``docs/timing-protocol.md``).

The names and results are those of the Rust functions (enum variants as lower-case strings,
``None`` for Rust's ``None``); both implementations are run against the one file of test
vectors, ``ipc-types/tests/vectors/timing.json``, so a rule changed on one side only fails a
test. The book (:mod:`adaptive_rig.book`), the plant (:mod:`adaptive_rig.plant`) and the
controller (:mod:`adaptive_rig.controller`) call these instead of restating them.
"""

import math

from .contract import CONTRACT_VERSION, MAX_PLAN, MAX_U, Timing, actuation_status, measurement_flags

U64 = (1 << 64) - 1

# ---- when the plant applies an input ----


def applies(lockstep: bool, deadline_fraction: float) -> str:
    """``"lockstep"``, ``"at-sample"`` (real time, ``d = 0``) or ``"at-deadline"``."""
    if lockstep:
        return "lockstep"
    return "at-sample" if deadline_fraction == 0.0 else "at-deadline"


def deadline_offset_ns(lockstep: bool, deadline_fraction: float, period_ns: int) -> int:
    """``D = d T`` ns, truncated, in real time; 0 in lockstep."""
    return 0 if lockstep else int(deadline_fraction * float(period_ns))


def application_instant(t_sample_ns: int, deadline_offset: int) -> int:
    """``t_k + D``, saturating at the ``u64`` range."""
    return min(t_sample_ns + deadline_offset, U64)


def timings_meet(plant_applies: str, timing: int) -> bool:
    """A plant applying at the sample instant needs a service that sends ahead."""
    return plant_applies != "at-sample" or timing == Timing.SEND_AHEAD


# ---- what the service answers, and when it is late ----


def _lead(timing: int) -> int:
    t = Timing.from_wire(timing)
    return t.lead if t is not None else 0


def answer_seq(k: int, timing: int) -> int:
    """The sample of the main answer to measurement ``k``: ``k + lead``, wrapping."""
    return (k + _lead(timing)) & U64


def answers_sample_itself(timing: int, sent_ahead_for_k: bool) -> bool:
    """Send-ahead also answers ``k`` itself when nothing went ahead for it."""
    return timing == Timing.SEND_AHEAD and not sent_ahead_for_k


def answer_deadline_ns(lockstep: bool, deadline_ns: int, period_ns: int, timing: int) -> int:
    """``D_k + lead T`` (saturating), 0 in lockstep."""
    return 0 if lockstep else min(deadline_ns + min(_lead(timing) * period_ns, U64), U64)


def answer_late(timestamp_ok: bool, deadline_ns: int, response_ns: int) -> bool:
    """Late: a deadline, a possible sample time, and a response past the deadline."""
    return timestamp_ok and deadline_ns > 0 and response_ns > deadline_ns


# ---- what an actuation carries, and what it answers ----


def plan_rows(plan_len: int) -> int:
    """``min(plan_len, MAX_PLAN)``."""
    return min(plan_len, MAX_PLAN)


def plan_row(seq: int, plan_len: int, k: int) -> "int | None":
    """Row ``j = k - seq - 1`` when ``k > seq`` and ``j < min(plan_len, MAX_PLAN)``."""
    if k <= seq:
        return None
    j = k - seq - 1
    return j if j < plan_rows(plan_len) else None


def carried(seq: int, plan_len: int, k: int) -> "str | tuple | None":
    """``"input"`` at ``k = seq``, ``("plan-row", j)`` after it, else ``None``."""
    if k == seq:
        return "input"
    j = plan_row(seq, plan_len, k)
    return None if j is None else ("plan-row", j)


def answered_measurement(seq: int, reply_to: int, timing: int) -> int:
    """``max(reply_to, seq - lead)`` (``seq - lead`` saturating at 0)."""
    return max(reply_to, max(seq - _lead(timing), 0))


def header_valid(a, n_u: int) -> bool:
    """This contract's version and the plant's ``n_u``."""
    return a.contract_version == CONTRACT_VERSION and a.counts.n_u == n_u


def actuation_valid(a, n_u: int) -> bool:
    """A valid header, ``plan_len <= MAX_PLAN``, finite ``u`` and plan rows (first ``n_u``)."""
    n = min(n_u, MAX_U)
    if not header_valid(a, n_u) or a.plan_len > MAX_PLAN:
        return False
    if not all(math.isfinite(v) for v in a.u[:n]):
        return False
    return all(math.isfinite(v) for row in a.plan[: plan_rows(a.plan_len)] for v in row[:n])


def arrival(a, n_u: int, k: int) -> str:
    """``"stall-ack"``, ``"invalid"``, ``"late"`` (``seq < k``) or ``"in-time"``."""
    if a.status & actuation_status.STALL_ACK:
        return "stall-ack" if header_valid(a, n_u) else "invalid"
    if not actuation_valid(a, n_u):
        return "invalid"
    return "late" if a.seq < k else "in-time"


def plan_supersedes(held: "int | None", candidate: int) -> bool:
    """A plan not older than the held one replaces it."""
    return held is None or candidate >= held


# ---- a miss, the watchdog and the plant's report ----


def on_miss(policy: str, plan_fallback: str, newest_plan_row: "int | None") -> "str | tuple":
    """``("plan-row", j)``, ``"hold"`` or ``"safe"``; ``policy`` ``"hold"``, ``"safe"`` or
    ``"plan"`` (with ``plan_fallback`` ``"hold"`` or ``"safe"``)."""
    if policy != "plan":
        return policy
    if newest_plan_row is not None:
        return ("plan-row", newest_plan_row)
    return plan_fallback


def watchdog_trips(tripped: bool, consecutive_misses: int, watchdog_periods: int) -> bool:
    """Trips when not tripped and the consecutive misses reached ``watchdog_periods``."""
    return not tripped and consecutive_misses >= watchdog_periods


def applied(miss: "str | tuple | None", tripped: bool) -> str:
    """``"answered"``, ``"plan"``, ``"held"``, ``"safe"`` or ``"watchdog-safe"``."""
    if tripped:
        return "watchdog-safe"
    if miss is None:
        return "answered"
    if isinstance(miss, tuple):
        return "plan"
    return "held" if miss == "hold" else "safe"


def report_flags(applied_as: str) -> int:
    """The flags of the next measurement about a period applied as ``applied_as``."""
    f = 0
    if applied_as != "answered":
        f |= measurement_flags.PREVIOUS_ACTUATION_MISSED
    if applied_as == "plan":
        f |= measurement_flags.PLAN_APPLIED
    if applied_as == "watchdog-safe":
        f |= measurement_flags.PLANT_SAFE_OUTPUT
    return f


def reported(flags: int) -> str:
    """``"on-time"``, ``"plan-row"`` or ``"held-or-safe"``."""
    missed = flags & measurement_flags.PREVIOUS_ACTUATION_MISSED
    if flags & measurement_flags.PLANT_SAFE_OUTPUT:
        return "held-or-safe"
    if not missed:
        return "on-time"
    return "plan-row" if flags & measurement_flags.PLAN_APPLIED else "held-or-safe"


# ---- what the service expects the plant to apply ----


def expected_input(sent_for_k: bool, newest: "tuple | None", k: int) -> "str | tuple":
    """``"sent"``, ``("plan-row", j)``, ``"held"`` or ``"safe"``; ``newest`` is ``(seq, plan_len)``."""
    if sent_for_k:
        return "sent"
    if newest is not None and newest[0] < k:
        j = plan_row(newest[0], newest[1], k)
        return "held" if j is None else ("plan-row", j)
    return "safe"


# ---- the timing a service runs ----


def resolve_timing(choice: "int | str", answers_ahead: bool) -> tuple:
    """``("ok", timing)`` or ``("needs-ahead", timing)``; ``choice`` ``"auto"`` or a timing."""
    if choice == "auto":
        return ("ok", Timing.SEND_AHEAD if answers_ahead else Timing.COMPUTE_FIRST)
    if choice == Timing.COMPUTE_FIRST or answers_ahead:
        return ("ok", Timing(choice))
    return ("needs-ahead", Timing(choice))


def plan_length(requested: int, timing: int) -> tuple:
    """``("ok", n)``, ``("refused", "past-capacity")`` or ``("refused", "compute-first")``."""
    if requested > MAX_PLAN:
        return ("refused", "past-capacity")
    if requested > 0 and timing == Timing.COMPUTE_FIRST:
        return ("refused", "compute-first")
    return ("ok", requested)


def effective_timing(configured: int, has_ahead: bool) -> int:
    """The configured timing with an ahead form, else compute-first."""
    return Timing(configured) if has_ahead else Timing.COMPUTE_FIRST


def effective_plan_length(timing: int, configured: int) -> int:
    """0 with compute-first, else ``min(configured, MAX_PLAN)``."""
    return 0 if timing == Timing.COMPUTE_FIRST else min(configured, MAX_PLAN)
