"""Kalman smoother and filter under the coloured-noise model: the estimator that keeps the past.

The generative model is the one :func:`attend.models.linear.simulate` samples::

    x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1]        y[k] = C x[k] + z[k]
    w = Lw e_w,  z = Lz e_z                          Lw Lw' = inv(Pi_w),  Lz Lz' = inv(Pi_z)
    e_w, e_z: unit white noise convolved with a Gaussian kernel of width s_w, s_z [s]
    unknown inputs: u = eta + Lu e_u, Lu Lu' = inv(P_v), e_u Gaussian-correlated with
                    autocorrelation rho(tau) = exp(-tau^2 / (4 s_u^2))

Each coloured channel e[k] is written as a small linear model (:func:`attend.models.noise.noise_state_space`:
a minimum-phase spectral factor of its autocorrelation, 3 to 16 states, autocorrelation matched to
~1e-7 (1e-5 for the inputs' prior), with a white part of 1e-8 of the variance for w and z and of
1e-12 .. 1e-10 for the inputs' prior where its fit allows: INPUT_WHITE_FLOORS), and the plant
state is augmented with those noise states. The Kalman filter on the
augmented state is then the causal posterior mean E[x[k] | y[0..k]] and the Rauch-Tung-Striebel
smoother the whole-log posterior mean E[x[k] | y[0..N-1]] of that model: up to the accuracy of
the noise fit, the exact Gaussian posterior (:func:`attend.perception.references.exact_posterior`)
in O(N). Kernel width 0 is white noise. Unlike the DEM observer, evidence from the whole past
(and, in the smoother, the whole future) is carried with its precision.

Speed: the gains do not depend on the data, so the covariance recursion runs only until it
has converged (typically tens to a few hundred samples); from there on the means follow a
time-invariant linear recurrence, evaluated with :func:`attend.perception.recurrence.linear_recurrence`.

Gaps and jitter (:mod:`attend.models.sample_times`): a NaN output is not used (the update at
that sample takes the observed rows of H = [C, 0, Lz readout]: the observed rows of C and the
matching rows of the sensor noise, whose states run on); a time stamp that skips k - 1 samples is
k steps without a measurement in between; steps off dt (jitter) are discretised for their own
length h: the plant's zero-order hold over h, x += h Lw e_w, and each noise as a continuous-time
process (:func:`attend.models.noise.continuous_noise_state_space`: its correlation rho at the true lags,
white floor 1e-8 for every noise, the inputs' prior included). Those runs go through
:func:`attend.perception.kalman_recursions.varying_pass`, a time-varying filter and smoother that
takes the steady gain again on stretches of complete, uniform samples; with jitter every step
costs O(dim^3) (dim: the augmented state's size).

Likelihood: log p(y) from the innovations (:meth:`KalmanEstimator.log_likelihood`; perception.input_width).
"""

from __future__ import annotations

import warnings
from dataclasses import KW_ONLY, InitVar, dataclass, field
from typing import NamedTuple

import numpy as np

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, positive_scalar, precision_matrix, require_finite
from attend._validation import kernel_width as checked_width
from attend.models.linear import LinearSystem, ModelWarning, zero_order_hold
from attend.models.noise_model import NoiseModel
from attend.models.noise import (
    NoiseStateSpace,
    continuous_noise_state_space,
    kernel_autocorrelation,
    noise_state_space,
    sampled_autocorrelation,
    white_state_space,
)
from attend.perception.estimate import Estimate, as_estimate, take_noise
from attend.perception.kalman_online import OnlineKalman
from attend.perception.kalman_recursions import (
    _filter_variances,
    _filtered_means,
    _gain_schedule,
    _predicted_means,
    _smoothed_means,
    _smoother_variances,
    _steady_predicted_covariance,
    InnovationTerms,
    innovation_terms,
    steady_gain,
    varying_innovation_terms,
    varying_pass,
)
from attend.models.sample_times import SampleGrid, bridge, matrix_with_gaps, sample_grid

__all__ = ["KalmanEstimator", "StateEstimate", "OnlineKalman"]


class StateEstimate(NamedTuple):
    """Estimates at every sample: time (N,) [s]; states (N, n) posterior means; inputs (N, r)
    posterior means of unknown inputs (the given ones when measured); state_std (N, n),
    input_std (N, r) posterior standard deviations (0 for measured inputs); method: which
    estimator produced them."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    method: str

    def as_estimate(self) -> Estimate:
        """This result as the common :class:`attend.perception.estimate.Estimate` (details: this result)."""
        return as_estimate(self)


def _factor(precision: np.ndarray, field: str) -> np.ndarray:
    """L with L L' = inv(precision); a singular precision (infinite variance somewhere) is an error."""
    eigenvalues, vectors = np.linalg.eigh(precision)
    if eigenvalues.min() <= 1e-300 or eigenvalues.min() <= 1e-14 * eigenvalues.max():
        raise AttendInputError(
            f"{field}: expected a positive definite precision (a zero precision means infinite noise: "
            "the channel carries no information)"
        )
    return vectors / np.sqrt(eigenvalues)


MAX_WIDTH_SAMPLES = 100
"""Largest kernel width in sample times: smoother noise is close to a constant offset over the
correlation time and its autocorrelation needs more lags than the noise-model fit affords."""


NOISE_WHITE_FLOOR = 1e-8
"""The white part of the process and sensor noise models (relative variance; the default of
:func:`attend.models.noise.noise_state_space`)."""

INPUT_WHITE_FLOORS = (1e-12, 1e-10)
"""White floors tried, smallest first, for the unknown inputs' Gaussian-process prior; the first
whose spectral-factor fit reproduces rho to INPUT_FIT_ACCURACY is kept, else the noises' 1e-8.

The floor is relative to the prior's variance, and unknown inputs usually have broad priors
(std e^4 .. e^5 in the AR.Drone settings of issue 29) that the data narrow by orders of magnitude:
at 1e-8 its white part (std 1e-4 sigma_u, 0.015 for sigma_u = e^5) is comparable to the posterior
std of a smooth input, and moved the smoother's inputs by up to 0.06 posterior std and their
std by up to 6 % from the exact posterior (benchmarks/bench_unknown_inputs.py). The inputs reach
the outputs only through the plant, so the recursion does not need that floor for its
conditioning (the sensor noise's floor keeps H P H' regular). The fit of the smaller floors is
accurate to ~1e-6 up to s_u ~ 15 dt (not at every width: then the next floor is used) and not
beyond, where they are not tried (INPUT_FLOOR_MAX_WIDTH, in sample times)."""
INPUT_FIT_ACCURACY = 1e-5
INPUT_FLOOR_MAX_WIDTH = 16


def _channel_model(dt: float, width: float, kind: str, field: str,
                   floor: float = NOISE_WHITE_FLOOR) -> tuple[NoiseStateSpace, float]:
    """(the noise model of one channel, its white floor: relative variance, 0 for white noise); floor: the
    white part of a "kernel" channel (process or sensor noise)."""
    if width == 0:
        return white_state_space(), 0.0
    if width > MAX_WIDTH_SAMPLES * dt:
        raise AttendInputError(
            f"{field}: {width:g} s is {width / dt:.6g} sample times; expected at most {MAX_WIDTH_SAMPLES} "
            f"({MAX_WIDTH_SAMPLES * dt:g} s): noise that smooth is a slowly varying offset, better modelled as a state"
        )
    if kind == "kernel":
        return noise_state_space(kernel_autocorrelation(dt, width), white_floor=floor), floor
    sequence = sampled_autocorrelation(dt, width)
    for floor in INPUT_WHITE_FLOORS if width <= INPUT_FLOOR_MAX_WIDTH * dt else ():
        model = noise_state_space(sequence, white_floor=floor)
        if model.autocorrelation_error <= INPUT_FIT_ACCURACY:
            return model, floor
    return noise_state_space(sequence), NOISE_WHITE_FLOOR


@dataclass(frozen=True, eq=False)
class KalmanEstimator:
    """Kalman smoother (batch) and filter (causal, online) for an LTI system under coloured noise:
    ``KalmanEstimator(system, dt, *, sensor_precision, process_precision, kernel_width, ...)`` or
    ``KalmanEstimator(system, dt, *, noise=NoiseModel(...), ...)`` (the system and the sample time
    first, everything else by keyword).

    system: the model (A, B, C) in continuous time [1/s]; dt: sample time [s];
    sensor_precision Pi_z [1/output unit^2] and process_precision Pi_w [s^2/state unit^2], as for
    :class:`attend.perception.dem.DEMObserver` (Pi_w = 1/sigma_w^2 for simulate(process_std=sigma_w));
    kernel_width s [s] for both noises, or process_kernel_width / sensor_kernel_width separately
    (0 = white); noise: an :class:`attend.models.NoiseModel` holding those four instead (its
    precisions and widths; giving it with any of them is an error); :attr:`noise_model` reads them
    back as one; known_inputs: inputs measured (True), estimated (False), or one flag per input;
    estimated inputs have a Gaussian-process prior around the prior mean passed to estimate(),
    with precision input_prior_precision P_v [1/input unit^2] (for all r inputs; the block of the
    estimated ones is used) and width input_kernel_width s_u [s] (default: the process width);
    initial_state: prior mean of x[0] (default 0) and initial_state_std its standard deviation
    (0: known; default: known when initial_state is given, else unknown: a broad prior, 100 times
    the scale of the state seen through C in the first sample, or of the sensor noise if larger).
    noise_white_floor: f, the white part of the process and sensor noise models at the nominal step: white noise
    of f times each noise's variance added to it (default NOISE_WHITE_FLOOR, 1e-8: a numerical floor;
    file_kalman_estimator raises it where the log supports more,
    :func:`attend.perception.input_width.choose_white_floor`); steps off dt (jitter) keep the floor 1e-8.
    input_width_choice: how input_kernel_width was chosen from a log (an
    :class:`attend.perception.input_width.InputWidthChoice`, set by file_kalman_estimator; None: given).
    Logs with missing values (NaN) and irregular time stamps: :meth:`estimate` (see the module).
    """

    system: LinearSystem
    dt: float
    _: KW_ONLY
    sensor_precision: np.ndarray | None = None
    process_precision: np.ndarray | None = None
    kernel_width: float | None = None
    process_kernel_width: float | None = None
    sensor_kernel_width: float | None = None
    input_prior_precision: np.ndarray | None = None
    input_kernel_width: float | None = None
    known_inputs: bool = True
    initial_state: np.ndarray | None = None
    initial_state_std: np.ndarray | float | None = None
    noise_white_floor: float = NOISE_WHITE_FLOOR
    input_width_choice: object = field(default=None, repr=False, compare=False)
    noise: InitVar[NoiseModel | None] = None
    _model: dict = field(default_factory=dict, repr=False)

    @with_single_blas_thread
    def __post_init__(self, noise):
        system = self.system
        if not isinstance(system, LinearSystem):
            raise AttendInputError("system: expected an attend.LinearSystem (a python-control StateSpace converts "
                                   "with attend.models.from_statespace)")
        set_ = object.__setattr__
        take_noise(self, noise, "KalmanEstimator")
        n, r, m = system.n_states, system.n_inputs, system.n_outputs
        set_(self, "dt", positive_scalar(self.dt, "dt", "s"))
        floor = self.noise_white_floor
        if isinstance(floor, bool) or not isinstance(floor, (int, float, np.floating)) or not 0 < floor < 1:
            raise AttendInputError(f"noise_white_floor: expected a fraction of the noise variance in (0, 1), got "
                                   f"{floor!r}")
        set_(self, "noise_white_floor", float(floor))
        shared = None if self.kernel_width is None else checked_width(self.kernel_width, "kernel_width")
        widths, sources = {}, {}
        for name in ("process_kernel_width", "sensor_kernel_width"):
            value = getattr(self, name)
            if value is None and shared is None:
                raise AttendInputError(f"{name}: required (or kernel_width for both noises); 0 means white noise")
            widths[name] = shared if value is None else checked_width(value, name)
            sources[name] = "kernel_width" if value is None else name
            set_(self, name, widths[name])
        self._model["width_fields"] = sources
        set_(self, "sensor_precision", precision_matrix(self.sensor_precision, m, "sensor_precision"))
        set_(self, "process_precision", precision_matrix(self.process_precision, n, "process_precision"))
        known = np.broadcast_to(np.asarray(self.known_inputs, dtype=bool), (r,)) if np.ndim(self.known_inputs) == 0 \
            else np.asarray(self.known_inputs, dtype=bool)
        if known.shape != (r,):
            raise AttendInputError(f"known_inputs: expected True, False or {r} flags (one per input)")
        set_(self, "known_inputs", bool(known.all()) if known.all() or not known.any() else tuple(known.tolist()))
        if not known.all():
            if self.input_prior_precision is None:
                raise AttendInputError("input_prior_precision: required when some inputs are unknown")
            full = precision_matrix(self.input_prior_precision, r, "input_prior_precision")
            set_(self, "input_prior_precision", full[np.ix_(~known, ~known)])
            width = self.input_kernel_width
            if width is None:
                width = widths["process_kernel_width"] or widths["sensor_kernel_width"]
            width = checked_width(width, "input_kernel_width")
            if width == 0:
                raise AttendInputError("input_kernel_width: expected a width > 0 [s] for the unknown inputs' "
                                       "prior (the noise widths are both 0)")
            set_(self, "input_kernel_width", width)
        if self.initial_state is not None:
            mean = np.asarray(self.initial_state, dtype=float).reshape(-1)
            if mean.shape != (n,):
                raise AttendInputError(f"initial_state: expected {n} numbers (one per state), got shape "
                                       f"{np.shape(self.initial_state)}")
            require_finite(mean, "initial_state")
            set_(self, "initial_state", mean)
        if self.initial_state_std is not None:
            std = np.broadcast_to(np.asarray(self.initial_state_std, dtype=float), (n,)).copy() \
                if np.ndim(self.initial_state_std) == 0 else np.asarray(self.initial_state_std, dtype=float)
            if std.shape != (n,) or not np.all(np.isfinite(std)) or np.any(std < 0):
                raise AttendInputError(f"initial_state_std: expected a number or {n} numbers >= 0, got "
                                       f"{self.initial_state_std!r}")
            set_(self, "initial_state_std", std)
        self._model.update(self._build())
        self._check_observable()

    # --- the augmented model -----------------------------------------------------------------

    @property
    def noise_model(self) -> NoiseModel:
        """The estimator's noise as one :class:`attend.models.NoiseModel` (the precision matrices
        and widths in use), e.g. to build another estimator with the same noise."""
        return NoiseModel(process_precision=self.process_precision, sensor_precision=self.sensor_precision,
                          process_kernel_width=self.process_kernel_width, sensor_kernel_width=self.sensor_kernel_width)

    @property
    def method(self) -> str:
        """A short name of the estimator for reports."""
        return "kalman (coloured-noise Kalman smoother)"

    def _build(self) -> dict:
        """The augmented model at the nominal step dt, with the noises sampled every dt (the
        discrete fits of :func:`attend.models.noise.noise_state_space`)."""
        system, dt = self.system, self.dt
        fields = self._model["width_fields"]
        floor = self.noise_white_floor
        process, process_floor = _channel_model(dt, self.process_kernel_width, "kernel", fields["process_kernel_width"],
                                                floor)
        sensor, sensor_floor = _channel_model(dt, self.sensor_kernel_width, "kernel", fields["sensor_kernel_width"],
                                              floor)
        unknown = not self._known_mask().all()
        inputs, input_floor = _channel_model(dt, self.input_kernel_width, "sampled", "input_kernel_width") \
            if unknown else (None, None)
        models = {"w": process, "z": sensor, "u": inputs}
        layout = self._layout({name: (model.output, model.stationary_covariance) for name, model in models.items()
                               if model is not None})
        Ad, Bd = system.discretize(dt)
        steps = {name: (model.transition, np.outer(model.noise_input, model.noise_input))
                 for name, model in models.items() if model is not None}
        T, Q, Bd_augmented = self._assemble(layout, Ad, Bd, dt, steps)
        return dict(layout, T=T, Q=Q, Ad=Ad, Bd=Bd, Bd_augmented=Bd_augmented,
                    noise_orders={"process": process.order, "sensor": sensor.order,
                                  "input": None if inputs is None else inputs.order},
                    noise_floors={"process": process_floor, "sensor": sensor_floor, "input": input_floor})

    def _layout(self, channels: dict) -> dict:
        """Blocks of the augmented state [x; noise states of w, z (and u)] and the maps that do not
        depend on the step: H (y = H a), output_map ([x; u - eta] = O a), the stationary prior of
        the noise states. channels: name -> (readout of one channel (width,), its stationary
        covariance (width, width))."""
        system = self.system
        n, m = system.n_states, system.n_outputs
        estimated = np.flatnonzero(~self._known_mask())
        counts = {"w": n, "z": m, "u": len(estimated)}
        slices, start = {"x": slice(0, n)}, n
        for name, (readout, _) in channels.items():
            slices[name] = slice(start, start + counts[name] * readout.size)
            start += counts[name] * readout.size
        dim = start
        readouts = {name: np.kron(np.eye(counts[name]), readout[None, :]) for name, (readout, _) in channels.items()}
        factors = {"w": _factor(self.process_precision, "process_precision"),
                   "z": _factor(self.sensor_precision, "sensor_precision")}
        H = np.zeros((m, dim))
        H[:, slices["x"]] = system.C
        H[:, slices["z"]] = factors["z"] @ readouts["z"]
        output_map = np.zeros((n + len(estimated), dim))  # [x; u - eta of the estimated inputs]
        output_map[:n, slices["x"]] = np.eye(n)
        if len(estimated):
            factors["u"] = _factor(self.input_prior_precision, "input_prior_precision")
            output_map[n:, slices["u"]] = factors["u"] @ readouts["u"]
        stationary = np.zeros((dim, dim))
        for name, (_, covariance) in channels.items():
            stationary[slices[name], slices[name]] = np.kron(np.eye(counts[name]), covariance)
        return dict(slices=slices, dim=dim, H=H, output_map=output_map, stationary=stationary,
                    unknown=len(estimated) > 0, estimated=estimated, readouts=readouts, factors=factors,
                    counts=counts)

    def _assemble(self, layout: dict, Ad, Bd, step: float, channels: dict):
        """(T, Q, Bd_augmented) of one step of ``step`` seconds: the plant's zero-order hold (Ad, Bd),
        the process noise held over the step (x += step Lw e_w) and each noise channel's
        (transition, covariance) in ``channels``."""
        slices, readouts, factors, counts = layout["slices"], layout["readouts"], layout["factors"], layout["counts"]
        dim = layout["dim"]
        T, Q = np.zeros((dim, dim)), np.zeros((dim, dim))
        for name, (transition, covariance) in channels.items():
            block = slices[name]
            T[block, block] = np.kron(np.eye(counts[name]), transition)
            Q[block, block] = np.kron(np.eye(counts[name]), covariance)
        T[slices["x"], slices["x"]] = Ad
        T[slices["x"], slices["w"]] = step * factors["w"] @ readouts["w"]
        if layout["unknown"]:
            T[slices["x"], slices["u"]] = Bd[:, layout["estimated"]] @ factors["u"] @ readouts["u"]
        Bd_augmented = np.zeros((dim, self.system.n_inputs))  # b = Bd u enters the plant block
        Bd_augmented[slices["x"]] = Bd
        return T, Q, Bd_augmented

    @property
    def augmented_model(self) -> dict:
        """The augmented model of uniform samples: the plant and noise blocks of the augmented state
        (keys such as "dim", "slices", the transition and noise matrices), built once per estimator."""
        return self._model

    def continuous_model(self) -> dict:
        """The augmented model for jittered time stamps: every noise a continuous-time process
        (:func:`attend.models.noise.continuous_noise_state_space`, autocorrelation rho(tau) at the actual
        lags), discretised per step by :meth:`continuous_step`. Built once."""
        if "continuous" not in self._model:
            widths = {"w": self.process_kernel_width, "z": self.sensor_kernel_width}
            if not self._known_mask().all():
                widths["u"] = self.input_kernel_width
            models = {name: continuous_noise_state_space(width) for name, width in widths.items()}
            layout = self._layout({name: (model.readout, model.stationary_covariance)
                                   for name, model in models.items()})
            self._model["continuous"] = dict(layout, models=models, widths=widths)
        return self._model["continuous"]

    def continuous_step(self, step: float):
        """(T, Q, Bd_augmented) of the continuous-time model over one step of ``step`` seconds."""
        model = self.continuous_model()
        Ad, Bd = zero_order_hold(self.system.A, self.system.B, step)
        channels = {name: noise.step(step, model["widths"][name]) for name, noise in model["models"].items()}
        return self._assemble(model, Ad, Bd, step, channels)

    def _known_mask(self) -> np.ndarray:
        """(r,) True where the input is measured."""
        return np.broadcast_to(np.asarray(self.known_inputs, dtype=bool), (self.system.n_inputs,))

    def _check_observable(self) -> None:
        """States (and estimated inputs, as constants) the outputs cannot see: an error when x[0] is unknown."""
        system = self.system
        n = system.n_states
        estimated = self._model["estimated"]
        e = len(estimated)
        A = np.zeros((n + e, n + e))  # continuous time: estimated inputs as constants
        A[:n, :n] = system.A
        A[:n, n:] = system.B[:, estimated]
        C = np.hstack([system.C, np.zeros((system.n_outputs, e))])
        names = list(system.state_names) + [system.input_names[i] for i in estimated]
        basis = unobservable_directions(A, C)
        if basis.shape[1] == 0:
            return
        hidden = [names[i] for i in range(n + e) if np.linalg.norm(basis[i]) > 1e-6]
        rank = n + e - basis.shape[1]
        unknown_start = self.initial_state_std is None and self.initial_state is None
        hidden_states = [name for name in hidden if name in system.state_names]
        message = f"{', '.join(hidden)}: not observable from the outputs (observable dimension {rank} of {n + e})"
        if hidden_states and unknown_start:
            raise AttendInputError(message + "; add outputs that see them, or give initial_state and "
                                   "initial_state_std (their estimate is then the prior's)")
        warnings.warn(message + "; their estimates follow the prior and its standard deviation", ModelWarning,
                      stacklevel=3)

    @property
    def noise_orders(self) -> dict:
        """Orders of the finite noise models (process, sensor, input; 0 = white)."""
        return dict(self._model["noise_orders"])

    @property
    def noise_floors(self) -> dict:
        """White floors of the noise models at the nominal step (process, sensor, input; relative
        variance, 0 = white noise, None = no unknown inputs): the one approximation of the model
        (NOISE_WHITE_FLOOR, INPUT_WHITE_FLOORS)."""
        return dict(self._model["noise_floors"])

    # --- data --------------------------------------------------------------------------------

    def _signals(self, outputs, inputs) -> tuple[np.ndarray, np.ndarray]:
        """(y (N, m), u (N, r)) checked; NaN marks a missing value (inf is an error)."""
        system = self.system
        m, r = system.n_outputs, system.n_inputs
        y = matrix_with_gaps(outputs, "outputs", m)
        if y.shape[0] < 2:
            raise AttendInputError(f"outputs: expected at least 2 samples, got {y.shape[0]}")
        field_name = "inputs" if self.known_inputs is True else "input_prior"
        if inputs is None:
            if self._known_mask().any():
                raise AttendInputError("inputs: the estimator was built with known_inputs=True; pass the measured inputs")
            u = np.zeros((y.shape[0], r))
        else:
            u = matrix_with_gaps(inputs, field_name, r)
            if u.shape != (y.shape[0], r):
                raise AttendInputError(f"{field_name}: expected shape ({y.shape[0]}, {r}), got {u.shape}")
        return y, u

    def initial_prior(self, y: np.ndarray, layout: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Prior mean and covariance of the augmented state at sample 0 (layout: the augmented
        model's blocks, default the nominal one). y: the outputs (NaN: missing); the diffuse prior
        is scaled by the first sample with a measured output."""
        model = self._model if layout is None else layout
        n = self.system.n_states
        mean = np.zeros(model["dim"])
        cov = model["stationary"].copy()
        x = model["slices"]["x"]
        if self.initial_state is not None:
            mean[x] = self.initial_state
        if self.initial_state_std is not None:
            cov[x, x] = np.diag(self.initial_state_std**2)
        elif self.initial_state is not None:
            cov[x, x] = 0.0
        else:  # diffuse: 100 x the scale of the state seen through C in the first sample
            observed = np.isfinite(y)
            first = int(np.argmax(observed.any(axis=1)))
            rows = np.flatnonzero(observed[first]) if observed[first].any() else np.arange(y.shape[1])
            inverse = np.linalg.pinv(self.system.C[rows])
            seen = inverse @ np.nan_to_num(y[first, rows])
            noise_cov = np.linalg.pinv(self.sensor_precision)[np.ix_(rows, rows)]
            noise = np.sqrt(np.mean(np.diag(inverse @ noise_cov @ inverse.T)))
            scale = max(float(np.sqrt(np.mean(seen**2))), float(noise), 1e-12)
            cov[x, x] = np.eye(n) * (100 * scale) ** 2
        return mean, cov

    # --- estimation --------------------------------------------------------------------------

    def estimate(self, outputs, inputs=None, *, time=None) -> Estimate:
        """Posterior means and standard deviations given the whole log (Kalman + RTS smoother), as an
        :class:`attend.perception.estimate.Estimate` (method "kalman smoother"; details: the
        :class:`StateEstimate`).

        outputs (N, m), NaN where a value is missing (no update for that channel at that sample);
        inputs (N, r): the measured inputs (known_inputs) or the inputs' prior mean eta (unknown
        inputs; default 0), NaN gaps of up to BRIDGED_GAP samples interpolated linearly;
        time (N,) [s]: the samples' time stamps (default k dt): skipped stamps are missing samples,
        steps off dt (jitter) are discretised exactly (:mod:`attend.models.sample_times`).
        Estimates are returned at every row, the missing ones included.
        """
        return as_estimate(self._run(outputs, inputs, smooth=True, time=time))

    def filter(self, outputs, inputs=None, *, time=None) -> Estimate:
        """Causal estimates E[x[k] | y[0..k]] and their standard deviations (the Kalman filter),
        as an :class:`attend.perception.estimate.Estimate` (method "kalman filter"; details: the
        StateEstimate); outputs, inputs and time as :meth:`estimate`."""
        return as_estimate(self._run(outputs, inputs, smooth=False, time=time))

    @with_single_blas_thread
    def _run(self, outputs, inputs, smooth: bool, time=None) -> StateEstimate:
        y, u = self._signals(outputs, inputs)
        grid = None if time is None else sample_grid(time, self.dt, y.shape[0])
        complete = np.all(np.isfinite(y)) and np.all(np.isfinite(u))
        if complete and (grid is None or (grid.uniform and not grid.inserted)):
            result = self._run_uniform(y, u, smooth)
            return result if grid is None else result._replace(time=grid.time)
        if grid is None:
            grid = sample_grid(np.arange(y.shape[0]) * self.dt, self.dt)
        return self._run_on_grid(y, u, smooth, grid)

    def _uniform_filter(self, y: np.ndarray, u: np.ndarray):
        """(gain schedule, predicted means, innovations) of the filter on a complete, uniform log."""
        N = y.shape[0]
        model = self._model
        T, H = model["T"], model["H"]
        mean0, cov0 = self.initial_prior(y)
        if "steady_predicted" not in model:
            model["steady_predicted"] = _steady_predicted_covariance(T, model["Q"], H)
        schedule = _gain_schedule(T, model["Q"], H, cov0, N, model["steady_predicted"], model["slices"].values())
        drive = np.zeros((N, model["dim"]))
        drive[:, model["slices"]["x"]] = u @ model["Bd"].T  # b[k] = Bd u[k] enters x[k+1]
        predicted, innovations = _predicted_means(schedule, T, H, y, drive, mean0)
        return schedule, predicted, innovations

    def _run_uniform(self, y: np.ndarray, u: np.ndarray, smooth: bool) -> StateEstimate:
        """Every sample present, uniform steps: the steady-gain shortcut of kalman_recursions."""
        N = y.shape[0]
        model = self._model
        T, H = model["T"], model["H"]
        schedule, predicted, innovations = self._uniform_filter(y, u)
        if smooth:
            readout = _smoothed_means(schedule, T, H, predicted, innovations, model["output_map"])
            covariance_diag = _smoother_variances(schedule, T, H, model["output_map"], N)
        else:
            readout = _filtered_means(schedule, predicted, innovations, model["output_map"])
            covariance_diag = _filter_variances(schedule, H, model["output_map"], N)
        return self._result(readout, covariance_diag, u, np.arange(N) * self.dt, smooth)

    def log_likelihood(self, outputs, inputs=None, *, time=None) -> float:
        """log p(y) under this model: sum_k log N(nu[k]; 0, S[k]) over the filter's innovations
        nu[k] = y[k] - E[y[k] | y[0..k-1]] and their covariances S[k] (exact for the augmented model,
        whose noise fits match the kernels to ~1e-7). outputs, inputs, time as :meth:`estimate`;
        missing outputs (NaN) are left out of y."""
        return self.innovation_terms(outputs, inputs, time=time).log_likelihood

    @with_single_blas_thread
    def innovation_terms(self, outputs, inputs=None, *, time=None) -> InnovationTerms:
        """The parts of :meth:`log_likelihood` (sums of log det S[k] and nu[k]' inv(S[k]) nu[k], the
        count of measured values): every covariance times 1 / lambda scales S[k] alike and keeps nu[k],
        so log p(y | lambda) is closed-form. outputs, inputs and time as :meth:`estimate`."""
        y, u = self._signals(outputs, inputs)
        grid = None if time is None else sample_grid(time, self.dt, y.shape[0])
        complete = np.all(np.isfinite(y)) and np.all(np.isfinite(u))
        if complete and (grid is None or (grid.uniform and not grid.inserted)):
            schedule, _, innovations = self._uniform_filter(y, u)
            return innovation_terms(schedule, self._model["H"], innovations)
        if grid is None:
            grid = sample_grid(np.arange(y.shape[0]) * self.dt, self.dt)
        layout, step_model, steady, y_grid, observed, _ = self._grid_model(y, u, grid)
        mean0, cov0 = self.initial_prior(y_grid, layout)
        return varying_innovation_terms(step_model, layout["H"], np.where(observed, y_grid, 0.0), observed, mean0,
                                        cov0, steady, layout["slices"].values())

    def _grid_model(self, y: np.ndarray, u: np.ndarray, grid: SampleGrid):
        """(layout, step_model, steady gain, y on the grid, its observed mask, u on the grid) of a log
        with missing values or irregular time stamps (see :func:`varying_pass`)."""
        if not np.isfinite(y).any():
            raise AttendInputError("outputs: every value is missing (NaN); expected some measured outputs")
        names = [self.system.input_names[j] for j in range(self.system.n_inputs)]
        field_name = "inputs" if self.known_inputs is True else "input_prior"
        u_grid = bridge(grid, u, field_name, names) if u.shape[1] else np.zeros((len(grid.time), 0))
        y_grid = grid.spread(y)
        observed = np.isfinite(y_grid)
        if grid.uniform:  # gaps of whole samples: the nominal model at every step
            layout = self._model
            T, Q = layout["T"], layout["Q"]
            drive = u_grid @ layout["Bd_augmented"].T
            if "steady_predicted" not in layout:
                layout["steady_predicted"] = _steady_predicted_covariance(T, Q, layout["H"])
            steady = steady_gain(layout["H"], layout["steady_predicted"])

            def step_model(k):
                return T, Q, drive[k - 1]
        else:  # jitter: continuous-time noise models, each step discretised for its own length
            layout, steps, steady = self.continuous_model(), grid.steps, None

            def step_model(k):
                T, Q, Bd_augmented = self.continuous_step(steps[k - 1])
                return T, Q, Bd_augmented @ u_grid[k - 1]
        return layout, step_model, steady, y_grid, observed, u_grid

    def _run_on_grid(self, y: np.ndarray, u: np.ndarray, smooth: bool, grid: SampleGrid) -> StateEstimate:
        """Missing values and irregular time stamps: the time-varying recursions on the grid."""
        layout, step_model, steady, y_grid, observed, u_grid = self._grid_model(y, u, grid)
        mean0, cov0 = self.initial_prior(y_grid, layout)
        readout, covariance_diag = varying_pass(step_model, layout["H"], np.where(observed, y_grid, 0.0), observed,
                                                mean0, cov0, layout["output_map"], smooth, steady,
                                                layout["slices"].values())
        rows = grid.rows
        return self._result(readout[rows], covariance_diag[rows], u_grid[rows], grid.time[rows], smooth)

    def _result(self, readout, covariance_diag, u, time, smooth: bool) -> StateEstimate:
        """StateEstimate from the readout O a (N, n + e) and its variances; u: the given inputs."""
        model = self._model
        n = self.system.n_states
        states = readout[:, :n]
        std = np.sqrt(np.clip(covariance_diag, 0, None))
        estimated_inputs, input_std = u.copy(), np.zeros_like(u)
        estimated_inputs[:, model["estimated"]] += readout[:, n:]
        input_std[:, model["estimated"]] = std[:, n:]
        if not (np.all(np.isfinite(states)) and np.all(np.isfinite(estimated_inputs))):
            raise AttendInputError("outputs: the estimate went non-finite; check the scale of the log and of the "
                                   "precisions")
        method = "kalman smoother" if smooth else "kalman filter"
        return StateEstimate(time, states, estimated_inputs, std[:, :n], input_std, method)

    def online(self, jittered: bool = False) -> "OnlineKalman":
        """A fixed-memory filter fed one sample at a time (see :class:`OnlineKalman`); jittered:
        time stamps off the nominal dt will be passed to its step()."""
        return OnlineKalman(self, jittered)


def unobservable_directions(A: np.ndarray, C: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
    """Orthonormal basis (columns) of the unobservable subspace of (A, C).

    The observable subspace is the Krylov space span{C', A' C', A'^2 C', ...}, built with an
    orthogonalisation at every step (a staircase) instead of the powers of A, whose columns
    become nearly parallel; a new direction counts when its norm exceeds ``tolerance`` times the
    scale of A and C.
    """
    size = A.shape[0]
    scale_A = max(np.linalg.norm(A, 2), 1e-300)
    basis = np.zeros((size, 0))
    block = C.T / max(np.linalg.norm(C, 2), 1e-300)
    for _ in range(size + 1):
        block = block - basis @ (basis.T @ block)
        block = block - basis @ (basis.T @ block)
        U, singular, _ = np.linalg.svd(block, full_matrices=False)
        new = U[:, singular > tolerance]
        if new.shape[1] == 0:
            break
        basis = np.hstack([basis, new])
        block = A.T @ new / scale_A
    if basis.shape[1] >= size:
        return np.zeros((size, 0))
    complement = np.linalg.svd(np.eye(size) - basis @ basis.T)[0][:, : size - basis.shape[1]]
    return complement
