"""attend._threads: one BLAS thread inside the estimators, the caller's setting restored after
(threadpoolctl, imported at the first use)."""

import threading

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS)

from attend import _threads


@pytest.fixture
def two_threads():
    before = _threads.blas_threads()
    if not before:
        pytest.skip("no BLAS found by threadpoolctl: nothing to limit")
    _threads.set_blas_threads(2)
    yield before
    for count in set(before):
        _threads.set_blas_threads(count)


def test_one_thread_inside_and_the_previous_count_after(two_threads):
    assert _threads.blas_threads() == [2] * len(two_threads)
    with _threads.single_blas_thread():
        assert _threads.blas_threads() == [1] * len(two_threads)
        with _threads.single_blas_thread():  # re-entrant
            assert _threads.blas_threads() == [1] * len(two_threads)
        assert _threads.blas_threads() == [1] * len(two_threads)
    assert _threads.blas_threads() == [2] * len(two_threads)


def test_restored_after_an_exception(two_threads):
    with pytest.raises(ValueError):
        with _threads.single_blas_thread():
            raise ValueError("boom")
    assert _threads.blas_threads() == [2] * len(two_threads)


def test_a_worker_thread_limits_and_restores(two_threads):
    """An estimator run in a worker thread (a thread pool, a Dask worker) gets one BLAS thread too."""
    seen = []

    def worker():
        with _threads.single_blas_thread():
            seen.append(_threads.blas_threads())
        seen.append(_threads.blas_threads())

    thread = threading.Thread(target=worker)
    thread.start()
    thread.join()
    assert seen == [[1] * len(two_threads), [2] * len(two_threads)]


def test_estimators_run_with_one_thread_and_restore(two_threads, monkeypatch):
    from attend.experiments.lorenz import lorenz_system
    from attend.perception.nonlinear import NonlinearDEM

    seen = []
    system = lorenz_system()
    original = system.f

    def spy(x, v):
        seen.append(tuple(_threads.blas_threads()))
        return original(x, v)

    object.__setattr__(system, "f", spy)
    dem = NonlinearDEM(system, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                       embedding_order=2)
    dem.estimate(np.ones((12, 3)))
    assert seen and set(seen) == {(1,) * len(two_threads)}
    assert _threads.blas_threads() == [2] * len(two_threads)


def test_the_switch_keeps_the_threads(two_threads, monkeypatch):
    monkeypatch.setenv("ATTEND_BLAS_THREADS", "keep")
    with _threads.single_blas_thread():
        assert _threads.blas_threads() == [2] * len(two_threads)
