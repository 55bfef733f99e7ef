"""asyncio MAVLink transport: UDP, TCP and serial links with pymavlink's generated codec.

No ``mavutil`` (it changes process-wide state), no threads, no blocking calls on the loop.
Connection strings follow ArduPilot/mavutil usage:

- ``udpin:HOST:PORT``  bind and listen; replies go to every peer heard from (up to 16), or,
  after :meth:`MavlinkLink.set_peer`, only to the address one (system, component) speaks from;
- ``udpout:HOST:PORT`` send to HOST:PORT; replies arrive on our ephemeral port;
- ``tcp:HOST:PORT``    TCP client that reconnects (1 s back-off) when the peer goes away;
- ``tcpin:HOST:PORT``  TCP server; sends go to every connected client (used by simulators);
- ``DEV[:BAUD]``       a serial device (``/dev/ttyACM0:115200``), raw mode, non-blocking fd,
  reopened every second after a failure (a USB autopilot rebooting); ``serial:DEV[:BAUD]``
  is accepted too.

A link parses what it receives into pymavlink messages (bad frames are counted, never
raised) and queues them for :meth:`MavlinkLink.recv`; a flood beyond ``max_pending``
messages drops the oldest ones (counted). A link opened with ``message_ids`` drops frames of
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
import math
import os
import socket
import termios
import time
import tty
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import Unavailable, UserError
from estimator.mavlink.signing import LinkSigning, SigningCodec
from estimator.telemetry.decode import FrameParser, message_source

log = logging.getLogger(__name__)

#: Most UDP peers a ``udpin`` link answers; the oldest is forgotten beyond this.
MAX_UDP_PEERS = 16
#: Seconds between attempts to reconnect a TCP client or reopen a serial device.
TCP_RECONNECT_S = 1.0
UDP_RECEIVE_BUFFER_BYTES = 1 << 20
#: A udpin link's pinned peer silent this long (s) may be replaced by the address its
#: (system, component) now speaks from (an autopilot restarted on another port).
REPIN_AFTER_S = 3.0
#: errno values of a serial device that may come back: missing, unplugged, busy, failing.
_DEVICE_MAY_COME_BACK = frozenset(
    {errno.ENOENT, errno.ENODEV, errno.ENXIO, errno.EBUSY, errno.EIO, errno.EAGAIN}
)
#: Datagrams read at one wake-up of the loop at most, and the largest one read whole.
UDP_DATAGRAMS_PER_WAKE = 64
UDP_DATAGRAM_MAX_BYTES = 65_535
DEFAULT_BAUD = 115200
_BAUD_RATES = {
    int(name[1:]): getattr(termios, name)
    for name in dir(termios)
    if name.startswith("B") and name[1:].isdigit()
}


@dataclass(frozen=True, slots=True)
class LinkAddress:
    """A parsed connection string. ``kind`` is udpin, udpout, tcp, tcpin or serial."""

    kind: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = DEFAULT_BAUD

    def __str__(self) -> str:
        if self.kind == "serial":
            return f"{self.device}:{self.baud}"
        return f"{self.kind}:{self.host}:{self.port}"


def parse_url(url: str) -> LinkAddress:
    """Parse a connection string; a malformed one is a UserError naming the accepted forms."""
    forms = "udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or DEV[:BAUD]"
    text = url.strip()
    kind, _, rest = text.partition(":")
    if kind in ("udpin", "udpout", "tcp", "tcpin"):
        host, sep, port_text = rest.rpartition(":")
        if not sep or not host or not port_text.isdigit() or not 0 <= int(port_text) < 65536:
            raise UserError(f"connection string {url!r} is not valid: use {forms}")
        return LinkAddress(kind, host=host, port=int(port_text))
    if kind == "serial":
        text = rest
    device, sep, baud_text = text.rpartition(":")
    if not sep:
        device, baud_text = text, str(DEFAULT_BAUD)
    if not device.startswith("/") or not baud_text.isdigit():
        raise UserError(f"connection string {url!r} is not valid: use {forms}")
    if int(baud_text) not in _BAUD_RATES:
        raise UserError(f"serial baud rate {baud_text} in {url!r} is not a standard rate")
    return LinkAddress("serial", device=device, baud=int(baud_text))


class MavlinkLink:
    """One MAVLink connection: received messages queue up for :meth:`recv`; :meth:`send`
    packs with our ids. Counters: ``counts['bad_frames']``, ``['dropped']`` (queue overflow),
    ``['rx_messages']``, ``['tx_messages']``, ``['tx_dropped']`` (no peer / not connected),
    ``['reconnects']``, ``['skipped_frames']`` (ids outside ``message_ids``),
    ``['foreign_peer']`` (udpin datagrams carrying the peer's ids from another address,
    dropped)."""

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

    # -- receiving --------------------------------------------------------------------------

    def parser(self, stream: bool) -> FrameParser:
        """A frame parser for this link's transport (``stream``: TCP, serial), checking
        signatures when the link signs."""
        codec = None if self.signing is None else SigningCodec(self.signing)
        return FrameParser(self.message_ids, stream, codec)

    def set_peer(self, source: tuple[int, int] | None) -> None:
        """``udpin`` only: answer only the address ``source`` (system, component) speaks
        from, and drop datagrams carrying its ids from any other address (counted in
        ``foreign_peer``) unless that address was silent for :data:`REPIN_AFTER_S`.
        None: answer every peer again. Other links are point to point: no effect."""
        if self._transport is not None:
            self._transport.set_peer(source)

    def _deliver(
        self, messages: list[mavlink.MAVLink_message], bad_frames: int, skipped_frames: int = 0
    ) -> None:
        """Called by the transport with each parsed chunk."""
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
) -> MavlinkLink:
    """Open a link from a connection string (see the module docstring). With
    ``message_ids``, frames of other ids are dropped unparsed (:class:`FrameParser`);
    ``signing``: sign what we send and check what we receive with it.

    A serial device that is missing or busy (it may come back: USB unplugged, another
    program holding it) is :class:`~estimator.errors.Unavailable`; failing to bind, or a
    device that is not a serial port, is a UserError; a ``tcp`` client that cannot connect yet
    keeps trying in the background (sends are dropped and counted meanwhile).
    """
    address = parse_url(url)
    link = MavlinkLink(address, source_system, source_component, max_pending, message_ids, signing)
    opener = {
        "udpin": _UdpTransport.open,
        "udpout": _UdpTransport.open,
        "tcp": _TcpClientTransport.open,
        "tcpin": _TcpServerTransport.open,
        "serial": _SerialTransport.open,
    }[address.kind]
    try:
        link._transport = await opener(link)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        if address.kind == "serial" and exc.errno in _DEVICE_MAY_COME_BACK:
            raise Unavailable(f"cannot open {url}: {reason}") from None
        raise UserError(f"cannot open {url}: {reason}") from None
    return link


# -- transports ---------------------------------------------------------------------------------


class _Transport:
    async def close(self) -> None:
        raise NotImplementedError

    def local_address(self) -> tuple[str, int] | None:
        return None

    def write(self, data: bytes) -> bool:
        """Queue ``data`` for sending; False when there is nowhere to send it."""
        raise NotImplementedError

    def set_peer(self, source: tuple[int, int] | None) -> None:
        """See :meth:`MavlinkLink.set_peer` (point-to-point transports ignore it)."""


class _StreamProtocol(asyncio.Protocol):
    """A byte stream (TCP connection) with its own frame parser."""

    def __init__(self, link: MavlinkLink, on_lost: Any = None) -> None:
        self.link = link
        self.parser = link.parser(stream=True)
        self.transport: asyncio.Transport | None = None
        self.lost = asyncio.get_running_loop().create_future()
        self._on_lost = on_lost

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport

    def data_received(self, data: bytes) -> None:
        parser = self.parser
        bad, skipped = parser.bad_frames, parser.skipped_frames
        messages = parser.feed(data)
        self.link._deliver(messages, parser.bad_frames - bad, parser.skipped_frames - skipped)

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None
        if not self.lost.done():
            self.lost.set_result(None)
        if self._on_lost is not None:
            self._on_lost(self)


class _Peers:
    """A udpin link's peers: every address heard from (up to :data:`MAX_UDP_PEERS`), or the
    one address a chosen (system, component) speaks from."""

    def __init__(self, link: MavlinkLink) -> None:
        self.link = link
        self.every: dict[Any, None] = {}
        self.source: tuple[int, int] | None = None
        self.pinned: Any = None
        self.pinned_heard_s = -math.inf
        self._last: tuple[Any, set[tuple[int, int]]] | None = None  # latest datagram's

    def choose(self, source: tuple[int, int] | None) -> None:
        """Answer only ``source``: pinned at once when the datagram being delivered is its."""
        self.source, self.pinned, self.pinned_heard_s = source, None, -math.inf
        if source is not None and self._last is not None and source in self._last[1]:
            self.pinned, self.pinned_heard_s = self._last[0], time.monotonic()

    def heard(self, addr: Any, messages: list[mavlink.MAVLink_message]) -> bool:
        """Note a datagram's sender; False to drop it (the chosen ids from a foreign address)."""
        sources = {message_source(m) for m in messages}
        self._last = addr, sources
        if self.source in sources:
            now_s = time.monotonic()
            if addr != self.pinned:
                if now_s - self.pinned_heard_s < REPIN_AFTER_S:
                    return False
                if self.pinned is not None:
                    log.warning(
                        "udpin %s: system %d component %d now speaks from %s (was %s)",
                        self.link.url,
                        *self.source,
                        addr,
                        self.pinned,
                    )
                self.pinned = addr
            self.pinned_heard_s = now_s
        if addr not in self.every:
            self.every[addr] = None
            if len(self.every) > MAX_UDP_PEERS:
                del self.every[next(iter(self.every))]
        return True

    def targets(self) -> list[Any]:
        if self.source is None:
            return list(self.every)
        return [] if self.pinned is None else [self.pinned]


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
        return cls(link, sock, _Peers(link) if addr.kind == "udpin" else None)

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
        if self.peers is not None and messages and not self.peers.heard(peer, messages):
            self.link.counts["foreign_peer"] += 1
            messages = []
        self.link._deliver(messages, parser.bad_frames - bad, parser.skipped_frames - skipped)

    def set_peer(self, source: tuple[int, int] | None) -> None:
        if self.peers is not None and source != self.peers.source:
            self.peers.choose(source)

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


def _open_tty(device: str, baud: int) -> int:
    """Open ``device`` raw, non-blocking, at ``baud``; OSError when it is not a tty."""
    fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        tty.setraw(fd)
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = _BAUD_RATES[baud]  # ispeed, ospeed
        attrs[2] |= termios.CLOCAL | termios.CREAD
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
    except termios.error as exc:
        os.close(fd)
        raise OSError(f"{device} is not a serial port ({exc})") from None
    return fd


class _SerialTransport(_Transport):
    """A tty in raw mode on a non-blocking fd, read with ``loop.add_reader``.

    When the device fails or hangs up (a USB autopilot rebooting), it is closed and reopened
    every second until it is back (``counts['reconnects']``)."""

    def __init__(self, link: MavlinkLink, fd: int) -> None:
        self.link = link
        self.fd: int | None = None
        self.parser = link.parser(stream=True)
        self.out = bytearray()
        self.loop = asyncio.get_running_loop()
        self.reopen_task: asyncio.Task[None] | None = None
        self._attach(fd)

    @classmethod
    async def open(cls, link: MavlinkLink) -> _SerialTransport:
        return cls(link, _open_tty(link.address.device, link.address.baud))

    def _attach(self, fd: int) -> None:
        self.fd = fd
        self.parser = self.link.parser(stream=True)
        self.loop.add_reader(fd, self._readable)

    def _detach(self, reason: str) -> None:
        """Drop the fd after a failure and start reopening the device."""
        if self.fd is None:
            return
        log.warning("serial %s: %s, reopening", self.link.address.device, reason)
        self.link.counts["socket_errors"] += 1
        self._close_fd()
        if not self.link.closed:
            self.reopen_task = self.loop.create_task(self._reopen())

    async def _reopen(self) -> None:
        addr = self.link.address
        while not self.link.closed:
            await asyncio.sleep(TCP_RECONNECT_S)
            try:
                fd = _open_tty(addr.device, addr.baud)
            except OSError:
                continue
            self.link.counts["reconnects"] += 1
            log.info("serial %s: reopened", addr.device)
            self._attach(fd)
            return

    def _readable(self) -> None:
        assert self.fd is not None
        try:
            data = os.read(self.fd, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            self._detach(f"read failed ({exc.strerror or exc})")
            return
        if not data:
            self._detach("hung up")
            return
        parser = self.parser
        bad, skipped = parser.bad_frames, parser.skipped_frames
        messages = parser.feed(data)
        self.link._deliver(messages, parser.bad_frames - bad, parser.skipped_frames - skipped)

    def write(self, data: bytes) -> bool:
        if self.fd is None:
            return False
        if self.out:
            self.out.extend(data)
            return True
        try:
            n = os.write(self.fd, data)
        except BlockingIOError:
            n = 0
        except OSError:
            return False
        if n < len(data):
            self.out.extend(data[n:])
            self.loop.add_writer(self.fd, self._writable)
        return True

    def _writable(self) -> None:
        assert self.fd is not None
        try:
            n = os.write(self.fd, self.out)
        except BlockingIOError:
            return
        except OSError:
            self.out.clear()
            n = 0
        del self.out[:n]
        if not self.out:
            self.loop.remove_writer(self.fd)

    def _close_fd(self) -> None:
        if self.fd is None:
            return
        self.loop.remove_reader(self.fd)
        if self.out:
            self.loop.remove_writer(self.fd)
            self.out.clear()
        os.close(self.fd)
        self.fd = None

    async def close(self) -> None:
        if self.reopen_task is not None:
            self.reopen_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.reopen_task
        self._close_fd()
