"""Reading the project's TOML files (vehicle, configuration, flight plan) with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from estimator.errors import UserError
from estimator.file_checks import check_nesting, regular_file


def read_toml(path: str | Path, kind: str) -> dict[str, Any]:
    """The parsed document of the ``kind`` file (e.g. "vehicle") at ``path``; every problem is
    one clear sentence in a :class:`UserError` (a FIFO or a device is refused before it is
    opened, a nesting deeper than :data:`~estimator.file_checks.MAX_NESTING` before parsing)."""
    path = regular_file(path, f"{kind} file")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {kind} file {path}: {exc}") from None
    check_nesting(text, f"{kind} file {path}", comment="#")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{kind} file {path} is not valid TOML: {exc}") from None
    except ValueError:  # an integer of thousands of digits (int()'s limit)
        raise UserError(f"{kind} file {path} holds a number too long to read") from None
