"""Every vector of ``ipc-types/tests/vectors/timing.json`` against the Python statement of the
timing rules (:mod:`adaptive_rig.timing_rules`) and the Python book (:mod:`adaptive_rig.book`).
The Rust rules and book run the same file (``ipc-types/tests/timing_vectors.rs``,
``plant-proxy/plant-side/tests/book_vectors.rs``), so a rule changed on one side only fails.

Run as the other unit tests of the package (``tests/tests/python_peers.rs`` does).
"""

import json
import unittest
from pathlib import Path

from adaptive_rig import book as bk
from adaptive_rig import timing_rules as rules
from adaptive_rig.contract import (
    CONTRACT_VERSION,
    Actuation,
    ChannelCounts,
    Timing,
    actuation_status,
    measurement_flags,
)

VECTORS = json.loads((Path(__file__).resolve().parents[2] / "tests" / "vectors" / "timing.json").read_text())

BITS = {
    name: getattr(measurement_flags, name)
    for name in (
        "LOCKSTEP",
        "PLANT_SAFE_OUTPUT",
        "PREVIOUS_ACTUATION_MISSED",
        "LAST_SAMPLE",
        "U_APPLIED",
        "PLAN_APPLIED",
        "INJECTED_STALL",
    )
}
BITS["STALL_ACK"] = actuation_status.STALL_ACK
REPORTED = ("PREVIOUS_ACTUATION_MISSED", "PLAN_APPLIED", "PLANT_SAFE_OUTPUT")


def value(v) -> float:
    """A number, or ``"nan"``, ``"inf"``, ``"-inf"``."""
    return float(v)


def timing(v) -> int:
    """A timing by name, or a wire value as it is."""
    if isinstance(v, str):
        t = Timing.from_label(v)
        if t is None:
            raise ValueError(f"no timing {v}")
        return t
    return v


def bits(names) -> int:
    out = 0
    for n in names:
        out |= BITS[n]
    return out


def actuation(v) -> Actuation:
    """An actuation of the file's encoding (fields and defaults in its description)."""
    u = v["u"]
    a = Actuation.zeroed(ChannelCounts.new(1, 1, 0, v.get("n_u", len(u))))
    a.seq, a.reply_to = v["seq"], v["reply_to"]
    a.timing = timing(v.get("timing", "send-ahead"))
    a.status = bits(v.get("status", []))
    a.contract_version = v.get("contract_version", CONTRACT_VERSION)
    for i, x in enumerate(u):
        a.u[i] = value(x)
    plan = v.get("plan", [])
    for j, row in enumerate(plan):
        for i, x in enumerate(row):
            a.plan[j][i] = value(x)
    a.plan_len = v.get("plan_len", len(plan))
    return a


def encoded(r):
    """A result in the file's encoding: ``(variant, payload)`` as ``{variant: payload}``,
    timings by name."""
    if isinstance(r, tuple):
        variant, payload = r
        return {variant: encoded(payload)}
    if isinstance(r, Timing):
        return r.label
    return r


def miss(v):
    return ("plan-row", v["plan-row"]) if isinstance(v, dict) else v


def run(rule: str, a: dict):
    """The rule's result on the vector's arguments, in the file's encoding."""
    if rule == "applies":
        return rules.applies(a["lockstep"], a["deadline_fraction"])
    if rule == "deadline_offset_ns":
        return rules.deadline_offset_ns(a["lockstep"], a["deadline_fraction"], a["period_ns"])
    if rule == "application_instant":
        return rules.application_instant(a["t_sample_ns"], a["deadline_offset_ns"])
    if rule == "timings_meet":
        return rules.timings_meet(a["applies"], timing(a["timing"]))
    if rule == "answer_seq":
        return rules.answer_seq(a["k"], timing(a["timing"]))
    if rule == "answers_sample_itself":
        return rules.answers_sample_itself(timing(a["timing"]), a["sent_ahead_for_k"])
    if rule == "answer_deadline_ns":
        return rules.answer_deadline_ns(a["lockstep"], a["deadline_ns"], a["period_ns"], timing(a["timing"]))
    if rule == "answer_late":
        return rules.answer_late(a["timestamp_ok"], a["deadline_ns"], a["response_ns"])
    if rule == "plan_row":
        return rules.plan_row(a["seq"], a["plan_len"], a["k"])
    if rule == "carried":
        return encoded(rules.carried(a["seq"], a["plan_len"], a["k"]))
    if rule == "answered_measurement":
        return rules.answered_measurement(a["seq"], a["reply_to"], timing(a["timing"]))
    if rule == "actuation_valid":
        return rules.actuation_valid(actuation(a["actuation"]), a["n_u"])
    if rule == "arrival":
        return rules.arrival(actuation(a["actuation"]), a["n_u"], a["k"])
    if rule == "plan_supersedes":
        return rules.plan_supersedes(a["held"], a["candidate"])
    if rule == "on_miss":
        return encoded(rules.on_miss(a["policy"], a["fallback"], a["newest_plan_row"]))
    if rule == "watchdog_trips":
        return rules.watchdog_trips(a["tripped"], a["consecutive_misses"], a["watchdog_periods"])
    if rule == "applied":
        return rules.applied(miss(a["miss"]), a["tripped"])
    if rule == "report_flags":
        f = rules.report_flags(a["applied"])
        names = [n for n in REPORTED if f & BITS[n]]
        if f & ~bits(REPORTED):
            raise AssertionError(f"unnamed bits in {f:#x}")
        return names
    if rule == "reported":
        return rules.reported(bits(a["flags"]))
    if rule == "expected_input":
        newest = tuple(a["newest"]) if a["newest"] is not None else None
        return encoded(rules.expected_input(a["sent_for_k"], newest, a["k"]))
    if rule == "resolve_timing":
        choice = a["choice"] if a["choice"] == "auto" else timing(a["choice"])
        return encoded(rules.resolve_timing(choice, a["answers_ahead"]))
    if rule == "plan_length":
        return encoded(rules.plan_length(a["requested"], timing(a["timing"])))
    if rule == "effective_timing":
        return encoded(rules.effective_timing(timing(a["configured"]), a["has_ahead"]))
    if rule == "effective_plan_length":
        return rules.effective_plan_length(timing(a["timing"]), a["configured"])
    raise AssertionError(f"a vector of an unknown rule: {rule}")


class TimingVectorsTest(unittest.TestCase):
    def test_every_rule_vector_holds_for_the_python_rules(self):
        failures = []
        for c in VECTORS["rules"]:
            got = run(c["rule"], c["args"])
            if got != c["expect"] or type(got) is not type(c["expect"]):
                failures.append(f"{c['rule']} ({c['description']}): expected {c['expect']!r}, got {got!r}")
        self.assertEqual(failures, [], "\n".join(failures))

    def test_every_book_vector_holds_for_the_python_book(self):
        failures = []
        for case in VECTORS["book"]:
            what, n_u = case["description"], case["n_u"]
            b = bk.ActuationBook(n_u, case["policy"], case["fallback"], capacity=case["capacity"])
            for i, step in enumerate(case["steps"]):
                if "offer" in step:
                    r = b.offer(actuation(step["offer"]), step["k"])
                    got = {"offer": r}
                    expected = {"offer": step["expect"]}
                    if r == bk.KEPT_DROPPING:
                        got["dropped_seq"] = b.dropped_seq
                    if "dropped_seq" in step:
                        expected["dropped_seq"] = step["dropped_seq"]
                elif "decide" in step:
                    d = b.decide(step["decide"])
                    if d.kind == "answered":
                        got = {"answered": d.u}
                    elif d.kind == "plan":
                        got = {"plan": d.u, "from_seq": d.from_seq}
                    else:
                        got = d.kind
                    expected = step["expect"]
                elif "answers" in step:
                    got, expected = b.answers(step["answers"]), step["expect"]
                elif "plan_seq" in step:
                    got = None if b.plan_source is None else b.plan_source.seq
                    expected = step["plan_seq"]
                elif "clear" in step:
                    b.clear()
                    continue
                else:
                    raise AssertionError(f"{what}: step {i} is no known step: {step}")
                if got != expected:
                    failures.append(f"{what}, step {i} {step}: expected {expected!r}, got {got!r}")
        self.assertEqual(failures, [], "\n".join(failures))


if __name__ == "__main__":
    unittest.main()
