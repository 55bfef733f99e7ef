"""Bytes → MAVLink messages, for the daemon's links and every log reader.

:class:`FrameParser` parses with pymavlink's generated ``dialects.v20.common`` codec (robust
parsing on; MAVLink 1 frames parse too), counts bad frames instead of raising, and can drop
whole frames of message ids nobody uses by their header, before pymavlink sees them. The
helpers read a raw frame's header (sender, payload) for messages of types the dialect lacks.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink


class FrameParser:
    """Bytes in, MAVLink messages out; bad frames are counted, never raised.

    With ``message_ids``, whole frames of other ids are dropped by their header before
    pymavlink sees them (counted in ``skipped_frames``; their checksum and signature are not
    verified): the walk goes frame by frame from the chunk's start while each frame begins
    with a MAVLink magic byte and lies whole in the chunk. What follows is parsed as it is
    (garbage: pymavlink resynchronizes and counts it); with ``stream`` (TCP, serial) a frame
    cut by the end of the chunk is held and completed by the next one. ``codec``: a pymavlink
    codec to parse with (e.g. one that checks signatures); frames it rejects for their
    signature are counted by its signing state, not as bad frames.
    """

    def __init__(
        self,
        message_ids: frozenset[int] | None = None,
        stream: bool = False,
        codec: mavlink.MAVLink | None = None,
    ) -> None:
        self._codec = codec or mavlink.MAVLink(None)
        self._codec.robust_parsing = True
        self._message_ids = message_ids
        self._stream = stream
        self._held = b""
        self.bad_frames = 0
        self.skipped_frames = 0

    def feed(self, data: bytes) -> list[mavlink.MAVLink_message]:
        """Parse a chunk (a datagram, a stream read, a tlog record) into good messages."""
        if self._message_ids is not None and self._codec.buf_len() == 0:
            data = self._wanted_frames(self._held + data)
            if not data:
                return []
        try:
            parsed = self._codec.parse_buffer(data) or []
        except Exception:  # pymavlink raises plain Exception subclasses on corrupt input
            self.bad_frames += 1
            return []
        good = []
        for msg in parsed:
            if isinstance(msg, mavlink.MAVLink_bad_data):
                self.bad_frames += msg.reason != "Invalid signature"
            else:
                good.append(msg)
        return good

    @property
    def holds_partial_frame(self) -> bool:
        """Whether bytes of an unfinished frame wait for the next chunk."""
        return bool(self._held) or self._codec.buf_len() > 0

    def _wanted_frames(self, data: bytes) -> bytes:
        """``data`` without the whole frames of unwanted ids at its start (see the class)."""
        assert self._message_ids is not None
        wanted, at, end = self._message_ids, 0, len(data)
        kept: list[bytes] = []
        while at < end:
            magic = data[at]
            if magic == 0xFD and at + 10 <= end:  # MAVLink 2: 10-byte header, signature flag
                size = 12 + data[at + 1] + (13 if data[at + 2] & 0x01 else 0)
                msgid = data[at + 7] | data[at + 8] << 8 | data[at + 9] << 16
            elif magic == 0xFE and at + 6 <= end:  # MAVLink 1: 6-byte header
                size, msgid = 8 + data[at + 1], data[at + 5]
            elif magic in (0xFD, 0xFE):
                size, msgid = end - at + 1, -1  # header cut by the chunk's end
            else:
                break  # not at a frame: pymavlink resynchronizes on the rest
            if at + size > end:
                if self._stream:  # the rest of the frame comes with the next chunk
                    self._held = data[at:]
                    return b"".join(kept)
                break
            if msgid in wanted:
                kept.append(data[at : at + size])
            else:
                self.skipped_frames += 1
            at += size
        self._held = b""
        kept.append(data[at:])
        return b"".join(kept)

    def decode_frame(self, frame: bytes) -> mavlink.MAVLink_message | None:
        """One whole frame (a log record's) into a message, without the byte-by-byte stream
        parser; None for a bad frame (counted)."""
        try:
            return self._codec.decode(bytearray(frame))
        except Exception:  # pymavlink's MAVError, struct.error on a damaged frame
            self.bad_frames += 1
            return None


def frame_source(frame: bytes) -> tuple[int, int]:
    """(system, component) from a raw MAVLink 1 or 2 frame's header."""
    at = 5 if frame[0] == 0xFD else 3
    return frame[at], frame[at + 1]


def frame_payload(frame: bytes) -> bytes:
    """The payload of a raw MAVLink 1 or 2 frame (MAVLink 2 trims trailing zeros)."""
    header = 10 if frame[0] == 0xFD else 6
    return frame[header : header + frame[1]]
