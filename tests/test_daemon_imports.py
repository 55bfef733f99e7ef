"""The daemon's import set stays lean: no scipy, matplotlib, scikit-learn, filterpy, dask or
pyarrow, neither at start-up nor once telemetry flows, return figures included (each would add
tens of MB to its resident memory, and none is in ``pip install uav-energy``: they come with
the ``analysis`` and ``fleet`` extras)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

FLIGHT_TLOG = Path(__file__).parent / "data" / "arducopter_guided.tlog"
#: A flight in wind with the autopilot's wind reports (the tracker's second channel).
RTL_TLOG = Path(__file__).parent.parent / "replay" / "rtl" / "north_upwind.tlog"
HEAVY = ("scipy", "matplotlib", "sklearn", "filterpy", "dask", "distributed", "pyarrow")

DAEMON_PATH = """
import json, sys
from estimator.commands import run  # everything `uav-energy run` imports
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.config import build_config
from estimator.mavlink.publish import json_line
from estimator.physics.vehicle import default_vehicle
from estimator.telemetry.decode import USED_MESSAGE_IDS, TelemetryDecoder
from estimator.telemetry.frames import FrameParser

started = sorted(sys.modules)
data = open(sys.argv[1], "rb").read()
settings = build_config({}, {}).pipeline_settings()
decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle(), settings)
estimates = returns = 0
for msg in FrameParser(USED_MESSAGE_IDS, stream=True).feed(data[8:]):  # the stamps: garbage
    for sample in decoder.decode(msg):
        if (estimate := pipeline.process(sample)) is not None:
            json_line(estimate)
            estimates += 1
            returns += estimate.rth_energy_wh is not None
print(json.dumps({"started": started, "flying": sorted(sys.modules), "estimates": estimates,
                  "returns": returns}))
"""


@pytest.mark.parametrize("log", [FLIGHT_TLOG, RTL_TLOG], ids=["guided", "rtl-in-wind"])
def test_the_daemon_path_imports_no_analysis_nor_fleet_package(log: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-c", DAEMON_PATH, str(log)],
        capture_output=True,
        text=True,
        check=True,
    )
    result = json.loads(out.stdout)
    assert result["estimates"] > 50  # the telemetry went through the whole pipeline
    assert result["returns"] > 50  # and the return figures were computed
    for stage in ("started", "flying"):
        heavy = sorted({m for m in result[stage] if m.split(".")[0] in HEAVY})
        assert heavy == [], f"{stage}: {heavy[:5]}"
