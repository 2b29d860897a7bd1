"""attend._threads: one BLAS thread inside the estimators, the caller's setting restored after."""

import threading

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS)

from attend import _threads


@pytest.fixture
def two_threads():
    controls = _threads._find_controls()
    if not controls:
        pytest.skip("no OpenBLAS loaded (another BLAS): nothing to limit")
    before = _threads.blas_threads()
    for _, setter in controls:
        setter(2)
    yield controls
    for (_, setter), count in zip(controls, before):
        setter(count)


def test_one_thread_inside_and_the_previous_count_after(two_threads):
    assert _threads.blas_threads() == [2] * len(two_threads)
    with _threads.single_blas_thread():
        assert _threads.blas_threads() == [1] * len(two_threads)
        with _threads.single_blas_thread():  # re-entrant
            assert _threads.blas_threads() == [1] * len(two_threads)
        assert _threads.blas_threads() == [1] * len(two_threads)
    assert _threads.blas_threads() == [2] * len(two_threads)


def test_restored_after_an_exception_and_shared_between_threads(two_threads):
    with pytest.raises(ValueError):
        with _threads.single_blas_thread():
            raise ValueError("boom")
    assert _threads.blas_threads() == [2] * len(two_threads)
    inside, release = threading.Event(), threading.Event()

    def worker():
        with _threads.single_blas_thread():
            inside.set()
            release.wait(5)

    thread = threading.Thread(target=worker)
    thread.start()
    inside.wait(5)
    with _threads.single_blas_thread():
        pass  # leaving here must not restore while the worker is still inside
    assert _threads.blas_threads() == [1] * len(two_threads)
    release.set()
    thread.join()
    assert _threads.blas_threads() == [2] * len(two_threads)


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
    dem = NonlinearDEM(system, 0.01, 0.02, 1.0, 1 / 400, embedding_order=2)
    dem.estimate(np.ones((12, 3)))
    assert seen and set(seen) == {(1,) * len(two_threads)}
    assert _threads.blas_threads() == [2] * len(two_threads)


def test_the_switch_keeps_the_threads(two_threads, monkeypatch):
    monkeypatch.setenv("ATTEND_BLAS_THREADS", "keep")
    with _threads.single_blas_thread():
        assert _threads.blas_threads() == [2] * len(two_threads)
