"""Is an estimate's spread supported by the data? A check that applies to every estimator.

An estimator given a model that does not fit the log (an unknown input with a prior far too wide
for a weakly observable state, a process noise far too large, ...) can return a state that swings
many times more than anything in the data or the model allows, with nothing to say so. This
module compares, per state and unknown input, the root mean square of the estimate with the
spread the data and the model support::

    ratio_i = RMS_k(xhat_i[k]) / reference_i          reference_i = the smallest of the available
      measured proxy:   y_j / c           (row j of C reads x_i alone, c its coefficient)
                        D(y_j / c) / a    (x_i is the time derivative of such a state: row j of A
                                           is a e_i' and no input enters it; D a central difference
                                           over the sensor kernel width, at least one sample)
      prior spread:     sqrt(P_ii + mean_k xbar_i[k]^2)   (over the log's second half, against the
                                           estimate's RMS there; a stable A: P the stationary covariance of
                                           A P + P A' + Q = 0, Q the noises' low-frequency intensity
                                           inv(Pi_w) sum_k rho_w(k dt) dt + B_u inv(P_v) B_u' sum_k
                                           rho_u(k dt) dt; xbar the model's response to the measured
                                           inputs and the input prior means from xhat[0])
      unknown input j:  sqrt(mean_k eta_j[k]^2 + 1 / P_v,jj)   (its prior)

and reports those with ratio_i > SPREAD_LIMIT, naming the settings that decide them. Nonlinear
models use their Jacobians along the estimate, keeping only the entries that are the same at every
point checked (a state read linearly by an output, or integrated into one); they have no prior
spread here. States with no reference are not checked.

Unknown inputs of a linear model also get a posterior predictive check of their prior
(:func:`input_prior_findings`; those the check above names are left out)::

    t_j = RMS_k(vhat_j[k] - eta_j[k]) / sigma_j        sigma_j = 1 / sqrt(P_v,jj min(lambda*, 1))

vhat the estimate, eta the prior mean, lambda* the profiled noise level when the width was chosen
from the log (every precision times lambda* leaves the smoother's mean as it is and makes the
prior std 1 / sqrt(P_v lambda*); only a widening is taken). Under a correct model vhat = E[v | y],
so Cov(vhat) = Cov(v) - E Cov(v | y) <= Cov(v) and, by Anderson's theorem, t_j^2 is
stochastically below the mean square of N samples of the unit prior, M = (1 / N) sum_k e[k]^2
with rho(tau) = exp(-tau^2 / (4 s_u^2)): cumulants 1, 2 tr(R^2) / N^2, 8 tr(R^3) / N^3 (R_kl =
rho((k - l) dt); variance 2 / nu, nu ~ N dt / (s_u sqrt(2 pi)) effective samples). t_j above the
(1 - INPUT_PRIOR_FALSE_RATE) quantile of sqrt(M) (:func:`input_prior_limit`) says the input
absorbs something the model lacks.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: An estimate's RMS above this multiple of its reference is reported. Calibrated with
#: benchmarks/bench_spread_check.py --cases 60 (correct models: 60 bank cases and 60 mechanical ones, the
#: Kalman smoother and DEM, 172 estimates): the largest ratio of an estimate that is not wild (RMS <= 3x
#: the truth's) is 6.45 (one DEM / Kalman estimate of the bank; the next below 5), so 8 fires on none.
SPREAD_LIMIT = 8.0


#: The input-prior check's false-warning probability per unknown input under a correct model: its
#: limit is this upper quantile of the prior's own RMS over the log (checked against 200000 draws of
#: the prior, and on correct models: benchmarks/bench_spread_check.py --input-prior).
INPUT_PRIOR_FALSE_RATE = 1e-3
#: The reference label of the input-prior check's findings.
INPUT_PRIOR_REFERENCE = "prior std about the prior mean"


class SpreadFinding(NamedTuple):
    """One state or unknown input whose estimate swings far beyond its reference.

    name: the state's / input's name; estimate_rms: RMS of its estimate over the log;
    reference_rms: the spread the data or the model support; reference: what that is
    ("measured proxy y_j", "derivative of ...", "prior spread", "input prior"); ratio:
    estimate_rms / reference_rms; settings: the model-file settings to check; limit: the ratio
    above which it was reported.
    """

    name: str
    estimate_rms: float
    reference_rms: float
    reference: str
    ratio: float
    settings: str
    limit: float = SPREAD_LIMIT


def _single(row: np.ndarray, tolerance: float = 1e-12) -> int | None:
    """Index of the only non-zero entry of ``row``, else None."""
    scale = float(np.max(np.abs(row), initial=0.0))
    if scale == 0.0:
        return None
    nonzero = np.flatnonzero(np.abs(row) > tolerance * scale)
    return int(nonzero[0]) if len(nonzero) == 1 else None


def _derivative(signal: np.ndarray, dt: float, step: int) -> np.ndarray:
    """Central difference over ``step`` samples each side (one-sided at the ends)."""
    n = len(signal)
    if n < 2:
        return np.zeros(n)
    step = max(1, min(step, (n - 1) // 2 or 1))
    ahead = np.clip(np.arange(n) + step, 0, n - 1)
    behind = np.clip(np.arange(n) - step, 0, n - 1)
    return (signal[ahead] - signal[behind]) / ((ahead - behind) * dt)


def measured_proxies(A: np.ndarray, B: np.ndarray | None, C: np.ndarray, outputs: np.ndarray, dt: float,
                     output_names, sensor_kernel_width: float = 0.0) -> tuple[np.ndarray, list]:
    """Per state, the RMS of its measured proxy (NaN where it has none) and its description.

    A (n, n), B (n, r) or None, C (m, n): the model (or its Jacobians, NaN where they vary);
    outputs (N, m): the log, NaN where missing; dt: sample time [s]; output_names: the outputs'
    names; sensor_kernel_width: s_z [s], the span of the central difference of derivative proxies.
    """
    n = A.shape[0]
    rms, labels, direct, source = np.full(n, np.nan), [""] * n, {}, {}
    for j, row in enumerate(C):
        i = _single(np.nan_to_num(row, nan=1.0))
        if i is None:
            continue
        proxy = outputs[:, j] / row[i]
        value = float(np.sqrt(np.nanmean(proxy**2))) if np.isfinite(proxy).any() else np.nan
        if np.isfinite(value) and not (value <= rms[i]):  # the largest of several proxies
            rms[i], labels[i], direct[i], source[i] = value, f"measured proxy {output_names[j]}", proxy, output_names[j]
    step = max(1, int(round(sensor_kernel_width / dt)))
    for j, proxy in list(direct.items()):
        i = _single(np.nan_to_num(A[j], nan=1.0))
        if i is None or i == j or i in direct or (B is not None and np.any(B[j] != 0)):
            continue
        filled = np.interp(np.arange(len(proxy)), np.flatnonzero(np.isfinite(proxy)), proxy[np.isfinite(proxy)])
        value = float(np.sqrt(np.mean((_derivative(filled, dt, step) / A[j, i]) ** 2)))
        if np.isfinite(value) and not (value <= rms[i]):
            rms[i], labels[i] = value, f"measured proxy d({source[j]})/dt"
    return rms, labels


def noise_intensity(kernel_width: float, dt: float) -> float:
    """sum_k rho(k dt) dt for the autocorrelation rho(tau) = exp(-tau^2 / (4 s^2)) of a coloured noise
    of unit variance per sample (dt for white noise, ~2 sqrt(pi) s for s >> dt): the low-frequency
    intensity that drives a slow state. kernel_width: s [s]; dt: sample time [s]."""
    if kernel_width <= 0:
        return dt
    reach = int(np.ceil(12 * kernel_width / dt)) + 1
    lags = np.arange(-reach, reach + 1) * dt
    return float(np.sum(np.exp(-(lags**2) / (4 * kernel_width**2))) * dt)


def prior_spread(A: np.ndarray, B: np.ndarray, dt: float, *, process_covariance: np.ndarray,
                 process_kernel_width: float, input_covariance: np.ndarray | None, input_kernel_width: float,
                 drive: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Per state, sqrt(P_ii + mean_k xbar_i[k]^2) (see the module docstring); inf when A is not stable.

    A (n, n), B (n, r): the model; dt: sample time [s]; process_covariance: inv(Pi_w) (n, n), inf
    allowed (a zero precision); process_kernel_width: s_w [s]; input_covariance: inv(P_v) (r, r) of
    the unknown inputs (0 rows / columns for measured ones), or None; input_kernel_width: s_u [s];
    drive (N, r): the measured inputs and the unknown inputs' prior means; start (n,): x at sample 0.
    The mean part is over the second half of the log, where the start has faded (see spread_findings).
    """
    from scipy.linalg import solve_continuous_lyapunov

    from attend.models.linear import zero_order_hold

    n = A.shape[0]
    if n == 0 or np.max(np.linalg.eigvals(A).real) >= 0 or not np.all(np.isfinite(process_covariance)):
        return np.full(n, np.inf)
    Q = process_covariance * noise_intensity(process_kernel_width, dt)
    if input_covariance is not None and B.shape[1]:
        Q = Q + B @ input_covariance @ B.T * noise_intensity(input_kernel_width, dt)
    P = solve_continuous_lyapunov(A, -0.5 * (Q + Q.T))
    Ad, Bd = zero_order_hold(A, B, dt)
    mean = np.empty((len(drive), n))
    x = np.asarray(start, dtype=float)
    for k in range(len(drive)):
        mean[k] = x
        x = Ad @ x + Bd @ drive[k]
    return np.sqrt(np.clip(np.diag(P), 0.0, None) + np.mean(mean[len(mean) // 2:] ** 2, axis=0))


def constant_jacobians(system, states: np.ndarray, inputs: np.ndarray, points: int = 5):
    """(A, B, C) of a nonlinear system at ``points`` samples of the estimate, NaN where they differ
    (to 1e-6 relative): the entries that are linear along this estimate. system: the
    NonlinearSystem; states (N, n), inputs (N, r): the estimate."""
    rows = np.unique(np.linspace(0, len(states) - 1, points).round().astype(int))
    found = [system.jacobians(states[k], inputs[k] if inputs.shape[1] else None)[:3] for k in rows]
    out = []
    for part in zip(*found):
        stack = np.array(part)
        same = np.all(np.abs(stack - stack[0]) <= 1e-6 * np.maximum(np.abs(stack[0]), 1e-12), axis=0)
        out.append(np.where(same, stack[0], np.nan))
    return tuple(out)


def implausible_spreads(states: np.ndarray, inputs: np.ndarray, references: np.ndarray, labels, names,
                        settings, limit: float = SPREAD_LIMIT) -> list[SpreadFinding]:
    """The findings (ratio > ``limit``) among the states and inputs with a finite reference.

    states (N, n), inputs (N, r): the estimate; references (n + r,): reference RMS per state then
    per input (NaN / inf: none); labels (n + r,): what each reference is; names (n + r,): their
    names; settings (n + r,): the settings to check for each; limit: SPREAD_LIMIT by default.
    """
    values = np.hstack([states, inputs])
    rms = np.sqrt(np.nanmean(values**2, axis=0)) if len(values) else np.zeros(values.shape[1])
    findings = []
    for i, (value, reference) in enumerate(zip(rms, references)):
        if not (np.isfinite(reference) and reference > 0 and np.isfinite(value)):
            continue
        if value > limit * reference:
            findings.append(SpreadFinding(names[i], float(value), float(reference), labels[i],
                                          float(value / reference), settings[i]))
    return findings


def _mean_square_cumulants(n_samples: int, dt: float, kernel_width: float) -> tuple[float, float, float]:
    """(k1, k2, k3) of (1 / N) sum_k e[k]^2, e unit-variance with rho(tau) = exp(-tau^2 / (4 s^2)):
    k1 = 1, k2 = 2 tr(R^2) / N^2, k3 = 8 tr(R^3) / N^3, R_kl = rho((k - l) dt); tr(R^3) with the
    inner sums over all lags (an upper bound: the tail a little heavier)."""
    N = n_samples
    if kernel_width <= 0:
        return 1.0, 2.0 / N, 8.0 / N**2
    lags = np.arange(-min(N - 1, int(np.ceil(10 * kernel_width / dt)) + 1),
                     min(N - 1, int(np.ceil(10 * kernel_width / dt)) + 1) + 1)
    rho = np.exp(-((lags * dt) ** 2) / (4 * kernel_width**2))
    weight = N - np.abs(lags)
    inner = np.convolve(rho, rho)[len(lags) // 2: len(lags) // 2 + len(lags)]  # (rho * rho) at the same lags
    return 1.0, 2.0 * float(np.sum(weight * rho**2)) / N**2, 8.0 * float(np.sum(weight * rho * inner)) / N**3


def effective_samples(n_samples: int, dt: float, kernel_width: float) -> float:
    """nu = N^2 / sum_kl rho((k - l) dt)^2 = 2 / k2: the independent samples whose mean square varies
    as that of N samples of the prior, ~ N dt / (s sqrt(2 pi)) for N dt >> s >> dt. n_samples: N;
    dt: sample time [s]; kernel_width: s_u [s] (0: white, nu = N)."""
    return 2.0 / _mean_square_cumulants(n_samples, dt, kernel_width)[1] if n_samples >= 1 else 0.0


def input_prior_limit(n_samples: int, dt: float, kernel_width: float,
                      false_rate: float = INPUT_PRIOR_FALSE_RATE) -> float:
    """The (1 - false_rate) quantile of the RMS of N samples of a unit prior, the limit of t_j (module
    docstring): the mean square's first three cumulants matched by a shifted chi-square (Pearson),
    q = 1 + sqrt(k2) (chi2_d^-1(1 - false_rate) - d) / sqrt(2 d), d = 8 k2^3 / k3^2. n_samples: N;
    dt: sample time [s]; kernel_width: s_u [s] (0: white); false_rate: the share of the prior's own
    draws above the limit."""
    from scipy.stats import chi2

    if n_samples < 1:
        return np.inf
    _, k2, k3 = _mean_square_cumulants(n_samples, dt, kernel_width)
    d = 8.0 * k2**3 / k3**2
    return float(np.sqrt(1.0 + np.sqrt(k2) * (chi2.isf(false_rate, d) - d) / np.sqrt(2.0 * d)))


def input_prior_ratios(inputs: np.ndarray, prior_mean: np.ndarray, prior_precision: np.ndarray,
                       noise_scale: float = 1.0) -> np.ndarray:
    """t_j = RMS_k(vhat_j[k] - eta_j[k]) sqrt(P_v,jj min(lambda*, 1)) per input (module docstring).
    inputs, prior_mean (N, r): vhat, eta; prior_precision (r,): P_v; noise_scale: lambda* (1: none)."""
    deviation = np.asarray(inputs, float) - np.asarray(prior_mean, float)
    rms = np.sqrt(np.nanmean(deviation**2, axis=0)) if len(deviation) else np.zeros(deviation.shape[1])
    return rms * np.sqrt(np.asarray(prior_precision, float) * _widening(noise_scale))


def _widening(noise_scale: float) -> float:
    """min(lambda*, 1), 1 for a lambda* that is not a positive number."""
    return min(float(noise_scale), 1.0) if np.isfinite(noise_scale) and noise_scale > 0 else 1.0


def input_prior_findings(inputs: np.ndarray, prior_mean: np.ndarray, prior_precision: np.ndarray, names, dt: float,
                         input_kernel_width: float, noise_scale: float = 1.0,
                         false_rate: float = INPUT_PRIOR_FALSE_RATE) -> list[SpreadFinding]:
    """The unknown inputs with t_j above :func:`input_prior_limit` (the posterior predictive check of
    the module docstring). inputs, prior_mean (N, r): vhat and eta of the unknown inputs;
    prior_precision (r,): P_v; names (r,); dt [s]; input_kernel_width: s_u [s] the estimator used;
    noise_scale: lambda*; false_rate: the limit's false-warning probability per input."""
    inputs = np.asarray(inputs, float)
    prior_precision = np.asarray(prior_precision, float)
    ratio = input_prior_ratios(inputs, prior_mean, prior_precision, noise_scale)
    findings = []
    for j, name in enumerate(names):
        count = int(np.sum(np.isfinite(inputs[:, j])))
        limit = input_prior_limit(count, dt, input_kernel_width, false_rate)
        if np.isfinite(ratio[j]) and ratio[j] > limit:
            std = 1.0 / np.sqrt(prior_precision[j] * _widening(noise_scale))
            findings.append(SpreadFinding(name, float(ratio[j] * std), float(std), INPUT_PRIOR_REFERENCE,
                                          float(ratio[j]), f"its prior_precision ([[inputs]] {name}), then the "
                                          "model's A and B", limit))
    return findings


def _reached_by(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(n, r) True where input j reaches state i through the structure of (A, B)."""
    n = A.shape[0]
    reach = np.nan_to_num(np.abs(B), nan=1.0) > 0  # NaN: an entry that varies along the estimate
    step = np.nan_to_num(np.abs(A), nan=1.0) > 0
    for _ in range(n):
        reach = reach | ((step.astype(int) @ reach.astype(int)) > 0)
    return reach


def spread_findings(system, dt: float, outputs: np.ndarray, states: np.ndarray, inputs: np.ndarray, *,
                    process_precision, process_kernel_width: float, sensor_kernel_width: float,
                    unknown: np.ndarray, drive: np.ndarray, input_prior_precision: np.ndarray,
                    input_kernel_width: float, limit: float = SPREAD_LIMIT, ratios: bool = False,
                    noise_scale: float = 1.0):
    """The check of the module docstring on one estimate (any estimator).

    system: a LinearSystem or NonlinearSystem; dt: sample time [s]; outputs (N, m): the log (NaN
    where missing); states (N, n), inputs (N, r): the estimate; process_precision: Pi_w (scalar,
    (n,) or (n, n)); process_kernel_width, sensor_kernel_width, input_kernel_width: s_w, s_z, s_u
    [s] (0: white); unknown (r,): True for the estimated inputs; drive (N, r): the measured inputs
    and the unknown inputs' prior means; input_prior_precision (r,): P_v of the unknown inputs
    (ignored for measured ones); limit: the ratio above which a finding is reported; noise_scale:
    lambda* of the input-prior check (linear models; 1: none). Returns the list of
    :class:`SpreadFinding`, or with ``ratios=True`` the ratios (n + r,) (NaN: no reference).
    """
    states, inputs = np.asarray(states, float), np.asarray(inputs, float).reshape(len(states), -1)
    n, r = states.shape[1], inputs.shape[1]
    unknown = np.asarray(unknown, dtype=bool).reshape(r)
    drive = np.nan_to_num(np.asarray(drive, float).reshape(len(states), r))
    precision = np.broadcast_to(np.asarray(input_prior_precision, float), (r,))
    output_names = list(getattr(system, "output_names", ()) or [f"y{j + 1}" for j in range(outputs.shape[1])])
    if hasattr(system, "A"):
        A, B, C = system.A, system.B, system.C
        input_cov = np.diag(np.where(unknown, 1.0 / np.where(unknown, precision, 1.0), 0.0))
        prior = prior_spread(A, B, dt, process_covariance=_covariance(process_precision, n),
                             process_kernel_width=process_kernel_width,
                             input_covariance=input_cov if unknown.any() else None,
                             input_kernel_width=input_kernel_width, drive=drive, start=states[0])
    else:
        A, B, C = constant_jacobians(system, states, inputs)
        prior = np.full(n, np.inf)
    proxy, labels = measured_proxies(A, B if r else None, C, outputs, dt, output_names, sensor_kernel_width)
    # the prior spread is compared over the second half of the log (the start, which the estimate's own
    # first sample stands for, has faded there): as a reference for the whole log's RMS it is scaled by
    # RMS(whole) / RMS(second half) of the estimate
    whole = np.sqrt(np.nanmean(states**2, axis=0))
    late = np.sqrt(np.nanmean(states[len(states) // 2:] ** 2, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        prior = np.where(late > 0, prior * whole / late, prior)
    references, reference_labels = np.full(n + r, np.nan), [""] * (n + r)
    for i in range(n):
        candidates = [(v, lab) for v, lab in ((proxy[i], labels[i]), (prior[i], "prior spread under the model"))
                      if np.isfinite(v)]
        if candidates:  # the tighter one: the estimate must be plausible under both
            references[i], reference_labels[i] = min(candidates)
    input_names = list(system.input_names)
    unknown_names = [name for name, bad in zip(input_names, unknown) if bad]
    reached = _reached_by(A, B[:, unknown]) if unknown.any() else np.zeros((n, 0), dtype=bool)
    settings = []
    for i in range(n):
        through = [name for name, hit in zip(unknown_names, reached[i]) if hit]
        if through:
            settings.append(f"the prior_precision of the unknown input{'s' if len(through) > 1 else ''} "
                            f"{', '.join(through)} and [observer] input_kernel_width, then process_precision")
        else:
            settings.append("[observer] process_precision and sensor_precision, and the model's A, C and units")
    for j in range(r):
        if unknown[j]:
            references[n + j] = float(np.sqrt(np.mean(drive[:, j] ** 2) + 1.0 / precision[j]))
            reference_labels[n + j] = "prior (mean and std)"
            settings.append(f"its prior_precision ([[inputs]] {input_names[j]}) and [observer] input_kernel_width")
        else:
            settings.append("")
    names = list(system.state_names) + input_names
    if ratios:
        values = np.hstack([states, inputs])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(np.nanmean(values**2, axis=0)) / np.where(references > 0, references, np.nan)
    findings = implausible_spreads(states, inputs, references, reference_labels, names, settings, limit)
    if hasattr(system, "A") and unknown.any():  # the input-prior check, for inputs not named already
        named = {finding.name for finding in findings}
        checked = [j for j in np.flatnonzero(unknown) if input_names[j] not in named]
        findings += input_prior_findings(inputs[:, checked], drive[:, checked], precision[checked],
                                         [input_names[j] for j in checked], dt, input_kernel_width, noise_scale)
    return findings


def check_estimate(model, log, estimate, input_kernel_width: float | None = None,
                   noise_scale: float | None = None) -> list[SpreadFinding]:
    """The spread check of ``attend estimate``: :func:`spread_findings` on an estimate of a model file.

    model: the :class:`attend.io.ModelFile`; log: the :class:`attend.io.Log` (its outputs by the
    model's output columns); estimate: the estimator's result (states (N, n), inputs (N, r));
    input_kernel_width: s_u [s] the estimator used when the file gives none (chosen from the log,
    :mod:`attend.perception.input_width`; None: the file's, or the process width); noise_scale:
    lambda* of that choice (None: 1).
    """
    states = np.asarray(estimate.states, float)
    r = model.system.n_inputs
    width = model.kernel_width or 0.0
    process_width = model.process_kernel_width if model.process_kernel_width is not None else width
    sensor_width = model.sensor_kernel_width if model.sensor_kernel_width is not None else width
    input_width = model.input_kernel_width if model.input_kernel_width is not None else process_width
    if model.input_kernel_width is None and input_kernel_width is not None:
        input_width = input_kernel_width
    drive = np.zeros((len(states), r))
    for j, spec in enumerate(model.inputs):
        drive[:, j] = (log.matrix([spec.column], missing=True)[:, 0] - spec.operating_point if spec.known
                       else spec.prior_mean)
    return spread_findings(
        model.system, float(log.dt), log.matrix(model.output_columns, missing=True), states,
        np.asarray(estimate.inputs, float), process_precision=model.process_precision,
        process_kernel_width=process_width, sensor_kernel_width=sensor_width,
        unknown=np.array([not spec.known for spec in model.inputs], dtype=bool), drive=drive,
        input_prior_precision=np.array([spec.prior_precision for spec in model.inputs], dtype=float),
        input_kernel_width=input_width, noise_scale=1.0 if noise_scale is None else noise_scale)


def _covariance(precision, n: int) -> np.ndarray:
    """inv(Pi) of a scalar, per-row list or matrix precision, inf where a diagonal precision is 0."""
    value = np.asarray(precision, dtype=float)
    if value.ndim < 2 and np.any(value == 0):
        return np.full((n, n), np.inf)
    if value.ndim == 0:
        value = np.full(n, float(value))
    if value.ndim == 1:
        return np.diag(1.0 / value)
    if np.linalg.matrix_rank(value) < n:
        return np.full((n, n), np.inf)
    return np.linalg.inv(value)


def describe(finding: SpreadFinding) -> str:
    """One line for the command line's warning. finding: a :class:`SpreadFinding`."""
    if finding.reference == INPUT_PRIOR_REFERENCE:
        return (f"unknown input '{finding.name}': its estimate's RMS about the prior mean ({finding.estimate_rms:.3g}) "
                f"is {finding.ratio:.3g}x the prior std ({finding.reference_rms:.3g}; the posterior mean under a correct "
                f"model stays under {finding.limit:.3g}x on this log): the model may lack dynamics the input is "
                f"absorbing, or the estimator is far from the posterior; check {finding.settings}")
    return (f"{finding.name}: the estimate's RMS {finding.estimate_rms:.3g} is {finding.ratio:.3g}x its "
            f"{finding.reference} ({finding.reference_rms:.3g}), far beyond what the data support: the model "
            f"does not fit this log there; check {finding.settings}")
