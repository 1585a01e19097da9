"""The plant's book of actuations: which input it applies for each sample.

A small version of plant-proxy's ``ActuationBook`` (``plant-proxy/src/actuation_book.rs``)
and late policy (``late_policy.rs``):

- :meth:`ActuationBook.offer` takes one received actuation while the plant is at sample
  ``k``: a valid one for ``k`` or later is kept (at most ``capacity``, the earliest received
  dropped when full), one for an earlier sample is late (its plan may still cover later
  samples), an invalid one is refused, a stall acknowledgement is never an input.
- :meth:`ActuationBook.decide` gives the input for ``k``: the actuation with ``seq = k``, else
  a miss resolved by the policy (``"hold"``, ``"safe"``, ``"plan"`` with a hold or safe
  fallback).
- :meth:`ActuationBook.answers` tells whether the service answered (or acknowledged)
  measurement ``k``: a lockstep plant waits for that.

Every rule is a call of :mod:`adaptive_rig.timing_rules` (validity and what an arriving
actuation is, the newest plan, the input of a miss, the measurement an actuation answers);
the book keeps the state. ``ipc-types/tests/vectors/timing.json`` holds the cases both this
book and the Rust one are tested against.
"""

from . import timing_rules as rules

KEPT = "kept"
KEPT_DROPPING = "kept-dropping"
LATE = "late"
INVALID = "invalid"
STALL_ACK = "stall-ack"


class Decision:
    """The input of one sample: ``kind`` is ``"answered"``, ``"plan"``, ``"hold"`` or ``"safe"``."""

    def __init__(self, kind: str, u=None, status: int = 0, timing: int = 0, from_seq=None, row=None):
        """A decision of ``kind`` with its input ``u`` (answered or plan), status and timing;
        for a plan, the ``seq`` of the actuation whose plan it is and the row."""
        self.kind = kind
        self.u = u
        self.status = status
        self.timing = timing
        self.from_seq = from_seq
        self.row = row

    @property
    def miss_input(self):
        """The miss's input as :func:`adaptive_rig.timing_rules.on_miss` gives it; ``None``
        when answered."""
        if self.kind == "answered":
            return None
        return ("plan-row", self.row) if self.kind == "plan" else self.kind

    @property
    def is_miss(self) -> bool:
        """True unless the actuation for the sample was there."""
        return self.kind != "answered"


class ActuationBook:
    """The actuations a plant holds for the current and later samples, the newest plan and how
    far the service answered."""

    def __init__(self, n_u: int, policy: str = "hold", plan_fallback: str = "hold", capacity: int = 8):
        """A book for ``n_u`` inputs; ``policy`` ``"hold"``, ``"safe"`` or ``"plan"``."""
        if policy not in ("hold", "safe", "plan") or plan_fallback not in ("hold", "safe"):
            raise ValueError(f"unknown late policy '{policy}' / plan fallback '{plan_fallback}'")
        self.n_u = n_u
        self.policy = policy
        self.plan_fallback = plan_fallback
        self.capacity = max(capacity, 1)
        self.clear()

    def clear(self) -> None:
        """Forgets everything (a new service took over)."""
        self.held = {}  # seq -> (arrival, Actuation)
        self.arrivals = 0
        self.plan_source = None
        self.answered = None
        self.acknowledged = None
        self.dropped_seq = None

    def _consider_plan(self, a) -> None:
        if rules.plan_supersedes(None if self.plan_source is None else self.plan_source.seq, a.seq):
            self.plan_source = a

    def offer(self, a, k: int) -> str:
        """Takes actuation ``a`` received while the plant is at sample ``k``; returns what it did."""
        arrival = rules.arrival(a, self.n_u, k)
        if arrival == "stall-ack":
            self.acknowledged = a.reply_to if self.acknowledged is None else max(self.acknowledged, a.reply_to)
            return STALL_ACK
        if arrival == "invalid":
            return INVALID
        answered = rules.answered_measurement(a.seq, a.reply_to, a.timing)
        self.answered = answered if self.answered is None else max(self.answered, answered)
        if arrival == "late":
            self._consider_plan(a)
            return LATE
        self.arrivals += 1
        outcome = KEPT
        if a.seq not in self.held and len(self.held) >= self.capacity:
            oldest = min(self.held, key=lambda s: self.held[s][0])
            del self.held[oldest]
            self.dropped_seq = oldest
            outcome = KEPT_DROPPING
        self.held[a.seq] = (self.arrivals, a)
        return outcome

    def decide(self, k: int) -> Decision:
        """The input for sample ``k`` (call once per sample, ``k`` increasing)."""
        answer = None
        for seq in sorted(s for s in self.held if s <= k):
            _, a = self.held.pop(seq)
            self._consider_plan(a)
            if seq == k:
                answer = a
        if answer is not None:
            return Decision("answered", list(answer.u[: self.n_u]), answer.status, answer.timing)
        p = self.plan_source
        row = rules.plan_row(p.seq, p.plan_len, k) if p is not None else None
        miss = rules.on_miss(self.policy, self.plan_fallback, row)
        if isinstance(miss, tuple):
            return Decision("plan", list(p.plan[row][: self.n_u]), from_seq=p.seq, row=row)
        return Decision(miss)

    def answers(self, k: int) -> bool:
        """True when the service answered measurement ``k`` (or a later one) or acknowledged it."""
        return (self.answered is not None and self.answered >= k) or (
            self.acknowledged is not None and self.acknowledged >= k
        )
