"""Unit tests of the parts of ``adaptive_rig`` that need no peer: the peer pin, the actuation
book (the cases of plant-proxy's ``actuation_book.rs``), channel counts and refusal texts.

Run: ``PYTHONPATH=ipc-types/python python -m unittest discover -s ipc-types/python/tests``
(``tests/tests/python_peers.rs`` does).
"""

import math
import unittest

from adaptive_rig import book as bk
from adaptive_rig.contract import Actuation, ChannelCounts, Timing, actuation_status
from adaptive_rig.peer import FOREIGN, NEW_PEER, PEER, PeerPin
from adaptive_rig.ports import Applies, ConnectError, ContractInfo, Side, service_names

C = ChannelCounts.new(1, 1, 0, 1)


def act(seq, reply_to, u, plan=(), timing=Timing.SEND_AHEAD):
    """An actuation for one input with a plan."""
    a = Actuation.zeroed(C)
    a.seq, a.reply_to, a.timing, a.u[0] = seq, reply_to, timing, u
    a.plan_len = len(plan)
    for j, v in enumerate(plan):
        a.plan[j][0] = v
    return a


class PeerPinTest(unittest.TestCase):
    def test_the_first_publisher_is_pinned_a_replacement_is_new_and_the_old_one_foreign(self):
        pin = PeerPin()
        self.assertEqual(pin.admit(0xA), PEER)
        self.assertEqual(pin.admit(0xA), PEER)
        self.assertEqual(pin.admit(0xB), NEW_PEER)
        self.assertEqual(pin.admit(0xA), FOREIGN)
        self.assertEqual(pin.admit(0), FOREIGN)
        self.assertEqual((pin.foreign_samples, pin.new_peers), (2, 1))


class ActuationBookTest(unittest.TestCase):
    def test_an_input_sent_ahead_is_applied_at_its_sample_and_its_plan_after_it(self):
        b = bk.ActuationBook(1, "plan")
        self.assertEqual(b.offer(act(5, 4, 0.5, [0.25]), 4), bk.KEPT)
        self.assertTrue(b.answers(4) and not b.answers(5))
        self.assertEqual(b.decide(4).kind, "hold")
        d = b.decide(5)
        self.assertEqual((d.kind, d.u), ("answered", [0.5]))
        d = b.decide(6)
        self.assertEqual((d.kind, d.u), ("plan", [0.25]))
        self.assertEqual(b.decide(7).kind, "hold")

    def test_late_invalid_and_stall_acknowledgements_are_not_inputs(self):
        b = bk.ActuationBook(1, "safe")
        self.assertEqual(b.offer(act(3, 3, 1.0, timing=Timing.COMPUTE_FIRST), 4), bk.LATE)
        self.assertEqual(b.offer(act(4, 4, math.nan), 4), bk.INVALID)
        ack = act(4, 4, 9.0)
        ack.status = actuation_status.STALL_ACK
        self.assertEqual(b.offer(ack, 4), bk.STALL_ACK)
        self.assertTrue(b.answers(4))
        self.assertEqual(b.decide(4).kind, "safe")

    def test_a_full_book_drops_the_earliest_received(self):
        b = bk.ActuationBook(1, "hold", capacity=2)
        self.assertEqual(b.offer(act(1, 0, 1.0), 0), bk.KEPT)
        self.assertEqual(b.offer(act(2, 1, 2.0), 0), bk.KEPT)
        self.assertEqual(b.offer(act(3, 2, 3.0), 0), bk.KEPT_DROPPING)
        self.assertEqual(b.decide(1).kind, "hold")
        self.assertEqual(b.decide(2).u, [2.0])


class TextsTest(unittest.TestCase):
    def test_counts_past_the_capacity_are_refused_with_the_rust_text(self):
        with self.assertRaises(ValueError) as e:
            ChannelCounts.new(1, 1, 0, 9)
        self.assertEqual(
            str(e.exception), "actuation channels u: 9 channels requested, the contract carries at most 8"
        )

    def test_rig_names_are_checked_as_in_rust(self):
        self.assertEqual(service_names("a-1").measurement, "adaptive-rig/a-1/measurement")
        with self.assertRaises(ConnectError) as e:
            service_names("a b")
        self.assertEqual(
            str(e.exception),
            "invalid rig name 'a b': only ASCII letters, digits, '-' and '_' are allowed",
        )

    def test_the_attributes_round_trip_and_differences_name_both_sides(self):
        plant = ContractInfo(Side.PLANT, C, 1_000_000, applies=Applies.LOCKSTEP)
        self.assertEqual(
            plant.attributes()[-2:], [("role", "plant"), ("timing", "lockstep")]
        )
        service = ContractInfo(Side.SERVICE, ChannelCounts.new(1, 1, 0, 2), 1_000_000,
                               timing=Timing.COMPUTE_FIRST)
        self.assertEqual(
            plant.differences(service), ["actuation channels (u): service uses 2, plant uses 1"]
        )


if __name__ == "__main__":
    unittest.main()
