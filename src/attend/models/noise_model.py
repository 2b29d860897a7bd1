"""The noise of a model as one value (:class:`NoiseModel`): the precisions of the process and sensor
noises and the widths of their Gaussian kernels, taken by every estimator and by the simulators.

Units are those the estimators use (paper eq. 1, dx/dt = f + w, y = g + z):

    process_precision   Pi_w = inv(Cov(w))  [s^2 / state unit^2]   (w is a rate, state unit / s)
    sensor_precision    Pi_z = inv(Cov(z))  [1 / output unit^2]
    process_kernel_width, sensor_kernel_width: s_w, s_z [s] of the Gaussian kernels (0 = white)

:func:`attend.models.simulate` draws w with standard deviation ``process_std`` = sigma_w per sample
(x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1]) and z with ``measurement_std`` = sigma_z, so the model
they simulate has Pi_w = 1 / sigma_w^2 and Pi_z = 1 / sigma_z^2 per channel:
``NoiseModel.from_std(process_std=sigma_w, sensor_std=sigma_z, ...)`` is that model, and
:attr:`NoiseModel.process_std` / :attr:`NoiseModel.sensor_std` give the standard deviations back.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field, fields

import numpy as np

from attend._validation import AttendInputError, numeric_array, precision_matrix
from attend._validation import kernel_width as checked_width

__all__ = ["NoiseModel"]


def _positive(value, name: str, what: str):
    """``value`` (a number, a vector or a square matrix) checked: finite, > 0 (a matrix symmetric
    positive definite); a scalar is returned as a float, arrays as read-only float64 copies."""
    array = numeric_array(value, name, f"a number, vector or matrix of {what}")
    if array.ndim > 2 or (array.ndim == 2 and array.shape[0] != array.shape[1]):
        raise AttendInputError(f"{name}: expected a number, a vector (one value per channel) or a square "
                               f"matrix of {what}, got shape {array.shape}")
    if array.size == 0:
        raise AttendInputError(f"{name}: expected at least one value, got an empty array")
    if not np.all(np.isfinite(array)):
        raise AttendInputError(f"{name}: expected finite {what}, got {value!r}")
    if array.ndim < 2:
        if np.any(array <= 0):
            raise AttendInputError(f"{name}: expected {what} > 0 (every channel), got {value!r}")
        if array.ndim == 0:
            return float(array)
    else:
        scale = float(np.abs(array).max())
        if not np.allclose(array, array.T, rtol=1e-10, atol=1e-12 * scale):
            raise AttendInputError(f"{name}: expected a symmetric matrix")
        if np.linalg.eigvalsh(array).min() <= 0:
            raise AttendInputError(f"{name}: expected a positive definite matrix of {what}")
    array = array.copy()
    array.setflags(write=False)
    return array


def _inverse(value):
    """1 / value for a number or a vector (per channel), inv(value) for a matrix."""
    if np.ndim(value) == 2:
        result = np.linalg.inv(value)
        result = 0.5 * (result + result.T)
    else:
        result = 1.0 / np.asarray(value, dtype=float)
        if result.ndim == 0:
            return float(result)
    result.setflags(write=False)
    return result


def _widths(kernel_width, process_kernel_width, sensor_kernel_width) -> tuple[float, float]:
    """(s_w, s_z) [s]: each given width, or kernel_width for both."""
    widths = []
    for value, name in ((process_kernel_width, "process_kernel_width"), (sensor_kernel_width, "sensor_kernel_width")):
        if value is None:
            if kernel_width is None:
                raise AttendInputError(f"{name}: required (or kernel_width for both noises); 0 means white noise")
            widths.append(checked_width(kernel_width, "kernel_width"))
        else:
            widths.append(checked_width(value, name))
    return widths[0], widths[1]


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """The process and sensor noise of a model: precisions and kernel widths, in one value.

    ``NoiseModel(process_precision=Pi_w, sensor_precision=Pi_z, kernel_width=s)`` (or
    process_kernel_width / sensor_kernel_width instead of kernel_width); all arguments by keyword.

    process_precision: Pi_w [s^2 / state unit^2], the precision of the process noise w (a rate, as
    in dx/dt = f + w); sensor_precision: Pi_z [1 / output unit^2], the precision of the sensor
    noise z. Each is a number (the same for every channel: times I), a vector (one per channel:
    a diagonal) or a symmetric positive definite matrix; the estimators check the sizes.
    process_kernel_width: s_w [s], the width of w's Gaussian kernel; sensor_kernel_width: s_z [s],
    z's (0 = white noise); kernel_width: s [s] for both (an argument only: the fields hold the two
    widths, and :attr:`kernel_width` reads them back when they are equal).

    Constructors from other forms: :meth:`from_std` (standard deviations, as
    :func:`attend.models.simulate` takes them: Pi_w = 1 / process_std^2, Pi_z = 1 / sensor_std^2)
    and :meth:`from_covariance` (Pi = inv(covariance)); the reverse: :attr:`process_std`,
    :attr:`sensor_std`, :attr:`process_covariance`, :attr:`sensor_covariance`. A model built by
    from_std (from_covariance) gives back exactly the numbers it was given, so that
    ``simulate(noise=NoiseModel.from_std(process_std=0.3, ...))`` draws the very noise
    ``simulate(process_std=0.3, ...)`` draws. Every estimator takes it as ``noise=``
    (KalmanEstimator, DEMObserver, NonlinearDEM, the unscented/extended smoothers, the particle
    smoother) and so do :func:`attend.models.simulate` and
    :func:`attend.perception.references.exact_posterior`. Two models are equal when their fields are.
    """

    process_precision: float | np.ndarray
    sensor_precision: float | np.ndarray
    process_kernel_width: float | None = None
    sensor_kernel_width: float | None = None
    kernel_width: InitVar[float | None] = None
    _given: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self, kernel_width):
        set_ = object.__setattr__
        set_(self, "process_precision", _positive(self.process_precision, "process_precision", "precisions"))
        set_(self, "sensor_precision", _positive(self.sensor_precision, "sensor_precision", "precisions"))
        process_width, sensor_width = _widths(kernel_width, self.process_kernel_width, self.sensor_kernel_width)
        set_(self, "process_kernel_width", process_width)
        set_(self, "sensor_kernel_width", sensor_width)

    # --- other forms ---------------------------------------------------------------------------

    @classmethod
    def from_std(cls, *, process_std, sensor_std, kernel_width=None, process_kernel_width=None,
                 sensor_kernel_width=None) -> "NoiseModel":
        """The noise model of standard deviations: process_std sigma_w [state unit / s] and
        sensor_std sigma_z [output unit] per sample (numbers or one per channel, > 0), as
        :func:`attend.models.simulate` takes them (its ``process_std`` and ``measurement_std``):
        Pi_w = 1 / sigma_w^2, Pi_z = 1 / sigma_z^2. kernel_width s [s] for both noises, or
        process_kernel_width / sensor_kernel_width separately (0 = white noise)."""
        stds = {}
        for value, name in ((process_std, "process_std"), (sensor_std, "sensor_std")):
            std = _positive(value, name, "standard deviations")
            if np.ndim(std) == 2:
                raise AttendInputError(f"{name}: expected a number or one standard deviation per channel (a "
                                       "vector); for correlated noise use NoiseModel.from_covariance")
            stds[name] = std
        model = cls(process_precision=_inverse(np.square(stds["process_std"])),
                    sensor_precision=_inverse(np.square(stds["sensor_std"])), kernel_width=kernel_width,
                    process_kernel_width=process_kernel_width, sensor_kernel_width=sensor_kernel_width)
        model._given.update(stds)
        return model

    @classmethod
    def from_covariance(cls, *, process_covariance, sensor_covariance, kernel_width=None,
                        process_kernel_width=None, sensor_kernel_width=None) -> "NoiseModel":
        """The noise model of covariances: process_covariance Cov(w) [state unit^2 / s^2] and
        sensor_covariance Cov(z) [output unit^2] per sample (a number, per-channel variances or a
        symmetric positive definite matrix): Pi_w = inv(Cov(w)), Pi_z = inv(Cov(z)). Note Cov(w) is
        the covariance of the rate w, not of the per-sample state increment dt w (the white-noise
        smoothers' Q = dt^2 Cov(w)). kernel_width s [s] for both noises, or process_kernel_width /
        sensor_kernel_width separately (0 = white noise)."""
        covariances = {name: _positive(value, name, "variances") for value, name in
                       ((process_covariance, "process_covariance"), (sensor_covariance, "sensor_covariance"))}
        model = cls(process_precision=_inverse(covariances["process_covariance"]),
                    sensor_precision=_inverse(covariances["sensor_covariance"]), kernel_width=kernel_width,
                    process_kernel_width=process_kernel_width, sensor_kernel_width=sensor_kernel_width)
        model._given.update(covariances)
        return model

    def _std(self, name: str, precision):
        if name in self._given:
            return self._given[name]
        if np.ndim(precision) == 2:
            if self.correlated:
                raise AttendInputError(f"noise: {name} is per channel, and this model's "
                                       f"{name.replace('std', 'precision')} is a matrix with off-diagonal terms "
                                       "(correlated channels); use the precision or covariance instead")
            precision = np.diag(precision)
        std = np.sqrt(_inverse(precision))
        return float(std) if np.ndim(std) == 0 else std

    @property
    def process_std(self):
        """sigma_w [state unit / s] per channel: 1 / sqrt(Pi_w) (a number for a number; the given
        values for a model built by :meth:`from_std`). An AttendInputError for correlated channels."""
        return self._std("process_std", self.process_precision)

    @property
    def sensor_std(self):
        """sigma_z [output unit] per channel: 1 / sqrt(Pi_z) (a number for a number; the given values
        for a model built by :meth:`from_std`). An AttendInputError for correlated channels."""
        return self._std("sensor_std", self.sensor_precision)

    @property
    def process_covariance(self):
        """Cov(w) [state unit^2 / s^2]: inv(Pi_w) (1 / Pi_w per channel for a number or a vector; the
        given values for a model built by :meth:`from_covariance`)."""
        return self._given.get("process_covariance", _inverse(self.process_precision))

    @property
    def sensor_covariance(self):
        """Cov(z) [output unit^2]: inv(Pi_z) (1 / Pi_z per channel for a number or a vector; the given
        values for a model built by :meth:`from_covariance`)."""
        return self._given.get("sensor_covariance", _inverse(self.sensor_precision))

    @property
    def correlated(self) -> bool:
        """True when a precision is a matrix with off-diagonal terms (channels correlated)."""
        return any(np.ndim(p) == 2 and np.any(p - np.diag(np.diag(p))) for p in
                   (self.process_precision, self.sensor_precision))

    def precision_matrices(self, n_states: int, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
        """(Pi_w (n, n), Pi_z (m, m)) as full matrices for a system of n_states states and n_outputs
        outputs (an AttendInputError names a precision of the wrong size)."""
        return (precision_matrix(self.process_precision, n_states, "noise.process_precision"),
                precision_matrix(self.sensor_precision, n_outputs, "noise.sensor_precision"))

    def precision_keywords(self) -> dict:
        """The keywords the estimators take for this model: sensor_precision, process_precision and
        either kernel_width (both widths equal; the per-channel widths None) or
        process_kernel_width and sensor_kernel_width (kernel_width None), as a caller would write them."""
        same = self.process_kernel_width == self.sensor_kernel_width
        return dict(sensor_precision=self.sensor_precision, process_precision=self.process_precision,
                    kernel_width=self.process_kernel_width if same else None,
                    process_kernel_width=None if same else self.process_kernel_width,
                    sensor_kernel_width=None if same else self.sensor_kernel_width)

    def __eq__(self, other) -> bool:
        if not isinstance(other, NoiseModel):
            return NotImplemented
        return all(np.shape(getattr(self, f.name)) == np.shape(getattr(other, f.name))
                   and np.array_equal(getattr(self, f.name), getattr(other, f.name))
                   for f in fields(self) if f.init)

    __hash__ = None


def _common_width(model: NoiseModel) -> float | None:
    """The common width s [s] of both noises, or None when process_kernel_width and
    sensor_kernel_width differ (``kernel_width`` is also an argument of the constructor, so this
    property is attached after the dataclass is made: the argument's default stays None; in
    dataclasses.replace the two per-channel widths, which are fields, take precedence over it)."""
    return model.process_kernel_width if model.process_kernel_width == model.sensor_kernel_width else None


NoiseModel.kernel_width = property(_common_width)


def resolve_noise(noise, given: dict, who: str) -> NoiseModel | None:
    """``noise`` checked against the separate keywords it replaces: ``noise`` (a :class:`NoiseModel`)
    when it is given, None when it is not; an AttendInputError when it is something else, or when
    it comes with any of the separate keywords in ``given`` (name -> value, None when not given),
    naming them. who: the estimator's or simulator's name, for the message. Converting the model
    into the keywords is the caller's (:meth:`NoiseModel.precision_keywords` for precisions,
    :attr:`NoiseModel.process_std` ... for standard deviations)."""
    if noise is None:
        return None
    if not isinstance(noise, NoiseModel):
        raise AttendInputError(f"noise: expected an attend.models.NoiseModel (or None), got {type(noise).__name__}")
    both = [name for name, value in given.items() if value is not None]
    if both:
        raise AttendInputError(f"noise and {', '.join(both)}: {who} takes the noise either as noise=NoiseModel(...) "
                               f"or as the separate keywords ({', '.join(given)}), not both")
    return noise
