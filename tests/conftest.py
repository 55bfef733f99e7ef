"""Tests that need data or simulators from ../shared: skipped with their reason on a clone
without them, failed in CI (``CI=true``), where ../shared is beside the clone and a missing
file is a broken path, not an absent one.

Mark a test ``@pytest.mark.needs(present, "what is missing")``."""

from __future__ import annotations

import os

import pytest


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "needs(present, what): data or a simulator the test needs (see conftest)"
    )


def pytest_runtest_setup(item: pytest.Item) -> None:
    for marker in item.iter_markers(name="needs"):
        present, what = marker.args
        if present:
            continue
        if os.environ.get("CI") == "true":
            pytest.fail(f"{what}: CI has ../shared, so this is a broken path", pytrace=False)
        pytest.skip(what)
