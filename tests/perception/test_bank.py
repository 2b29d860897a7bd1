"""The random-system bank of benchmarks/bench_bank.py on three tiny systems: its generator draws
valid cases and the coloured-noise Kalman smoother matches the exact posterior on them."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_benchmark


@pytest.fixture(scope="module")
def bank():
    return load_benchmark("bench_bank")


@pytest.mark.parametrize("index", [0, 2, 3])  # known sines; unknown GP input; unknown pulses
def test_smoother_matches_exact_posterior_on_tiny_bank_cases(bank, index):
    case = bank.draw_case(index, tiny=True)
    n, N = case.system.n_states, len(case.outputs)
    assert 2 <= n <= 3 and 150 <= N <= 200
    assert np.max(np.linalg.eigvals(case.system.A).real) < 0
    assert case.system.is_observable()
    assert case.known == (index % 4 < 2)
    limit, _ = bank.exact(case)
    smoother, _ = bank.kalman(case)
    assert smoother.status == "ok"
    ratio = bank.sse(smoother.states, case.states) / bank.sse(limit.states, case.states)
    assert ratio <= 1.1
    if not case.known:
        assert bank.sse(smoother.inputs, case.inputs) / bank.sse(limit.inputs, case.inputs) <= 1.1


def test_generator_is_reproducible(bank):
    first, second = bank.draw_case(5, tiny=True), bank.draw_case(5, tiny=True)
    assert np.array_equal(first.outputs, second.outputs)
    assert np.array_equal(first.system.A, second.system.A)
