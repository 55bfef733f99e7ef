"""Reading the project's TOML files (vehicle, configuration, flight plan) with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from estimator.errors import UserError


def read_toml(path: str | Path, kind: str) -> dict[str, Any]:
    """The parsed document of the ``kind`` file (e.g. "vehicle") at ``path``; every problem is
    one clear sentence in a :class:`UserError`."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise UserError(f"{kind} file {path} does not exist") from None
    except IsADirectoryError:
        raise UserError(f"{kind} file {path} is a directory") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {kind} file {path}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{kind} file {path} is not valid TOML: {exc}") from None
