"""Shared fixtures. Real data lives in ../shared/data beside the checkout."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent (CI has ../shared beside the checkout)")
    return SHARED_DATA


# Deadlines off: the first call of a numba kernel in a fresh environment compiles it, which
# is a one-off cost, not what these tests measure (speed lives in benchmarks/).
from hypothesis import settings  # noqa: E402

settings.register_profile("camkit", deadline=None, max_examples=100)
settings.load_profile("camkit")
