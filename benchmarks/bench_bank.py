"""Random-system bank (issue 12): every estimator against the exact Gaussian posterior.

Run:  python benchmarks/bench_bank.py [--quick] [--seeds 52] [--json OUT] [--no-speed]

The bank: ``--seeds`` (default 52; --quick: 12) stable, observable LTI systems drawn by
:func:`draw_case` with seed ``[BANK_SEED, index]``. Case ``index`` fixes the design factors so that
every combination appears: input kind = index % 4 (known sums of sinusoids, known short pulses,
unknown inputs drawn from the GP prior the estimators assume, unknown deterministic pulses: a model
mismatch), widths shared when (index // 4) % 3 == 0 (else process and sensor widths drawn
separately), x[0] unknown when (index + index // 4) is odd. The rest is random: n 2..8, m 1..3,
r 1..4 (r <= m when the inputs are unknown), eigenvalue real parts -1 .. -0.02 1/s, dt 0.02..0.1 s,
N 300..600 (N n <= 2400 keeps the exact posterior affordable), kernel widths s / dt in
{0 (white), 0.5, 1, 2, 5, 10}, process-to-sensor std ratio sigma_w / sigma_z over 1e-2 .. 1e2 [1/s].

Estimators per case: the coloured-noise Kalman smoother (``KalmanEstimator.estimate``, the default
of ``attend estimate``) and filter (``.filter``, causal); the DEM observer with its defaults
(embedding_order="auto"; an AttendInputError is counted as "refused"); white-noise RTS smoother and
Kalman filter with the true per-sample variances (Q = dt^2 sigma_w^2 I, R = sigma_z^2 I; known
inputs) and the augmented random-walk RTS / KF (unknown inputs; its input increment variance is the
best of INPUT_GRID = 1e-3 .. 1e3 x sigma_u^2 (dt / s_u)^2 per case and estimator, chosen with the
true states and inputs: an oracle tuning that favours the baseline). The limits: ``exact_posterior`` (smoother) and its ``causal_states``.

Metrics: SSE over all samples and states (inputs), as a ratio to the exact posterior's SSE on the
same log; calibration: fraction of |error| < 2 std over the interior samples (10 % trimmed at each
end), pooled over the cases whose data follow the estimators' model (all but the unknown-pulse
cases); samples/s: log samples over set-up + estimation time.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")  # one core, before numpy loads BLAS

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import timeit  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402

from attend._validation import AttendInputError  # noqa: E402
from attend.models.noise import autocorrelation  # noqa: E402
from attend.perception import references as bl  # noqa: E402
from attend.perception.dem import DEMObserver  # noqa: E402
from attend.perception.kalman import KalmanEstimator  # noqa: E402
from attend.models.linear import LinearSystem, ModelWarning, simulate  # noqa: E402

BANK_SEED = 12  # issue 12
WIDTH_STEPS = (0.0, 0.5, 1.0, 2.0, 5.0, 10.0)  # s / dt (0: white noise)
INPUT_KINDS = ("known-sines", "known-pulses", "unknown-gp", "unknown-pulses")
MAX_STATE_SAMPLES = 2400  # N n: the exact posterior costs O((N n)^3)
INPUT_GRID = (1e-3, 1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3)  # augmented RW: multiples of sigma_u^2 (dt / s_u)^2
FAIL_RATIO = 10.0
TRIM = 0.1  # calibration: interior samples


@dataclass(frozen=True, eq=False)
class Case:
    """One log of the bank: the model the estimators get and the truth they are scored on.

    process_std sigma_w [state unit/s], sensor_std sigma_z [output unit] (per sample);
    process_width, sensor_width, input_width: kernel widths [s] (0: white); input_prior_mean
    (N, r) and input_prior_std (r,) of unknown inputs (None when known); initial_std: prior std of
    x[0] about 0 (0: known x[0] = 0); states (N, n), inputs (N, r), outputs (N, m): the log.
    """

    index: int
    system: LinearSystem
    dt: float
    process_std: float
    sensor_std: float
    process_width: float
    sensor_width: float
    input_width: float | None
    input_kind: str
    input_prior_mean: np.ndarray | None
    input_prior_std: np.ndarray | None
    initial_std: float
    states: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray

    @property
    def known(self) -> bool:
        return self.input_prior_mean is None

    @property
    def shared(self) -> bool:
        return self.process_width == self.sensor_width

    @property
    def calibration_case(self) -> bool:
        """The data follow the estimators' model (the unknown pulses do not)."""
        return self.input_kind != "unknown-pulses"

    def describe(self) -> str:
        n, r, m = self.system.n_states, self.system.n_inputs, self.system.n_outputs
        return (f"n={n} m={m} r={r} N={len(self.outputs)} dt={self.dt:g} s_w/dt={self.process_width / self.dt:g} "
                f"s_z/dt={self.sensor_width / self.dt:g} sw/sz={self.process_std / self.sensor_std:.3g} "
                f"{self.input_kind} x0={'unknown' if self.initial_std else 'known'}")


# --- the generator -------------------------------------------------------------------------

def _random_rotation(rng, n) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))


def _min_singular(matrix) -> float:
    return float(np.linalg.svd(matrix, compute_uv=False)[-1])


def random_system(rng, n: int, m: int, r: int, unknown_inputs: bool) -> LinearSystem:
    """Stable A (eigenvalue real parts -1 .. -0.02 1/s, some complex pairs with 0.3..3 rad/s),
    well-conditioned modal basis, Gaussian B and C; redrawn until (A, C) passes the PBH test with
    margin (and, for unknown inputs, [A B; C 0] has full column rank: inputs distinguishable)."""
    while True:
        pairs = int(rng.integers(0, n // 2 + 1))
        J = np.zeros((n, n))
        decay = -10 ** rng.uniform(np.log10(0.02), 0.0, size=n)
        for i in range(pairs):
            a, b = decay[2 * i], rng.uniform(0.3, 3.0)
            J[2 * i: 2 * i + 2, 2 * i: 2 * i + 2] = [[a, b], [-b, a]]
        for i in range(2 * pairs, n):
            J[i, i] = decay[i]
        V = _random_rotation(rng, n) @ np.diag(10 ** rng.uniform(-0.3, 0.3, n)) @ _random_rotation(rng, n)
        A = V @ J @ np.linalg.inv(V)
        B = rng.standard_normal((n, r))
        C = rng.standard_normal((m, n))
        scale = np.linalg.norm(A) + np.linalg.norm(C)
        pbh = min(_min_singular(np.vstack([A - lam * np.eye(n), C])) for lam in np.linalg.eigvals(A))
        if pbh < 1e-3 * scale:
            continue
        if unknown_inputs and _min_singular(np.block([[A, B], [C, np.zeros((m, r))]])) < 1e-3 * scale:
            continue
        return LinearSystem(A, B, C)


def _sines(rng, t, r) -> np.ndarray:
    """Sum of 3 sinusoids per input, periods from ~dt*20 (or 1 s) to the log length."""
    duration = t[-1] + t[1]
    top = min(1.0 / (20 * t[1]), 1.0)
    u = np.zeros((len(t), r))
    for j in range(r):
        for _ in range(3):
            f = 10 ** rng.uniform(np.log10(0.5 / duration), np.log10(top))
            u[:, j] += np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) / np.sqrt(3)
    return u


def _pulses(rng, t, r) -> tuple[np.ndarray, float, float]:
    """1-3 short Gaussian bumps per input (std 3..10 samples); returns (u, width [s], amplitude)."""
    dt, duration = t[1], t[-1] + t[1]
    width = rng.uniform(3, 10) * dt
    u = np.zeros((len(t), r))
    amplitude = 0.0
    for j in range(r):
        for _ in range(int(rng.integers(1, 4))):
            a = rng.uniform(0.5, 2.0) * rng.choice([-1, 1])
            u[:, j] += a * np.exp(-0.5 * ((t - rng.uniform(0.1, 0.8) * duration) / width) ** 2)
            amplitude = max(amplitude, abs(a))
    return u, width, amplitude


def gp_input(rng, t, mean, std, width) -> np.ndarray:
    """Draw u ~ GP(mean, std^2 exp(-tau^2 / (4 s_u^2))) at the samples t (the estimators' prior)."""
    K = autocorrelation(t[:, None] - t[None, :], width)
    values, vectors = np.linalg.eigh(K)
    root = vectors * np.sqrt(np.clip(values, 0, None))
    return mean + (root @ rng.standard_normal((len(t), len(mean)))) * std


def draw_case(index: int, seed: int = BANK_SEED, tiny: bool = False) -> Case:
    """Case ``index`` of the bank (see the module docstring); tiny: n 2..3, m, r <= 2, N 150..200."""
    rng = np.random.default_rng([seed, index])
    kind = INPUT_KINDS[index % 4]
    shared = (index // 4) % 3 == 0
    x0_unknown = (index + index // 4) % 2 == 1
    unknown = kind.startswith("unknown")
    n = int(rng.integers(2, 4 if tiny else 9))
    m = int(rng.integers(1, 3 if tiny else 4))
    r = int(rng.integers(1, (min(m, 3) if unknown else (2 if tiny else 4)) + 1))
    dt = float(rng.choice([0.02, 0.05, 0.1]))
    N = int(rng.integers(150, 201)) if tiny else int(min(rng.integers(300, 601), MAX_STATE_SAMPLES // n))
    system = random_system(rng, n, m, r, unknown)
    t = np.arange(N) * dt
    process_width = float(rng.choice(WIDTH_STEPS)) * dt
    if shared:
        sensor_width = process_width
    else:
        sensor_width = float(rng.choice([w for w in WIDTH_STEPS if w * dt != process_width])) * dt
    prior_mean = prior_std = input_width = None
    if kind == "known-sines":
        u = _sines(rng, t, r)
    elif kind == "known-pulses":
        u = _pulses(rng, t, r)[0]
    elif kind == "unknown-gp":
        if process_width >= 2 * dt and rng.uniform() < 0.5:
            input_width = process_width  # the smoothness DEM assumes for its inputs
        else:
            input_width = float(rng.choice([2.0, 5.0, 10.0, 20.0])) * dt
        mean = rng.uniform(-1, 1, r)
        prior_std = 10 ** rng.uniform(-0.5, 0.3, r)
        u = gp_input(rng, t, mean, prior_std, input_width)
        prior_mean = np.broadcast_to(mean, (N, r)).copy()
    else:  # unknown pulses, estimated under a zero-mean GP prior of the pulses' scale
        u, input_width, amplitude = _pulses(rng, t, r)
        prior_mean = np.zeros((N, r))
        prior_std = np.full(r, 0.5 * amplitude)
    clean = simulate(system, u, dt, kernel_width=0.0, seed=0)
    state_scale = max(float(np.sqrt(np.mean(clean.states**2))), 1e-3)
    output_scale = max(float(np.sqrt(np.mean(clean.outputs**2))), 1e-3)
    sensor_std = output_scale * 10 ** rng.uniform(-2.0, -0.7)
    process_std = sensor_std * 10 ** rng.uniform(-2.0, 2.0)
    initial_std = state_scale if x0_unknown else 0.0
    x0 = rng.standard_normal(n) * initial_std
    log = simulate(system, u, dt, process_kernel_width=process_width, sensor_kernel_width=sensor_width,
                   process_std=process_std, measurement_std=sensor_std, initial_state=x0,
                   seed=int(rng.integers(2**31)))
    return Case(index, system, dt, process_std, sensor_std, process_width, sensor_width, input_width, kind,
                prior_mean, prior_std, initial_std, log.states, u, log.outputs)


# --- estimators ----------------------------------------------------------------------------

@dataclass
class Result:
    """One estimator on one case: states, inputs (None when known), their std (None: not
    reported), seconds (set-up + estimation), status ("ok", "refused", "error: ...")."""

    states: np.ndarray | None = None
    inputs: np.ndarray | None = None
    state_std: np.ndarray | None = None
    input_std: np.ndarray | None = None
    seconds: float = float("nan")
    status: str = "ok"
    info: dict | None = None


def exact(case: Case, jitter: float = 1e-12, causal: bool = True):
    """The limit: exact posterior (smoother) and exact causal estimate, from one factorisation."""
    start = time.perf_counter()
    post = bl.exact_posterior(
        case.system, case.dt, case.outputs, case.inputs if case.known else None,
        process_kernel_width=case.process_width, sensor_kernel_width=case.sensor_width,
        input_kernel_width=case.input_width, process_std=case.process_std, measurement_std=case.sensor_std,
        input_prior_mean=case.input_prior_mean, input_prior_std=case.input_prior_std,
        initial_std=case.initial_std, causal=causal, jitter=jitter)
    seconds = time.perf_counter() - start
    unknown = not case.known
    smoother = Result(post.states, post.inputs if unknown else None, post.state_std,
                      post.input_std if unknown else None, seconds)
    causal = Result(post.causal_states, post.causal_inputs if unknown else None, None, None, seconds)
    return smoother, causal


def kalman(case: Case) -> tuple[Result, Result]:
    """KalmanEstimator (coloured-noise Kalman) smoother and filter, given the true model."""
    r = case.system.n_inputs
    start = time.perf_counter()
    try:
        estimator = KalmanEstimator(
            case.system, case.dt, sensor_precision=case.sensor_std**-2, process_precision=case.process_std**-2,
            process_kernel_width=case.process_width, sensor_kernel_width=case.sensor_width,
            known_inputs=case.known,
            input_prior_precision=None if case.known else case.input_prior_std**-2,
            input_kernel_width=case.input_width,
            initial_state=np.zeros(case.system.n_states), initial_state_std=case.initial_std)
    except AttendInputError as error:
        return Result(status=f"error: {error}"), Result(status=f"error: {error}")
    setup = time.perf_counter() - start
    signal = case.inputs if case.known else case.input_prior_mean
    out = []
    for run in (estimator.estimate, estimator.filter):
        start = time.perf_counter()
        try:
            est = run(case.outputs, signal)
        except AttendInputError as error:
            out.append(Result(status=f"error: {error}"))
            continue
        seconds = setup + time.perf_counter() - start
        out.append(Result(est.states, None if case.known else est.inputs[:, :r], est.state_std,
                          None if case.known else est.input_std, seconds))
    return out[0], out[1]


def dem(case: Case) -> Result:
    """DEMObserver with its defaults (embedding_order="auto"), given the true precisions/widths."""
    start = time.perf_counter()
    try:
        observer = DEMObserver(
            case.system, case.dt, kernel_width=None, sensor_precision=case.sensor_std**-2,
            process_precision=case.process_std**-2,
            input_prior_precision=None if case.known else case.input_prior_std**-2,
            known_inputs=case.known, process_kernel_width=case.process_width,
            sensor_kernel_width=case.sensor_width, input_kernel_width=None if case.known else case.input_width,
            initial_state=None if case.initial_std else np.zeros(case.system.n_states))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ModelWarning)
            est = observer.estimate(case.outputs, case.inputs if case.known else case.input_prior_mean)
    except AttendInputError as error:
        return Result(status=f"refused: {str(error)[:90]}")
    seconds = time.perf_counter() - start
    messages = [str(w.message) for w in caught]
    warned = any("worse than the model's prior mean" in m or "not informed by the outputs" in m for m in messages)
    # diverged: non-finite, or estimates beyond 100x the largest true state (a flow running away)
    scale = np.max(np.abs(case.states)) + 1e-12
    diverged = not np.all(np.isfinite(est.states)) or np.max(np.abs(est.states)) > 100 * scale
    return Result(est.states, None if case.known else est.inputs, est.state_std,
                  None if case.known else est.input_std, seconds,
                  info=dict(embedding_order=observer.embedding_order, warned=warned, diverged=bool(diverged)))


def dem_noise_free(case: Case) -> float:
    """State SSE of the DEM defaults on the noise-free log of a known-input case (x[0] = 0): the
    error of DEM's continuous generalised motion on the sampled zero-order-hold plant."""
    clean = simulate(case.system, case.inputs, case.dt, kernel_width=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        observer = DEMObserver(
            case.system, case.dt, kernel_width=None, sensor_precision=case.sensor_std**-2,
            process_precision=case.process_std**-2, known_inputs=True,
            process_kernel_width=case.process_width, sensor_kernel_width=case.sensor_width,
            initial_state=np.zeros(case.system.n_states))
        return sse(observer.estimate(clean.outputs, case.inputs).states, clean.states)


def white(case: Case) -> tuple[Result, Result]:
    """White-noise RTS smoother and KF with the true per-sample variances (known inputs only)."""
    Q, R = bl.simulation_covariances(case.system, case.dt, case.process_std, case.sensor_std)
    P0 = np.eye(case.system.n_states) * case.initial_std**2
    out = []
    for run in (bl.rts_smoother, bl.kalman_filter):
        start = time.perf_counter()
        est = run(case.system, case.dt, case.outputs, case.inputs, process_covariance=Q,
                  measurement_covariance=R, initial_covariance=P0)
        out.append(Result(est.states, None, est.state_std, None, time.perf_counter() - start))
    return out[0], out[1]


def augmented(case: Case, limit: Result) -> tuple[Result, Result, dict]:
    """Augmented random-walk RTS and KF (unknown inputs): the increment variance is the best of
    INPUT_GRID x sigma_u^2 (dt / s_u)^2 per case and per estimator, judged by
    SSE_x / SSE_x(exact) + SSE_u / SSE_u(exact) (oracle tuning)."""
    Q, R = bl.simulation_covariances(case.system, case.dt, case.process_std, case.sensor_std)
    P0 = np.eye(case.system.n_states) * case.initial_std**2
    base = case.input_prior_std**2 * (case.dt / case.input_width) ** 2
    best, chosen = [None, None], [None, None]
    for factor in INPUT_GRID:
        for slot, smooth in enumerate((True, False)):
            start = time.perf_counter()
            est = bl.augmented_kalman_filter(
                case.system, case.dt, case.outputs, process_covariance=Q, measurement_covariance=R,
                input_variance=base * factor, initial_covariance=P0, initial_input=case.input_prior_mean[0],
                initial_input_std=case.input_prior_std, smooth=smooth)
            seconds = time.perf_counter() - start
            score = (sse(est.states, case.states) / sse(limit.states, case.states)
                     + sse(est.inputs, case.inputs) / sse(limit.inputs, case.inputs))
            if not np.isfinite(score):
                score = np.inf
            if best[slot] is None or score < best[slot][0]:
                best[slot] = (score, Result(est.states, est.inputs, est.state_std, est.input_std, seconds))
                chosen[slot] = factor
    return best[0][1], best[1][1], {"aug_rts_factor": chosen[0], "aug_kf_factor": chosen[1]}


# --- metrics -------------------------------------------------------------------------------

def sse(estimate, truth) -> float:
    return float(np.sum((np.asarray(estimate) - truth) ** 2))


def coverage(estimate, std, truth) -> tuple[int, int]:
    """(inside, counted): samples of the interior with |error| < 2 std (finite std only)."""
    N = truth.shape[0]
    window = slice(int(TRIM * N), N - int(TRIM * N))
    error, std = np.abs(estimate[window] - truth[window]), np.asarray(std)[window]
    ok = np.isfinite(std) & np.isfinite(error)
    return int(np.sum((error < 2 * std) & ok)), int(np.sum(ok))


ESTIMATORS = {  # key: (label, causal, needs unknown inputs / known inputs / both)
    "kalman_smoother": ("kalman smoother (default)", False, "both"),
    "kalman_filter": ("kalman filter (online)", True, "both"),
    "dem": ("DEM defaults (p auto)", False, "both"),
    "white_rts": ("white RTS, true variances", False, "known"),
    "white_kf": ("white KF, true variances", True, "known"),
    "aug_rts": ("augmented RW RTS (tuned)", False, "unknown"),
    "aug_kf": ("augmented RW KF (tuned)", True, "unknown"),
    "exact": ("exact posterior (limit)", False, "both"),
    "exact_causal": ("exact causal (limit)", True, "both"),
}


def run_case(case: Case) -> dict:
    """Every estimator on one case: per-estimator SSEs, ratios, coverage counts, seconds."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        results = {}
        results["exact"], results["exact_causal"] = exact(case)
        results["kalman_smoother"], results["kalman_filter"] = kalman(case)
        results["dem"] = dem(case)
        extra = {}
        if case.known:
            results["white_rts"], results["white_kf"] = white(case)
        else:
            results["aug_rts"], results["aug_kf"], extra = augmented(case, results["exact"])
    limit, causal_limit = results["exact"], results["exact_causal"]
    # numerical uncertainty of the limit itself: its state SSE with 100x the default jitter
    loose, loose_causal = exact(case, jitter=1e-10)
    limit_jitter = sse(loose.states, case.states) / sse(limit.states, case.states) - 1
    causal_jitter = sse(loose_causal.states, case.states) / sse(causal_limit.states, case.states) - 1
    record = dict(index=case.index, describe=case.describe(), known=case.known, shared=case.shared,
                  calibration_case=case.calibration_case, white_noise=case.process_width == 0 or case.sensor_width == 0,
                  x0_known=case.initial_std == 0, n_samples=len(case.outputs), limit_jitter=limit_jitter,
                  causal_jitter=causal_jitter,
                  estimators={}, **extra)
    for key, result in results.items():
        entry = dict(status=result.status, seconds=result.seconds, **(result.info or {}))
        if result.status == "ok":
            entry["state_sse"] = sse(result.states, case.states)
            entry["state_ratio"] = entry["state_sse"] / sse(limit.states, case.states)
            entry["state_ratio_causal"] = entry["state_sse"] / sse(causal_limit.states, case.states)
            reference = causal_limit if ESTIMATORS[key][1] else limit  # the limit of its kind
            entry["state_deviation"] = sse(result.states, reference.states) / sse(reference.states, case.states)
            if result.state_std is not None:
                entry["state_coverage"] = coverage(result.states, result.state_std, case.states)
            if not case.known:
                entry["input_sse"] = sse(result.inputs, case.inputs)
                entry["input_ratio"] = entry["input_sse"] / sse(limit.inputs, case.inputs)
                entry["input_ratio_causal"] = entry["input_sse"] / sse(causal_limit.inputs, case.inputs)
                if result.input_std is not None:
                    entry["input_coverage"] = coverage(result.inputs, result.input_std, case.inputs)
        record["estimators"][key] = entry
    # paired comparisons with the white / augmented baselines
    own = record["estimators"]
    if case.known and own["dem"]["status"] == "ok":  # DEM's deterministic error on the known inputs
        record["dem_noise_free_ratio"] = dem_noise_free(case) / own["exact"]["state_sse"]
    base_smooth, base_causal = ("white_rts", "white_kf") if case.known else ("aug_rts", "aug_kf")
    for key, base in (("kalman_smoother", base_smooth), ("kalman_filter", base_causal)):
        if own[key]["status"] == "ok":
            own[key]["state_ratio_baseline"] = own[key]["state_sse"] / own[base]["state_sse"]
    return record


# --- the report ----------------------------------------------------------------------------

def _finite_or_inf(values) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    return np.where(np.isfinite(a), a, np.inf)


def stats(values) -> dict:
    a = _finite_or_inf(values)
    if a.size == 0:
        return dict(count=0, median=float("nan"), p90=float("nan"), worst=float("nan"))
    return dict(count=int(a.size), median=float(np.median(a)), p90=float(np.percentile(a, 90)),
                worst=float(np.max(a)))


def summarize(records: list[dict]) -> dict:
    """Per estimator: ratio statistics, failures, refusals, calibration and speed."""
    summary = {}
    for key in ESTIMATORS:
        rows = [r for r in records if key in r["estimators"]]
        ok = [r for r in rows if r["estimators"][key]["status"] == "ok"]
        refused = sum(r["estimators"][key]["status"].startswith("refused") for r in rows)
        errors = [r["index"] for r in rows if r["estimators"][key]["status"].startswith("error")]
        state = [r["estimators"][key]["state_ratio"] for r in ok]
        unknown = [r for r in ok if not r["known"]]
        inputs = [r["estimators"][key]["input_ratio"] for r in unknown]
        suffix = "_causal" if ESTIMATORS[key][1] else ""  # causal estimators: against the exact causal
        failed = [r["index"] for r in ok
                  if not max(r["estimators"][key][f"state_ratio{suffix}"],
                             r["estimators"][key].get(f"input_ratio{suffix}", 0)) <= FAIL_RATIO]
        entry = dict(cases=len(rows), ran=len(ok), refused=refused, errors=errors, failed=failed,
                     state=stats(state), input=stats(inputs),
                     state_vs_causal=stats([r["estimators"][key]["state_ratio_causal"] for r in ok]),
                     input_vs_causal=stats([r["estimators"][key]["input_ratio_causal"] for r in unknown]))
        for quantity in ("state", "input"):
            for scope, chosen in (("", [r for r in ok if r["calibration_case"]]),
                                  ("_mismatch", [r for r in ok if not r["calibration_case"]])):
                counts = [r["estimators"][key][f"{quantity}_coverage"] for r in chosen
                          if f"{quantity}_coverage" in r["estimators"][key]]
                if counts:
                    inside, total = np.sum(counts, axis=0)
                    entry[f"{quantity}_calibration{scope}"] = float(inside / total) if total else float("nan")
        seconds = sum(r["estimators"][key]["seconds"] for r in ok)
        entry["samples_per_second"] = sum(r["n_samples"] for r in ok) / seconds if seconds > 0 else float("nan")
        baseline = [r["estimators"][key]["state_ratio_baseline"] for r in ok if "state_ratio_baseline" in r["estimators"][key]]
        if baseline:
            entry["vs_baseline_known"] = stats([r["estimators"][key]["state_ratio_baseline"] for r in ok if r["known"]])
            entry["vs_baseline_unknown"] = stats([r["estimators"][key]["state_ratio_baseline"] for r in ok
                                                  if not r["known"]])
        groups = {}
        for name, test in GROUPS.items():
            groups[name] = stats([r["estimators"][key]["state_ratio"] for r in ok if test(r)])
        entry["groups"] = groups
        summary[key] = entry
    return summary


GROUPS = {
    "shared widths": lambda r: r["shared"],
    "separate widths": lambda r: not r["shared"],
    "a white noise": lambda r: r["white_noise"],
    "known inputs": lambda r: r["known"],
    "unknown inputs": lambda r: not r["known"],
    "unknown GP": lambda r: not r["known"] and r["calibration_case"],
    "unknown pulses": lambda r: not r["calibration_case"],
    "x0 known": lambda r: r["x0_known"],
    "x0 unknown": lambda r: not r["x0_known"],
}


def _verdict(value, low=None, high=None, digits=4) -> str:
    """PASS when the value, rounded as printed (4 decimals), is within [low, high]."""
    if value is None or not np.isfinite(value):
        return "MISS"
    value = round(float(value), digits)
    ok = (low is None or value >= low) and (high is None or value <= high)
    return "PASS" if ok else "MISS"


def _line(label, value, target="", verdict="", fmt="{:.4f}") -> str:
    text = fmt.format(value) if isinstance(value, (int, float, np.floating)) else str(value)
    return f"  {label:<46} {text:>10}   {target:<24} {verdict}"


def report(records: list[dict], summary: dict, elapsed: float) -> list[str]:
    out = []
    n_known = sum(r["known"] for r in records)
    calib = sum(r["calibration_case"] for r in records)
    out.append(f"Random-system bank: {len(records)} cases ({n_known} known inputs, {len(records) - n_known} unknown; "
               f"{sum(r['shared'] for r in records)} shared widths; {sum(not r['x0_known'] for r in records)} "
               f"x0 unknown; calibration pooled over {calib} model-matched cases), {elapsed:.0f} s")
    out.append("SSE over all samples, as a ratio to the exact posterior's SSE on the same log; "
               "calibration: |err| < 2 std, interior 80 %")
    jitter = np.abs([r["limit_jitter"] for r in records])
    causal = np.abs([r["causal_jitter"] for r in records])
    out.append(f"The limits' own numerical uncertainty (|change of the state SSE| with 100x their jitter): exact "
               f"median {np.median(jitter):.1e}, worst {np.max(jitter):.1e}; exact causal median "
               f"{np.median(causal):.1e}, worst {np.max(causal):.1e}")
    out.append("")

    def block(key):
        s = summary[key]
        label = ESTIMATORS[key][0]
        out.append(f"{label}: ran {s['ran']}/{s['cases']}, refused {s['refused']}, errors {len(s['errors'])}, "
                   f"samples/s {s['samples_per_second']:.3g}")
        return s

    def calibration_lines(s):
        for quantity in ("state", "input"):
            value = s.get(f"{quantity}_calibration")
            if value is not None:
                out.append(_line(f"calibration {quantity}s (model-matched cases)", 100 * value, "target 93-97 %",
                                 _verdict(100 * value, 93, 97, digits=1), "{:.1f} %"))
            mismatch = s.get(f"{quantity}_calibration_mismatch")
            if mismatch is not None:
                out.append(_line(f"  ({quantity}s, unknown pulses: mismatch)", 100 * mismatch, "(no target)", "",
                                 "{:.1f} %"))

    def deviation_line(key, limit):
        values = [r["estimators"][key]["state_deviation"] for r in records if r["estimators"][key]["status"] == "ok"]
        worst = int(np.argmax(values))
        name = "state_ratio" + ("_causal" if ESTIMATORS[key][1] else "")
        jitter = "causal_jitter" if ESTIMATORS[key][1] else "limit_jitter"
        off = [f"{r['index']} ({r['estimators'][key][name]:.3f}; limit jitter {r[jitter]:+.1%})"
               for r in records if r["estimators"][key]["status"] == "ok" and abs(r["estimators"][key][name] - 1) > 0.02]
        out.append(_line(f"|mean - {limit} mean|^2 / {limit} SSE: median / worst",
                         f"{np.median(values):.2g} / {values[worst]:.2g}", "(0 = the limit itself)"))
        out.append(f"    cases whose SSE ratio is off 1 by > 2 % (ratio; change of the limit's SSE with 100x jitter):")
        for start in range(0, len(off), 3):
            out.append("      " + ", ".join(off[start:start + 3]))

    s = block("kalman_smoother")
    out.append(_line("state SSE / exact: median", s["state"]["median"], "target <= 1.05", _verdict(s["state"]["median"], high=1.05)))
    out.append(_line("state SSE / exact: 90th percentile", s["state"]["p90"], "target <= 1.2", _verdict(s["state"]["p90"], high=1.2)))
    out.append(_line("state SSE / exact: worst", s["state"]["worst"], "target <= 2 (never > 2x)", _verdict(s["state"]["worst"], high=2.0)))
    out.append(_line("state SSE / white RTS (known inputs): median", s["vs_baseline_known"]["median"], "target <= 1.0",
                     _verdict(s["vs_baseline_known"]["median"], high=1.0)))
    out.append(_line("state SSE / augmented RTS (unknown): median", s["vs_baseline_unknown"]["median"], "target <= 1.0",
                     _verdict(s["vs_baseline_unknown"]["median"], high=1.0)))
    out.append(_line("input SSE / exact: median", s["input"]["median"], "target <= 1.3", _verdict(s["input"]["median"], high=1.3)))
    out.append(_line("input SSE / exact: 90th pct / worst", f"{s['input']['p90']:.3f} / {s['input']['worst']:.3f}"))
    out.append(_line("failures (> 10x)", len(s["failed"]), "target 0", _verdict(-len(s["failed"]), low=0), "{:d}"))
    deviation_line("kalman_smoother", "exact")
    calibration_lines(s)
    out.append("")
    s = block("kalman_filter")
    out.append(_line("state SSE / exact causal: median", s["state_vs_causal"]["median"], "target <= 1.1",
                     _verdict(s["state_vs_causal"]["median"], high=1.1)))
    out.append(_line("state SSE / exact causal: 90th pct / worst",
                     f"{s['state_vs_causal']['p90']:.3f} / {s['state_vs_causal']['worst']:.3f}"))
    out.append(_line("state SSE / white KF (known inputs): median", s["vs_baseline_known"]["median"], "target < 1.0",
                     _verdict(s["vs_baseline_known"]["median"], high=1.0)))
    out.append(_line("state SSE / augmented KF (unknown): median", s["vs_baseline_unknown"]["median"], "target < 1.0",
                     _verdict(s["vs_baseline_unknown"]["median"], high=1.0)))
    out.append(_line("input SSE / exact causal: median", s["input_vs_causal"]["median"]))
    out.append(_line("failures (> 10x the exact causal)", len(s["failed"]), "", "", "{:d}"))
    deviation_line("kalman_filter", "exact causal")
    calibration_lines(s)
    out.append("")
    s = block("dem")
    dem_runs = [r["estimators"]["dem"] for r in records if r["estimators"]["dem"]["status"] == "ok"]
    diverged = sum(bool(e.get("diverged")) for e in dem_runs)
    out.append(_line("divergent (non-finite or running away)", diverged, "target 0", _verdict(-diverged, low=0),
                     "{:d}"))
    inaccurate = len(s["failed"])
    warned = sum(bool(r["estimators"]["dem"].get("warned")) for r in records if r["index"] in s["failed"])
    out.append(f"  > 10x the exact posterior (inaccurate): {inaccurate}, of which named by a ModelWarning "
               f"(worse than the prior / not informed): {warned}")
    statuses = [r["estimators"]["dem"]["status"] for r in records]
    white_refusals = sum(s_.startswith("refused") and "white noise" in s_ for s_ in statuses)
    start_refusals = sum(s_.startswith("refused") and "remembers its start" in s_ for s_ in statuses)
    out.append(f"    refused: {white_refusals} white-noise widths, {start_refusals} 'remembers its start too long', "
               f"{s['refused'] - white_refusals - start_refusals} other")
    ran = [r for r in records if r["estimators"]["dem"]["status"] == "ok"]
    orders = sorted({r["estimators"]["dem"]["embedding_order"] for r in ran})
    for p in orders:
        chosen = [r for r in ran if r["estimators"]["dem"]["embedding_order"] == p]
        bad = [r["index"] for r in chosen if r["index"] in s["failed"]]
        out.append(f"    p = {p} (auto): {len(chosen)} cases, divergent {len(bad)} {bad}")
    out.append(_line("state SSE / exact: median / 90th pct / worst",
                     f"{s['state']['median']:.3f} / {s['state']['p90']:.3f} / {s['state']['worst']:.3g}"))
    out.append(_line("input SSE / exact: median / 90th pct / worst",
                     f"{s['input']['median']:.3f} / {s['input']['p90']:.3f} / {s['input']['worst']:.3g}"))
    calibration_lines(s)
    clean = [r["dem_noise_free_ratio"] for r in records if "dem_noise_free_ratio" in r]
    if clean:
        out.append(_line("known inputs: SSE on the noise-free log / exact",
                         f"{np.median(clean):.3g} / {np.max(clean):.3g}", "(median / worst; 0 = ideal)"))
    out.append("")
    for key in ("white_rts", "white_kf", "aug_rts", "aug_kf", "exact", "exact_causal"):
        s = block(key)
        compare = "state_vs_causal" if key in ("white_kf", "aug_kf") else "state"
        limit = "exact causal" if compare == "state_vs_causal" else "exact"
        if key == "exact_causal":
            out.append(_line("state SSE / exact: median / 90th pct / worst",
                             f"{s['state']['median']:.3f} / {s['state']['p90']:.3f} / {s['state']['worst']:.3g}"))
            out.append(_line("input SSE / exact: median / 90th pct / worst",
                             f"{s['input']['median']:.3f} / {s['input']['p90']:.3f} / {s['input']['worst']:.3g}"))
        elif key != "exact":
            out.append(_line(f"state SSE / {limit}: median / 90th pct / worst",
                             f"{s[compare]['median']:.3f} / {s[compare]['p90']:.3f} / {s[compare]['worst']:.3g}"))
            if s["input"]["count"]:
                icompare = "input_vs_causal" if compare == "state_vs_causal" else "input"
                out.append(_line(f"input SSE / {limit}: median / 90th pct / worst",
                                 f"{s[icompare]['median']:.3f} / {s[icompare]['p90']:.3f} / {s[icompare]['worst']:.3g}"))
            out.append(_line(f"failures (> 10x the {limit})", len(s["failed"]), "", "", "{:d}"))
        calibration_lines(s)
        out.append("")
    out.append("State SSE / exact posterior, median [90th pct] by group (cases):")
    names = list(GROUPS)
    counts = {name: sum(GROUPS[name](r) for r in records) for name in names}
    out.append(f"  {'':<28}" + "".join(f"{name[:15]:>16}" for name in names))
    out.append(f"  {'(cases)':<28}" + "".join(f"{counts[name]:>16d}" for name in names))
    for key in ESTIMATORS:
        if key == "exact":
            continue
        cells = []
        for name in names:
            g = summary[key]["groups"][name]
            cells.append(f"{g['median']:7.3f} [{g['p90']:6.3g}]" if g["count"] else f"{'-':>15}")
        out.append(f"  {ESTIMATORS[key][0][:28]:<28}" + "".join(f"{c:>16}" for c in cells))
    return out


# --- speed ---------------------------------------------------------------------------------

def _best(function, repeats=3) -> float:
    """The shortest of ``repeats`` timed calls of ``function`` [s] (timeit: perf_counter, GC paused)."""
    return min(timeit.repeat(function, number=1, repeat=repeats))


def speed_system(n: int, seed: int = 0) -> LinearSystem:
    return random_system(np.random.default_rng([BANK_SEED, 1000 + n, seed]), n, 1, 1, False)


def speed(quick: bool) -> tuple[list[str], dict]:
    """KalmanEstimator batch samples/s and online step time (n = 2, m = r = 1, s / dt = 2)."""
    dt = 0.05
    out, data = [], {}

    def estimator(n):
        return KalmanEstimator(speed_system(n), dt, sensor_precision=1e4, process_precision=1e2,
                               kernel_width=2 * dt)

    def rates(n, N):
        est = estimator(n)
        rng = np.random.default_rng(1)
        y, u = rng.standard_normal((N, 1)) * 0.01, np.sin(np.arange(N) * dt)[:, None]
        smooth = _best(lambda: est.estimate(y, u))
        filt = _best(lambda: est.filter(y, u))
        return N / smooth, N / filt, est

    def online_step(est, steps=3000):
        rng = np.random.default_rng(2)
        y = rng.standard_normal(steps) * 0.01
        stream = est.online()
        times = np.empty(steps)
        for k in range(steps):
            start = time.perf_counter()
            stream.step([y[k]], [np.sin(k * dt)])
            times[k] = time.perf_counter() - start
        return float(np.median(times[steps // 3:])), float(np.percentile(times[steps // 3:], 99))

    start = time.perf_counter()
    estimator(2)
    setup = time.perf_counter() - start
    smooth, filt, est = rates(2, 100_000)
    step, step99 = online_step(est)
    out.append("Speed: KalmanEstimator, n = 2, m = 1, r = 1 (known), s / dt = 2, one core")
    out.append(_line("set-up (noise models, Riccati) [s]", setup, "", "", "{:.3f}"))
    out.append(_line("batch smoother, N = 1e5 [samples/s]", smooth, "target >= 2e5", _verdict(smooth, low=2e5), "{:.3g}"))
    out.append(_line("batch filter, N = 1e5 [samples/s]", filt, "", "", "{:.3g}"))
    out.append(_line("online step, median [us] (99th pct)", f"{1e6 * step:.1f} ({1e6 * step99:.0f})", "target <= 100 us",
                     _verdict(1e6 * step, high=100)))
    data["n2"] = dict(setup_s=setup, smoother_samples_per_s=smooth, filter_samples_per_s=filt,
                      online_step_s=step, online_step_p99_s=step99)
    out.append("  scaling (samples/s smoother / filter; online step us):")
    scaling = []
    for n in (2, 4, 8):
        for N in ((1_000, 10_000) if quick else (1_000, 10_000, 100_000)):
            s_rate, f_rate, est = rates(n, N)
            row = dict(n=n, N=N, smoother=s_rate, filter=f_rate)
            if N == 1_000:
                row["online_step_s"] = online_step(est, 1500)[0]
            scaling.append(row)
            extra = f"   online {1e6 * row['online_step_s']:.1f} us" if "online_step_s" in row else ""
            out.append(f"    n = {n}, N = {N:>6}: {s_rate:10.3g} / {f_rate:10.3g}{extra}")
    data["scaling"] = scaling
    return out, data


# --- main ----------------------------------------------------------------------------------

def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="12 systems (< 2 min)")
    parser.add_argument("--seeds", type=int, default=None, help="number of systems (default 52; --quick 12)")
    parser.add_argument("--bank-seed", type=int, default=BANK_SEED, help="seed of the bank (case i uses [seed, i])")
    parser.add_argument("--json", metavar="OUT", help="save per-case records and the summary as JSON")
    parser.add_argument("--no-speed", action="store_true", help="skip the speed section")
    parser.add_argument("--verbose", action="store_true", help="one line per case")
    args = parser.parse_args(argv)
    count = args.seeds if args.seeds is not None else (12 if args.quick else 52)
    start = time.perf_counter()
    records = []
    for index in range(count):
        case = draw_case(index, args.bank_seed)
        tic = time.perf_counter()
        record = run_case(case)
        records.append(record)
        if args.verbose:
            e = record["estimators"]
            dem_text = f"{e['dem']['state_ratio']:.3g}" if e["dem"]["status"] == "ok" else e["dem"]["status"][:7]
            print(f"[{index:2d}] {case.describe()}  kalman {e['kalman_smoother'].get('state_ratio', float('nan')):.3f} "
                  f"filter/causal {e['kalman_filter'].get('state_ratio_causal', float('nan')):.3f} dem {dem_text} "
                  f"({time.perf_counter() - tic:.1f} s)", flush=True)
    elapsed = time.perf_counter() - start
    summary = summarize(records)
    lines = report(records, summary, elapsed)
    print("\n".join(lines), flush=True)
    speed_data = None
    if not args.no_speed:
        speed_lines, speed_data = speed(args.quick)
        print()
        print("\n".join(speed_lines))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(dict(bank_seed=args.bank_seed, cases=records, summary=summary, speed=speed_data), handle,
                      indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))


if __name__ == "__main__":
    main()
