"""Binary logs that a text-mode transfer or checkout converted to CRLF line endings.

Such a transfer puts a CR (0x0D) before every LF (0x0A) byte of the file. In a binary log
LF bytes fall about one in 256, each after a CR by chance one time in 256: a file with at
least :data:`CRLF_MIN_PAIRS` LF bytes, every one of them after a CR, was converted. Turning
each CR LF back into LF gives the log back byte for byte when the conversion put a CR before
every LF (a CR LF of the log itself became CR CR LF, and comes back too). One that left the
log's own CR LF pairs alone (as ``unix2dos`` and git's ``autocrlf`` do) cannot be told from
them: their CR is lost, and the few frames or records that held one (one LF in 256 bytes,
one of those after a CR by chance) stay damaged and are counted as such by the reader.

The tlog reader undoes it in memory (:func:`crlf_undone`); the DataFlash and ULog readers,
whose libraries read a file by its name or handle, read a repaired copy in a temporary
directory (:func:`repaired_copy`), written a chunk at a time. Only the first
:data:`PROBE_BYTES` of a file are looked at to tell: a log that was not converted costs one
short read.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from pathlib import Path

from estimator.errors import UserError

#: LF bytes, each after a CR, that show a log converted to CRLF line endings as text.
CRLF_MIN_PAIRS = 16
#: The bytes at the start of a file looked at to tell whether it was converted.
PROBE_BYTES = 1 << 20


def crlf_undone(data: bytes) -> tuple[bytes, str | None]:
    """``data`` with a text-mode line-ending conversion undone and a sentence saying so, else
    ``data`` and None (see the module docstring)."""
    if not _converted(data):
        return data, None
    return data.replace(b"\r\n", b"\n"), _note(data.count(b"\n"))


@contextlib.contextmanager
def repaired_copy(path: Path) -> Iterator[tuple[Path, str | None]]:
    """(the file to read, a sentence on its repair): ``path`` and None for a log that was not
    converted; else a copy with the conversion undone, written a chunk of
    :data:`PROBE_BYTES` at a time, in a temporary directory removed when the context ends (a
    reader that maps the copy keeps its bytes until it closes it)."""
    try:
        with path.open("rb") as f:
            converted = _converted(f.read(PROBE_BYTES))
    except OSError:
        converted = False  # the reader says what is wrong with the file, in its own words
    if not converted:
        yield path, None
        return
    with tempfile.TemporaryDirectory(prefix="uav-energy-", ignore_cleanup_errors=True) as tmp:
        copy = Path(tmp) / path.name
        pairs = _undo_into(path, copy)
        yield (path, None) if pairs is None else (copy, _note(pairs))


def _undo_into(path: Path, copy: Path) -> int | None:
    """Write ``path`` with every CR LF turned back into LF to ``copy``: the number of LF bytes,
    or None when one does not follow a CR (then the file was not converted as a whole)."""
    pairs = 0
    try:
        with path.open("rb") as source, copy.open("wb") as out:
            carry = b""
            while chunk := source.read(PROBE_BYTES):
                chunk, carry = carry + chunk, b""
                if chunk.endswith(b"\r"):  # its LF may open the next chunk
                    chunk, carry = chunk[:-1], b"\r"
                lf = chunk.count(b"\n")
                if chunk.count(b"\r\n") != lf:
                    return None
                pairs += lf
                out.write(chunk.replace(b"\r\n", b"\n"))
            out.write(carry)
    except OSError as exc:
        raise UserError(f"cannot read {path} to undo its line endings: {exc.strerror}") from None
    return pairs


def _converted(data: bytes) -> bool:
    pairs = data.count(b"\r\n")
    return pairs >= CRLF_MIN_PAIRS and pairs == data.count(b"\n")


def _note(pairs: int) -> str:
    return (
        f"every LF byte of the file follows a CR ({pairs} of them): it was converted to CRLF "
        "line endings as text (a text-mode transfer or checkout); read with the conversion "
        "undone, fetch it as binary"
    )
