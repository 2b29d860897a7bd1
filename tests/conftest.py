"""Shared test fixtures: where the shared data lives."""

import os
from pathlib import Path

# One BLAS thread: the small matrices of these tests run slower multi-threaded on 2 cores.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import pytest

SHARED = Path(os.environ.get("ATTEND_SHARED", Path(__file__).resolve().parents[2] / "shared"))
QUADROTOR_DATA = SHARED / "data" / "quadrotor-wind"


@pytest.fixture
def quadrotor_data() -> Path:
    if not QUADROTOR_DATA.is_dir():
        pytest.skip(f"quadrotor flight data not found at {QUADROTOR_DATA} (set ATTEND_SHARED)")
    return QUADROTOR_DATA
