"""A model file's f and g at many points at once (attend.io.python_model, ``at_rows``): the same
values as one call per point, and the same checks and messages, whatever the function returns."""

import numpy as np
import pytest

from attend import io
from attend._validation import AttendInputError

LORENZ_PY = '''
import numpy as np

P = (18.0, -4.0, 46.92)
BUFFER = np.zeros(3)


def f(x, v{extra}):
    J = np.array([[-P[0], P[0], 0.0], [P[2] - x[2], -1.0, -x[0]], [x[1], x[0], P[1]]])
    return {value}


def g(x, v{extra}):
    return np.array([x[0] + x[1] + x[2]])
{parameters}'''

TOML = '''[model]
python = "model.py"
n_states = 3
n_inputs = 0
n_outputs = 1

[outputs]
columns = ["y1"]

[observer]
kernel_width = 0.125
sensor_precision = 1.0
process_precision = 1e6
'''


def _f(tmp_path, value="J @ x / 32.0", parameters=False):
    """The checked f of a model file whose f returns ``value``."""
    extra = ", parameters" if parameters else ""
    (tmp_path / "model.py").write_text(LORENZ_PY.format(
        extra=extra, value=value, parameters='\nparameters = {"scale": 32.0}\n' if parameters else ""))
    (tmp_path / "model.toml").write_text(TOML)
    return io.read_model(tmp_path / "model.toml").system.f


def _points(count=7, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(scale=10.0, size=(count, 3)), np.zeros((count, 0))


@pytest.mark.parametrize("value, parameters", [
    ("J @ x / 32.0", False), ("J @ x / parameters['scale']", True), ("(J @ x / 32.0)[:, None]", False),
    ("list(J @ x / 32.0)", False),
    ("BUFFER.__setitem__(slice(None), J @ x / 32.0) or BUFFER", False),  # one buffer, filled at every call
    ("BUFFER.__setitem__(slice(None), J @ x / 32.0) or BUFFER[:]", False),  # a new view of that buffer each time
    ("x", False),  # a view of the point itself
])
def test_many_points_give_the_values_of_one_call_each(tmp_path, value, parameters):
    f = _f(tmp_path, value, parameters)
    x, v = _points()
    rows = f.at_rows(x, v)
    assert rows.shape == (7, 3) and rows.dtype == float
    np.testing.assert_array_equal(rows, np.array([f(a, b).copy() for a, b in zip(x, v)]))
    assert len(np.unique(rows[:, 0])) == 7
    assert f.at_rows(x[:0], v[:0]).shape == (0, 3)


@pytest.mark.parametrize("value, message", [
    ("J @ x / (x[0] - x[0])", "f(x, v) returned non-finite values"),
    ("J @ x / (1 // int(abs(x[0]) > 1))", "f(x, v) failed (line 10): ZeroDivisionError"),
    ("J @ x if x[0] == 0 else (J @ x)[:2]", "f(x, v) returned shape (2,); expected 3 values"),  # fine where read
    ("J @ x if x[0] == 0 else None", "f(x, v) returned NoneType"),
])
def test_a_failure_at_one_point_is_reported_as_one_call_reports_it(tmp_path, value, message):
    f = _f(tmp_path, value)
    x, v = _points()
    x[3, 0] = 0.5  # the ZeroDivisionError's point: |x1| <= 1
    with pytest.raises(AttendInputError) as one:
        for a, b in zip(x, v):
            f(a, b)
    with pytest.raises(AttendInputError) as many:
        f.at_rows(x, v)
    assert message in str(many.value)
    assert str(many.value) == str(one.value)
