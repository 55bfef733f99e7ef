"""The daemon's estimates as JSON objects (:func:`estimator.mavlink.publish.json_line`): a
datagram each to ``udp:HOST:PORT``, or a line each on stdout (``-``). The event loop never
blocks on a slow reader: lines beyond :data:`JSON_BUFFER_LIMIT_BYTES` waiting in a pipe are
dropped and counted; a regular file gets blocking writes (a file never stalls long)."""

from __future__ import annotations

import asyncio
import sys

from estimator.estimation.estimate import Estimate
from estimator.mavlink import publish
from estimator.mavlink.link_address import parse_url

#: JSON lines waiting for a slow stdout reader beyond this are dropped (counted).
JSON_BUFFER_LIMIT_BYTES = 1 << 20


class JsonOutput:
    """Where the JSON estimates go (``target``: ``udp:HOST:PORT`` or ``-`` for stdout)."""

    def __init__(self, target: str) -> None:
        self.target = target
        self._udp: asyncio.DatagramTransport | None = None
        self._pipe: asyncio.WriteTransport | None = None
        self.dropped = 0

    async def open(self) -> None:
        """The UDP endpoint, or a non-blocking transport on stdout (none for a regular
        file)."""
        loop = asyncio.get_running_loop()
        if self.target.startswith("udp:"):
            addr = parse_url("udpout:" + self.target[4:])
            self._udp, _ = await loop.create_datagram_endpoint(
                asyncio.DatagramProtocol, remote_addr=(addr.host, addr.port)
            )
        elif self.target == "-":
            try:
                self._pipe, _ = await loop.connect_write_pipe(asyncio.Protocol, sys.stdout)
            except (ValueError, OSError, AttributeError):
                self._pipe = None  # stdout is a regular file

    def write(self, estimate: Estimate) -> None:
        """One estimate as a JSON object."""
        line = publish.json_line(estimate)
        if self._udp is not None:
            self._udp.sendto(line.encode())
        elif self._pipe is not None:
            if self._pipe.get_write_buffer_size() > JSON_BUFFER_LIMIT_BYTES:
                self.dropped += 1
                return
            self._pipe.write((line + "\n").encode())
        else:
            sys.stdout.write(line + "\n")
            sys.stdout.flush()

    def close(self) -> None:
        for transport in (self._udp, self._pipe):
            if transport is not None:
                transport.close()
