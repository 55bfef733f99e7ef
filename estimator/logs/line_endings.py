"""Binary logs that a text-mode transfer or checkout converted to CRLF line endings.

Such a transfer puts a CR (0x0D) before every LF (0x0A) byte of the file. In a binary log
LF bytes fall about one in 256, each after a CR by chance one time in 256: a file with at
least :data:`CRLF_MIN_PAIRS` LF bytes, every one of them after a CR, was converted. Turning
each CR LF back into LF gives the log back byte for byte (a CR LF of the log itself had
become CR CR LF, and comes back too).

The tlog reader undoes it in memory (:func:`crlf_undone`); the DataFlash and ULog readers,
whose libraries read a file by its name or handle, read a repaired copy in a temporary
directory (:func:`repaired_copy`). Only the first :data:`PROBE_BYTES` of a file are looked
at to tell: a log that was not converted costs one short read.
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
    converted; else a copy with the conversion undone, in a temporary directory removed when
    the context ends (a reader that maps the copy keeps its bytes until it closes it)."""
    try:
        with path.open("rb") as f:
            head = f.read(PROBE_BYTES)
    except OSError:
        yield path, None  # the reader says what is wrong with it, in its own words
        return
    if not _converted(head):
        yield path, None
        return
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    repaired, note = crlf_undone(data)
    if note is None:  # converted at its start only: not a text-mode transfer
        yield path, None
        return
    with tempfile.TemporaryDirectory(prefix="uav-energy-", ignore_cleanup_errors=True) as tmp:
        copy = Path(tmp) / path.name
        copy.write_bytes(repaired)
        del data, repaired
        yield copy, note


def _converted(data: bytes) -> bool:
    pairs = data.count(b"\r\n")
    return pairs >= CRLF_MIN_PAIRS and pairs == data.count(b"\n")


def _note(pairs: int) -> str:
    return (
        f"every LF byte of the file follows a CR ({pairs} of them): it was converted to CRLF "
        "line endings as text (a text-mode transfer or checkout); read with the conversion "
        "undone, fetch it as binary"
    )
