"""DataFlash records of chosen message types, decoded column-wise from pymavlink's index.

pymavlink's ``DFReader_binary`` indexes a log when it opens it: per message type id the byte
offsets of its records (``offsets``, ``counts``) and the format the log declares for it
(``formats``: a ``DFFormat`` with the record's struct layout ``msg_struct``, its length
``len`` in bytes, header included, its ``columns``, per column the Python type ``msg_types``
and the scale ``msg_mults``). Its ``recv_match`` then builds one message object per record
and converts a field at each attribute read. Here the records of one type are gathered from
the memory-mapped file in one numpy step, each column asked for is converted once, and each
record becomes a :class:`Row`: a named tuple with the surface of pymavlink's message that
:mod:`estimator.logs.dataflash` reads (``get_type()``, ``fmt``, the columns as attributes),
holding the values that attribute reads of pymavlink's message give (same Python types,
the format's scale applied the same way; ``tests/test_dataflash_records.py`` compares them
field by field on real logs).

This walk equals ``recv_match(type=names, strict=True)`` — records in file order, the first
one that runs past the end of the file ending the read — only where each name's index entry
is that name's format and the format's struct fills its declared length;
:func:`plan` returns None otherwise (a damaged or forged FMT record) and the caller reads
the library's own messages.
"""

from __future__ import annotations

import array
import collections
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.DFReader import DFReader_binary

#: Bytes before a record's fields: the two sync bytes and the type id.
HEADER_BYTES = 3
#: Records decoded at once (bounds the memory a long log takes while it is read).
CHUNK_RECORDS = 20_000


class Row:
    """The part of pymavlink's message a row shares: its format and type name; the columns
    come from the named tuple each message type's row class also derives from."""

    __slots__ = ()
    fmt: Any

    def get_type(self) -> str:
        return str(self.fmt.name)


@dataclass(frozen=True)
class RecordPlan:
    """Where the records of the chosen types are: byte offsets in file order and, for each,
    the index of its type in ``type_ids``; ``columns``: the column names rows carry (those
    the type's format has)."""

    log: DFReader_binary
    type_ids: tuple[int, ...]
    offsets: np.ndarray
    kinds: np.ndarray
    columns: tuple[str, ...]

    def rows(self) -> Iterator[list[Any]]:
        """Rows in file order, in lists of up to :data:`CHUNK_RECORDS`."""
        row_types = [_row_type(self.log.formats[t], self.columns) for t in self.type_ids]
        for start in range(0, len(self.offsets), CHUNK_RECORDS):
            offsets = self.offsets[start : start + CHUNK_RECORDS]
            kinds = self.kinds[start : start + CHUNK_RECORDS]
            out = np.empty(len(offsets), dtype=object)
            for kind, type_id in enumerate(self.type_ids):
                mine = kinds == kind
                if mine.any():
                    fmt = self.log.formats[type_id]
                    values = _columns(self.log, fmt, offsets[mine], row_types[kind]._fields)
                    rows = map(row_types[kind], *values)
                    out[mine] = np.fromiter(rows, dtype=object, count=int(mine.sum()))
            yield out.tolist()


def plan(log: DFReader_binary, names: set[str], columns: tuple[str, ...]) -> RecordPlan | None:
    """The records of the message types ``names`` that the log has, or None when the
    library's own read must be used (see the module docstring)."""
    type_ids: list[int] = []
    for name in sorted(names):
        type_id = log.name_to_id.get(name)
        if type_id is None:
            continue
        fmt = log.formats.get(type_id)
        if fmt is None or fmt.name != name or not _fills_record(fmt):
            return None
        type_ids.append(type_id)
    parts = [np.asarray(log.offsets[t][: log.counts[t]], dtype=np.int64) for t in type_ids]
    offsets = np.concatenate([np.zeros(0, dtype=np.int64), *parts])
    kinds = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    order = np.argsort(offsets, kind="stable")
    offsets, kinds = offsets[order], kinds[order]
    lengths = np.array([log.formats[t].len for t in type_ids], dtype=np.int64)
    past_end = np.flatnonzero(offsets + lengths[kinds] > log.data_len)
    if len(past_end):  # the read ends at the first record cut off by the end of the file
        offsets, kinds = offsets[: past_end[0]], kinds[: past_end[0]]
    return RecordPlan(log, tuple(type_ids), offsets, kinds, columns)


def _fills_record(fmt: Any) -> bool:
    """Whether the format's struct layout is exactly its declared record length."""
    try:
        return struct.calcsize(fmt.msg_struct) == fmt.len - HEADER_BYTES
    except struct.error:
        return False


def _row_type(fmt: Any, columns: tuple[str, ...]) -> Any:
    """A row class for ``fmt``: a named tuple of the wanted columns the format has values
    for (a column named beyond its format's fields has none: reading it raises
    AttributeError, as an absent column does)."""
    present = tuple(c for c in columns if fmt.colhash.get(c, len(fmt.msg_fmts)) < len(fmt.msg_fmts))
    base = collections.namedtuple(f"{fmt.name}Row", present)  # type: ignore[misc]
    return type(base.__name__, (base, Row), {"__slots__": (), "fmt": fmt})


def _columns(
    log: DFReader_binary, fmt: Any, offsets: np.ndarray, names: tuple[str, ...]
) -> list[list[Any]]:
    """The values of columns ``names`` of the records at ``offsets`` (Python values, as
    pymavlink's attribute reads give them)."""
    codes = _struct_codes(fmt.msg_struct)
    dtype = np.dtype(
        {
            "names": [f"f{i}" for i in range(len(codes))],
            "formats": [_numpy_code(c) for c in codes],
            "offsets": _field_offsets(codes),
            "itemsize": fmt.len - HEADER_BYTES,
        }
    )
    body = np.arange(HEADER_BYTES, fmt.len, dtype=np.int64)
    data = np.frombuffer(log.data_map, dtype=np.uint8)
    try:
        records = data[offsets[:, None] + body].view(dtype).reshape(len(offsets))
    finally:
        del data  # the library closes its memory map: no view of it may outlive this call
    return [_converted(records[f"f{fmt.colhash[name]}"], fmt, fmt.colhash[name]) for name in names]


def _struct_codes(layout: str) -> list[str]:
    """The field codes of a little-endian struct layout ("<hH64s" → ["h", "H", "64s"])."""
    codes, count = [], ""
    for char in layout.lstrip("<"):
        if char.isdigit():
            count += char
        else:
            codes.append(count + char)
            count = ""
    return codes


def _numpy_code(code: str) -> str:
    """The numpy type of one struct field code: bytes stay raw (void) for the conversion."""
    return f"V{code[:-1]}" if code.endswith("s") else f"<{code}"


def _field_offsets(codes: list[str]) -> list[int]:
    sizes = [struct.calcsize(f"<{c}") for c in codes]
    return [int(x) for x in np.cumsum([0, *sizes[:-1]])]


def _converted(values: np.ndarray, fmt: Any, index: int) -> list[Any]:
    """One column as pymavlink's attribute read gives it: text for string fields, an array
    of int16 for ``a`` fields, the format's scale applied (a scale below 1 by dividing by its
    reciprocal), else the plain number."""
    kind, scale = fmt.msg_types[index], fmt.msg_mults[index]
    if kind is str:
        return [_text(raw) for raw in values.tolist()]
    if fmt.msg_fmts[index] == "a":
        return [array.array("h", raw) for raw in values.tolist()]
    if scale is not None:
        scaled = values.astype(np.float64)
        scaled = scaled / (1 / scale) if 0.0 < scale < 1.0 else scaled * scale
        return list(scaled.tolist())
    return list(values.tolist())


def _text(raw: bytes) -> str:
    """A string field: UTF-8, else Latin-1, up to its first NUL."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("ISO-8859-1")
    return text.split("\0", 1)[0]
