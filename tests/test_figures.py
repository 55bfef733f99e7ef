"""The result figures of README.md and docs/*.md are what their generators print now
(``scripts/figures.py``; ``make figures`` rewrites them, ``make figures-check`` checks them):
a figure that drifts from the code or the committed data fails here."""

from __future__ import annotations

from pathlib import Path

import pytest
from script_loader import load_script

from estimator.errors import UserError
from estimator.reports.doc_blocks import blocks_in, rewrite

ROOT = Path(__file__).resolve().parent.parent
figures = load_script("figures")

BLOCKS = figures.all_blocks()
NAMES = sorted({b.name for b in BLOCKS})
#: Checked here; the slow ones by the test that computes their results anyway.
CHECKED_HERE = [n for n in NAMES if n not in figures.CHECKED_BY]


def test_every_block_has_a_generator_and_every_generator_a_block() -> None:
    assert set(NAMES) == set(figures.GENERATORS)


def _needing_its_data(name: str) -> object:
    reads = figures.OUTSIDE_DATA.get(name)
    if reads is None:
        return name
    return pytest.param(name, marks=pytest.mark.needs(reads.is_dir(), f"{reads} for {name}"))


@pytest.mark.parametrize("name", [_needing_its_data(n) for n in CHECKED_HERE])
def test_the_block_is_what_its_generator_prints(name: str) -> None:
    blocks = [b for b in BLOCKS if b.name == name]
    assert figures.stale(blocks) == [], "run `make figures` and review the diff"


def test_every_slow_block_names_a_test_that_checks_it() -> None:
    for name, test in figures.CHECKED_BY.items():
        assert f'"{name}"' in (ROOT / test).read_text(), (name, test)


def test_a_rewrite_changes_only_the_blocks(tmp_path: Path) -> None:
    doc = tmp_path / "doc.md"
    doc.write_text(
        "Intro 1.0 W.\n<!-- figures:a -->\n| old | 1 |\n<!-- /figures:a -->\n"
        "Inline <!-- figures:b -->2.0 %<!-- /figures:b --> and 3.0 W outside.\n"
    )
    assert rewrite(doc, {"a": "| new | 2 |\n| more | 3 |", "b": "4.5 %"})
    assert doc.read_text() == (
        "Intro 1.0 W.\n<!-- figures:a -->\n| new | 2 |\n| more | 3 |\n<!-- /figures:a -->\n"
        "Inline <!-- figures:b -->4.5 %<!-- /figures:b --> and 3.0 W outside.\n"
    )
    assert [(b.name, b.text, b.inline) for b in blocks_in(doc)] == [
        ("a", "| new | 2 |\n| more | 3 |", False),
        ("b", "4.5 %", True),
    ]
    assert not rewrite(doc, {"a": "| new | 2 |\n| more | 3 |"})


def test_a_stale_figure_is_found(tmp_path: Path) -> None:
    doc = tmp_path / "doc.md"
    now = figures.GENERATORS["plan-still-air"]()
    doc.write_text(f"<!-- figures:plan-still-air -->{now}<!-- /figures:plan-still-air -->\n")
    assert figures.stale(blocks_in(doc)) == []
    doc.write_text(doc.read_text().replace(now, now.replace(".", ",", 1)))
    [(block, text)] = figures.stale(blocks_in(doc))
    assert block.name == "plan-still-air" and text == now


@pytest.mark.parametrize(
    "text",
    [
        "<!-- figures:a -->1 W\n",
        "1 W<!-- /figures:a -->\n",
        "<!-- figures:a -->\n1 W<!-- /figures:a -->\n",
        "<!-- figures:a -->1<!-- /figures:a --> <!-- figures:a -->2<!-- /figures:a -->\n",
    ],
)
def test_an_unpaired_or_doubled_marker_is_one_sentence(tmp_path: Path, text: str) -> None:
    doc = tmp_path / "doc.md"
    doc.write_text(text)
    with pytest.raises(UserError):
        blocks_in(doc)
    with pytest.raises(UserError):
        rewrite(doc, {"a": "9 W"})
    assert doc.read_text() == text
