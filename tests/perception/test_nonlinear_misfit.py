"""The checks of a nonlinear estimate against its log (attend.perception.nonlinear.misfit): the
misfit ratio on well-specified logs, and the error when the estimate has left the data."""

import warnings

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.experiments import lorenz
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear.misfit import EXCURSION_LIMIT, check_excursion, sample_misfit


@pytest.fixture(scope="module")
def lorenz_case():
    cfg = lorenz.SETTINGS
    system = lorenz.build_system(cfg)
    log = simulate_nonlinear(system, 200, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=20.0,
                             measurement_std=1.0, initial_state=cfg["initial_state"], seed=5)
    dem = NonlinearDEM(system, cfg["dt"], kernel_width=cfg["kernel_width"], sensor_precision=1.0,
                       process_precision=1 / 400, embedding_order=6)
    return dem, log


def test_a_well_specified_log_has_a_misfit_ratio_near_one(lorenz_case):
    dem, log = lorenz_case
    estimate = dem.estimate(log.outputs, keep_generalized=True)
    ratio = sample_misfit(dem, dem.checked_signals(log.outputs, None), estimate.generalized)
    assert 0.2 < ratio < 2.5  # docs: 0.40-0.44 on Lorenz


def test_an_estimate_near_the_data_passes_and_one_far_from_it_is_an_error(lorenz_case):
    dem, log = lorenz_case
    signals = dem.checked_signals(log.outputs, None)
    no_inputs = np.zeros((len(signals), 0))
    check_excursion(dem, signals, log.states, no_inputs, "test")  # the truth: within ~1 scale
    scale = np.ptp(log.outputs[:, 1]) + 1.0  # y2's range plus its noise std (Pi_z = 1)
    states = log.states.copy()
    states[120:, 1] += 1.5 * EXCURSION_LIMIT * scale  # y = x: y2 predicted 150 scales away
    with pytest.raises(AttendInputError, match=r"test: the estimate left the data: at sample 1\d\d the predicted "
                                               r"y2 = .* output scales from the measured"):
        check_excursion(dem, signals, states, no_inputs, "test")
    states[120:, 1] = np.nan  # non-finite predictions are an excursion too
    with pytest.raises(AttendInputError, match="left the data"):
        check_excursion(dem, signals, states, no_inputs, "test")


def test_a_diverging_d_step_is_an_error_not_a_warning(monkeypatch):
    """Case 24 of benchmarks/bench_nonlinear_bank.py (3 states, a tanh flow, one sinusoidal sensor):
    the D-step's flow runs away (|x| ~ 4e4 against a true scale of 1.8), below the absolute
    divergence_limit; it was a misfit warning only, it is now an error naming the output. Path
    mode, which also starts from the unscented smoother, stays on the data."""
    import sys
    from pathlib import Path

    monkeypatch.syspath_prepend(str(Path(__file__).parents[2] / "benchmarks"))
    import bench_nonlinear_bank as bank

    case = bank.draw_case(24)
    settings = dict(dt=bank.DT, kernel_width=case["s"], sensor_precision=1 / case["sigma_z"] ** 2,
                    process_precision=1 / case["sigma_w"] ** 2, embedding_order=case["p"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(AttendInputError, match=r"NonlinearDEM: the estimate left the data: at sample \d+ the "
                                                   r"predicted y1 = "):
            NonlinearDEM(case["system"], **settings).estimate(case["log"].outputs)
        path = NonlinearDEM(case["system"], states="path", **settings).estimate(
            case["log"].outputs, initial_state=np.zeros(3), initial_state_std=1.0)
    assert np.max(np.abs(path.states)) < 10 * np.max(np.abs(case["log"].states))
    sys.modules.pop("bench_nonlinear_bank", None)
