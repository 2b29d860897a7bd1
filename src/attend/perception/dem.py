"""DEM observer: state and input estimation in generalised coordinates (D-step, spec §5).

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
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.linalg import expm

from attend._validation import (
    AttendInputError,
    as_matrix,
    numeric_array,
    order,
    positive_scalar,
    precision_matrix,
    require_finite,
)
from attend.generalized import block_precisions, embedding_weights, shift_operator
from attend.perception.recurrence import linear_recurrence
from attend.systems import LinearSystem, ModelWarning, as_linear_system


class DEMEstimate(NamedTuple):
    """Estimates at every sample: states (N, n), inputs (N, r) (the known inputs when they were
    given), their standard deviations (N, n) / (N, r) from the conditional precision, and the
    generalised estimates X (N, dim X) when requested (else None)."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    generalized: np.ndarray | None


@dataclass(frozen=True, eq=False)
class DEMObserver:
    """A DEM state (and unknown-input) observer for an LTI system.

    system: the model (A, B, C; a python-control StateSpace is converted with
    :func:`attend.interop.from_statespace`); dt: sample time [s]; kernel_width: s of the Gaussian noise
    kernel [s]; sensor_precision: Pi_z [1/output unit^2]; process_precision: Pi_w
    [s^2/state unit^2 as in dx/dt]; input_prior_precision: P_v [1/input unit^2] (unknown inputs);
    embedding_order: p (states/outputs have p + 1 orders); input_order: d; known_inputs: inputs
    measured (True) or estimated (False); precision_convention: "size" (SPM) or "max" (Meera:
    invert V at max(p, d) then truncate); window_offset: the embedding window of row k is centred
    on sample k + window_offset (0 centred; -1 reproduces the authors' quadrotor code);
    edges: where the window reaches past the log, "order0" uses the sample itself with zero
    derivatives (Meera; the default: repeated end samples fake large derivatives whose effect
    decays slowly through the imprecise high orders) or "clamp" repeats the end samples (SPM).
    Precisions are scalars (times I), vectors (diagonal) or matrices.
    """

    system: LinearSystem
    dt: float
    kernel_width: float
    sensor_precision: np.ndarray
    process_precision: np.ndarray
    input_prior_precision: np.ndarray | None = None
    embedding_order: int = 6
    input_order: int = 2
    known_inputs: bool = False
    precision_convention: str = "size"
    window_offset: int = 0
    edges: str = "order0"
    _matrices: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        system = as_linear_system(self.system)
        set_ = object.__setattr__
        set_(self, "system", system)
        set_(self, "dt", positive_scalar(self.dt, "dt", "s"))
        set_(self, "kernel_width", positive_scalar(self.kernel_width, "kernel_width", "s"))
        set_(self, "embedding_order", order(self.embedding_order, "embedding_order"))
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
        if int(self.window_offset) != self.window_offset:
            raise AttendInputError(f"window_offset: expected an integer number of samples, got {self.window_offset!r}")
        self._matrices.update(self._build())

    # --- construction ----------------------------------------------------------------------

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
        return max(self._after(self.embedding_order + 1), self._after(self.input_order + 1)) + self.window_offset

    @staticmethod
    def _after(window: int) -> int:
        return window - 1 - window // 2

    def generalized_matrices(self) -> dict[str, np.ndarray]:
        """C~, A~, B~, D_x, D_v, Vy, W, Vv, A_obs, B_obs, Pi_X (see the module docstring)."""
        return dict(self._matrices)

    def _build(self) -> dict[str, np.ndarray]:
        A, B, C = self.system.A, self.system.B, self.system.C
        n, r, m = self.system.n_states, self.system.n_inputs, self.system.n_outputs
        p, d = self.embedding_order, self.input_order
        S_p, S_d = block_precisions(p, d, self.kernel_width, self.precision_convention)
        Ct = np.kron(np.eye(p + 1), C)
        At = np.kron(np.eye(p + 1), A)
        Bt = np.kron(np.eye(p + 1, d + 1), B)
        Dx = shift_operator(p + 1, n)
        Dv = shift_operator(d + 1, r)
        Vy = np.kron(S_p, self.sensor_precision)
        W = np.kron(S_p, self.process_precision)
        Vv = np.kron(S_d, self.input_prior_precision)
        motion = Dx - At
        Pxx = Ct.T @ Vy @ Ct + motion.T @ W @ motion
        if self.known_inputs:
            A_obs = Dx - Pxx
            B_obs = np.hstack([Ct.T @ Vy, motion.T @ W @ Bt])  # drives: [y~; u~]
            Pi_X = Pxx
        else:
            Pxv = -motion.T @ W @ Bt
            Pvv = Vv + Bt.T @ W @ Bt
            Pi_X = np.block([[Pxx, Pxv], [Pxv.T, Pvv]])
            D_X = np.zeros_like(Pi_X)
            D_X[: n * (p + 1), : n * (p + 1)] = Dx
            D_X[n * (p + 1):, n * (p + 1):] = Dv
            A_obs = D_X - Pi_X
            B_obs = np.block([
                [Ct.T @ Vy, np.zeros((n * (p + 1), r * (d + 1)))],
                [np.zeros((r * (d + 1), m * (p + 1))), Vv],
            ])  # drives: [y~; eta~]
        size, width = A_obs.shape[0], B_obs.shape[1]
        block = np.zeros((size + width, size + width))
        block[:size, :size] = A_obs * self.dt
        block[:size, size:] = B_obs * self.dt
        with np.errstate(over="ignore", invalid="ignore"):
            exponential = expm(block)
        transition, gain = exponential[:size, :size], exponential[:size, size:]
        if not np.all(np.isfinite(exponential)):
            suspect = ("kernel_width" if self.kernel_width > 50 * self.dt
                       else "sensor_precision, process_precision, input_prior_precision")
            raise AttendInputError(
                f"{suspect}: the observer's flow matrix could not be discretised (overflow) with kernel_width = "
                f"{self.kernel_width:g} s, dt = {self.dt:g} s, p = {self.embedding_order}, d = {self.input_order} "
                "(derivative order i is weighted by about kernel_width^(2i)); expected a kernel_width of a few "
                "sample times, smaller precisions or lower embedding orders"
            )
        radius = np.max(np.abs(np.linalg.eigvals(transition)))
        if radius >= 1.0:
            warnings.warn(
                f"the DEM observer is not stable for these settings (spectral radius {radius:.6f} >= 1)",
                ModelWarning,
                stacklevel=3,
            )
        window_gain, offsets = self._fold_embedding(gain)
        window_B_obs, _ = self._fold_embedding(B_obs)
        order0 = np.r_[0:m, m * (p + 1): m * (p + 1) + r]  # columns of y and eta/u at order 0
        try:
            covariance = np.linalg.inv(Pi_X)
        except np.linalg.LinAlgError:
            covariance = np.linalg.pinv(Pi_X)
        return dict(
            Ct=Ct, At=At, Bt=Bt, Dx=Dx, Dv=Dv, Vy=Vy, W=W, Vv=Vv, S_p=S_p, S_d=S_d,
            A_obs=A_obs, B_obs=B_obs, Pi_X=Pi_X, Sigma_X=covariance,
            transition=transition, gain=gain, window_gain=window_gain, window_B_obs=window_B_obs,
            offsets=offsets, order0_gain=gain[:, order0], order0_B_obs=B_obs[:, order0],
        )

    def _fold_embedding(self, gain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fold the embedding weights into Gamma: drive[k] = sum_i G_i [y; u][k + offset_i].

        Returns G stacked as (size, n_offsets * (m + r)) over the raw window (offsets ascending)
        and the offsets relative to k.
        """
        m, r = self.system.n_outputs, self.system.n_inputs
        p, d = self.embedding_order, self.input_order
        Ey = embedding_weights(p + 1, self.dt)  # (p+1 orders, p+1 samples)
        Eu = embedding_weights(d + 1, self.dt)
        first = -max((p + 1) // 2, (d + 1) // 2)
        last = max(self._after(p + 1), self._after(d + 1))
        offsets = np.arange(first, last + 1)
        width = m + r
        folded = np.zeros((gain.shape[0], len(offsets) * width))
        gain_y = gain[:, : m * (p + 1)].reshape(gain.shape[0], p + 1, m)
        gain_u = gain[:, m * (p + 1):].reshape(gain.shape[0], d + 1, r)
        for i in range(p + 1):  # sample i of the y window sits at offset i - (p + 1) // 2
            column = (i - (p + 1) // 2 - first) * width
            folded[:, column: column + m] += np.einsum("sjc,j->sc", gain_y, Ey[:, i])
        for i in range(d + 1):
            column = (i - (d + 1) // 2 - first) * width + m
            folded[:, column: column + r] += np.einsum("sjc,j->sc", gain_u, Eu[:, i])
        return folded, offsets + self.window_offset

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

    def initial_state(self, window: np.ndarray, edge: bool) -> np.ndarray:
        """Start of the flow: the static MAP of the first row's data, X0 = inv(Pi_X) B_obs Y[0].

        This is the mode of F for that sample's data alone (no generalised motion); the fixed
        point of the flow, inv(D_X - Pi_X) B_obs Y[0], is ill-conditioned when the highest orders
        are imprecise and can start the estimate far off. ``window`` is the raw window of the
        row, or (``edge``) its own sample [y; u] for an order-0 edge row.
        """
        mats = self._matrices
        data = mats["order0_B_obs"] @ window if edge else mats["window_B_obs"] @ window
        return np.linalg.lstsq(mats["Pi_X"], data, rcond=None)[0]

    def _edge_rows(self, n_samples: int, start: int, stop: int) -> np.ndarray:
        """Rows in [start, stop) whose embedding window reaches past the log (relative indices)."""
        if self.edges == "clamp":
            return np.zeros(0, dtype=int)
        offsets = self._matrices["offsets"]
        rows = np.arange(start, stop)
        return np.flatnonzero((rows + offsets[0] < 0) | (rows + offsets[-1] > n_samples - 1))

    def _centre_samples(self, signals: np.ndarray, rows: np.ndarray) -> np.ndarray:
        return signals[np.clip(rows + self.window_offset, 0, signals.shape[0] - 1)]

    def estimate(self, outputs, inputs=None, *, keep_generalized: bool = False,
                 initial_state=None, segment: int = 1 << 14) -> DEMEstimate:
        """Batch estimation over a whole log.

        outputs: (N, m) measured outputs; inputs: (N, r) measured inputs (known_inputs=True) or the
        input prior eta (unknown inputs; default 0). The log is processed in segments of
        ``segment`` samples so memory stays O(segment) beyond the (N, n + r) results.
        Row k is the estimate at sample k (it uses samples up to k + delay).
        """
        signals = self._signals(outputs, inputs)
        n_samples = signals.shape[0]
        mats = self._matrices
        n, r, p = self.system.n_states, self.system.n_inputs, self.embedding_order
        n_x = n * (p + 1)
        size = mats["transition"].shape[0]
        states = np.empty((n_samples, n))
        inputs_out = np.empty((n_samples, r))
        generalized = np.empty((n_samples, size)) if keep_generalized else None
        gain_t = mats["window_gain"].T
        state = None if initial_state is None else np.asarray(initial_state, dtype=float)
        for start in range(0, n_samples, segment):
            stop = min(start + segment, n_samples)
            windows = self._raw_windows(signals, start, stop)
            drive = windows @ gain_t
            edge = self._edge_rows(n_samples, start, stop)
            if len(edge):
                drive[edge] = self._centre_samples(signals, start + edge) @ mats["order0_gain"].T
            if state is None:
                first_is_edge = len(edge) > 0 and edge[0] == 0
                first = self._centre_samples(signals, np.array([start]))[0] if first_is_edge else windows[0]
                state = self.initial_state(first, first_is_edge)
            X = linear_recurrence(mats["transition"], drive, state)
            state = X[-1]
            states[start:stop] = X[:, :n]
            if self.known_inputs:
                inputs_out[start:stop] = signals[start:stop, self.system.n_outputs:]
            else:
                inputs_out[start:stop] = X[:, n_x: n_x + r]
            if keep_generalized:
                generalized[start:stop] = X
        std = np.sqrt(np.clip(np.diag(mats["Sigma_X"]), 0, None))
        state_std = np.broadcast_to(std[:n], (n_samples, n))
        input_std = np.broadcast_to(std[n_x: n_x + r] if not self.known_inputs else np.zeros(r), (n_samples, r))
        return DEMEstimate(np.arange(n_samples) * self.dt, states, inputs_out, state_std, input_std, generalized)

    def online(self) -> "OnlineDEM":
        """A fixed-memory observer fed one sample at a time (see :class:`OnlineDEM`)."""
        return OnlineDEM(self)


class OnlineDEM:
    """Sample-by-sample DEM: fixed-size state, output delayed by ``observer.delay`` samples.

    ``step(y, u)`` takes sample k (outputs, and the measured input or input prior) and returns
    (states, inputs) at sample k - delay once enough samples have arrived (None before).
    ``finish()`` returns the last ``delay`` estimates by repeating the final sample, as the
    batch mode does at the end of a log; batch and online results agree sample by sample.
    Memory does not grow with the length of the stream.
    """

    def __init__(self, observer: DEMObserver):
        self.observer = observer
        mats = observer._matrices
        self._transition = mats["transition"]
        self._gain = mats["window_gain"]
        offsets = mats["offsets"]
        self._before = int(-offsets[0])
        self._window = len(offsets)
        self._width = observer.system.n_outputs + observer.system.n_inputs
        self._buffer = np.zeros((self._window, self._width))
        self._count = 0
        self._state: np.ndarray | None = None
        self._n = observer.system.n_states
        self._n_x = self._n * (observer.embedding_order + 1)
        self._r = observer.system.n_inputs
        self._order0 = observer.edges == "order0"

    def _advance(self, edge: bool) -> tuple[np.ndarray, np.ndarray]:
        mats = self.observer._matrices
        if edge:
            data = self._buffer[self._before]
            drive = mats["order0_gain"] @ data
        else:
            data = self._buffer.reshape(-1)
            drive = self._gain @ data
        if self._state is None:
            self._state = self.observer.initial_state(data, edge)
        self._state = self._transition @ self._state + drive
        states = self._state[: self._n].copy()
        if self.observer.known_inputs:
            inputs = self._buffer[self._before, -self._r:].copy()
        else:
            inputs = self._state[self._n_x: self._n_x + self._r].copy()
        return states, inputs

    def step(self, output, input_value=None):
        """Feed sample k (outputs (m,), input or input prior (r,)); return (states, inputs) of
        sample k - delay, or None while the first window fills."""
        output = np.ravel(numeric_array(output, "step: output"))
        input_value = np.zeros(self._r) if input_value is None else np.ravel(numeric_array(input_value, "step: input_value"))
        sample = np.concatenate([output, input_value])
        if sample.shape[0] != self._width:
            raise AttendInputError(f"step: expected {self._width - self._r} outputs and {self._r} inputs")
        require_finite(sample, "step sample")
        if self._count == 0:
            # samples before the first one are the first one repeated (as in batch mode)
            self._buffer[:] = sample
        else:
            self._buffer[:-1] = self._buffer[1:]
            self._buffer[-1] = sample
        self._count += 1
        lead = self._window - 1 - self._before  # future samples needed by the window
        if self._count <= lead:
            return None
        row = self._count - 1 - lead
        return self._advance(edge=self._order0 and row < self._before)

    def finish(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Flush the estimates still waiting for future samples (end samples repeated)."""
        lead = self._window - 1 - self._before
        out = []
        for _ in range(min(lead, self._count)):
            self._buffer[:-1] = self._buffer[1:].copy()
            out.append(self._advance(edge=self._order0))
        return out
