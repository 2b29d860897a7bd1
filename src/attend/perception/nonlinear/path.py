"""Path mode of nonlinear DEM: one trajectory for the whole log, by Gauss-Newton on its free energy.

The D-step (:mod:`attend.perception.nonlinear.dem`) gives every sample its own generalised state
X_k and moves it by a gradient flow that sees only the embedding window around sample k: a
filter in generalised coordinates, about p/2 samples into the future. Path mode ties the
generalised states to one sampled trajectory z = (x_t, v_t), t = 0..N-1 (v only for unknown
inputs), exactly as the embedding ties y~ to the sampled outputs::

    X_c = [E_p x_window(c); E_d v_window(c)]     (E: the embedding weights, window centred on c)

and maximises the D-step's free energy summed over every centre c whose windows lie in the log::

    F(z) = -1/2 sum_c e_c' Pi~ e_c,   e_c = [y~_c - g~(X_c); D X_c - f~(X_c); v~_c - eta~_c]

with the D-step's own errors, precisions Pi~ = blkdiag(S_p Pi_z, S_p Pi_w, S_d P_v) and
Jacobians (:meth:`NonlinearDEM.errors`). Each window's Jacobian J_c = (de_c/dX_c) (dX_c/dz_window)
touches W consecutive samples, so the Gauss-Newton curvature H = sum_c J_c' Pi~ J_c is block
tridiagonal in blocks of W samples: each Levenberg-Marquardt step solves
(H + lambda diag H) dz = -grad in O(N) (:mod:`attend.perception.block_tridiagonal`), and a step
is kept only if F rises. The start is the D-step's estimate.

For a linear model the maximiser is a smoother: on the mass-spring-damper its state SSE is
1.00x (s/dt = 1), 1.02x (2) and 0.99x (4) that of the exact Gaussian posterior mean, where the
D-step's is 5.4x, 2.3x and 1.3x (benchmarks/bench_nonlinear.py part 5).

Uncertainty: every datum enters p + 1 windows, so inv(H) is not a posterior covariance (it is
too small, by a factor that depends on s/dt). The reported std is instead the spread of the
estimator itself under the generative model, linearised at the estimate (a sandwich)::

    z_hat - z = -inv(H) sum_c J_c' Pi~ eps_c,   Cov = inv(H) Var(sum_c J_c' Pi~ eps_c) inv(H)

with eps_c the embedded coloured noises of window c (sensor z ~ inv(Pi_z), process w ~ inv(Pi_w),
input deviations ~ inv(P_v), kernels of width s and s_v); Var is estimated from
``uncertainty_draws`` draws of those noises (relative error about 1/sqrt(2 draws)).
"""

from __future__ import annotations

import warnings

import numpy as np

from attend._progress import steps
from attend._threads import single_blas_thread
from attend._validation import AttendInputError
import attend.perception.block_tridiagonal as block_tridiagonal
from attend.models.linear import ModelWarning
from attend.models.noise import coloured_noise
from attend.models.nonlinear import evaluate_many
from attend.perception.dem import DEMEstimate
from attend.perception.nonlinear.misfit import check_excursion, warn_if_misfit
from attend.perception.nonlinear.path_starts import smoother_start

CHUNK = 1024  # centres whose Jacobians are held in memory at once


class _Layout:
    """Where each centre's window sits in the trajectory, and the map from a window of samples
    to the generalised coordinates X_c. dem: the :class:`NonlinearDEM`; n_samples: N."""

    def __init__(self, dem, n_samples: int):
        mats = dem.generalized_matrices()
        n, r, p, d, _ = mats["sizes"]
        self.n, self.r = n, r
        self.estimates_inputs = mats["estimates_inputs"]
        self.q = n + (r if self.estimates_inputs else 0)  # unknowns per sample
        offsets = mats["offsets"]
        self.W = len(offsets)  # samples per window (= samples per block)
        self.y_positions, self.u_positions = mats["y_positions"], mats["u_positions"]
        self.Ey, self.Eu = mats["Ey"], mats["Eu"]
        self.starts = np.arange(n_samples - self.W + 1)  # first sample of each window
        self.centres = self.starts - offsets[0]
        self.n_blocks = -(-n_samples // self.W) + 1  # blocks of W samples, one spare at the end
        n_x = n * (p + 1)
        M = np.zeros((n_x + (r * (d + 1) if self.estimates_inputs else 0), self.W * self.q))
        for j, position in enumerate(self.y_positions):  # X[k n + i] = sum_j Ey[k, j] x[window j, i]
            for i in range(n):
                M[np.arange(p + 1) * n + i, position * self.q + i] = self.Ey[:, j]
        if self.estimates_inputs:
            for j, position in enumerate(self.u_positions):
                for i in range(r):
                    M[n_x + np.arange(d + 1) * r + i, position * self.q + n + i] = self.Eu[:, j]
        self.window_map = M
        self.precision = _block_diagonal(mats["Pi"])

    def windows(self, series: np.ndarray, positions: np.ndarray, weights: np.ndarray, starts) -> np.ndarray:
        """Embedded windows (C, orders * channels) of ``series`` (N, channels) for window starts
        ``starts``: weights (orders, len(positions)) applied to the samples at starts + positions."""
        samples = series[starts[:, None] + positions[None, :]]  # (C, len(positions), channels)
        return np.einsum("kj,cjm->ckm", weights, samples).reshape(len(starts), -1)


def _block_diagonal(blocks) -> np.ndarray:
    """blkdiag of the square matrices ``blocks``."""
    size = sum(block.shape[0] for block in blocks)
    out = np.zeros((size, size))
    start = 0
    for block in blocks:
        stop = start + block.shape[0]
        out[start:stop, start:stop] = block
        start = stop
    return out


def _linearized_errors(dem, X_all, y_tilde, u_tilde, jacobians: bool):
    """:meth:`NonlinearDEM.errors` of many windows at once for motion="linearized" (the same
    numbers): only f, g and their Jacobians are called per window (all windows in one call of f and
    one of g for a vectorized system, :func:`attend.models.nonlinear.evaluate_many`).
    Returns (e (C, n_e), E or None)."""
    mats, system = dem.generalized_matrices(), dem.system
    n, r, p, d, top = mats["sizes"]
    C = len(X_all)
    x = X_all[:, : n * (p + 1)].reshape(C, p + 1, n)
    estimates_inputs = mats["estimates_inputs"]
    v = (X_all[:, n * (p + 1):] if estimates_inputs else u_tilde).reshape(C, d + 1, r)
    f0, g0, fx, fv, gx, gv = evaluate_many(system, x[:, 0], v[:, 0])
    g_t = np.einsum("ckn,cmn->ckm", x, gx)
    f_t = np.einsum("ckn,cmn->ckm", x, fx)
    if r:
        v_pad = np.zeros((C, p + 1, r))
        v_pad[:, :top] = v[:, :top]
        g_t += np.einsum("ckr,cmr->ckm", v_pad, gv)
        f_t += np.einsum("ckr,cmr->ckm", v_pad, fv)
    g_t[:, 0] = g0
    f_t[:, 0] = f0
    motion_error = np.empty((C, p + 1, n))
    motion_error[:, :-1] = x[:, 1:] - f_t[:, :-1]
    motion_error[:, -1] = 0.0 if dem.integration == "spm" else -f_t[:, -1]
    parts = [y_tilde - g_t.reshape(C, -1), motion_error.reshape(C, -1)]
    if estimates_inputs:
        parts.append(X_all[:, n * (p + 1):] - u_tilde)
    e = np.concatenate(parts, axis=1)
    if not jacobians:
        return e, None
    E = np.repeat(mats["E_template"][None], C, axis=0)
    flat = E.reshape(C, -1)
    places = mats["E_places"]
    flat[:, places["gx"]] = -gx[:, None]
    flat[:, places["fx"]] = -fx[:, None]
    if estimates_inputs:
        flat[:, places["gv"]] = -gv[:, None]
        flat[:, places["fv"]] = -fv[:, None]
    return e, E


def _errors(dem, layout: _Layout, z: np.ndarray, y_tilde, u_tilde, starts, jacobians: bool):
    """Errors e_c (C, n_e) of the windows starting at ``starts`` and, with ``jacobians``, their
    J_c = de_c/dz_window (C, n_e, W q). z: (N_padded, q) the trajectory; y_tilde, u_tilde: the
    embedded data of those windows."""
    W, q = layout.W, layout.q
    X_all = z[starts[:, None] + np.arange(W)[None, :]].reshape(len(starts), W * q) @ layout.window_map.T
    if dem.motion == "linearized":
        e, E = _linearized_errors(dem, X_all, y_tilde, u_tilde, jacobians)
        if not np.isfinite(e).all():
            raise AttendInputError("NonlinearDEM (states='path'): a prediction error became non-finite; check f/g "
                                   "or start nearer the data (initial_state)")
        return e, (E @ layout.window_map if jacobians else None)
    errors, jacobian_rows = [], []
    for X, yt, ut in zip(X_all, y_tilde, u_tilde):
        e, E, _ = dem.errors(X, yt, ut)
        errors.append(e)
        if jacobians:
            jacobian_rows.append(E)
    e = np.array(errors)
    if not np.isfinite(e).all():
        raise AttendInputError("NonlinearDEM (states='path'): a prediction error became non-finite; check f/g "
                               "or start nearer the data (initial_state)")
    return e, (np.array(jacobian_rows) @ layout.window_map if jacobians else None)


def _accumulate(layout: _Layout, starts, blocks, vectors, Dg, Off, rhs) -> None:
    """Add each window's curvature block (C, Wq, Wq) and right-hand sides (C, Wq, k) into the
    block-tridiagonal Dg (K, b, b), Off (K - 1, b, b) and rhs (K, b, k), b = W q."""
    W, q = layout.W, layout.q
    b = W * q
    block_of, offset_of = starts // W, starts % W
    for offset in range(W):
        chosen = offset_of == offset
        if not chosen.any():
            continue
        k = block_of[chosen]  # distinct blocks for one offset
        rows = slice(offset * q, (offset + W) * q)
        if blocks is not None:
            padded = np.zeros((len(k), 2 * b, 2 * b))
            padded[:, rows, rows] = blocks[chosen]
            Dg[k] += padded[:, :b, :b]
            Dg[k + 1] += padded[:, b:, b:]
            Off[k] += padded[:, b:, :b]
        padded_rhs = np.zeros((len(k), 2 * b, vectors.shape[-1]))
        padded_rhs[:, rows] = vectors[chosen]
        rhs[k] += padded_rhs[:, :b]
        rhs[k + 1] += padded_rhs[:, b:]


class _Problem:
    """F(z), its gradient and Gauss-Newton curvature over the whole log (module docstring).
    dem: the NonlinearDEM; y: (N, m) outputs; u: (N, r) known inputs or the prior mean eta;
    initial_prior: (mean, precision) of the first sample's states, each (n,), or None."""

    def __init__(self, dem, y: np.ndarray, u: np.ndarray, initial_prior=None):
        self.dem = dem
        self.initial_prior = initial_prior  # (mean (n,), precision (n,)) of x_0, or None
        self.n_samples = len(y)
        self.final_cost = np.nan  # -F at the estimate (set by _optimise)
        self.layout = layout = _Layout(dem, len(y))
        self.padded = layout.n_blocks * layout.W
        self.y_tilde = layout.windows(y, layout.y_positions, layout.Ey, layout.starts)
        self.u_tilde = layout.windows(u, layout.u_positions, layout.Eu, layout.starts)
        self.free_inputs = self._inputs_outside_every_window(u)

    def _inputs_outside_every_window(self, u):
        """(samples t, channels j, prior means eta, prior precisions P) of the unknown inputs that no
        input window reaches (the first and last few samples when d < p): the input prior alone
        informs them (-F gains 1/2 P (v - eta)^2 for each)."""
        layout = self.layout
        if not layout.estimates_inputs:
            return None
        covered = np.zeros(self.n_samples, dtype=bool)
        for position in layout.u_positions:
            covered[layout.starts + position] = True
        samples = np.flatnonzero(~covered)
        precision = np.diag(self.dem.input_prior_precision)
        t, j = np.repeat(samples, layout.r), np.tile(np.arange(layout.r), len(samples))
        return t, j, u[t, j], precision[j]

    def add_priors(self, z, Dg, rhs) -> float:
        """Add the priors outside the windows to the curvature blocks Dg (K, b, b) and the gradient
        rhs (K, b) (in place): unknown inputs no window reaches (1/2 P (v - eta)^2) and the optional
        prior on x_0 (1/2 (x_0 - m)' P_0 (x_0 - m)); returns their share of -F. z: (N_padded, q)."""
        layout = self.layout
        b = layout.W * layout.q
        total = 0.0
        if self.free_inputs is not None and len(self.free_inputs[0]):
            t, j, eta, precision = self.free_inputs
            deviation = z[t, layout.n + j] - eta
            total += 0.5 * float(np.sum(precision * deviation**2))
            flat = t * layout.q + layout.n + j  # places in the (K, b) block vector
            np.add.at(rhs, (flat // b, flat % b), precision * deviation)
            Dg[flat // b, flat % b, flat % b] += precision
        if self.initial_prior is not None:
            mean, precision = self.initial_prior
            deviation = z[0, : layout.n] - mean
            total += 0.5 * float(np.sum(precision * deviation**2))
            rhs[0, : layout.n] += precision * deviation
            Dg[0, np.arange(layout.n), np.arange(layout.n)] += precision
        return total

    def prior_draws(self, count: int, rng) -> list:
        """(flat places in the (K, b) vector, draws (places, count)) of the priors' gradients
        P (v - eta) ~ N(0, P) and P_0 (x_0 - m) ~ N(0, P_0), for the std's sandwich."""
        layout = self.layout
        out = []
        if self.free_inputs is not None and len(self.free_inputs[0]):
            t, j, _, precision = self.free_inputs
            out.append((t * layout.q + layout.n + j, np.sqrt(precision)[:, None] * rng.standard_normal((len(t), count))))
        if self.initial_prior is not None:
            precision = self.initial_prior[1]
            out.append((np.arange(layout.n), np.sqrt(precision)[:, None] * rng.standard_normal((layout.n, count))))
        return out

    def chunks(self):
        for first in range(0, len(self.layout.starts), CHUNK):
            yield slice(first, first + CHUNK)

    def curvature(self, z):
        """(-F, Dg, Off, gradient of -F (K, b)) at z (N_padded, q): -F = 1/2 sum_c e_c' Pi~ e_c and
        H = sum_c J_c' Pi~ J_c in blocks."""
        layout = self.layout
        b = layout.W * layout.q
        K = layout.n_blocks
        Dg, Off, rhs = np.zeros((K, b, b)), np.zeros((K - 1, b, b)), np.zeros((K, b, 1))
        total = 0.0
        for part in self.chunks():
            starts = layout.starts[part]
            e, J = _errors(self.dem, layout, z, self.y_tilde[part], self.u_tilde[part], starts, jacobians=True)
            weighted = layout.precision @ J  # Pi~ J_c
            total += 0.5 * np.einsum("ci,ij,cj->", e, layout.precision, e)
            _accumulate(layout, starts, np.swapaxes(J, 1, 2) @ weighted,
                        np.einsum("cia,ci->ca", weighted, e)[:, :, None], Dg, Off, rhs)
        total += self.add_priors(z, Dg, rhs[..., 0])
        _fill_unused(Dg)
        return total, Dg, Off, rhs[..., 0]


def _fill_unused(Dg) -> None:
    """Put 1 on the diagonal of Dg (K, b, b) where nothing enters (the padding after the log's end),
    so that the block Cholesky exists; those coordinates keep their value (zero gradient)."""
    K, b, _ = Dg.shape
    unused = np.flatnonzero(np.einsum("kii->ki", Dg).ravel() == 0)
    Dg.reshape(K, b * b)[unused // b, (unused % b) * (b + 1)] = 1.0


def _solve(Dg, Off, rhs, damping: float):
    """(H + damping diag H)^{-1} rhs for rhs (K, b) or (R, K, b); None if not positive definite."""
    damped = Dg.copy()
    diagonal = np.einsum("kii->ki", damped)
    diagonal *= 1.0 + damping
    try:
        _, Bk, Linv = block_tridiagonal.cholesky(damped[None], Off[None])
    except np.linalg.LinAlgError:
        return None
    many = rhs if rhs.ndim == 3 else rhs[None]
    shape = (len(many),) + Linv.shape[1:]
    solution = block_tridiagonal.solve(np.broadcast_to(Linv, shape), np.broadcast_to(Bk, (len(many),) + Bk.shape[1:]),
                                       many)
    return solution if rhs.ndim == 3 else solution[0]


def _optimise(problem: _Problem, z: np.ndarray, max_iterations: int, tolerance: float):
    """Levenberg-Marquardt on -F from z; returns (z, curvature blocks at z, iterations, converged);
    the last -F is kept in ``problem.final_cost``."""
    q = problem.layout.q
    cost, Dg, Off, gradient = problem.curvature(z)
    damping = 1e-3
    for iteration in steps(range(1, max_iterations + 1), "path mode: Levenberg-Marquardt", unit="step"):
        while True:
            step = _solve(Dg, Off, -gradient, damping)
            trial = None
            if step is not None:
                candidate = z + step.reshape(-1, q)[: len(z)]
                try:
                    trial = problem.curvature(candidate)
                except AttendInputError:
                    trial = None
            if (trial is not None and trial[0] <= cost) or damping > 1e10:
                break
            damping = max(10.0 * damping, 1e-9)
        if trial is None or not trial[0] <= cost:  # no step lowers -F: z is the maximiser
            problem.final_cost = cost
            return z, (Dg, Off), iteration, True
        decrease = cost - trial[0]
        z = candidate
        cost, Dg, Off, gradient = trial
        damping = damping / 10.0 if damping > 1e-12 else 0.0  # Gauss-Newton once the steps succeed
        if decrease <= tolerance * max(1.0, cost):
            problem.final_cost = cost
            return z, (Dg, Off), iteration, True
    problem.final_cost = cost
    return z, (Dg, Off), max_iterations, False


def _noise_sources(dem, layout: _Layout):
    """(precision, kernel width, embedding weights, window positions) of each noise the windows
    carry: sensor, process and (unknown inputs) the input prior's fluctuations."""
    sources = [(dem.sensor_precision, dem.kernel_width, layout.Ey, layout.y_positions),
               (dem.process_precision, dem.kernel_width, layout.Ey, layout.y_positions)]
    if layout.estimates_inputs:
        sources.append((dem.input_prior_precision, dem.input_kernel_width or dem.kernel_width, layout.Eu,
                        layout.u_positions))
    return sources


def _draw_noises(dem, layout: _Layout, n_samples: int, count: int, rng) -> list:
    """count draws of each noise (N, count, channels): coloured, scaled by the inverse precision."""
    out = []
    for precision, width, _, _ in _noise_sources(dem, layout):
        channels = len(precision)
        noise = coloured_noise(n_samples, count * channels, dem.dt, width, 1.0, rng)
        out.append(noise.reshape(n_samples, count, channels) @ _inverse_root(precision).T)
    return out


def _embedded_noises(dem, layout: _Layout, noises: list, starts) -> np.ndarray:
    """The window errors eps_c (count, C, n_e) of the windows starting at ``starts``, from the
    noise draws of :func:`_draw_noises` (top-order motion error 0 with integration="spm")."""
    parts = []
    for noise, (_, _, weights, positions) in zip(noises, _noise_sources(dem, layout)):
        samples = noise[starts[:, None] + positions[None, :]]  # (C, window, R, channels)
        embedded = np.einsum("kj,cjrm->rckm", weights, samples)
        parts.append(embedded.reshape(noise.shape[1], len(starts), -1))
    if dem.integration == "spm":
        parts[1][:, :, -layout.n:] = 0.0
    return np.concatenate(parts, axis=2)


def _inverse_root(precision) -> np.ndarray:
    """A square root L of inv(precision) (L L' = inv(precision))."""
    return np.linalg.cholesky(np.linalg.inv(precision))


#: floats of Jacobians kept between noise batches (beyond it they are recomputed per batch)
JACOBIAN_BUDGET = 25_000_000
#: floats of noise samples drawn at once
NOISE_BUDGET = 10_000_000


def _spread(problem: _Problem, z, curvature, draws: int, seed) -> np.ndarray:
    """std (N, q) of z_hat - z under the generative model, linearised at z (module docstring):
    noise drawn in batches, each window chunk's Pi~ J_c computed once when they fit in memory."""
    layout, dem = problem.layout, problem.dem
    Dg, Off = curvature
    rng = np.random.default_rng(seed)
    channels = sum(len(source[0]) for source in _noise_sources(dem, layout))
    batch = max(1, min(draws, int(NOISE_BUDGET // max(1, problem.n_samples * channels))))
    n_e = layout.precision.shape[0]
    keep = len(layout.starts) * n_e * layout.W * layout.q <= JACOBIAN_BUDGET
    kept = {}

    def weighted_jacobian(index, part):
        if index in kept:
            return kept[index]
        _, J = _errors(dem, layout, z, problem.y_tilde[part], problem.u_tilde[part], layout.starts[part], True)
        weighted = layout.precision @ J
        if keep:
            kept[index] = weighted
        return weighted

    total = np.zeros((layout.n_blocks, layout.W * layout.q))
    done = 0
    while done < draws:
        count = min(batch, draws - done)
        noises = _draw_noises(dem, layout, problem.n_samples, count, rng)
        rhs = np.zeros((layout.n_blocks, layout.W * layout.q, count))
        for index, part in enumerate(problem.chunks()):
            eps = _embedded_noises(dem, layout, noises, layout.starts[part])
            _accumulate(layout, layout.starts[part], None,
                        np.einsum("cia,rci->car", weighted_jacobian(index, part), eps), None, None, rhs)
        for places, values in problem.prior_draws(count, rng):
            rhs.reshape(-1, count)[places] += values
        deviation = _solve(Dg, Off, np.moveaxis(rhs, 2, 0), 0.0)
        if deviation is None:  # the curvature is singular to rounding: some direction is not informed
            warnings.warn("NonlinearDEM (states='path'): the curvature at the estimate is singular (a state or "
                          "input is not informed by the data); its std is reported as NaN", ModelWarning, stacklevel=4)
            return np.full((problem.n_samples, layout.q), np.nan)
        total += np.sum(deviation**2, axis=0)
        done += count
    return np.sqrt(total / draws).reshape(-1, layout.q)[: problem.n_samples]


#: share of samples whose two ends lie more than 2 std apart above which F is said to have several maxima
SEVERAL_MAXIMA_SHARE = 0.01


def _warn_if_several_maxima(ends, best, std, n_samples: int) -> None:
    """Warn when the two starts ended at different maxima of F: more than SEVERAL_MAXIMA_SHARE of
    the samples with |z_1 - z_2| > 2 std in some coordinate. The std is the spread about the kept
    maximum only and is then too small (random nonlinear bank: 68-92 % of the errors within 2 std
    in the 6 of 36 cases that warned, ~95 % in the others but one)."""
    if len(ends) < 2 or not np.all(np.isfinite(std)):
        return
    first, second = (end[0][0][:n_samples] for end in ends)
    apart = float(np.mean(np.any(np.abs(first - second) > 2 * std, axis=1)))
    if apart > SEVERAL_MAXIMA_SHARE:
        other = max(end[1] for end in ends)
        warnings.warn(
            f"NonlinearDEM (states='path'): F has more than one maximum on this log: the starts from the D-step and "
            f"from the unscented smoother ended more than 2 std apart at {apart:.0%} of the samples (F differs by "
            f"{other - best[1]:.3g}); the larger F is kept, and its std covers the spread about that maximum only "
            "(too small where the other maximum is close: check the estimate against the unscented smoother)",
            ModelWarning, stacklevel=4)


def _initial_prior(n: int, initial_state, initial_state_std):
    """(mean, precision) of the prior on x_0 from initial_state (n,) and its std (scalar or (n,),
    > 0), or None without a std; an AttendInputError naming the argument otherwise."""
    if initial_state_std is None:
        return None
    if initial_state is None:
        raise AttendInputError("initial_state_std: given without initial_state (the prior mean of x[0])")
    mean = np.asarray(initial_state, dtype=float).ravel()
    std = np.broadcast_to(np.asarray(initial_state_std, dtype=float), (n,)) if np.ndim(initial_state_std) == 0 \
        else np.asarray(initial_state_std, dtype=float).ravel()
    if mean.shape != (n,) or std.shape != (n,):
        raise AttendInputError(f"initial_state, initial_state_std: expected {n} values each (one per state), got "
                               f"{mean.shape[0]} and {std.shape[0]}")
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0)):
        raise AttendInputError(f"initial_state_std: expected finite stds > 0 [state units] (a known x[0]: a small "
                               f"std), got {std.tolist()}")
    return mean, 1.0 / std**2


def _warn_if_misfit(problem: _Problem) -> None:
    """:func:`attend.perception.nonlinear.misfit.warn_if_misfit` with -F at the estimate over
    1/2 (windows) (error rows), what errors drawn from the model give."""
    rows = problem.layout.precision.shape[0] - (problem.layout.n if problem.dem.integration == "spm" else 0)
    warn_if_misfit(problem.final_cost / (0.5 * len(problem.layout.starts) * rows), "NonlinearDEM (states='path')", 4)


def estimate_path(dem, signals: np.ndarray, initial_state=None, *, initial_state_std=None, max_iterations: int = 50,
                  tolerance: float = 1e-10, uncertainty_draws: int = 200, seed: int = 0,
                  keep_generalized: bool = False) -> DEMEstimate:
    """Path-mode estimates (module docstring): Levenberg-Marquardt from the D-step's estimate of the
    same log and from the unscented smoother's (:mod:`attend.perception.nonlinear.path_starts`),
    the larger F kept.

    dem: a :class:`NonlinearDEM`; signals: (N, m + r) outputs then inputs (known inputs, or the
    prior mean eta), as validated by NonlinearDEM.estimate; initial_state: the D-step's start
    guess (n order-0 states) and, with initial_state_std (scalar or (n,), > 0, state units), the
    mean of a Gaussian prior on the first sample's states (default: none, x_0 free);
    max_iterations: Levenberg-Marquardt steps; tolerance: stop when -F falls by less than
    this fraction; uncertainty_draws: noise draws of the std (0: std not computed, NaN);
    seed: of those draws; keep_generalized: also return X_c at every sample (NaN where no
    window is centred). Row k is the trajectory at sample k, which uses the whole log.
    """
    m, r = dem.system.n_outputs, dem.system.n_inputs
    prior = _initial_prior(dem.system.n_states, initial_state, initial_state_std)
    start = dem.dstep_estimate(signals, dem.path_starts == "both", initial_state, check=False)
    with single_blas_thread():
        problem = _Problem(dem, signals[:, :m], signals[:, m:], prior)
        layout = problem.layout
        ends = []  # (result, -F) from each start
        smoothed = smoother_start(dem, signals, prior, start) if dem.path_starts == "both" else None
        for states, inputs in [(start.states, start.inputs)] + ([smoothed] if smoothed else []):
            z = np.zeros((problem.padded, layout.q))
            z[: problem.n_samples, : layout.n] = states
            if layout.estimates_inputs:
                z[: problem.n_samples, layout.n:] = inputs
            result = _optimise(problem, z, max_iterations, tolerance)
            ends.append((result, problem.final_cost))
        best = min(ends, key=lambda end: end[1])
        (z, curvature, iterations, converged), problem.final_cost = best
        if not converged:
            warnings.warn(f"NonlinearDEM (states='path'): not converged in {max_iterations} Gauss-Newton steps "
                          "(raise max_iterations, or check the model)", ModelWarning, stacklevel=3)
        _warn_if_misfit(problem)
        std = (_spread(problem, z, curvature, uncertainty_draws, seed) if uncertainty_draws > 0
               else np.full((problem.n_samples, layout.q), np.nan))
        _warn_if_several_maxima(ends, best, std[: problem.n_samples], problem.n_samples)
        generalized = None
        if keep_generalized:
            generalized = np.full((problem.n_samples, layout.window_map.shape[0]), np.nan)
            windows = z[layout.starts[:, None] + np.arange(layout.W)[None, :]].reshape(len(layout.starts), -1)
            generalized[layout.centres] = windows @ layout.window_map.T
    z = z[: problem.n_samples]
    n = layout.n
    if layout.estimates_inputs:
        inputs, input_std = z[:, n:], std[:, n:]
    else:
        inputs, input_std = signals[:, m:], np.zeros((problem.n_samples, r))
    check_excursion(dem, signals, z[:, :n], inputs, "NonlinearDEM (states='path')")
    return DEMEstimate(np.arange(problem.n_samples) * dem.dt, z[:, :n].copy(), inputs.copy(), std[:, :n].copy(),
                       input_std.copy(), generalized)
