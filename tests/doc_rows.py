"""The measured tables of the docs that live tests hold their figures to: a row
``| name | low–high unit (what was measured) |`` gives the range each run's figure must lie
in. A live flight differs from run to run, so the docs promise a range and say what was
measured; a figure that drifts out of its row fails the test that flew it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


class DocRows:
    """The range rows of one document (``doc``: its path from the repository root)."""

    def __init__(self, doc: str) -> None:
        self.doc = doc
        self.text = (ROOT / doc).read_text()

    def check(self, name: str, value: float) -> None:
        """``value`` lies in the range the row ``name`` gives (and is printed)."""
        print(f"{name}: {value:.2f}")
        row = re.search(
            rf"^\| {re.escape(name)} \| ([-+\d.]+)–([-+\d.]+)\b", self.text, re.MULTILINE
        )
        assert row is not None, f"{self.doc} has no row for {name!r}"
        assert float(row[1]) <= value <= float(row[2]), (name, value, row[0])
