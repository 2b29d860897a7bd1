"""Shared test fixtures: where the shared data lives; benchmarks loaded as modules."""

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


def load_benchmark(name: str):
    """The module benchmarks/NAME.py (benchmarks are scripts, not a package), loaded once."""
    import importlib.util
    import sys

    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def model_file_text(*sections) -> str:
    """The text of a model file (TOML) from (header, {key: value}) pairs, e.g.
    ("[observer]", {"kernel_width": 0.5}) or ("[[inputs]]", {...}): one ``key = value`` line per entry,
    values written as JSON (which TOML reads alike for numbers, strings in double quotes and lists),
    a blank line between sections. Tests edit the text with str.replace, so it is plain and stable."""
    import json

    tables = [header + "\n" + "".join(f"{key} = {json.dumps(value)}\n" for key, value in table.items())
              for header, table in sections]
    return "\n" + "\n".join(tables)


#: A mass-spring-damper model file whose stiffness, damping and gain are learned from a log with
#: columns t, y, u (prior A[2,1] = A[2,2] = -1, B[2,1] = 1; noise kernel width 0.5 s).
MASS_SPRING_LEARNING_MODEL = """
[model]
A = [[0, 1], [-1.0, -1.0]]
B = [[0], [1.0]]
C = [[1, 0]]
[outputs]
columns = ["y"]
[[inputs]]
name = "force"
column = "u"
[observer]
kernel_width = 0.5
sensor_precision = 2980.0
process_precision = 2980.0
[learning]
free = ["A[2,1]", "A[2,2]", "B[2,1]"]
max_iterations = 50
"""
