"""A service shell without Zenoh, for testing the service classes in-process.

It is the real ``services.common.ServiceShell`` (its decoding, its dropping and counting of bad messages)
over a fake session: publishers record what is put, subscriptions keep their callbacks (or, with a ring
handler, the newest sample, as Zenoh's RingChannel(1) does; with a FIFO handler, every sample in order),
and a test delivers bytes to a key as Zenoh would.
"""

from __future__ import annotations

import logging
from collections import defaultdict
from dataclasses import dataclass

import zenoh

from services.common import ServiceShell
from shared.wire.keys import KeySpace
from shared.wire.messages import Message, decode, encode


@dataclass
class _Payload:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class _Sample:
    key_expr: str
    payload: _Payload


class _Publisher:
    def __init__(self, sink: list[bytes]) -> None:
        self.sink = sink

    def put(self, data: bytes) -> None:
        self.sink.append(bytes(data))


class _Ring:
    """A subscriber with a ring of one: try_recv gives the newest sample once, then None."""

    def __init__(self) -> None:
        self.sample = None

    def try_recv(self):
        sample, self.sample = self.sample, None
        return sample

    def undeclare(self) -> None:
        pass


class _Fifo:
    """A subscriber with a queue: try_recv gives the oldest sample not taken yet, then None."""

    def __init__(self) -> None:
        self.samples: list = []

    def try_recv(self):
        return self.samples.pop(0) if self.samples else None

    def undeclare(self) -> None:
        pass


class FakeSession:
    """declare_publisher / declare_subscriber as zenoh.Session has them, in memory."""

    def __init__(self) -> None:
        self.sent: dict[str, list[bytes]] = defaultdict(list)
        self.callbacks: dict[str, list] = defaultdict(list)
        self.rings: dict[str, list[_Ring]] = defaultdict(list)
        self.fifos: dict[str, list[_Fifo]] = defaultdict(list)

    def declare_publisher(self, key: str) -> _Publisher:
        return _Publisher(self.sent[key])

    def declare_subscriber(self, key: str, handler):
        if isinstance(handler, zenoh.handlers.RingChannel):
            ring = _Ring()
            self.rings[key].append(ring)
            return ring
        if isinstance(handler, zenoh.handlers.FifoChannel):
            fifo = _Fifo()
            self.fifos[key].append(fifo)
            return fifo
        self.callbacks[key].append(handler)
        return self

    def undeclare(self) -> None:
        pass

    def close(self) -> None:
        pass


class FakeShell(ServiceShell):
    """ServiceShell over a FakeSession (no network, no liveliness)."""

    def __init__(self, name: str, prefix: str = "test/fake") -> None:      # noqa: D401 - no Zenoh to open
        self.name = name
        self.log = logging.getLogger(name)
        self.keys = KeySpace(prefix)
        self.session = FakeSession()
        self.token = None
        self.bad_messages = 0
        self._last_bad_log = -1e9
        self._subscribers = []

    def deliver(self, key: str, message: Message | bytes) -> None:
        """Hand a message (or raw bytes) to every subscription on key, as Zenoh would."""
        data = message if isinstance(message, bytes) else encode(message)
        for callback in self.session.callbacks[key]:
            callback(_Sample(key, _Payload(data)))
        for ring in self.session.rings[key]:
            ring.sample = _Sample(key, _Payload(data))
        for fifo in self.session.fifos[key]:
            fifo.samples.append(_Sample(key, _Payload(data)))

    def published(self, key: str, kind: type[Message]) -> list:
        """Every message put on key so far, decoded."""
        return [decode(data, kind) for data in self.session.sent[key]]
