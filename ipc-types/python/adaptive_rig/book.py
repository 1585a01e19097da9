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

Valid means: this contract version, the plant's ``n_u``, ``plan_len <= MAX_PLAN``, finite
``u`` and plan entries.
"""

import math

from .contract import CONTRACT_VERSION, MAX_PLAN, Timing, actuation_status

KEPT = "kept"
KEPT_DROPPING = "kept-dropping"
LATE = "late"
INVALID = "invalid"
STALL_ACK = "stall-ack"


class Decision:
    """The input of one sample: ``kind`` is ``"answered"``, ``"plan"``, ``"hold"`` or ``"safe"``."""

    def __init__(self, kind: str, u=None, status: int = 0, timing: int = 0):
        """A decision of ``kind`` with its input ``u`` (answered or plan), status and timing."""
        self.kind = kind
        self.u = u
        self.status = status
        self.timing = timing

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

    def _header_ok(self, a) -> bool:
        return a.contract_version == CONTRACT_VERSION and a.counts.n_u == self.n_u

    def _valid(self, a) -> bool:
        n = self.n_u
        if not self._header_ok(a) or a.plan_len > MAX_PLAN:
            return False
        if not all(math.isfinite(v) for v in a.u[:n]):
            return False
        return all(math.isfinite(v) for e in a.plan[: a.plan_len] for v in e[:n])

    def _consider_plan(self, a) -> None:
        if self.plan_source is None or a.seq >= self.plan_source.seq:
            self.plan_source = a

    def offer(self, a, k: int) -> str:
        """Takes actuation ``a`` received while the plant is at sample ``k``; returns what it did."""
        if a.status & actuation_status.STALL_ACK:
            if not self._header_ok(a):
                return INVALID
            self.acknowledged = a.reply_to if self.acknowledged is None else max(self.acknowledged, a.reply_to)
            return STALL_ACK
        if not self._valid(a):
            return INVALID
        t = Timing.from_wire(a.timing)
        answered = max(a.reply_to, a.seq - (t.lead if t is not None else 0))
        self.answered = answered if self.answered is None else max(self.answered, answered)
        if a.seq < k:
            self._consider_plan(a)
            return LATE
        self.arrivals += 1
        outcome = KEPT
        if a.seq not in self.held and len(self.held) >= self.capacity:
            oldest = min(self.held, key=lambda s: self.held[s][0])
            del self.held[oldest]
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
        if self.policy != "plan":
            return Decision(self.policy)
        p = self.plan_source
        entry = p.input_for(k) if p is not None and p.seq < k else None
        if entry is not None:
            return Decision("plan", entry)
        return Decision(self.plan_fallback)

    def answers(self, k: int) -> bool:
        """True when the service answered measurement ``k`` (or a later one) or acknowledged it."""
        return (self.answered is not None and self.answered >= k) or (
            self.acknowledged is not None and self.acknowledged >= k
        )
