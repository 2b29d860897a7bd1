"""Pure functions of active inference control in generalised coordinates (no state, no validation).

Layout of the joint state Z = [x~ (P n); v~ (Q r); a (k)], P = p + 1 orders of x and y, Q = d + 1
orders of v; every generalised vector is order-major ([x; x'; x''; ...]).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from scipy.linalg.blas import dgemm, dgemv

from attend.control._exponential import AugmentedExponential, exponential_and_integral


def causal_embedding_weights(n_orders: int, window: int, dt: float) -> np.ndarray:
    """W (n_orders, window): y~[k] = W @ [y[k - window + 1]; ...; y[k]], the derivatives at the newest sample
    of the least-squares polynomial of degree n_orders - 1 through the last ``window`` samples (window =
    n_orders: exact backward differences). dt: sample spacing [s]."""
    from math import factorial

    offsets = (np.arange(window) - (window - 1)) * dt
    taylor = np.stack([offsets**j / factorial(j) for j in range(n_orders)], axis=1)  # (window, n_orders)
    return np.linalg.pinv(taylor)


def rectangular_identity(rows: int, cols: int) -> np.ndarray:
    """I (rows, cols): ones on the diagonal."""
    return np.eye(rows, cols)


def generalised_errors(x_t, v_t, y_t, eta_t, f0, g0, fx, fv, gx, gv, P, Q):
    """(e_y, e_x, e_v): sensory, motion and cause prediction errors of the local linearisation.

        e_y = y~ - g~,  g~ = [g(x, v); gx x' + gv v'; ...]
        e_x = D x~ - f~, f~ = [f(x, v); fx x' + fv v'; ...]        (x^(P) = 0)
        e_v = v~ - eta~
    x_t (P n,), v_t (Q r,), y_t (P m,), eta_t (Q r,); f0 = f(x, v), g0 = g(x, v) at order 0."""
    n, r = fx.shape[0], fv.shape[1]
    X = x_t.reshape(P, n)
    V = np.zeros((P, r))
    orders = min(P, Q)
    V[:orders] = v_t.reshape(Q, r)[:orders]
    predicted_y = X @ gx.T + V @ gv.T
    predicted_y[0] = g0
    predicted_f = X @ fx.T + V @ fv.T
    predicted_f[0] = f0
    motion = np.zeros_like(X)
    motion[:-1] = X[1:]
    return y_t - predicted_y.reshape(-1), (motion - predicted_f).reshape(-1), v_t - eta_t


def _diagonal_blocks(out: np.ndarray, block: np.ndarray, rows: int, cols: int, sign: float = 1.0) -> None:
    """Write sign * kron(eye(rows, cols), block) into ``out`` (rows * a, cols * b) in place (no kron temporaries)."""
    a, b = block.shape
    if a == 0 or b == 0:
        return
    view = out.reshape(rows, a, cols, b)
    index = np.arange(min(rows, cols))
    view[index, :, index, :] = sign * block


def error_jacobian(fx, fv, gx, gv, P, Q):
    """(E_y, E_x, E_v) = de/dX for X = [x~; v~], Jacobians of f, g held fixed (Gauss-Newton)::

        E_y = -[kron(I_P, gx), kron(I_PQ, gv)],  E_x = [D_x - kron(I_P, fx), -kron(I_PQ, fv)],  E_v = [0, I]"""
    n, r, m = fx.shape[0], fv.shape[1], gx.shape[0]
    size_x, size_v = P * n, Q * r
    E_y = np.zeros((P * m, size_x + size_v))
    E_x = np.zeros((size_x, size_x + size_v))
    left_y, right_y = np.zeros((P * m, size_x)), np.zeros((P * m, size_v))
    left_x, right_x = np.zeros((size_x, size_x)), np.zeros((size_x, size_v))
    _diagonal_blocks(left_y, np.asarray(gx, dtype=float), P, P, -1.0)
    _diagonal_blocks(right_y, np.asarray(gv, dtype=float), P, Q, -1.0)
    _diagonal_blocks(left_x, np.asarray(fx, dtype=float), P, P, -1.0)
    _diagonal_blocks(right_x, np.asarray(fv, dtype=float), P, Q, -1.0)
    left_x[np.arange(size_x - n), np.arange(n, size_x)] += 1.0  # the shift D_x = kron(U_P, I_n)
    E_y[:, :size_x], E_y[:, size_x:] = left_y, right_y
    E_x[:, :size_x], E_x[:, size_x:] = left_x, right_x
    E_v = np.zeros((size_v, size_x + size_v))
    E_v[:, size_x:] = np.eye(size_v)
    return E_y, E_x, E_v


def error_jacobian_reference(fx, fv, gx, gv, P, Q):
    """:func:`error_jacobian` written with numpy's kron (the definition; slower), for tests."""
    n, r = fx.shape[0], fv.shape[1]
    I_P, I_PQ = np.eye(P), rectangular_identity(P, Q)
    shift = np.kron(np.eye(P, k=1), np.eye(n))
    E_y = -np.hstack([np.kron(I_P, gx), np.kron(I_PQ, gv)])
    E_x = np.hstack([shift - np.kron(I_P, fx), -np.kron(I_PQ, fv)])
    E_v = np.hstack([np.zeros((Q * r, P * n)), np.eye(Q * r)])
    return E_y, E_x, E_v


def shift_matrix(P: int, n: int, Q: int, r: int) -> np.ndarray:
    """D = blkdiag(kron(U_P, I_n), kron(U_Q, I_r)): the derivative operator on X = [x~; v~]."""
    size_x, size_v = P * n, Q * r
    D = np.zeros((size_x + size_v, size_x + size_v))
    D[:size_x, :size_x] = np.kron(np.eye(P, k=1), np.eye(n))
    D[size_x:, size_x:] = np.kron(np.eye(Q, k=1), np.eye(r))
    return D


def joint_system(D, E_y, E_x, E_v, Pi_y, Pi_x, Pi_v, G, Pi_a, gain, action_prior_precision):
    """Jacobian J of the joint flow of Z = [X; a] and the gains (K_y, K_eta) of its data::

        dX/dt = D X - E' Pi e              (perception: D-step, gradient of F = -e' Pi e / 2)
        da/dt = -kappa (G' Pi_a e_y + P_a a) (action: G = dy~/da, Pi_a the precision on sensory errors)

    with e_y = y~ + G (a - a_k) - g~(X): within a sample the agent predicts its sensations move with
    its action (SPM's joint integration of world and agent). Linear in Z:
    flow(Z) = J Z + K_y (y~ - G a_k) + K_eta eta~ + (offsets of a nonlinear f, g)."""
    nX, k = D.shape[0], G.shape[1]
    Wy, Wx, Wv = Pi_y @ E_y, Pi_x @ E_x, Pi_v @ E_v
    curvature = E_y.T @ Wy + E_x.T @ Wx + E_v.T @ Wv
    J = np.empty((nX + k, nX + k))
    J[:nX, :nX] = D - curvature
    J[:nX, nX:] = -Wy.T @ G
    PaG = Pi_a @ G
    J[nX:, :nX] = -gain * (PaG.T @ E_y)
    J[nX:, nX:] = -gain * (G.T @ PaG) - gain * action_prior_precision * np.eye(k)
    K_y = np.vstack([-Wy.T, -gain * PaG.T])
    K_eta = np.vstack([Wv.T, np.zeros((k, Wv.shape[0]))])
    return J, K_y, K_eta, curvature


def local_linearisation_step(J: np.ndarray, flow: np.ndarray, dt: float) -> np.ndarray:
    """dZ = (expm(J dt) - I) inv(J) flow (Ozaki), from one exponential of [[J, flow], [0, 0]] dt."""
    N = J.shape[0]
    block = np.zeros((N + 1, N + 1))
    block[:N, :N] = J * dt
    block[:N, N] = flow * dt
    return expm(block)[:N, N]


def relative_degrees(G: np.ndarray, n_orders: int) -> np.ndarray:
    """Per output i, the lowest order of motion at which some action moves it (rows of G = dy~/da,
    order-major, n_orders blocks); n_orders - 1 for an output no action moves."""
    blocks = np.any(G.reshape(n_orders, -1, G.shape[1]) != 0, axis=2)  # (orders, m)
    first = np.argmax(blocks, axis=0)
    first[~blocks.any(axis=0)] = n_orders - 1
    return first


def sensory_precision(S_by_order: list, orders: np.ndarray, precision: np.ndarray) -> np.ndarray:
    """Pi~_z ((P m, P m)) when output i is attended up to order orders[i]: for a diagonal Pi_z,
    Pi~_z[(o, i), (o', i)] = pi_i S_(orders[i])[o, o'] with S_q = S(s) of q + 1 orders (the marginal precision
    of the attended orders) and 0 beyond; a full Pi_z uses the lowest order for all outputs, kron(S_q, Pi_z).
    S_by_order[q]: S_q padded with zeros to (P, P)."""
    m = precision.shape[0]
    P = S_by_order[0].shape[0]
    if np.count_nonzero(precision - np.diag(np.diagonal(precision))) == 0:
        out = np.zeros((P, m, P, m))
        for i in range(m):
            out[:, i, :, i] = precision[i, i] * S_by_order[orders[i]]
        return out.reshape(P * m, P * m)
    return np.kron(S_by_order[int(orders.min())], precision)


def discrete_transition(J: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(expm(J dt), int_0^dt expm(J t) dt): the exact step of the linear flow dZ/dt = J Z + c, c held; the blocks of
    expm([[J, I], [0, 0]] dt) from N x N products (:func:`exponential_and_integral`)."""
    return exponential_and_integral(J, dt)


def moving_data_transition(J: np.ndarray, K_y: np.ndarray, K_eta: np.ndarray, P: int, m: int, Q: int, r: int,
                           dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(expm(J dt), int_0^dt expm(J t) dt, Gamma_y, Gamma_eta): the exact step of
    dZ/dt = J Z + K_y y~(t) + K_eta eta~(t) + c (c held) when the data move with their generalised motion within
    the sample: y~(t) = expm(D_y t) y~[k], eta~(t) = expm(D_v t) eta~[k], D the shift of P orders of m outputs
    and of Q orders of r causes (spm_DEM integrates [y~; x~; v~] jointly, with dy~/dt = D y~).
    Gamma_y = int_0^dt expm(J (dt - t)) K_y expm(D_y t) dt, and so for eta~: the upper blocks of
    expm([[J, K_y, K_eta], [0, D_y, 0], [0, 0, D_v]] dt); expm(J dt) and its integral are :func:`discrete_transition`'s
    (the same numbers as for held data)."""
    N, ny, nv = J.shape[0], P * m, Q * r
    size = N + ny + nv
    block = np.zeros((size, size))
    block[:N, :N] = J
    block[:N, N: N + ny] = K_y
    block[:N, N + ny:] = K_eta
    block[N:, N:] = shift_matrix(P, m, Q, r)
    full = expm(block * dt)
    transition, integral = discrete_transition(J, dt)
    return transition, integral, full[:N, N: N + ny], full[:N, N + ny:]


def _diagonal_blocks_view(matrix: np.ndarray, row: int, col: int, count: int, height: int, width: int):
    """The ``count`` blocks (height, width) of ``matrix`` at (row + i height, col + i width), i = 0..count-1, as one
    writable strided view (count, height, width): writing a block there writes kron(eye(count), block) in place.
    None when the blocks are empty."""
    if count == 0 or height == 0 or width == 0:
        return None
    rows, cols = matrix.strides
    return np.lib.stride_tricks.as_strided(matrix[row:, col:], shape=(count, height, width),
                                           strides=(height * rows + width * cols, rows, cols))


class JointFlow:
    """The joint flow of Z = [x~ (P n); v~ (Q r); a (k)] linearised at the beliefs: :func:`error_jacobian`,
    :func:`joint_system`, :func:`generalised_errors` and the flow of the D-step and the action in one pass over
    preallocated arrays (the step that re-linearises every sample)::

        e = [e_y; e_x; e_v],   F = de/dZ = [[E_y, G], [E_x, 0], [E_v, 0]],   Pi~ = blkdiag(Pi~_y, Pi~_x, Pi~_v)
        J = L - H' F,    flow(Z) = L Z - H' e,    L = blkdiag(D, -kappa P_a I),    H = Pi~ F R

    R = diag(1 on the columns of X, kappa on those of a), so that H' F holds the curvature F' Pi~ F in the rows of X
    and the action's rows kappa G' Pi~_y [E_y, G] of :func:`joint_system`; with a separate action precision Pi_a the
    action columns of H are [kappa Pi_a G; 0; 0]. Only the Jacobians of f and g (:meth:`set_jacobians`), dy~/da
    (:meth:`set_action_jacobian`) and Pi~_y (:meth:`set_sensory_precision`) change; the shift in E_x, E_v = [0, I],
    Pi~_x, Pi~_v and L are written once. D: :func:`shift_matrix`; Pi_x, Pi_v: kron(S_P, Pi_w), kron(S_Q, P_v); gain:
    kappa; action_prior_precision: P_a; dt: the sample time [s]."""

    def __init__(self, n: int, r: int, m: int, k: int, P: int, Q: int, D: np.ndarray, Pi_x: np.ndarray,
                 Pi_v: np.ndarray, gain: float, action_prior_precision: float, dt: float):
        nX, N = P * n + Q * r, P * n + Q * r + k
        ry, rx = P * m, P * m + P * n  # first rows of e_x and of e_v in e
        self.sizes = (n, r, m, k, P, Q)
        self.dt = dt
        F = np.zeros((rx + Q * r, N))
        F[ry:rx, : P * n] = D[: P * n, : P * n]  # the shift D_x of E_x = D_x - kron(I_P, fx)
        F[rx:, P * n: nX] = np.eye(Q * r)  # E_v = [0, I]
        self.F = F
        self._make_views()
        Pi = np.zeros((F.shape[0], F.shape[0]))
        Pi[ry:rx, ry:rx] = Pi_x
        Pi[rx:, rx:] = Pi_v
        self.Pi = Pi
        self.L = np.zeros((N, N))
        self.L[:nX, :nX] = D
        self._R = np.ones(N)
        self.set_action_gain(gain, action_prior_precision)
        self._Pi_a = None  # the action's own precision on e_y (None: Pi~_y)
        self.G = None
        self.errors = None  # e of the last flow
        self.H = np.empty_like(F)  # Pi~ F R of the last linearisation
        self.J = np.empty((N, N))
        self._augmented = np.zeros((N + 1, N + 1))
        self._exponential = AugmentedExponential(N + 1)
        self._moving = None  # (block, shift, exponential) of :meth:`moving_data_increment`, made at first use

    _VIEWS = ("_F_X", "_gx", "_gv", "_fx", "_fv")
    top_motion_error = True  # False: e_x at the top order p is 0 in :meth:`flow` (spm_DEM_eval)
    world_increment = None  # the world's increment of the last :meth:`_world_increment`
    _world = None  # (block, exponential) of :meth:`_world_increment`, made at first use

    def _make_views(self) -> None:
        """The views into F written and read every sample: its columns of X and the diagonal blocks of the Jacobians
        (rebuilt after a copy or unpickling, which would detach them from F)."""
        n, r, m, k, P, Q = self.sizes
        F, ry, orders = self.F, P * m, min(P, Q)
        self._F_X = F[:, : P * n + Q * r]
        self._gx = _diagonal_blocks_view(F, 0, 0, P, m, n)
        self._gv = _diagonal_blocks_view(F, 0, P * n, orders, m, r)
        self._fx = _diagonal_blocks_view(F, ry, 0, P, n, n)
        self._fv = _diagonal_blocks_view(F, ry, P * n, orders, n, r)

    def __getstate__(self) -> dict:
        return {key: value for key, value in self.__dict__.items() if key not in self._VIEWS}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._make_views()

    def set_action_gain(self, gain: float, action_prior_precision: float) -> None:
        """kappa and P_a: the action rows of L and the action entries of R."""
        n, r, m, k, P, Q = self.sizes
        nX = P * n + Q * r
        self.gain, self.action_prior_precision = gain, action_prior_precision
        self.L[nX:, nX:] = -gain * action_prior_precision * np.eye(k)
        self._R[nX:] = gain

    def set_jacobians(self, fx, fv, gx, gv) -> None:
        """Write the Jacobians of f and g at the beliefs into F (E_y = -[kron(I_P, gx), kron(I_PQ, gv)],
        E_x = [D_x - kron(I_P, fx), -kron(I_PQ, fv)])."""
        for view, block in ((self._gx, gx), (self._gv, gv), (self._fx, fx), (self._fv, fv)):
            if view is not None:
                np.negative(block, out=view)

    def set_action_jacobian(self, G: np.ndarray) -> None:
        """dy~/da ((P m, k)) into the action columns of F."""
        n, r, m, k, P, Q = self.sizes
        self.F[: P * m, P * n + Q * r:] = G
        self.G = G

    def set_sensory_precision(self, Pi_y: np.ndarray, Pi_a: np.ndarray | None = None) -> None:
        """Pi~_y ((P m, P m)) into Pi~; Pi_a: the action's precision on e_y (None: Pi~_y)."""
        ry = Pi_y.shape[0]
        self.Pi[:ry, :ry] = Pi_y
        self._Pi_a = Pi_a

    def linearise(self) -> np.ndarray:
        """J ((N, N)) of the joint flow at the Jacobians, dy~/da and precisions written (also keeps H)."""
        F, H, J = self.F, self.H, self.J
        # C-ordered arrays to BLAS as their transposes: H' = F' Pi~' and J' = L' - F' H
        dgemm(1.0, F.T, self.Pi.T, 0.0, H.T, overwrite_c=1)
        H *= self._R
        if self._Pi_a is not None:
            ry, nX = self._Pi_a.shape[0], F.shape[1] - self.sizes[3]
            H[:, nX:] = 0.0
            np.multiply(self._Pi_a @ self.G, self.gain, out=H[:ry, nX:])
        np.copyto(J, self.L)
        dgemm(-1.0, F.T, H.T, 1.0, J.T, overwrite_c=1, trans_b=1)
        return J

    def flow(self, Z: np.ndarray, y_t: np.ndarray, eta_t: np.ndarray, f0: np.ndarray, g0: np.ndarray) -> np.ndarray:
        """flow(Z) = L Z - H' e at the last linearisation, e the prediction errors of :func:`generalised_errors` (from F
        and f(x, v), g(x, v) at order 0; kept as ``errors``); with ``top_motion_error`` False the motion error at the
        top order p is 0, as spm_DEM_eval computes it (the Jacobian F keeps that row)."""
        n, r, m, k, P, Q = self.sizes
        ry, rx = P * m, P * m + P * n
        e = self._F_X @ Z[: Z.shape[0] - k]  # the linear part: orders >= 1 of -g~, D x~ - f~, and v~
        e[:ry] += y_t
        np.subtract(y_t[:m], g0, out=e[:m])
        if P > 1:
            np.subtract(Z[n: 2 * n], f0, out=e[ry: ry + n])
        else:
            np.negative(f0, out=e[ry: ry + n])
        if not self.top_motion_error:  # spm_DEM_eval: no motion error at the top order (its Jacobian kept)
            e[rx - n: rx] = 0.0
        e[rx:] -= eta_t
        self.errors = e
        return dgemv(-1.0, self.H.T, e, 1.0, self.L @ Z, overwrite_y=1)

    def increment(self, flow: np.ndarray) -> np.ndarray | None:
        """dZ = (expm(J dt) - I) inv(J) flow, from the last column of the exponential of [[J, flow], [0, 0]] dt (as
        :func:`local_linearisation_step`; :class:`AugmentedExponential`); None when J or the flow is not finite."""
        N = flow.shape[0]
        block = self._augmented
        np.multiply(self.J, self.dt, out=block[:N, :N])
        np.multiply(flow, self.dt, out=block[:N, N])
        column = self._exponential.last_column(block)
        return None if column is None else column[:N]

    def moving_data_increment(self, flow: np.ndarray, y_t: np.ndarray, eta_t: np.ndarray,
                              world=None, prior_motion=None) -> np.ndarray | None:
        """dZ over one sample when the data y~ and the prior eta~ move with their own generalised motion within it
        (spm_DEM and spm_ALAP integrate [Z; y~; eta~] jointly): the first N entries of the last column of
        expm(A dt) for the local linearisation of the joint flow of [Z; y~; eta~],

            A = [[J, K_y, K_eta, flow], [0, D_y, 0, D_y y~], [0, 0, D_v, D_v eta~], [0, 0, 0, 0]],
            K_y = d flow / d y~ = -H'_y,   K_eta = d flow / d eta~ = H'_v

        (H'_y, H'_v: the columns of H' on e_y and e_v; D_y, D_v the shifts of P orders of m outputs and of Q orders
        of r causes) at the last linearisation; flow: flow(Z) of :meth:`flow`, y_t: y~, eta_t: eta~ of this sample.
        world: None, or the world's linearised motion (attend.control.process.WorldMotion) integrated jointly with
        the agent, as spm_ADEM does (:meth:`_world_increment`; its increment is kept in ``world_increment``).
        prior_motion: None (the prior moves with its own motion, D_v eta~) or the eta~ ((Q r,)) whose motion D_v
        moves it instead (the rest of eta~ held over the sample). None when a value is not finite."""
        if prior_motion is not None:
            eta_t = prior_motion  # from here on eta_t only gives the prior's motion; its value is in the flow
        if world is not None:
            return self._world_increment(flow, y_t, eta_t, world)
        n, r, m, k, P, Q = self.sizes
        N, ny, nv = flow.shape[0], P * m, Q * r
        size = N + ny + nv + 1
        if self._moving is None or self._moving[0].shape[0] != size:
            block = np.zeros((size, size))
            shift = shift_matrix(P, m, Q, r)
            self._moving = (block, shift, AugmentedExponential(size))
        block, shift, exponential = self._moving
        dt, H = self.dt, self.H
        np.multiply(self.J, dt, out=block[:N, :N])
        np.multiply(H[:ny].T, -dt, out=block[:N, N: N + ny])
        np.multiply(H[ny + P * n:].T, dt, out=block[:N, N + ny: N + ny + nv])
        np.multiply(shift, dt, out=block[N: N + ny + nv, N: N + ny + nv])
        np.multiply(flow, dt, out=block[:N, -1])
        data = np.concatenate([y_t, eta_t])
        np.multiply(shift @ data, dt, out=block[N: N + ny + nv, -1])
        column = exponential.last_column(block)
        return None if column is None else column[:N]

    def _world_increment(self, flow: np.ndarray, y_t: np.ndarray, eta_t: np.ndarray, world) -> np.ndarray | None:
        """:meth:`moving_data_increment` with the world integrated jointly (spm_ADEM's D-step), for the increments of
        Z, the data y~ and prior eta~ and the world's w (``world``, attend.control.process.WorldMotion)::

            dZ/dt = flow + J dZ + K_y dy~ + K_eta deta~      dw/dt = c + A w + B da      (da: the action's rows of dZ)
            dy^(i)/dt = y^(i+1) + (C w)^(i)   on the rows the world drives (``world.driven``), orders i <= p - 2
            dy^(i)/dt = y^(i+1) + dy^(i+1),   deta^(i)/dt = eta^(i+1) + deta^(i+1)   on the others (their own motion)

        (K_y = -H'_y, K_eta = H'_v as in :meth:`moving_data_increment`; the action moves the world within the sample).
        The rows that move with their own motion are polynomials in time, dy^(i)(t) = sum_j t^j / j! y^(i+j) (and so
        the driven rows at order p - 1, whose C w is 0), so they enter through p "clock" states tau_j = t^j / j!
        (tau_1' = 1, tau_j' = tau_(j-1)) with the coefficients K_y u_j + K_eta v_j, u_j, v_j the data's orders j
        above each row. Integrated by the last column of expm(A dt) of [Z; driven rows of y~; w; tau; 1]. Keeps the
        world's increment w(dt) in ``world_increment``; returns that of Z (None when a value is not finite)."""
        n, r, m, k, P, Q = self.sizes
        p = P - 1
        N, nw = flow.shape[0], world.A.shape[0]
        ny = P * m
        rows = np.flatnonzero(world.driven[: (p - 1) * m]) if p > 1 else np.zeros(0, dtype=int)
        nd, nc = rows.size, max(p, Q - 1, 1)
        Y, E = y_t.reshape(P, m), eta_t.reshape(Q, r)
        U = np.zeros((nc, ny))  # U[j - 1]: the coefficient of t^j / j! in the data's increments (orders 0..p-1)
        for i in range(p):
            for j in range(1, p - i + 1):
                U[j - 1, i * m: (i + 1) * m] = Y[i + j]
        U[:, rows] = 0.0  # those move with the world
        V = np.zeros((nc, Q * r))
        for i in range(Q - 1):
            for j in range(1, Q - i):
                V[j - 1, i * r: (i + 1) * r] = E[i + j]
        H = self.H
        size = N + nd + nw + nc + 1
        cached = self._world
        if cached is None or cached[0].shape[0] != size:
            cached = (np.zeros((size, size)), AugmentedExponential(size))
            self._world = cached
        block, exponential = cached
        dt = self.dt
        d0, w0, c0 = N, N + nd, N + nd + nw
        np.multiply(self.J, dt, out=block[:N, :N])
        np.multiply(H[rows].T, -dt, out=block[:N, d0:w0])
        clocks = H[ny + P * n:].T @ V.T - H[:ny].T @ U.T  # (N, nc): K_y u_j + K_eta v_j
        np.multiply(clocks, dt, out=block[:N, c0:-1])
        np.multiply(flow, dt, out=block[:N, -1])
        np.multiply(world.C[rows], dt, out=block[d0:w0, w0:c0])
        np.multiply(y_t[rows + m], dt, out=block[d0:w0, -1])
        np.multiply(world.B, dt, out=block[w0:c0, N - k:N])
        np.multiply(world.A, dt, out=block[w0:c0, w0:c0])
        np.multiply(world.c, dt, out=block[w0:c0, -1])
        index = np.arange(c0 + 1, size - 1)
        block[index, index - 1] = dt  # tau_j' = tau_(j-1)
        block[c0, -1] = dt  # tau_1' = 1
        column = exponential.last_column(block)
        if column is None:
            self.world_increment = None
            return None
        self.world_increment = column[w0:c0].copy()
        return column[:N]
