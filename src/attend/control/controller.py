"""Active inference control: perception by a D-step, action by descending sensory prediction errors.

At every sample y[k] the agent embeds its outputs in generalised coordinates (y~: value and
derivatives at the newest sample, from a causal least-squares polynomial over the last W samples)
and integrates over one sample dt the joint flow of its beliefs X = [x~; v~] and its action a::

    dX/dt = D X + dF/dX = D X - E' Pi~ e                         (perception, the D-step of DEM)
    da/dt = -kappa (dy~/da)' Pi~_z e_y                           (action)

    e = [e_y; e_x; e_v] = [y~ - g~(X); D x~ - f~(X); v~ - eta~]  (sensory, motion, cause errors)
    Pi~ = blkdiag(kron(S, Pi_z), kron(S, Pi_w), kron(S_d, P_v))  F = -e' Pi~ e / 2 + log|Pi~| / 2

E = de/dX (Jacobians of f, g held fixed over the sample), S = S(s) the smoothness precision
(attend.models.generalized), kappa the ``action_gain``. dy~/da is the process's column of Markov
parameters [g_a; g_x f_a; g_x f_x f_a; ...] (as spm_ADEM/spm_ALAP take it from the generative
process): a matrix you give, a function of the beliefs, or "process" (then :func:`run` passes the
true process's Jacobian at its true state each sample, exactly SPM's convention). Within the
sample the agent predicts its sensations move with its action, y~ + dy~/da (a - a[k]) (SPM
integrates world and agent jointly); the joint flow is integrated by local linearisation,
Z <- Z + (expm(J dt) - I) inv(J) flow(Z) (Ozaki), which is exact for linear models.

Sensory precision Pi_z may be constant, a function Pi_z(x, v) (state-dependent: attention, e.g.
sensory attenuation), multiplied by a rhythm pi(t) (``precision_schedule``) and/or learned online
(``precision_learning``). Action uses the same Pi_z(t) unless ``action_precision`` fixes it (SPM's
G.U: a reflex arc whose gain does not follow attention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from attend._validation import AttendInputError, number, positive_scalar, precision_matrix
from attend.control._checks import ClosedLoopDivergence, count, vector
from attend.control._checks import action_limits as checked_action_limits
from attend.control._core import (
    JointFlow,
    causal_embedding_weights,
    relative_degrees,
    sensory_precision,
    discrete_transition,
    error_jacobian,
    generalised_errors,
    joint_system,
    moving_data_transition,
    shift_matrix,
)
from attend.control.model import GenerativeModel
from attend.models.generalized import smoothness_precision


@dataclass(frozen=True)
class SensorPrecisionLearning:
    """Online learning of the sensory log-precisions lambda (Pi_z = diag(exp(lambda))), one per output.

    Per output i, q_i tracks the squared sensory prediction error of each sample before the D-step
    absorbs it (a trusted sensor cannot hide its own noise in the belief, as it can in the residual
    after the step), with forgetting time tau (``time_constant`` [s]):
    q_i <- (1 - dt/tau) q_i + (dt/tau) q_i(now), and
    lambda_i maximises n_eff/2 (c_i lambda - e^lambda q_i) - P_lambda/2 (lambda - eta_lambda)^2 (Newton
    steps; n_eff = tau/dt samples), the M-step's free energy with a Gaussian hyperprior: eta_lambda the
    model's log-precision, P_lambda ``hyperprior_precision``; lambda stays within eta_lambda +- ``bounds``.
    ``orders`` "value" (default): q_i(now) = e_i0^2, c_i = 1, the order-0 error whose variance is
    1/pi_i (plus the belief's one-sample prediction variance) whatever the embedding; "all":
    q_i(now) = e_i' S e_i over the attended orders, c_i their count (needs derivatives that follow S(s)). ``level`` "relative"
    (default): lambda shifted so that sum(exp(lambda)) = sum(exp(eta_lambda)), only each sensor's share
    of the designed total precision (the sensory gain of the controller) is learned: an agent's sensory
    errors hold its own intended prediction errors (what drives its action), which the absolute level
    counts as noise; "absolute": each lambda_i as above (an estimate of each sensor's noise level; under
    control it lowers the gain with the agent's own errors: on the three plants of docs/control.md it
    raised the step ITAE 27-620x over fixed precision where "relative" lowered it). ``groups``: None (one total over all outputs) or one label per
    output (e.g. the joint each sensor reads): the relative level keeps the total within each group, so that
    sensors of different variables do not trade precision. A linear model keeps its cached transition until some
    lambda_i has moved by more than ``rebuild_tolerance``.
    """

    time_constant: float = 2.0
    hyperprior_precision: float = 1.0 / 16.0
    bounds: float = 12.0
    orders: str = "value"
    level: str = "relative"
    rebuild_tolerance: float = 0.05
    groups: tuple | None = None

    def __post_init__(self) -> None:
        if self.orders not in ("value", "all"):
            raise AttendInputError(f"orders: expected 'value' or 'all', got {self.orders!r}")
        if self.level not in ("absolute", "relative"):
            raise AttendInputError(f"level: expected 'absolute' or 'relative', got {self.level!r}")
        object.__setattr__(self, "rebuild_tolerance", positive_scalar(self.rebuild_tolerance, "rebuild_tolerance"))
        if self.groups is not None:
            labels = np.asarray(self.groups)
            if labels.ndim != 1 or labels.size == 0 or labels.dtype.kind not in "iu":
                raise AttendInputError(f"groups: expected one integer label per output, got {self.groups!r}")
            object.__setattr__(self, "groups", tuple(int(v) for v in labels))
        object.__setattr__(self, "time_constant", positive_scalar(self.time_constant, "time_constant", "s"))
        object.__setattr__(self, "hyperprior_precision", positive_scalar(self.hyperprior_precision, "hyperprior_precision"))
        object.__setattr__(self, "bounds", positive_scalar(self.bounds, "bounds"))


class StepInfo(NamedTuple):
    """The agent after one sample: time [s]; action a (k,); states x and causes v (order 0 of the
    beliefs); sensory_error e_y at order 0 (m,); sensor_precision: diag of Pi_z(t) (m,);
    free_energy: -e' Pi~ e / 2 + log|Pi~| / 2 (up to a constant)."""

    time: float
    action: np.ndarray
    states: np.ndarray
    causes: np.ndarray
    sensory_error: np.ndarray
    sensor_precision: np.ndarray
    free_energy: float


def _schedule(schedule) -> Callable | None:
    """A function t -> precision multiplier pi(t) from an attend.rhythm schedule or a function."""
    if schedule is None:
        return None
    from attend.rhythm import FixedSchedule, PrecisionOscillator, RhythmicSchedule

    if isinstance(schedule, PrecisionOscillator):
        return schedule.multiplier
    if isinstance(schedule, RhythmicSchedule):
        return schedule.oscillator.multiplier
    if isinstance(schedule, FixedSchedule):
        if schedule.act_s > 0:
            raise AttendInputError("precision_schedule: a FixedSchedule with act_s > 0 gives no precision for its act "
                                   "phase; use act_s = 0 (a constant multiplier) or a PrecisionOscillator")
        value = schedule.multiplier
        return lambda t: value
    if callable(schedule):
        return schedule
    raise AttendInputError("precision_schedule: expected a PrecisionOscillator, RhythmicSchedule, FixedSchedule "
                           f"or a function t -> multiplier, got {type(schedule).__name__}")


class ActiveInferenceController:
    """Active inference controller for a :class:`GenerativeModel`: ``step(y)`` -> action, one sample at a time.

    model: the agent's :class:`GenerativeModel`; dt: sample time [s].
    action_gain: kappa > 0 in da/dt = -kappa (dy~/da)' Pi~_z e_y.
    action_jacobian: dy~/da, ((p + 1) m, k) rows order-major (see :func:`markov_parameters`), or a
    function ``(x, v, a) -> matrix`` of the beliefs, or "process": given each sample by
    :func:`run` from the true process (SPM's convention). n_actions: k (needed unless
    action_jacobian is a matrix). action_precision: None (the model's Pi_z(t), attention gates
    action) or a fixed (m, m) precision (scalar, vector or matrix) for the action's errors.
    action_prior_precision: P_a >= 0, a leak -kappa P_a a towards a = 0. action_limits: optional
    (low, high): the action is clipped there (anti-windup). initial_action: a at t = 0 (zeros).
    precision_schedule: a rhythm on Pi_z: PrecisionOscillator, RhythmicSchedule (its oscillator),
    FixedSchedule (act_s = 0: its constant multiplier) or a function t -> multiplier (scalar or m).
    precision_learning: a :class:`SensorPrecisionLearning` to learn Pi_z online (diagonal).
    embedding_window: W samples per least-squares fit in the causal embedding (default: rho_i + 1,
    exact backward differences of the attended orders of output i). sensory_orders:
    the orders of motion of each output that carry sensory precision: "relative_degree" (default:
    output i up to the first order at which the action moves it, with the marginal precision
    S(rho_i + 1); outputs no action moves keep all orders), "all" (SPM: kron(S, Pi_z) on p + 1
    orders) or a highest order for every output. In a sampled loop the finite-difference embedding
    of a zero-order-held action shows each jump of a in the orders above the relative degree, with
    the sign opposite to dy~/da there: attending to them is positive feedback (docs/control.md).
    precision_gradient: for a state-dependent Pi_z(x, v), include d/dx (log|Pi~| - e' Pi~ e) / 2 in
    the belief flow (True, as spm_ALAP). divergence_limit: |Z| beyond which the controller stops
    with :class:`ClosedLoopDivergence` naming the settings. jacobian_tolerance: None (default: a nonlinear
    model is re-linearised every sample) or a relative tolerance >= 0: while dy~/da and Pi_z are unchanged and
    each Jacobian of f and g moved by at most this fraction of its largest entry (max(1, .)) since the last
    linearisation, that linearisation and its transition int_0^dt expm(J s) ds are reused (0: only when the
    Jacobians are exactly equal, which changes nothing but the speed). data_motion: "held" (default: within the
    sample the agent holds its data y~[k] and prior eta~(t_k), so by the end of the sample a belief that moves with
    the data lags them by its motion times dt) or "generalised" (the data and the prior move with their own generalised
    motion within the sample, y~(t) = expm(D t) y~[k], as spm_DEM integrates [y~; x~; v~] jointly; needs the exact
    linear step, and costs nothing per sample there). integration: "attend" (default) or "spm", the conventions of
    spm_ADEM / spm_ALAP's D-step: the data and the prior move with their generalised motion within the sample (as
    data_motion="generalised", for any model: the general step then integrates [Z; y~; eta~] jointly), and the cause
    prior's precision on its d + 1 orders is the top-left block of S(s) at p + 1 orders (SPM weighs the prior errors
    at p + 1 orders, those above d pinned at 0), not S(s) at d + 1 orders. top_motion_error: True (default) or
    False: the motion error of the states at the top order p, D x~ - f~ there, is taken as 0 (its Jacobian kept), as
    spm_DEM_eval computes it for spm_ADEM (then every step is the general one). belief_prior_precision: P_u >= 0, a
    weak Gaussian prior on the beliefs centred at 0, with precision blkdiag(kron(S, P_u I_n), kron(S_dd, P_u I_r)) on
    [x~; v~] (S = S(s) at p + 1 orders, S_dd its top-left d + 1 block), as spm_ADEM's Pu (P_u = exp(-8) there; 0,
    the default: none; > 0: every step is the general one). With ``integration="spm"``,
    :meth:`step_generalised` can also integrate the world jointly with the agent (``world_motion``), as spm_ADEM does.
    """

    def __init__(self, model: GenerativeModel, dt: float, *, action_gain: float = 1.0, action_jacobian="process",
                 n_actions: int | None = None, action_precision=None, action_prior_precision: float = 0.0,
                 action_limits=None, initial_action=None, precision_schedule=None,
                 precision_learning: SensorPrecisionLearning | None = None, embedding_window: int | None = None,
                 precision_gradient: bool = True, divergence_limit: float = 1e8,
                 sensory_orders="relative_degree", jacobian_tolerance: float | None = None,
                 data_motion: str = "held", integration: str = "attend", top_motion_error: bool = True,
                 belief_prior_precision: float = 0.0):
        if not isinstance(model, GenerativeModel):
            raise AttendInputError(f"model: expected an attend.control.GenerativeModel, got {type(model).__name__}")
        self.model = model
        self.dt = positive_scalar(dt, "dt", "s")
        self.action_gain = positive_scalar(action_gain, "action_gain")
        n, r, m = model.n_states, model.n_causes, model.n_outputs
        P, Q = model.embedding_order + 1, model.cause_order + 1
        self._sizes = (n, r, m, P, Q)
        if isinstance(action_jacobian, str):
            if action_jacobian != "process":
                raise AttendInputError(f"action_jacobian: expected a matrix, a function (x, v, a) -> matrix or "
                                       f"'process', got {action_jacobian!r}")
            self._G_source = "process"
        elif callable(action_jacobian):
            self._G_source = action_jacobian
        else:
            array = np.asarray(action_jacobian, dtype=float)
            if array.ndim != 2:
                raise AttendInputError(f"action_jacobian: expected a ((p + 1) m, k) = ({P * m}, k) matrix, got shape "
                                       f"{array.shape}")
            n_actions = array.shape[1] if n_actions is None else n_actions
            self._G_source = None
        if n_actions is None:
            raise AttendInputError("n_actions: expected the number of actions k when action_jacobian is 'process' "
                                   "or a function")
        self.n_actions = k = count(n_actions, "n_actions", 1)
        if isinstance(sensory_orders, str):
            if sensory_orders not in ("relative_degree", "all"):
                raise AttendInputError(f"sensory_orders: expected 'relative_degree', 'all' or an order 0..{P - 1}, got "
                                       f"{sensory_orders!r}")
        else:
            sensory_orders = count(sensory_orders, "sensory_orders", 0)
            if sensory_orders > P - 1:
                raise AttendInputError(f"sensory_orders: expected an order 0..p = {P - 1}, got {sensory_orders}")
        self.sensory_orders = sensory_orders
        self._orders = None
        self.action_precision = (None if action_precision is None
                                 else precision_matrix(action_precision, m, "action_precision"))
        pa = number(action_prior_precision, "action_prior_precision")
        if not math.isfinite(pa) or pa < 0:
            raise AttendInputError(f"action_prior_precision: expected a finite number >= 0, got {action_prior_precision!r}")
        self.action_prior_precision = pa
        action_limits = checked_action_limits(action_limits, k)
        self.action_limits = action_limits
        self._a0 = np.zeros(k) if initial_action is None else vector(initial_action, k, "initial_action")
        self._multiplier = _schedule(precision_schedule)
        self.precision_schedule = precision_schedule
        if precision_learning is not None and not isinstance(precision_learning, SensorPrecisionLearning):
            raise AttendInputError("precision_learning: expected a SensorPrecisionLearning or None")
        if precision_learning is not None and model.state_dependent_precision:
            raise AttendInputError("precision_learning: cannot learn a state-dependent sensor_precision(x, v); give a "
                                   "constant sensor_precision to start learning from")
        if precision_learning is not None and precision_learning.groups is not None and len(precision_learning.groups) != m:
            raise AttendInputError(f"precision_learning.groups: expected one label per output ({m}), got "
                                   f"{len(precision_learning.groups)}")
        self.precision_learning = precision_learning
        if embedding_window is not None:
            embedding_window = count(embedding_window, "embedding_window", 1)
        self.embedding_window = embedding_window
        self._buffer_length = P if embedding_window is None else max(P, embedding_window)
        self._embed_full = None
        if sensory_orders != "relative_degree":
            self._set_orders(np.full(m, P - 1 if sensory_orders == "all" else sensory_orders))
        self.precision_gradient = bool(precision_gradient)
        self.divergence_limit = positive_scalar(divergence_limit, "divergence_limit")
        if jacobian_tolerance is not None:
            jt = number(jacobian_tolerance, "jacobian_tolerance")
            if not math.isfinite(jt) or jt < 0:
                raise AttendInputError(f"jacobian_tolerance: expected None or a finite number >= 0, got "
                                       f"{jacobian_tolerance!r}")
            jacobian_tolerance = jt
        self.jacobian_tolerance = jacobian_tolerance
        self._general_cache = None
        if data_motion not in ("held", "generalised"):
            raise AttendInputError(f"data_motion: expected 'held' or 'generalised', got {data_motion!r}")
        if integration not in ("attend", "spm"):
            raise AttendInputError(f"integration: expected 'attend' or 'spm', got {integration!r}")
        self.integration = integration
        if integration == "spm":  # spm_ADEM / spm_ALAP's D-step: the data and the prior move within the sample
            data_motion = "generalised"
        self.data_motion = data_motion
        S_P = smoothness_precision(P, model.kernel_width)
        S_Q = smoothness_precision(Q, model.kernel_width)
        self._S_P = S_P
        self._S_by_order = []
        for q in range(P):
            padded = np.zeros((P, P))
            padded[: q + 1, : q + 1] = smoothness_precision(q + 1, model.kernel_width)
            self._S_by_order.append(padded)
        self._S_logdet = [float(np.linalg.slogdet(S[: q + 1, : q + 1])[1]) for q, S in enumerate(self._S_by_order)]
        self._Pi_x = np.kron(S_P, model.process_precision)
        # SPM weighs the cause prior's errors at p + 1 orders with S(s) of p + 1 orders, the orders above d pinned at 0:
        # on the d + 1 orders estimated, the top-left block of that S (attend: S(s) of d + 1 orders)
        S_v = S_P[:Q, :Q] if integration == "spm" and Q <= P else S_Q
        self._Pi_v = np.kron(S_v, model.cause_prior_precision)
        self._D = shift_matrix(P, n, Q, r)
        self._logdet_fixed = (np.linalg.slogdet(self._Pi_x)[1] + (np.linalg.slogdet(self._Pi_v)[1] if r else 0.0))
        self._fast = (model.is_linear and not model.state_dependent_precision
                      and (self._multiplier is None or _is_constant_schedule(precision_schedule)))
        if data_motion == "generalised" and not self._fast and integration != "spm":
            raise AttendInputError("data_motion: 'generalised' needs the exact linear step (a linear model with "
                                   "constant or learned precision, no state-dependent precision or rhythm); use 'held'")
        self._fast_cache: dict = {}
        if model.is_linear:
            A, B, C, Dm = model.matrices
            self._E = error_jacobian(A, B, C, Dm, P, Q)
        # the general step's joint flow in preallocated arrays (F, Pi~, J); a linear model's Jacobians are written once
        self._joint = JointFlow(n, r, m, k, P, Q, self._D, self._Pi_x, self._Pi_v, self.action_gain, pa, self.dt)
        if model.is_linear:
            self._joint.set_jacobians(*model.matrices)
        self._joint_precision = None  # the Pi_z (and action_precision) last written into the joint flow
        self._joint_action_precision = None
        self._joint_orders = None
        self._joint_Pi_a = None  # Pi~ of the action precision last written into the joint flow
        self._moving_data = integration == "spm"  # the data and the prior move within the sample (general step)
        self.top_motion_error = bool(top_motion_error)
        self._joint.top_motion_error = self.top_motion_error
        if not self.top_motion_error:
            self._fast = False  # the exact linear step has the top order's motion error in it
        pu = number(belief_prior_precision, "belief_prior_precision")
        if not math.isfinite(pu) or pu < 0:
            raise AttendInputError("belief_prior_precision: expected a finite number >= 0, got "
                                   f"{belief_prior_precision!r}")
        self.belief_prior_precision = pu
        self._Pi_u = None
        if pu > 0:  # in the joint flow's linear part L: flow = L Z - H' e and J = L - H' F both take -Pi_u
            self._Pi_u = np.zeros((P * n + Q * r, P * n + Q * r))
            self._Pi_u[: P * n, : P * n] = np.kron(S_P, pu * np.eye(n))
            self._Pi_u[P * n:, P * n:] = np.kron(S_P[:Q, :Q] if Q <= P else S_Q, pu * np.eye(r))
            self._joint.L[: P * n + Q * r, : P * n + Q * r] -= self._Pi_u
            self._fast = False  # the exact linear step has no such prior
        self._world_motion = None  # the world's motion of this step (:meth:`step_generalised`)
        self._prior_motion = None  # the prior's motion of this step (:meth:`step_generalised`)
        self._world_increment = None
        self._G_fixed = None if self._G_source is not None else self._check_G(action_jacobian)
        self.reset()

    # --- state ------------------------------------------------------------------------------

    def reset(self) -> None:
        """Back to t = 0: beliefs at the model's initial states and prior causes, action at initial_action."""
        n, r, m, P, Q = self._sizes
        model = self.model
        Z = np.zeros(P * n + Q * r + self.n_actions)
        Z[:n] = model.initial_states
        eta = model.prior(0.0)
        Z[P * n: P * n + Q * r] = eta
        if model.initial_causes is not None:
            Z[P * n: P * n + r] = model.initial_causes
        Z[P * n + Q * r:] = self._a0
        self._Z = Z
        self._buffer = np.zeros((self._buffer_length, m))
        self._count = 0
        self._k = 0
        self._y_t = np.zeros(P * m)
        self._G_last = None
        if self.precision_learning is not None:
            base = np.diag(model.sensor_precision)
            self._log_precision = np.log(base).copy()
            self._prior_log_precision = np.log(base).copy()
            self._q = None  # set at the first update, when the attended orders are known
        self._last_precision = None
        self._general_cache = None
        self._evaluation = None  # (x0, v0) and the model's values there (:meth:`_evaluate`)
        self._last_prior = None  # (t, eta~(t)) of the last step
        self._base_precision = None  # (x0, v0, Pi_z(x0, v0)) of the last call of :meth:`_precision`
        self._logdet = None  # (Pi_z, log|Pi~_z|) of the last :meth:`_sensory_logdet`

    @property
    def time(self) -> float:
        """t [s] of the next sample."""
        return self._k * self.dt

    @property
    def action(self) -> np.ndarray:
        """The current action a (k,)."""
        return self._Z[-self.n_actions:].copy()

    @property
    def generalised_states(self) -> np.ndarray:
        """x~ ((p + 1) n,), order-major."""
        n, _, _, P, _ = self._sizes
        return self._Z[: P * n].copy()

    @property
    def generalised_causes(self) -> np.ndarray:
        """v~ ((d + 1) r,), order-major."""
        n, r, _, P, Q = self._sizes
        return self._Z[P * n: P * n + Q * r].copy()

    @property
    def states(self) -> np.ndarray:
        """x (n,): the believed states (order 0)."""
        return self._Z[: self._sizes[0]].copy()

    @property
    def causes(self) -> np.ndarray:
        """v (r,): the believed causes (order 0)."""
        n, r, _, P, _ = self._sizes
        return self._Z[P * n: P * n + r].copy()

    @property
    def sensor_precision(self) -> np.ndarray:
        """diag Pi_z used at the last sample (m,) (learned, scheduled or state-dependent)."""
        if self._last_precision is None:
            n, r, _, P, _ = self._sizes
            return np.diag(self._precision(self._Z[:n], self._Z[P * n: P * n + r], 0.0))
        return np.diag(self._last_precision).copy()

    # --- the step ---------------------------------------------------------------------------

    def step(self, y, action_jacobian=None) -> np.ndarray:
        """Take sample y[k] (m,), update beliefs and action over one sample; return the action a (k,)
        to hold until the next sample. action_jacobian: dy~/da for this sample (needed when the
        controller was built with action_jacobian="process"; :func:`run` passes it)."""
        m = self._sizes[2]
        sample = np.asarray(y, dtype=float).reshape(-1)
        if sample.shape[0] != m:
            raise AttendInputError(f"y: expected {m} outputs (the model's n_outputs), got {sample.shape[0]}")
        if not np.isfinite(sample).all():
            raise AttendInputError(f"y: expected finite outputs, got {sample.tolist()} at t = {self.time:g} s")
        buffer = self._buffer
        if self._count == 0:
            buffer[:] = sample  # clamp: the first sample repeated before the log starts
        else:
            buffer[:-1] = buffer[1:]
            buffer[-1] = sample
        self._count += 1
        G = self._resolve_G(action_jacobian)  # fixes the attended orders (and the embedding) at the first sample
        self._y_t = self._embed_full @ buffer.reshape(-1)
        return self._advance(self._y_t, G)

    def step_generalised(self, y_tilde, action_jacobian=None, world_motion=None, prior_motion=None) -> np.ndarray:
        """As :meth:`step`, with the generalised outputs given: y_tilde = y~ ((p + 1) m,), order-major (e.g.
        measured rates); action_jacobian: dy~/da for this sample, as in :meth:`step`. world_motion: None, or the
        world's motion over this sample linearised (:meth:`GenerativeProcess.generalised_motion`; needs
        ``integration="spm"``): the world, the data it drives and the agent are then integrated jointly, as
        spm_ADEM does, and the world's increment is :attr:`world_increment`. prior_motion: None (the prior eta~(t)
        moves with its own motion within the sample) or eta~_m ((d + 1) r,), order-major (needs
        ``integration="spm"``): the prior moves with the motion of eta~_m instead, the rest of eta~ - eta~_m held
        over the sample; e.g. a prior embedded at p + 1 orders and folded onto d + 1, whose folded part spm_ALAP
        holds while the prior's own orders 0..d move (:func:`attend.control.attenuation.embedded_intention`)."""
        _, _, m, P, Q = self._sizes
        y_t = np.asarray(y_tilde, dtype=float).reshape(-1)
        if y_t.shape[0] != P * m:
            raise AttendInputError(f"y_tilde: expected (p + 1) m = {P * m} values, got {y_t.shape[0]}")
        if not np.isfinite(y_t).all():
            raise AttendInputError("y_tilde: expected finite values")
        if world_motion is not None:
            if self.integration != "spm":
                raise AttendInputError("world_motion: integrating the world jointly needs integration='spm'")
            if world_motion.C.shape != (P * m, world_motion.A.shape[0]) or world_motion.B.shape[1] != self.n_actions:
                raise AttendInputError(f"world_motion: expected C of shape ({P * m}, {world_motion.A.shape[0]}) and B "
                                       f"with {self.n_actions} columns, got {world_motion.C.shape} and "
                                       f"{world_motion.B.shape}")
        if prior_motion is not None:
            if self.integration != "spm":
                raise AttendInputError("prior_motion: moving the prior within the sample needs integration='spm'")
            prior_motion = vector(prior_motion, Q * self.model.n_causes, "prior_motion")
        self._y_t = y_t
        self._world_motion = world_motion
        self._prior_motion = prior_motion
        try:
            return self._advance(y_t, self._resolve_G(action_jacobian))
        finally:
            self._world_motion = None
            self._prior_motion = None

    @property
    def world_increment(self) -> np.ndarray | None:
        """The world's increment over the last step taken with ``world_motion`` (:meth:`step_generalised`): the
        change of the chosen states and their orders 0..p-1 (order-major; the first block is the states' own change);
        None after a step without it."""
        return None if self._world_increment is None else self._world_increment.copy()

    def _check_G(self, G, dead_columns: bool = True) -> np.ndarray:
        """dy~/da checked: shape, finite and (``dead_columns``) no all-zero column."""
        _, _, m, P, _ = self._sizes
        G = np.asarray(G, dtype=float)
        k = getattr(self, "n_actions", G.shape[1] if G.ndim == 2 else 0)
        if G.shape != (P * m, k):
            raise AttendInputError(f"action_jacobian: expected dy~/da of shape ((p + 1) m, k) = ({P * m}, {k}), "
                                   f"got {G.shape}")
        if not np.isfinite(G).all():
            raise AttendInputError("action_jacobian: expected finite values in dy~/da")
        dead = np.flatnonzero(~np.any(G != 0, axis=0)) if dead_columns else ()
        if len(dead):
            raise AttendInputError(f"action_jacobian: column {int(dead[0])} of dy~/da is zero: action a[{int(dead[0])}] "
                                   f"has no effect on any output at any of the p + 1 = {P} orders of motion; "
                                   "raise embedding_order or check which outputs the action moves")
        if self._orders is None:  # sensory_orders "relative_degree": fixed by the first dy~/da
            self._set_orders(relative_degrees(G, P))
        return G

    def _set_orders(self, orders: np.ndarray) -> None:
        """Fix the attended orders per output and the causal embedding: output i from a least-squares
        polynomial of degree orders[i] through its last W samples (W = orders[i] + 1 unless embedding_window)."""
        _, _, m, P, _ = self._sizes
        orders = np.asarray(orders, dtype=int)
        length = self._buffer_length
        full = np.zeros((P, m, length, m))
        for i, q in enumerate(orders):
            window = q + 1 if self.embedding_window is None else self.embedding_window
            if window < q + 1:
                raise AttendInputError(f"embedding_window: expected at least {q + 1} samples to embed output {i} up to "
                                       f"order {q}, got {window}")
            full[: q + 1, i, length - window:, i] = causal_embedding_weights(q + 1, window, self.dt)
        self._orders = orders
        self._embed_full = full.reshape(P * m, length * m)

    def _resolve_G(self, given) -> np.ndarray:
        if given is not None:
            if self._G_last is not None and given is self._G_last[0]:
                return self._G_last[1]
            # a Jacobian from the process may vanish for a while (a saturated actuator): only the first is
            # required to move some output
            checked = self._check_G(given, dead_columns=self._k == 0)
            self._G_last = (given, checked)
            return checked
        if self._G_fixed is not None:
            return self._G_fixed
        if self._G_source == "process":
            raise AttendInputError("action_jacobian: the controller takes dy~/da from the process; pass "
                                   "step(y, action_jacobian=...) each sample, use attend.control.run, or build the "
                                   "controller with a matrix")
        n, r, _, P, _ = self._sizes
        return self._check_G(self._G_source(self._Z[:n].copy(), self._Z[P * n: P * n + r].copy(), self.action),
                             dead_columns=self._k == 0)

    def _precision(self, x0, v0, t) -> np.ndarray:
        """Pi_z(t) (m, m): learned or model precision times the schedule's multiplier."""
        m = self._sizes[2]
        if self.precision_learning is not None:
            base = np.diag(np.exp(self._log_precision))
        else:
            base = self.model.sensor_precision_at(x0, v0)
            self._base_precision = (x0, v0, base)  # for the precision gradient at the same beliefs
        if self._multiplier is None:
            return base
        mult = np.asarray(self._multiplier(t), dtype=float).reshape(-1)
        if mult.size not in (1, m) or not np.isfinite(mult).all() or np.any(mult <= 0):
            raise AttendInputError(f"precision_schedule: expected a finite multiplier > 0 (1 or {m} values) at "
                                   f"t = {t:g} s, got {mult.tolist()}")
        root = np.sqrt(np.broadcast_to(mult, (m,)))
        return base * root[:, None] * root[None, :]

    def _advance(self, y_t: np.ndarray, G: np.ndarray) -> np.ndarray:
        n, r, m, P, Q = self._sizes
        t = self._k * self.dt
        eta = self.model.prior(t)
        self._last_prior = (t, eta)  # for :meth:`info`
        self._world_increment = None
        if self._fast and self._world_motion is None and self._prior_motion is None:
            Z = self._fast_step(G, y_t, eta)
        else:
            Z = self._general_step(G, y_t, eta, t)
        if self.action_limits is not None:  # np.clip's values, without its Python-level overhead
            action = Z[-self.n_actions:]
            np.minimum(np.maximum(action, self.action_limits[0], out=action), self.action_limits[1], out=action)
        if not np.abs(Z).max() <= self.divergence_limit:  # also catches NaN (a comparison with NaN is False)
            self._diverged(Z, t)
        self._Z = Z
        self._k += 1
        return Z[-self.n_actions:].copy()

    def _diverged(self, Z, t) -> None:
        precision = self._last_precision if self._last_precision is not None else np.eye(self._sizes[2])
        raise ClosedLoopDivergence(
            f"controller diverged at t = {t:g} s (|beliefs, action| reached {np.nanmax(np.abs(Z)):.3g} > "
            f"divergence_limit {self.divergence_limit:.3g}): action_gain kappa = {self.action_gain:g}, dt = {self.dt:g} s, "
            f"max sensor precision {np.max(np.diag(precision)):.3g}; lower action_gain or dt, or check the sign of "
            "dy~/da (action_jacobian)")

    @property
    def action_jacobian_source(self) -> str:
        """Where dy~/da comes from: "matrix" (given, constant), "function" (of the beliefs and the
        action, each sample) or "process" (the world's, which :func:`attend.control.run` passes
        each sample)."""
        if self._G_fixed is not None:
            return "matrix"
        return "process" if self._G_source == "process" else "function"

    def linear_update(self, process=None):
        """The agent's step as one constant linear map, or None where it is not one (a nonlinear
        or state-dependent model, learned or scheduled precision, dy~/da from a function):

            Z[k+1] = Phi Z[k] + Gamma_y y~[k] (+ the prior's constant term),
            y~[k] = embed @ (the last ``window`` samples of y, flattened oldest first).

        Returns (Phi, Gamma_y, embed, window). process: the world whose dy~/da at its initial
        state is used when the source is "process" (None: then no map is returned)."""
        if not self._fast or self.precision_learning is not None:
            return None
        if self._G_fixed is not None:
            G = self._G_fixed
        elif self._G_source == "process" and process is not None:
            P = self._sizes[3]
            G = self._check_G(process.action_jacobian(process.initial_states, np.zeros(process.n_actions), P - 1))
        else:
            return None
        _, Phi, Gamma_y, _, _, _ = self._fast_matrices(G)
        return Phi, Gamma_y, self._embed_full, self._buffer_length

    def _fast_matrices(self, G) -> tuple:
        """(G, Phi, Gamma_y, Gamma_eta, learned log-precision, precision) of the exact linear step
        Z+ = Phi Z + Gamma_y y~ + Gamma_eta eta~ at the current precision (no state changes)."""
        n, r, m, P, Q = self._sizes
        learning = self.precision_learning
        precision = self._precision(self._Z[:n], self._Z[P * n: P * n + r], 0.0)
        Pi_y = sensory_precision(self._S_by_order, self._orders, precision)
        Pi_a = Pi_y if self.action_precision is None else sensory_precision(self._S_by_order, self._orders,
                                                                           self.action_precision)
        E_y, E_x, E_v = self._E
        J, K_y, K_eta, curvature = joint_system(self._D, E_y, E_x, E_v, Pi_y, self._Pi_x, self._Pi_v, G, Pi_a,
                                                self.action_gain, self.action_prior_precision)
        # the offsets of a linear model vanish: flow(Z) = J Z + K_y (y~ - G a_k) + K_eta eta~
        if self.data_motion == "generalised":  # y~ and eta~ move by D within the sample (spm_DEM's D y)
            transition, integral, Gamma_y, Gamma_eta = moving_data_transition(J, K_y, K_eta, P, m, Q, r, self.dt)
        else:
            transition, integral = discrete_transition(J, self.dt)
            Gamma_y, Gamma_eta = integral @ K_y, integral @ K_eta
        Phi = transition.copy()
        Phi[:, -self.n_actions:] -= integral @ K_y @ G
        learned = None if learning is None else self._log_precision.copy()
        return G, Phi, Gamma_y, Gamma_eta, learned, precision

    def _fast_step(self, G, y_t, eta) -> np.ndarray:
        """Linear model, constant (or learned) precision: Z+ = Phi Z + Gamma_y y~ + Gamma_eta eta~. The matrices are
        cached per dy~/da and rebuilt when a learned log-precision has moved by more than ``rebuild_tolerance``."""
        cached = self._fast_cache.get(id(G))
        learning = self.precision_learning
        if cached is None or cached[0] is not G or (
                learning is not None and np.max(np.abs(self._log_precision - cached[4])) > learning.rebuild_tolerance):
            cached = self._fast_matrices(G)
            self._fast_cache = {id(G): cached}
            self._last_precision = cached[5]
        _, Phi, Gamma_y, Gamma_eta, _, _ = cached
        if learning is not None:  # the prediction error of this sample, before the step absorbs it
            n, r, m, P, Q = self._sizes
            A, B, C, Dm = self.model.matrices
            predicted = self._Z[: P * n].reshape(P, n) @ C.T
            if r:
                V = np.zeros((P, r))
                V[: min(P, Q)] = self._Z[P * n: P * n + Q * r].reshape(Q, r)[: min(P, Q)]
                predicted = predicted + V @ Dm.T
            self._learn(y_t - predicted.reshape(-1))
        return Phi @ self._Z + Gamma_y @ y_t + Gamma_eta @ eta

    def _general_step(self, G, y_t, eta, t) -> np.ndarray:
        """Re-linearise the joint flow at the beliefs (or reuse the last linearisation, ``jacobian_tolerance``) and
        integrate it over one sample: Z + (expm(J dt) - I) inv(J) flow(Z)."""
        n, r, m, P, Q = self._sizes
        model, Z, joint = self.model, self._Z, self._joint
        nX = P * n + Q * r
        x0, v0 = Z[:n], Z[P * n: P * n + r]
        if model.is_linear:
            A, B, C, Dm = model.matrices
            fx, fv, gx, gv = A, B, C, Dm
            f0, g0 = A @ x0 + B @ v0, C @ x0 + Dm @ v0
        else:  # shapes checked here; a non-finite Jacobian makes J non-finite, found by the exponential below
            fx, fv, gx, gv, f0, g0 = self._evaluate(x0, v0)
        precision = self._precision(x0, v0, t)
        self._last_precision = precision
        # reuse of the last sample's linearisation: same dy~/da and precision, Jacobians within jacobian_tolerance
        cached = self._general_cache
        tolerance = self.jacobian_tolerance
        reuse = (tolerance is not None and not self._moving_data and cached is not None and cached["G"] is G
                 and np.array_equal(cached["precision"], precision)
                 and all(np.abs(new - old).max(initial=0.0) <= tolerance * max(1.0, np.abs(old).max(initial=0.0))
                         for new, old in zip((fx, fv, gx, gv), cached["jacobians"])))
        if not reuse:  # the joint flow holds the last linearisation's F and Pi~ while it is reused
            # settings read every sample, as attributes that may be changed between steps
            if joint.gain != self.action_gain or joint.action_prior_precision != self.action_prior_precision:
                joint.set_action_gain(self.action_gain, self.action_prior_precision)
            joint.dt = self.dt
            joint.set_action_jacobian(G)  # every sample: a function may return its array changed in place
            last = self._joint_precision  # Pi~_y is rebuilt when Pi_z changes (the model's constant: never)
            if (last is None or self.action_precision is not self._joint_action_precision
                    or not (precision is model.sensor_precision and last is precision)
                    and not np.array_equal(precision, last)):
                Pi_y = sensory_precision(self._S_by_order, self._orders, precision)
                if self.action_precision is None:
                    Pi_a = None
                elif (self._joint_action_precision is self.action_precision and self._joint_Pi_a is not None
                      and self._joint_orders is self._orders):
                    Pi_a = self._joint_Pi_a  # a fixed action precision: its Pi~ is built once
                else:
                    Pi_a = sensory_precision(self._S_by_order, self._orders, self.action_precision)
                joint.set_sensory_precision(Pi_y, Pi_a)
                self._joint_Pi_a = Pi_a
                self._joint_orders = self._orders
                self._joint_action_precision = self.action_precision
                self._joint_precision = precision if precision is model.sensor_precision else precision.copy()
            if not model.is_linear:
                joint.set_jacobians(fx, fv, gx, gv)
            J = joint.linearise()
            if tolerance is not None:
                self._general_cache = dict(G=G, precision=precision, jacobians=(fx, fv, gx, gv), J=J.copy(),
                                           integral=None)
        flow = joint.flow(Z, y_t, eta, f0, g0)
        if self.precision_gradient and model.state_dependent_precision:
            flow[:nX] += self._precision_gradient(x0, v0, joint.errors[: P * m], t)
        if reuse:  # int_0^dt expm(J s) ds, computed at the first reuse of this J, then one product per sample
            if cached["integral"] is None:
                cached["integral"] = discrete_transition(cached["J"], self.dt)[1]
            Z = Z + cached["integral"] @ flow
        else:
            increment = (joint.moving_data_increment(flow, y_t, eta, self._world_motion, self._prior_motion)
                         if self._moving_data else joint.increment(flow))
            if self._world_motion is not None:
                self._world_increment = joint.world_increment
            if increment is None:  # J or the flow is not finite: name a non-finite Jacobian, else diverge
                model.jacobians(x0, v0)
                increment = np.full(Z.shape, np.nan)
            Z = Z + increment
        if self.precision_learning is not None:
            self._learn(joint.errors[: P * m])  # the prediction error before the step absorbed this sample
        return Z

    def _evaluate(self, x0: np.ndarray, v0: np.ndarray) -> tuple:
        """(fx, fv, gx, gv, f(x, v), g(x, v)) of the model at the order-0 beliefs (x0, v0), Jacobians checked for
        shape only. The last evaluation is kept: :meth:`info` after a step and the next step linearise at the same
        beliefs, so the model (and a finite-difference Jacobian) is evaluated once per sample."""
        model = self.model
        key = np.concatenate([x0, v0])
        cached = self._evaluation
        if cached is not None and np.array_equal(cached[0], key):
            return cached[1]
        fx, fv, gx, gv = model.jacobians(x0, v0, check_finite=False)
        f0 = np.asarray(model.f(x0, v0), dtype=float).reshape(-1)
        g0 = np.asarray(model.g(x0, v0), dtype=float).reshape(-1)
        values = (fx, fv, gx, gv, f0, g0)
        self._evaluation = (key, values)
        return values

    def _attended(self) -> np.ndarray:
        """Per output, the highest order of motion carrying sensory precision (all before the first dy~/da)."""
        _, _, m, P, _ = self._sizes
        return self._orders if self._orders is not None else np.full(m, P - 1)

    def _sensory_logdet(self, precision: np.ndarray) -> float:
        """log|Pi~_z| over the attended orders (kept for the last Pi_z: a constant one is summed once)."""
        if self._logdet is not None and self._logdet[0] is precision and self._logdet[2] is self._orders:
            return self._logdet[1]
        orders = self._attended()
        if _is_diagonal(precision):
            value = float(sum(self._S_logdet[q] + (q + 1) * math.log(precision[i, i]) for i, q in enumerate(orders)))
        else:
            q = int(orders.min())
            value = float(precision.shape[0] * self._S_logdet[q] + (q + 1) * np.linalg.slogdet(precision)[1])
        if precision is self.model.sensor_precision:  # the model's constant (never changed in place)
            self._logdet = (precision, value, self._orders)
        return value

    def _precision_gradient(self, x0, v0, e_y, t) -> np.ndarray:
        """d/d(x, v) at order 0 of (log|Pi~_z| - e_y' Pi~_z e_y) / 2 for a state-dependent Pi_z(x, v) (the
        log-determinant term is unchanged by the schedule's multiplier pi(t))::

            d/dz_j = sum_i (rho_i + 1) (dpi_i/dz_j) / pi_i / 2 - sum_i pi(t)_i (dpi_i/dz_j) e_i' S_(rho_i) e_i / 2

        for a diagonal Pi_z = diag(pi) (e_i: the attended orders rho_i of output i's error), and
        ((rho + 1) tr(Pi_z^-1 dPi_z/dz_j) - sum(dPi_z/dz_j * M * (E' S_rho E))) / 2 for a full one (M = root(pi(t))
        root(pi(t))', E the (P, m) errors, rho the lowest order). dPi_z/dz_j from the model's
        ``sensor_precision_gradient`` when it gives one, else by central differences of Pi_z (step eps^(1/3) max(1, |z_j|))."""
        n, r, m, P, Q = self._sizes
        model = self.model
        out = np.zeros(P * n + Q * r)
        known = self._base_precision  # Pi_z(x, v) of this sample's step (:meth:`_precision`)
        if known is not None and known[0] is x0 and known[1] is v0:
            precision = known[2]
        else:
            precision = model.sensor_precision_at(x0, v0)
        diagonal = _is_diagonal(precision)
        orders = self._attended()
        mult = (np.ones(m) if self._multiplier is None
                else np.broadcast_to(np.asarray(self._multiplier(t), dtype=float).reshape(-1), (m,)))
        errors = e_y.reshape(P, m)
        if diagonal:  # the quadratic form per output, and the log-determinant's weights, once per sample
            pi = np.diagonal(precision)
            quadratic = np.array([errors[:, i] @ self._S_by_order[orders[i]] @ errors[:, i] for i in range(m)])
            weights = 0.5 * (orders + 1) / pi - 0.5 * mult * quadratic  # d/dz_j = weights . dpi/dz_j
        else:
            rho = int(orders.min())
            root = np.sqrt(mult)
            inverse = np.linalg.inv(precision)
            # e' kron(S, dPi) e = sum(dPi * (E' S E)); the log-determinant's d/dz_j = (rho + 1) tr(Pi^-1 dPi) / 2
            weights = 0.5 * (rho + 1) * inverse.T - 0.5 * (errors.T @ self._S_by_order[rho] @ errors) * np.outer(root, root)
        derivatives = self._precision_derivatives(x0, v0, diagonal)  # (n + r, m) or (n + r, m, m)
        values = derivatives.reshape(n + r, -1) @ weights.reshape(-1)
        out[:n] = values[:n]
        out[P * n: P * n + r] = values[n:]
        return out

    def _precision_derivatives(self, x0, v0, diagonal: bool) -> np.ndarray:
        """dPi_z/dz_j for z = (x, v) at order 0: rows j of d diag(Pi_z) ((n + r, m), ``diagonal``) or of dPi_z
        ((n + r, m, m)); from the model's ``sensor_precision_gradient`` (diagonal) or central differences."""
        n, r, m = self._sizes[:3]
        model = self.model
        if diagonal and model.sensor_precision_gradient is not None:
            return model.sensor_precision_derivatives(x0, v0)
        point = np.concatenate([x0, v0])
        steps = np.cbrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(point))
        out = np.empty((n + r, m) if diagonal else (n + r, m, m))
        for j, h in enumerate(steps):
            up, down = point.copy(), point.copy()
            up[j] += h
            down[j] -= h
            dPi = (model.sensor_precision_at(up[:n], up[n:]) - model.sensor_precision_at(down[:n], down[n:])) / (2 * h)
            out[j] = np.diagonal(dPi) if diagonal else dPi
        return out

    def _learn(self, e_y: np.ndarray) -> None:
        """One online update of the sensory log-precisions from the sensory prediction error e_y ((p + 1) m,) of
        this sample before the D-step (see :class:`SensorPrecisionLearning`)."""
        n, r, m, P, Q = self._sizes
        learning = self.precision_learning
        e = e_y.reshape(P, m)
        if learning.orders == "value":
            counts = np.ones(m)
            q_now = e[0] ** 2
        else:
            orders = self._attended()
            counts = (orders + 1).astype(float)
            q_now = np.array([e[:, i] @ self._S_by_order[orders[i]] @ e[:, i] for i in range(m)])
        beta = min(1.0, self.dt / learning.time_constant)
        if self._q is None:
            self._q = counts / np.exp(self._log_precision)
        self._q = (1 - beta) * self._q + beta * q_now
        n_eff = learning.time_constant / self.dt
        lam, prior, Pl = self._log_precision, self._prior_log_precision, learning.hyperprior_precision
        for _ in range(3):
            grad = 0.5 * n_eff * (counts - np.exp(lam) * self._q) - Pl * (lam - prior)
            hess = -0.5 * n_eff * np.exp(lam) * self._q - Pl
            lam = np.clip(lam - grad / hess, prior - learning.bounds, prior + learning.bounds)
        if learning.level == "relative":  # keep sum(pi): learn each sensor's share of the designed total
            if learning.groups is None:
                lam = lam + math.log(np.exp(prior).sum() / np.exp(lam).sum())
            else:
                labels = np.asarray(learning.groups)
                for label in np.unique(labels):
                    members = labels == label
                    lam[members] += math.log(np.exp(prior[members]).sum() / np.exp(lam[members]).sum())
        self._log_precision = lam

    # --- reporting --------------------------------------------------------------------------

    def info(self) -> StepInfo:
        """The agent now (after the last step): action, beliefs, order-0 sensory error, Pi_z and free energy."""
        n, r, m, P, Q = self._sizes
        model, Z = self.model, self._Z
        nX = P * n + Q * r
        x_t, v_t = Z[: P * n], Z[P * n: nX]
        x0, v0 = x_t[:n], v_t[:r]
        t = max(self._k - 1, 0) * self.dt
        fx, fv, gx, gv, f0, g0 = self._evaluate(x0, v0)
        if not math.isfinite(float(fx.sum()) + float(fv.sum()) + float(gx.sum()) + float(gv.sum())):
            model.jacobians(x0, v0)  # names the non-finite Jacobian
        eta = self._last_prior[1] if self._last_prior is not None and self._last_prior[0] == t else model.prior(t)
        e_y, e_x, e_v = generalised_errors(x_t, v_t, self._y_t, eta, f0, g0, fx, fv, gx, gv, P, Q)
        if not self.top_motion_error:
            e_x[(P - 1) * n:] = 0.0
        precision = self._last_precision if self._last_precision is not None else self._precision(x0, v0, t)
        joint_precision = self._joint_precision
        if (not self._fast and joint_precision is not None and self._joint_action_precision is self.action_precision
                and (precision is joint_precision or np.array_equal(precision, joint_precision))):
            Pi_y = self._joint.Pi[: P * m, : P * m]  # the step's Pi~_z at this Pi_z, already built
        else:
            Pi_y = sensory_precision(self._S_by_order, self._attended(), precision)
        quadratic = e_y @ Pi_y @ e_y + e_x @ self._Pi_x @ e_x + e_v @ self._Pi_v @ e_v
        if self._Pi_u is not None:
            quadratic += Z[:nX] @ self._Pi_u @ Z[:nX]
        free_energy = -0.5 * quadratic + 0.5 * (self._sensory_logdet(precision) + self._logdet_fixed)
        return StepInfo(t, Z[nX:].copy(), x0.copy(), v0.copy(), e_y[:m].copy(), np.diag(precision).copy(),
                        float(free_energy))


def _is_diagonal(matrix: np.ndarray) -> bool:
    return not np.any(matrix - np.diag(np.diagonal(matrix)))


def _is_constant_schedule(schedule) -> bool:
    from attend.rhythm import FixedSchedule

    return isinstance(schedule, FixedSchedule)

