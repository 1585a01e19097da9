"""The Python side of the adaptive-rig wire contract (contract version 3, iceoryx2 0.10).

- :mod:`adaptive_rig.contract`: the payloads ``Measurement`` and ``Actuation`` (ctypes,
  the layout of ``ipc_types``), flags, statuses, timings, channel counts.
- :mod:`adaptive_rig.ports`: connecting as the plant or as the service, with the same
  services, settings, attributes, verification and error texts as ``ipc_types::ports``.
- :mod:`adaptive_rig.peer`: the pinned peer publisher.
- :mod:`adaptive_rig.timing_rules`: the rules of the timing protocol (``ipc_types::timing_rules``).
- :mod:`adaptive_rig.book`: which input a plant applies for each sample.
- :mod:`adaptive_rig.plant`: the plant side (clock master; lockstep or real time).
- :mod:`adaptive_rig.controller`: the controller side (compute-first).
"""

from .contract import (  # noqa: F401
    CONTRACT_VERSION,
    MAX_PLAN,
    MAX_R,
    MAX_U,
    MAX_Y,
    MAX_Z,
    Actuation,
    ChannelCounts,
    Measurement,
    Timing,
    actuation_status,
    measurement_flags,
)
from .ports import Applies, ConnectError, ContractInfo, Side, connect  # noqa: F401
