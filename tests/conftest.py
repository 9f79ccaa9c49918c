"""Shared test fixtures: where the real vendor metadata lives, and the rendered scene with roads of
the snapping tests (``rendered``, tests/support/snapping.py).

The real test data (Pleiades DIMAP, WorldView-2 and WorldView-3 Maxar XML, with their attribution
and licences in tests/data/README.md) is kept in the repository under tests/data/, so a bare clone
runs the whole suite.
"""
from pathlib import Path

import pytest

from tests.support import plugin_package  # noqa: F401 (registers the package pushbroom_adjust)
from tests.support.paths import TEST_DATA
from tests.support.snapping import rendered  # noqa: F401 (a fixture: test_snapping.py, test_snaplines.py)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The folder of the real vendor test data (tests/data: pleiades/, worldview2/, worldview3/)."""
    if not TEST_DATA.is_dir():
        pytest.fail(f"real test data not found at {TEST_DATA} (it is part of the repository)")
    return TEST_DATA
