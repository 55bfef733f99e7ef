"""Result blocks in Markdown documents: text between ``<!-- figures:NAME -->`` and
``<!-- /figures:NAME -->`` that a registered generator prints (``scripts/figures.py``).

A block is inline (both markers on one line: the text between them is the generator's, as
is) or on its own lines (the opening marker ends a line, the closing one starts a line: the
lines between them are the generator's). Rewriting a document changes the text inside its
blocks and nothing else.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from estimator.errors import UserError

_BLOCK = re.compile(r"<!-- figures:([a-z0-9-]+) -->(.*?)<!-- /figures:\1 -->", re.DOTALL)
_MARKER = re.compile(r"<!-- /?figures:([a-z0-9-]+) -->")


@dataclass(frozen=True)
class Block:
    """One block of one document: its name, the file, and the text now between its markers
    (without the line breaks next to the markers of a block on its own lines)."""

    name: str
    path: Path
    text: str
    inline: bool


def blocks_in(path: Path) -> list[Block]:
    """The blocks of ``path`` in document order; UserError on an unpaired marker or a name
    used twice."""
    text = path.read_text()
    found = []
    for match in _BLOCK.finditer(text):
        inner = match.group(2)
        inline = "\n" not in inner
        if not inline:
            if not (inner.startswith("\n") and inner.endswith("\n")):
                raise UserError(
                    f"{path}: block {match.group(1)!r}: put each marker on its own line, "
                    "or both on one line"
                )
            inner = inner[1:-1]
        found.append(Block(match.group(1), path, inner, inline))
    unpaired = _MARKER.search(_BLOCK.sub("", text))
    if unpaired is not None:
        raise UserError(f"{path}: the marker of block {unpaired.group(1)!r} has no partner")
    if len({b.name for b in found}) != len(found):
        raise UserError(f"{path}: a block name appears twice")
    return found


def rewrite(path: Path, generated: Mapping[str, str]) -> bool:
    """Put ``generated[name]`` between the markers of each block of ``path`` that has an
    entry there; True if the file changed."""
    blocks_in(path)  # refuse unpaired markers before writing anything
    old = path.read_text()

    def fill(match: re.Match[str]) -> str:
        name, inner = match.group(1), match.group(2)
        if name not in generated:
            return match.group(0)
        if "\n" not in inner and "\n" in generated[name]:
            raise UserError(f"{path}: block {name!r} is on one line; its text is not")
        body = generated[name] if "\n" not in inner else f"\n{generated[name]}\n"
        return f"<!-- figures:{name} -->{body}<!-- /figures:{name} -->"

    new = _BLOCK.sub(fill, old)
    if new != old:
        path.write_text(new)
    return new != old
