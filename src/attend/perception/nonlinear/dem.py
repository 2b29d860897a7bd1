"""The D-step of nonlinear DEM, batch (:class:`NonlinearDEM`); the equations are in
:mod:`attend.perception.nonlinear`."""

from __future__ import annotations

from dataclasses import KW_ONLY, InitVar, dataclass, field
from math import factorial, isfinite

import numpy as np

from attend._progress import steps
from attend._threads import single_blas_thread
from attend._validation import AttendInputError, as_matrix, order, positive_scalar, precision_matrix, require_finite
from attend.models.generalized import block_precisions, embedding_weights, shift_operator, smoothness_precision
from attend.models.noise_model import NoiseModel
from attend.models.nonlinear import NonlinearSystem
from attend.perception.dem import DEMEstimate
from attend.perception.estimate import Estimate, as_estimate, take_noise
from attend.perception.nonlinear._linalg import (block_diagonal_positions, diagonal_blocks, expm_last_column,
                                                  inverse_diagonals)
from attend.perception.nonlinear._workspace import StepWorkspace
from attend.perception.nonlinear.jax_backend import check_backend, estimate_with_jax
from attend.perception.nonlinear.misfit import check_excursion, sample_misfit, warn_if_misfit
from attend.perception.nonlinear.online import OnlineNonlinearDEM
from attend.perception.nonlinear.path import estimate_path
from attend.perception.nonlinear.start import gauss_newton_start


# --- the D-step -----------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class NonlinearDEM:
    """DEM state (and unknown-input) estimation for a :class:`NonlinearSystem` (module docstring):
    ``NonlinearDEM(system, dt, *, kernel_width, sensor_precision, process_precision, ...)`` or
    ``NonlinearDEM(system, dt, *, noise=NoiseModel(...), ...)`` (the system and the sample time
    first, everything else by keyword).

    system: the model; dt: sample time [s]; kernel_width: s of the Gaussian noise kernel [s];
    sensor_precision: Pi_z [1/output unit^2]; process_precision: Pi_w [s^2/state unit^2, as in
    dx/dt]; noise: an :class:`attend.models.NoiseModel` holding the two precisions and the kernel
    width instead (one width for both noises here: a model whose process and sensor widths differ
    is an error; giving it with any of the three is an error too); :attr:`noise_model` reads them
    back as one; input_prior_precision: P_v [1/input unit^2] (required for unknown inputs);
    embedding_order: p (states/outputs have p + 1 orders); input_order: d; known_inputs: the
    inputs are measured (True) or estimated (False); precision_convention: "size" (SPM) or
    "max" (invert V at max(p, d), see :func:`attend.models.generalized.block_precisions`);
    edges: "order0" (rows whose embedding window reaches past the log use the sample with zero
    derivatives, attend's default) or "clamp" (end samples repeated, SPM);
    flow_time: how long the gradient flow runs per sample. "samples" (default, SPM's D-step): one
    unit of time per sample, i.e. the flow of the model written in sample units (order k scaled by
    dt^k), so the estimates do not depend on the time unit of dt, s and f (the units of the states
    themselves still set the metric of the gradient flow, as in SPM) and the precisions alone set
    how fast the estimate follows the data. "seconds": dt seconds per sample, the flow of attend's linear
    observer (DEMObserver), which it reproduces exactly for linear f, g; with precisions near 1
    [1/unit^2] this flow is slow (rate ~ precision per second) and lags the data.
    motion: how f~ and g~ are formed. "linearized" (SPM): Jacobians at order 0 held fixed,
    f~ = [f; fx x' + fv v'; fx x'' + fv v''; ...]. "path": the derivatives of f(x(tau), v(tau))
    along the Taylor path x(tau) = sum_i x^(i) tau^i / i! (central differences over p + 1 points
    spaced dt), which keeps the curvature terms the linearisation drops (e.g. 2 f_xx x' x' at
    order 2); p + 1 Jacobian evaluations per step. Both are exact for linear f, g.
    input_kernel_width: the smoothness s_v [s] of the input prior, S_d = S(s_v) (default: kernel_width,
    one s for all fluctuations as in SPM); a slower s_v suits inputs smoother than the noise.
    substeps: D-steps per sample (SPM's E.nD), each over 1/substeps of the sample with the
    Jacobians recomputed, the data held at the sample's values.
    divergence_limit: an estimate with |x| or |v| above this [state/input units] (or non-finite)
    stops the run with an :class:`AttendInputError` naming the settings to change.
    integration: how the data enter the one-sample step (docs/spm.md). "attend" (default): y~,
    eta~ held at sample k's values, row k the state after the step with sample k. "spm" (spm_DEM's
    D-step): the data ride along their own motion over the step, d/dt [X; y~; u~] =
    [D X + dF/dX; D y~; D u~], integrated jointly by the exponential of the Jacobian
    [[J, -E' Pi de/dy~, -E' Pi de/du~], [0, D, 0], [0, 0, D]]; row k is the state before the step
    with sample k (row 0 = the start, ``initial_state`` taken as given with higher orders 0, as
    SPM's M(1).x); the top order's motion error is set to 0 (its Jacobian kept).
    states: "sample" (default, the D-step: every sample's generalised state flows on its own
    window, a filter about p/2 samples ahead; :meth:`online` gives the same) or "path" (one
    trajectory for the whole log, the D-step's free energy summed over all windows and maximised
    by Gauss-Newton from the D-step's estimate: a smoother, batch only;
    :mod:`attend.perception.nonlinear.path`).
    path_starts: with states="path", where its optimiser starts: "both" (default: the D-step's
    estimate and the unscented smoother's, the larger F kept; ~2-3x the time of one start) or
    "dstep" (:mod:`attend.perception.nonlinear.path_starts`).
    backend: "numpy" (default) or "jax" (the batch D-step compiled with JAX, f and g written with
    jax.numpy; 2-3x faster; :mod:`attend.perception.nonlinear.jax_backend`).
    Precisions are scalars (times I), vectors (diagonal) or matrices.

    Reported standard deviations: ``state_std``/``input_std`` are the square roots of the diagonal
    of inv(E' Pi~ E), the Laplace (Gauss-Newton) conditional covariance at each sample. Reported, and
    calibrated on simulated data with the true precisions: |error| < 2 std in 94 % (Lorenz) and
    97 % (pendulum, slightly conservative) of the states' samples over 20 seeds (bench_nonlinear;
    tests/perception/test_nonlinear.py checks 93-97 % on Lorenz). ``input_std`` is reported the
    same way but not checked for calibration. They are the conditional
    precision of the instantaneous generalised state, as in the linear observer: under a
    mis-specified model (wrong precisions, wrong f) they are not calibrated.
    """

    system: NonlinearSystem
    dt: float
    _: KW_ONLY
    kernel_width: float | None = None
    sensor_precision: np.ndarray | None = None
    process_precision: np.ndarray | None = None
    input_prior_precision: np.ndarray | None = None
    embedding_order: int = 6
    input_order: int = 2
    known_inputs: bool = False
    precision_convention: str = "size"
    edges: str = "order0"
    divergence_limit: float = 1e6
    flow_time: str = "samples"
    substeps: int = 1
    motion: str = "linearized"
    input_kernel_width: float | None = None
    integration: str = "attend"
    states: str = "sample"
    backend: str = "numpy"
    path_starts: str = "both"
    noise: InitVar[NoiseModel | None] = None
    _matrices: dict = field(default_factory=dict, repr=False)
    #: the starts :meth:`initial_state` found, by their data, guess and iterations (each found once)
    _starts: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self, noise):
        system = self.system
        if not isinstance(system, NonlinearSystem):
            raise AttendInputError("system: expected an attend NonlinearSystem (f, g, n_states, n_inputs, n_outputs)")
        set_ = object.__setattr__
        if noise is not None and getattr(noise, "kernel_width", 0.0) is None:
            raise AttendInputError(f"noise: NonlinearDEM uses one kernel width for both noises; this model has "
                                   f"process_kernel_width {noise.process_kernel_width:g} s and sensor_kernel_width "
                                   f"{noise.sensor_kernel_width:g} s")
        take_noise(self, noise, "NonlinearDEM", required=("kernel_width", "sensor_precision", "process_precision"))
        set_(self, "dt", positive_scalar(self.dt, "dt", "s"))
        set_(self, "kernel_width", positive_scalar(self.kernel_width, "kernel_width", "s"))
        set_(self, "embedding_order", order(self.embedding_order, "embedding_order"))
        set_(self, "input_order", order(self.input_order, "input_order"))
        set_(self, "divergence_limit", positive_scalar(self.divergence_limit, "divergence_limit"))
        set_(self, "sensor_precision", precision_matrix(self.sensor_precision, system.n_outputs, "sensor_precision"))
        set_(self, "process_precision", precision_matrix(self.process_precision, system.n_states, "process_precision"))
        r = system.n_inputs
        if self.known_inputs or r == 0:
            prior = np.zeros((r, r))
        else:
            if self.input_prior_precision is None:
                raise AttendInputError("input_prior_precision: required when the inputs are unknown")
            prior = precision_matrix(self.input_prior_precision, r, "input_prior_precision")
        set_(self, "input_prior_precision", prior)
        if self.edges not in ("order0", "clamp"):
            raise AttendInputError(f"edges: expected 'order0' or 'clamp', got {self.edges!r}")
        if isinstance(self.substeps, bool) or int(self.substeps) != self.substeps or not 1 <= int(self.substeps) <= 64:
            raise AttendInputError(f"substeps: expected an integer in 1..64, got {self.substeps!r}")
        set_(self, "substeps", int(self.substeps))
        if self.input_kernel_width is not None:
            set_(self, "input_kernel_width", positive_scalar(self.input_kernel_width, "input_kernel_width", "s"))
        if self.motion not in ("linearized", "path"):
            raise AttendInputError(f"motion: expected 'linearized' or 'path', got {self.motion!r}")
        if self.integration not in ("attend", "spm"):
            raise AttendInputError(f"integration: expected 'attend' or 'spm', got {self.integration!r}")
        if self.states not in ("sample", "path"):
            raise AttendInputError(f"states: expected 'sample' or 'path', got {self.states!r}")
        if self.flow_time not in ("samples", "seconds"):
            raise AttendInputError(f"flow_time: expected 'samples' or 'seconds', got {self.flow_time!r}")
        if self.path_starts not in ("both", "dstep"):
            raise AttendInputError(f"path_starts: expected 'both' or 'dstep', got {self.path_starts!r}")
        check_backend(self)
        self._matrices.update(self._build())

    # construction ----------------------------------------------------------------------------

    @property
    def noise_model(self) -> NoiseModel:
        """The estimator's noise as one :class:`attend.models.NoiseModel` (the precision matrices and
        the kernel width in use, for both noises), e.g. to build another estimator with the same noise."""
        return NoiseModel(process_precision=self.process_precision, sensor_precision=self.sensor_precision,
                          kernel_width=self.kernel_width)

    @property
    def estimates_inputs(self) -> bool:
        """True when the generalised state X holds unknown inputs v~ (inputs not measured, r > 0)."""
        return not self.known_inputs and self.system.n_inputs > 0

    @property
    def n_state_coordinates(self) -> int:
        """Size of x~: n (p + 1)."""
        return self.system.n_states * (self.embedding_order + 1)

    @property
    def n_input_coordinates(self) -> int:
        """Size of v~: r (d + 1), or 0 with known inputs."""
        return self.system.n_inputs * (self.input_order + 1) if self.estimates_inputs else 0

    @staticmethod
    def _after(window: int) -> int:
        return window - 1 - window // 2

    @property
    def delay(self) -> int:
        """Samples of the future the embedding window needs: the online estimate lags by this."""
        return int(self._matrices["offsets"][-1])

    def generalized_matrices(self) -> dict:
        """The D-step's constant arrays by name (a new dict; the arrays are the estimator's own: read
        them, do not change them): the embedding window's ``offsets`` (relative to the row) and the
        positions of the output and input windows in it (``y_positions``, ``u_positions``), the
        embedding weights ``Ey``, ``Eu``, the precisions ``Vy``, ``W``, ``Vv`` and their blocks
        ``Pi``, the shift operators ``D_X``, ``Dx``, ``Dy``, ``Du``, the constant part of E = de/dX
        (``E_template``, ``E_u_template``, ``E_places``), ``sizes`` (n, r, p, d, min(p, d) + 1),
        ``estimates_inputs``, the ``reported`` coordinates of X (order-0 states and unknown inputs),
        and ``order_scale`` (dt^k of each coordinate)."""
        return dict(self._matrices)

    def _build(self) -> dict:
        n, r, m = self.system.n_states, self.system.n_inputs, self.system.n_outputs
        p, d = self.embedding_order, self.input_order
        S_p, S_d = block_precisions(p, d, self.kernel_width, self.precision_convention)
        if self.input_kernel_width is not None:
            S_d = smoothness_precision(d + 1, self.input_kernel_width)
        if r > 0:
            first = -max((p + 1) // 2, (d + 1) // 2)
            last = max(self._after(p + 1), self._after(d + 1))
        else:
            first, last = -((p + 1) // 2), self._after(p + 1)
        offsets = np.arange(first, last + 1)
        # positions of the y window (p + 1 samples) and input window (d + 1) inside the raw window
        y_positions = np.arange(p + 1) - (p + 1) // 2 - first
        u_positions = np.arange(d + 1) - (d + 1) // 2 - first
        n_x, n_v = self.n_state_coordinates, self.n_input_coordinates
        D_X = np.zeros((n_x + n_v, n_x + n_v))
        D_X[:n_x, :n_x] = shift_operator(p + 1, n)
        D_X[n_x:, n_x:] = shift_operator(d + 1, r) if n_v else np.zeros((0, 0))
        grid = (np.arange(p + 1) - (p + 1) // 2) * self.dt
        taylor = np.array([[t**i / factorial(i) for i in range(p + 1)] for t in grid])
        Vy, W, Vv = np.kron(S_p, self.sensor_precision), np.kron(S_p, self.process_precision), \
            np.kron(S_d, self.input_prior_precision)
        return dict(
            **self._jacobian_templates(), Pi=(Vy, W, Vv) if n_v else (Vy, W),
            sizes=(n, r, p, d, min(p, d) + 1), estimates_inputs=bool(n_v), reported=np.r_[0:n, n_x: n_x + (r if n_v else 0)], scale_outer=np.outer(*(2 * [self._order_scale()])), path_taylor=taylor, path_weights=np.linalg.inv(taylor),
            S_p=S_p, S_d=S_d, offsets=offsets, y_positions=y_positions, u_positions=u_positions,
            Ey=embedding_weights(p + 1, self.dt), Eu=embedding_weights(d + 1, self.dt),
            Vy=Vy, W=W, Vv=Vv, D_X=D_X,
            Dx=shift_operator(p + 1, n), Dy=shift_operator(p + 1, m), Du=shift_operator(d + 1, r),
            y_scale=np.repeat(self.dt ** np.arange(p + 1), m), u_scale=np.repeat(self.dt ** np.arange(d + 1), r),
            order_scale=self._order_scale(),
        )

    def _order_scale(self) -> np.ndarray:
        """dt^k for each coordinate of X (k its order): the change to sample units."""
        n, r, p, d = self.system.n_states, self.system.n_inputs, self.embedding_order, self.input_order
        return np.concatenate([np.repeat(self.dt ** np.arange(p + 1), n),
                               np.repeat(self.dt ** np.arange(d + 1), r) if self.n_input_coordinates else []])

    def _jacobian_templates(self) -> dict:
        """The constant part of E = de/dX (D on the motion rows, I on the input-prior rows), of
        de/du~ for unknown inputs, and the flat places of the Jacobian blocks of f and g in them."""
        n, r, m = self.system.n_states, self.system.n_inputs, self.system.n_outputs
        p, d = self.embedding_order, self.input_order
        n_y, n_x, n_v = m * (p + 1), self.n_state_coordinates, self.n_input_coordinates
        n_u = r * (d + 1)
        E = np.zeros((n_y + n_x + n_v, n_x + n_v))
        E[n_y: n_y + n_x, :n_x] = shift_operator(p + 1, n)
        E[n_y + n_x:, n_x:] = np.eye(n_v)
        E_u = np.zeros((E.shape[0], n_u))
        E_u[n_y + n_x:] = -np.eye(n_v, n_u)
        # the input blocks sit in E's v columns (unknown inputs) or in de/du~ (known inputs)
        shape_v, column_v = (E.shape, n_x) if n_v else ((n_y + n_x, n_u), 0)
        if not n_v:
            E_u = E_u[: n_y + n_x]
        places = dict(gx=block_diagonal_positions(E.shape, 0, 0, (m, n), p + 1),
                      fx=block_diagonal_positions(E.shape, n_y, 0, (n, n), p + 1),
                      gv=block_diagonal_positions(shape_v, 0, column_v, (m, r), min(p, d) + 1),
                      fv=block_diagonal_positions(shape_v, n_y, column_v, (n, r), min(p, d) + 1))
        return dict(E_template=E, E_u_template=E_u, E_places=places)

    # one sample ------------------------------------------------------------------------------

    def _split(self, X, u_tilde):
        """(x~ (p+1, n), v~ (d+1, r)) from X, or v~ = the embedded known inputs."""
        n, r, p, d, _ = self._matrices["sizes"]
        x = X[: n * (p + 1)].reshape(p + 1, n)
        if self._matrices["estimates_inputs"]:
            return x, X[n * (p + 1):].reshape(d + 1, r)
        return x, u_tilde.reshape(d + 1, r)

    def errors(self, X, y_tilde, u_tilde):
        """Prediction errors and their Jacobian at X, Jacobians of f, g held at order 0 of X.

        Returns (e, E, Pi) with e = [e_y; e_x; e_v] (e_v only for unknown inputs), E = de/dX and
        Pi = blkdiag(Vy, W, Vv). X: the generalised state [x~; v~]; y_tilde: the embedded outputs
        y~ ((p + 1) m values); u_tilde: the embedded input prior eta~ (unknown inputs) or the
        embedded measured inputs u~ (known inputs), (d + 1) r values. With integration="spm"
        the top order's motion error is 0.
        """
        return self._errors(X, y_tilde, u_tilde)[:3]

    def _errors(self, X, y_tilde, u_tilde, data_jacobian: bool = False):
        """(e, E, Pi, de/du~) as :meth:`errors`; de/du~ only with ``data_jacobian`` (else None)."""
        mats = self._matrices
        system = self.system
        n, r, p, _, top = mats["sizes"]
        x, v = self._split(X, u_tilde)
        v_pad = np.zeros((p + 1, r))
        v_pad[:top] = v[:top]
        if self.motion == "path":
            f_t, g_t, *blocks = self._path_predictions(x, v_pad)
            E, E_u = self._jacobian_from_blocks(*blocks, data_jacobian)
        else:
            fx, fv, gx, gv = system.jacobians(x[0], v[0])
            g_t, f_t = x @ gx.T, x @ fx.T
            if r:  # (without inputs the terms are zeros)
                g_t += v_pad @ gv.T
                f_t += v_pad @ fv.T
            g_t[0] = system.observe(x[0], v[0])
            f_t[0] = system.flow(x[0], v[0])
            E, E_u = self._jacobian_from_local(fx, fv, gx, gv, data_jacobian)
        e_parts = [y_tilde - g_t.ravel(), np.empty(n * (p + 1))]
        motion_error = e_parts[1].reshape(p + 1, n)
        np.subtract(x[1:], f_t[:-1], out=motion_error[:-1])
        # spm_DEM: no motion error at the top order
        motion_error[-1] = 0.0 if self.integration == "spm" else -f_t[-1]
        if mats["estimates_inputs"]:
            e_parts.append(X[n * (p + 1):] - u_tilde)
        return np.concatenate(e_parts), E, mats["Pi"], E_u

    def _jacobian_from_local(self, fx, fv, gx, gv, data_jacobian: bool):
        """(E, de/du~) for motion="linearized": the template of the constant blocks (D, I) with
        -g_x, -f_x, -g_v, -f_v written on their block diagonals (kron(I, J) without building it).
        fx, fv, gx, gv: the Jacobians of f and g at order 0; data_jacobian: also return de/du~."""
        mats = self._matrices
        E = mats["E_template"].copy()
        flat = E.reshape(-1)
        places = mats["E_places"]
        flat[places["gx"]] = -gx
        flat[places["fx"]] = -fx
        E_u = None
        if self.estimates_inputs:
            flat[places["gv"]] = -gv
            flat[places["fv"]] = -fv
            if data_jacobian:
                E_u = mats["E_u_template"]
        elif data_jacobian:
            E_u = np.zeros(mats["E_u_template"].shape)
            flat_u = E_u.reshape(-1)
            flat_u[places["gv"]] = -gv
            flat_u[places["fv"]] = -fv
        return E, E_u

    def _jacobian_from_blocks(self, Fx, Fv, Gx, Gv, data_jacobian: bool):
        """(E, de/du~) from full generalised Jacobian blocks F~_x, F~_v, G~_x, G~_v (motion="path").
        Fx, Fv, Gx, Gv: the blocks; data_jacobian: also return de/du~."""
        mats = self._matrices
        n_y, n_x = Gx.shape[0], self.n_state_coordinates
        E = mats["E_template"].copy()
        E[:n_y, :n_x] = -Gx
        E[n_y: n_y + n_x, :n_x] = mats["Dx"] - Fx
        E_u = None
        if self.estimates_inputs:
            E[:n_y, n_x:] = -Gv
            E[n_y: n_y + n_x, n_x:] = -Fv
            E_u = mats["E_u_template"] if data_jacobian else None
        elif data_jacobian:
            E_u = np.vstack([-Gv, -Fv])
        return E, E_u

    def _path_predictions(self, x, v_pad):
        """f~, g~ as the derivatives of f and g along the path x(tau) = sum_i x^(i) tau^i / i!
        (central differences over p + 1 points tau_j spaced dt), with their Jacobians."""
        mats = self._matrices
        system = self.system
        n, r, m = system.n_states, system.n_inputs, system.n_outputs
        p, d = self.embedding_order, self.input_order
        T, E = mats["path_taylor"], mats["path_weights"]
        xs, vs = T @ x, T @ v_pad
        F = np.empty((p + 1, n))
        G = np.empty((p + 1, m))
        jac = [system.jacobians(xs[j], vs[j]) for j in range(p + 1)]
        for j in range(p + 1):
            F[j] = system.flow(xs[j], vs[j])
            G[j] = system.observe(xs[j], vs[j])
        fx, fv, gx, gv = (np.stack([jj[i] for jj in jac]) for i in range(4))
        weights = E[:, :, None] * T[None, :, :]  # (k, j, i): E_kj T_ji
        def blocks(J, columns):
            full = np.einsum("kji,jab->kaib", weights[:, :, :columns], J)
            return full.reshape((p + 1) * J.shape[1], columns * J.shape[2])
        n_v = min(p, d) + 1
        Fv = np.zeros(((p + 1) * n, (d + 1) * r))
        Gv = np.zeros(((p + 1) * m, (d + 1) * r))
        if r:
            Fv[:, : n_v * r] = blocks(fv, n_v)
            Gv[:, : n_v * r] = blocks(gv, n_v)
        return E @ F, E @ G, blocks(fx, p + 1), Fv, blocks(gx, p + 1), Gv

    @staticmethod
    def _weighted(e, E, Pi):
        """(Pi e, Pi E) with Pi = blkdiag(Pi) applied block by block."""
        weighted_E = np.empty_like(E)
        weighted_e = np.empty_like(e)
        start = 0
        for block in Pi:
            stop = start + block.shape[0]
            np.matmul(block, E[start:stop], out=weighted_E[start:stop])
            np.matmul(block, e[start:stop], out=weighted_e[start:stop])
            start = stop
        return weighted_e, weighted_E

    def _gradient_curvature(self, X, y_tilde, u_tilde):
        e, E, Pi = self.errors(X, y_tilde, u_tilde)
        weighted_e, weighted_E = self._weighted(e, E, Pi)
        gradient = -(E.T @ weighted_e)         # dF/dX
        curvature = E.T @ weighted_E           # -d2F/dX2 (Gauss-Newton)
        free_energy = -0.5 * e @ weighted_e
        return gradient, curvature, free_energy

    def dstep(self, X, y_tilde, u_tilde):
        """One D-step over dt: X + (expm(J dt) - I) inv(J) (D X + dF/dX); returns (X, curvature).
        X: the generalised state; y_tilde, u_tilde: the sample's embedded data (see :meth:`errors`)."""
        gradient, curvature, _ = self._gradient_curvature(X, y_tilde, u_tilde)
        D_X = self._matrices["D_X"]
        size = X.shape[0]
        block = np.zeros((size + 1, size + 1))
        if self.flow_time == "samples":
            # the flow in sample units: X_k -> X_k dt^k, gradient / dt^k, one unit of time per sample
            scale = self._matrices["order_scale"]
            np.subtract(D_X, curvature / self._matrices["scale_outer"], out=block[:size, :size])
            block[:size, size] = D_X @ (X * scale) + gradient / scale
            if self.substeps != 1:
                block /= self.substeps
            with np.errstate(over="ignore", invalid="ignore"):
                increment = expm_last_column(block) / scale
        else:
            block[:size, :size] = (D_X - curvature) * (self.dt / self.substeps)
            block[:size, size] = (D_X @ X + gradient) * (self.dt / self.substeps)
            with np.errstate(over="ignore", invalid="ignore"):
                increment = expm_last_column(block)
        return X + increment, curvature

    def dstep_spm(self, X, y_tilde, u_tilde):
        """spm_DEM's D-step over dt/substeps: [X; y~; u~] flowed jointly by the exponential of
        [[J, -E' Pi de/dy~, -E' Pi de/du~], [0, D, 0], [0, 0, D]] (class docstring); in sample
        units with flow_time="samples". Returns (X, y~, u~ at the end of the step, curvature).
        X: the generalised state; y_tilde, u_tilde: the embedded data at the start of the step."""
        mats = self._matrices
        e, E, Pi, E_u = self._errors(X, y_tilde, u_tilde, data_jacobian=True)
        weighted_e, weighted_E = self._weighted(e, E, Pi)
        gradient, curvature = -(E.T @ weighted_e), E.T @ weighted_E
        n_y = y_tilde.shape[0]
        couplings = (-weighted_E[:n_y].T, -weighted_E.T @ E_u)     # d(dF/dX)/dy~, d(dF/du~)
        if self.flow_time == "samples":
            scales, duration = (mats["order_scale"], mats["y_scale"], mats["u_scale"]), 1.0 / self.substeps
        else:
            scales, duration = (np.ones(X.shape[0]), np.ones(n_y), np.ones(u_tilde.shape[0])), self.dt / self.substeps
        parts = (X, y_tilde, u_tilde)
        sizes = np.cumsum([0] + [part.shape[0] for part in parts])
        total = int(sizes[-1])
        block = np.zeros((total + 1, total + 1))
        sX = scales[0]
        block[: sizes[1], : sizes[1]] = mats["D_X"] - curvature / np.outer(sX, sX)
        for i, coupling in ((1, couplings[0]), (2, couplings[1])):
            block[: sizes[1], sizes[i]: sizes[i + 1]] = coupling / np.outer(sX, scales[i])
        block[sizes[1]: sizes[2], sizes[1]: sizes[2]] = mats["Dy"]
        block[sizes[2]: sizes[3], sizes[2]: sizes[3]] = mats["Du"]
        block[:total, total] = np.concatenate([mats["D_X"] @ (X * sX) + gradient / sX, mats["Dy"] @ (y_tilde * scales[1]),
                                               mats["Du"] @ (u_tilde * scales[2])])
        with np.errstate(over="ignore", invalid="ignore"):
            increment = expm_last_column(block * duration)
        moved = [part + increment[sizes[i]: sizes[i + 1]] / scales[i] for i, part in enumerate(parts)]
        return moved[0], moved[1], moved[2], curvature

    def generalized_guess(self, guess) -> np.ndarray:
        """A generalised state from ``guess``: order-0 states (n,) with the rest 0, a full X, or zeros."""
        size = self.n_state_coordinates + self.n_input_coordinates
        X = np.zeros(size)
        if guess is not None:
            guess = np.asarray(guess, dtype=float).ravel()
            if guess.shape[0] == self.system.n_states:
                X[: self.system.n_states] = guess
            elif guess.shape[0] == size:
                X = guess.copy()
            else:
                raise AttendInputError(f"initial_state: expected {self.system.n_states} order-0 states or a "
                                       f"generalised state of {size} values, got {guess.shape[0]}")
            require_finite(X, "initial_state")
        return X

    def initial_state(self, y_tilde, u_tilde, guess=None, iterations: int = 20) -> np.ndarray:
        """Start of the flow: the static mode of F for the first sample's data (no generalised
        motion), by Gauss-Newton from ``guess`` (order-0 states (n,), or a full X; default zeros)
        with step halving so F never decreases. For a linear model one step reaches
        inv(Pi_X) B_obs Y[0], the linear observer's start. y_tilde, u_tilde: the first sample's
        embedded outputs and inputs (see :meth:`errors`); iterations: the most Gauss-Newton steps."""
        guess = self.generalized_guess(guess)
        # the same first sample is often started twice (attend estimate runs the D-step on the whole log
        # and on its first samples): the search is deterministic, so its result is kept
        key = (np.asarray(y_tilde, dtype=float).tobytes(), np.asarray(u_tilde, dtype=float).tobytes(), guess.tobytes(),
               int(iterations))
        if key not in self._starts:
            evaluate = self._gradient_curvature
            if self.motion == "linearized" and self.integration == "attend":  # the same, with fewer calls
                evaluate = StepWorkspace(self).gradient_curvature
            self._starts[key] = gauss_newton_start(lambda X: evaluate(X, y_tilde, u_tilde), guess, iterations)
        return self._starts[key].copy()

    # data --------------------------------------------------------------------------------------

    def checked_signals(self, outputs, inputs) -> np.ndarray:
        """The log as the D-step reads it: (N, m + r) samples [y, u] after checking the shapes, the
        inputs' finiteness and that there are enough samples for the embedding window. outputs:
        (N, m); inputs: (N, r) measured inputs (known_inputs=True) or the input prior mean eta
        (None: zeros)."""
        system = self.system
        m, r = system.n_outputs, system.n_inputs
        y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
        if y.shape[1] != m:
            raise AttendInputError(f"outputs: expected {m} columns (one per output), got {y.shape[1]}")
        name = "inputs" if self.known_inputs else "input_prior"
        if inputs is None:
            if self.known_inputs and r > 0:
                raise AttendInputError("inputs: the estimator was built with known_inputs=True; pass the measured inputs")
            u = np.zeros((y.shape[0], r))
        else:
            u = np.asarray(inputs, dtype=float)
            if u.ndim == 1 and r == 1:
                u = u[:, None]
            if u.shape != (y.shape[0], r):
                raise AttendInputError(f"{name}: expected shape ({y.shape[0]}, {r}), got {u.shape}")
            require_finite(u, name)
        minimum = max(self.embedding_order, self.input_order if r else 0) + 1
        if y.shape[0] < minimum:
            raise AttendInputError(f"outputs: expected at least {minimum} samples (the embedding window of "
                                   f"order {minimum - 1}), got {y.shape[0]}")
        return np.hstack([y, u])

    def embed_row(self, window: np.ndarray, edge: bool, centre: np.ndarray):
        """(y~, u~) of one row from its raw window (n_offsets, m + r) of samples [y, u], or with
        ``edge`` (a window reaching past the log, edges="order0") the row's own sample ``centre``
        (m + r,) at order 0 with zero derivatives."""
        mats = self._matrices
        m, r = self.system.n_outputs, self.system.n_inputs
        p, d = self.embedding_order, self.input_order
        if edge:
            y_t = np.zeros((p + 1, m))
            u_t = np.zeros((d + 1, r))
            y_t[0] = centre[:m]
            u_t[0] = centre[m:]
        else:  # the positions are consecutive: slices, not index arrays
            first_y, first_u = mats["y_positions"][0], mats["u_positions"][0]
            y_t = mats["Ey"] @ window[first_y: first_y + p + 1, :m]
            if not r:
                return y_t.ravel(), np.empty(0)
            u_t = mats["Eu"] @ window[first_u: first_u + d + 1, m:]
        return y_t.ravel(), u_t.ravel()

    def check_divergence(self, X, sample: int) -> None:
        """Raise an AttendInputError naming what to change when the generalised state X of sample
        ``sample`` has left the model's range (|order-0 estimate| > divergence_limit, or not finite)."""
        order0 = X[self._matrices["reported"]]
        # X @ X is finite when all of X is (one call; its overflow falls back to the exact test)
        if np.abs(order0).max() > self.divergence_limit or not (isfinite(X @ X) or np.isfinite(X).all()):
            raise AttendInputError(
                f"NonlinearDEM: the estimate diverged at sample {sample} (max |order-0 estimate| = "
                f"{np.max(np.abs(order0)):.3g} > divergence_limit = {self.divergence_limit:.3g}). The local "
                "linearisation is not valid over one sample: lower embedding_order or kernel_width, lower "
                "process_precision relative to sensor_precision, check f/g and their Jacobians, start "
                "nearer the data (initial_state), or raise divergence_limit if such values are expected.")

    def order0_estimate(self, X, curvature, u_tilde):
        """(order-0 states, inputs, curvature) of a sample from its generalised state X, the
        curvature E' Pi E of its D-step and its embedded inputs u_tilde (the inputs when they are
        measured); the std comes later from the curvature (many samples in one call)."""
        n, r = self.system.n_states, self.system.n_inputs
        n_x = self.n_state_coordinates
        if self.estimates_inputs:
            return X[:n], X[n_x: n_x + r], curvature
        return X[:n], u_tilde[:r], curvature

    def _with_std(self, rows) -> list:
        """Rows (states, inputs, curvature, X) -> (states, inputs, state std, input std, X): the
        std are sqrt(diag(inv(E' Pi E))) of the order-0 states (and inputs), all rows at once."""
        if not rows:
            return []
        n, r = self.system.n_states, self.system.n_inputs
        std = np.sqrt(np.clip(inverse_diagonals(np.array([row[2] for row in rows]),
                                                       self._matrices["reported"]), 0, None))
        input_std = std[:, n:] if self.estimates_inputs else np.zeros((len(rows), r))
        return [(row[0], row[1], std[i, :n], input_std[i], row[3]) for i, row in enumerate(rows)]

    def estimate(self, outputs, inputs=None, *, keep_generalized: bool = False, initial_state=None,
                 initial_state_std=None) -> Estimate:
        """Batch estimation over a whole log, as an :class:`attend.perception.estimate.Estimate`
        (method "nonlinear dem"; details: a :class:`attend.perception.dem.DEMEstimate`, the linear
        observer's fields).

        outputs: (N, m); inputs: (N, r) measured inputs (known_inputs=True) or the input prior
        mean eta (unknown inputs; default 0); initial_state: a guess of the order-0 states (n,)
        (or a full generalised state) where the Gauss-Newton start is sought (default zeros);
        initial_state_std: with states="path", the std (scalar or (n,), > 0) of a Gaussian prior on
        the first sample's states about initial_state (default: none).
        Row k is the estimate at sample k after the flow over that sample (it uses samples up to
        k + delay). Batch and :meth:`online` agree sample by sample. With states="path" row k is
        the trajectory at sample k given the whole log, and its std is the estimator's spread
        (:mod:`attend.perception.nonlinear.path`). keep_generalized: also return
        the generalised state [x~; v~] of every sample (``generalized``, (N, n (p + 1) + r (d + 1))).
        """
        signals = self.checked_signals(outputs, inputs)
        if self.states == "path":
            result = estimate_path(self, signals, initial_state, initial_state_std=initial_state_std,
                                   keep_generalized=keep_generalized)
        elif initial_state_std is not None:
            raise AttendInputError("initial_state_std: a prior on x[0] is used by states='path' only (the D-step "
                                   "takes initial_state as the guess where its start is sought)")
        elif self.backend == "jax":
            result = estimate_with_jax(self, signals, initial_state, keep_generalized)
        else:
            result = self.dstep_estimate(signals, keep_generalized, initial_state)
        return as_estimate(result, "nonlinear dem")

    def dstep_estimate(self, signals, keep_generalized: bool = False, initial_state=None,
                       check: bool = True) -> DEMEstimate:
        """The D-step (states="sample") over ``signals`` (N, m + r) checked by :meth:`checked_signals`,
        whatever ``states`` and ``backend`` say (see :meth:`estimate` for keep_generalized and
        initial_state); check: warn when the log is far from the model, and raise when the estimate
        has left the data (:mod:`attend.perception.nonlinear.misfit`)."""
        online = OnlineNonlinearDEM(self, initial_state=initial_state)
        rows, pending = [], []
        with single_blas_thread():  # small matrices: one BLAS thread is 10-20x faster (attend._threads)
            for sample in steps(signals, "NonlinearDEM D-step"):
                out = online.push_row(sample)
                if out is not None:
                    pending.append(out)
                if len(pending) == 32:  # the std of a chunk of samples in one call (the stack stays in cache)
                    rows.extend(self._with_std(pending))
                    pending = []
            pending.extend(online.flush_rows())
            rows.extend(self._with_std(pending))
            if check:
                warn_if_misfit(sample_misfit(self, signals, [row[4] for row in rows]), "NonlinearDEM", 3)
        estimate = self._collect(rows, keep_generalized)
        if check:
            check_excursion(self, signals, estimate.states, estimate.inputs, "NonlinearDEM")
        return estimate

    def _collect(self, rows, keep_generalized):
        n_samples = len(rows)
        states = np.array([row[0] for row in rows])
        inputs = np.array([row[1] for row in rows]).reshape(n_samples, self.system.n_inputs)
        state_std = np.array([row[2] for row in rows])
        input_std = np.array([row[3] for row in rows]).reshape(n_samples, self.system.n_inputs)
        generalized = np.array([row[4] for row in rows]) if keep_generalized else None
        return DEMEstimate(np.arange(n_samples) * self.dt, states, inputs, state_std, input_std, generalized)

    def online(self, initial_state=None) -> "OnlineNonlinearDEM":
        """A fixed-memory estimator fed one sample at a time (see :class:`OnlineNonlinearDEM`);
        initial_state: a guess of the order-0 states (n,) for the start (default zeros)."""
        if self.states == "path":
            raise AttendInputError("states: 'path' needs the whole log; online() runs the D-step sample by sample "
                                   "(build the estimator with states='sample')")
        return OnlineNonlinearDEM(self, initial_state=initial_state)
