"""What a DEM observer can promise before it sees data: stability, start transient, error std.

In the interior of a log the DEM observer is a linear time-invariant filter of the raw samples
s[k] = [y[k]; u[k]] (u the measured input, or the input prior eta)::

    X[k] = Phi X[k-1] + sum_j G_j s[k + o_j]          (Phi = expm(A_obs dt), see dem.py)

so everything it can promise follows from (Phi, G) and the generative model it assumes
(simulate()'s discretisation)::

    x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1]        y[k] = C x[k] + z[k]
    w, z: white noise convolved with the unit-energy Gaussian kernel of attend.models.noise
          (covariance per sample inv(Pi_w), inv(Pi_z); widths s_w, s_z)
    unknown inputs: u = eta + a stationary Gaussian process of covariance inv(P_v) and
          autocorrelation exp(-tau^2 / (4 s_w^2)) (as references.exact_posterior models it)

Steady-state error. With z = exp(i w) and the transfer functions P(z) = inv(z I - Ad) of the
plant and H(z) = inv(I - Phi / z) sum_j G_j z^(o_j) of the filter (H_y: its output columns, R_x,
R_v: the rows of the order-0 states / inputs), the estimation error is a stationary Gaussian
process driven by three independent sources::

    e_x = (R_x H_y C - I) P dt w + R_x H_y z + (R_x H_y C - I) P Bd du
    e_v =  R_v H_y C P dt w      + R_v H_y z + (R_v H_y C P Bd - I) du

and its variance is (1/pi) int_0^pi sum_sources diag(E Sigma E^H) S(w) dw, with S the power
spectrum of the source's colour (DTFT of its discrete autocorrelation, unit variance). The
integral is a trapezoid rule on a grid that is uniform on [0, pi], dense where the noise
spectra live (|w| < ~10 dt / s) and refined geometrically around every pole of Phi or Ad near
the unit circle (their peaks are narrower than any uniform grid).
"""

from __future__ import annotations

import numpy as np

from attend.models.noise import gaussian_kernel

#: Base grid sizes of the frequency integral (uniform on [0, pi]; dense at low frequencies).
UNIFORM_NODES = 2048
LOW_NODES = 1024

#: A state / input is "unobservable" when its steady-state error variance exceeds this multiple of
#: its prior (stationary) variance (the estimate is far worse than ignoring the data), is unbounded,
#: or when the outputs do not change its conditional variance (see DEMObserver.analysis).
UNOBSERVABLE_RATIO = 100.0
#: Unknown inputs with at least this prior precision (std <= 1e-5 input units) count as given
#: (measured inputs passed as unknowns, as attend.io and the quadrotor benchmark do): not flagged.
PINNED_INPUT_PRECISION = 1e10


def kernel_spectrum(omegas: np.ndarray, dt: float, kernel_width: float) -> np.ndarray:
    """Power spectrum of attend.models.noise.coloured_noise at unit variance: |DTFT(h)|^2 for the
    unit-energy kernel h = gaussian_kernel(dt, s); (1/pi) int_0^pi S = 1."""
    h = gaussian_kernel(dt, kernel_width)
    correlation = np.correlate(h, h, mode="full")[len(h) - 1:]  # lags 0, 1, ...
    return _cosine_series(omegas, correlation)


def process_spectrum(omegas: np.ndarray, dt: float, kernel_width: float) -> np.ndarray:
    """Power spectrum of samples of a process with autocorrelation exp(-tau^2 / (4 s^2))."""
    reach = int(np.ceil(np.sqrt(4 * np.log(1e18)) * kernel_width / dt)) + 1
    lags = np.arange(reach + 1) * dt
    return _cosine_series(omegas, np.exp(-(lags**2) / (4 * kernel_width**2)))


def _cosine_series(omegas: np.ndarray, correlation: np.ndarray) -> np.ndarray:
    """r_0 + 2 sum_k r_k cos(w k), in chunks so memory stays small for long correlations."""
    out = np.empty(len(omegas))
    lags = np.arange(1, len(correlation))
    chunk = max(1, 4_000_000 // max(1, len(lags)))
    for start in range(0, len(omegas), chunk):
        w = omegas[start: start + chunk]
        out[start: start + chunk] = correlation[0] + 2 * np.cos(np.outer(w, lags)) @ correlation[1:]
    return np.clip(out, 0.0, None)


def frequency_grid(poles: np.ndarray, dt: float, widths) -> np.ndarray:
    """Sorted nodes in [0, pi] for the trapezoid rule (see the module docstring)."""
    nodes = [np.linspace(0.0, np.pi, UNIFORM_NODES + 1)]
    low = min(np.pi, 12.0 * dt / min(widths))
    nodes.append(np.linspace(0.0, low, LOW_NODES + 1))
    spacing = np.pi / UNIFORM_NODES
    ratios = 2.0 ** (np.arange(-16, 0.5, 0.25))  # geometric offsets, 1/2^16 .. 1 of the reach
    for pole in np.atleast_1d(poles):
        distance = abs(1.0 - abs(pole))
        if distance > 20 * spacing:
            continue
        angle = abs(np.angle(pole))
        reach = 40 * max(distance, spacing)
        offsets = reach * ratios
        offsets = offsets[offsets > 1e-3 * max(distance, 1e-9)]
        nodes.append(np.clip(np.concatenate([angle - offsets, angle + offsets, [angle]]), 0.0, np.pi))
    grid = np.unique(np.concatenate(nodes))
    return grid


def trapezoid_weights(grid: np.ndarray) -> np.ndarray:
    """Weights w_i with sum_i w_i f(grid_i) ~ (1/pi) int_0^pi f."""
    weights = np.zeros(len(grid))
    steps = np.diff(grid)
    weights[:-1] += steps / 2
    weights[1:] += steps / 2
    return weights / np.pi


def split_covariance(precision: np.ndarray, tolerance: float = 1e-12):
    """Covariance factor L (Sigma = L L') of the finite part of inv(precision), and the
    directions U0 where the precision is 0 (infinite variance)."""
    values, vectors = np.linalg.eigh(precision)
    scale = max(float(np.abs(values).max(initial=0.0)), 1e-300)
    finite = values > tolerance * scale
    factor = vectors[:, finite] / np.sqrt(values[finite])
    return factor, vectors[:, ~finite]


def derivative_scales(n_orders: int, kernel_width: float) -> np.ndarray:
    """sqrt(V_kk): std of the k-th derivative of a unit-variance process of kernel width s."""
    k = np.arange(n_orders)
    odd = np.array([np.prod(np.arange(2 * j - 1, 0, -2, dtype=float)) for j in k])
    return np.sqrt(odd / (2 * kernel_width**2) ** k)


def _matrix_power_rows(rows: np.ndarray, powers: list, t: int) -> np.ndarray:
    """rows @ Phi^t from the stored powers Phi^(2^j)."""
    bit = 0
    while t:
        if t & 1:
            rows = rows @ powers[bit]
        t >>= 1
        bit += 1
    return rows


def _powers(transition: np.ndarray, count: int) -> list:
    powers = [transition]
    while len(powers) < count:
        powers.append(powers[-1] @ powers[-1])
    return powers


def _ratio(rows: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(rows, axis=1), initial=0.0))


def start_time_constant(transition: np.ndarray, readout: np.ndarray, scales: np.ndarray, dt: float,
                        level: float = np.exp(-1.0)) -> float:
    """Effective time constant [s] of the start transient seen in the order-0 estimates.

    influence(t) = max_i || (R Phi^t diag(scales))_i || is the largest effect, on an order-0
    estimate, of a start error of one natural unit per coordinate (order k of a variable in
    units of its k-th derivative's std, ``scales``; R the order-0 rows); influence(0) = 1. The
    effective time constant is the last time at which the influence is still >= 1/e: for a
    single visible mode lambda it is -dt / ln|lambda|. Modes the order-0 estimates do not see
    (the nearly free highest orders) do not count. inf when the observer is not stable or the
    influence is still >= 1/e after 2^50 samples.
    """
    if np.max(np.abs(np.linalg.eigvals(transition)), initial=0.0) >= 1.0:
        return float("inf")
    start = readout * scales[None, :]
    powers = [transition]
    values = [_ratio(start @ transition)]  # influence at t = 2^j
    while len(powers) < 51:
        powers.append(powers[-1] @ powers[-1])
        values.append(_ratio(start @ powers[-1]))
        if values[-1] < 1e-3 * level and values[-2] < 1e-3 * level:
            break
    else:
        if values[-1] >= level:
            return float("inf")
    above = [j for j, v in enumerate(values) if v >= level]
    if not above:
        return dt * (1.0 if _ratio(start) >= level else 0.0)
    j = above[-1]
    low, high = 2**j, 2 ** (j + 1)  # influence(low) >= level > influence(high)
    for _ in range(10):
        if high - low <= 1:
            break
        middle = (low + high) // 2
        if _ratio(_matrix_power_rows(start, powers, middle)) >= level:
            low = middle
        else:
            high = middle
    return low * dt


def start_influence(transition: np.ndarray, readout: np.ndarray, scales: np.ndarray, first: int,
                    last: int, points: int = 24) -> float:
    """Largest influence(t) (see start_time_constant) over t in [first, last] samples, sampled at
    ``points`` geometrically spaced times (and the ends)."""
    first, last = max(int(first), 0), max(int(last), int(first), 0)
    start = readout * scales[None, :]
    times = np.unique(np.round(np.geomspace(max(first, 1), max(last, 1), points)).astype(np.int64))
    times = np.unique(np.concatenate([[first, last], times]))
    powers = _powers(transition, max(1, int(last).bit_length()))
    return max(_ratio(_matrix_power_rows(start, powers, int(t))) for t in times)


def steady_state_error_variance(transition, window_gain, offsets, rows_x, rows_v, *, A, B, C, dt,
                                process_precision, sensor_precision, input_prior_precision,
                                process_width, sensor_width, known_inputs, input_width=None, chunk: int = 256):
    """Steady-state error variances of the order-0 states and inputs of a DEM filter, and the
    prior (stationary) variances of the same quantities, under the model of the module docstring.

    Returns (error_x (n,), error_v (r,), prior_x (n,), prior_v (r,)); inf marks a variance that
    is unbounded (a zero precision that reaches the estimate, a plant pole on or outside the unit
    circle that the filter does not cancel). With known inputs the input entries are 0.
    """
    from attend.models.linear import zero_order_hold

    n, r = A.shape[0], B.shape[1]
    Ad, Bd = zero_order_hold(A, B, dt)
    plant_poles = np.linalg.eigvals(Ad)
    if np.any(np.abs(plant_poles) > 1 + 1e-9):
        infinite = np.full(n, np.inf)
        return infinite, np.full(r, 0.0 if known_inputs else np.inf), infinite, np.full(r, 0.0 if known_inputs else np.inf)
    on_circle = np.abs(np.angle(plant_poles[np.abs(np.abs(plant_poles) - 1) < 1e-9]))
    input_width = process_width if input_width is None else input_width
    widths = [process_width, sensor_width] + ([] if known_inputs else [input_width])
    grid = frequency_grid(np.concatenate([np.linalg.eigvals(transition), plant_poles]), dt, widths)
    for angle in on_circle:
        grid = grid[np.abs(grid - angle) > 1e-9]
    weights = trapezoid_weights(grid)
    spectra = _ErrorSpectra(transition, window_gain, offsets, rows_x, rows_v, Ad, Bd, C, dt,
                            process_precision, sensor_precision, input_prior_precision,
                            process_width, sensor_width, input_width, known_inputs)
    r_v = len(rows_v)  # 0 with known inputs
    error_x, error_v, prior_x, prior_v = np.zeros(n), np.zeros(r_v), np.zeros(n), np.zeros(r_v)
    unbounded_x, unbounded_v, unbounded_prior = np.zeros(n), np.zeros(r_v), np.zeros(n)
    for start in range(0, len(grid), chunk):
        omegas, w = grid[start: start + chunk], weights[start: start + chunk]
        ex, ev, px, pv, ux, uv, upx = spectra(omegas)
        error_x += w @ ex
        error_v += w @ ev
        prior_x += w @ px
        prior_v += w @ pv
        unbounded_x += w @ ux
        unbounded_v += w @ uv
        unbounded_prior += w @ upx
    # zero precisions (infinite noise variance) that reach an estimate make its error unbounded
    error_x[unbounded_x > 1e-12 * np.maximum(unbounded_prior, 1e-300)] = np.inf
    error_v[unbounded_v > 1e-12] = np.inf
    prior_x[unbounded_prior > 0] = np.inf
    if spectra.Uu.shape[1]:
        prior_v[np.sum(spectra.Uu**2, axis=1) > 1e-12] = np.inf
    # a plant pole on the unit circle: the variance is unbounded where the integrand grows like
    # 1 / distance^2 towards the pole (the filter does not cancel it)
    for angle in on_circle:
        side = -1.0 if angle > np.pi / 2 else 1.0
        near = [a[0] for a in spectra(np.array([angle + side * 1e-5]))[:4]]
        nearer = [a[0] for a in spectra(np.array([angle + side * 1e-6]))[:4]]
        for variance, a, b in zip((error_x, error_v, prior_x, prior_v), near, nearer):
            variance[b > 10 * np.maximum(a, 1e-300)] = np.inf
    if known_inputs:
        return error_x, np.zeros(r), prior_x, np.zeros(r)
    return error_x, error_v, prior_x, prior_v


class _ErrorSpectra:
    """The integrand of :func:`steady_state_error_variance`: per frequency, the power spectra of the
    error and of the prior of the order-0 states and inputs (the arguments as there; Ad, Bd the
    plant's zero-order hold)."""

    def __init__(self, transition, window_gain, offsets, rows_x, rows_v, Ad, Bd, C, dt,
                 process_precision, sensor_precision, input_prior_precision,
                 process_width, sensor_width, input_width, known_inputs):
        n, r, m = Ad.shape[0], Bd.shape[1], C.shape[0]
        size = transition.shape[0]
        self.transition, self.offsets, self.rows_x, self.rows_v = transition, offsets, rows_x, rows_v
        self.Ad, self.Bd, self.C, self.dt, self.known_inputs = Ad, Bd, C, dt, known_inputs
        self.process_width, self.sensor_width, self.input_width = process_width, sensor_width, input_width
        self.Lw, self.Uw = split_covariance(process_precision)
        self.Lz, _ = split_covariance(sensor_precision)  # a sensor of precision 0 gets gain 0 from DEM
        if known_inputs:
            self.Lu, self.Uu = np.zeros((r, 0)), np.zeros((r, 0))
        else:
            self.Lu, self.Uu = split_covariance(input_prior_precision)
        self.gains = window_gain.reshape(size, len(offsets), -1)[:, :, :m]  # (size, n_offsets, m)
        self.identity_x, self.identity_v = np.eye(n), np.eye(r)

    def __call__(self, omegas):
        """Per-frequency (error_x, error_v, prior_x, prior_v, unbounded_x, unbounded_v,
        unbounded_prior), unweighted."""
        dt, identity_x, identity_v = self.dt, self.identity_x, self.identity_v
        Lw, Uw, Lz, Lu, Uu = self.Lw, self.Uw, self.Lz, self.Lu, self.Uu
        size, n = self.transition.shape[0], self.Ad.shape[0]
        z = np.exp(1j * omegas)
        G = np.einsum("soc,ko->ksc", self.gains, np.exp(1j * np.outer(omegas, self.offsets)))
        H = np.linalg.solve(np.eye(size)[None] - self.transition[None] / z[:, None, None], G)
        RxHy, RvHy = H[:, self.rows_x, :], H[:, self.rows_v, :]
        P = np.linalg.solve(z[:, None, None] * identity_x[None] - self.Ad[None],
                            np.broadcast_to(identity_x, (len(z), n, n)))
        Sw = kernel_spectrum(omegas, dt, self.process_width)
        Sz = kernel_spectrum(omegas, dt, self.sensor_width)
        through_y = np.einsum("kim,mj->kij", RxHy, self.C) - identity_x  # R_x H_y C - I
        v_through_y = np.einsum("kim,mj->kij", RvHy, self.C)
        power = lambda E, L: np.sum(np.abs(E @ L) ** 2, axis=-1)  # noqa: E731
        Pw = P * dt
        ex = power(through_y @ Pw, Lw) * Sw[:, None] + power(RxHy, Lz) * Sz[:, None]
        ev = power(v_through_y @ Pw, Lw) * Sw[:, None] + power(RvHy, Lz) * Sz[:, None]
        px = power(Pw, Lw) * Sw[:, None]
        pv = np.zeros((len(z), len(self.rows_v)))
        ux = power(through_y @ Pw, Uw) * Sw[:, None]
        uv = power(v_through_y @ Pw, Uw) * Sw[:, None]
        upx = power(Pw, Uw) * Sw[:, None]
        if not self.known_inputs:
            Su = process_spectrum(omegas, dt, self.input_width)
            PB = P @ self.Bd
            ex_u = through_y @ PB
            ev_u = v_through_y @ PB - identity_v
            ex += power(ex_u, Lu) * Su[:, None]
            ev += power(ev_u, Lu) * Su[:, None]
            px += power(PB, Lu) * Su[:, None]
            pv += np.sum(Lu**2, axis=1)[None, :] * Su[:, None]
            ux += power(ex_u, Uu) * Su[:, None]
            uv += power(ev_u, Uu) * Su[:, None]
            upx += power(PB, Uu) * Su[:, None]
        return ex, ev, px, pv, ux, uv, upx


def marginal_variances(precision: np.ndarray, indices: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Diagonal entries of inv(precision) at ``indices`` (inf where the coordinate has a component
    in the null space), computed on the Jacobi-scaled matrix diag(scale)^-1/2 P diag(scale)^-1/2."""
    root = np.sqrt(scale)
    scaled = precision / np.outer(root, root)
    values, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    keep = values > 1e-13 * max(values.max(initial=0.0), 1e-300)
    rows = vectors[indices]
    null_weight = np.sum(rows[:, ~keep] ** 2, axis=1)
    variance = np.sum(rows[:, keep] ** 2 / values[keep], axis=1) / scale[indices]
    return np.where(null_weight > 1e-8, np.inf, variance)


def not_informed_by_outputs(observer) -> np.ndarray:
    """Generalised observability given the precisions: order-0 coordinate i is not informed
    by the outputs when its conditional variance, diag(inv(Pi_X)), is the same (to 0.1 %) with
    the sensory term C~' Vy C~ removed from Pi_X (or is unbounded either way).

    observer: the DEMObserver; returns one flag per order-0 state and unknown input.
    """
    mats = observer.generalized_matrices()
    rows_x, rows_v = observer.order0_rows
    indices = np.concatenate([rows_x, rows_v])
    Pi_X = mats["Pi_X"]
    without = Pi_X.copy()
    n_x = mats["Ct"].shape[1]
    without[:n_x, :n_x] -= mats["Ct"].T @ mats["Vy"] @ mats["Ct"]
    scale = np.clip(np.diag(Pi_X), 1e-300, None)
    with_data = marginal_variances(Pi_X, indices, scale)
    no_data = marginal_variances(without, indices, scale)
    with np.errstate(invalid="ignore"):
        return ~np.isfinite(with_data) | (with_data >= 0.999 * no_data)


def observer_error_std(observer, names) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Steady-state error std of a stable DEM observer's order-0 states and unknown inputs
    (:func:`steady_state_error_variance`), NaN where the outputs do not inform them.

    A quantity is uninformed when its error variance is unbounded or above UNOBSERVABLE_RATIO
    times its prior variance, or :func:`not_informed_by_outputs` flags it (inputs with prior
    precision >= PINNED_INPUT_PRECISION count as given). observer: the DEMObserver; names: the
    names of the states and unknown inputs, in order. Returns (std, prior variances, names of
    the uninformed ones).
    """
    mats, system, n = observer.generalized_matrices(), observer.system, observer.system.n_states
    rows_x, rows_v = observer.order0_rows
    lag = 1 if getattr(observer, "integration", "attend") == "spm" else 0  # row k reports X[k - 1]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        error_x, error_v, prior_x, prior_v = steady_state_error_variance(
            mats["transition"], mats["window_gain"], mats["offsets"] - lag, rows_x, rows_v,
            A=system.A, B=system.B, C=system.C, dt=observer.dt,
            process_precision=observer.process_precision, sensor_precision=observer.sensor_precision,
            input_prior_precision=observer.input_prior_precision,
            process_width=observer.process_kernel_width, sensor_width=observer.sensor_kernel_width,
            input_width=observer.input_kernel_width, known_inputs=observer.known_inputs,
        )
    errors = np.concatenate([error_x, error_v if not observer.known_inputs else []])
    priors = np.concatenate([prior_x, prior_v if not observer.known_inputs else []])
    with np.errstate(invalid="ignore", over="ignore"):
        structural = not_informed_by_outputs(observer)
        if not observer.known_inputs:  # measured inputs passed as pinned unknowns are given
            structural[n:] &= np.diag(observer.input_prior_precision) < PINNED_INPUT_PRECISION
        uninformed = ~np.isfinite(errors) | (errors > UNOBSERVABLE_RATIO * priors) | structural
    unobservable = tuple(name for name, bad in zip(names, uninformed) if bad)
    std = np.where(uninformed, np.nan, np.sqrt(np.where(uninformed, 0.0, errors)))
    return std, priors, unobservable
