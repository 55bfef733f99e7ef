"""A serial device (a USB or UART autopilot) as a MAVLink link's transport: the tty in raw mode
on a non-blocking fd (``termios``, no pyserial), read with ``loop.add_reader``, reopened
every :data:`REOPEN_S` after a failure or hang-up (a USB autopilot rebooting)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import termios
import tty
from typing import TYPE_CHECKING, Any

from estimator.mavlink.link_address import BAUD_RATES

if TYPE_CHECKING:
    from estimator.mavlink.link import MavlinkLink

log = logging.getLogger(__name__)

#: Seconds between attempts to reopen a device that failed.
REOPEN_S = 1.0


def open_tty(device: str, baud: int) -> int:
    """Open ``device`` raw, non-blocking, at ``baud``; OSError when it is not a tty."""
    fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        tty.setraw(fd)
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = BAUD_RATES[baud]  # ispeed, ospeed
        attrs[2] |= termios.CLOCAL | termios.CREAD
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
    except termios.error as exc:
        os.close(fd)
        raise OSError(f"{device} is not a serial port ({exc})") from None
    return fd


class SerialTransport:
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
    async def open(cls, link: MavlinkLink) -> SerialTransport:
        return cls(link, open_tty(link.address.device, link.address.baud))

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
            await asyncio.sleep(REOPEN_S)
            try:
                fd = open_tty(addr.device, addr.baud)
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

    def local_address(self) -> tuple[str, int] | None:
        return None

    def answer_only(self, peer: Any) -> None:
        """A serial device has one peer: nothing to choose."""
