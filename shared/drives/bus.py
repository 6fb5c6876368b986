"""Opening the CAN bus: python-can interfaces, with what CANopen over them needs.

* socketcan (``vcan0`` on a developer's Linux, ``can0`` on the cell): used as it is.
* udp_multicast (python-can's own interface): the transport of machines without kernel CAN. It must never
  leave the machine, so it is refused unless this process sits in a private network namespace whose only
  interface is ``lo`` (the launcher or test makes it with ``unshare``). Such a bus also receives the
  frames it sends, which a CAN controller does not: in CANopen every COB-ID has exactly one producer, so
  ``OwnFrameFilter`` drops received frames with an identifier this process has itself sent: in the kernel
  where it can (``shared.drives.echo_filter``, a socket filter), and in Python for whatever passes.
"""

from __future__ import annotations

import logging
import socket
import threading

import can

from shared.core.errors import HrcError
from shared.drives import echo_filter

log = logging.getLogger(__name__)

ECHOING_INTERFACES = {"udp_multicast"}
DEFAULT_MULTICAST_GROUP = "239.74.163.2"


class BusError(HrcError):
    """The bus cannot be opened (or must not be, here)."""


def network_interfaces() -> list[str]:
    """Interfaces of this process's network namespace (if_nameindex asks the kernel for the current
    namespace; /sys/class/net would show the namespace sysfs was mounted in)."""
    try:
        return sorted(name for _, name in socket.if_nameindex())
    except OSError:
        return []


def in_private_namespace() -> bool:
    """True when the only network interface this process sees is the loopback."""
    return network_interfaces() == ["lo"]


class OwnFrameFilter(can.BusABC):
    """Wraps a bus that echoes sent frames back; drops received frames with an identifier sent here. Each
    new identifier also goes into the socket's kernel filter (when the bus has a socket and the kernel
    takes it), so most echoes never wake the receiving thread."""

    def __init__(self, bus: can.BusABC) -> None:
        self._bus = bus
        self._sent: set[int] = set()
        self.in_kernel = True          # False once the kernel refused the filter: Python alone from then on
        self._lock = threading.Lock()  # send() is called from several threads
        super().__init__(channel=getattr(bus, "channel_info", "filtered"))
        self.channel_info = f"{getattr(bus, 'channel_info', bus)} (own frames filtered)"

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id not in self._sent:
            with self._lock:
                self._sent = self._sent | {msg.arbitration_id}      # a new set: readers never see it change
                self._filter_in_kernel()
        self._bus.send(msg, timeout)

    def _filter_in_kernel(self) -> None:
        if not self.in_kernel:
            return
        try:
            fd = self._bus.fileno()
            if fd < 0:
                raise OSError("the bus has no socket")
            echo_filter.attach(fd, self._sent)
        except (OSError, NotImplementedError, AttributeError) as exc:
            self.in_kernel = False
            log.info("own frames filtered in Python only (no kernel socket filter: %s)", exc)

    def _recv_internal(self, timeout: float | None):
        msg = self._bus.recv(timeout)
        if msg is not None and msg.arbitration_id in self._sent:
            return None, True                       # an echo of our own frame
        return msg, False

    def shutdown(self) -> None:
        self._bus.shutdown()
        super().shutdown()


def open_bus(interface: str, channel: str | None = None) -> can.BusABC:
    """Open a python-can bus by interface name; udp_multicast only inside a private namespace."""
    if interface == "udp_multicast":
        if not in_private_namespace():
            raise BusError("udp_multicast would send multicast out of this machine's interfaces "
                           f"({', '.join(network_interfaces())}); run it only inside a private network namespace "
                           "(e.g. unshare -rn, with only lo up and a 224.0.0.0/4 route on lo)")
        channel = channel or DEFAULT_MULTICAST_GROUP
    try:
        bus = can.Bus(interface=interface, channel=channel)
    except Exception as exc:                 # python-can raises several types for a missing interface
        raise BusError(f"cannot open CAN interface {interface!r} channel {channel!r}: {exc}") from None
    return OwnFrameFilter(bus) if interface in ECHOING_INTERFACES else bus


def describe(interface: str, channel: str | None) -> str:
    return f"{interface}:{channel or DEFAULT_MULTICAST_GROUP if interface == 'udp_multicast' else channel}"
