"""Connection strings (``udpin:HOST:PORT``, ``DEV[:BAUD]``, … as
:mod:`estimator.mavlink.link` describes them) parsed into a :class:`LinkAddress`, without
importing the link itself (asyncio, pymavlink): a configuration is checked by commands that
open no link (``uav-energy replay``).
"""

from __future__ import annotations

import termios
from dataclasses import dataclass

from estimator.errors import UserError

DEFAULT_BAUD = 115200
#: Standard baud rates and their termios constants.
BAUD_RATES = {
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


def parse_url(url: str, listen: bool = True) -> LinkAddress:
    """Parse a connection string; a malformed one is a UserError naming the accepted forms.
    ``listen``: ``udp:`` binds (``udpin``) when true, sends (``udpout``) when false, as
    pymavlink's ``mavlink_connection(..., input=listen)``."""
    forms = (
        "udpin:HOST:PORT, udpout:HOST:PORT, udp:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT, "
        "DEV[:BAUD] or DEV,BAUD"
    )
    text = url.strip()
    kind, _, rest = text.partition(":")
    if kind == "udp":
        kind = "udpin" if listen else "udpout"
    if kind in ("udpin", "udpout", "tcp", "tcpin"):
        host, sep, port_text = rest.rpartition(":")
        if not sep or not host or not port_text.isdigit() or not 0 <= int(port_text) < 65536:
            raise UserError(f"connection string {url!r} is not valid: use {forms}")
        return LinkAddress(kind, host=host, port=int(port_text))
    if kind == "serial":
        text = rest
    device, sep, baud_text = text.rpartition("," if "," in text else ":")
    if not sep:
        device, baud_text = text, str(DEFAULT_BAUD)
    if not device.startswith("/") or not baud_text.isdigit():
        raise UserError(f"connection string {url!r} is not valid: use {forms}")
    if int(baud_text) not in BAUD_RATES:
        raise UserError(f"serial baud rate {baud_text} in {url!r} is not a standard rate")
    return LinkAddress("serial", device=device, baud=int(baud_text))
