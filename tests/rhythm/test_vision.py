"""Active vision: exact Bayes against enumeration, information gain against quadrature,
salience of resolved locations, determinism, emergent inhibition of return, bad input."""

import itertools

import numpy as np
import pytest
from scipy import integrate, stats

from attend._validation import AttendInputError
from attend.rhythm import PrecisionOscillator, RhythmicSchedule, fixation_policy
from attend.rhythm import vision as V
from attend.rhythm.vision import antithetic_noise, entropy, information_gain, update_beliefs, uniform_log_posterior

EpistemicPolicy, FoveatedEye, RandomPolicy, Scene = V.EpistemicPolicy, V.FoveatedEye, V.RandomPolicy, V.Scene
letter_patterns, random_scene, salience_map = V.letter_patterns, V.random_scene, V.salience_map


def test_bayesian_update_matches_brute_force_enumeration():
    """Two locations, three patterns in 2-D, three observations at different precisions: the
    factorised sequential update equals the joint posterior over all 3 x 3 scene hypotheses."""
    rng = np.random.default_rng(4)
    patterns = np.array([[0.0, 0.0], [1.0, 0.5], [0.2, 1.0]])
    prior = np.array([[0.2, 0.5, 0.3], [0.6, 0.1, 0.3]])
    observations = rng.normal(size=(3, 2, 2))
    precisions = np.array([[2.0, 0.3], [0.5, 1.5], [4.0, 0.0]])
    log_posterior = np.log(prior)
    for y, lam in zip(observations, precisions):
        log_posterior = update_beliefs(log_posterior, y, lam, patterns)
    joint = np.zeros((3, 3))
    for c0, c1 in itertools.product(range(3), repeat=2):
        weight = prior[0, c0] * prior[1, c1]
        for y, lam in zip(observations, precisions):
            for location, c in ((0, c0), (1, c1)):
                if lam[location] > 0:
                    weight *= stats.multivariate_normal(patterns[c], np.eye(2) / lam[location]).pdf(y[location])
        joint[c0, c1] = weight
    joint /= joint.sum()
    np.testing.assert_allclose(np.exp(log_posterior[0]), joint.sum(axis=1), rtol=1e-10)
    np.testing.assert_allclose(np.exp(log_posterior[1]), joint.sum(axis=0), rtol=1e-10)


def _quadrature_information(q, means, lam):
    """I(c; y) = H(c) - E_y H(c | y) for y | c ~ N(means[c], 1 / lam), by numerical integration."""
    sd = 1.0 / np.sqrt(lam)

    def integrand(y):
        likelihood = stats.norm.pdf(y, means, sd)
        joint = q * likelihood
        evidence = joint.sum()
        if evidence <= 0:
            return 0.0
        return np.sum(joint * np.log(np.maximum(likelihood, 1e-300) / evidence))

    value, _ = integrate.quad(integrand, means.min() - 12 * sd, means.max() + 12 * sd, limit=200)
    return value


@pytest.mark.parametrize("lam", [0.3, 2.0, 10.0])
def test_information_gain_matches_quadrature(lam):
    q = np.array([0.3, 0.5, 0.2])
    means = np.array([0.0, 1.0, 1.8])
    exact = _quadrature_information(q, means, lam)
    noise = antithetic_noise(20000, 1, seed=1)
    estimate = information_gain(np.log(q)[None, :], np.array([lam]), means[:, None], noise)[0]
    assert estimate == pytest.approx(exact, abs=0.01, rel=0.02)
    assert 0.0 < estimate <= entropy(np.log(q)[None, :])[0] + 1e-12


def test_information_gain_limits():
    q = np.log(np.array([[0.25, 0.25, 0.5]]))
    patterns = letter_patterns("EFT")
    noise = antithetic_noise(64, 25)
    assert information_gain(q, np.array([0.0]), patterns, noise)[0] == pytest.approx(0.0, abs=1e-12)
    assert information_gain(q, np.array([1e4]), patterns, noise)[0] == pytest.approx(entropy(q)[0], rel=1e-6)


def test_resolved_location_has_no_salience():
    scene = random_scene(3, 3, seed=2)
    eye = FoveatedEye(0.6, 12.0)
    noise = antithetic_noise(32, 25)
    resolved = np.full((9, 6), np.log(1e-12))
    resolved[np.arange(9), scene.true_labels] = 0.0
    resolved -= np.log(np.exp(resolved).sum(axis=1, keepdims=True))
    gains = information_gain(resolved, np.full(9, 5.0), scene.patterns, noise)
    assert np.all(gains < 1e-9)
    # salience with every location resolved: ~0 everywhere (skip shortcut disabled too)
    assert np.all(salience_map(resolved, scene.locations, eye, 0.3, scene.patterns, noise) == 0.0)
    assert np.all(salience_map(resolved, scene.locations, eye, 0.3, scene.patterns, noise,
                               resolved_entropy=0.0) < 1e-8)
    # one open location: the salience map peaks there
    one_open = resolved.copy()
    one_open[4] = np.log(np.full(6, 1 / 6))
    salience = salience_map(one_open, scene.locations, eye, 0.3, scene.patterns, noise)
    assert np.argmax(salience) == 4 and salience[4] > 0.5


def test_salience_map_equals_brute_force_over_all_pairs():
    scene = random_scene(4, 3, seed=5)
    eye = FoveatedEye(0.8, 10.0)
    noise = antithetic_noise(16, 25)
    rng = np.random.default_rng(0)
    log_posterior = np.log(rng.dirichlet(np.ones(6), size=12))
    brute = information_gain(log_posterior, 10.0 * 0.2 * eye.acuity(scene.locations), scene.patterns, noise).sum(axis=1)
    fast = salience_map(log_posterior, scene.locations, eye, 0.2, scene.patterns, noise, resolved_entropy=0.0,
                        negligible_acuity=0.0)
    np.testing.assert_allclose(fast, brute, rtol=1e-10, atol=1e-12)
    single = salience_map(log_posterior, scene.locations, eye, 0.2, scene.patterns, noise, fixations=[7],
                          resolved_entropy=0.0, negligible_acuity=0.0)
    assert single[0] == pytest.approx(brute[7], rel=1e-10)


def test_acuity_falls_with_eccentricity():
    eye = FoveatedEye(0.5, 10.0)
    locations = random_scene(1, 4).locations
    precisions = eye.precisions(locations, 0, 0.1)
    np.testing.assert_allclose(precisions, 10.0 * 0.1 * np.exp(-np.arange(4) ** 2 / (2 * 0.25)))


def _episode(policy, seed):
    osc = PrecisionOscillator(4.0, 1.0)
    scheduler = fixation_policy(RhythmicSchedule(osc))
    return V.look(random_scene(4, 4, seed=seed), FoveatedEye(0.6, 12.0), policy, scheduler, 0.29,
                       n_saccades=8, seed=seed, monte_carlo_samples=8)


def test_episode_is_reproducible_and_entropy_falls():
    first, second = _episode(EpistemicPolicy(), 3), _episode(EpistemicPolicy(), 3)
    assert first.fixations == second.fixations
    np.testing.assert_array_equal(first.entropy, second.entropy)
    assert len(first.entropy) == 9 and first.entropy[-1] < 0.5 * first.entropy[0]


def test_inhibition_of_return_emerges():
    """No IOR is coded, yet the epistemic eye revisits far less than random saccades."""
    epistemic = np.mean([_episode(EpistemicPolicy(), s).revisit_rate for s in range(3)])
    random = np.mean([_episode(RandomPolicy(), s).revisit_rate for s in range(3)])
    assert epistemic <= 0.1 < random


@pytest.mark.parametrize("make, field", [
    (lambda: FoveatedEye(fovea_width=0.0), "fovea_width"),
    (lambda: FoveatedEye(fovea_width=-1.0), "fovea_width"),
    (lambda: FoveatedEye(foveal_precision_rate=0.0), "foveal_precision_rate"),
    (lambda: letter_patterns("EE"), "letters"),
    (lambda: letter_patterns("E?"), "letters"),
    (lambda: random_scene(0, 3), "rows"),
    (lambda: Scene(np.array([[0, 7]]), letter_patterns("EF")), "identities"),
    (lambda: Scene(np.array([[0, 1]]), np.ones(3)), "patterns"),
    (lambda: antithetic_noise(0, 3), "monte_carlo_samples"),
])
def test_bad_input_names_the_field(make, field):
    with pytest.raises(AttendInputError, match=field):
        make()


def test_uniform_prior():
    np.testing.assert_allclose(np.exp(uniform_log_posterior(3, 4)), 0.25)


# ---- dwell adaptation (diminishing returns of a fixation) -------------------------------------


def test_dwell_dose_has_diminishing_returns_and_no_adaptation_is_exact():
    from attend.rhythm.vision import FoveatedEye

    plain = FoveatedEye()
    assert plain.dwell_dose(0.3, 0.0125) == 0.0125  # bit for bit: g dt
    eye = FoveatedEye(adaptation_time=0.15)
    steps = [eye.dwell_dose(k * 0.0125, 0.0125) for k in range(40)]
    assert np.all(np.diff(steps) < 0) and steps[0] < 0.0125
    assert sum(steps) == pytest.approx(0.15 * (1 - np.exp(-40 * 0.0125 / 0.15)), rel=1e-12)
    assert sum(steps) < 0.15
    with pytest.raises(AttendInputError, match="adaptation_time"):
        FoveatedEye(adaptation_time=0.0)
