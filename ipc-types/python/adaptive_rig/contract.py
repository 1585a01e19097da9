"""The wire contract's payloads, as ctypes structures with the layout of ``ipc_types``.

``Measurement`` and ``Actuation`` are byte-for-byte the ``#[repr(C)]`` structs of
``ipc-types/src/lib.rs`` (and of ``ipc-types/include/adaptive_rig_contract.h``): same
capacities, field order, field types, hence the same offsets, padding, size and alignment.
Their ``type_name()`` is the Rust type name, which iceoryx2 compares (with the size and the
alignment) when a Python port opens a service a Rust process created.

A plant publishes one ``Measurement`` per sample; the service answers with an
``Actuation``. Flags, statuses and timings are the Rust constants.
"""

import ctypes
import enum

#: Version of the contract; a peer of another version is refused at connect.
CONTRACT_VERSION = 3
#: Capacity of the measurement vector ``y``.
MAX_Y = 16
#: Capacity of the performance vector ``z``.
MAX_Z = 16
#: Capacity of the command vector ``r``.
MAX_R = 16
#: Capacity of the actuation vector ``u``.
MAX_U = 8
#: Capacity of an actuation's plan.
MAX_PLAN = 64


class measurement_flags:  # noqa: N801 (the Rust module's name)
    """Bits a plant sets in ``Measurement.flags`` (``ipc_types::measurement_flags``)."""

    LOCKSTEP = 1 << 0
    PLANT_SAFE_OUTPUT = 1 << 1
    PREVIOUS_ACTUATION_MISSED = 1 << 2
    LAST_SAMPLE = 1 << 3
    U_APPLIED = 1 << 4
    PLAN_APPLIED = 1 << 5
    INJECTED_STALL = 1 << 6


class actuation_status:  # noqa: N801 (the Rust module's name)
    """Bits the service sets in ``Actuation.status`` (``ipc_types::actuation_status``)."""

    OK = 0
    SAFE_STATE = 1 << 0
    MEASUREMENT_REJECTED = 1 << 1
    SATURATED = 1 << 2
    STARTING = 1 << 3
    CONTROLLER_FAULT = 1 << 4
    OPEN_LOOP = 1 << 5
    FALLBACK = 1 << 6
    STALL_ACK = 1 << 7


class Timing(enum.IntEnum):
    """When the service answers a sample; the value is the wire value of ``Actuation.timing``."""

    COMPUTE_FIRST = 0
    ANSWER_FIRST = 1
    SEND_AHEAD = 2

    @property
    def label(self) -> str:
        """The name used in attributes and reports (``"compute-first"``, ...)."""
        return self.name.lower().replace("_", "-")

    @property
    def lead(self) -> int:
        """How many samples ahead of the measurement it answers the input is (1 for send-ahead)."""
        return 1 if self is Timing.SEND_AHEAD else 0

    @classmethod
    def from_label(cls, label: str) -> "Timing | None":
        """The timing named ``label``; ``None`` for an unknown name."""
        return next((t for t in cls if t.label == label), None)

    @classmethod
    def from_wire(cls, value: int) -> "Timing | None":
        """The timing of a wire value; ``None`` for an unknown one."""
        try:
            return cls(value)
        except ValueError:
            return None


class ChannelCounts(ctypes.Structure):
    """Channel counts used by one side (``ipc_types::ChannelCounts``, four ``u16``)."""

    _fields_ = [
        ("n_y", ctypes.c_uint16),
        ("n_z", ctypes.c_uint16),
        ("n_r", ctypes.c_uint16),
        ("n_u", ctypes.c_uint16),
    ]

    @staticmethod
    def type_name() -> str:
        """The Rust type name."""
        return "adaptive_rig::ChannelCounts.v1"

    @classmethod
    def new(cls, n_y: int, n_z: int, n_r: int, n_u: int) -> "ChannelCounts":
        """Counts refused (``ValueError``, the Rust message) when one exceeds its capacity."""
        for what, n, cap in (
            ("measurement channels y", n_y, MAX_Y),
            ("performance channels z", n_z, MAX_Z),
            ("command channels r", n_r, MAX_R),
            ("actuation channels u", n_u, MAX_U),
        ):
            if n < 0 or n > cap:
                raise ValueError(
                    f"{what}: {n} channels requested, the contract carries at most {cap}"
                )
        return cls(n_y, n_z, n_r, n_u)

    def as_tuple(self) -> tuple:
        """``(n_y, n_z, n_r, n_u)``."""
        return (self.n_y, self.n_z, self.n_r, self.n_u)

    def within_capacity(self) -> bool:
        """True when every count is within the contract's capacities."""
        return self.n_y <= MAX_Y and self.n_z <= MAX_Z and self.n_r <= MAX_R and self.n_u <= MAX_U

    def differences(self, own: str, peer: "ChannelCounts", peer_name: str) -> list:
        """One line per count that differs from ``peer``'s, as ``ChannelCounts::differences``."""
        out = []
        for what, mine, theirs in (
            ("measurement channels (y)", self.n_y, peer.n_y),
            ("performance channels (z)", self.n_z, peer.n_z),
            ("command channels (r)", self.n_r, peer.n_r),
            ("actuation channels (u)", self.n_u, peer.n_u),
        ):
            if mine != theirs:
                out.append(f"{what}: {peer_name} uses {theirs}, {own} uses {mine}")
        return out

    def __repr__(self) -> str:
        return f"ChannelCounts(n_y={self.n_y}, n_z={self.n_z}, n_r={self.n_r}, n_u={self.n_u})"

    @staticmethod
    def add_arguments(parser, peer_timeout_s: float = 30.0) -> None:
        """Adds the options of a peer process to an ``argparse`` parser: ``--rig``,
        ``--period`` (s), the counts ``--n-y``, ``--n-z``, ``--n-r``, ``--n-u`` (1, 1, 0, 1),
        ``--peer-timeout`` (s) and ``--contract-version`` (for tests of the refusal)."""
        parser.add_argument("--rig", required=True)
        parser.add_argument("--period", type=float, default=0.001, help="sample period T, s")
        for name, default in (("y", 1), ("z", 1), ("r", 0), ("u", 1)):
            parser.add_argument(f"--n-{name}", type=int, default=default)
        parser.add_argument("--peer-timeout", type=float, default=peer_timeout_s, help="s")
        parser.add_argument("--contract-version", type=int, default=None, help="state another version (tests)")

    @classmethod
    def from_arguments(cls, args) -> "ChannelCounts":
        """The counts of the options :meth:`add_arguments` added (raises ``ValueError``)."""
        return cls.new(args.n_y, args.n_z, args.n_r, args.n_u)


def _fields(kind, *names) -> list:
    """``(name, kind)`` for each name: consecutive fields of one C type."""
    return [(n, kind) for n in names]


class _Payload(ctypes.Structure):
    """What both payloads have: the Rust type name iceoryx2 compares (``_TYPE_NAME``) and an
    all-zero value of this contract version with given counts."""

    _TYPE_NAME = ""

    @classmethod
    def type_name(cls) -> str:
        """The Rust type name iceoryx2 compares."""
        return cls._TYPE_NAME

    @classmethod
    def zeroed(cls, counts: ChannelCounts):
        """An all-zero payload of this contract version with the given counts."""
        p = cls()
        p.contract_version = CONTRACT_VERSION
        p.counts = counts
        return p


class Measurement(_Payload):
    """One sample of the plant, published at the start of period ``seq``."""

    _TYPE_NAME = "adaptive_rig::Measurement.v3"

    _fields_ = [
        *_fields(ctypes.c_uint32, "contract_version", "flags"),
        *_fields(ctypes.c_uint64, "seq", "t_sample_ns", "period_ns", "deadline_ns"),
        ("counts", ChannelCounts),
        *[(n, ctypes.c_double * cap) for n, cap in (("y", MAX_Y), ("z", MAX_Z), ("r", MAX_R), ("u_applied", MAX_U))],
    ]

    def used_y(self) -> list:
        """The used part of ``y``."""
        return list(self.y[: min(self.counts.n_y, MAX_Y)])

    def used_z(self) -> list:
        """The used part of ``z``."""
        return list(self.z[: min(self.counts.n_z, MAX_Z)])

    def used_r(self) -> list:
        """The used part of ``r``."""
        return list(self.r[: min(self.counts.n_r, MAX_R)])

    def used_u_applied(self) -> "list | None":
        """The used part of ``u_applied`` when the plant reports it (``U_APPLIED``)."""
        if self.flags & measurement_flags.U_APPLIED == 0:
            return None
        return list(self.u_applied[: min(self.counts.n_u, MAX_U)])


class Actuation(_Payload):
    """The service's answer: the input for the period that starts at sample ``seq``, and a plan."""

    _TYPE_NAME = "adaptive_rig::Actuation.v3"

    _fields_ = [
        *_fields(ctypes.c_uint32, "contract_version", "status"),
        *_fields(ctypes.c_uint64, "seq", "reply_to", "t_sample_ns", "t_publish_ns", "compute_ns"),
        ("counts", ChannelCounts),
        *_fields(ctypes.c_uint32, "timing", "plan_len"),
        ("u", ctypes.c_double * MAX_U),
        ("plan", (ctypes.c_double * MAX_U) * MAX_PLAN),
    ]

    @classmethod
    def zeroed(cls, counts: ChannelCounts) -> "Actuation":
        """An all-zero actuation of this contract version (compute-first) with the given counts."""
        a = super().zeroed(counts)
        a.timing = Timing.COMPUTE_FIRST
        return a

    def used_u(self) -> list:
        """The used part of ``u``."""
        return list(self.u[: min(self.counts.n_u, MAX_U)])

    def plan_entry(self, j: int) -> "list | None":
        """The used part of the plan entry for sample ``seq + 1 + j``; ``None`` past ``plan_len``."""
        if j < 0 or j >= min(self.plan_len, MAX_PLAN):
            return None
        return list(self.plan[j][: min(self.counts.n_u, MAX_U)])

    def input_for(self, k: int) -> "list | None":
        """The input this actuation carries for sample ``k`` (``u`` or a plan entry), else ``None``."""
        if k == self.seq:
            return self.used_u()
        if k > self.seq:
            return self.plan_entry(k - self.seq - 1)
        return None


def layout() -> dict:
    """Size, alignment, type name and every field's offset, in field order, of ``Measurement``,
    ``Actuation`` and ``ChannelCounts`` (``fields``: a list of ``[name, offset]``)."""
    out = {}
    for t in (Measurement, Actuation, ChannelCounts):
        out[t.__name__] = {
            "type_name": t.type_name(),
            "size": ctypes.sizeof(t),
            "align": ctypes.alignment(t),
            "fields": [[name, getattr(t, name).offset] for name, _ in t._fields_],
        }
    return out
