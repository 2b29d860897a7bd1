import io

import numpy as np

import attend
from attend._progress import steps
from attend.experiments.lorenz import lorenz_system
from attend.perception.nonlinear_smoothers import unscented_kalman


def test_loops_are_bare_unless_progress_bars_are_asked_for():
    samples = range(5)
    assert steps(samples, "x") is samples
    with attend.progress_bars():
        bar = steps(samples, "x")
        assert bar is not samples and list(bar) == [0, 1, 2, 3, 4]
        with attend.progress_bars(False):  # nested: the inner setting holds inside, the outer after
            assert steps(samples, "x") is samples
        assert steps(samples, "x") is not samples
    assert steps(samples, "x") is samples


def test_a_slow_unscented_smoother_shows_its_progress(monkeypatch):
    # the bar appears after a second (tqdm's delay): make every sample slow enough
    written = io.StringIO()
    monkeypatch.setattr("sys.stderr", written)
    system = lorenz_system()
    calls = {"count": 0}
    f = system.f

    def slow(x, v):
        calls["count"] += 1
        if calls["count"] % 280 == 0:  # once per sample (7 sigma points x 40 RK4 stages)
            import time
            time.sleep(0.05)
        return f(x, v)

    slow_system = attend.NonlinearSystem(slow, system.g, 3, 0, 3)
    y = np.zeros((40, 3)) + [1.0, 1.0, 24.0]
    with attend.progress_bars():
        unscented_kalman(slow_system, 0.01, y, process_covariance=1.0, measurement_covariance=1.0,
                         initial_mean=[1.0, 1.0, 24.0], initial_covariance=1.0)
    assert "unscented_kalman" in written.getvalue()
    written.truncate(0)
    unscented_kalman(slow_system, 0.01, y[:5], process_covariance=1.0, measurement_covariance=1.0)
    assert written.getvalue() == ""
