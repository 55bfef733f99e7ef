"""MAVLink 2 message signing for the daemon's links: the key file, and a codec that checks
signatures before it trusts their timestamps.

Signing (MAVLink 2 spec, "Message Signing") appends 13 bytes to a frame: a link id, a 48-bit
timestamp in units of 10 µs since 2015-01-01 00:00 UTC, and the first 6 bytes of
SHA-256(secret key ‖ header ‖ payload ‖ CRC ‖ link id ‖ timestamp). pymavlink implements it
(``MAVLink.signing``: ``secret_key``, ``link_id``, ``timestamp``, ``sign_outgoing``,
``allow_unsigned_callback``, ``stream_timestamps``); this module configures it and fixes one
order of checks:

- pymavlink's ``check_signature`` records a stream's timestamp *before* comparing the
  signature, so one forged frame with a wrong signature and a timestamp far ahead would make
  every later genuine frame of that (link id, system, component) look replayed.
  :class:`SigningCodec` compares the signature first; only a frame signed with our key moves
  the stream's timestamp.
- A badly signed frame is never accepted, even when unsigned frames are allowed (pymavlink's
  callback would accept it).

Counters (:attr:`LinkSigning.rejected`): ``bad_signature`` (wrong key or altered frame),
``replayed`` (right key, timestamp not newer than the stream's last, or a new stream more
than a minute behind our clock), ``unsigned`` (an unsigned frame while signing is required);
accepted unsigned frames count in pymavlink's ``unsigned_count``.

Outgoing frames are signed with the link's id and a timestamp that is never behind the wall
clock and grows by one per frame (:meth:`LinkSigning.stamp`).
"""

from __future__ import annotations

import hashlib
import stat
import time
from collections import Counter
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import UserError

#: 2015-01-01 00:00:00 UTC as a Unix time (s): the signing timestamps' epoch.
SIGNING_EPOCH_UNIX_S = 1_420_070_400
#: Signing timestamp units per second (10 µs).
TICKS_PER_S = 100_000
KEY_BYTES = 32


def signing_timestamp(unix_s: float | None = None) -> int:
    """Now (or ``unix_s``) in the signing clock: 10 µs units since 2015-01-01 UTC."""
    now_s = time.time() if unix_s is None else unix_s
    return int(max(now_s - SIGNING_EPOCH_UNIX_S, 0.0) * TICKS_PER_S)


def load_key(path: str | Path) -> bytes:
    """The 32-byte secret key from ``path``; one-line UserError for a missing file, a file
    that group or others may read or write (like ssh), or an unusable content.

    Accepted contents: 32 raw bytes; 64 hexadecimal digits (one line); or any other one-line
    passphrase, whose SHA-256 is the key (what MAVProxy's ``signing setup PASSPHRASE`` and
    QGroundControl do).
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
        data = path.read_bytes()
    except OSError as exc:
        raise UserError(f"signing key file {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise UserError(f"signing key file {path} is not a regular file")
    if mode & 0o077:
        raise UserError(
            f"signing key file {path} is accessible by group or others "
            f"(mode {stat.S_IMODE(mode):04o}): run chmod 600 {path}"
        )
    if len(data) == KEY_BYTES:
        return data
    text = data.decode("utf-8", errors="replace").strip()
    if not text or "\n" in text:
        raise UserError(
            f"signing key file {path} must hold 32 bytes, 64 hex digits or a one-line passphrase"
        )
    if len(text) == 2 * KEY_BYTES and all(c in "0123456789abcdefABCDEF" for c in text):
        return bytes.fromhex(text)
    return hashlib.sha256(text.encode()).digest()


class LinkSigning(mavlink.MAVLinkSigning):
    """One link's signing state, shared by the link's encoder and all its parsers.

    ``require``: unsigned frames are rejected (else accepted and counted by pymavlink)."""

    def __init__(self, key: bytes, link_id: int, require: bool) -> None:
        super().__init__()
        if len(key) != KEY_BYTES:
            raise ValueError("a MAVLink signing key is 32 bytes")
        self.secret_key = key
        self.link_id = link_id
        self.sign_outgoing = True
        self.require = require
        self.timestamp = signing_timestamp()
        self.rejected: Counter[str] = Counter()
        self.allow_unsigned_callback = _allow_unsigned

    def stamp(self) -> None:
        """Before signing a frame: the timestamp never lags the wall clock (pymavlink adds
        one per frame and keeps it at least the newest accepted frame's)."""
        self.timestamp = max(self.timestamp, signing_timestamp())


def _allow_unsigned(codec: mavlink.MAVLink, _msg_id: int) -> bool:
    """pymavlink asks this for every frame whose signature did not verify or is absent."""
    assert isinstance(codec, SigningCodec)
    signing = codec.signing
    assert isinstance(signing, LinkSigning)
    if codec.failed_signature:  # signed, but not by our key, or replayed: never
        codec.failed_signature = False
        return False
    if signing.require:
        signing.rejected["unsigned"] += 1
        return False
    return True


class SigningCodec(mavlink.MAVLink):
    """pymavlink's codec with the signature compared before the timestamp is recorded."""

    def __init__(self, signing: LinkSigning) -> None:
        super().__init__(None)
        self.robust_parsing = True
        self.signing = signing
        self.failed_signature = False

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:
        signing = self.signing
        assert isinstance(signing, LinkSigning) and signing.secret_key is not None
        digest = hashlib.sha256(signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
        if digest != bytes(msgbuf[-6:]):
            signing.rejected["bad_signature"] += 1
            self.failed_signature = True
            return False
        if not super().check_signature(msgbuf, srcSystem, srcComponent):
            signing.rejected["replayed"] += 1
            self.failed_signature = True
            return False
        return True
