"""``uav-energy replay --report``: the endurance's σ against the truth beside a log
(:mod:`estimator.analysis.endurance_truth`, :mod:`estimator.reports.endurance_reliability`).

Two SITL pack flights (replay/sitl_packs, flown to their true reserve) replayed by the command
with the SITL vehicle file under the packs' 5.0 Ah label give the same coverage as
:mod:`estimator.analysis.pack_flights` computes for them; a log without a truth, or whose truth
has no reserve or is not one, gives no word of it."""

from __future__ import annotations

import io
import json
import re
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import norm

from estimator.analysis.endurance_truth import NOMINAL_LEVELS, reliability, within
from estimator.analysis.pack_flights import replay_pack_flight
from estimator.cli import main
from estimator.physics.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
NAMES = ("pack_c100_r1", "pack_c65_r1")
VEHICLE_FILE = ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
NO_TRUTH_LOG = ROOT / "tests" / "data" / "arducopter_guided.tlog"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _labelled_vehicle(directory: Path) -> Path:
    """The SITL vehicle file with the packs' labelled capacity, as pack_flights replays."""
    label_ah = json.loads((FLIGHTS / NAMES[0] / "truth.json").read_text())["battery"][
        "labelled_capacity_ah"
    ]
    assert all(
        json.loads((FLIGHTS / n / "truth.json").read_text())["battery"]["labelled_capacity_ah"]
        == label_ah
        for n in NAMES
    )
    text, n = re.subn(
        r"(?m)^capacity_ah = .*$", f"capacity_ah = {label_ah}", VEHICLE_FILE.read_text()
    )
    assert n == 1
    path = directory / "labelled.toml"
    path.write_text(text)
    return path


def _replay(*args: str | Path) -> dict[str, Any]:
    """``uav-energy replay ARGS --json``: its JSON object."""
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["replay", *map(str, args), "--json"]) == 0
    result: dict[str, Any] = json.loads(out.getvalue())
    return result


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """The report folder and JSON of the two pack flights replayed together."""
    d = tmp_path_factory.mktemp("reliability")
    logs = [FLIGHTS / n / "flight.tlog" for n in NAMES]
    result = _replay(*logs, "--vehicle", _labelled_vehicle(d), "--report", d / "report")
    return d / "report", result


@pytest.fixture(scope="module")
def pack_z() -> dict[str, np.ndarray]:
    """The scored z of each flight as pack_flights computes them."""
    vehicle = load_vehicle(VEHICLE_FILE)
    return {n: replay_pack_flight(FLIGHTS / n, vehicle).z for n in NAMES}


def test_the_reports_coverage_is_pack_flights_coverage(
    report: tuple[Path, dict[str, Any]], pack_z: dict[str, np.ndarray]
) -> None:
    _, result = report
    truth = result["endurance_truth"]
    z = np.concatenate([pack_z[n] for n in NAMES])
    assert len(z) > 300
    assert truth["flights"] == len(NAMES)
    assert truth["estimates"] == len(z)
    assert truth["within_1sigma"] == np.mean(np.abs(z) <= 1.0)
    assert truth["within_3sigma"] == np.mean(np.abs(z) <= 3.0)
    observed = [r["observed"] for r in truth["reliability"]]
    nominal = [r["nominal"] for r in truth["reliability"]]
    assert nominal == list(NOMINAL_LEVELS)
    assert observed == [np.mean(np.abs(z) <= norm.ppf(0.5 + p / 2)) for p in nominal]
    for row, name in zip(truth["per_flight"], NAMES, strict=True):
        assert row["flight"] == f"{name}/flight"
        assert row["estimates"] == len(pack_z[name])
        assert row["within_1sigma"] == np.mean(np.abs(pack_z[name]) <= 1.0)


def test_the_report_has_the_reliability_diagram_and_each_flights_endurance_against_truth(
    report: tuple[Path, dict[str, Any]],
) -> None:
    folder, result = report
    truth = result["endurance_truth"]
    pngs = [folder / "reliability.png"] + [
        folder / f"{n}_flight-endurance-truth.png" for n in NAMES
    ]
    for png in pngs:
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert png.stat().st_size > 10_000
    summary = (folder / "summary.md").read_text()
    assert "## Endurance against the truth" in summary
    assert f"{100 * truth['within_1sigma']:.1f} % within 1σ" in summary
    assert f"{100 * truth['within_3sigma']:.1f} % within 3σ" in summary
    assert f"over {truth['estimates']} estimates of 2 flights" in summary
    assert "![reliability](reliability.png)" in summary
    assert "label differs" not in summary
    for name in NAMES:
        assert f"![endurance-truth]({name}_flight-endurance-truth.png)" in summary


def test_a_vehicle_file_off_the_packs_label_is_named_in_the_report(tmp_path: Path) -> None:
    log = FLIGHTS / NAMES[1] / "flight.tlog"
    _replay(log, "--vehicle", VEHICLE_FILE, "--report", tmp_path)
    summary = (tmp_path / "summary.md").read_text()
    assert "Replayed under the vehicle file's 2.2 Ah; the pack's label differs on: " in summary


def test_a_log_without_truth_gives_no_reliability_section(tmp_path: Path) -> None:
    assert not (NO_TRUTH_LOG.parent / "truth.json").exists()
    result = _replay(NO_TRUTH_LOG, "--report", tmp_path)
    assert "endurance_truth" not in result
    assert "against the truth" not in (tmp_path / "summary.md").read_text()
    assert not list(tmp_path.glob("*reliability*")) and not list(tmp_path.glob("*truth*"))


@pytest.mark.parametrize(
    ("truth", "warning"),
    [
        ('{"events": {"takeoff_s": 10.0, "landed_s": 60.0}}', None),  # not flown to its reserve
        ("not json", "not JSON"),
        ("[1, 2]", "no 'events' object"),
        ('{"events": {"takeoff_s": 10, "reserve_s": "300"}}', "events.reserve_s is not a finite"),
        ('{"events": {"takeoff_s": 10, "reserve_s": 1e999}}', "events.reserve_s is not a finite"),
        ('{"events": {"takeoff_s": 1' + "0" * 400 + ', "reserve_s": 9}}', "events.takeoff_s"),
        ('{"events": {"takeoff_s": 300, "reserve_s": 10}}', "is not after takeoff_s"),
        ("[" * 100_000, "not JSON"),
    ],
    ids=["no-reserve", "text", "list", "string", "infinite", "huge-int", "reversed", "deep"],
)
def test_a_truth_without_a_reserve_or_not_a_truth_gives_no_section(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], truth: str, warning: str | None
) -> None:
    log = tmp_path / "flight.tlog"
    log.write_bytes(NO_TRUTH_LOG.read_bytes())
    (tmp_path / "truth.json").write_text(truth)
    code = main(["replay", str(log), "--report", str(tmp_path / "report"), "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert "endurance_truth" not in json.loads(out)
    assert "against the truth" not in (tmp_path / "report" / "summary.md").read_text()
    if warning is None:
        assert "truth.json" not in err
    else:
        assert f"warning: {tmp_path / 'truth.json'}: " in err and warning in err
        assert "endurance not scored" in err


def test_a_reserve_too_close_to_take_off_to_score_says_so_without_a_plot(tmp_path: Path) -> None:
    log = tmp_path / "flight.tlog"
    log.write_bytes(NO_TRUTH_LOG.read_bytes())
    (tmp_path / "truth.json").write_text('{"events": {"takeoff_s": 0.0, "reserve_s": 100.0}}')
    result = _replay(log, "--report", tmp_path / "report")
    assert result["endurance_truth"]["estimates"] == 0
    assert result["endurance_truth"]["within_1sigma"] is None
    assert "No estimate in the scored span." in (tmp_path / "report" / "summary.md").read_text()
    assert not (tmp_path / "report" / "reliability.png").exists()


def test_reliability_of_calibrated_and_overconfident_sigmas() -> None:
    z = np.random.default_rng(7).standard_normal(20_000)
    assert np.allclose(reliability(z), NOMINAL_LEVELS, atol=0.015)
    too_sure = reliability(2.0 * z)  # σ half the real spread
    assert np.all(too_sure < np.array(NOMINAL_LEVELS) - 0.04)
    assert within(np.array([0.5, np.nan, -2.0]), 1.0) == pytest.approx(1 / 3)
    assert np.isnan(within(np.empty(0), 1.0))
