"""Shared test fixtures: where the real vendor metadata lives.

CI clones the repository with ``shared/`` beside it, so the real data is ../shared/data
relative to the repository root (also in a developer's checkout).
"""
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.fail(f"real test data not found at {SHARED_DATA} (expected shared/ beside the repository)")
    return SHARED_DATA
