"""The unknown inputs' prior width s_u chosen from the log, when the model file gives none.

The Kalman smoother models an unknown input as a Gaussian process about its prior mean with
autocorrelation rho(tau) = exp(-tau^2 / (4 s_u^2)) (:mod:`attend.perception.kalman`). Without
``[observer] input_kernel_width`` the width used to be the process noise's, which has nothing to
do with how fast the inputs move. Here it is the maximum of the log's marginal likelihood, with
the model's overall noise level profiled out::

    s_u = argmax over a grid of  max_lambda log p(y | s_u, lambda)

log p(y | s_u) = -0.5 sum_k (log det S[k] + nu[k]' inv(S[k]) nu[k] + m log 2 pi), the
prediction-error decomposition of the Kalman filter the smoother already runs
(:meth:`attend.perception.kalman.KalmanEstimator.innovation_terms`: innovations nu[k], their
covariances S[k]; exact for the model, every setting as the file gives it). lambda multiplies
every precision of the model (sensor, process, the inputs' prior, the start's) at once: the gains
and the innovations stay as they are and S[k] becomes S[k] / lambda, so the maximum over lambda is
closed-form, lambda* = M / sum_k nu[k]' inv(S[k]) nu[k] (M: the number of measured values), at no
extra cost. Why: real logs rarely come with calibrated precisions (on the quadrotor flights of
``shared/data`` with the published settings the innovations are ~10^3 times their predicted
variance at every width), and the likelihood at the stated precisions then prefers whichever
width shrinks the largest innovations, the roughest input, which turns sensor noise and model
error into a swinging input and a wrong rate (state SSE 14-275x the best width's on those
flights; benchmarks/bench_unknown_inputs_misfit.py). With lambda profiled only the shape of the
innovations counts; the smoother itself runs at the file's precisions. lambda* is reported
(:attr:`InputWidthChoice.noise_scale`): far from 1 it says the precisions are off.

The grid (:func:`input_width_grid`): the octaves 0.25, 0.5, ..., 16 sample times, then the
half-octaves (factor sqrt(2)) either side of the best octave, so the chosen width is known to a
factor sqrt(2) (9 filter passes, :func:`innovation_terms_on`: no Riccati equation, the covariance
recursion stops where the gain settles; about 0.1-0.3 s each on a 12-state model with 4 unknown
inputs and 2600 samples). Flat likelihood: when every width of the grid is within FLAT_LOG_LIKELIHOOD
(2, about the 95 % likelihood-ratio interval of one parameter) of the best, the log does not
decide the width; the process width (the previous default) is kept and
:meth:`InputWidthChoice.warning` says so, naming ``[observer] input_kernel_width``. A best width at
either end of the grid is reported as such (the likelihood may still rise beyond it). lambda*
beyond MISFIT_SCALE (100) either way, innovations 10x larger or smaller in std than the model
predicts, is a warning too (:meth:`InputWidthChoice.misfit`): the model does not fit the log.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from attend._validation import AttendInputError

#: Octaves of the coarse grid, in sample times: 0.25, 0.5, 1, 2, 4, 8, 16.
OCTAVES = tuple(0.25 * 2.0**k for k in range(7))
#: Log-likelihood difference [nats] under which two widths are not told apart by the log.
FLAT_LOG_LIKELIHOOD = 2.0
#: White parts of the process and sensor noise tried above the numerical floor, in decades (fractions of
#: each noise's variance): 1e-7 .. 1e-1.
WHITE_FLOOR_DECADES = (1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
#: lambda* beyond this factor either way (innovations 100x the variance the model predicts, or
#: 1/100 of it: 10x in std) is a warning that the model does not fit the log.
MISFIT_SCALE = 100.0


class InputWidthChoice(NamedTuple):
    """How input_kernel_width s_u was chosen from a log.

    width: the width used [s] (the best of the grid, or ``fallback`` when flat); widths (W,):
    the widths tried [s], increasing; log_likelihoods (W,): max over lambda of log p(y | s_u,
    lambda) at each (the criterion) [nats]; stated_log_likelihoods (W,): log p(y | s_u) at the
    file's precisions (lambda = 1); noise_scales (W,): lambda* at each width (the factor on every
    precision that fits the innovations' size); best: the width of the largest criterion [s];
    supported: (smallest, largest) width within FLAT_LOG_LIKELIHOOD of the best [s]; flat: every
    width is within FLAT_LOG_LIKELIHOOD of the best (the log does not decide); fallback: the width
    used when flat [s] (the process width); dt: the sample time [s]; at_edge: the best is the
    smallest or largest width tried; white_floor: the :class:`WhiteFloorChoice` made with it (None: not searched).
    """

    width: float
    widths: np.ndarray
    log_likelihoods: np.ndarray
    stated_log_likelihoods: np.ndarray
    noise_scales: np.ndarray
    best: float
    supported: tuple
    flat: bool
    fallback: float
    dt: float
    at_edge: bool
    white_floor: object = None

    @property
    def noise_scale(self) -> float:
        """lambda* at the width used: the factor on every precision that fits the log's innovations."""
        return float(self.noise_scales[int(np.argmin(np.abs(np.log(self.widths / self.width))))])

    def _noise_note(self) -> str:
        scale = self.noise_scale
        if 0.1 <= scale <= 10 or self.misfit():  # (beyond MISFIT_SCALE: a warning of its own)
            return ""
        return (f"; the log's innovations are {1 / scale:.3g}x the variance the model predicts "
                f"(lambda* = {scale:.3g}): check sensor_precision and process_precision")

    def describe(self) -> str:
        """One line for the command line: the width chosen and how."""
        if self.flat:
            return self.warning()
        low, high = self.supported
        near = (f"widths with a log-likelihood within {FLAT_LOG_LIKELIHOOD:g} of it: {low:g}-{high:g} s" if high > low
                else f"no other width within {FLAT_LOG_LIKELIHOOD:g} of its log-likelihood")
        edge = ""
        if self.at_edge:
            side = "smallest" if self.best == self.widths[0] else "largest"
            edge = f"; the {side} width tried (the likelihood may rise beyond it)"
        floor = "" if self.white_floor is None else self.white_floor.describe()
        return (f"input prior width {self.width:g} s ({self.width / self.dt:.3g} sample times) chosen from the log "
                f"([observer] input_kernel_width not given): maximum likelihood over {len(self.widths)} widths "
                f"{self.widths[0] / self.dt:.3g}-{self.widths[-1] / self.dt:.3g} sample times, noise level profiled; "
                f"{near}{edge}{self._noise_note()}{'; ' + floor if floor else ''}")

    def misfit(self) -> str | None:
        """The warning to give when lambda* is beyond MISFIT_SCALE either way (and the likelihood
        is not flat, whose warning says it), or None."""
        scale = self.noise_scale
        if self.flat or 1 / MISFIT_SCALE <= scale <= MISFIT_SCALE:
            return None
        return (f"[observer] sensor_precision, process_precision: the log's innovations are {1 / scale:.3g}x the "
                f"variance this model predicts (at the input width {self.width:g} s): the precisions, or A, B and C, "
                f"do not fit this log, and the estimates' std are off by about {np.sqrt(1 / scale):.3g}x")

    def warning(self) -> str | None:
        """The warning to give (the likelihood is flat), or None."""
        if not self.flat:
            return None
        return (f"[observer] input_kernel_width: not given, and the log does not decide it (log-likelihood within "
                f"{FLAT_LOG_LIKELIHOOD:g} of its best over {self.widths[0]:g}-{self.widths[-1]:g} s); using the "
                f"process width {self.fallback:g} s; set input_kernel_width to the time over which the unknown "
                f"inputs change{self._noise_note()}")


class WhiteFloorChoice(NamedTuple):
    """How the white part of the process and sensor noise was chosen from a log
    (:func:`choose_white_floor`). floor: the one used (a fraction of each noise's variance); floors (F,):
    those tried, increasing from the numerical floor; log_likelihoods (F,): max over lambda of
    log p(y | floor) at each [nats]."""

    floor: float
    floors: np.ndarray
    log_likelihoods: np.ndarray

    @property
    def raised(self) -> bool:
        """The floor used is above the numerical one (the first tried)."""
        return bool(self.floor > self.floors[0])

    def describe(self) -> str:
        """A clause for the command line when the floor was raised, else ""."""
        if not self.raised:
            return ""
        gain = float(self.log_likelihoods[list(self.floors).index(self.floor)] - self.log_likelihoods[0])
        return (f"white part of the process and sensor noise raised from {self.floors[0]:g} to {self.floor:g} of "
                f"their variance (log-likelihood +{gain:.1f}: the log has fast content the smooth noise does not "
                "carry)")


def choose_white_floor(score: Callable[[float], float], floor: float, value: float) -> WhiteFloorChoice:
    """The white part of the process and sensor noise, raised from the numerical ``floor`` a decade at a
    time (WHITE_FLOOR_DECADES) while each raise lifts the profiled log-likelihood by more than
    FLAT_LOG_LIKELIHOOD::

        f_j = 10 f_(j-1)  kept while  L(f_j) > L(f_(j-1)) + FLAT_LOG_LIKELIHOOD

    L(f) = max over lambda of log p(y | f) (:func:`profiled_log_likelihood`). The smooth (Gaussian-kernel)
    noise of the model predicts its next sample almost exactly; a log whose model error or noise has
    fast content makes the filter's innovations far larger than predicted, and the estimates then follow
    whatever the numerical floor allows (docs/benchmarks.md, "Unknown inputs on logs the model fits
    poorly"). Raising the floor while the log supports each step is maximum likelihood over that part,
    stopped at the first decade that does not pay: one extra filter pass where nothing is raised.
    score(f) -> L(f) at the input width chosen; value: L(floor)."""
    floors, values = [float(floor)], [float(value)]
    for candidate in WHITE_FLOOR_DECADES:
        if candidate <= floors[-1]:
            continue
        result = float(score(candidate))
        floors.append(candidate)
        values.append(result)
        if not result > values[-2] + FLAT_LOG_LIKELIHOOD:
            break
    kept = 0
    while kept + 1 < len(floors) and values[kept + 1] > values[kept] + FLAT_LOG_LIKELIHOOD:
        kept += 1
    return WhiteFloorChoice(floor=floors[kept], floors=np.array(floors), log_likelihoods=np.array(values))


def input_width_grid(dt: float) -> np.ndarray:
    """The coarse grid of widths [s]: OCTAVES sample times. dt: sample time [s]."""
    return np.asarray(OCTAVES) * dt


def profiled_log_likelihood(terms) -> tuple[float, float]:
    """(max over lambda of log p(y | lambda), lambda*) with every precision of the model times lambda
    (S[k] -> S[k] / lambda): lambda* = M / Q and the maximum -0.5 (log det + M log(Q / M) + M + M log 2 pi),
    Q the sum of nu' inv(S) nu and M the number of measured values. terms: the filter's
    :class:`~attend.perception.kalman_recursions.InnovationTerms` at lambda = 1."""
    count = terms.count
    quadratic = max(terms.quadratic, 1e-300 * count)
    scale = count / quadratic
    value = -0.5 * (terms.log_determinant + count * np.log(quadratic / count) + count + count * np.log(2 * np.pi))
    return float(value), float(scale)


def innovation_terms_on(estimator, outputs, signals=None, time=None):
    """The Kalman filter's InnovationTerms of a :class:`~attend.perception.kalman.KalmanEstimator` on
    a log, for the criterion: on a complete log of uniform samples (``time`` None, nothing missing)
    the filter whose covariance recursion stops where its gain settles, without the Riccati
    equation the smoother solves for its steady gain
    (:func:`attend.perception.kalman_recursions.converged_innovation_terms`: on 2600 samples of a
    12-state model with 4 unknown inputs, 0.1-0.3 s a width instead of 0.3-0.8 s, within 1e-4 nats);
    otherwise the estimator's own :meth:`~attend.perception.kalman.KalmanEstimator.innovation_terms`.
    outputs (N, m), NaN where missing; signals (N, r): the measured inputs and the unknown ones'
    prior means (None: zeros); time (N,) [s] or None."""
    from attend._threads import single_blas_thread
    from attend.perception.kalman_recursions import converged_innovation_terms

    y = np.asarray(outputs, dtype=float)
    model = estimator.augmented_model
    Bd = model["Bd"]
    u = np.zeros((len(y), Bd.shape[1])) if signals is None else np.asarray(signals, dtype=float).reshape(len(y), -1)
    if time is not None or not (np.all(np.isfinite(y)) and np.all(np.isfinite(u))):
        return estimator.innovation_terms(outputs, signals, time=time)
    with single_blas_thread():
        mean0, cov0 = estimator.initial_prior(y)
        drive = np.zeros((len(y), model["dim"]))
        drive[:, model["slices"]["x"]] = u @ Bd.T  # b[k] = Bd u[k] enters x[k + 1], as the smoother's
        return converged_innovation_terms(model["T"], model["Q"], model["H"], y, drive, mean0, cov0,
                                          model["slices"].values())


def choose_input_width(innovation_terms: Callable[[float], object], dt: float, fallback: float,
                       smallest: float | None = None) -> InputWidthChoice:
    """The maximum-likelihood input width (see the module docstring).

    innovation_terms(width) -> the filter's InnovationTerms at s_u = width (e.g. ``lambda s:
    KalmanEstimator(..., input_kernel_width=s).innovation_terms(y, eta)``); dt: the log's sample
    time [s]; fallback: the width used when the likelihood is flat [s] (the process width);
    smallest: no width below it is tried (it is tried itself) [s]; None: the whole grid.
    """
    values = {}

    def evaluate(width: float) -> float:
        key = round(width / dt, 9)
        if key not in values:
            terms = innovation_terms(float(width))
            values[key] = (*profiled_log_likelihood(terms), float(terms.log_likelihood))
        return values[key][0]

    coarse = input_width_grid(dt)
    if smallest is not None:
        coarse = coarse[coarse > smallest * (1 + 1e-9)]
        coarse = np.concatenate([[float(smallest)], coarse])
    scores = np.array([evaluate(width) for width in coarse])
    if not np.isfinite(scores).any():
        raise AttendInputError("input_kernel_width: not given, and the log-likelihood is not finite at any width "
                               f"{coarse[0] / dt:.3g}-{coarse[-1] / dt:.3g} sample times; give [observer] "
                               "input_kernel_width, then check the precisions and the log's scale")
    best = int(np.nanargmax(np.where(np.isfinite(scores), scores, -np.inf)))
    for neighbour in (best - 1, best + 1):  # the half-octaves either side of the best octave
        if 0 <= neighbour < len(coarse):
            evaluate(float(np.sqrt(coarse[best] * coarse[neighbour])))
    keys = sorted(values)
    widths = np.array(keys) * dt
    profiled, scales, stated = (np.array([values[key][i] for key in keys]) for i in range(3))
    profiled = np.where(np.isfinite(profiled), profiled, -np.inf)
    top = int(np.argmax(profiled))
    near = widths[profiled >= profiled[top] - FLAT_LOG_LIKELIHOOD]
    flat = bool(np.all(profiled >= profiled[top] - FLAT_LOG_LIKELIHOOD))
    return InputWidthChoice(
        width=float(fallback if flat else widths[top]), widths=widths, log_likelihoods=profiled,
        stated_log_likelihoods=stated, noise_scales=scales, best=float(widths[top]),
        supported=(float(near.min()), float(near.max())), flat=flat, fallback=float(fallback), dt=float(dt),
        at_edge=top in (0, len(widths) - 1))
