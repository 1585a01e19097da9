"""Connecting one side of the contract over iceoryx2, as ``ipc_types::ports::connect`` does.

Services of rig ``N`` (the payload types are checked by iceoryx2: type name, size, alignment):

==============================  =================  ===============  ==========
service                         pattern            payload          created by
==============================  =================  ===============  ==========
``adaptive-rig/N/measurement``  publish-subscribe  ``Measurement``  plant
``adaptive-rig/N/actuation``    publish-subscribe  ``Actuation``    service
``adaptive-rig/N/measurement``  event              --               either
``adaptive-rig/N/actuation``    event              --               either
==============================  =================  ===============  ==========

Every publish-subscribe service admits 1 publisher and 1 subscriber, a subscriber buffer of
4, no history, safe overflow; a publisher loans at most 2 samples; every event service
admits 1 notifier and 1 listener. The side that creates a publish-subscribe service defines
its attributes ``contract-version``, ``n-y``, ``n-z``, ``n-r``, ``n-u``, ``period-ns``,
``role`` and ``timing``; the peer reads them and refuses a different contract, naming every
difference (:class:`ConnectError`, whose ``str()`` is the Rust ``Display`` text).

The order is Rust's: own service, own publisher (the slot that makes this process the rig's
only plant or service), the peer's service (verified), the event services, notifier,
listener, subscriber last; then wait for the peer's publisher and for the peer's subscriber
on this side's service, so that the first sample sent after :func:`connect` is not lost.

Differences from Rust, where the Python bindings of iceoryx2 0.10 give less: the peer is
pinned on its first sample (:mod:`adaptive_rig.peer`), the holder of a taken slot is named
from the service's node list (not its port list), and a node counts as dead when iceoryx2
says so and its pid does not exist (no check of pid reuse).
"""

import ctypes
import os
import sys
import time
from dataclasses import dataclass, field

import iceoryx2 as iox

from . import timing_rules
from .contract import CONTRACT_VERSION, Actuation, ChannelCounts, Measurement, Timing
from .peer import FOREIGN, NEW_PEER, PeerPin

#: Prefix of every service name of this product.
SERVICE_PREFIX = "adaptive-rig"
# Samples a subscriber's queue holds, as ipc_types::ports::SUBSCRIBER_BUFFER: a service
# created with less is refused when the Rust side opens it.
SUBSCRIBER_BUFFER = 256
#: How long a side that refuses a peer for a contract mismatch keeps its own service up,
#: so that the peer can read it and refuse too (Rust: ``MISMATCH_LINGER``).
MISMATCH_LINGER_S = 3.0
#: How long a slot held by a dead process is retried (Rust: ``STALE_SLOT_RETRY``).
STALE_SLOT_RETRY_S = 2.0

_IPC = iox.ServiceType.Ipc


class Side:
    """Which side of the contract a process is on: ``Side.PLANT`` or ``Side.SERVICE``."""

    PLANT = "plant"
    SERVICE = "service"

    @staticmethod
    def peer(side: str) -> str:
        """The other side."""
        return Side.SERVICE if side == Side.PLANT else Side.PLANT


class Applies:
    """When a plant applies the input of sample ``k`` (its ``timing`` attribute)."""

    AT_SAMPLE = "at-sample"
    AT_DEADLINE = "at-deadline"
    LOCKSTEP = "lockstep"
    ALL = (AT_SAMPLE, AT_DEADLINE, LOCKSTEP)


class ConnectError(Exception):
    """Why a connection could not be made; ``str()`` is the text of Rust's ``ConnectError``.

    ``kind`` names the Rust variant (``"Mismatch"``, ``"PeerTimeout"``, ``"AlreadyRunning"``,
    ...); the other attributes are its fields.
    """

    def __init__(self, kind: str, **fields):
        """An error of variant ``kind`` with the variant's fields."""
        self.kind = kind
        self.fields = fields
        super().__init__(self._text())

    def __getattr__(self, name):
        fields = self.__dict__.get("fields", {})
        if name in fields:
            return fields[name]
        raise AttributeError(name)

    def _text(self) -> str:
        f = self.fields
        k = self.kind
        if k == "InvalidRigName":
            return f"invalid rig name '{f['rig']}': {f['detail']}"
        if k == "Mismatch":
            text = (
                f"contract mismatch on '{f['service']}' (defined by the {f['holder']}), "
                "refusing to connect:"
            )
            return text + "".join(f"\n  - {d}" for d in f["differences"])
        if k == "IncompatibleType":
            return (
                f"'{f['service']}' carries another payload type (type name, size or alignment "
                "differ): the peer was built against another contract layout; rebuild it "
                f"against contract version {CONTRACT_VERSION}"
            )
        if k == "NotAContractService":
            return f"'{f['service']}' is not an adaptive-rig contract service: {f['detail']}"
        if k == "PeerTimeout":
            return (
                f"no peer: '{f['service']}' did not appear within {f['waited']:.1f} s (is the "
                "other process running with the same rig name?)"
            )
        if k == "Interrupted":
            return "interrupted while connecting"
        if k == "AlreadyRunning":
            if f["side"] == Side.SERVICE:
                what = f"rig '{f['rig']}' is already served by {f['holder']}"
            else:
                what = f"rig '{f['rig']}' already has a plant: {f['holder']}"
            return (
                f"{what}, which holds the one publisher of '{f['service']}'; refusing to start "
                f"a second {f['side']}"
            )
        if k == "SlotTaken":
            r = f["reserved_for"]
            return (
                f"'{f['service']}' admits one {f['port']}, the {r}'s, and {f['holder']} holds "
                f"it: another {r} runs on this rig, or a foreign process occupies the slot; "
                "refusing to connect"
            )
        if k == "NotExclusive":
            return (
                f"'{f['service']}' {f['detail']}, the contract allows one of each: it was "
                "created by an older build or by a foreign process; refusing to connect (stop "
                "the processes that use it)"
            )
        if k == "PermissionDenied":
            return (
                f"permission denied while {f['what']} '{f['item']}' ({f['detail']}): the "
                "iceoryx2 files of this machine belong to another user; run the service and "
                "the plant process as the same dedicated user (docs/deployment.md, \"Trust and "
                "deployment model\")"
            )
        return f"iceoryx2 failure while {f['what']} '{f['item']}': {f['detail']}"


def _ipc_err(what: str, item: str, e: BaseException) -> ConnectError:
    """An iceoryx2 failure, as Rust's ``ipc_err``: the variant name is the detail."""
    detail = str(e.args[0]) if getattr(e, "args", None) else repr(e)
    kind = "PermissionDenied" if (
        "InsufficientPermissions" in detail or "PermissionDenied" in detail
    ) else "Ipc"
    return ConnectError(kind, what=what, item=item, detail=detail)


def _variant(e: BaseException) -> str:
    """The iceoryx2 error variant of an exception (``"DoesNotExist"``, ...)."""
    return str(e.args[0]) if getattr(e, "args", None) else ""


@dataclass
class ContractInfo:
    """What one side states about itself when it connects (``ipc_types::ports::ContractInfo``)."""

    side: str
    counts: ChannelCounts
    period_ns: int
    version: int = CONTRACT_VERSION
    timing: "Timing | None" = None
    applies: "str | None" = None

    def attributes(self) -> list:
        """The (key, value) pairs this side defines on the service it creates."""
        kv = [
            ("contract-version", str(self.version)),
            ("n-y", str(self.counts.n_y)),
            ("n-z", str(self.counts.n_z)),
            ("n-r", str(self.counts.n_r)),
            ("n-u", str(self.counts.n_u)),
            ("period-ns", str(self.period_ns)),
            ("role", self.side),
        ]
        if self.side == Side.SERVICE and self.timing is not None:
            kv.append(("timing", Timing(self.timing).label))
        if self.side == Side.PLANT and self.applies is not None:
            kv.append(("timing", self.applies))
        return kv

    def specifier(self) -> "iox.AttributeSpecifier":
        """The iceoryx2 attribute specifier of :meth:`attributes`."""
        spec = iox.AttributeSpecifier.new()
        for k, v in self.attributes():
            spec = spec.define(iox.AttributeKey.new(k), iox.AttributeValue.new(v))
        return spec

    @classmethod
    def from_attributes(cls, attrs, service: str) -> "ContractInfo":
        """The info a service's attribute set states; ``NotAContractService`` when malformed."""
        values = {}
        for a in attrs.values:
            values.setdefault(a.key.to_string(), a.value.to_string())

        def bad(detail):
            return ConnectError("NotAContractService", service=service, detail=detail)

        def get(k):
            if k not in values:
                raise bad(f"it has no attribute '{k}'")
            return values[k]

        def num(k):
            v = get(k)
            if not v.isdigit():
                raise bad(f"attribute '{k}' = '{v}' is not a number")
            return int(v)

        side = get("role")
        if side not in (Side.PLANT, Side.SERVICE):
            raise bad(f"attribute 'role' = '{side}' is neither plant nor service")
        timing = applies = None
        if "timing" in values:
            v = values["timing"]
            if side == Side.SERVICE:
                timing = Timing.from_label(v)
                ok = timing is not None
            else:
                applies = v if v in Applies.ALL else None
                ok = applies is not None
            if not ok:
                raise bad(f"attribute 'timing' = '{v}' is not a timing of a {side}")
        version = num("contract-version")
        counts = ChannelCounts(num("n-y"), num("n-z"), num("n-r"), num("n-u"))
        return cls(side, counts, num("period-ns"), version, timing, applies)

    def differences(self, other: "ContractInfo") -> list:
        """Every difference that makes ``self`` and ``other`` incompatible, one line each."""
        me, them = self.side, other.side
        out = []
        if self.version != other.version:
            out.append(f"contract version: {them} has {other.version}, {me} has {self.version}")
        out.extend(self.counts.differences(me, other.counts, them))
        if self.period_ns != other.period_ns:
            out.append(
                f"sample period: {them} runs at {other.period_ns} ns "
                f"({1e9 / max(other.period_ns, 1):.3f} Hz), {me} at {self.period_ns} ns "
                f"({1e9 / max(self.period_ns, 1):.3f} Hz)"
            )
        plant, service = (self, other) if self.side == Side.PLANT else (other, self)
        if (
            plant.side != service.side
            and plant.applies is not None
            and service.timing is not None
            and not timing_rules.timings_meet(plant.applies, service.timing)
        ):
            out.append(
                "timing: the plant applies each input at its sample instant (its deadline is "
                "0), which only a service that sends ahead can meet; the service answers "
                f"{Timing(service.timing).label} (set service.timing = \"send-ahead\", or give "
                "the plant a deadline inside the period)"
            )
        return out


@dataclass
class RigServiceNames:
    """The service names of one rig."""

    measurement: str
    actuation: str


def service_names(rig: str) -> RigServiceNames:
    """Service names of rig ``rig`` (1 to 64 ASCII letters, digits, ``-``, ``_``)."""
    if not rig or len(rig) > 64:
        raise ConnectError("InvalidRigName", rig=rig, detail="it must have 1 to 64 characters")
    if not all((c.isascii() and c.isalnum()) or c in "-_" for c in rig):
        raise ConnectError(
            "InvalidRigName",
            rig=rig,
            detail="only ASCII letters, digits, '-' and '_' are allowed",
        )
    return RigServiceNames(
        f"{SERVICE_PREFIX}/{rig}/measurement", f"{SERVICE_PREFIX}/{rig}/actuation"
    )


def pid_alive(pid: int) -> bool:
    """Whether a process with this id exists (signal 0; another user's process counts)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def cleanup_dead_nodes() -> int:
    """Removes the stale resources of every dead iceoryx2 node whose process is gone; returns how many."""
    n = 0
    try:
        states = iox.Node.list(_IPC, iox.config.global_config())
    except Exception:  # a listing failure leaves nothing to clean up
        return 0
    for st in states:
        if not isinstance(st, iox.NodeState.Dead):
            continue
        view = st[0]
        try:
            if not pid_alive(view.id.pid(_IPC)) and view.try_remove_stale_resources():
                n += 1
        except Exception:  # another process is cleaning it up
            pass
    return n


@dataclass
class _Holder:
    pid: "int | None"
    node: "str | None"
    alive: bool

    def __str__(self):
        s = f"pid {self.pid}" if self.pid is not None else "a process of unknown pid"
        if self.node is not None:
            s += f" (node '{self.node}')"
        if not self.alive:
            s += ", which is dead"
        return s


def _describe(holders: list) -> str:
    if not holders:
        return "a process that is no longer listed"
    return " and ".join(str(h) for h in holders)


def _holders(factory, own_node, name_hint: "str | None") -> list:
    """The processes of the nodes attached to ``factory`` other than ``own_node``; those named
    ``name_hint`` when there are such (the bindings list no ports, only nodes)."""
    out = []
    for st in factory.nodes:
        if not isinstance(st, (iox.NodeState.Alive, iox.NodeState.Dead)):
            continue
        view = st[0]
        if view.id.value == own_node.id.value:
            continue
        details = view.details
        pid = view.id.pid(_IPC)
        out.append(
            _Holder(
                pid,
                details.name.as_str() if details is not None else None,
                isinstance(st, iox.NodeState.Alive) and pid_alive(pid),
            )
        )
    named = [h for h in out if name_hint is not None and h.node == name_hint]
    return named or out


def _exclusive_port(create, full_variant: str, holders, refuse, what_item):
    """Creates a port whose slot is exclusive; a dead holder is cleaned up and retried, a live
    one refused with ``refuse(description)``."""
    start = time.monotonic()
    while True:
        try:
            return create()
        except Exception as e:  # iceoryx2 raises its own exception types
            if _variant(e) != full_variant:
                raise _ipc_err(what_item[0], what_item[1], e) from None
            h = holders()
            live = [x for x in h if x.alive]
            if live:
                raise refuse(_describe(live)) from None
            if time.monotonic() - start >= STALE_SLOT_RETRY_S:
                raise refuse(f"{_describe(h)} (its stale port could not be removed)") from None
            cleanup_dead_nodes()
            time.sleep(0.02)


class _Waiter:
    """The wait for the peer: Rust's ``wait_a_little`` (5 ms steps, ``PeerTimeout``)."""

    def __init__(self, timeout_s: float, shutdown):
        self.timeout_s = timeout_s
        self.shutdown = shutdown

    def wait(self, start: float, name: str):
        if self.shutdown is not None and self.shutdown():
            raise ConnectError("Interrupted")
        waited = time.monotonic() - start
        if waited >= self.timeout_s:
            raise ConnectError("PeerTimeout", service=name, waited=waited)
        time.sleep(0.005)


def _pubsub_builder(node, name: str, payload):
    return (
        node.service_builder(iox.ServiceName.new(name))
        .publish_subscribe(payload)
        .max_publishers(1)
        .max_subscribers(1)
        .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
        .history_size(0)
        .enable_safe_overflow(True)
    )


def _verify(existing: ContractInfo, own: ContractInfo, service: str):
    d = own.differences(existing)
    if d:
        raise ConnectError("Mismatch", service=service, holder=existing.side, differences=d)


def _verify_exclusive(factory, name: str):
    c = factory.static_config
    if c.max_publishers != 1 or c.max_subscribers != 1:
        raise ConnectError(
            "NotExclusive",
            service=name,
            detail=f"admits {c.max_publishers} publishers and {c.max_subscribers} subscribers",
        )


def _open_own(node, name, payload, own: ContractInfo, waiter: _Waiter):
    start = time.monotonic()
    while True:
        try:
            f = _pubsub_builder(node, name, payload).open()
            existing = ContractInfo.from_attributes(f.attributes, name)
            # The service may survive a crash of this side, held open by the peer.
            existing.side = own.side
            _verify(existing, own, name)
            _verify_exclusive(f, name)
            return f
        except ConnectError:
            raise
        except Exception as e:
            v = _variant(e)
            if v == "IncompatibleTypes":
                raise ConnectError("IncompatibleType", service=name) from None
            if v not in ("DoesNotExist", "IsMarkedForDestruction"):
                raise _ipc_err("opening", name, e) from None
        try:
            return _pubsub_builder(node, name, payload).create_with_attributes(own.specifier())
        except Exception as e:
            if _variant(e) not in ("AlreadyExists", "IsBeingCreatedByAnotherInstance"):
                raise _ipc_err("creating", name, e) from None
        waiter.wait(start, name)


def _open_peer(node, name, payload, own: ContractInfo, waiter: _Waiter):
    start = time.monotonic()
    last_cleanup = start
    while True:
        try:
            f = _pubsub_builder(node, name, payload).open()
            peer = ContractInfo.from_attributes(f.attributes, name)
            if peer.side != Side.peer(own.side):
                raise ConnectError(
                    "NotAContractService",
                    service=name,
                    detail=f"it was created by a {peer.side}, expected the {Side.peer(own.side)}",
                )
            _verify(peer, own, name)
            _verify_exclusive(f, name)
            return f, peer
        except ConnectError:
            raise
        except Exception as e:
            v = _variant(e)
            if v == "HangsInCreation":
                if time.monotonic() - last_cleanup >= 1.0:
                    cleanup_dead_nodes()
                    last_cleanup = time.monotonic()
            elif v == "IncompatibleTypes":
                raise ConnectError("IncompatibleType", service=name) from None
            elif v not in ("DoesNotExist", "IsMarkedForDestruction"):
                raise _ipc_err("opening", name, e) from None
        waiter.wait(start, name)


def _open_event(node, name: str):
    try:
        f = (
            node.service_builder(iox.ServiceName.new(name))
            .event()
            .max_notifiers(1)
            .max_listeners(1)
            .open_or_create()
        )
    except Exception as e:
        raise _ipc_err("opening the event service", name, e) from None
    c = f.static_config
    if c.max_notifiers != 1 or c.max_listeners != 1:
        raise ConnectError(
            "NotExclusive",
            service=f"{name} (event)",
            detail=f"admits {c.max_notifiers} notifiers and {c.max_listeners} listeners",
        )
    return f


@dataclass
class Ports:
    """The ports of one side: publishes ``Out``, receives ``In``, notifies after each send."""

    publisher: object
    subscriber: object
    notifier: object
    listener: object
    peer: ContractInfo
    pin: PeerPin
    in_type: type
    rig: str
    _keep: list = field(default_factory=list, repr=False)

    def send(self, payload) -> None:
        """Publishes ``payload`` (a ``Measurement`` or ``Actuation``) and notifies the peer."""
        self.publisher.send_copy(payload)
        self.notifier.notify()

    def receive(self) -> list:
        """Copies of every pending sample of the pinned peer, oldest first, as ``(origin, payload)``.

        ``origin`` is ``peer.PEER`` or ``peer.NEW_PEER``; samples of other publishers are
        refused and counted (``self.pin.foreign_samples``)."""
        out = []
        size = ctypes.sizeof(self.in_type)
        while True:
            s = self.subscriber.receive()
            if s is None:
                return out
            origin = self.pin.admit(s.header.publisher_id.value)
            if origin != FOREIGN:
                v = self.in_type()
                ctypes.memmove(ctypes.addressof(v), s.payload_ptr, size)
                out.append((origin, v))
            s.delete()

    def wait(self, timeout_s: float) -> None:
        """Waits up to ``timeout_s`` (at least 1 ms) for the peer's notification (or sleeps
        when this side has no listener)."""
        t = max(timeout_s, 0.001)
        if self.listener is None:
            time.sleep(t)
        else:
            self.listener.timed_wait(iox.Duration.from_secs_f64(t))

    @property
    def foreign_samples(self) -> int:
        """Samples refused as foreign so far."""
        return self.pin.foreign_samples

    @property
    def new_peers(self) -> int:
        """How many times a new peer replaced the pinned one."""
        return self.pin.new_peers

    def close(self) -> None:
        """Releases the ports and the node (also done when the process exits)."""
        for p in (self.subscriber, self.listener, self.notifier, self.publisher):
            if p is not None:
                p.delete()
        self._keep.clear()


def connect(
    rig: str,
    own: ContractInfo,
    node_name: str,
    peer_timeout_s: float,
    listen: bool = False,
    waiting_message: "str | None" = None,
    shutdown=None,
) -> Ports:
    """Connects as ``own.side`` to rig ``rig`` (see the module docs); raises :class:`ConnectError`.

    ``peer_timeout_s``: how long to wait for the peer; ``listen``: create a listener on the
    peer's event service (for blocking waits); ``waiting_message``: printed to stderr once
    this side's own service exists; ``shutdown``: a callable that returns True to abandon
    the wait (``Interrupted``)."""
    names = service_names(rig)
    if own.side == Side.PLANT:
        own_name, peer_name, out_t, in_t = names.measurement, names.actuation, Measurement, Actuation
    else:
        own_name, peer_name, out_t, in_t = names.actuation, names.measurement, Actuation, Measurement
    iox.set_log_level(iox.LogLevel.Error)
    cleanup_dead_nodes()
    try:
        node = (
            iox.NodeBuilder.new()
            .name(iox.NodeName.new(node_name))
            .signal_handling_mode(iox.SignalHandlingMode.Disabled)
            .create(_IPC)
        )
    except Exception as e:
        raise _ipc_err("creating the node", node_name, e) from None
    waiter = _Waiter(peer_timeout_s, shutdown)

    own_service = _open_own(node, own_name, out_t, own, waiter)
    publisher = _exclusive_port(
        lambda: own_service.publisher_builder().max_loaned_samples(2).create(),
        "ExceedsMaxSupportedPublishers",
        lambda: _holders(own_service, node, node_name),
        lambda holder: ConnectError(
            "AlreadyRunning", rig=rig, side=own.side, service=own_name, holder=holder
        ),
        ("creating the publisher of", own_name),
    )
    if waiting_message is not None:
        print(waiting_message, file=sys.stderr, flush=True)
    try:
        peer_service, peer = _open_peer(node, peer_name, in_t, own, waiter)
    except ConnectError as e:
        if e.kind == "Mismatch":
            # Keep this side's service up a moment, so that a peer polling for it also finds
            # it and reports the same mismatch instead of timing out.
            until = time.monotonic() + MISMATCH_LINGER_S
            while time.monotonic() < until and not (shutdown is not None and shutdown()):
                time.sleep(0.01)
            publisher.delete()
        raise

    own_event = _open_event(node, own_name)
    peer_event = _open_event(node, peer_name)

    def event_port(event, name: str, port: str, create, full_variant: str):
        return _exclusive_port(
            create,
            full_variant,
            lambda: _holders(event, node, None),
            lambda holder: ConnectError(
                "SlotTaken", service=f"{name} (event)", port=port, reserved_for=own.side, holder=holder
            ),
            (f"creating the {port} of", name),
        )

    notifier = event_port(
        own_event, own_name, "notifier", lambda: own_event.notifier_builder().create(), "ExceedsMaxSupportedNotifiers"
    )
    listener = None
    if listen:
        listener = event_port(
            peer_event,
            peer_name,
            "listener",
            lambda: peer_event.listener_builder().create(),
            "ExceedsMaxSupportedListeners",
        )
    # The subscriber comes last: a peer that sees it knows this side's listener exists.
    subscriber = _exclusive_port(
        lambda: peer_service.subscriber_builder().create(),
        "ExceedsMaxSupportedSubscribers",
        lambda: _holders(peer_service, node, None),
        lambda holder: ConnectError(
            "SlotTaken",
            service=peer_name,
            port="subscriber",
            reserved_for=own.side,
            holder=holder,
        ),
        ("creating the subscriber of", peer_name),
    )
    # The peer's publisher, then the peer's subscriber on this side's service.
    start = time.monotonic()
    while peer_service.dynamic_config.number_of_publishers < 1:
        waiter.wait(start, peer_name)
    start = time.monotonic()
    while own_service.dynamic_config.number_of_subscribers < 1:
        waiter.wait(start, own_name)
    peer_nodes = [
        st[0]
        for st in peer_service.nodes
        if isinstance(st, iox.NodeState.Alive) and st[0].id.value != node.id.value
    ]
    peer_pid = peer_nodes[0].id.pid(_IPC) if len(peer_nodes) == 1 else None
    publisher.update_connections()
    return Ports(
        publisher=publisher,
        subscriber=subscriber,
        notifier=notifier,
        listener=listener,
        peer=peer,
        pin=PeerPin(0, peer_pid),
        in_type=in_t,
        rig=rig,
        _keep=[node, own_service, peer_service, own_event, peer_event],
    )
