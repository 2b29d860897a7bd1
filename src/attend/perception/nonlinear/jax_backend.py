"""The D-step of :class:`attend.perception.nonlinear.NonlinearDEM` compiled with JAX
(``backend="jax"``): the same equations as the NumPy step (motion="linearized",
integration="attend"), traced once per estimator and run as one compiled loop over the samples.

Per sample, at the order-0 expansion point (x, v): the Jacobians fx, fv, gx, gv by forward-mode
differentiation of the user's f and g (``jax.jacfwd``; analytic ``jacobian_f``/``jacobian_g`` and
finite differences are not used), the errors e and their Jacobian E (module docstring of
:mod:`attend.perception.nonlinear`), the gradient -E' Pi~ e and curvature E' Pi~ E, and the step

    X <- X + (expm(J) - I) inv(J) (D X_s + dF/dX_s) / S,      J = D - inv(S) E' Pi~ E inv(S)

in sample units (S = diag(dt^k); S = I and J dt with flow_time="seconds"), the exponential by
Pade 13 with scaling and squaring (Higham 2005). The estimates equal the
NumPy backend's to rounding (tests/perception/test_nonlinear_jax.py: 1e-8 relative).

f and g must be written with ``jax.numpy`` (traceable): NumPy functions cannot be traced and get
an error naming the function. JAX is optional (``pip install "attend[jax]"``, ~400 MB); it runs
in double precision inside ``jax.enable_x64`` without changing the caller's JAX settings. The
samples run in chunks of :data:`CHUNK` (one compilation per estimator, whatever the log length;
the first call traces and compiles, ~1.5-3 s). The start (Gauss-Newton), the std, the misfit
check and the excursion check's predictions are compiled too; the embedding of the data and the
final checks stay in NumPy. Lorenz (n = 3, p = 6): ~2e4 samples/s against the NumPy step's
~1.1e4 (benchmarks/bench_nonlinear.py --parts 0).
"""

from __future__ import annotations

import weakref

import numpy as np

from attend._validation import AttendInputError
from attend.perception.dem import DEMEstimate
from attend.perception.nonlinear._linalg import inverse_diagonals
from attend.perception.nonlinear.misfit import (CHECKED_WINDOWS, check_excursion, excursion_rows, misfit_rows,
                                                 warn_if_misfit)

#: samples per compiled call (the last chunk is padded with rows that are skipped)
CHUNK = 128
BACKENDS = ("numpy", "jax")
#: each estimator's compiled functions (built at its first estimate), kept as long as the estimator
_COMPILED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _import_jax():
    """The jax module, or an AttendInputError saying how to install it."""
    try:
        import jax
    except ImportError as error:
        raise AttendInputError(f"backend: 'jax' needs JAX, which is not installed ({error}); "
                               "pip install 'attend[jax]', or use backend='numpy'") from None
    return jax


def _double_precision(jax):
    """A context in which JAX computes in float64 (jax.enable_x64, or its older experimental name)."""
    if hasattr(jax, "enable_x64"):
        return jax.enable_x64(True)
    from jax.experimental import enable_x64  # pragma: no cover - older JAX
    return enable_x64(True)


def check_backend(estimator) -> None:
    """Raise an AttendInputError unless ``estimator.backend`` is usable with its settings.
    estimator: the NonlinearDEM being built."""
    if estimator.backend not in BACKENDS:
        raise AttendInputError(f"backend: expected 'numpy' or 'jax', got {estimator.backend!r}")
    if estimator.backend == "numpy":
        return
    for name, wanted in (("motion", "linearized"), ("integration", "attend"), ("states", "sample")):
        if getattr(estimator, name) != wanted:
            raise AttendInputError(f"backend: 'jax' runs the D-step with {name}='{wanted}' only (got "
                                   f"{name}={getattr(estimator, name)!r}); use backend='numpy'")
    _import_jax()


def embedded_rows(estimator, signals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(y~ (N, m (p + 1)), u~ (N, r (d + 1))) of every row, as the online estimator embeds them:
    windows clamped at the log's ends (first and last samples repeated), rows whose window reaches
    past the log as order 0 alone with edges="order0". estimator: the NonlinearDEM; signals:
    (N, m + r) outputs and inputs."""
    mats = estimator.generalized_matrices()
    m, r = estimator.system.n_outputs, estimator.system.n_inputs
    p, d = estimator.embedding_order, estimator.input_order
    offsets = mats["offsets"]
    n_samples = signals.shape[0]
    windows = signals[np.clip(np.arange(n_samples)[:, None] + offsets[None, :], 0, n_samples - 1)]
    first_y, first_u = mats["y_positions"][0], mats["u_positions"][0]
    y_tilde = np.einsum("ij,kjc->kic", mats["Ey"], windows[:, first_y: first_y + p + 1, :m])
    u_tilde = np.einsum("ij,kjc->kic", mats["Eu"], windows[:, first_u: first_u + d + 1, m:])
    if estimator.edges == "order0":
        rows = np.arange(n_samples)
        edge = (rows < -offsets[0]) | (rows >= n_samples - offsets[-1])
        y_tilde[edge] = 0.0
        u_tilde[edge] = 0.0
        y_tilde[edge, 0] = signals[edge, :m]
        u_tilde[edge, 0] = signals[edge, m:]
    return y_tilde.reshape(n_samples, -1), u_tilde.reshape(n_samples, -1)


def _traced(system, which: str):
    """f or g of ``system`` as a function of (x, v) returning a flat array (parameters bound)."""
    jnp = _import_jax().numpy
    function, size = (system.f, system.n_states) if which == "f" else (system.g, system.n_outputs)

    def traced(x, v):
        value = jnp.asarray(system.call_with_parameters(function, x, v))
        if value.size != size:
            raise AttendInputError(f"{which}: expected {size} values (a 1-D array), got shape {value.shape}")
        return jnp.reshape(value, (size,))

    return traced


# Pade 13 coefficients b_0..b_13 and its accuracy bound theta_13 (Higham 2005, as SciPy's expm)
_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
           129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
           40840800.0, 960960.0, 16380.0, 182.0, 1.0)
_THETA13 = 5.371920351148152


def _expm_last_column(jnp, lax, block):
    """expm(block)[:-1, -1] by the Pade 13 approximant of block / 2^s, s = max(0, ceil(log2(
    |block|_1 / theta_13))), squared s times (Higham 2005: backward error at unit roundoff). block:
    (k + 1, k + 1) with a zero last row, [[J, b], [0, 0]], so the last squaring needs its column only."""
    b = _PADE13
    norm = jnp.max(jnp.sum(jnp.abs(block), axis=0))
    squarings = jnp.maximum(0.0, jnp.ceil(jnp.log2(norm / _THETA13)))
    A = block / 2.0 ** squarings
    identity = jnp.eye(A.shape[0])
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * identity)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * identity
    R = jnp.linalg.solve(V - U, V + U)
    # s - 1 squarings, then only the last column of the last one: [[P, q], [0, 1]]^2 has q <- P q + q
    R = lax.fori_loop(0, jnp.maximum(squarings - 1, 0).astype(int), lambda _, M: M @ M, R)
    P, q = R[:-1, :-1], R[:-1, -1]
    return jnp.where(squarings > 0, P @ q + q, q)


def _functions(estimator):
    """Traceable (step, evaluate, misfit, g) of the estimator: step(X, y~, u~) -> (X after one D-step
    over 1/substeps of the sample, E' Pi~ E); evaluate(X, y~, u~) -> (dF/dX, E' Pi~ E, F);
    misfit(X, y~, u~) -> e' Pi~ e / dim(e) (:mod:`attend.perception.nonlinear.misfit`); g(x, v)."""
    jax = _import_jax()
    jnp = jax.numpy

    mats, system = estimator.generalized_matrices(), estimator.system
    n, r, p, d, top = mats["sizes"]
    n_x, n_v = estimator.n_state_coordinates, estimator.n_input_coordinates
    template, D_X = mats["E_template"], mats["D_X"]
    size = template.shape[1]
    starts = np.cumsum([0] + [len(block) for block in mats["Pi"]])
    blocks = list(zip(starts, mats["Pi"]))  # (first row, Vy / W / Vv)
    samples = estimator.flow_time == "samples"
    scale = mats["order_scale"] if samples else np.ones(size)
    duration = (1.0 if samples else estimator.dt) / estimator.substeps
    f, g = _traced(system, "f"), _traced(system, "g")
    jacobian_f, jacobian_g = jax.jacfwd(f, argnums=(0, 1)), jax.jacfwd(g, argnums=(0, 1))
    curvature_scale = np.outer(scale, scale)
    states_grid, inputs_grid = np.eye(p + 1), np.eye(p + 1, d + 1)  # kron(grid, J): J on the block diagonal

    def kron(grid, J):
        return (grid[:, None, :, None] * J[None, :, None, :]).reshape(grid.shape[0] * J.shape[0], -1)

    def errors(X, y_tilde, u_tilde):
        """(e, E) as NonlinearDEM._errors with motion="linearized", integration="attend"."""
        x = X[:n_x].reshape(p + 1, n)
        v = (X[n_x:] if n_v else u_tilde).reshape(d + 1, r)
        fx, fv = jacobian_f(x[0], v[0])
        gx, gv = jacobian_g(x[0], v[0])
        v_pad = jnp.concatenate([v[1:top], jnp.zeros((p + 1 - top, r))]) if p else jnp.zeros((0, r))
        g_t = jnp.concatenate([g(x[0], v[0])[None], x[1:] @ gx.T + v_pad @ gv.T])
        f_t = jnp.concatenate([f(x[0], v[0])[None], x[1:] @ fx.T + v_pad @ fv.T])
        parts = [y_tilde - g_t.ravel(), (x[1:] - f_t[:-1]).ravel(), -f_t[-1]]
        columns = [jnp.concatenate([-kron(states_grid, gx), -kron(states_grid, fx), jnp.zeros((n_v, n_x))])]
        if n_v:
            parts.append(X[n_x:] - u_tilde)
            columns.append(jnp.concatenate([-kron(inputs_grid, gv), -kron(inputs_grid, fv), jnp.zeros((n_v, n_v))]))
        return jnp.concatenate(parts), template + jnp.concatenate(columns, axis=1)

    def products(E_e):
        """[E | e]' Pi~ [E | e], Pi~ = blkdiag(Vy, W, Vv) applied block by block."""
        return sum(E_e[start: start + len(block)].T @ (block @ E_e[start: start + len(block)])
                   for start, block in blocks)

    def evaluate(X, y_tilde, u_tilde):
        e, E = errors(X, y_tilde, u_tilde)
        both = products(jnp.concatenate([E, e[:, None]], axis=1))
        return -both[:size, size], both[:size, :size], -0.5 * both[size, size]

    def misfit(X, y_tilde, u_tilde):
        e = errors(X, y_tilde, u_tilde)[0]
        return products(e[:, None])[0, 0] / e.shape[0]

    def step(X, y_tilde, u_tilde):
        gradient, curvature, _ = evaluate(X, y_tilde, u_tilde)
        flow = jnp.concatenate([(D_X - curvature / curvature_scale) * duration,
                                ((D_X @ (X * scale) + gradient / scale) * duration)[:, None]], axis=1)
        block = jnp.concatenate([flow, jnp.zeros((1, size + 1))])
        return X + _expm_last_column(jnp, jax.lax, block) / scale, curvature

    return step, evaluate, misfit, g


def _variances(jax, curvatures, reported):
    """diag(inv(C))[reported] of a stack of curvatures, by Cholesky with the reported coordinates
    last (as :func:`attend.perception.nonlinear._linalg.inverse_diagonals`; NaN where C is not
    positive definite)."""
    jnp = jax.numpy
    others = np.setdiff1d(np.arange(curvatures.shape[1]), reported)
    last = np.concatenate([others, reported])
    factor = jnp.linalg.cholesky(curvatures[:, last[:, None], last])
    k = len(reported)
    trailing = factor[:, -k:, -k:]
    inverse = jax.scipy.linalg.solve_triangular(trailing, jnp.broadcast_to(jnp.eye(k), trailing.shape), lower=True)
    return (inverse * inverse).sum(axis=1)


def _gauss_newton(jax, evaluate, X, y_tilde, u_tilde, iterations: int = 20, halvings: int = 30):
    """:func:`attend.perception.nonlinear.start.gauss_newton_start` traced: Gauss-Newton steps
    inv(C) dF/dX (Jacobi-scaled least squares) halved until F does not decrease."""
    jnp, lax = jax.numpy, jax.lax

    def solve(curvature, gradient):
        diagonal = jnp.sqrt(jnp.abs(jnp.diag(curvature)))
        d = jnp.where(diagonal > 0, 1.0 / jnp.where(diagonal > 0, diagonal, 1.0), 1.0)
        return d * jnp.linalg.lstsq(curvature * jnp.outer(d, d), gradient * d)[0]

    def halve(state):
        X, (gradient, curvature, energy), step, count, _, found = state
        candidate = evaluate(X + step, y_tilde, u_tilde)
        ok = jnp.isfinite(candidate[2]) & (candidate[2] >= energy)
        return X, (gradient, curvature, energy), jnp.where(ok, step, step / 2), count + 1, ok, \
            jax.tree_util.tree_map(lambda new, old: jnp.where(ok, new, old), candidate, found)

    def iterate(state):
        X, values, iteration, _ = state
        step = solve(values[1], values[0])
        _, _, step, _, accepted, found = lax.while_loop(lambda h: (~h[4]) & (h[3] < halvings), halve,
                                                        (X, values, step, 0, False, values))
        converged = found[2] - values[2] <= 1e-12 * jnp.maximum(1.0, jnp.abs(found[2]))
        return jnp.where(accepted, X + step, X), found, iteration + 1, (~accepted) | converged

    X, *_ = lax.while_loop(lambda state: (state[2] < iterations) & ~state[3], iterate,
                           (X, evaluate(X, y_tilde, u_tilde), 0, False))
    return X


def _compiled(estimator) -> dict:
    """The estimator's compiled functions (built once, kept in _COMPILED): run(X0, Y~, U~, real)
    -> (X after the chunk, X rows, curvatures, variances of the reported coordinates) over CHUNK
    rows; start(X, y~, u~) -> the start of the flow (Gauss-Newton from X); misfit(X rows, Y~, U~)
    -> the misfit ratio of each row; observe(X rows, V rows) -> g at each row. estimator: the
    NonlinearDEM."""
    cached = _COMPILED.get(estimator)
    if cached is not None:
        return cached
    jax = _import_jax()
    (step, evaluate, misfit, observe), substeps = _functions(estimator), estimator.substeps
    reported = estimator.generalized_matrices()["reported"]

    def advance(X, y_tilde, u_tilde):
        for _ in range(substeps):
            X, curvature = step(X, y_tilde, u_tilde)
        return X, curvature

    def body(X, data):
        y_tilde, u_tilde, real = data  # padding rows (real False) leave X as it is, at no cost
        X, curvature = jax.lax.cond(real, advance, lambda X, *_: (X, jax.numpy.eye(X.shape[0])), X, y_tilde, u_tilde)
        return X, (X, curvature)

    def run(X0, Y, U, real):
        last, (rows, curvatures) = jax.lax.scan(body, X0, (Y, U, real))
        return last, rows, curvatures, _variances(jax, curvatures, reported)

    compiled = dict(run=jax.jit(run), start=jax.jit(lambda X, y, u: _gauss_newton(jax, evaluate, X, y, u)),
                    misfit=jax.jit(jax.vmap(misfit)), observe=jax.jit(jax.vmap(observe)))
    _COMPILED[estimator] = compiled
    return compiled


def _call(function, *args):
    """function(*args), a failure to trace the user's f or g turned into an AttendInputError."""
    try:
        return function(*args)
    except AttendInputError as error:
        if "Tracer" in str(error):  # the user's code met a JAX tracer (checked in attend.io's wrapper)
            raise AttendInputError(f"{error}; backend='jax' traces f and g: write them with jax.numpy") from None
        raise
    except Exception as error:
        first_line = str(error).splitlines()[0] if str(error) else ""
        raise AttendInputError(
            f"f, g: backend='jax' traces f and g with JAX and they could not be traced ({type(error).__name__}: "
            f"{first_line}); write them with jax.numpy (jnp.stack, jnp.sin, ...) instead of NumPy, or use "
            "backend='numpy'") from None


def _flow(estimator, X0, y_tilde, u_tilde):
    """The D-step over all rows in compiled chunks: (X (N, size), curvatures (N, size, size),
    variances of the reported coordinates (N, k))."""
    run = _compiled(estimator)["run"]
    n_samples = y_tilde.shape[0]
    parts = []
    X = X0
    for start in range(0, n_samples, CHUNK):  # dispatched asynchronously, the carry passed on unread
        rows = np.arange(start, start + CHUNK)  # the last chunk padded with rows that are skipped
        index = np.minimum(rows, n_samples - 1)
        X, *outputs = _call(run, X, y_tilde[index], u_tilde[index], rows < n_samples)
        parts.append(outputs)
    return [np.concatenate([np.asarray(part) for part in column])[:n_samples] for column in zip(*parts)]


def _misfit(estimator, generalized, y_tilde, u_tilde) -> float:
    """The misfit ratio of sample_misfit at the same rows (misfit_rows), compiled."""
    rows = misfit_rows(estimator, len(generalized))
    if len(rows) == 0:
        return np.nan
    padded = np.resize(rows, 2 * CHECKED_WINDOWS)  # fewer than 2 CHECKED_WINDOWS rows: one compiled shape
    costs = np.asarray(_compiled(estimator)["misfit"](generalized[padded], y_tilde[padded], u_tilde[padded]))
    return float(np.mean(costs[: len(rows)]))


def estimate_with_jax(estimator, signals: np.ndarray, initial_state, keep_generalized: bool) -> DEMEstimate:
    """NonlinearDEM.estimate's D-step with backend="jax" (same fields and checks as the NumPy
    run). estimator: the NonlinearDEM; signals: validated (N, m + r) outputs and inputs;
    initial_state: the guess for the start; keep_generalized: also return every sample's X."""
    with _double_precision(_import_jax()):  # jax.numpy in double precision, the caller's setting kept
        return _estimate(estimator, signals, initial_state, keep_generalized)


def _estimate(estimator, signals, initial_state, keep_generalized: bool) -> DEMEstimate:
    system = estimator.system
    n, r = system.n_states, system.n_inputs
    y_tilde, u_tilde = embedded_rows(estimator, signals)
    start = _call(_compiled(estimator)["start"], estimator.generalized_guess(initial_state), y_tilde[0], u_tilde[0])
    generalized, curvatures, variances = _flow(estimator, start, y_tilde, u_tilde)
    reported = estimator.generalized_matrices()["reported"]
    bad = ~np.isfinite(generalized).all(axis=1) | (np.abs(generalized[:, reported]).max(axis=1)
                                                   > estimator.divergence_limit)
    if bad.any():
        first = int(np.argmax(bad))
        estimator.check_divergence(generalized[first], first)
    singular = ~np.isfinite(variances).all(axis=1)  # not positive definite: the NumPy route's fallback
    if singular.any():
        variances[singular] = inverse_diagonals(curvatures[singular], reported)
    std = np.sqrt(np.clip(variances, 0, None))
    warn_if_misfit(_misfit(estimator, generalized, y_tilde, u_tilde), "NonlinearDEM", 4)
    n_x = estimator.n_state_coordinates
    if estimator.estimates_inputs:
        inputs, input_std = generalized[:, n_x: n_x + r], std[:, n:]
    else:
        inputs, input_std = u_tilde[:, :r], np.zeros((len(signals), r))
    rows = excursion_rows(len(signals))
    padded = np.resize(rows, 2 * CHECKED_WINDOWS + 1)  # one compiled shape for every log
    predicted = np.asarray(_call(_compiled(estimator)["observe"], generalized[padded, :n], inputs[padded]))
    check_excursion(estimator, signals, generalized[:, :n], inputs, "NonlinearDEM", predicted[: len(rows)])
    return DEMEstimate(np.arange(len(signals)) * estimator.dt, generalized[:, :n].copy(), inputs.copy(),
                       std[:, :n], input_std, generalized if keep_generalized else None)
