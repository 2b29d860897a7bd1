"""python-control interoperability: models in, the DEM observer out (checked by simulation)."""

import numpy as np
import pytest

control = pytest.importorskip("control")

from attend import DEMObserver, convolution_model  # noqa: E402
from attend._validation import AttendInputError  # noqa: E402
from attend.models import from_statespace  # noqa: E402
from attend.perception.interop import observer_to_statespace  # noqa: E402


def test_from_statespace_round_trip():
    model = convolution_model()
    converted = from_statespace(control.ss(model.A, model.B, model.C, 0))
    np.testing.assert_array_equal(converted.A, model.A)
    np.testing.assert_array_equal(converted.C, model.C)
    with pytest.raises(AttendInputError, match="continuous-time"):
        from_statespace(control.ss(model.A, model.B, model.C, 0, 0.1))
    with pytest.raises(AttendInputError, match="D must be zero"):
        from_statespace(control.ss(model.A, model.B, model.C, np.ones((4, 1))))


@pytest.mark.parametrize("known_inputs", [False, True])
def test_exported_observer_reproduces_batch_estimates(known_inputs):
    system = convolution_model()
    observer = DEMObserver(system, 0.1, kernel_width=0.5, sensor_precision=np.exp(8), process_precision=np.exp(8),
                           input_prior_precision=None if known_inputs else np.exp(-8), embedding_order=6, input_order=2,
                           known_inputs=known_inputs, edges="clamp")
    rng = np.random.default_rng(0)
    y = np.cumsum(rng.standard_normal((300, 4)), axis=0) * 0.01
    u = np.sin(np.arange(300) * 0.05)[:, None]
    y[:20], u[:20] = 0.0, 0.0  # a quiet start, so both begin from X = 0 with zero windows
    size = observer.n_state_coordinates + observer.n_input_coordinates
    batch = observer.estimate(y, u, initial_state=np.zeros(size))
    statespace = observer_to_statespace(observer)
    assert statespace.dt == 0.1 and statespace.ninputs == 5 and statespace.noutputs == 3
    response = control.forced_response(statespace, U=np.hstack([y, u]).T, X0=0)
    delay = observer.delay
    exported = response.outputs.T[delay:]  # row k + delay estimates sample k
    np.testing.assert_allclose(exported[:, :2], batch.states[: 300 - delay], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(exported[:, 2:], batch.inputs[: 300 - delay], rtol=1e-7, atol=1e-9)
