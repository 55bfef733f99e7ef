"""docs/residuals.md's simulated flights whose effect changes during the flight (each hidden
from the built-in vehicle, ``scripts/residual_figures.py``): the analysis names the hidden
change first, its held-out error stays within 2.5 noise floors and its in-sample fit within
1.2, and the doc's table is what it measures."""

from __future__ import annotations

from typing import Any

import pytest
from test_figures import figures

NAMES = {"residuals-sim-changing", "residuals-sim-changing-floors"}
CHANGING = figures.residual_figures.CHANGING


@pytest.fixture(scope="module")
def results() -> dict[str, dict[str, Any]]:
    """``uav-energy residuals --json`` of each flight (≈ 50 s of CPU, shared with the block's
    generator)."""
    return dict(figures.residual_figures.changing_runs(figures.run_cli))


def test_the_docs_table_is_what_the_analysis_gives(results: dict[str, dict[str, Any]]) -> None:
    blocks = [b for b in figures.all_blocks() if b.name in NAMES]
    assert {b.name for b in blocks} == NAMES, f"not every one of {NAMES} in the docs"
    assert figures.stale(blocks) == [], "run `make figures` and review the diff"


@pytest.mark.parametrize("label", list(CHANGING))
def test_the_hidden_change_is_named_first_and_fits_at_the_noise_floor(
    results: dict[str, dict[str, Any]], label: str
) -> None:
    result, hidden = results[label], CHANGING[label]
    assert result["effects"] and result["effects"][0]["name"] == hidden[0].name
    floor_w = result["noise_floor_w"]
    assert result["rmse_after_w"] <= 2.5 * floor_w < result["rmse_before_w"]
    assert result["rmse_in_sample_w"] <= 1.2 * floor_w


def test_a_released_payload_as_good_as_a_load_is_named_the_mass(
    results: dict[str, dict[str, Any]],
) -> None:
    [label] = [k for k, effects in CHANGING.items() if len({e.name for e in effects}) == 2]
    first = results[label]["effects"][0]
    assert first["name"] == "mass"
    rivals = [r["candidate"] for r in first["indistinguishable_from"]]
    assert "avionics (window)" in rivals, rivals
