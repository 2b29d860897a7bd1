"""Where the unscented smoother starts when nobody says: a global search over x[0].

Without ``initial_state`` the state at the first sample is unknown, and for a nonlinear model the
first samples can fit several starts (a double well seen through x^2, an angle seen through sin,
a chaotic system the filter cannot reach from a wrong point). The search runs a bank of unscented
filters (a Gaussian sum) over a broad prior on x[0] along the log and keeps what the data support:

1. Prior p(x[0]) (:class:`StartPrior`): about mu_0 with scale sigma_0 per state, z = (x - mu_0) /
   sigma_0; a multivariate Student t with one degree of freedom (a scale mixture of Gaussians:
   flat near mu_0, a start at |z| >> 1 costs ~(n + 1) ln|z| nats, not |z|^2 / 2) or a Gaussian.
2. Components: mu_0, and shells of radius r = 0.5, 1, 2, ..., 256 sigma_0 in the 2n axis
   directions (and the 2^n diagonals for n <= 3), each N(centre, (r / 2)^2 sigma_0^2): every point
   within 256 sigma_0 of mu_0 lies within 1.1 (n <= 2), 1.3 (n = 3), 1.9 (n = 4) component std of
   a centre. Extra starts (DEM's) join them.
3. The bank: each component is an unscented Kalman filter of the smoother's own white-noise model,
   scored log p(y[0..k] | component) + log p(centre) + 1/2 log|2 pi P_0| (the evidence of the data
   and the prior mass the component stands for). After every sample, components PRUNE_NATS below
   the best go, and of two whose filtered means lie each within the other's one-std ellipsoid the
   lower-scoring one goes. The bank stops when one is left or after BANK_HORIZON samples.
4. Modes (:func:`_mode`): each of the best MAX_MODES components is smoothed over the whole log from
   its prior; what the log says of x[0] (the smoothed N(m, Sigma) with the component's prior divided
   out, :func:`data_information`) is combined with p(x[0]) (:func:`prior_map`), and the smoother runs
   again from that x0_hat with its std widened by START_STD_INFLATION. The prior itself and the extra
   starts run once as they are (anchors: the bank's evidence of a wide component can be too kind
   where the model's nonlinearity makes its Gaussian predictions wrong). A mode's score is the
   second run's evidence + log p(x0_hat) + 1/2 log|2 pi S| (S its start covariance): a Laplace
   estimate of its posterior mass, comparable between modes.
5. The best mode starts the smoother. A second mode within AMBIGUITY_NATS of it whose estimate
   differs from the best's after the start-up (more than 3 joint std at over 1 % of the samples
   after the first max(20, N / 10)) makes the start ambiguous (:attr:`StartSearch.ambiguous`);
   modes that differ only during the start-up are the same estimate (the data resolved them).

Cost: the bank moves (2d + 1) sigma points of up to 141 components (n = 3) over its first samples,
then a few, with the smoother's RK4 sub-steps divided by BANK_SUBSTEP_FRACTION; then two smoother runs
per mode and one per anchor, with the sub-steps divided by SEARCH_SUBSTEP_FRACTION (no error spread;
each start is smoothed once, so a mode whose first run starts where an anchor does reuses that run).
The modes run first; a mode's second run and an anchor then stop as soon as their score can no longer
come within AMBIGUITY_NATS + FLOOR_MARGIN_NATS of the best so far (the filter's evidence_floor: each
later sample adds at most -1/2 log|2 pi R| to the log-likelihood), so a hopeless start (on Lorenz, the
prior N(0, I) itself, ~3000 nats below) costs a few samples, not a whole run; the starts that finish,
and so the choice and the ambiguity, are the same. On the first three Lorenz logs of
``benchmarks/bench_nonlinear_start.py`` (128 samples) the search calls f 35 000-72 000 times (51 000-
113 000 before issue 29's bank sub-steps and floors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attend._validation import AttendInputError

#: shell radii of the bank's component centres, in units of the prior scale sigma_0
SHELL_RADII = 0.5 * 2.0 ** np.arange(10)
#: a component's std over its shell's radius (neighbouring shells and directions overlap)
SHELL_WIDTH = 0.5
#: components scoring this many nats below the best are dropped (generous: a component in the
#: right basin but started far from the truth pays for its first predictions)
PRUNE_NATS = 25.0
#: the bank stops after this many samples (or when one component is left); the modes it keeps are
#: then compared on the whole log
BANK_HORIZON = 64
#: at most this many of the bank's components become modes
MAX_MODES = 4
#: two modes whose scores differ by less (posterior odds below e^3 ~ 20) are equally good
AMBIGUITY_NATS = 3.0
#: the std of x0_hat is widened by this before the mode's second run (it has seen the data once)
START_STD_INFLATION = 2.0
#: the search's smoother runs integrate with this fraction of the smoother's RK4 sub-steps (rounded up):
#: h rho <= 0.4 where the smoother's follow rk4_substeps (h rho <= 0.2)
SEARCH_SUBSTEP_FRACTION = 2
#: the bank integrates with this fraction of the smoother's RK4 sub-steps (rounded up): h rho <= 0.8
BANK_SUBSTEP_FRACTION = 4
#: a mode's second run or an anchor stops once its score can no longer come within AMBIGUITY_NATS plus
#: this margin of the best score so far (then it can be neither the best nor a rival of the best)
FLOOR_MARGIN_NATS = 1.0
#: a best start whose estimate leaves the outputs this many sensor noise variances from the log
#: (mean r' inv(R) r / m; about 1 or less where the estimate follows the log) did not find the log
MISFIT_LIMIT = 4.0


class AmbiguousStartError(AttendInputError):
    """The log fits several starts about equally well and they lead to different estimates."""


@dataclass(frozen=True)
class StartPrior:
    """The search's prior on x[0]: z = (x - centre) / scale, a multivariate Student t with ``dof``
    degrees of freedom, log p = -(dof + n)/2 ln(1 + |z|^2 / dof) - sum ln scale (+ const), or for
    dof = inf the Gaussian N(centre, diag(scale^2)), log p = -|z|^2 / 2 - sum ln scale (+ const).

    centre: mu_0 (n,); scale: sigma_0 (n,) > 0 [state unit]; dof: nu > 0 or inf."""

    centre: np.ndarray
    scale: np.ndarray
    dof: float = 1.0

    def log_density(self, x) -> np.ndarray:
        """log p(x) up to a constant, for points x (..., n)."""
        squared = np.sum(((np.asarray(x, dtype=float) - self.centre) / self.scale) ** 2, axis=-1)
        n = len(self.centre)
        body = -0.5 * squared if np.isinf(self.dof) else -0.5 * (self.dof + n) * np.log1p(squared / self.dof)
        return body - np.sum(np.log(self.scale))

    def weight(self, x) -> float:
        """The prior's local Gaussian precision factor w at x (p ~ N(centre, diag(scale^2) / w) there):
        (dof + n) / (dof + |z|^2), 1 for a Gaussian (iteratively reweighted least squares)."""
        if np.isinf(self.dof):
            return 1.0
        squared = float(np.sum(((np.asarray(x, dtype=float) - self.centre) / self.scale) ** 2))
        return (self.dof + len(self.centre)) / (self.dof + squared)


@dataclass(frozen=True)
class StartMode:
    """One mode of the posterior of x[0] found by the search.

    mean (n,): x0_hat; std (n,): the std the estimate starts with; score: its log posterior mass
    [nats] (evidence of the log from N(mean, diag(std^2)) + log p(mean) + 1/2 log|2 pi diag(std^2)|);
    states (N, n), state_std (N, n): the smoother's estimate from this start (white-noise
    covariances); misfit: mean over the samples of r_k' inv(R) r_k / m, r_k = y_k - g(x_k, v_k)
    at that estimate (about 1 or less where the estimate follows the log; R the sensor noise
    covariance, m outputs)."""

    mean: np.ndarray
    std: np.ndarray
    score: float
    states: np.ndarray
    state_std: np.ndarray
    misfit: float


@dataclass(frozen=True)
class StartSearch:
    """The result of :func:`search_start`.

    modes: the distinct modes found, best first; components: the bank's size at the first sample;
    samples_searched: the samples the bank ran; ambiguous: True when a second mode scores within
    AMBIGUITY_NATS of the best and its estimate differs after the start-up (:attr:`message`)."""

    modes: tuple
    components: int
    samples_searched: int
    ambiguous: bool

    @property
    def mean(self) -> np.ndarray:
        """x[0] of the best mode (n,)."""
        return self.modes[0].mean

    @property
    def std(self) -> np.ndarray:
        """The std of x[0] the estimate starts with (n,)."""
        return self.modes[0].std

    @property
    def message(self) -> str:
        """One line: the two best starts, their scores and how far apart their estimates are."""
        best, second = self.modes[0], self.modes[1]
        gap = np.max(np.abs(best.states - second.states))
        equal = sum(1 for mode in self.modes if best.score - mode.score < AMBIGUITY_NATS)
        return (f"initial_state: not given, and the log fits {equal} starts about equally well (x[0] = "
                f"{_short(best.mean)} and {_short(second.mean)}, log posterior {best.score:.1f} and "
                f"{second.score:.1f} nats), whose estimates differ by up to {gap:.3g} after the start-up; give "
                "initial_state (and initial_state_std) to choose")

    @property
    def misfit_message(self) -> str:
        """One line: the best start's estimate does not follow the log (misfit above MISFIT_LIMIT)."""
        best = self.modes[0]
        return (f"initial_state: not given, and from the best start the search found (x[0] = {_short(best.mean)}) the "
                f"unscented smoother's outputs are {best.misfit:.3g} sensor noise variances from the log on average "
                f"(about 1 where it follows the log, {MISFIT_LIMIT:g} at most): the estimate is not reliable; give "
                "initial_state, or try [observer] method = \"dem\" with states = \"path\"")


def _short(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in np.asarray(values, dtype=float)) + "]"


def shell_directions(n: int) -> np.ndarray:
    """Unit directions (D, n) of a shell: the 2n axes, and for n <= 3 the 2^n diagonals."""
    axes = np.vstack([np.eye(n), -np.eye(n)])
    if n == 1 or n > 3:
        return axes
    corners = np.array(np.meshgrid(*[[-1.0, 1.0]] * n, indexing="ij")).reshape(n, -1).T / np.sqrt(n)
    return np.vstack([axes, corners])


def initial_components(centre, scale) -> tuple[np.ndarray, np.ndarray]:
    """(centres (K, n), stds (K, n)) of the bank: the prior's centre with std SHELL_WIDTH times the
    first radius, and every :func:`shell_directions` direction at every radius r of SHELL_RADII with
    std SHELL_WIDTH r; in units of ``scale`` (n,) about ``centre`` (n,)."""
    centre, scale = np.asarray(centre, dtype=float), np.asarray(scale, dtype=float)
    directions = shell_directions(len(centre))
    radii = np.repeat(SHELL_RADII, len(directions))
    points = np.vstack([np.zeros(len(centre)), np.tile(directions, (len(SHELL_RADII), 1)) * radii[:, None]])
    widths = SHELL_WIDTH * np.concatenate([[SHELL_RADII[0]], radii])
    return centre + points * scale, widths[:, None] * scale


def search_start(system, dt: float, outputs, inputs=None, *, process_covariance, measurement_covariance,
                 input_variance=None, input_mean=None, known_inputs=None, substeps: int = 10, prior_mean=None,
                 prior_scale=None, prior_dof: float = 1.0, extra_starts=(), step_lengths=None) -> StartSearch:
    """Search x[0] for the unscented smoother (the module's steps 1-5).

    system: the NonlinearSystem; dt: sample time [s]; outputs (N, m); inputs, process_covariance,
    measurement_covariance, input_variance, input_mean, known_inputs, substeps, step_lengths: the smoother's own
    white-noise model and the log's steps (:func:`attend.perception.nonlinear_smoothers.unscented_kalman`); prior_mean:
    mu_0 (n,) (default 0); prior_scale: sigma_0 (n,) or a scalar > 0 (default 1) [state unit];
    prior_dof: the prior's degrees of freedom (1: heavy-tailed, inf: Gaussian; :class:`StartPrior`);
    extra_starts: more (mean (n,), std (n,)) starts for the bank and the anchors (e.g. DEM's).
    An AttendInputError from f or g is raised only when every component fails with it."""
    n = system.n_states
    centre = np.zeros(n) if prior_mean is None else np.asarray(prior_mean, dtype=float).reshape(n)
    scale = np.broadcast_to(np.asarray(1.0 if prior_scale is None else prior_scale, dtype=float), (n,)).copy()
    if not (np.all(np.isfinite(centre)) and np.all(np.isfinite(scale)) and np.all(scale > 0)):
        raise AttendInputError(f"initial_state_std: the search's prior needs a finite scale > 0 per state, got "
                               f"{_short(scale)}")
    prior = StartPrior(centre, scale, float(prior_dof))
    centres, stds = initial_components(centre, scale)
    extra = []
    for mean, std in extra_starts:
        mean, std = np.asarray(mean, dtype=float).reshape(n), np.broadcast_to(np.asarray(std, dtype=float), (n,))
        if np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0):
            centres, stds = np.vstack([centres, mean]), np.vstack([stds, std])
            extra.append(len(centres) - 1)
    # the search only ranks starts: RK4 at half the smoother's sub-steps (h rho <= 0.4 where the smoother's
    # follow rk4_substeps, local error ~ 0.4^5 / 120 ~ 1e-4) is accurate enough for that
    options = dict(process_covariance=process_covariance, measurement_covariance=measurement_covariance,
                   input_variance=input_variance, input_mean=input_mean, known_inputs=known_inputs,
                   substeps=max(1, int(np.ceil(substeps / SEARCH_SUBSTEP_FRACTION))), step_lengths=step_lengths)
    # the bank only prunes (by PRUNE_NATS, generously) and ranks: at h rho <= 0.8 the estimates are those
    # of a bank at the smoother runs' 0.4 to the bit on the 22 logs of benchmarks/bench_nonlinear_start.py
    bank_options = dict(options, substeps=max(1, int(np.ceil(substeps / BANK_SUBSTEP_FRACTION))))
    try:
        bank = _Bank(system, dt, outputs, inputs, bank_options, centres, stds, prior)
    except AttendInputError:  # e.g. too few sub-steps for RK4 to be stable at the centre: the runs' sub-steps
        bank = _Bank(system, dt, outputs, inputs, options, centres, stds, prior)
    survivors, searched = bank.run()
    starts = [(centre, scale)] + [(centres[k], stds[k]) for k in extra
                                  if not (np.allclose(centres[k], centre) and np.allclose(stds[k], scale))]
    runs: dict = {}  # a mode's first run is often an anchor's (DEM's start survives the bank): run it once
    # modes first, then anchors; each run after the first score stops where it can no longer come near
    # the best score so far (_floor): the modes and anchors that finish are the same
    best, modes, anchors = -np.inf, [], []
    for k in survivors[:MAX_MODES]:
        modes.append(_mode(system, dt, outputs, inputs, options, centres[k], stds[k], prior, runs, best))
        best = best if modes[-1] is None else max(best, modes[-1].score)
    for mean, std in starts:
        anchors.append(_anchor(system, dt, outputs, inputs, options, mean, std, prior, runs, best))
        best = best if anchors[-1] is None else max(best, anchors[-1].score)
    basins = _basins([mode for mode in modes + anchors if mode is not None])
    if not basins:
        raise AttendInputError("initial_state: the search found no start from which the unscented smoother "
                               "follows the log; give initial_state and initial_state_std")
    ambiguous = len(basins) > 1 and basins[0].score - basins[1].score < AMBIGUITY_NATS
    return StartSearch(tuple(basins), len(centres), searched, bool(ambiguous))


def _basins(modes: list) -> list:
    """The best mode of each basin, best first: modes whose estimates do not differ after the start-up
    (:func:`_differ`) are one basin."""
    kept: list = []
    for mode in sorted(modes, key=lambda mode: -mode.score):
        if all(_differ(mode, other) for other in kept):
            kept.append(mode)
    return kept


def _differ(a: StartMode, b: StartMode) -> bool:
    """True when the estimates from two starts differ after the start-up (max(20, N / 10) samples):
    by more than 3 joint std at over 1 % of those samples."""
    count = len(a.states)
    later = slice(min(count - 1, max(20, count // 10)), None)
    joint = np.sqrt(a.state_std[later] ** 2 + b.state_std[later] ** 2) + 1e-12
    apart = np.any(np.abs(a.states[later] - b.states[later]) > 3.0 * joint, axis=1)
    return bool(np.mean(apart) > 0.01)


def _smoother(system, dt, outputs, inputs, options, mean, std, runs: dict | None = None, floor: float | None = None):
    """The unscented RTS smoother from N(mean, diag(std^2)) (no error spread), or None where it fails
    or its log-likelihood falls below ``floor`` [nats] (None: no floor; the filter then stops early,
    :class:`~attend.perception.nonlinear_smoothers.EvidenceBelowFloor`); runs: the runs so far of this
    search by their start (each start is smoothed once; a run stopped at its floor is not kept), or None."""
    key = None if runs is None else (np.asarray(mean, dtype=float).tobytes(), np.asarray(std, dtype=float).tobytes())
    if key is not None and key in runs:
        return runs[key]
    from attend.perception.nonlinear_smoothers import EvidenceBelowFloor

    try:
        run = _smoothed(system, dt, outputs, inputs, options if floor is None else dict(options, evidence_floor=floor),
                        mean, std)
    except EvidenceBelowFloor:
        return None
    if key is not None:
        runs[key] = run
    return run


def _smoothed(system, dt, outputs, inputs, options, mean, std):
    """:func:`_smoother` without the record of runs."""
    from attend.perception.nonlinear_smoothers import unscented_kalman

    try:
        with np.errstate(all="ignore"):
            run = unscented_kalman(system, dt, outputs, inputs, initial_mean=mean, initial_covariance=np.diag(std**2),
                                   **options)
    except (AttendInputError, np.linalg.LinAlgError, ValueError):
        return None
    finite = np.all(np.isfinite(run.states)) and np.all(np.isfinite(run.state_covariance[0]))
    return run if finite and np.isfinite(run.log_likelihood) else None


def _prior_mass(mean, std, prior: StartPrior) -> float:
    """log p(mean) + 1/2 log|2 pi diag(std^2)|: what a start N(mean, diag(std^2)) adds to its run's
    log-likelihood in its score (:class:`StartMode`)."""
    return float(prior.log_density(mean)) + 0.5 * float(np.sum(np.log(2 * np.pi * std**2)))


def _floor(best: float, mean, std, prior: StartPrior) -> float | None:
    """The log-likelihood below which a run from N(mean, diag(std^2)) scores less than ``best`` (the
    best score so far) - AMBIGUITY_NATS - FLOOR_MARGIN_NATS: it could be neither the best start nor
    one within AMBIGUITY_NATS of it, so it changes neither the choice nor the ambiguity. None
    while there is no best yet."""
    if not np.isfinite(best):
        return None
    return best - AMBIGUITY_NATS - FLOOR_MARGIN_NATS - _prior_mass(mean, std, prior)


def _scored(system, outputs, options, run, mean, std, prior: StartPrior) -> StartMode:
    """The :class:`StartMode` of a smoother run from N(mean, diag(std^2))."""
    score = run.log_likelihood + _prior_mass(mean, std, prior)
    return StartMode(np.asarray(mean, dtype=float), std, float(score), run.states, run.state_std,
                     _misfit(system, outputs, run, options["measurement_covariance"]))


def _mode(system, dt, outputs, inputs, options, mean, std, prior: StartPrior, runs: dict | None = None,
          best: float = -np.inf) -> StartMode | None:
    """Smooth from the component's N(mean, diag(std^2)); combine what the log says of x[0]
    (:func:`data_information`) with the prior (:func:`prior_map`); smooth again from there with
    the std widened by START_STD_INFLATION. None where a run fails, or where the second run cannot
    score within AMBIGUITY_NATS of ``best``, the best score so far (:func:`_floor`). runs: as
    :func:`_smoother`."""
    first = _smoother(system, dt, outputs, inputs, options, mean, std, runs)
    if first is None:
        return None
    try:
        information, shift = data_information(first.states[0], first.state_covariance[0], mean, std)
        start = prior_map(information, shift, first.states[0], prior)
        # the second run sees the data again: start from the prior and a 1/INFLATION^2 share of their information
        covariance = np.linalg.inv(information / START_STD_INFLATION**2 + prior.weight(start) * np.diag(prior.scale**-2.0))
    except np.linalg.LinAlgError:
        return None
    start_std = np.maximum(np.sqrt(np.clip(np.diag(covariance), 0, None)), 1e-9 * (1.0 + np.abs(start)))
    second = _smoother(system, dt, outputs, inputs, options, start, start_std, runs,
                       _floor(best, start, start_std, prior))
    return None if second is None else _scored(system, outputs, options, second, start, start_std, prior)


def _anchor(system, dt, outputs, inputs, options, mean, std, prior: StartPrior, runs: dict | None = None,
            best: float = -np.inf) -> StartMode | None:
    """The smoother from N(mean, diag(std^2)) as it is, scored like a mode; None where it fails or
    cannot score within AMBIGUITY_NATS of ``best`` (:func:`_floor`). runs: as :func:`_smoother`."""
    std = np.maximum(np.asarray(std, dtype=float), 1e-9 * (1.0 + np.abs(mean)))
    run = _smoother(system, dt, outputs, inputs, options, mean, std, runs, _floor(best, mean, std, prior))
    return None if run is None else _scored(system, outputs, options, run, mean, std, prior)


def data_information(smoothed_mean, smoothed_covariance, prior_mean, prior_std) -> tuple[np.ndarray, np.ndarray]:
    """What the log says of x[0], (J, h): the smoothed N(m, Sigma) (smoothed_mean m (n,),
    smoothed_covariance Sigma (n, n)) with the component's prior N(c, diag(P)) (prior_mean c (n,),
    prior_std sqrt(P) (n,)) divided out: the information J = inv(Sigma) - inv(P) (negative
    eigenvalues, linearisation noise, set to 0) and shift h = inv(Sigma) m - inv(P) c, so that the
    log's likelihood of x[0] is ~ exp(-1/2 x'J x + h'x). Directions the log does not see get J ~ 0
    (there the smoother kept the component's prior, which says nothing of the truth)."""
    precision = np.linalg.pinv(smoothed_covariance, hermitian=True)
    prior_precision = np.diag(1.0 / np.asarray(prior_std, dtype=float) ** 2)
    information = precision - prior_precision
    values, vectors = np.linalg.eigh(0.5 * (information + information.T))
    information = (vectors * np.clip(values, 0, None)) @ vectors.T
    return information, precision @ smoothed_mean - prior_precision @ prior_mean


def prior_map(information, shift, guess, prior: StartPrior, iterations: int = 50) -> np.ndarray:
    """x[0] at the mode of exp(-1/2 x'J x + h'x) p(x) (information J (n, n), shift h (n,) from
    :func:`data_information`; p the ``prior``, a :class:`StartPrior`), by iteratively reweighted least
    squares (p as a Gaussian of precision w diag(1/scale^2), :meth:`StartPrior.weight` at the current
    x; at most ``iterations`` steps) from ``guess`` (n,) and from the prior's centre, keeping the
    higher of the two (where the log says little of a direction, the maximum near the data's guess
    can be a local one). Where the log sees x[0], J dominates and x[0] stays where the data put it;
    where it does not, x[0] returns to the prior's centre."""
    inverse_scale = np.diag(1.0 / prior.scale**2)

    def objective(x):
        return float(-0.5 * x @ information @ x + shift @ x + prior.log_density(x))

    best = None
    for x in (np.asarray(guess, dtype=float), prior.centre):
        for _ in range(iterations):
            w = prior.weight(x)
            new = np.linalg.solve(information + w * inverse_scale, shift + w * inverse_scale @ prior.centre)
            settled = np.max(np.abs(new - x)) <= 1e-10 * (1.0 + np.max(np.abs(x)))
            x = new
            if settled:
                break
        if best is None or objective(x) > objective(best):
            best = x
    return best


def _misfit(system, outputs, estimate, measurement_covariance) -> float:
    """mean_k r_k' inv(R) r_k / m with r_k = y_k - g(x_k, v_k) at ``estimate`` (a KalmanEstimate);
    with missing outputs (NaN) the sum over the measured ones (R_oo) over their number."""
    from attend.perception.nonlinear_smoothers.kalman import observe_points

    y = np.asarray(outputs, dtype=float).reshape(len(estimate.states), -1)
    try:
        with np.errstate(all="ignore"):
            residual = y - observe_points(system, estimate.states, np.asarray(estimate.inputs).reshape(len(y), -1))
    except AttendInputError:
        return float("inf")
    R = np.atleast_2d(np.asarray(measurement_covariance, dtype=float))
    measured = np.isfinite(y)
    if measured.all():
        value = float(np.mean(np.einsum("ki,ki->k", residual, np.linalg.solve(R, residual.T).T)) / y.shape[1])
    else:  # missing outputs (NaN): each sample's measured ones, over the number of measured values
        total = sum(float(row[seen] @ np.linalg.solve(R[np.ix_(seen, seen)], row[seen]))
                    for row, seen in zip(residual, measured) if seen.any())
        value = total / max(int(measured.sum()), 1)
    return value if np.isfinite(value) else float("inf")


class _Bank:
    """The components' unscented filters, stepped together (one call of the transition, and one of
    the observation, for all sigma points of all components)."""

    def __init__(self, system, dt, outputs, inputs, options, centres, stds, prior: StartPrior):
        from attend.perception.nonlinear_smoothers.kalman import _Model

        # the sub-steps are checked at the prior's centre (centres[0]), where the search starts, not at
        # x = 0: a model may be stiff only near 0
        self.model = _Model(system, dt, outputs, inputs, options["input_variance"], options["input_mean"],
                            options["process_covariance"], options["measurement_covariance"], centres[0], None,
                            options["substeps"], options["known_inputs"], missing=True, steps=options.get("step_lengths"))
        n, d = system.n_states, self.model.size
        self.mean = np.tile(self.model.m0, (len(centres), 1))
        self.mean[:, :n] = centres
        self.cov = np.tile(self.model.P0, (len(centres), 1, 1))
        self.cov[:, :n, :n] = np.einsum("ki,ij->kij", stds**2, np.eye(n))
        # the prior mass each component stands for: log p(centre) + 1/2 log|2 pi P_0|
        self.score = prior.log_density(centres) + 0.5 * np.sum(np.log(2 * np.pi * stds**2), axis=1)
        self.index = np.arange(len(centres))
        self.d = d
        # alpha = 1, beta = 2, kappa = 0 (unscented_kalman's defaults): points at +-sqrt(d) std
        self.weights_mean = np.full(2 * d + 1, 1.0 / (2 * d))
        self.weights_mean[0] = 0.0
        self.weights_cov = self.weights_mean.copy()
        self.weights_cov[0] = 2.0

    def _points(self, mean, cov):
        """Sigma points (K, 2d + 1, d): mean and mean +- the columns of chol(d P)."""
        d = self.d
        scaled = d * cov + 1e-12 * np.eye(d) * np.maximum(1.0, np.trace(cov, axis1=1, axis2=2))[:, None, None]
        try:
            root = np.linalg.cholesky(scaled)
        except np.linalg.LinAlgError:
            values, vectors = np.linalg.eigh(scaled)
            root = vectors * np.sqrt(np.clip(values, 0, None))[:, None, :]
        columns = np.swapaxes(root, 1, 2)
        return np.concatenate([mean[:, None], mean[:, None] + columns, mean[:, None] - columns], axis=1)

    def _apply(self, function, points, k):
        """function (rows -> rows) on every component's points (K, P, d); a component whose points
        fail (an error from f or g) gets NaN. Raises the error when all fail."""
        K, P, _ = points.shape
        try:
            with np.errstate(all="ignore"):
                return np.asarray(function(points.reshape(K * P, -1), k), dtype=float).reshape(K, P, -1)
        except AttendInputError as error:
            failure = error
        out = []
        for c in range(K):
            try:
                with np.errstate(all="ignore"):
                    out.append(np.asarray(function(points[c], k), dtype=float))
            except AttendInputError as error:
                failure = error
                out.append(None)
        if all(value is None for value in out):
            raise failure
        width = next(value for value in out if value is not None).shape[1]
        return np.stack([np.full((P, width), np.nan) if value is None else value for value in out])

    def _keep(self, mask):
        self.mean, self.cov, self.score, self.index = self.mean[mask], self.cov[mask], self.score[mask], self.index[mask]

    def run(self) -> tuple[list, int]:
        """(the indices of the components left, best first; the samples run)."""
        model, y = self.model, self.model.y
        wm, wc = self.weights_mean, self.weights_cov
        noise = model.step_noise()
        for k in range(len(y)):
            if k > 0:
                moved = self._apply(model.transition_points, self._points(self.mean, self.cov), k)
                self.mean = np.einsum("p,kpd->kd", wm, moved)
                spread = moved - self.mean[:, None]
                self.cov = np.einsum("p,kpi,kpj->kij", wc, spread, spread) + (noise if noise.ndim == 2 else noise[k])
            self._update(y[k], k)
            finite = np.isfinite(self.score) & np.all(np.isfinite(self.mean), axis=1) \
                & np.all(np.isfinite(self.cov), axis=(1, 2))
            if not finite.any():
                raise AttendInputError("initial_state: every start of the search left the model's domain (non-finite "
                                       "filter values); give initial_state and initial_state_std")
            self._keep(finite)
            self._keep(self.score >= self.score.max() - PRUNE_NATS)
            self._merge()
            if len(self.score) == 1 or k + 1 >= BANK_HORIZON:
                break
        order = np.argsort(-self.score)
        return [int(i) for i in self.index[order]], k + 1

    def _update(self, outputs, k: int) -> None:
        """Every component's unscented update with the outputs (m,) of sample k, and its score; a
        missing output (NaN) is left out, and a sample without any is no update."""
        model, wm, wc = self.model, self.weights_mean, self.weights_cov
        measured = np.isfinite(outputs)
        if not measured.any():
            return
        points = self._points(self.mean, self.cov)
        observed = self._apply(model.observation_points, points, k)[:, :, measured]
        predicted = np.einsum("p,kpm->km", wm, observed)
        residual = observed - predicted[:, None]
        S = np.einsum("p,kpi,kpj->kij", wc, residual, residual) + model.R[np.ix_(measured, measured)]
        cross = np.einsum("p,kpi,kpj->kij", wc, points - self.mean[:, None], residual)
        innovation = outputs[measured] - predicted
        with np.errstate(all="ignore"):
            gain, whitened, logdet = self._solve(S, cross, innovation)
            self.mean = self.mean + np.einsum("kij,kj->ki", gain, innovation)
            self.cov = self.cov - np.einsum("kij,kjl,kml->kim", gain, S, gain)
            self.cov = 0.5 * (self.cov + np.swapaxes(self.cov, 1, 2))
            self.score = self.score - 0.5 * (np.einsum("ki,ki->k", innovation, whitened) + logdet
                                             + int(measured.sum()) * np.log(2 * np.pi))

    @staticmethod
    def _solve(S, cross, innovation):
        """(gain C inv(S), inv(S) innovation, log|S|) per component (NaN where S is singular)."""
        try:
            gain = np.swapaxes(np.linalg.solve(S, np.swapaxes(cross, 1, 2)), 1, 2)
            return gain, np.linalg.solve(S, innovation[..., None])[..., 0], np.linalg.slogdet(S)[1]
        except np.linalg.LinAlgError:
            pass
        gain, whitened = np.full(cross.shape, np.nan), np.full(innovation.shape, np.nan)
        logdet = np.full(len(S), np.nan)
        for c in range(len(S)):
            try:
                gain[c] = np.linalg.solve(S[c], cross[c].T).T
                whitened[c] = np.linalg.solve(S[c], innovation[c])
                logdet[c] = np.linalg.slogdet(S[c])[1]
            except np.linalg.LinAlgError:
                pass
        return gain, whitened, logdet

    def _merge(self) -> None:
        """Of two components whose filtered means lie each within the other's one-std ellipsoid
        (Mahalanobis distance^2 below 1 under P_i and under P_j: a wide component does not swallow a
        narrow one), keep the one with the higher score."""
        kept: list[int] = []
        for i in np.argsort(-self.score):
            if not kept or not self._near_any(int(i), np.array(kept)):
                kept.append(int(i))
        mask = np.zeros(len(self.score), dtype=bool)
        mask[kept] = True
        self._keep(mask)

    def _near_any(self, i: int, others: np.ndarray) -> bool:
        """Whether component i and one of ``others`` (indices) lie each within the other's one-std
        ellipsoid: max(e' inv(P_i) e, e' inv(P_j) e) < 1, e = m_i - m_j. All pairs in one call of
        the solver (the same numbers as one pair at a time); a pair with a singular covariance does
        not count (:meth:`_near_pair`)."""
        difference = (self.mean[i] - self.mean[others])[:, :, None]  # (pairs, d, 1)
        try:
            own = np.linalg.solve(np.broadcast_to(self.cov[i], (len(others),) + self.cov[i].shape), difference)
            theirs = np.linalg.solve(self.cov[others], difference)
        except np.linalg.LinAlgError:
            return any(self._near_pair(i, int(j)) for j in others)
        row = np.swapaxes(difference, 1, 2)
        under_own, under_theirs = (row @ own)[:, 0, 0], (row @ theirs)[:, 0, 0]
        distance = np.where(under_theirs > under_own, under_theirs, under_own)  # max(own, theirs), as max() takes NaN
        return bool(np.any(distance < 1.0))

    def _near_pair(self, i: int, j: int) -> bool:
        """:meth:`_near_any` for one pair (False where either covariance is singular)."""
        difference = self.mean[i] - self.mean[j]
        try:
            distance = max(difference @ np.linalg.solve(self.cov[i], difference),
                           difference @ np.linalg.solve(self.cov[j], difference))
        except np.linalg.LinAlgError:
            return False
        return bool(distance < 1.0)
