"""DEM observer: state and input estimation in generalised coordinates (the D-step).

Unknowns X = [x~; v~] (states with p + 1 orders, inputs with d + 1 orders). Prediction errors::

    e_y = y~ - C~ x~                 sensory,   precision Vy = kron(S_p, Pi_z)
    e_v = v~ - eta~                  input prior, precision Vv = kron(S_d, P_v)
    e_x = D_x x~ - A~ x~ - B~ v~     motion,    precision W  = kron(S_p, Pi_w)

Free energy F(X) = -1/2 e' Pi~ e. The generalised gradient flow dX/dt = D_X X + dF/dX is linear
for LTI models::

    dX/dt = A_obs X + B_obs [y~; eta~]

and is discretised exactly (zero-order hold over dt): X[k] = Phi X[k-1] + Gamma [y~; eta~][k].
With known inputs, v~ leaves the unknowns and the embedded input u~ drives the flow instead.
The conditional precision Pi_X = -d2F/dX2 is time-invariant; its inverse gives the standard
deviations of the estimates.

Since the embedding y~[k] = E window[k] is linear in the raw samples, the embedding weights are
folded into Gamma: each step is a product with the raw window of samples around k.

Before estimating, :meth:`DEMObserver.analysis` says what the observer can promise (stability of
Phi, how long the start is remembered, the steady-state error std under the model; see
:mod:`attend.perception.dem_analysis`). What cannot run on the log is refused with an
AttendInputError naming the setting to change, unless ``allow_unstable=True``: a stable observer
that still remembers its start late in the log ("drifting"), or one whose slowest mode grows
(spectral radius rho >= 1) by GROWTH_LIMIT (2x) or more over the log's N samples, rho^N >= 2. Since
N is known only there, that judgement is made in :meth:`DEMObserver.estimate`; slower growth runs
with a ModelWarning naming it (the authors' AR.Drone settings: rho = 1.00007, 1.2x over 2600
samples). The constructor refuses only orders that double within the shortest log they accept,
or have a mode on the unit circle (to 1e-9: a coordinate the flow does not pull at all).
"""

from __future__ import annotations

import warnings
from dataclasses import KW_ONLY, InitVar, dataclass, field
from typing import NamedTuple

import numpy as np

from attend._threads import with_single_blas_thread
from attend._validation import (
    AttendInputError,
    as_matrix,
    order,
    positive_scalar,
    precision_matrix,
    require_finite,
)
from attend.models.generalized import smoothness_condition
from attend.models.linear import LinearSystem, ModelWarning, as_linear_system
from attend.models.noise_model import NoiseModel
from attend.perception.dem_analysis import (
    derivative_scales,
    PINNED_INPUT_PRECISION,
    UNOBSERVABLE_RATIO,  # noqa: F401 (importable from attend.perception.dem as before)
    observer_error_std,
    start_influence,
    start_time_constant,
)
from attend.perception.dem_flow import (centre_samples, flow_matrices, known_input_error, samples_after_centre,
                                        start_state)
from attend.perception.dem_online import OnlineDEM
from attend.perception.estimate import Estimate, as_estimate, take_noise
from attend.perception.recurrence import linear_recurrence


#: Largest embedding order that embedding_order="auto" considers.
AUTO_MAX_ORDER = 6
#: embedding_order="auto" accepts an order only if cond(S) in sample units (s / dt) stays below this.
AUTO_MAX_CONDITION = 1e8
#: embedding_order="auto" accepts an order only if its start time constant (see DEMAnalysis) is at
#: most this many sample times / kernel widths (or twice the best among the stable orders).
AUTO_START_WIDTHS = 50
#: A log is too short for the observer ("drifting") when 5 start time constants exceed its length.
DRIFT_FACTOR = 5.0
#: An observer whose slowest mode does not decay (spectral radius rho >= 1) runs on a log of N samples
#: when that mode grows less than this factor over it, rho^N < GROWTH_LIMIT (with a ModelWarning).
GROWTH_LIMIT = 2.0
#: A spectral radius within this of 1 is a mode on the unit circle (a coordinate the flow does not
#: pull at all; it may grow polynomially, not as rho^N): refused at construction as before.
ON_CIRCLE = 1e-9


def log_growth(radius: float, n_samples: int) -> float:
    """rho^N: the growth of the slowest mode of a transition of spectral radius rho (``radius``) over
    a log of N samples (``n_samples``); < 1 for a stable observer, whose start then fades."""
    with np.errstate(over="ignore"):
        return float(np.exp(n_samples * np.log(radius))) if radius > 0 else 0.0


def _width(value, name: str) -> float:
    """A kernel width > 0 [s]; 0 (white noise) gets its own message."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = None
    if number == 0.0:
        raise AttendInputError(
            f"{name}: 0 means white noise, which has no derivatives, so DEM's generalised coordinates "
            "carry no information beyond order 0; give the noise's kernel width (> 0 s), or use "
            "method=\"kalman\" (the coloured-noise Kalman smoother) for white noise"
        )
    return positive_scalar(value, name, "s")


class DEMEstimate(NamedTuple):
    """Estimates at every sample: states (N, n), inputs (N, r) (the known inputs when they were
    given), their standard deviations (N, n) / (N, r), and the generalised estimates X
    (N, dim X) when requested (else None).

    The standard deviations are the steady-state std of the DEM filter's estimation error under
    the generative model (coloured noises of covariance inv(Pi_w), inv(Pi_z), unknown inputs a
    Gaussian process of covariance inv(P_v) about eta; see :mod:`attend.perception.dem_analysis`),
    the same at every sample: edges (the first and last windows) are not covered. NaN marks a
    quantity the data do not inform (unobservable given the precisions; a ModelWarning names
    it) or an observer run with allow_unstable=True. Known inputs have std 0.
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    generalized: np.ndarray | None

    def as_estimate(self, method: str = "dem") -> Estimate:
        """This result as the common :class:`attend.perception.estimate.Estimate` (details: this
        result); method: the estimator's name ("dem"; "nonlinear dem" for NonlinearDEM, whose
        details are DEMEstimates too)."""
        return as_estimate(self, method)


class DEMAnalysis(NamedTuple):
    """What a DEM observer promises before it sees data (:meth:`DEMObserver.analysis`).

    embedding_order: p in use; automatic: chosen by embedding_order="auto";
    spectral_radius: of the discrete transition Phi = expm(A_obs dt) (stable when < 1);
    slowest_time_constant: -dt / ln(spectral_radius) [s] over all modes (inf if not stable);
    doubling_time: dt ln 2 / ln(spectral_radius) [s], the time in which the slowest mode of an
    observer that is not stable doubles (inf when spectral_radius <= 1): estimate() runs such an
    observer only on logs shorter than this (growth rho^N < GROWTH_LIMIT (2) over N samples, with
    a ModelWarning) and refuses longer ones;
    start_time_constant: effective time constant [s] of the start transient as seen in the
    order-0 estimates (modes those estimates do not see excluded; see
    dem_analysis.start_time_constant). A log shorter than DRIFT_FACTOR (5) of these is
    "drifting": the start still matters at its end, and estimate() refuses it;
    condition_S: largest cond(S) of the temporal precisions in sample units (s / dt);
    precision_singular: Pi_X (Jacobi-scaled) is singular, some coordinate is not pinned down;
    unobservable: names of states / inputs the outputs do not inform: their conditional variance
    diag(inv(Pi_X)) does not change when the sensory term is removed from Pi_X (generalised
    observability given the precisions: C = 0, sensor_precision 0, ...), or their steady-state
    error variance is unbounded or above UNOBSERVABLE_RATIO (100) times the prior variance
    (inputs with prior precision >= PINNED_INPUT_PRECISION count as given, not unobservable);
    state_std (n,), input_std (r,): steady-state std of the estimation error (NaN where
    unobservable, or when the slowest mode doubles within the shortest log the observer accepts;
    0 for known inputs). For an observer that is not stable it is the std of the filter with the
    same frequency response, which the log sees while its slowest mode has grown less than 2x.
    """

    embedding_order: int
    automatic: bool
    spectral_radius: float
    slowest_time_constant: float
    start_time_constant: float
    condition_S: float
    precision_singular: bool
    unobservable: tuple
    state_std: np.ndarray
    input_std: np.ndarray
    doubling_time: float = float("inf")


@dataclass(frozen=True, eq=False)
class DEMObserver:
    """A DEM state (and unknown-input) observer for an LTI system:
    ``DEMObserver(system, dt, *, kernel_width, sensor_precision, process_precision, ...)`` or
    ``DEMObserver(system, dt, *, noise=NoiseModel(...), ...)`` (the system and the sample time
    first, everything else by keyword).

    system: the model (A, B, C; a python-control StateSpace is converted with
    :func:`attend.models.from_statespace`); dt: sample time [s]; kernel_width: s of the Gaussian noise
    kernel [s], used for both noises unless process_kernel_width / sensor_kernel_width are
    given (then it may be None); sensor_precision: Pi_z [1/output unit^2]; process_precision:
    Pi_w [s^2/state unit^2 as in dx/dt]; noise: an :class:`attend.models.NoiseModel` holding the two
    precisions and the kernel widths instead (giving it with any of them is an error; the widths
    must be > 0); :attr:`noise_model` reads them back as one; input_prior_precision: P_v
    [1/input unit^2] (unknown inputs); embedding_order: p (states/outputs have p + 1 orders), an int or "auto" (the
    default: the largest p <= 6 whose observer is stable (spectral radius <= 1 - 1e-9), has
    cond(S) <= AUTO_MAX_CONDITION in sample units, and forgets its start quickly: start time
    constant <= max(AUTO_START_WIDTHS (50) sample times or kernel widths, twice the best of
    the stable orders), since the highest orders are the ones that make the flow slow or
    unstable; after construction the attribute holds the int and analysis().automatic is
    True); input_order: d; known_inputs: inputs measured (True) or estimated (False);
    precision_convention: "size" (SPM) or "max" (Meera: invert V at max(p, d) then truncate);
    window_offset: the embedding window of row k is centred on sample k + window_offset (0
    centred; -1 reproduces the authors' quadrotor code); edges: where the window reaches past the
    log, "order0" uses the sample itself with zero derivatives (Meera; the default: repeated end
    samples fake large derivatives whose effect decays slowly through the imprecise high orders)
    or "clamp" repeats the end samples (SPM).
    process_kernel_width: s_w [s] of the process noise w: W = kron(S_p(s_w), Pi_w); the input
    prior Vv = kron(S_d(s_u), P_v) uses input_kernel_width s_u [s], by default s_w (an unknown
    input enters the motion like process noise); sensor_kernel_width: s_z [s] of the sensor noise
    z: Vy = kron(S_p(s_z), Pi_z). Both default to kernel_width. A width of 0 (white noise) has no
    derivatives and is refused: use method="kalman" for white noise.
    initial_state: order-0 states (n,) the flow starts from (default: the static MAP of the
    first sample, see :meth:`estimate`); allow_unstable: run configurations that would be refused
    (a slowest mode that grows 2x or more over the log, or a drifting start; with a ModelWarning
    and NaN std where the growth is 2x or more) instead of refusing them.
    integration: "attend" (default: the data held over each step, row k the state after the step
    with sample k) or "spm" (spm_DEM's D-step: the data ride along their generalised motion over the
    step, row k is the state before the step with sample k (row 0 the start), the top order's motion
    error 0; :func:`attend.perception.dem_flow.spm_discretisation`, docs/spm.md).
    Precisions are scalars (times I), vectors (diagonal) or matrices.
    """

    system: LinearSystem
    dt: float
    _: KW_ONLY
    kernel_width: float | None = None
    sensor_precision: np.ndarray | None = None
    process_precision: np.ndarray | None = None
    input_prior_precision: np.ndarray | None = None
    embedding_order: int | str = "auto"
    input_order: int = 2
    known_inputs: bool = False
    precision_convention: str = "size"
    window_offset: int = 0
    edges: str = "order0"
    process_kernel_width: float | None = None
    sensor_kernel_width: float | None = None
    initial_state: np.ndarray | None = None
    allow_unstable: bool = False
    input_kernel_width: float | None = None
    integration: str = "attend"
    noise: InitVar[NoiseModel | None] = None
    _matrices: dict = field(default_factory=dict, repr=False)
    _cache: dict = field(default_factory=dict, repr=False)

    @with_single_blas_thread
    def __post_init__(self, noise):
        system = as_linear_system(self.system)
        set_ = object.__setattr__
        take_noise(self, noise, "DEMObserver")
        set_(self, "system", system)
        set_(self, "dt", positive_scalar(self.dt, "dt", "s"))
        if self.kernel_width is None:
            if self.process_kernel_width is None or self.sensor_kernel_width is None:
                raise AttendInputError("kernel_width: required unless process_kernel_width and "
                                       "sensor_kernel_width are both given")
        else:
            set_(self, "kernel_width", _width(self.kernel_width, "kernel_width"))
        for name in ("process_kernel_width", "sensor_kernel_width"):
            value = getattr(self, name)
            set_(self, name, self.kernel_width if value is None else _width(value, name))
        set_(self, "input_kernel_width", self.process_kernel_width if self.input_kernel_width is None
             else _width(self.input_kernel_width, "input_kernel_width"))
        set_(self, "input_order", order(self.input_order, "input_order"))
        set_(self, "sensor_precision", precision_matrix(self.sensor_precision, system.n_outputs, "sensor_precision"))
        set_(self, "process_precision", precision_matrix(self.process_precision, system.n_states, "process_precision"))
        if self.known_inputs:
            prior = np.zeros((system.n_inputs, system.n_inputs))
        else:
            if self.input_prior_precision is None:
                raise AttendInputError("input_prior_precision: required when the inputs are unknown")
            prior = precision_matrix(self.input_prior_precision, system.n_inputs, "input_prior_precision")
        set_(self, "input_prior_precision", prior)
        if self.edges not in ("order0", "clamp"):
            raise AttendInputError(f"edges: expected 'order0' or 'clamp', got {self.edges!r}")
        if self.integration not in ("attend", "spm"):
            raise AttendInputError(f"integration: expected 'attend' or 'spm', got {self.integration!r}")
        if int(self.window_offset) != self.window_offset:
            raise AttendInputError(f"window_offset: expected an integer number of samples, got {self.window_offset!r}")
        if self.initial_state is not None:
            start = np.asarray(self.initial_state, dtype=float).reshape(-1)
            if start.shape != (system.n_states,):
                raise AttendInputError(f"initial_state: expected {system.n_states} order-0 states, "
                                       f"got shape {np.shape(self.initial_state)}")
            require_finite(start, "initial_state")
            set_(self, "initial_state", start)
        if self.precision_convention not in ("size", "max"):
            raise AttendInputError(f"precision_convention: expected 'size' or 'max', got {self.precision_convention!r}")
        automatic = isinstance(self.embedding_order, str)
        if automatic:
            if self.embedding_order != "auto":
                raise AttendInputError(f"embedding_order: expected an integer or 'auto', got {self.embedding_order!r}")
            p, matrices = self._choose_order()  # caches the start time constant
            set_(self, "embedding_order", p)
            self._matrices.update(matrices)
        else:
            set_(self, "embedding_order", order(self.embedding_order, "embedding_order"))
            self._matrices.update(self._build(self.embedding_order))
        self._cache["automatic"] = automatic
        radius = self._matrices["radius"]
        if radius >= 1.0 and not automatic and not self._runs_on_some_log():
            # no log is short enough: refused now (a slower growth is judged on the log, in estimate())
            shortest = max(self.embedding_order, self.input_order) + 1
            reason = (f"a mode on the unit circle, which the flow does not pull at all"
                      if radius <= 1.0 + ON_CIRCLE else
                      f"its slowest mode grows {log_growth(radius, shortest):.3g}x over the shortest log of "
                      f"{shortest} samples")
            message = (f"embedding_order: the DEM observer is unstable at p = {self.embedding_order} for this "
                       f"model (spectral radius {radius:.6g} >= 1: {reason})")
            if not self.allow_unstable:
                raise AttendInputError(message + f"; {self._suggestion()} (or allow_unstable=True to run it anyway)")
            warnings.warn(message + "; running it anyway (allow_unstable=True), std not reported",
                          ModelWarning, stacklevel=3)

    # --- construction ----------------------------------------------------------------------

    @property
    def noise_model(self) -> NoiseModel:
        """The observer's noise as one :class:`attend.models.NoiseModel` (the precision matrices and
        widths in use), e.g. to build another estimator with the same noise."""
        return NoiseModel(process_precision=self.process_precision, sensor_precision=self.sensor_precision,
                          process_kernel_width=self.process_kernel_width, sensor_kernel_width=self.sensor_kernel_width)

    def _runs_on_some_log(self) -> bool:
        """A stable observer, or one whose slowest mode lies off the unit circle (|rho - 1| > ON_CIRCLE)
        and grows less than GROWTH_LIMIT over the shortest log estimate() accepts."""
        radius = self._matrices["radius"]
        shortest = max(self.embedding_order, self.input_order) + 1
        return radius < 1.0 or (radius > 1.0 + ON_CIRCLE and log_growth(radius, shortest) < GROWTH_LIMIT)

    def _suggestion(self) -> str:
        try:
            p, _ = self._choose_order()
        except AttendInputError:
            return "no order 0..6 is stable for this model: check the precisions, kernel widths and input_order"
        return f"use p <= {p} or embedding_order='auto'"

    def _choose_order(self) -> tuple[int, dict]:
        """embedding_order="auto": among p = 0..AUTO_MAX_ORDER with cond(S) <= AUTO_MAX_CONDITION
        (sample units) and spectral radius <= 1 - 1e-9, the largest p whose start time constant
        is at most max(AUTO_START_WIDTHS * max(dt, s_w, s_z), 2 * the smallest one among them)."""
        rejected, candidates = [], []
        for p in range(AUTO_MAX_ORDER, -1, -1):
            condition = self._condition_S(p)
            if condition > AUTO_MAX_CONDITION:
                rejected.append(f"p = {p}: cond(S) {condition:.2g}")
                continue
            matrices = self._build(p)
            if matrices["radius"] >= 1.0 - 1e-9:
                rejected.append(f"p = {p}: spectral radius {matrices['radius']:.6g}")
                continue
            candidates.append((p, matrices, self._start_time_constant(matrices, p)))
        if not candidates:
            raise AttendInputError(
                "embedding_order: 'auto' found no order 0..6 with a stable DEM observer for this model ("
                + "; ".join(rejected) + "); check the precisions, kernel widths and input_order, or pass "
                "an explicit embedding_order with allow_unstable=True"
            )
        scale = max(self.dt, self.process_kernel_width, self.sensor_kernel_width)
        limit = max(AUTO_START_WIDTHS * scale, 2.0 * min(tau for _, _, tau in candidates))
        p, matrices, tau = next(c for c in candidates if c[2] <= limit)
        self._cache["start_time_constant"] = tau
        return p, matrices

    def _condition_S(self, p: int) -> float:
        d = self.input_order
        widths = {self.process_kernel_width, self.sensor_kernel_width}
        values = [smoothness_condition(p + 1, s, self.dt) for s in widths]
        if not self.known_inputs:
            values.append(smoothness_condition(d + 1, self.input_kernel_width, self.dt))
        return float(max(values))

    @property
    def order0_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows of the order-0 states, rows of the unknown inputs (none with known inputs)) in
        the generalised state X = [x~; v~] of this observer."""
        return self._readout(self.embedding_order)

    def _readout(self, p: int) -> tuple[np.ndarray, np.ndarray]:
        n, r = self.system.n_states, self.system.n_inputs
        n_x = n * (p + 1)
        rows_v = np.arange(n_x, n_x + r) if not self.known_inputs else np.zeros(0, dtype=int)
        return np.arange(n), rows_v

    def _start_problem(self, matrices: dict, p: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, order-0 readout rows, natural scale of every coordinate) for the start analysis."""
        n, r, d = self.system.n_states, self.system.n_inputs, self.input_order
        scales = np.kron(derivative_scales(p + 1, self.process_kernel_width), np.ones(n))
        if not self.known_inputs:
            scales = np.concatenate([scales, np.kron(derivative_scales(d + 1, self.input_kernel_width), np.ones(r))])
        rows_x, rows_v = self._readout(p)
        size = matrices["transition"].shape[0]
        readout = np.eye(size)[np.concatenate([rows_x, rows_v])]
        return matrices["transition"], readout, scales

    def _start_time_constant(self, matrices: dict, p: int) -> float:
        return start_time_constant(*self._start_problem(matrices, p), self.dt)

    @property
    def n_state_coordinates(self) -> int:
        """Size of x~: n (p + 1)."""
        return self.system.n_states * (self.embedding_order + 1)

    @property
    def n_input_coordinates(self) -> int:
        """Size of v~: r (d + 1), or 0 with known inputs."""
        return 0 if self.known_inputs else self.system.n_inputs * (self.input_order + 1)

    @property
    def delay(self) -> int:
        """Samples of the future the embedding window needs: the online estimate lags by this."""
        return max(samples_after_centre(self.embedding_order + 1),
                   samples_after_centre(self.input_order + 1)) + self.window_offset

    def generalized_matrices(self) -> dict[str, np.ndarray]:
        """C~, A~, B~, D_x, D_v, Vy, W, Vv, A_obs, B_obs, Pi_X (see the module docstring) and the
        flow's transition, window_gain, order0_gain, offsets and spectral radius, by name (a new
        dict; the arrays are the observer's own: read them, do not change them)."""
        return dict(self._matrices)

    def _build(self, p: int) -> dict[str, np.ndarray]:
        return flow_matrices(self, p)

    # --- estimation ------------------------------------------------------------------------

    def _raw_windows(self, signals: np.ndarray, start: int, stop: int) -> np.ndarray:
        """(stop - start, n_offsets * (m + r)) raw windows, end samples repeated at the edges.

        Row t is the window of samples t + offsets, flattened sample-major: consecutive rows
        overlap, so they are read from one padded copy through a strided view.
        """
        n_samples, width = signals.shape
        offsets = self._matrices["offsets"]
        span = np.clip(np.arange(start + offsets[0], stop + offsets[-1]), 0, n_samples - 1)
        padded = np.ascontiguousarray(signals[span])
        item = padded.itemsize
        view = np.lib.stride_tricks.as_strided(
            padded, shape=(stop - start, len(offsets) * width), strides=(width * item, item), writeable=False
        )
        return np.ascontiguousarray(view)

    def _signals(self, outputs, inputs) -> np.ndarray:
        m, r = self.system.n_outputs, self.system.n_inputs
        y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
        if y.shape[1] != m:
            raise AttendInputError(f"outputs: expected {m} columns (one per output), got {y.shape[1]}")
        if inputs is None:
            if self.known_inputs:
                raise AttendInputError("inputs: the observer was built with known_inputs=True; pass the measured inputs")
            u = np.zeros((y.shape[0], r))
        else:
            u = as_matrix(inputs, "inputs" if self.known_inputs else "input_prior", cols=r if np.ndim(inputs) == 2 else 1)
            if u.shape != (y.shape[0], r):
                raise AttendInputError(
                    f"{'inputs' if self.known_inputs else 'input_prior'}: expected shape ({y.shape[0]}, {r}), got {u.shape}"
                )
        minimum = max(self.embedding_order, self.input_order) + 1
        if y.shape[0] < minimum:
            raise AttendInputError(
                f"outputs: expected at least {minimum} samples (the embedding window of order "
                f"{minimum - 1}), got {y.shape[0]}"
            )
        return np.hstack([y, u])

    def _edge_rows(self, n_samples: int, start: int, stop: int) -> np.ndarray:
        """Rows in [start, stop) whose embedding window reaches past the log (relative indices)."""
        if self.edges == "clamp":
            return np.zeros(0, dtype=int)
        offsets = self._matrices["offsets"]
        rows = np.arange(start, stop)
        return np.flatnonzero((rows + offsets[0] < 0) | (rows + offsets[-1] > n_samples - 1))

    @with_single_blas_thread
    def estimate(self, outputs, inputs=None, *, keep_generalized: bool = False,
                 initial_state=None, segment: int = 1 << 14, time=None) -> Estimate:
        """Batch estimation over a whole log, as an :class:`attend.perception.estimate.Estimate`
        (method "dem"; details: the :class:`DEMEstimate`, with ``generalized``).

        outputs: (N, m) measured outputs; inputs: (N, r) measured inputs (known_inputs=True) or the
        input prior eta (unknown inputs; default 0). Gaps: NaN values, and time (N,) [s], the
        samples' time stamps when they skip samples or jitter: DEM's embedding needs a uniform grid,
        so the log is resampled onto t_0 + k dt by linear interpolation of every column, bridging at
        most BRIDGED_GAP (3) consecutive missing samples (a longer gap is an error naming its rows),
        and the estimates are interpolated back to the log's rows (:mod:`attend.perception.dem_gaps`).
        The log is processed in segments of
        ``segment`` samples so memory stays O(segment) beyond the (N, n + r) results.
        Row k is the estimate at sample k (it uses samples up to k + delay).
        keep_generalized: also return every generalised state X_t (memory O(N dim X)).
        initial_state: the full generalised start X0 (dim X,); default: order 0 from the first
        sample, higher orders at their prior mean (see :func:`attend.perception.dem_flow.start_state`;
        the constructor's ``initial_state`` sets its order-0 states).
        Raises AttendInputError when the log is shorter than DRIFT_FACTOR start time constants
        (analysis().start_time_constant): the start would still matter at its end; and, for an
        observer that is not stable (spectral radius rho >= 1), when its slowest mode grows
        rho^N >= GROWTH_LIMIT (2x) over the N samples (analysis().doubling_time): less growth runs
        with a ModelWarning naming it (:meth:`_check_log_length`). The std
        columns are those of :meth:`analysis` (steady state under the model, edges excluded);
        with known inputs the state std adds the mean square, over the middle 80 % of the log, of
        the filter's own error on the noise-free response to the given inputs (see
        :func:`attend.perception.dem_flow.known_input_error`), so it depends on the log.
        """
        try:
            gaps = time is not None or np.isnan(np.asarray(outputs, dtype=float)).any() or \
                (inputs is not None and np.isnan(np.asarray(inputs, dtype=float)).any())
        except (TypeError, ValueError):  # not numbers: _signals says what was expected
            gaps = False
        if gaps:
            from attend.perception.dem_gaps import estimate_with_gaps

            return as_estimate(estimate_with_gaps(self, outputs, inputs, time, keep_generalized=keep_generalized,
                                                  initial_state=initial_state, segment=segment), "dem")
        signals = self._signals(outputs, inputs)
        n_samples = signals.shape[0]
        n, r = self.system.n_states, self.system.n_inputs
        size = self._matrices["transition"].shape[0]
        self._check_log_length(n_samples)
        if initial_state is None:
            state = None
        else:
            state = np.asarray(initial_state, dtype=float).reshape(-1)
            if state.shape != (size,):
                raise AttendInputError(f"initial_state: expected the generalised start X0 of size {size}, "
                                       f"got shape {np.shape(initial_state)}")
            require_finite(state, "initial_state")
        states, inputs_out, generalized = self.run_flow(signals, state, keep_generalized, segment)
        analysis = self.analysis()
        if analysis.unobservable:
            warnings.warn(
                f"{', '.join(analysis.unobservable)}: not informed by the outputs under these precisions "
                "(unobservable given C and sensor_precision, or an unbounded steady-state error); "
                "their std is NaN and their estimates follow the model and the prior only",
                ModelWarning, stacklevel=2,
            )
        state_std, input_std = analysis.state_std, analysis.input_std
        if not self._runs_on_some_log() or log_growth(self._matrices["radius"], n_samples) >= GROWTH_LIMIT:
            state_std, input_std = np.full(n, np.nan), np.where(input_std == 0.0, 0.0, np.nan)
        if self.known_inputs and np.all(np.isfinite(state_std)) and n_samples >= 10:
            state_std = np.sqrt(state_std**2 + known_input_error(self, signals, segment))
        self._warn_if_worse_than_the_prior(state_std, input_std)
        state_std = np.broadcast_to(state_std, (n_samples, n))
        input_std = np.broadcast_to(input_std, (n_samples, r))
        return as_estimate(DEMEstimate(np.arange(n_samples) * self.dt, states, inputs_out, state_std, input_std,
                                       generalized), "dem")

    def run_flow(self, signals: np.ndarray, state=None, keep_generalized: bool = False, segment: int = 1 << 14):
        """The flow over a whole log, without :meth:`estimate`'s checks and standard deviations:
        (states (N, n), inputs (N, r), every generalised state X (N, dim X) or None).

        signals: (N, m + r) samples [y, u] (outputs, then the measured inputs or the input prior);
        state: the generalised start X0 (dim X,), or None for :func:`attend.perception.dem_flow.start_state`;
        keep_generalized: also return every X; segment: samples per segment (memory O(segment))."""
        mats = self._matrices
        n_samples = signals.shape[0]
        n, r = self.system.n_states, self.system.n_inputs
        n_x = self.n_state_coordinates
        size = mats["transition"].shape[0]
        states = np.empty((n_samples, n))
        inputs_out = np.empty((n_samples, r))
        generalized = np.empty((n_samples, size)) if keep_generalized else None
        gain_t = mats["window_gain"].T
        for start in range(0, n_samples, segment):
            stop = min(start + segment, n_samples)
            windows = self._raw_windows(signals, start, stop)
            drive = windows @ gain_t
            edge = self._edge_rows(n_samples, start, stop)
            if len(edge):
                drive[edge] = centre_samples(signals, start + edge, self.window_offset) @ mats["order0_gain"].T
            if state is None:
                state = start_state(self, signals, start, len(edge) > 0 and edge[0] == 0)
            X = linear_recurrence(mats["transition"], drive, state)
            if self.integration == "spm":  # row k: the state before the step with sample k
                X, state = np.vstack([state[None, :], X[:-1]]), X[-1]
            else:
                state = X[-1]
            states[start:stop] = X[:, :n]
            if self.known_inputs:
                inputs_out[start:stop] = signals[start:stop, self.system.n_outputs:]
            else:
                inputs_out[start:stop] = X[:, n_x: n_x + r]
            if keep_generalized:
                generalized[start:stop] = X
        return states, inputs_out, generalized

    def _check_log_length(self, n_samples: int) -> None:
        """Drifting: a start error of one natural unit (see DEMAnalysis.start_time_constant) still
        moves an order-0 estimate by >= 1/e of it somewhere after the first 1/DRIFT_FACTOR of the
        log (for a single visible mode: time constant > log length / 5).

        An observer whose slowest mode does not decay (spectral radius rho >= 1, an explicit
        embedding_order) never forgets its start: a start error in that mode, and the noise that
        enters it, grow by rho^N over the N samples of the log. What grows less than GROWTH_LIMIT
        (2x) runs with a ModelWarning naming the growth; more is refused (AttendInputError naming
        embedding_order and the longest log that would run) unless allow_unstable=True."""
        radius = self._matrices["radius"]
        if radius >= 1.0:
            if self._runs_on_some_log():  # else refused at construction, or allowed explicitly
                self._check_growth(radius, n_samples)
            return
        first = int(np.ceil(n_samples / DRIFT_FACTOR))
        if self._start_constant() < first * self.dt:
            return
        key = ("start_influence", n_samples)
        if key not in self._cache:
            self._cache[key] = start_influence(*self._start_problem(self._matrices, self.embedding_order),
                                               first, n_samples)
        influence = self._cache[key]
        if influence < np.exp(-1.0):
            return
        length = n_samples * self.dt
        message = (f"the DEM observer at p = {self.embedding_order} remembers its start for too long for "
                   f"this log: after a fifth of it ({first * self.dt:.4g} s of {length:.4g} s) a start error "
                   f"still moves the estimates by {influence:.2g} of itself (start time constant "
                   f"{self._start_constant():.4g} s)")
        if not self.allow_unstable:
            hint = "" if self._cache["automatic"] else "embedding_order='auto' or "
            raise AttendInputError(
                f"embedding_order: {message}; use {hint}a longer log, or a larger sensor_precision "
                "(a faster observer), or allow_unstable=True to run it anyway"
            )
        warnings.warn(message, ModelWarning, stacklevel=3)

    def _check_growth(self, radius: float, n_samples: int) -> None:
        """The growth test of :meth:`_check_log_length` for rho >= 1 (see there)."""
        growth = log_growth(radius, n_samples)
        p, length = self.embedding_order, n_samples * self.dt
        doubling = self.analysis().doubling_time
        if growth < GROWTH_LIMIT:
            self._cache[("growth", n_samples)] = growth
            warnings.warn(
                f"embedding_order: the DEM observer at p = {p} is not stable (spectral radius {radius:.6g}): over "
                f"this log ({n_samples} samples, {length:.4g} s) its slowest mode, and a start error in it, grow "
                f"{growth:.3g}x (< {GROWTH_LIMIT:g}x: run; it doubles in {doubling:.4g} s); for an observer that "
                f"forgets its start, {self._suggestion()}", ModelWarning, stacklevel=5)
            return
        message = (f"the DEM observer at p = {p} is not stable (spectral radius {radius:.6g}): over this log "
                   f"({n_samples} samples, {length:.4g} s) its slowest mode, and a start error in it, grow "
                   f"{growth:.3g}x (>= {GROWTH_LIMIT:g}x; it doubles in {doubling:.4g} s, "
                   f"{int(np.log(GROWTH_LIMIT) / np.log(radius))} samples)")
        if not self.allow_unstable:
            raise AttendInputError(f"embedding_order: {message}; a log shorter than {doubling:.4g} s runs, else "
                                   f"{self._suggestion()} (or allow_unstable=True to run it anyway)")
        warnings.warn(message + "; running it anyway (allow_unstable=True), std not reported",
                      ModelWarning, stacklevel=5)

    def _start_constant(self) -> float:
        if "start_time_constant" not in self._cache:
            self._cache["start_time_constant"] = self._start_time_constant(self._matrices, self.embedding_order)
        return self._cache["start_time_constant"]

    @with_single_blas_thread
    def analysis(self) -> DEMAnalysis:
        """Stability, start transient, conditioning and steady-state error std of this observer
        (see :class:`DEMAnalysis`). Computed once (a frequency integral on a few thousand
        points) and cached."""
        if "analysis" in self._cache:
            return self._cache["analysis"]
        mats = self._matrices
        system = self.system
        n, r, p = system.n_states, system.n_inputs, self.embedding_order
        radius = mats["radius"]
        slowest = -self.dt / np.log(radius) if 0 < radius < 1 else (0.0 if radius == 0 else np.inf)
        tau = self._start_constant()
        with np.errstate(invalid="ignore", divide="ignore"):
            scaled = mats["Pi_X"] / np.sqrt(np.outer(*(2 * [np.clip(np.diag(mats["Pi_X"]), 1e-300, None)])))
        singular = bool(np.any(np.diag(mats["Pi_X"]) <= 0) or np.linalg.eigvalsh(scaled).min() < 1e-13)
        names = tuple(system.state_names) + (() if self.known_inputs else tuple(system.input_names))
        doubling = self.dt * np.log(GROWTH_LIMIT) / np.log(radius) if radius > 1.0 else np.inf
        if not self._runs_on_some_log():  # no log runs (allow_unstable=True)
            state_std, input_std = np.full(n, np.nan), np.full(r, 0.0 if self.known_inputs else np.nan)
            unobservable = ()
        else:
            std, priors, unobservable = observer_error_std(self, names)
            self._cache["prior_std"] = np.sqrt(priors)
            state_std = std[:n]
            input_std = std[n:] if not self.known_inputs else np.zeros(r)
        result = DEMAnalysis(
            embedding_order=p, automatic=self._cache["automatic"], spectral_radius=radius,
            slowest_time_constant=float(slowest), start_time_constant=float(tau),
            condition_S=self._condition_S(p), precision_singular=singular, unobservable=unobservable,
            state_std=state_std, input_std=input_std, doubling_time=float(doubling),
        )
        self._cache["analysis"] = result
        return result

    def _warn_if_worse_than_the_prior(self, state_std: np.ndarray, input_std: np.ndarray) -> None:
        """ModelWarning naming the states / inputs whose DEM error std exceeds their own spread under
        the model without data (the estimate is then worse than the prior mean: it happens when the
        process noise is small, because DEM keeps no memory of the evidence beyond one window)."""
        prior = self._cache.get("prior_std")
        if prior is None:
            return
        names = list(self.system.state_names) + ([] if self.known_inputs else list(self.system.input_names))
        std = np.concatenate([state_std, [] if self.known_inputs else input_std])
        checked = np.ones(len(std), dtype=bool)
        if not self.known_inputs:  # measured inputs passed as pinned unknowns are given, not estimated
            checked[self.system.n_states:] = np.diag(self.input_prior_precision) < PINNED_INPUT_PRECISION
        with np.errstate(invalid="ignore"):
            worse = checked & np.isfinite(std) & np.isfinite(prior) & (std > 1.01 * prior)
        if worse.any():
            listed = ", ".join(f"{name} (error std {e:.3g}, spread {s:.3g})"
                               for name, e, s, bad in zip(names, std, prior, worse) if bad)
            warnings.warn(f"{listed}: the DEM estimate is worse than the model's prior mean (its error exceeds "
                          "the spread of the variable without data); the coloured-noise Kalman smoother "
                          "(method=\"kalman\", attend estimate's default) keeps the evidence of the whole log",
                          ModelWarning, stacklevel=3)

    def online(self) -> "OnlineDEM":
        """A fixed-memory observer fed one sample at a time (see :class:`OnlineDEM`). A stream has no
        end, so an observer whose slowest mode does not decay (spectral radius >= 1, which
        :meth:`estimate` runs on logs shorter than analysis().doubling_time) is refused unless
        allow_unstable=True."""
        radius = self._matrices["radius"]
        if radius >= 1.0 and not self.allow_unstable:
            raise AttendInputError(
                f"embedding_order: the DEM observer at p = {self.embedding_order} is not stable (spectral radius "
                f"{radius:.6g}; it doubles in {self.analysis().doubling_time:.4g} s) and a stream has no end; "
                f"{self._suggestion()}, or allow_unstable=True to run it anyway")
        return OnlineDEM(self)
