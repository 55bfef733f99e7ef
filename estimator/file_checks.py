"""Input files as data: a regular file before anything reads it, nesting bounded before a
parser recurses, numbers within their documented ranges. Every problem is one sentence in a
:class:`~estimator.errors.UserError` naming the file, the key and what is allowed.
"""

from __future__ import annotations

import errno
import math
import stat
from pathlib import Path
from typing import Any

from estimator.errors import UserError

#: Deepest nesting of arrays/tables/objects a TOML or JSON input may have: the project's own
#: files nest 3 deep; a parser recursing on 1000 levels ends in RecursionError.
MAX_NESTING = 32


def regular_file(path: str | Path, kind: str) -> Path:
    """``path`` if it is a regular file (after symbolic links); otherwise one sentence saying
    what it is instead (missing, dangling or looping link, directory, FIFO, socket, device),
    so that nothing blocks on opening a FIFO or reads a device. ``kind`` names the file."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        if path.is_symlink():
            raise UserError(f"{kind} {path} is a symbolic link to a missing file") from None
        raise UserError(f"{kind} {path} does not exist") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise UserError(f"{kind} {path} is a symbolic link loop") from None
        raise UserError(f"cannot read {kind} {path}: {exc.strerror}") from None
    if stat.S_ISDIR(mode):
        raise UserError(f"{kind} {path} is a directory")
    if not stat.S_ISREG(mode):
        what = "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else None
        raise UserError(f"{kind} {path} is {what or 'a device'}, not a regular file")
    return path


def check_nesting(text: str, where: str, comment: str | None = None) -> None:
    """UserError if brackets or braces outside strings in ``text`` (TOML or JSON) nest deeper
    than :data:`MAX_NESTING`; one pass, no recursion. A string ends at its closing quote or
    at the end of its line (a bracket in a multi-line string may count, which only matters
    past the limit); ``comment`` starts a comment to the end of the line (TOML's "#")."""
    depth = 0
    quote = ""
    escaped = False
    in_comment = False
    for char in text:
        if in_comment:
            in_comment = char != "\n"
        elif quote:
            if escaped:
                escaped = False
            elif char == "\\" and quote == '"':
                escaped = True
            elif char == quote or char == "\n":
                quote = ""
        elif char in "\"'":
            quote = char
        elif char == comment:
            in_comment = True
        elif char in "[{":
            depth += 1
            if depth > MAX_NESTING:
                raise UserError(f"{where} nests deeper than {MAX_NESTING} levels")
        elif char in "]}":
            depth -= 1


def number_in_range(
    table: dict[str, Any],
    key: str,
    where: str,
    bounds: tuple[float, float],
    unit: str = "",
    integer: bool = False,
) -> float:
    """``table[key]`` as a float, if it is a number (an integer if ``integer``) within
    ``bounds`` (inclusive); else UserError naming ``where``, the key and the range."""
    if key not in table:
        raise UserError(f"{where} is missing '{key}'")
    return in_range(table[key], f"{where} '{key}'", bounds, unit, integer)


def in_range(
    value: Any, name: str, bounds: tuple[float, float], unit: str = "", integer: bool = False
) -> float:
    """``value`` as a float, if it is a number (an integer if ``integer``) within ``bounds``
    (inclusive); else UserError: "``name`` must be a number from LO to HI UNIT, got VALUE"."""
    lo, hi = bounds
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if (
        not number
        or not math.isfinite(value)
        or (integer and value != int(value))
        or not lo <= value <= hi
    ):
        kind = "an integer" if integer else "a number"
        raise UserError(
            f"{name} must be {kind} from {lo:g} to {hi:g}{' ' + unit if unit else ''}, "
            f"got {value!r}"
        )
    return float(value)
