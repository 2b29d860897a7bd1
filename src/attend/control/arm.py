"""A two-link planar arm in the vertical plane, driven by joint torques, for control benchmarks.

Joint angles q = (q1, q2): q1 of the upper arm from the horizontal, counter-clockwise; q2 of the
forearm relative to the upper arm (q = (-pi/2, 0): hanging straight down). Gravity acts along -y.
The rigid-body dynamics (e.g. Spong, Hutchinson and Vidyasagar, *Robot Modeling and Control*, ch. 7)::

    M(q) q'' + C(q, q') q' + g(q) = tau + tau_d(t) - B q'

    M11 = m1 lc1^2 + I1 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2) + I2
    M12 = M21 = m2 (lc2^2 + l1 lc2 cos q2) + I2,     M22 = m2 lc2^2 + I2
    C   = h [[-q2', -(q1' + q2')], [q1', 0]],          h = m2 l1 lc2 sin q2
    g   = gravity [(m1 lc1 + m2 l1) cos q1 + m2 lc2 cos(q1 + q2),  m2 lc2 cos(q1 + q2)]

m_i link masses [kg], l_i link lengths [m], lc_i distances from joint i to the link's centre of
mass [m], I_i inertias about the centre of mass [kg m^2], B = diag(b1, b2) viscous joint friction
[N m s/rad] (:class:`ArmParameters`). g = dV/dq for the potential energy
V = gravity (m1 lc1 sin q1 + m2 (l1 sin q1 + lc2 sin(q1 + q2))), and M' - 2 C is skew-symmetric, so
without torque and friction the energy q' M q' / 2 + V is conserved (the tests check both).

The plant (:func:`arm_plant`) is an :class:`attend.control.GenerativeProcess` with states
x = (q1, q2, q1', q2') [rad, rad/s], actions tau (2,) [N m] saturating at ``torque_limits``, a coloured
torque disturbance tau_d on each joint (the process's ``action_noise_std``: it enters where the
torque does, through M(q)^-1), and ``sensors_per_joint`` joint-angle sensors per joint with coloured
noise, outputs ordered sensor-major (y = [q1, q2] of sensor 1, then of sensor 2, ...).

Building blocks for controllers of the arm, each on a model of it (possibly wrong):
:class:`ArmActionJacobian` (dy~/da for :class:`attend.control.ActiveInferenceController`),
:class:`GravityFeedforward` (adds g^(q) at the angles a controller believes or measures),
:func:`joint_pid` (a PID per joint with gravity feed-forward), :class:`ArmLQG` (LQG with integral
action on the arm linearised about a pose at rest).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Callable

import numpy as np

from attend._validation import AttendInputError, number, positive_scalar
from attend.control._checks import count, vector


@dataclass(frozen=True)
class ArmParameters:
    """The arm: link_masses (m1, m2) [kg]; link_lengths (l1, l2) [m]; com_distances (lc1, lc2) [m] from each
    joint to its link's centre of mass; link_inertias (I1, I2) [kg m^2] about the centres of mass;
    joint_friction (b1, b2) [N m s/rad] viscous; gravity [m/s^2] (0: a horizontal arm).

    Defaults: a small lab arm, links of 0.5 and 0.4 m and 2.0 and 1.2 kg, uniform rods (lc = l/2,
    I = m l^2 / 12), friction 0.1 and 0.05 N m s/rad. Each link needs inertia about its joint
    (m_i lc_i^2 + I_i > 0), which makes M(q) positive definite at every q.
    """

    link_masses: tuple = (2.0, 1.2)
    link_lengths: tuple = (0.5, 0.4)
    com_distances: tuple = (0.25, 0.2)
    link_inertias: tuple = (2.0 * 0.5**2 / 12.0, 1.2 * 0.4**2 / 12.0)
    joint_friction: tuple = (0.1, 0.05)
    gravity: float = 9.81

    def __post_init__(self) -> None:
        rules = (("link_masses", "masses > 0 [kg]", False), ("link_lengths", "lengths > 0 [m]", False),
                 ("com_distances", "distances >= 0 [m]", True), ("link_inertias", "inertias >= 0 [kg m^2]", True),
                 ("joint_friction", "friction coefficients >= 0 [N m s/rad]", True))
        for name, what, zero_allowed in rules:
            value = vector(getattr(self, name), 2, name, what)
            if np.any(value < 0) or (not zero_allowed and np.any(value == 0)):
                raise AttendInputError(f"{name}: expected 2 {what}, got {value.tolist()}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        gravity = number(self.gravity, "gravity")
        if not math.isfinite(gravity) or gravity < 0:
            raise AttendInputError(f"gravity: expected a finite number >= 0 [m/s^2], got {self.gravity!r}")
        object.__setattr__(self, "gravity", gravity)
        for i in range(2):
            if self.link_masses[i] * self.com_distances[i] ** 2 + self.link_inertias[i] <= 0:
                j = i + 1
                raise AttendInputError(f"link_inertias: link {j} has no inertia about its joint (m{j} lc{j}^2 + I{j} = "
                                       f"0); give I{j} > 0 or com_distances[{i}] > 0")

    def scaled(self, **factors) -> "ArmParameters":
        """A copy with fields multiplied: ``factors`` maps a field name (link_masses, ..., gravity) to a number or
        a pair (one factor per link), e.g. ``scaled(link_masses=1.3, link_inertias=1.3)`` (a heavier arm)."""
        names = {f.name for f in fields(self)}
        changed = {}
        for name, factor in factors.items():
            if name not in names:
                raise AttendInputError(f"{name}: not a field of ArmParameters (expected one of "
                                       f"{', '.join(sorted(names))})")
            if name == "gravity":
                changed[name] = self.gravity * number(factor, name)
            else:
                changed[name] = tuple(np.asarray(getattr(self, name)) * vector(factor, 2, name, "factors"))
        return ArmParameters(**{**{f.name: getattr(self, f.name) for f in fields(self)}, **changed})

    def _constants(self) -> tuple:
        """(a, b, d, g1, g2, b1, b2): M11 = a + 2 b cos q2, M12 = d + b cos q2, M22 = d; gravity torques
        g1 cos q1 + g2 cos(q1 + q2) and g2 cos(q1 + q2); friction b1, b2."""
        (m1, m2), (c1, c2), (i1, i2) = self.link_masses, self.com_distances, self.link_inertias
        l1 = self.link_lengths[0]
        d = m2 * c2**2 + i2
        a = m1 * c1**2 + i1 + m2 * l1**2 + d
        return (a, m2 * l1 * c2, d, self.gravity * (m1 * c1 + m2 * l1), self.gravity * m2 * c2) + self.joint_friction


# --- the dynamics: pure functions of (parameters, arrays) ----------------------------------------

def _pair(value, field: str) -> np.ndarray:
    return vector(value, 2, field)


def mass_matrix(params: ArmParameters, angles) -> np.ndarray:
    """M(q) (2, 2) [kg m^2] of the arm ``params`` at the joint angles q = ``angles`` (2,) [rad]."""
    q = _pair(angles, "angles")
    a, b, d = params._constants()[:3]
    c2 = math.cos(q[1])
    return np.array([[a + 2 * b * c2, d + b * c2], [d + b * c2, d]])


def coriolis_matrix(params: ArmParameters, angles, velocities) -> np.ndarray:
    """C(q, q') (2, 2) [kg m^2 / s] of the arm ``params`` (Christoffel form: M' - 2 C is skew-symmetric); angles q
    [rad], velocities q' [rad/s], each (2,)."""
    q, w = _pair(angles, "angles"), _pair(velocities, "velocities")
    h = params._constants()[1] * math.sin(q[1])
    return np.array([[-h * w[1], -h * (w[0] + w[1])], [h * w[0], 0.0]])


def gravity_torque(params: ArmParameters, angles) -> np.ndarray:
    """g(q) (2,) [N m]: the torques that hold the arm ``params`` still at the angles q = ``angles`` (2,) [rad]."""
    q = _pair(angles, "angles")
    g1, g2 = params._constants()[3:5]
    c12 = math.cos(q[0] + q[1])
    return np.array([g1 * math.cos(q[0]) + g2 * c12, g2 * c12])


def potential_energy(params: ArmParameters, angles) -> float:
    """V(q) [J] of the arm ``params``, zero with both links horizontal (angles q (2,) [rad]); g(q) = dV/dq."""
    q = _pair(angles, "angles")
    g1, g2 = params._constants()[3:5]
    return float(g1 * math.sin(q[0]) + g2 * math.sin(q[0] + q[1]))


def energy(params: ArmParameters, angles, velocities) -> float:
    """q' M(q) q' / 2 + V(q) [J] of the arm ``params``: conserved by the unforced arm without friction (angles [rad],
    velocities [rad/s])."""
    w = _pair(velocities, "velocities")
    return float(0.5 * w @ mass_matrix(params, angles) @ w) + potential_energy(params, angles)


def _acceleration(constants: tuple, q1: float, q2: float, w1: float, w2: float, t1: float, t2: float):
    """q'' = M^-1 (tau - C q' - g - B q') from floats (the plant's inner loop: no arrays, no checks)."""
    a, b, d, g1, g2, b1, b2 = constants
    c2, s2 = math.cos(q2), math.sin(q2)
    m11, m12 = a + 2 * b * c2, d + b * c2
    h = b * s2
    c12 = math.cos(q1 + q2)
    r1 = t1 + h * (2 * w1 * w2 + w2 * w2) - g1 * math.cos(q1) - g2 * c12 - b1 * w1
    r2 = t2 - h * w1 * w1 - g2 * c12 - b2 * w2
    det = m11 * d - m12 * m12
    return (d * r1 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det


def forward_dynamics(params: ArmParameters, angles, velocities, torques) -> np.ndarray:
    """q'' (2,) [rad/s^2] = M^-1 (tau - C q' - g - B q') of the arm ``params`` at angles q [rad], velocities q' [rad/s]
    and joint torques tau [N m], each (2,)."""
    q, w, t = _pair(angles, "angles"), _pair(velocities, "velocities"), _pair(torques, "torques")
    return np.array(_acceleration(params._constants(), q[0], q[1], w[0], w[1], t[0], t[1]))


def inverse_dynamics(params: ArmParameters, angles, velocities, accelerations) -> np.ndarray:
    """tau (2,) [N m] = M q'' + C q' + g + B q' of the arm ``params``: the torques that give the accelerations
    q'' [rad/s^2] at angles q [rad] and velocities q' [rad/s] (each (2,)); at rest (q' = q'' = 0) the gravity
    torque g(q)."""
    w, acc = _pair(velocities, "velocities"), _pair(accelerations, "accelerations")
    return (mass_matrix(params, angles) @ acc + coriolis_matrix(params, angles, w) @ w + gravity_torque(params, angles)
            + np.asarray(params.joint_friction) * w)


def state_jacobians(params: ArmParameters, states, torques) -> tuple[np.ndarray, np.ndarray]:
    """(df/dx (4, 4), df/dtau (4, 2)) of f(x, tau) = (q', q'') of the arm ``params`` at the states
    x = (q1, q2, q1', q2') [rad, rad/s] and torques tau (2,) [N m], in closed form::

        dq''/dq  = -M^-1 (dM/dq q'' + d(C q')/dq + dg/dq),   dq''/dq' = -M^-1 (d(C q')/dq' + B),   dq''/dtau = M^-1
    """
    x, t = vector(states, 4, "states"), _pair(torques, "torques")
    a, b, d, g1, g2, b1, b2 = constants = params._constants()
    q1, q2, w1, w2 = x
    acc = np.array(_acceleration(constants, q1, q2, w1, w2, t[0], t[1]))
    c2, s2 = math.cos(q2), math.sin(q2)
    s1, s12 = math.sin(q1), math.sin(q1 + q2)
    M = np.array([[a + 2 * b * c2, d + b * c2], [d + b * c2, d]])
    Minv = np.linalg.inv(M)
    dM_dq2 = np.array([[-2 * b * s2, -b * s2], [-b * s2, 0.0]])
    # Coriolis and centrifugal torques C q' = b sin q2 [-(2 w1 w2 + w2^2), w1^2]
    dh_dq2 = b * c2 * np.array([-(2 * w1 * w2 + w2 * w2), w1 * w1])
    dh_dw = b * s2 * np.array([[-2 * w2, -2 * (w1 + w2)], [2 * w1, 0.0]])
    dg_dq = -np.array([[g1 * s1 + g2 * s12, g2 * s12], [g2 * s12, g2 * s12]])
    d_dq = dg_dq.copy()
    d_dq[:, 1] += dM_dq2 @ acc + dh_dq2
    fx = np.zeros((4, 4))
    fx[0, 2] = fx[1, 3] = 1.0
    fx[2:, :2] = -Minv @ d_dq
    fx[2:, 2:] = -Minv @ (dh_dw + np.diag([b1, b2]))
    fa = np.zeros((4, 2))
    fa[2:] = Minv
    return fx, fa


def linearise(params: ArmParameters, angles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (4, 4), B (4, 2), tau_0 (2,)): the arm ``params`` at rest at the angles q_0 = ``angles`` [rad], held by
    tau_0 = g(q_0): d(dx)/dt = A dx + B (tau - tau_0) for dx = x - (q_0, 0)."""
    q = _pair(angles, "angles")
    holding = gravity_torque(params, q)
    A, B = state_jacobians(params, np.concatenate([q, [0.0, 0.0]]), holding)
    return A, B, holding


def sensor_matrix(sensors_per_joint: int = 2) -> np.ndarray:
    """C (2 s, 4): s = ``sensors_per_joint`` angle sensors per joint, sensor-major rows [q1, q2, q1, q2, ...]."""
    s = count(sensors_per_joint, "sensors_per_joint", 1)
    return np.tile(np.hstack([np.eye(2), np.zeros((2, 2))]), (s, 1))


# --- the plant -------------------------------------------------------------------------------------

def arm_plant(params: ArmParameters | None = None, *, initial_angles=(-math.pi / 2, 0.0), initial_velocities=(0.0, 0.0),
              torque_noise_std=0.0, torque_kernel_width: float = 0.0, sensor_std=0.0, sensor_kernel_width: float = 0.0,
              sensors_per_joint: int = 2, torque_limits=None, sensor_noise_scale=None, substeps: int = 2):
    """The arm as an :class:`attend.control.GenerativeProcess`: states (q1, q2, q1', q2') [rad, rad/s], actions
    tau (2,) [N m], ``sensors_per_joint`` angle sensors per joint (outputs sensor-major, :func:`sensor_matrix`).

    params: :class:`ArmParameters` (default: the small lab arm); initial_angles [rad], initial_velocities
    [rad/s]: x(0) (default hanging at rest); torque_noise_std [N m] (a number or one per joint),
    torque_kernel_width [s]: the coloured torque disturbance tau_d; sensor_std [rad] (a number or one per
    output), sensor_kernel_width [s]: each sensor's coloured noise; torque_limits: None or |tau_i| <= limit
    (a number or one per joint) [N m]; sensor_noise_scale: optional sigma_z(t) -> scalar or (2 s,) multiplying
    the sensor noise (a sensor that degrades); substeps: Runge-Kutta 4 steps per sample."""
    from attend.control.process import GenerativeProcess

    params = ArmParameters() if params is None else params
    if not isinstance(params, ArmParameters):
        raise AttendInputError(f"params: expected attend.control.arm.ArmParameters, got {type(params).__name__}")
    start = np.concatenate([_pair(initial_angles, "initial_angles"), _pair(initial_velocities, "initial_velocities")])
    C = sensor_matrix(sensors_per_joint)
    limits = None
    if torque_limits is not None:
        high = vector(torque_limits, 2, "torque_limits", "limits [N m]")
        if np.any(high <= 0):
            raise AttendInputError(f"torque_limits: expected limits > 0 [N m], got {high.tolist()}")
        limits = (-high, high)
    constants = params._constants()
    zeros = np.zeros((C.shape[0], 2))

    def f(x, tau):
        q1, q2, w1, w2 = x
        acc1, acc2 = _acceleration(constants, q1, q2, w1, w2, tau[0], tau[1])
        return np.array([w1, w2, acc1, acc2])

    return GenerativeProcess(
        f=f, g=lambda x, tau: C @ x, n_states=4, n_actions=2, n_outputs=C.shape[0], initial_states=start,
        action_noise_std=torque_noise_std, action_kernel_width=torque_kernel_width, sensor_noise_std=sensor_std,
        sensor_kernel_width=sensor_kernel_width, action_limits=limits, sensor_noise_scale=sensor_noise_scale,
        jacobian_f=lambda x, tau: state_jacobians(params, x, tau), jacobian_g=lambda x, tau: (C, zeros),
        substeps=substeps)


# --- controllers' building blocks --------------------------------------------------------------------

def _joint_means(y: np.ndarray) -> np.ndarray:
    """(q1, q2) as the mean of each joint's sensors (outputs sensor-major)."""
    return np.asarray(y, dtype=float).reshape(-1, 2).mean(axis=0)


class ArmActionJacobian:
    """dy~/da of the arm from a model of it, for ``ActiveInferenceController(action_jacobian=...)``: a function
    (x, v, a) -> ((p + 1) 2 s, 2) of the agent's beliefs x = (q, q') (the Markov parameters of the model's
    linearisation at x; for angle sensors and p = 2: zeros at orders 0 and 1, M^-1(q) at order 2).

    params: the agent's :class:`ArmParameters` (possibly wrong); embedding_order: p; sensors_per_joint: s;
    tolerance: the same array is returned (so the controller keeps its cached transition) until dy~/da
    has moved by more than this fraction of its largest entry since it was last refreshed (0: every
    change refreshes it); hold: tau >= 0 [s], 0 (default) for the instantaneous Markov parameters, or the
    sample time for the response at the end of a torque held over one sample (:func:`markov_parameters`'s
    ``hold``: about M^-1 tau^2 / 2, M^-1 tau and M^-1 at orders 0, 1 and 2)."""

    def __init__(self, params: ArmParameters, embedding_order: int = 2, sensors_per_joint: int = 2,
                 tolerance: float = 0.02, hold: float = 0.0):
        from attend._validation import order

        if not isinstance(params, ArmParameters):
            raise AttendInputError(f"params: expected attend.control.arm.ArmParameters, got {type(params).__name__}")
        self.params = params
        self.embedding_order = order(embedding_order, "embedding_order", 12)
        self._C = sensor_matrix(sensors_per_joint)
        tolerance = number(tolerance, "tolerance")
        if not math.isfinite(tolerance) or tolerance < 0:
            raise AttendInputError(f"tolerance: expected a finite number >= 0, got {tolerance!r}")
        self.tolerance = tolerance
        hold = number(hold, "hold")
        if not math.isfinite(hold) or hold < 0:
            raise AttendInputError(f"hold: expected a finite time >= 0 (s), got {hold!r}")
        self.hold = hold
        self._constants = (params, params._constants())
        self._sensors = self._C.shape[0] // 2
        self._workspace: dict = {}
        self._last = None
        self._scale = 0.0
        self.refreshes = 0

    def __call__(self, x, v, a) -> np.ndarray:
        G = self._column(x)
        last = self._last
        if last is not None and np.abs(G - last).max() <= self.tolerance * self._scale:
            return last
        self._last = G
        self._scale = np.abs(G).max()
        self.refreshes += 1
        return G

    def _column(self, x) -> np.ndarray:
        """dy~/da at the beliefs x (no caching): the arm's Jacobians in closed form (:func:`_jacobian_blocks`) and,
        with a hold, the held column by :func:`_held_integral`; equal to ``markov_parameters(*state_jacobians(params,
        x, g(q)), C, 0, p + 1, hold)`` up to rounding (tests/control/test_arm.py)."""
        from attend.control.process import markov_parameters

        values = np.asarray(x, dtype=float).reshape(-1).tolist()
        if len(values) != 4:
            raise AttendInputError(f"states: expected 4 values (q1, q2, q1', q2') [rad, rad/s], got {len(values)}")
        q1, q2, w1, w2 = values
        if self._constants[0] is not self.params:  # params is an attribute: follow it if it is replaced
            self._constants = (self.params, self.params._constants())
        K, D, Minv = _jacobian_blocks(self._constants[1], q1, q2, w1, w2)
        fx = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [K[0], K[1], D[0], D[1]],
                       [K[2], K[3], D[2], D[3]]])
        fa = np.array([[0.0, 0.0], [0.0, 0.0], [Minv[0], Minv[1]], [Minv[2], Minv[3]]])
        hold, P = self.hold, self.embedding_order + 1
        # |f_x tau|_1, summed as numpy sums the columns of f_x tau (the series' length depends on it)
        size = max(abs(K[0] * hold) + abs(K[2] * hold), abs(K[1] * hold) + abs(K[3] * hold),
                   (hold + abs(D[0] * hold)) + abs(D[2] * hold), (hold + abs(D[1] * hold)) + abs(D[3] * hold))
        if hold == 0.0 or size > 1.0:  # the instantaneous column, or a long hold: the general path
            return markov_parameters(fx, fa, self._C, np.zeros((self._C.shape[0], 2)), P, hold=hold)
        integral = _held_integral(fx, fa, hold, size, self._workspace)
        # g_x = [I 0] per sensor and f_x = [[0, I], [K, D]]: order 0 is the top of Gamma f_a, order 1 the top of
        # expm(f_x tau) f_a = f_a + f_x Gamma f_a, which is the bottom of Gamma f_a, and order i >= 2 the bottom of
        # f_x^(i - 2) expm(f_x tau) f_a
        out = np.empty((P, self._sensors, 2, 2))
        out[0] = integral[:2]  # each order's block repeated for every sensor (C = [I 0] per sensor)
        if P > 1:
            out[1] = integral[2:]
        column = integral
        for order in range(2, P):
            column = fa + fx @ column if order == 2 else fx @ column
            out[order] = column[2:]
        return out.reshape(P * 2 * self._sensors, 2)


def _jacobian_blocks(constants: tuple, q1: float, q2: float, w1: float, w2: float) -> tuple:
    """(K, D, M^-1), each a 2 x 2 matrix as 4 floats row by row, of the arm (``ArmParameters._constants()``) at
    x = (q1, q2, w1, w2) held by its gravity torque: f_x = [[0, I], [K, D]], f_a = [0; M^-1] (:func:`state_jacobians`
    at tau = g(q), written out in floats; M^-1 from the adjugate)."""
    a, b, d, g1, g2, b1, b2 = constants
    c2, s2 = math.cos(q2), math.sin(q2)
    s1, s12, c12 = math.sin(q1), math.sin(q1 + q2), math.cos(q1 + q2)
    acc1, acc2 = _acceleration(constants, q1, q2, w1, w2, g1 * math.cos(q1) + g2 * c12, g2 * c12)
    m11, m12 = a + 2 * b * c2, d + b * c2
    det = m11 * d - m12 * m12
    i11, i12, i22 = d / det, -m12 / det, m11 / det
    # d(M q'' + C q' + g)/dq at q'' = acc (only M and C q' depend on q2)
    bs2, bc2 = b * s2, b * c2
    p00, p10 = -(g1 * s1 + g2 * s12), -(g2 * s12)
    p01 = p10 + (-2 * bs2 * acc1 + -bs2 * acc2 + bc2 * -(2 * w1 * w2 + w2 * w2))
    p11 = p10 + (-bs2 * acc1 + bc2 * (w1 * w1))
    # d(C q')/dq' + B
    r00, r01, r10, r11 = bs2 * (-2 * w2) + b1, bs2 * (-2 * (w1 + w2)), bs2 * (2 * w1), b2
    K = (-(i11 * p00 + i12 * p10), -(i11 * p01 + i12 * p11), -(i12 * p00 + i22 * p10), -(i12 * p01 + i22 * p11))
    D = (-(i11 * r00 + i12 * r10), -(i11 * r01 + i12 * r11), -(i12 * r00 + i22 * r10), -(i12 * r01 + i22 * r11))
    return K, D, (i11, i12, i12, i22)


def _held_integral(fx: np.ndarray, fa: np.ndarray, hold: float, size: float, workspace: dict) -> np.ndarray:
    """Gamma(tau) f_a = tau sum_{j <= J} (f_x tau)^j f_a / (j + 1)! for |f_x tau|_1 = ``size`` <= 1, J the first j whose
    bound size^j / (j + 1)! is below 2^-53 (the series and truncation of :func:`markov_parameters`'s hold, there summed
    by Horner's rule). The Krylov columns (f_x tau)^j f_a, j < 2^L, come from L doublings, V[c:2c] = X^c V[:c] with
    X^c by squaring, and one product with the weights tau / (j + 1)!: about 2 L + 1 small array operations against 3
    per term. ``workspace`` holds the columns' array and the weights per J."""
    terms, bound = 0, 1.0
    while bound > 2.0**-53 and terms < 30:
        terms += 1
        bound *= size / (terms + 1)
    n, k = fa.shape
    columns = workspace.get("columns")
    if columns is None or columns.shape[1:] != (n, k):
        columns = workspace["columns"] = np.empty((32, n, k))
    columns[0] = fa
    X, count = fx * hold, 1
    while True:
        np.matmul(X, columns[:count], out=columns[count: 2 * count])
        count *= 2
        if count > terms:
            break
        X = X @ X
    weight = workspace.get(terms)
    if weight is None:
        weight = workspace[terms] = np.array([hold / math.factorial(j + 1) for j in range(terms + 1)])
    return (weight @ columns[: terms + 1].reshape(terms + 1, n * k)).reshape(n, k)


class GravityFeedforward:
    """A controller plus the gravity torque of a model of the arm: a = controller.step(y) + g^(q).

    controller: any controller of the arm (``dt``, ``n_actions`` = 2, ``step(y)``, ``reset()``); params: the
    :class:`ArmParameters` of g^ (possibly wrong); angles: where q comes from: "believed" (the active
    inference controller's beliefs after its step, ``controller.states[:2]``) or "measured" (the mean of
    each joint's sensors)."""

    def __init__(self, controller, params: ArmParameters, angles: str = "measured"):
        if angles not in ("believed", "measured"):
            raise AttendInputError(f"angles: expected 'believed' or 'measured', got {angles!r}")
        if not isinstance(params, ArmParameters):
            raise AttendInputError(f"params: expected attend.control.arm.ArmParameters, got {type(params).__name__}")
        self.controller, self.params, self.angles = controller, params, angles
        self._constants = (params, params._constants())
        self.dt, self.n_actions = controller.dt, controller.n_actions

    def reset(self) -> None:
        """Reset the wrapped controller."""
        if hasattr(self.controller, "reset"):
            self.controller.reset()

    def step(self, y) -> np.ndarray:
        """Take y[k] (2 s,), return the torques a[k] (2,) [N m]."""
        action = np.asarray(self.controller.step(y), dtype=float)
        q = self.controller.states[:2] if self.angles == "believed" else _joint_means(y)
        if self._constants[0] is not self.params:
            self._constants = (self.params, self.params._constants())
        g1, g2 = self._constants[1][3:5]
        q1, q2 = q.tolist()
        c12 = math.cos(q1 + q2)  # gravity_torque(params, q) without its input checks
        return action + np.array([g1 * math.cos(q1) + g2 * c12, g2 * c12])


def joint_pid(params: ArmParameters, dt: float, *, gains, reference, sensors_per_joint: int = 2, torque_limits=None):
    """A PID per joint on the mean of its sensors with gravity feed-forward g^(q measured) inside the saturation (so
    that the integrator stops at the true limit): an object with ``dt``, ``n_actions``, ``reset()``, ``step(y)``.

    params: the model for g^; dt [s]; gains: per joint (kp, ki, kd, tau_d) [N m/rad, N m/(rad s), N m s/rad, s],
    a (2, 4) array; reference: r(t) -> (2,) [rad] or two numbers; sensors_per_joint: angle sensors per joint
    (outputs sensor-major); torque_limits: None or per joint [N m]."""
    from attend.control.baselines import PIDController

    gains = np.asarray(gains, dtype=float)
    if gains.shape != (2, 4) or not np.isfinite(gains).all():
        raise AttendInputError(f"gains: expected a (2, 4) array of finite (kp, ki, kd, tau_d) per joint, got shape "
                               f"{gains.shape}")
    m = 2 * count(sensors_per_joint, "sensors_per_joint", 1)
    target = reference if callable(reference) else (lambda t, r=_pair(reference, "reference"): r)
    limits = None if torque_limits is None else vector(torque_limits, 2, "torque_limits")
    joints = []
    for i in range(2):
        weights = np.zeros(m)
        weights[i::2] = 1.0 / (m // 2)
        joints.append(PIDController(
            *gains[i, :3], dt, reference=lambda t, i=i: float(target(t)[i]), n_outputs=m, output_weights=weights,
            derivative_filter=gains[i, 3], action_limits=None if limits is None else (-limits[i], limits[i]),
            feedforward=lambda t, y, i=i: float(gravity_torque(params, _joint_means(y))[i])))
    return _Joints(joints, dt)


class _Joints:
    """Independent single-action controllers, one per joint, as one controller of 2 actions."""

    def __init__(self, joints, dt):
        self.joints, self.dt, self.n_actions = joints, dt, len(joints)

    def reset(self) -> None:
        for joint in self.joints:
            joint.reset()

    def step(self, y) -> np.ndarray:
        return np.concatenate([joint.step(y) for joint in self.joints])


class ArmLQG:
    """LQG with integral action (:class:`attend.control.LQGController`) on a model of the arm linearised at rest at
    the pose q_o (``operating_angles``), held by tau_o = g^(q_o): the filter and the regulator work on
    dx = x - (q_o, 0) and da = tau - tau_o.

    params: the model (possibly wrong); dt [s]; operating_angles q_o (2,) [rad]; reference: r(t) -> (2,) or two
    numbers [rad]; reference_trajectory: optional function t -> (q_r (2,), q_r' (2,), q_r'' (2,)) [rad, rad/s,
    rad/s^2]: the regulator follows x_r = (q_r, q_r') with the model's inverse dynamics tau_r as feed-forward;
    initial_angles: the estimate's q at t = 0 (default q_o; velocity 0); sensors_per_joint; state_weight
    (4,) or number, integral_weight, action_weight, process_covariance, sensor_covariance: as
    LQGController's; torque_limits: None or per joint [N m]."""

    def __init__(self, params: ArmParameters, dt: float, *, operating_angles, reference, reference_trajectory=None,
                 initial_angles=None, sensors_per_joint: int = 2, state_weight=1.0, integral_weight: float = 1.0,
                 action_weight=1.0, process_covariance=1e-4, sensor_covariance=1e-4, torque_limits=None):
        from attend.control.baselines import LQGController

        self.params = params
        q_o = _pair(operating_angles, "operating_angles")
        A, B, tau_o = linearise(params, q_o)
        self._x_o = np.concatenate([q_o, [0.0, 0.0]])
        self._tau_o = tau_o
        C = sensor_matrix(sensors_per_joint)
        self._y_o = C @ self._x_o
        target = reference if callable(reference) else (lambda t, r=_pair(reference, "reference"): r)
        limits = None
        if torque_limits is not None:
            high = vector(torque_limits, 2, "torque_limits")
            limits = (-high - tau_o, high - tau_o)
        if reference_trajectory is not None and not callable(reference_trajectory):
            raise AttendInputError("reference_trajectory: expected a function t -> (q_r, q_r', q_r'')")

        def shifted(t):  # the reference state and its feed-forward torque, as deviations from the operating point
            q_r, w_r, acc_r = (np.asarray(value, dtype=float) for value in reference_trajectory(t))
            return np.concatenate([q_r - q_o, w_r]), inverse_dynamics(params, q_r, w_r, acc_r) - tau_o
        start = None if initial_angles is None else np.concatenate([_pair(initial_angles, "initial_angles") - q_o,
                                                                   [0.0, 0.0]])
        self.lqg = LQGController(A, B, C, dt, reference=lambda t: np.asarray(target(t), dtype=float) - q_o,
                                 tracked=np.hstack([np.eye(2), np.zeros((2, 2))]), state_weight=state_weight,
                                 integral_weight=integral_weight, action_weight=action_weight,
                                 process_covariance=process_covariance, sensor_covariance=sensor_covariance,
                                 action_limits=limits, initial_estimate=start,
                                 reference_state=None if reference_trajectory is None else shifted)
        self.dt, self.n_actions = self.lqg.dt, 2

    def reset(self) -> None:
        """Estimate back at its initial value, integrators zero, t = 0."""
        self.lqg.reset()

    def step(self, y) -> np.ndarray:
        """Take y[k] (2 s,), return the torques a[k] (2,) [N m]."""
        return self._tau_o + self.lqg.step(np.asarray(y, dtype=float) - self._y_o)


def critically_damped_model(bandwidth: float, *, sensor_std: float, process_precision: float, kernel_width: float,
                            cause_prior: Callable, cause_prior_precision: float = math.exp(8.0),
                            embedding_order: int = 2, sensors_per_joint: int = 2, initial_angles=(0.0, 0.0),
                            reference_acceleration: bool = False):
    """The agent of the arm benchmark (an :class:`attend.control.GenerativeModel`): it believes each joint is drawn,
    critically damped at ``bandwidth`` w [rad/s], to the target angle and velocity, its causes
    v = (q*_1, q*_2, q*_1', q*_2') (and, with ``reference_acceleration``, the target's acceleration q*'')::

        q'' = [q*''] - w^2 (q - q*) - 2 w (q' - q*'),     y = C x (s angle sensors per joint)

    sensor_std [rad]: each sensor's noise (Pi_z = 1/sensor_std^2); process_precision: Pi_w; kernel_width: s [s];
    cause_prior: eta(t) -> r or 2 r numbers (the target and its motion, r = 4 or 6 causes); cause_prior_precision:
    P_v; embedding_order: p; sensors_per_joint: s; initial_angles [rad]: the belief at t = 0 (at rest);
    reference_acceleration: the target's acceleration is a cause too (6 causes), fed forward in the belief."""
    from attend.control.model import GenerativeModel

    w = positive_scalar(bandwidth, "bandwidth", "rad/s")
    I, Z = np.eye(2), np.zeros((2, 2))
    A = np.block([[Z, I], [-w**2 * I, -2 * w * I]])
    B = np.block([[Z, Z], [w**2 * I, 2 * w * I]])
    if reference_acceleration:
        B = np.hstack([B, np.vstack([Z, I])])
    C = sensor_matrix(sensors_per_joint)
    std = positive_scalar(sensor_std, "sensor_std", "rad")
    return GenerativeModel.linear(A, B, C, sensor_precision=1.0 / std**2, process_precision=process_precision,
                                  cause_prior_precision=cause_prior_precision, cause_prior=cause_prior,
                                  kernel_width=kernel_width, embedding_order=embedding_order, cause_order=1,
                                  initial_states=np.concatenate([_pair(initial_angles, "initial_angles"), [0.0, 0.0]]),
                                  initial_causes=np.asarray(cause_prior(0.0), dtype=float)[:B.shape[1]])
