"""The folder a report is written into."""

from __future__ import annotations

from pathlib import Path

from estimator.errors import UserError


def make_report_dir(out_dir: Path) -> None:
    """Create ``out_dir`` (and its parents) if missing; UserError when it cannot be."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create report directory {out_dir}: {exc.strerror}") from None
