"""Fuzzed model files and logs through `attend estimate` and `attend identify` (a fast subset of
benchmarks/bench_fuzz.py): exit 0 with finite output, or exit 2 with one line naming the file."""

import tempfile
import warnings
from pathlib import Path

from hypothesis import HealthCheck, given, settings

from fuzz_cases import ALLOWED, fuzz_case, nonlinear_fuzz_case, run_case


@settings(max_examples=100, deadline=None, database=None, derandomize=True,
          suppress_health_check=list(HealthCheck))
@given(case=fuzz_case())
def test_generated_files_give_results_or_one_line_errors(case):
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for command in ("estimate", "identify"):
            outcome = run_case(case, Path(folder) / command, command)
            assert outcome.category in ALLOWED, (outcome.category, outcome.mutations, outcome.stderr)


@settings(max_examples=40, deadline=None, database=None, derandomize=True,
          suppress_health_check=list(HealthCheck))
@given(case=nonlinear_fuzz_case())
def test_generated_nonlinear_files_give_results_or_one_line_errors(case):
    """Nonlinear model files: f broken the ways users break it, wrong sizes, bad settings, gaps."""
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        outcome = run_case(case, Path(folder) / "estimate", "estimate")
        assert outcome.category in ALLOWED, (outcome.category, outcome.mutations, outcome.stderr)
