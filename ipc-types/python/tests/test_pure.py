"""Unit tests of the parts of ``adaptive_rig`` that need no peer: the peer pin, channel counts
and refusal texts (the actuation book and the timing rules: ``test_timing_vectors.py``).

Run: ``PYTHONPATH=ipc-types/python python -m unittest discover -s ipc-types/python/tests``
(``tests/tests/python_peers.rs`` does).
"""

import unittest

from adaptive_rig.contract import ChannelCounts, Timing
from adaptive_rig.peer import FOREIGN, NEW_PEER, PEER, PeerPin
from adaptive_rig.ports import Applies, ConnectError, ContractInfo, Side, service_names

C = ChannelCounts.new(1, 1, 0, 1)


class PeerPinTest(unittest.TestCase):
    def test_the_first_publisher_is_pinned_a_replacement_is_new_and_the_old_one_foreign(self):
        pin = PeerPin()
        self.assertEqual(pin.admit(0xA), PEER)
        self.assertEqual(pin.admit(0xA), PEER)
        self.assertEqual(pin.admit(0xB), NEW_PEER)
        self.assertEqual(pin.admit(0xA), FOREIGN)
        self.assertEqual(pin.admit(0), FOREIGN)
        self.assertEqual((pin.foreign_samples, pin.new_peers), (2, 1))


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
