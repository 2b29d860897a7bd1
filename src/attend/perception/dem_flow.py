"""The DEM observer's linear flow: its generalised matrices, their exact discretisation with the
embedding weights folded in, and where the flow starts (see :mod:`attend.perception.dem`)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from attend._validation import AttendInputError
from attend.models.generalized import block_precisions, embedding_weights, shift_operator
from attend.perception.recurrence import linear_recurrence


def flow_matrices(observer, p: int) -> dict[str, np.ndarray]:
    """The generalised matrices of ``observer``'s flow at embedding order p (module docstring of
    attend.perception.dem): C~, A~, B~, D_x, D_v, Vy, W, Vv, A_obs, B_obs, Pi_X and its inverse,
    the exact discretisation Phi (transition) and Gamma (gain), Gamma folded over the raw window.

    observer: the DEMObserver (its system, dt, widths, precisions, input_order, known_inputs);
    p: the embedding order.
    """
    A, B, C = observer.system.A, observer.system.B, observer.system.C
    n, r, m = observer.system.n_states, observer.system.n_inputs, observer.system.n_outputs
    d = observer.input_order
    S_p, S_d = block_precisions(p, d, observer.process_kernel_width, observer.precision_convention)
    S_pz = S_p if observer.sensor_kernel_width == observer.process_kernel_width else \
        block_precisions(p, d, observer.sensor_kernel_width, observer.precision_convention)[0]
    if observer.input_kernel_width != observer.process_kernel_width:
        S_d = block_precisions(p, d, observer.input_kernel_width, observer.precision_convention)[1]
    Ct = np.kron(np.eye(p + 1), C)
    At = np.kron(np.eye(p + 1), A)
    Bt = np.kron(np.eye(p + 1, d + 1), B)
    Dx = shift_operator(p + 1, n)
    Dv = shift_operator(d + 1, r)
    Vy = np.kron(S_pz, observer.sensor_precision)
    W = np.kron(S_p, observer.process_precision)
    Vv = np.kron(S_d, observer.input_prior_precision)
    motion = Dx - At
    Pxx = Ct.T @ Vy @ Ct + motion.T @ W @ motion
    if observer.known_inputs:
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
    if getattr(observer, "integration", "attend") == "spm":
        transition, gain = spm_discretisation(observer, p, Ct, motion, Bt, (Vy, W, Vv))
        exponential = np.hstack([transition, gain])
    else:
        block = np.zeros((size + width, size + width))
        block[:size, :size] = A_obs * observer.dt
        block[:size, size:] = B_obs * observer.dt
        with np.errstate(over="ignore", invalid="ignore"):
            exponential = expm(block)
        transition, gain = exponential[:size, :size], exponential[:size, size:]
    if not np.all(np.isfinite(exponential)):
        suspect = ("kernel_width" if observer.kernel_width > 50 * observer.dt
                   else "sensor_precision, process_precision, input_prior_precision")
        raise AttendInputError(
            f"{suspect}: the observer's flow matrix could not be discretised (overflow) with kernel_width = "
            f"{observer.kernel_width:g} s, dt = {observer.dt:g} s, p = {observer.embedding_order}, d = {observer.input_order} "
            "(derivative order i is weighted by about kernel_width^(2i)); expected a kernel_width of a few "
            "sample times, smaller precisions or lower embedding orders"
        )
    radius = float(np.max(np.abs(np.linalg.eigvals(transition))))
    window_gain, offsets = fold_embedding(observer, gain, p)
    window_B_obs, _ = fold_embedding(observer, B_obs, p)
    order0 = np.r_[0:m, m * (p + 1): m * (p + 1) + r]  # columns of y and eta/u at order 0
    try:
        covariance = np.linalg.inv(Pi_X)
    except np.linalg.LinAlgError:
        covariance = np.linalg.pinv(Pi_X)
    return dict(
        Ct=Ct, At=At, Bt=Bt, Dx=Dx, Dv=Dv, Vy=Vy, W=W, Vv=Vv, S_p=S_p, S_d=S_d,
        A_obs=A_obs, B_obs=B_obs, Pi_X=Pi_X, Sigma_X=covariance, S_pz=S_pz, radius=radius,
        transition=transition, gain=gain, window_gain=window_gain, window_B_obs=window_B_obs,
        offsets=offsets, order0_gain=gain[:, order0], order0_B_obs=B_obs[:, order0],
    )


def spm_discretisation(observer, p: int, Ct, motion, Bt, precisions) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) of spm_DEM's D-step for the linear flow (integration="spm", docs/spm.md).

    Over one sample the data ride along their generalised motion, d/dt [X; y~; u~] =
    [D_X X - E' Pi_M (E X + H data~); D data~], integrated by the local linearisation with the
    Jacobian J_aug = [[D_X - E' Pi E, -E' Pi H], [0, D]] (E = de/dX, H = de/d data~; Pi_M: the precision with
    the columns of the top order's motion error zeroed, spm_DEM's e_x^(p) = 0). With
    Psi = int_0^dt expm(J_aug t) dt (one exponential of [[J_aug, I], [0, 0]] dt):
    X[k+1] = (I + Psi_XX A_M) X[k] + (Psi_XX B_M + Psi_Xd D) data~[k], A_M = D_X - E' Pi_M E,
    B_M = -E' Pi_M H. observer: the DEMObserver; p: the embedding order; Ct, motion = D_x - A~,
    Bt: the generalised C, motion operator and B; precisions: (Vy, W, Vv).
    """
    n, r, m = observer.system.n_states, observer.system.n_inputs, observer.system.n_outputs
    d = observer.input_order
    Vy, W, Vv = precisions
    n_x, n_y, n_u = n * (p + 1), m * (p + 1), r * (d + 1)
    mask = np.ones(n_x)
    mask[-n:] = 0.0  # no motion error at the top order
    if observer.known_inputs:  # e = [y~ - Ct x~; motion x~ - Bt u~], data [y~; u~]
        E = np.vstack([-Ct, motion])
        H = np.block([[np.eye(n_y), np.zeros((n_y, n_u))], [np.zeros((n_x, n_y)), -Bt]])
        Pi, Pi_M = _block_diagonal(Vy, W), _block_diagonal(Vy, W * mask[None, :])
        D_X = shift_operator(p + 1, n)
    else:  # e = [y~ - Ct x~; motion x~ - Bt v~; v~ - eta~], data [y~; eta~]
        E = np.block([[-Ct, np.zeros((n_y, n_u))], [motion, -Bt], [np.zeros((n_u, n_x)), np.eye(n_u)]])
        H = np.zeros((n_y + n_x + n_u, n_y + n_u))
        H[:n_y, :n_y], H[n_y + n_x:, n_y:] = np.eye(n_y), -np.eye(n_u)
        Pi, Pi_M = _block_diagonal(Vy, W, Vv), _block_diagonal(Vy, W * mask[None, :], Vv)
        D_X = _block_diagonal(shift_operator(p + 1, n), shift_operator(d + 1, r))
    D_data = _block_diagonal(shift_operator(p + 1, m), shift_operator(d + 1, r))
    size, width = E.shape[1], H.shape[1]
    jacobian = np.block([[D_X - E.T @ Pi @ E, -E.T @ Pi @ H], [np.zeros((width, size)), D_data]])
    total = size + width
    block = np.zeros((2 * total, 2 * total))
    block[:total, :total], block[:total, total:] = jacobian * observer.dt, np.eye(total) * observer.dt
    with np.errstate(over="ignore", invalid="ignore"):
        psi = expm(block)[:size, total:]  # rows of X in int_0^dt expm(J_aug t) dt
    transition = np.eye(size) + psi[:, :size] @ (D_X - E.T @ Pi_M @ E)
    gain = psi[:, :size] @ (-E.T @ Pi_M @ H) + psi[:, size:] @ D_data
    return transition, gain


def _block_diagonal(*blocks) -> np.ndarray:
    """blkdiag(blocks) of square matrices."""
    size = sum(block.shape[0] for block in blocks)
    out = np.zeros((size, size))
    start = 0
    for block in blocks:
        out[start: start + block.shape[0], start: start + block.shape[0]] = block
        start += block.shape[0]
    return out


def known_input_error(observer, signals: np.ndarray, segment: int) -> np.ndarray:
    """Mean square (n,) of the DEM filter's own error on the noise-free response to the known
    inputs, over the middle 80 % of the log.

    The plant x[k] = Ad x[k-1] + Bd u[k-1] (from x = 0) and DEM's generalised motion
    dx/dt = A x + B u (embedded u) respond differently to the same input (sample-and-hold
    delay, finite-difference derivatives); that deterministic error depends on the input
    signal, so it is measured on the given one and added to the noise-driven variance.
    observer: the DEMObserver; signals: (N, m + r) samples [y, u]; segment: samples per segment
    of its batch run."""
    system = observer.system
    m, n = system.n_outputs, system.n_states
    u = signals[:, m:]
    Ad, Bd = system.discretize(observer.dt)
    response = np.zeros((signals.shape[0], n))
    with np.errstate(over="ignore", invalid="ignore"):
        response[1:] = linear_recurrence(Ad, u[:-1] @ Bd.T, np.zeros(n))
        clean = np.hstack([response @ system.C.T, u])
        states = observer.run_flow(clean, None, False, segment)[0]
    middle = slice(signals.shape[0] // 10, signals.shape[0] - signals.shape[0] // 10)
    error = np.mean((states[middle] - response[middle]) ** 2, axis=0)
    return np.where(np.isfinite(error), error, np.inf)


def samples_after_centre(window: int) -> int:
    """How many samples of an embedding window of ``window`` samples lie after its centre sample
    (sample window // 2 of the window)."""
    return window - 1 - window // 2


def centre_samples(signals: np.ndarray, rows: np.ndarray, window_offset: int) -> np.ndarray:
    """The samples the embedding windows of ``rows`` are centred on: rows + window_offset, clamped
    to the log. signals: (N, m + r) samples [y, u]; rows: row indices; window_offset: the
    observer's (0: centred)."""
    return signals[np.clip(rows + window_offset, 0, signals.shape[0] - 1)]


def fold_embedding(observer, gain: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """Fold the embedding weights into Gamma: drive[k] = sum_i G_i [y; u][k + offset_i].

    Returns G stacked as (size, n_offsets * (m + r)) over the raw window (offsets ascending)
    and the offsets relative to k. observer: the DEMObserver; gain: Gamma over the embedded
    [y~; u~] (or B_obs); p: the embedding order.
    """
    m, r = observer.system.n_outputs, observer.system.n_inputs
    d = observer.input_order
    Ey = embedding_weights(p + 1, observer.dt)  # (p+1 orders, p+1 samples)
    Eu = embedding_weights(d + 1, observer.dt)
    first = -max((p + 1) // 2, (d + 1) // 2)
    last = max(samples_after_centre(p + 1), samples_after_centre(d + 1))
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
    return folded, offsets + observer.window_offset


def start_state(observer, signals: np.ndarray, row: int, edge: bool) -> np.ndarray:
    """Where the flow starts at row ``row``: order 0 from that row's own sample, every higher
    order at its prior mean.

    Order 0 is the static MAP of the sample [y; eta] (or [y; u]) given the prior: it
    minimises |y - C x|^2_Pi_z + |v - eta|^2_P_v + |A x + B v|^2_Pi_w (the motion error at
    order 0 with x' at its prior mean 0), by least squares with the minimum-norm deviation
    from the prior where the data do not decide (so unobservable states start at 0, inputs
    at eta); the constructor's ``initial_state`` replaces the states' part (the inputs then
    take their MAP given it). Higher orders: 0 for the states; for unknown inputs the
    derivatives of eta embedded from its window (0 at an order-0 edge row). Starting the
    higher orders from the data instead (finite differences of noisy samples, or the static
    MAP of the whole window) puts large values into the least precise coordinates, which a
    slow observer mode then carries through the log.

    observer: the DEMObserver; signals: (N, m + r) samples [y, eta or u]; row: the row the flow
    starts at; edge: whether that row's window reaches past the log (order-0 edge row).
    """
    system = observer.system
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    A, B, C = system.A, system.B, system.C
    Pz, Pw, Pv = observer.sensor_precision, observer.process_precision, observer.input_prior_precision
    sample = centre_samples(signals, np.array([row]), observer.window_offset)[0]
    y, u = sample[:m], sample[m:]
    p, d = observer.embedding_order, observer.input_order
    X = np.zeros(observer.n_state_coordinates + observer.n_input_coordinates)
    if observer.known_inputs:
        if observer.initial_state is not None:
            X[:n] = observer.initial_state
        else:
            normal = C.T @ Pz @ C + A.T @ Pw @ A
            X[:n] = np.linalg.lstsq(normal, C.T @ Pz @ y - A.T @ Pw @ B @ u, rcond=1e-12)[0]
        return X
    if observer.initial_state is not None:  # inputs: MAP given the states
        x = observer.initial_state
        dv = np.linalg.lstsq(Pv + B.T @ Pw @ B, -B.T @ Pw @ (A @ x + B @ u), rcond=1e-12)[0]
    else:  # deviations (dx, dv) from the prior means (0, eta)
        normal = np.block([[C.T @ Pz @ C + A.T @ Pw @ A, A.T @ Pw @ B], [B.T @ Pw @ A, Pv + B.T @ Pw @ B]])
        rhs = np.concatenate([C.T @ Pz @ y - A.T @ Pw @ B @ u, -B.T @ Pw @ B @ u])
        deviation = np.linalg.lstsq(normal, rhs, rcond=1e-12)[0]
        x, dv = deviation[:n], deviation[n:]
    n_x = n * (p + 1)
    X[:n] = x
    if not edge:
        centre = row + observer.window_offset
        window = signals[np.clip(np.arange(centre - (d + 1) // 2, centre - (d + 1) // 2 + d + 1),
                                 0, signals.shape[0] - 1), m:]
        X[n_x:] = (embedding_weights(d + 1, observer.dt) @ window).reshape(-1)  # eta~, order-major
    X[n_x: n_x + r] = u + dv
    return X
