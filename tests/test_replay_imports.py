"""`uav-energy replay` starts with what a replay needs: a PX4 .ulg replay imports no pymavlink
(only tlogs and DataFlash logs are read with it), no replay imports asyncio (the daemon's links;
a configuration's connection strings are checked without them)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from fixtures.flight import write_bin, write_ulg

REPLAY = """
import contextlib, io, json, sys
from estimator.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["replay", sys.argv[1], "--json"])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


@pytest.mark.parametrize(
    ("writer", "unwanted"),
    [(write_ulg, ("pymavlink", "asyncio")), (write_bin, ("asyncio",))],
    ids=["ulog", "dataflash"],
)
def test_replay_imports_only_what_its_log_needs(
    tmp_path: Path, writer: object, unwanted: tuple[str, ...]
) -> None:
    log = writer(tmp_path / "flight", None)  # type: ignore[operator]
    out = subprocess.run(
        [sys.executable, "-c", REPLAY, str(log)], capture_output=True, text=True, check=True
    )
    result = json.loads(out.stdout.splitlines()[-1])
    assert result["code"] == 0
    loaded = sorted({m for m in result["modules"] if m.split(".")[0] in unwanted})
    assert loaded == [], loaded[:5]
