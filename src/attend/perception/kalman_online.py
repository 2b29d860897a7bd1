"""The coloured-noise Kalman filter fed one sample at a time (:class:`OnlineKalman`), the
streaming form of :meth:`attend.perception.kalman.KalmanEstimator.filter`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from attend._threads import single_blas_thread
from attend._validation import AttendInputError, require_finite, stream_sample
from attend.perception.kalman_recursions import (
    STEADY_TOLERANCE,
    _blockwise_distance,
    _gain_stream,
    _innovation_weight,
    _joseph,
    _Plateau,
    _steady_predicted_covariance,
    steady_gain,
)
from attend.models.sample_times import SHORTEST_STEP, UNIFORM_TOLERANCE

if TYPE_CHECKING:
    from attend.perception.kalman import KalmanEstimator

__all__ = ["OnlineKalman"]


class OnlineKalman:
    """The Kalman filter fed one sample at a time: ``step(y, u)`` returns (states, inputs,
    state_std, input_std) of the same sample (no delay), equal to :meth:`KalmanEstimator.filter`
    sample by sample (estimator: the KalmanEstimator whose model it runs). Memory does not grow
    with the stream; once the gain is steady each step is two small matrix-vector products.

    Gaps: NaN outputs are not used (no update for those channels); ``step(..., time=t)`` with a
    time stamp that skips samples predicts over the skipped ones (the inputs held). jittered=True:
    time stamps off the nominal dt, each step discretised exactly under the continuous-time noise
    models (as the batch estimators do on a jittered log); then every step needs its time stamp.
    """

    def __init__(self, estimator: KalmanEstimator, jittered: bool = False):
        self.estimator = estimator
        self.jittered = bool(jittered)
        self._model = estimator.augmented_model
        self._count = 0
        self._mean = None
        self._previous_input = None
        self._stream = None
        self._steady = False
        self._time = None
        # explicit covariance (after the first missing value or skipped stamp, or with jitter)
        self._explicit = self.jittered
        self._layout = estimator.continuous_model() if self.jittered else estimator.augmented_model
        self._filtered_cov = None
        self._calm, self._plateau, self._on_steady = 0, _Plateau(), False

    def _covariance_step(self, y: np.ndarray) -> np.ndarray:
        """One step of the time-varying filter (until the gain is steady); returns the filtered mean."""
        est, model = self.estimator, self._model
        T, H = model["T"], model["H"]
        if self._count == 0:
            if "steady_predicted" not in model:
                model["steady_predicted"] = _steady_predicted_covariance(T, model["Q"], H)
            mean, P0 = est.initial_prior(y[None, :])
            self._stream = _gain_stream(T, model["Q"], H, P0, model["steady_predicted"], model["slices"].values())
        else:
            mean = T @ self._mean + model["Bd_augmented"] @ self._previous_input
        K, _, P, self._steady = next(self._stream)
        A = np.eye(model["dim"]) - K @ H
        self._gain = K
        self._filtered_cov = A @ P @ A.T
        variances = np.einsum("ij,jl,il->i", model["output_map"], self._filtered_cov, model["output_map"])
        self._std = np.sqrt(np.clip(variances, 0, None))
        if self._steady:
            self._closed = A @ T
            self._drive_gain = A @ model["Bd_augmented"]
        return mean + K @ (y - H @ mean)

    def _steps(self, time) -> tuple[int, float]:
        """(k, h): the new sample is k steps of h seconds after the previous one."""
        dt = self.estimator.dt
        if time is None:
            if self.jittered:
                raise AttendInputError("time: required at every step of a filter built with online(jittered=True)")
            if self._time is not None:  # a step of dt from the last stamp
                self._time += dt
            return 1, dt
        try:
            stamp = float(time)
        except (TypeError, ValueError):
            raise AttendInputError(f"time: expected the sample's time stamp [s], got {time!r}") from None
        if not np.isfinite(stamp):
            raise AttendInputError(f"time: expected a finite time stamp [s], got {stamp}")
        previous, self._time = self._time, stamp
        if previous is None:
            return 1, dt
        step = stamp - previous
        if step <= 0:
            self._time = previous
            raise AttendInputError(f"time: {stamp:.6g} s is not after the previous sample's {previous:.6g} s; "
                                   "expected strictly increasing time stamps")
        if step < SHORTEST_STEP * dt:
            self._time = previous
            raise AttendInputError(f"time: step of {step:.6g} s is shorter than half the sample time dt = {dt:.6g} s "
                                   "(a duplicated sample?)")
        count = max(1, int(np.floor(step / dt + 0.5)))
        if not self.jittered and abs(step / count - dt) > UNIFORM_TOLERANCE * dt:
            self._time = previous
            raise AttendInputError(f"time: step of {step:.6g} s is not a whole number of sample times dt = {dt:.6g} s; "
                                   "for jittered time stamps build the filter with estimator.online(jittered=True)")
        return count, step / count

    def _explicit_step(self, y: np.ndarray, count: int, step: float) -> np.ndarray:
        """One sample with the covariance carried explicitly: count - 1 steps without a
        measurement, then the update with the measured channels of y; returns the filtered mean."""
        est, layout = self.estimator, self._layout
        H, O = layout["H"], layout["output_map"]
        rows = np.flatnonzero(np.isfinite(y))
        if not self.jittered and "steady_gain" not in self.__dict__:
            model = self._model
            if "steady_predicted" not in model:
                model["steady_predicted"] = _steady_predicted_covariance(model["T"], model["Q"], H)
            self.steady_gain = steady_gain(H, model["steady_predicted"])
        steady = None if self.jittered else self.steady_gain
        if self._count == 0:
            mean, P = est.initial_prior(y[None, :], layout)
        else:
            mean, P_f = self._mean, self._filtered_cov
            for _ in range(count):
                T, Q, Bd_augmented = est.continuous_step(step) if self.jittered else \
                    (layout["T"], layout["Q"], layout["Bd_augmented"])
                mean = T @ mean + Bd_augmented @ self._previous_input
                if self._on_steady and count == 1 and rows.size == H.shape[0]:
                    P = None
                else:
                    P = steady.predicted.copy() if self._on_steady else T @ P_f @ T.T + Q
                    P, P_f = 0.5 * (P + P.T), 0.5 * (P + P.T)
                    self._on_steady, self._calm, self._plateau = False, 0, _Plateau()
        if P is None:  # the steady gain
            K, P_filtered = steady.gain, self._steady_filtered
            mean = mean + K @ (y - H @ mean)
        elif rows.size:
            Ho = H[rows]
            K = P @ _innovation_weight(Ho, P)
            mean = mean + K @ (y[rows] - Ho @ mean)
            P_filtered = _joseph(P, K, Ho)
        else:
            K, P_filtered = np.zeros((H.shape[1], 0)), P
        self._filtered_cov = P_filtered
        self._std = np.sqrt(np.clip(np.einsum("ij,ij->i", O @ P_filtered, O), 0, None))
        if steady is not None and P is not None and rows.size == H.shape[0]:  # back to the steady gain?
            distance = _blockwise_distance(K, steady.gain, layout["slices"].values())
            self._calm = self._calm + 1 if distance <= STEADY_TOLERANCE else 0
            if self._plateau.reached(distance):
                self._calm = 3
            if self._calm >= 3:
                self._on_steady, self._steady_filtered = True, _joseph(steady.predicted, steady.gain, H)
        return mean

    def step(self, output, input_value=None, time=None):
        """Feed sample k (output: the outputs (m,), NaN where missing; input_value: the measured
        input or input prior (r,), default 0; time: its time stamp [s], optional, see the class);
        return its estimate."""
        est = self.estimator
        m, r, n = est.system.n_outputs, est.system.n_inputs, est.system.n_states
        y, u = stream_sample(output, input_value, m, r)
        require_finite(u, "step input_value")
        if np.isinf(y).any():
            raise AttendInputError(f"step output: expected finite numbers (NaN for a missing value), got {y}")
        if self._count == 0 and np.isnan(y).all() and est.initial_state is None and est.initial_state_std is None:
            raise AttendInputError("step output: the first sample has no measured output and the initial state is "
                                   "unknown; give initial_state, or start the stream at a measured sample")
        count, step = self._steps(time)
        if not self._explicit and (count > 1 or np.isnan(y).any()):
            if self._count and self._steady:  # entering the explicit recursion from the steady gain
                model = self._model
                self._filtered_cov = _joseph(model["steady_predicted"], self._gain, model["H"])
            self._explicit = True
        with single_blas_thread():
            if self._explicit:
                mean = self._explicit_step(y, count, step)
            elif self._steady:  # a_f[k] = (I - K H)(T a_f[k-1] + b[k-1]) + K y[k]: precomputed products
                mean = self._closed @ self._mean + self._drive_gain @ self._previous_input + self._gain @ y
            else:
                mean = self._covariance_step(y)
        self._mean = mean
        self._previous_input = u
        self._count += 1
        layout = self._layout if self._explicit else self._model
        readout = layout["output_map"] @ mean
        std = self._std
        inputs, input_std = u.copy(), np.zeros(r)
        inputs[layout["estimated"]] += readout[n:]
        input_std[layout["estimated"]] = std[n:]
        return readout[:n], inputs, std[:n], input_std
