"""asyncio MAVLink transport: UDP, TCP and serial links with pymavlink's generated codec.

No ``mavutil`` (it changes process-wide state), no threads, no blocking calls on the loop.
Connection strings follow ArduPilot/mavutil usage
(:func:`~estimator.mavlink.link_address.parse_url`):

- ``udpin:HOST:PORT``  bind and listen; replies go to every peer heard from (up to 16), or,
  after :meth:`MavlinkLink.answer_only`, only to one address (or to none);
- ``udpout:HOST:PORT`` send to HOST:PORT; replies arrive on our ephemeral port;
- ``tcp:HOST:PORT``    TCP client that reconnects (1 s back-off) when the peer goes away;
- ``tcpin:HOST:PORT``  TCP server; sends go to every connected client (used by simulators);
- ``udp:HOST:PORT``    as ``mavutil.mavlink_connection`` reads it: ``udpin`` on a link we
  receive from (its default ``input=True``: MAVProxy's ``--master``), ``udpout`` on one we
  publish to (MAVProxy's ``--out``);
- ``DEV[:BAUD]``       a serial device (``/dev/ttyACM0:115200``), raw mode, non-blocking fd,
  reopened every second after a failure (a USB autopilot rebooting); MAVProxy's
  ``DEV,BAUD`` and ``serial:DEV[:BAUD]`` are accepted too.

A link parses what it receives into pymavlink messages (bad frames are counted, never
raised) and queues them for :meth:`MavlinkLink.recv`; a flood beyond ``max_pending``
messages drops the oldest ones (counted); :attr:`MavlinkLink.peer` is the address the chunk
being delivered came from. A link opened with ``message_ids`` drops frames of
other ids by their header, before parsing (``counts['skipped_frames']``). Outgoing messages
are packed with the link's own system/component id and sequence (:attr:`MavlinkLink.mav` is
that encoder), and signed when the link has a :class:`~estimator.mavlink.signing.LinkSigning`
(incoming frames are then checked by it too)::

    link = await open_link("udpin:127.0.0.1:14550", source_system=1, source_component=191)
    link.send(link.mav.heartbeat_encode(18, 8, 0, 0, 4))
    for msg in await link.recv():
        ...
    await link.close()
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import os
import socket
from collections import Counter, deque
from collections.abc import Callable
from typing import Any, Protocol

from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import Unavailable, UserError
from estimator.mavlink.link_address import LinkAddress, parse_url
from estimator.mavlink.serial_device import REOPEN_S, SerialTransport
from estimator.mavlink.signing import LinkSigning, SigningCodec
from estimator.telemetry.frames import FrameParser

log = logging.getLogger(__name__)

#: Most UDP peers a ``udpin`` link answers; the oldest is forgotten beyond this.
MAX_UDP_PEERS = 16
#: Seconds between attempts to reconnect a TCP client.
TCP_RECONNECT_S = REOPEN_S
UDP_RECEIVE_BUFFER_BYTES = 1 << 20
#: Serial devices that appear when a USB autopilot is plugged in (by name, or udev's links):
#: missing at start, they may come yet. Any other missing device (an on-board UART, a
#: misspelt name) is a mistake.
HOT_PLUGGED_NAMES = ("ttyACM", "ttyUSB")
HOT_PLUGGED_LINKS = "/dev/serial/"
#: errno values of a serial device that may come back: missing, unplugged, busy, failing.
_DEVICE_MAY_COME_BACK = frozenset(
    {errno.ENOENT, errno.ENODEV, errno.ENXIO, errno.EBUSY, errno.EIO, errno.EAGAIN}
)
#: Datagrams read at one wake-up of the loop at most, and the largest one read whole.
UDP_DATAGRAMS_PER_WAKE = 64
UDP_DATAGRAM_MAX_BYTES = 65_535


class MavlinkLink:
    """One MAVLink connection: received messages queue up for :meth:`recv`; :meth:`send`
    packs with our ids. Counters: ``counts['bad_frames']``, ``['dropped']`` (queue overflow),
    ``['rx_messages']``, ``['tx_messages']``, ``['tx_dropped']`` (no peer / not connected),
    ``['reconnects']``, ``['skipped_frames']`` (ids outside ``message_ids``)."""

    def __init__(
        self,
        address: LinkAddress,
        source_system: int,
        source_component: int,
        max_pending: int,
        message_ids: frozenset[int] | None = None,
        signing: LinkSigning | None = None,
    ) -> None:
        self.address = address
        self.message_ids = message_ids
        self.mav = mavlink.MAVLink(None, srcSystem=source_system, srcComponent=source_component)
        self.signing = signing
        if signing is not None:
            self.mav.signing = signing
        self.counts: Counter[str] = Counter()
        self._pending: deque[mavlink.MAVLink_message] = deque()
        self._max_pending = max_pending
        self._ready = asyncio.Event()
        self._closed = False
        self._transport: _Transport | None = None
        self._listener: Callable[[list[mavlink.MAVLink_message]], None] | None = None
        #: Where the chunk being delivered came from: a udpin datagram's (host, port), a
        #: tcpin client's address; None on point-to-point links (one peer).
        self.peer: Any = None

    @property
    def url(self) -> str:
        return str(self.address)

    @property
    def local_address(self) -> tuple[str, int] | None:
        """(host, port) we listen on for udpin/tcpin/udpout (useful after binding port 0)."""
        return None if self._transport is None else self._transport.local_address()

    @property
    def bad_frames(self) -> int:
        return self.counts["bad_frames"]

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def shared(self) -> bool:
        """Whether several senders may speak on this link (udpin, tcpin): one is not
        answered before it is chosen. Other links reach the one peer their address names."""
        return self.address.kind in ("udpin", "tcpin")

    # -- receiving --------------------------------------------------------------------------

    def parser(self, stream: bool) -> FrameParser:
        """A frame parser for this link's transport (``stream``: TCP, serial), checking
        signatures when the link signs."""
        codec = None if self.signing is None else SigningCodec(self.signing)
        return FrameParser(self.message_ids, stream, codec)

    def answer_only(self, peer: Any) -> None:
        """``udpin`` only: send only to ``peer`` (an address :attr:`peer` gave), or to nobody
        with None. Other links: no effect."""
        if self._transport is not None:
            self._transport.answer_only(peer)

    def _deliver(
        self,
        messages: list[mavlink.MAVLink_message],
        bad_frames: int,
        skipped_frames: int = 0,
        peer: Any = None,
    ) -> None:
        """Called by the transport with each parsed chunk and the address it came from."""
        self.peer = peer
        if bad_frames:
            self.counts["bad_frames"] += bad_frames
        if skipped_frames:
            self.counts["skipped_frames"] += skipped_frames
        if not messages:
            return
        self.counts["rx_messages"] += len(messages)
        if self._listener is not None:
            self._listener(messages)
            return
        self._pending.extend(messages)
        overflow = len(self._pending) - self._max_pending
        if overflow > 0:
            for _ in range(overflow):
                self._pending.popleft()
            self.counts["dropped"] += overflow
        self._ready.set()

    def set_listener(
        self, listener: Callable[[list[mavlink.MAVLink_message]], None] | None
    ) -> None:
        """Hand each parsed chunk to ``listener`` as it arrives, in the transport's callback
        (no queue, no task switch: the lowest latency); None goes back to :meth:`recv`.
        The listener must not block and should not raise."""
        self._listener = listener

    async def recv(self) -> list[mavlink.MAVLink_message]:
        """Wait for at least one message and return everything queued, oldest first.

        Returns an empty list once the link is closed.
        """
        while not self._pending and not self._closed:
            self._ready.clear()
            await self._ready.wait()
        out = list(self._pending)
        self._pending.clear()
        return out

    # -- sending ----------------------------------------------------------------------------

    def send(self, msg: mavlink.MAVLink_message) -> None:
        """Pack ``msg`` with this link's system/component id and sequence (signed when the
        link signs), and send it."""
        if self.signing is not None:
            self.signing.stamp()
        self.send_bytes(msg.pack(self.mav))

    def send_bytes(self, data: bytes) -> None:
        """Send raw bytes (already-packed frames, or anything a test wants to inject)."""
        if self._closed or self._transport is None or not self._transport.write(data):
            self.counts["tx_dropped"] += 1
            return
        self.counts["tx_messages"] += 1

    async def close(self) -> None:
        """Close the link; pending :meth:`recv` calls return an empty list."""
        if self._closed:
            return
        self._closed = True
        self._ready.set()
        if self._transport is not None:
            await self._transport.close()


async def open_link(
    url: str,
    *,
    source_system: int = 1,
    source_component: int = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER,
    max_pending: int = 10_000,
    message_ids: frozenset[int] | None = None,
    signing: LinkSigning | None = None,
    listen: bool = True,
) -> MavlinkLink:
    """Open a link from a connection string (see the module docstring and :func:`parse_url`
    for ``listen``). With
    ``message_ids``, frames of other ids are dropped unparsed (:class:`FrameParser`);
    ``signing``: sign what we send and check what we receive with it.

    A serial device that is busy or failing, or a missing hot-plugged one (USB: it may come
    back), is :class:`~estimator.errors.Unavailable`; failing to bind, a missing on-board
    port (a mistaken name), or a device that is not a serial port, is a UserError; a ``tcp``
    client that cannot connect yet keeps trying in the background (sends are dropped and
    counted meanwhile).
    """
    address = parse_url(url, listen)
    link = MavlinkLink(address, source_system, source_component, max_pending, message_ids, signing)
    opener = {
        "udpin": _UdpTransport.open,
        "udpout": _UdpTransport.open,
        "tcp": _TcpClientTransport.open,
        "tcpin": _TcpServerTransport.open,
        "serial": SerialTransport.open,
    }[address.kind]
    try:
        link._transport = await opener(link)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        if address.kind == "serial" and exc.errno == errno.ENOENT:
            device = address.device
            if not (
                os.path.basename(device).startswith(HOT_PLUGGED_NAMES)
                or device.startswith(HOT_PLUGGED_LINKS)
            ):
                raise UserError(f"serial device {device} does not exist") from None
        if address.kind == "serial" and exc.errno in _DEVICE_MAY_COME_BACK:
            raise Unavailable(f"cannot open {url}: {reason}") from None
        raise UserError(f"cannot open {url}: {reason}") from None
    return link


# -- transports ---------------------------------------------------------------------------------


class _Transport(Protocol):
    """What a link needs of its transport (the serial one:
    :class:`~estimator.mavlink.serial_device.SerialTransport`)."""

    async def close(self) -> None:
        raise NotImplementedError

    def local_address(self) -> tuple[str, int] | None:
        return None

    def write(self, data: bytes) -> bool:
        """Queue ``data`` for sending; False when there is nowhere to send it."""
        raise NotImplementedError

    def answer_only(self, peer: Any) -> None:
        """See :meth:`MavlinkLink.answer_only` (other transports ignore it)."""


class _StreamProtocol(asyncio.Protocol):
    """A byte stream (TCP connection) with its own frame parser."""

    def __init__(self, link: MavlinkLink, on_lost: Any = None) -> None:
        self.link = link
        self.parser = link.parser(stream=True)
        self.transport: asyncio.Transport | None = None
        self.lost = asyncio.get_running_loop().create_future()
        self._on_lost = on_lost
        self.peer: Any = None  # a tcpin client's address

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        if self.link.shared:
            self.peer = transport.get_extra_info("peername")

    def data_received(self, data: bytes) -> None:
        parser = self.parser
        bad, skipped = parser.bad_frames, parser.skipped_frames
        messages = parser.feed(data)
        bad, skipped = parser.bad_frames - bad, parser.skipped_frames - skipped
        self.link._deliver(messages, bad, skipped, self.peer)

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None
        if not self.lost.done():
            self.lost.set_result(None)
        if self._on_lost is not None:
            self._on_lost(self)


class _Peers:
    """A udpin link's peers: every address heard from (up to :data:`MAX_UDP_PEERS`), or the
    one address it answers only (:meth:`MavlinkLink.answer_only`)."""

    def __init__(self) -> None:
        self.every: dict[Any, None] = {}
        self.chosen = False
        self.only: Any = None

    def heard(self, addr: Any) -> None:
        if addr not in self.every:
            self.every[addr] = None
            if len(self.every) > MAX_UDP_PEERS:
                del self.every[next(iter(self.every))]

    def targets(self) -> list[Any]:
        if not self.chosen:
            return list(self.every)
        return [] if self.only is None else [self.only]


class _UdpTransport(_Transport):
    """A non-blocking UDP socket read with ``loop.add_reader``: each wake-up reads every
    datagram waiting (up to :data:`UDP_DATAGRAMS_PER_WAKE`), without asyncio's datagram
    transport and protocol between the socket and the parser. Each datagram is parsed on its
    own, so a truncated frame never swallows the next one: a datagram that leaves part of a
    frame in the parser gets a new parser for the next. ``udpin`` answers the peers heard
    from (or the chosen peer, :class:`_Peers`); ``udpout`` sends to its address from a
    connected socket."""

    def __init__(self, link: MavlinkLink, sock: socket.socket, peers: _Peers | None) -> None:
        self.link = link
        self.sock = sock
        self.peers = peers
        self._parser = link.parser(stream=False)
        self.loop = asyncio.get_running_loop()
        self.loop.add_reader(sock.fileno(), self._readable)

    @classmethod
    async def open(cls, link: MavlinkLink) -> _UdpTransport:
        addr = link.address
        loop = asyncio.get_running_loop()
        infos = await loop.getaddrinfo(addr.host, addr.port, type=socket.SOCK_DGRAM)
        if not infos:
            raise OSError(f"cannot resolve {addr.host}")
        family, _, _, _, sockaddr = infos[0]
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if addr.kind == "udpin":
                sock.bind(sockaddr)
                # absorb bursts while the loop is busy (the kernel may cap it)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_RECEIVE_BUFFER_BYTES)
            else:
                sock.connect(sockaddr)
        except OSError:
            sock.close()
            raise
        return cls(link, sock, _Peers() if addr.kind == "udpin" else None)

    def _readable(self) -> None:
        for _ in range(UDP_DATAGRAMS_PER_WAKE):  # then let the loop's other work run
            try:
                data, peer = self.sock.recvfrom(UDP_DATAGRAM_MAX_BYTES)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ICMP port unreachable from a peer that went away: count, go on
                self.link.counts["socket_errors"] += 1
                return
            self._received(data, peer)

    def _received(self, data: bytes, peer: Any) -> None:
        parser = self._parser
        bad, skipped = parser.bad_frames, parser.skipped_frames
        messages = parser.feed(data)
        if parser.holds_partial_frame:  # a truncated datagram: its bytes go with the parser
            self._parser = self.link.parser(stream=False)
        if self.peers is None:
            peer = None
        elif messages:
            self.peers.heard(peer)
        bad, skipped = parser.bad_frames - bad, parser.skipped_frames - skipped
        self.link._deliver(messages, bad, skipped, peer)

    def answer_only(self, peer: Any) -> None:
        if self.peers is not None:
            self.peers.chosen, self.peers.only = True, peer

    def write(self, data: bytes) -> bool:
        targets = [None] if self.peers is None else self.peers.targets()
        if not targets:
            return False
        for peer in targets:
            try:
                if peer is None:
                    self.sock.send(data)
                else:
                    self.sock.sendto(data, peer)
            except (BlockingIOError, InterruptedError):  # send buffer full: datagram lost
                self.link.counts["tx_dropped"] += 1
            except OSError:  # e.g. ICMP port unreachable reported on a connected socket
                self.link.counts["socket_errors"] += 1
        return True

    def local_address(self) -> tuple[str, int] | None:
        host, port = self.sock.getsockname()[:2]
        return str(host), int(port)

    async def close(self) -> None:
        self.loop.remove_reader(self.sock.fileno())
        self.sock.close()


class _TcpClientTransport(_Transport):
    """Connects, and reconnects after a loss, until closed."""

    def __init__(self, link: MavlinkLink) -> None:
        self.link = link
        self.protocol: _StreamProtocol | None = None
        self.task: asyncio.Task[None] | None = None

    @classmethod
    async def open(cls, link: MavlinkLink) -> _TcpClientTransport:
        self = cls(link)
        self.task = asyncio.get_running_loop().create_task(self._run())
        return self

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        addr = self.link.address
        first = True
        while not self.link.closed:
            try:
                _, protocol = await loop.create_connection(
                    lambda: _StreamProtocol(self.link), addr.host, addr.port
                )
            except OSError as exc:
                if first:
                    log.warning(
                        "tcp %s:%d: cannot connect (%s), retrying", addr.host, addr.port, exc
                    )
                first = False
                await asyncio.sleep(TCP_RECONNECT_S)
                continue
            log.info("tcp %s:%d: connected", addr.host, addr.port)
            self.protocol = protocol
            await protocol.lost
            self.protocol = None
            if self.link.closed:
                return
            self.link.counts["reconnects"] += 1
            log.warning("tcp %s:%d: connection lost, reconnecting", addr.host, addr.port)
            first = True
            await asyncio.sleep(TCP_RECONNECT_S)

    def write(self, data: bytes) -> bool:
        protocol = self.protocol
        if protocol is None or protocol.transport is None:
            return False
        protocol.transport.write(data)
        return True

    async def close(self) -> None:
        if self.protocol is not None and self.protocol.transport is not None:
            self.protocol.transport.close()
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task


class _TcpServerTransport(_Transport):
    """Accepts any number of clients; sends go to all of them."""

    def __init__(self, link: MavlinkLink) -> None:
        self.link = link
        self.clients: set[_StreamProtocol] = set()
        self.server: asyncio.Server | None = None

    @classmethod
    async def open(cls, link: MavlinkLink) -> _TcpServerTransport:
        self = cls(link)
        loop = asyncio.get_running_loop()

        def factory() -> _StreamProtocol:
            protocol = _StreamProtocol(link, on_lost=self.clients.discard)
            self.clients.add(protocol)
            return protocol

        self.server = await loop.create_server(
            factory, link.address.host, link.address.port, reuse_address=True
        )
        return self

    def write(self, data: bytes) -> bool:
        sent = False
        for client in list(self.clients):
            if client.transport is not None:
                client.transport.write(data)
                sent = True
        return sent

    def local_address(self) -> tuple[str, int] | None:
        assert self.server is not None
        host, port = self.server.sockets[0].getsockname()[:2]
        return str(host), int(port)

    async def close(self) -> None:
        for client in list(self.clients):
            if client.transport is not None:
                client.transport.close()
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
