"""The peer's identity: which publisher a received sample may come from (``ipc_types::peer``).

Each publish-subscribe service of the contract admits one publisher. The Rust side pins the
peer's publisher at connect, from the service's publisher list; the Python bindings of
iceoryx2 0.10 give no publisher list (only the counts), so the Python side pins the
publisher of the **first sample** it receives, from the sample header's publisher id (the
slot admits one publisher, so that is the peer's). From then on, as in Rust:

- the pinned publisher: ``PEER``, use the sample;
- another publisher: the slot admits one, so the pinned one is gone and this is a
  restarted or replaced peer: ``NEW_PEER`` (the pin moves to it);
- the publisher the pin moved away from, or a null id: ``FOREIGN``, refused and counted.

Unlike Rust's ``Sample::origin()``, the header's publisher id is written by the sender.
"""

PEER = "peer"
NEW_PEER = "new-peer"
FOREIGN = "foreign"


class PeerPin:
    """The pinned peer publisher and the counters of what was refused."""

    def __init__(self, publisher: int = 0, pid: "int | None" = None):
        """Pins ``publisher`` (a raw ``UniquePublisherId`` value; 0: pin on the first sample)."""
        self.pinned = publisher
        self.retired = 0
        self.pid = pid
        self.foreign_samples = 0
        self.new_peers = 0

    def admit(self, origin: int) -> str:
        """Where a sample of publisher ``origin`` came from: ``PEER``, ``NEW_PEER`` or ``FOREIGN``."""
        if origin != 0 and origin == self.pinned:
            return PEER
        if origin == 0 or origin == self.retired:
            self.foreign_samples += 1
            return FOREIGN
        if self.pinned == 0:
            self.pinned = origin
            return PEER
        self.retired = self.pinned
        self.pinned = origin
        self.pid = None
        self.new_peers += 1
        return NEW_PEER
