"""The package's layers: every import inside ``estimator`` points down (or stays in its folder).

The order is the data flow from the bottom up, as drawn in the README ("Layout"): a module may
import modules of its own folder and of lower layers, never of a higher layer or of a peer
folder on the same layer.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "estimator"

#: Bottom to top; folders (or top-level modules) on one line are peers.
LAYERS: list[set[str]] = [
    {"errors"},
    {"file_checks"},
    {"toml_files"},
    {"telemetry"},
    {"physics"},
    {"logs"},
    {"estimation"},
    {"analysis", "mavlink"},
    {"reports"},
    {"sim", "sitl"},
    {"commands"},
    {"cli"},
]


def layer_of(part: str) -> int:
    for i, names in enumerate(LAYERS):
        if part in names:
            return i
    raise AssertionError(f"estimator.{part} is in no layer: add it to LAYERS and the README")


def top_part(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0].removesuffix(".py")


def imported_parts(path: Path) -> set[str]:
    """First component under ``estimator`` of every module ``path`` imports."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
            if node.module == "estimator":
                names = [f"estimator.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out |= {n.split(".")[1] for n in names if n.startswith("estimator.")}
    return {p for p in out if (PACKAGE / p).is_dir() or (PACKAGE / f"{p}.py").is_file()}


def modules() -> list[Path]:
    return [p for p in PACKAGE.rglob("*.py") if p.name != "__init__.py" or p.parent != PACKAGE]


def test_every_module_belongs_to_a_layer() -> None:
    for path in modules():
        layer_of(top_part(path))


def test_imports_only_point_down() -> None:
    wrong = []
    for path in modules():
        here = top_part(path)
        for there in imported_parts(path) - {here}:
            if layer_of(there) >= layer_of(here):
                wrong.append(f"{path.relative_to(PACKAGE)} imports estimator.{there}")
    assert not wrong, "imports that point up or sideways:\n" + "\n".join(sorted(wrong))


def test_the_check_sees_an_upward_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(
        "from estimator import __version__\n"
        "from estimator.sim.simulator import simulate\nimport estimator.cli\n"
    )
    assert imported_parts(bad) == {"sim", "cli"}
    assert layer_of("sim") > layer_of("physics")
