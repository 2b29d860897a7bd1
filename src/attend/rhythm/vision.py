"""Active vision: a foveated eye infers hidden letters on a grid (paper Sec. 2-3, Fig. 1).

Generative model. A scene is a grid of L = rows x cols locations x_l (grid units); location l
holds letter c_l in {1..K}, drawn uniformly, with pattern mu_k in R^D (a 5x5 glyph, D = 25,
intensities 0/1). Fixating location f for a step of length dt [s] at precision multiplier g gives at
every location an observation

    y_l = mu_{c_l} + e_l,   e_l ~ N(0, I / lambda_fl),
    lambda_fl = rho * g * dt * exp(-|x_l - x_f|^2 / (2 w^2))

rho ``foveal_precision_rate`` [1/(intensity^2 s)], w ``fovea_width`` [grid units]: acuity falls with
eccentricity |x_l - x_f|. g comes from the fixation policy (:mod:`attend.rhythm.fixations`;
suppressed during saccades). :func:`look` runs one scene.

Diminishing returns of dwelling (optional): with ``adaptation_time`` tau_a [s] the precision rate
decays during a fixation (adaptation, fading of a stabilised image): a step from dwell time tau
to tau + dt delivers the dose g tau_a (exp(-tau / tau_a) - exp(-(tau + dt) / tau_a)) instead of
g dt, so a fixation of length D yields at most g tau_a (1 - exp(-D / tau_a)) < g tau_a; a saccade
restores the full rate. tau_a = inf (default): the dose is g dt, bit for bit.

Beliefs: independent categorical posteriors q_l(k), updated exactly (Bayes):

    log q_l'(k) = log q_l(k) - lambda_l / 2 |y_l - mu_k|^2 - log Z_l.

Salience of fixation f = expected information gain (epistemic value) of one fixation there,
with total precision lambda_fl = rho * D_fix * acuity (D_fix = integral of g dt over the fixation):

    S(f) = sum_l I(c_l; y_l | lambda_fl),
    I(c; y | lambda) = - sum_c q(c) E_e[ log sum_k q(k) exp(a_ck(e)) ],
    a_ck(e) = -lambda/2 |mu_c - mu_k|^2 - sqrt(lambda) e.(mu_c - mu_k),   e ~ N(0, I_D),

estimated by Monte Carlo with fixed antithetic samples e (common random numbers, so S is smooth
in lambda and reproducible). A resolved location (q one-hot) has I = 0 exactly: inhibition of
return emerges, it is not coded.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from attend._validation import AttendInputError, positive_scalar
from attend.rhythm.fixations import ScheduleTrace, drive
from attend.rhythm.schedule import ACT

GLYPHS: dict[str, tuple[str, ...]] = {
    "E": ("11111", "10000", "11110", "10000", "11111"),
    "F": ("11111", "10000", "11110", "10000", "10000"),
    "T": ("11111", "00100", "00100", "00100", "00100"),
    "L": ("10000", "10000", "10000", "10000", "11111"),
    "O": ("01110", "10001", "10001", "10001", "01110"),
    "C": ("01111", "10000", "10000", "10000", "01111"),
    "I": ("01110", "00100", "00100", "00100", "01110"),
    "H": ("10001", "10001", "11111", "10001", "10001"),
    "X": ("10001", "01010", "00100", "01010", "10001"),
    "P": ("11110", "10001", "11110", "10000", "10000"),
}


def _logsumexp(values: np.ndarray, axis: int, keepdims: bool = False) -> np.ndarray:
    """log sum exp along ``axis`` (max-shifted; a lean replacement for scipy's)."""
    peak = np.max(values, axis=axis, keepdims=True)
    total = np.log(np.sum(np.exp(values - peak), axis=axis, keepdims=True)) + peak
    return total if keepdims else np.squeeze(total, axis=axis)


def letter_patterns(letters: str = "EFTLOC") -> np.ndarray:
    """Patterns mu_k of the ``letters`` (at least 2 distinct, from GLYPHS) as rows of a (K, 25) array of 0/1 intensities."""
    if not isinstance(letters, str) or len(letters) < 2 or len(set(letters)) != len(letters):
        raise AttendInputError(f"letters: expected at least 2 distinct letters, got {letters!r}")
    unknown = [c for c in letters if c not in GLYPHS]
    if unknown:
        raise AttendInputError(f"letters: no glyph for {unknown}; known: {''.join(GLYPHS)}")
    return np.array([[float(ch) for row in GLYPHS[c] for ch in row] for c in letters])


@dataclass(frozen=True)
class Scene:
    """A grid of hidden letters: ``identities`` (rows, cols) indices into ``patterns`` (K, D);
    ``letters``: their names (for display)."""

    identities: np.ndarray
    patterns: np.ndarray
    letters: str = ""

    def __post_init__(self) -> None:
        identities = np.asarray(self.identities)
        patterns = np.asarray(self.patterns, dtype=float)
        if identities.ndim != 2 or identities.size == 0:
            raise AttendInputError(f"identities: expected a non-empty 2-D grid, got shape {identities.shape}")
        if patterns.ndim != 2 or patterns.shape[0] < 2:
            raise AttendInputError(f"patterns: expected a (K >= 2, D) array, got shape {patterns.shape}")
        if not np.all(np.isfinite(patterns)):
            raise AttendInputError("patterns: expected finite intensities")
        if not np.issubdtype(identities.dtype, np.integer) or identities.min() < 0 or identities.max() >= len(patterns):
            raise AttendInputError(f"identities: expected integers in 0..{len(patterns) - 1}")
        object.__setattr__(self, "identities", identities)
        object.__setattr__(self, "patterns", patterns)

    @property
    def shape(self) -> tuple[int, int]:
        return self.identities.shape

    @property
    def n_locations(self) -> int:
        return self.identities.size

    @property
    def locations(self) -> np.ndarray:
        """(L, 2) grid coordinates (row, col) [grid units], row-major."""
        rows, cols = self.shape
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        return np.stack([r.ravel(), c.ravel()], axis=1).astype(float)

    @property
    def true_labels(self) -> np.ndarray:
        """(L,) letter index at each location."""
        return self.identities.ravel()

    def image(self) -> np.ndarray:
        """The scene as an image: the glyphs side by side, one blank pixel between cells."""
        rows, cols = self.shape
        side = int(round(np.sqrt(self.patterns.shape[1])))
        canvas = np.zeros((rows * (side + 1) + 1, cols * (side + 1) + 1))
        for (r, c), k in np.ndenumerate(self.identities):
            top, left = 1 + r * (side + 1), 1 + c * (side + 1)
            canvas[top:top + side, left:left + side] = self.patterns[k].reshape(side, side)
        return canvas


def random_scene(rows: int = 4, cols: int = 4, letters: str = "EFTLOC", seed: int = 0) -> Scene:
    """A ``rows`` x ``cols`` scene with ``letters`` drawn uniformly and independently at each
    location (``seed``: the draw)."""
    for name, value in (("rows", rows), ("cols", cols)):
        if isinstance(value, bool) or int(value) != value or int(value) < 1:
            raise AttendInputError(f"{name}: expected an integer >= 1, got {value!r}")
    patterns = letter_patterns(letters)
    rng = np.random.default_rng(seed)
    return Scene(rng.integers(0, len(patterns), size=(int(rows), int(cols))), patterns, letters)


@dataclass(frozen=True)
class FoveatedEye:
    """Acuity exp(-d^2 / (2 w^2)) with d the eccentricity [grid units]; ``fovea_width`` w > 0
    [grid units]; ``foveal_precision_rate`` rho > 0 [1/(intensity^2 s)]: precision per second of
    viewing at the fovea at precision multiplier 1; ``adaptation_time`` tau_a > 0 [s] (inf: none): the precision
    rate decays as exp(-tau / tau_a) with the dwell time tau of a fixation (module docstring)."""

    fovea_width: float = 0.7
    foveal_precision_rate: float = 12.0
    adaptation_time: float = float("inf")

    def __post_init__(self) -> None:
        if not (isinstance(self.adaptation_time, (int, float)) and self.adaptation_time > 0
                and not np.isnan(self.adaptation_time)):
            raise AttendInputError(f"adaptation_time: expected a time > 0 s (inf: no adaptation), got {self.adaptation_time!r}")
        object.__setattr__(self, "fovea_width", positive_scalar(self.fovea_width, "fovea_width", "grid units"))
        object.__setattr__(self, "foveal_precision_rate",
                           positive_scalar(self.foveal_precision_rate, "foveal_precision_rate", "1/(intensity^2 s)"))

    def dwell_dose(self, dwell: float, duration: float) -> float:
        """Effective viewing time [s] of a step from dwell time ``dwell`` to ``dwell + duration``
        [s]: tau_a (exp(-dwell / tau_a) - exp(-(dwell + duration) / tau_a)); ``duration`` if no
        adaptation."""
        if not np.isfinite(self.adaptation_time):
            return duration
        tau = self.adaptation_time
        return tau * (np.exp(-dwell / tau) - np.exp(-(dwell + duration) / tau))

    def acuity(self, locations: np.ndarray) -> np.ndarray:
        """(F, L) acuity, for ``locations`` (L, 2) [grid units], exp(-|x_l - x_f|^2 / (2 w^2)) of every fixation f at every location l."""
        squared = np.sum((locations[:, None, :] - locations[None, :, :]) ** 2, axis=-1)
        return np.exp(-squared / (2.0 * self.fovea_width ** 2))

    def precisions(self, locations: np.ndarray, fixation: int, dose: float) -> np.ndarray:
        """(L,) lambda_l = rho * dose * acuity(fixation, l) at ``locations`` (L, 2) when fixating
        location index ``fixation``; dose = g * dt [s]."""
        squared = np.sum((locations - locations[fixation]) ** 2, axis=-1)
        return self.foveal_precision_rate * dose * np.exp(-squared / (2.0 * self.fovea_width ** 2))


def observe(scene: Scene, precisions: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(L, D) samples y_l = mu_{c_l} + e_l / sqrt(lambda_l), e_l ~ N(0, I) of ``scene`` with
    ``precisions`` lambda (L,) > 0, drawn from ``rng``."""
    means = scene.patterns[scene.true_labels]
    noise = rng.standard_normal(means.shape)
    return means + noise / np.sqrt(np.maximum(precisions, 1e-300))[:, None]


def uniform_log_posterior(n_locations: int, n_patterns: int) -> np.ndarray:
    """log q_l(k) = -log K for each of ``n_locations`` locations, K = ``n_patterns``."""
    return np.full((n_locations, n_patterns), -np.log(n_patterns))


def update_beliefs(log_posterior: np.ndarray, observations: np.ndarray, precisions: np.ndarray,
                   patterns: np.ndarray) -> np.ndarray:
    """Exact Bayes: log q'_l(k) = log q_l(k) - lambda_l/2 |y_l - mu_k|^2 - log Z_l, for
    ``log_posterior`` (L, K), ``observations`` y (L, D), ``precisions`` lambda (L,) and
    ``patterns`` mu (K, D)."""
    squared = np.sum((observations[:, None, :] - patterns[None, :, :]) ** 2, axis=-1)
    unnormalised = log_posterior - 0.5 * precisions[:, None] * squared
    return unnormalised - _logsumexp(unnormalised, axis=1, keepdims=True)


def entropy(log_posterior: np.ndarray) -> np.ndarray:
    """H_l = -sum_k q_l(k) log q_l(k) [nats] of ``log_posterior`` (L, K), shape (L,)."""
    return -np.sum(np.exp(log_posterior) * log_posterior, axis=-1)


def antithetic_noise(n_samples: int, dimension: int, seed: int = 0) -> np.ndarray:
    """(2 n, D) standard normal samples e and -e for the Monte-Carlo information gain
    (n = ``n_samples``, D = ``dimension``, ``seed``: the draw)."""
    if isinstance(n_samples, bool) or int(n_samples) != n_samples or int(n_samples) < 1:
        raise AttendInputError(f"monte_carlo_samples: expected an integer >= 1, got {n_samples!r}")
    half = np.random.default_rng(seed).standard_normal((int(n_samples), dimension))
    return np.concatenate([half, -half])


def information_gain(log_posterior: np.ndarray, precisions: np.ndarray, patterns: np.ndarray,
                     noise: np.ndarray) -> np.ndarray:
    """I(c_l; y_l | lambda_l) [nats] for log_posterior (L, K) and precisions (..., L) -> (..., L).

    I = -sum_c q(c) mean_s logsumexp_k(log q(k) + a_ck(e_s)), a as in the module docstring;
    ``patterns`` mu (K, D); ``noise`` (S, D) standard normal samples."""
    lam = np.asarray(precisions, dtype=float)
    batch = lam.ndim - 1                                                  # leading axes before L
    differences = patterns[None, :, :] - patterns[:, None, :]            # [k, c] = mu_c - mu_k
    squared = np.sum(differences ** 2, axis=-1)                          # (K, K)
    projections = np.einsum("sd,kcd->kcs", noise, differences)           # (K, K, S)
    expand = (...,) + (None,) * lam.ndim
    exponent = -0.5 * squared[expand][:, :, None] * lam - projections[expand] * np.sqrt(lam)
    log_q = log_posterior.T.reshape((log_posterior.shape[1], 1, 1) + (1,) * batch + (log_posterior.shape[0],))
    log_marginal = _logsumexp(exponent + log_q, axis=0)                   # (K_c, S, ..., L)
    q = np.exp(log_posterior).T.reshape((log_posterior.shape[1],) + (1,) * batch + (log_posterior.shape[0],))
    return np.maximum(-np.sum(q * log_marginal.mean(axis=1), axis=0), 0.0)


def salience_map(log_posterior: np.ndarray, locations: np.ndarray, eye: FoveatedEye, dose: float,
                 patterns: np.ndarray, noise: np.ndarray, fixations=None,
                 resolved_entropy: float = 1e-4, negligible_acuity: float = 1e-6) -> np.ndarray:
    """S(f) = sum_l I(c_l; y_l | rho * dose * acuity(f, l)) [nats] for every candidate fixation f
    (all locations, or the indices ``fixations``); ``dose`` = integral of g dt [s]; beliefs
    ``log_posterior`` (L, K) at ``locations`` (L, 2), seen by ``eye``; ``patterns`` (K, D);
    ``noise`` (S, D) as in :func:`information_gain`.

    I is computed once per (location, distinct eccentricity). Locations with entropy H_l below
    ``resolved_entropy`` [nats] are skipped (I <= H_l, so S changes by less than L times that)
    and so are eccentricities with acuity below ``negligible_acuity``."""
    candidates = np.arange(len(locations)) if fixations is None else np.asarray(fixations, dtype=int)
    open_locations = entropy(log_posterior) > resolved_entropy
    result = np.zeros(len(candidates))
    if not open_locations.any():
        return result
    squared = np.sum((locations[candidates][:, None, :] - locations[open_locations][None, :, :]) ** 2, axis=-1)
    if len(candidates) == 1:  # one fixation: one eccentricity per location, compute directly
        acuity = np.exp(-squared / (2.0 * eye.fovea_width ** 2))
        lam = eye.foveal_precision_rate * dose * np.where(acuity >= negligible_acuity, acuity, 0.0)
        return information_gain(log_posterior[open_locations], lam, patterns, noise).sum(axis=1)
    distinct, inverse = np.unique(np.round(squared, 9), return_inverse=True)
    inverse = inverse.reshape(squared.shape)
    acuity = np.exp(-distinct / (2.0 * eye.fovea_width ** 2))
    acuity = np.where(acuity >= negligible_acuity, acuity, 0.0)
    lam = eye.foveal_precision_rate * dose * acuity                             # (U,)
    gains = np.zeros((len(distinct), int(open_locations.sum())))
    visible = acuity > 0
    gains[visible] = information_gain(log_posterior[open_locations],
                                      np.broadcast_to(lam[visible, None], (int(visible.sum()), gains.shape[1])),
                                      patterns, noise)
    return np.take_along_axis(gains, inverse, axis=0).sum(axis=1)


def static_saliency_map(scene: Scene) -> np.ndarray:
    """Bottom-up conspicuity of ``scene`` (centre-surround contrast of the true image), fixed over time:
    C_l = |mu_{c_l} - mean_{n in N8(l)} mu_{c_n}| (Euclidean, intensities), shape (L,)."""
    rows, cols = scene.shape
    features = scene.patterns[scene.identities]                           # (rows, cols, D)
    conspicuity = np.zeros((rows, cols))
    for r in range(rows):
        for c in range(cols):
            neighbours = [features[i, j] for i in range(max(0, r - 1), min(rows, r + 2))
                          for j in range(max(0, c - 1), min(cols, c + 2)) if (i, j) != (r, c)]
            surround = np.mean(neighbours, axis=0) if neighbours else np.zeros(features.shape[-1])
            conspicuity[r, c] = np.linalg.norm(features[r, c] - surround)
    return conspicuity.ravel()


# --- saccade policies -------------------------------------------------------------------------

class EpistemicPolicy:
    """Saccade to argmax_f S(f): the expected information gain of the next fixation. No
    inhibition of return is coded; it emerges because resolved locations have S ~ 0."""

    name = "epistemic"

    def salience(self, agent: "ActiveVisionAgent") -> np.ndarray:
        """S(f) [nats] of every fixation for the ``agent``'s planned fixation dose."""
        return agent.salience(agent.fixation_dose)

    def choose(self, agent: "ActiveVisionAgent", salience: np.ndarray) -> int:
        """argmax of ``salience`` (``agent`` is not consulted)."""
        return int(np.argmax(salience))


class StaticSaliencyPolicy:
    """Classical bottom-up saliency: saccade to the most conspicuous location of a map fixed over
    time. With ``inhibition_of_return`` (as in Itti & Koch 2001, coded explicitly) the visited
    locations are masked until all have been visited, then the mask resets; without it the eye
    returns to the same maximum."""

    def __init__(self, inhibition_of_return: bool = True) -> None:
        self.inhibition_of_return = bool(inhibition_of_return)
        self.name = "static saliency" + ("" if self.inhibition_of_return else " (no IOR)")

    def salience(self, agent: "ActiveVisionAgent") -> np.ndarray:
        """The fixed conspicuity map of the ``agent``'s scene."""
        return agent.static_saliency

    def choose(self, agent: "ActiveVisionAgent", salience: np.ndarray) -> int:
        """argmax of ``salience`` over the locations the ``agent`` has not visited since the
        last reset (all, without inhibition of return)."""
        if not self.inhibition_of_return:
            return int(np.argmax(salience))
        visited = agent.visited_since_reset
        if len(visited) >= agent.scene.n_locations:
            visited.clear()
            visited.add(agent.fixation)
        masked = np.where([i in visited for i in range(len(salience))], -np.inf, salience)
        return int(np.argmax(masked))


class RandomPolicy:
    """Saccade to a location drawn uniformly among the others (seeded by the agent)."""

    name = "random"

    def salience(self, agent: "ActiveVisionAgent") -> np.ndarray:
        """Uniform probabilities over the locations other than the ``agent``'s fixation."""
        others = np.ones(agent.scene.n_locations)
        others[agent.fixation] = 0.0
        return others / others.sum()

    def choose(self, agent: "ActiveVisionAgent", salience: np.ndarray) -> int:
        """A draw from the probabilities ``salience`` with the ``agent``'s policy generator."""
        return int(agent.policy_rng.choice(len(salience), p=salience))


POLICIES = {"epistemic": EpistemicPolicy, "static": StaticSaliencyPolicy, "random": RandomPolicy}


# --- the agent (a FixationTask) -----------------------------------------------------------------

@dataclass
class SaccadeRecord:
    """One saccade: ``time`` [s], ``origin``/``target`` location indices, the salience map used (L,), and the
    summed entropy [nats] and accuracy just before it."""

    time: float
    origin: int
    target: int
    salience: np.ndarray
    entropy: float
    accuracy: float


class ActiveVisionAgent:
    """A foveated ``eye`` (:class:`FoveatedEye`) with categorical beliefs over the letters of
    ``scene``; follows :class:`attend.rhythm.fixations.FixationTask` so any fixation policy can
    time its saccades, and saccades where ``policy`` (:class:`EpistemicPolicy`,
    :class:`StaticSaliencyPolicy`, :class:`RandomPolicy`) says.

    ``fixation_dose`` [s]: expected integral of g dt over one fixation, used to plan the next
    fixation (salience). ``initial_fixation``: location index (None: the centre).
    ``monte_carlo_samples``: antithetic pairs of the information gain. ``seed`` seeds the sensor
    noise, the Monte-Carlo samples and the random policy.
    """

    def __init__(self, scene: Scene, eye: FoveatedEye, policy, fixation_dose: float,
                 initial_fixation: int | None = None, monte_carlo_samples: int = 48, seed: int = 0) -> None:
        self.scene, self.eye, self.policy = scene, eye, policy
        self.fixation_dose = positive_scalar(fixation_dose, "fixation_dose", "s")
        self.locations = scene.locations
        if initial_fixation is None:
            centre = self.locations.mean(axis=0)
            initial_fixation = int(np.argmin(np.sum((self.locations - centre) ** 2, axis=1) + 1e-9 * np.arange(scene.n_locations)))
        if not 0 <= int(initial_fixation) < scene.n_locations:
            raise AttendInputError(f"initial_fixation: expected a location index in 0..{scene.n_locations - 1}")
        self.fixation = int(initial_fixation)
        self.log_posterior = uniform_log_posterior(scene.n_locations, len(scene.patterns))
        self.sensor_rng = np.random.default_rng([seed, 1])
        self.policy_rng = np.random.default_rng([seed, 2])
        self.noise = antithetic_noise(monte_carlo_samples, scene.patterns.shape[1], seed=seed + 7919)
        self.static_saliency = static_saliency_map(scene)
        self.visited = {self.fixation}
        self.visited_since_reset = {self.fixation}
        self.fixations = [self.fixation]
        self.saccades: list[SaccadeRecord] = []
        self.revisits = 0
        self.time = 0.0
        self.dwell = 0.0
        self.entropy_trace: list[float] = []
        self.accuracy_trace: list[float] = []

    # beliefs
    def total_entropy(self) -> float:
        """sum_l H_l [nats]."""
        return float(entropy(self.log_posterior).sum())

    def accuracy(self) -> float:
        """Fraction of locations whose MAP letter is the true one."""
        return float(np.mean(np.argmax(self.log_posterior, axis=1) == self.scene.true_labels))

    def salience(self, dose: float, fixations=None) -> np.ndarray:
        """Epistemic salience S(f) [nats] of every fixation (or of the indices ``fixations``) for
        a viewing ``dose`` [s]."""
        return salience_map(self.log_posterior, self.locations, self.eye, dose, self.scene.patterns,
                            self.noise, fixations)

    def _sample(self, dose: float) -> None:
        precisions = self.eye.precisions(self.locations, self.fixation, dose)
        observations = observe(self.scene, precisions, self.sensor_rng)
        self.log_posterior = update_beliefs(self.log_posterior, observations, precisions, self.scene.patterns)

    def _record(self, duration: float) -> None:
        self.time += duration
        self.entropy_trace.append(self.total_entropy())
        self.accuracy_trace.append(self.accuracy())

    # FixationTask
    def expected_gain_of_staying(self, precision_multiplier: float, duration: float) -> float:
        """Expected information gain [nats] of fixating here for ``duration`` [s] more at
        ``precision_multiplier``."""
        dose = precision_multiplier * self.eye.dwell_dose(self.dwell, duration)
        return float(self.salience(dose, [self.fixation])[0])

    def expected_gain_of_moving(self, precision_multiplier: float, duration: float) -> float:
        """Expected information gain [nats] of a fixation of ``duration`` [s] at the best other
        location, at ``precision_multiplier``."""
        others = [i for i in range(self.scene.n_locations) if i != self.fixation]
        return float(self.salience(precision_multiplier * self.eye.dwell_dose(0.0, duration), others).max())

    def perceive(self, precision_multiplier: float, duration: float) -> None:
        """Fixate for ``duration`` [s] at ``precision_multiplier``: sample and update beliefs."""
        self._sample(precision_multiplier * self.eye.dwell_dose(self.dwell, duration))
        self.dwell += duration
        self._record(duration)

    def act(self, precision_multiplier: float, duration: float, onset: bool) -> None:
        """One saccade step of ``duration`` [s] (data weighted by ``precision_multiplier``); at
        the ``onset`` of a saccade the policy chooses the target."""
        if onset:
            salience = np.asarray(self.policy.salience(self), dtype=float)
            target = self.policy.choose(self, salience)
            self.saccades.append(SaccadeRecord(self.time, self.fixation, target, salience,
                                               self.total_entropy(), self.accuracy()))
            if target in self.visited:
                self.revisits += 1
            self.visited.add(target)
            self.visited_since_reset.add(target)
            self.fixation = target
            self.fixations.append(target)
            self.dwell = 0.0
        self._sample(precision_multiplier * duration)  # data taken while moving: suppressed precision
        self._record(duration)

    def revisit_rate(self) -> float:
        """Fraction of saccades landing on a location fixated before (including the current one)."""
        return self.revisits / len(self.saccades) if self.saccades else float("nan")


@dataclass
class VisionEpisode:
    """Result of one scene (:func:`look`): ``entropy``/``accuracy`` [nats]/[fraction] after
    n = 0..N saccades (index n: just before saccade n + 1), the ``revisit_rate`` of the
    saccades, the ``fixations`` (location indices), the per-step ``entropy_trace`` and
    ``accuracy_trace``, the ``saccades`` records, the fixation policy's ``schedule`` trace and
    its ``time_step`` [s]."""

    entropy: np.ndarray
    accuracy: np.ndarray
    revisit_rate: float
    fixations: list[int]
    saccades: list[SaccadeRecord]
    entropy_trace: np.ndarray
    accuracy_trace: np.ndarray
    schedule: ScheduleTrace
    time_step: float = field(default=0.0)


def look(scene: Scene, eye: FoveatedEye, policy, fixations, fixation_dose: float,
         n_saccades: int | None = None, n_steps: int | None = None, seed: int = 0,
         monte_carlo_samples: int = 48, initial_fixation: int | None = None) -> VisionEpisode:
    """Look at ``scene`` with ``eye``: an :class:`ActiveVisionAgent` choosing targets by
    ``policy``, timed by the fixation policy ``fixations`` (:func:`attend.rhythm.fixations.
    fixation_policy`), for ``n_saccades`` saccades (stops just before saccade n_saccades + 1) or
    ``n_steps`` steps. ``fixation_dose``, ``seed``, ``monte_carlo_samples`` and
    ``initial_fixation`` go to the agent."""
    if n_saccades is None and n_steps is None:
        raise AttendInputError("n_saccades: give n_saccades or n_steps")
    agent = ActiveVisionAgent(scene, eye, policy, fixation_dose, initial_fixation, monte_carlo_samples, seed)
    limit = n_steps if n_steps is not None else 10 ** 9

    def saccade_limit_reached(step) -> bool:
        return (n_saccades is not None and step.mode == ACT and step.onset
                and len(agent.saccades) >= n_saccades)

    trace = drive(fixations, agent, limit, until=saccade_limit_reached)
    entropies = [s.entropy for s in agent.saccades] + [agent.total_entropy()]
    accuracies = [s.accuracy for s in agent.saccades] + [agent.accuracy()]
    return VisionEpisode(np.array(entropies), np.array(accuracies), agent.revisit_rate(), agent.fixations,
                         agent.saccades, np.array(agent.entropy_trace), np.array(agent.accuracy_trace), trace,
                         fixations.time_step)
