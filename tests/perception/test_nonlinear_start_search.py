"""The start search without initial_state (attend.perception.nonlinear.start_search): its prior and
components in closed form, the bank's filter against the library's unscented filter, and a
bimodal start (a double well seen through x^2) that the data decide, or cannot."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear import start_search as search
from attend.perception.nonlinear_smoothers import unscented_kalman, white_noise_options


def test_the_prior_is_flat_near_its_centre_and_heavy_tailed():
    prior = search.StartPrior(np.array([1.0, -2.0]), np.array([2.0, 0.5]))
    assert prior.log_density(prior.centre) == pytest.approx(-np.log(2.0 * 0.5))
    # far out, t_1 in n = 2 falls as |z|^-(n + 1): ten times farther costs 3 ln 10 nats, not 50 |z|^2
    far = prior.centre + np.array([2.0, 0.5]) * np.array([1e3, 0.0])
    farther = prior.centre + np.array([2.0, 0.5]) * np.array([1e4, 0.0])
    assert prior.log_density(far) - prior.log_density(farther) == pytest.approx(3 * np.log(10), rel=1e-5)
    assert prior.weight(prior.centre) == pytest.approx(3.0)  # (dof + n) / dof
    gaussian = search.StartPrior(prior.centre, prior.scale, np.inf)
    assert gaussian.log_density(far) - gaussian.log_density(prior.centre) == pytest.approx(-0.5e6)
    assert gaussian.weight(far) == 1.0


@pytest.mark.parametrize("n, bound", [(1, 1.0), (2, 1.1), (3, 1.3), (4, 1.9)])
def test_the_components_cover_the_prior_out_to_256_scales(n, bound):
    """Every point within 256 sigma_0 of the centre is within ``bound`` component std of a component
    centre (the module docstring's figures), on 4000 points with log-uniform radii."""
    centres, stds = search.initial_components(np.zeros(n), np.ones(n))
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(4000, n))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    points = directions * np.exp(rng.uniform(np.log(0.01), np.log(256.0), 4000))[:, None]
    distance = np.sqrt(np.min(np.sum(((points[:, None] - centres[None]) / stds[None]) ** 2, axis=2), axis=1))
    assert distance.max() <= bound


def test_data_information_divides_out_the_components_prior():
    """Gaussian oracle: prior N(c, diag(P)) times the likelihood exp(-1/2 x'J x + h'x) is N(m, Sigma)
    with inv(Sigma) = J + inv(P), m = Sigma (h + inv(P) c); dividing the prior out gives J and h back."""
    rng = np.random.default_rng(1)
    root = rng.normal(size=(3, 3))
    information = root @ root.T
    shift = rng.normal(size=3)
    c, std = rng.normal(size=3), np.array([2.0, 3.0, 0.5])
    covariance = np.linalg.inv(information + np.diag(std**-2.0))
    mean = covariance @ (shift + c / std**2)
    got_information, got_shift = search.data_information(mean, covariance, c, std)
    np.testing.assert_allclose(got_information, information, atol=1e-9)
    np.testing.assert_allclose(got_shift, shift, atol=1e-9)


def test_the_prior_takes_back_only_the_directions_the_log_does_not_see():
    prior = search.StartPrior(np.zeros(2), np.ones(2))
    # the log fixes x1 = 3 (information 100) and says nothing of x2, whose guess (50) is the component's
    start = search.prior_map(np.diag([100.0, 0.0]), np.array([300.0, 0.0]), np.array([3.0, 50.0]), prior)
    assert start[0] == pytest.approx(3.0, abs=0.1) and abs(start[1]) < 1e-6
    # a state the log fixes far from the centre (Lorenz at 30) stays there: the t prior pulls it in by a
    # fraction w / (1 + w) with w = 3 / (1 + |z|^2) ~ 0.0017 (0.05 of 30), where a N(0, 1) prior would halve it
    start = search.prior_map(np.eye(2), np.array([30.0, -30.0]), np.array([30.0, -30.0]), prior)
    weight = prior.weight(start)
    np.testing.assert_allclose(start, np.array([30.0, -30.0]) / (1 + weight), rtol=1e-8)
    assert 29.9 < start[0] < 30.0


DT = 1.0


def _double_well(x0, amplitude, samples=64, seed=0):
    """SPM's double well, y = x^2 / 16 + z (sigma_z = e^-1), pushed by u = a sin(pi t / 16)."""
    system = NonlinearSystem(lambda x, v: (16 * x / (1 + x**2) - x / 2 + 2 * v) / 8, lambda x, v: x**2 / 16, 1, 1, 1)
    u = amplitude * np.sin(np.pi * np.arange(samples) / 16.0)[:, None]
    log = simulate_nonlinear(system, u, DT, kernel_width=0.5, process_std=np.exp(-8), measurement_std=np.exp(-1),
                             initial_state=[x0], seed=seed)
    return system, log


def _options(unknown: bool):
    return white_noise_options(DT, process_precision=np.array([[np.exp(16)]]), sensor_precision=np.array([[np.exp(2)]]),
                               input_prior_precision=np.array([0.125]) if unknown else None, input_kernel_width=0.5,
                               input_mean=np.zeros(1) if unknown else None)


def test_the_banks_filters_are_the_librarys_unscented_filter():
    """Oracle: the bank steps its components as one batch; each component's evidence equals
    unscented_kalman's log-likelihood from the same prior on the same samples. Two mirrored starts of
    the symmetric double well (unknown input) keep equal scores, so neither is pruned or merged and the
    bank runs BANK_HORIZON samples."""
    system, log = _double_well(5.6, 8.0)
    options = _options(unknown=True)
    centres, stds = np.array([[5.0], [-5.0]]), np.array([[1.0], [1.0]])
    prior = search.StartPrior(np.zeros(1), np.ones(1))
    bank = search._Bank(system, DT, log.outputs, None, dict(options, known_inputs=None, substeps=2), centres, stds,
                        prior)
    mass = bank.score.copy()
    survivors, samples = bank.run()
    assert sorted(survivors) == [0, 1] and samples == search.BANK_HORIZON
    for k, centre in enumerate(centres):
        filtered = unscented_kalman(system, DT, log.outputs[:samples], None, initial_mean=centre,
                                    initial_covariance=np.diag(stds[k] ** 2), smooth=False, substeps=2, **options)
        assert bank.score[list(bank.index).index(k)] - mass[k] == pytest.approx(filtered.log_likelihood, abs=1e-8)


@pytest.mark.parametrize("x0", [-5.6, 5.6])
def test_a_measured_push_tells_the_wells_apart(x0):
    system, log = _double_well(x0, 4.0, samples=96)
    found = search.search_start(system, DT, log.outputs, log.inputs, substeps=8, **_options(unknown=False))
    assert not found.ambiguous
    assert np.sign(found.mean[0]) == np.sign(x0)
    assert found.modes[0].misfit < search.MISFIT_LIMIT


def test_a_symmetric_model_gives_two_equal_starts_and_says_so():
    """With the input unknown the double well is symmetric (x, v) -> (-x, -v): the search finds both
    wells with scores within AMBIGUITY_NATS and different estimates, and its message names
    initial_state."""
    system, log = _double_well(5.6, 8.0, samples=96)
    found = search.search_start(system, DT, log.outputs, None, substeps=8, **_options(unknown=True))
    assert found.ambiguous
    best, second = found.modes[:2]
    assert best.score - second.score < search.AMBIGUITY_NATS
    assert best.mean[0] == pytest.approx(-second.mean[0], rel=0.05)
    assert found.message.startswith("initial_state: not given") and "give initial_state" in found.message


def test_a_bad_prior_scale_is_named():
    system, log = _double_well(5.6, 4.0, samples=20)
    with pytest.raises(AttendInputError, match="initial_state_std: the search's prior needs a finite scale > 0"):
        search.search_start(system, DT, log.outputs, log.inputs, prior_scale=[0.0], **_options(unknown=False))


def _merged_one_pair_at_a_time(mean, cov, score):
    """The components _Bank._merge keeps, by its rule checked pair by pair (the reference)."""
    kept = []
    for i in np.argsort(-score):
        duplicate = False
        for j in kept:
            difference = mean[i] - mean[j]
            try:
                distance = max(difference @ np.linalg.solve(cov[i], difference),
                               difference @ np.linalg.solve(cov[j], difference))
            except np.linalg.LinAlgError:
                continue
            if distance < 1.0:
                duplicate = True
                break
        if not duplicate:
            kept.append(int(i))
    return sorted(kept)


@pytest.mark.parametrize("singular", [False, True])
def test_the_merge_checks_all_pairs_at_once_as_one_pair_at_a_time(singular):
    """Random components (d = 2), many of them within each other's ellipsoids: the merge keeps the same
    ones as the pair-by-pair rule; with a singular covariance (its pairs skipped) too."""
    system, log = _double_well(5.6, 8.0, samples=8)
    options = _options(unknown=True)
    rng = np.random.default_rng(3)
    count = 60
    bank = search._Bank(system, DT, log.outputs, None, dict(options, known_inputs=None, substeps=2),
                        rng.normal(size=(count, 1)), np.ones((count, 1)), search.StartPrior(np.zeros(1), np.ones(1)))
    root = rng.normal(scale=0.7, size=(count, 2, 2))
    bank.mean, bank.cov = rng.normal(scale=2.0, size=(count, 2)), root @ np.swapaxes(root, 1, 2) + 0.05 * np.eye(2)
    if singular:
        bank.cov[5] = np.zeros((2, 2))
    bank.score = rng.normal(size=count)
    expected = _merged_one_pair_at_a_time(bank.mean, bank.cov, bank.score)
    bank._merge()
    assert 1 < len(expected) < count
    assert sorted(bank.index.tolist()) == expected


def test_each_start_is_smoothed_once(monkeypatch):
    """A mode's first run from the same start as an anchor's (here DEM's start, given as the prior's
    centre and scale and as an extra start, survives the bank) is the anchor's run, not a second one."""
    system, log = _double_well(5.6, 4.0, samples=48)
    starts = []
    smoothed = search._smoothed

    def counted(system, dt, outputs, inputs, options, mean, std):
        starts.append((tuple(mean), tuple(std)))
        return smoothed(system, dt, outputs, inputs, options, mean, std)

    monkeypatch.setattr(search, "_smoothed", counted)
    found = search.search_start(system, DT, log.outputs, log.inputs, substeps=8, prior_mean=[5.0], prior_scale=[1.0],
                                prior_dof=np.inf, extra_starts=[([5.0], [1.0])], **_options(unknown=False))
    assert len(starts) == len(set(starts))
    assert found.modes[0].misfit < search.MISFIT_LIMIT


def test_a_start_that_cannot_come_near_the_best_stops_early_and_changes_nothing(monkeypatch):
    """The modes run first; an anchor (here the prior N(0, 1), far from the truth at 5.6) stops as soon
    as its score cannot come within AMBIGUITY_NATS + FLOOR_MARGIN_NATS of the best mode's. The result
    equals the search without floors (every run to the end): the same modes, scores and estimates."""
    from attend.perception.nonlinear_smoothers import EvidenceBelowFloor

    system, log = _double_well(5.6, 4.0, samples=96)
    stopped = []
    smoothed = search._smoothed

    def recorded(system, dt, outputs, inputs, options, mean, std):
        try:
            return smoothed(system, dt, outputs, inputs, options, mean, std)
        except EvidenceBelowFloor as stop:
            stopped.append(stop.samples)
            raise

    monkeypatch.setattr(search, "_smoothed", recorded)
    found = search.search_start(system, DT, log.outputs, log.inputs, substeps=8, prior_mean=[0.0], prior_scale=[1.0],
                                **_options(unknown=False))
    assert len(stopped) == 1 and stopped[0] < len(log.outputs)
    monkeypatch.setattr(search, "_floor", lambda *unused: None)
    every = search.search_start(system, DT, log.outputs, log.inputs, substeps=8, prior_mean=[0.0], prior_scale=[1.0],
                                **_options(unknown=False))
    assert len(stopped) == 1  # none without floors
    assert found.ambiguous == every.ambiguous and len(found.modes) == len(every.modes)
    for mode, reference in zip(found.modes, every.modes):
        assert mode.score == reference.score
        np.testing.assert_array_equal(mode.mean, reference.mean)
        np.testing.assert_array_equal(mode.states, reference.states)


def test_a_model_stiff_only_near_zero_is_searched_about_the_priors_centre():
    """dx/dt = -0.2 (x - 3) - 400 exp(-(x / 0.1)^2) x is stiff (rate 400) only within ~0.1 of 0 and
    slow about the prior's centre 3: the bank checks its RK4 sub-steps where it starts (the
    centre), not at x = 0 (where 2 sub-steps of 0.1 s are unstable), and the smoothed start lies
    at the true x[0] = 3.5 within the sensor's noise."""
    system = NonlinearSystem(lambda x, v: np.array([-0.2 * (x[0] - 3.0) - 400.0 * np.exp(-(x[0] / 0.1) ** 2) * x[0]]),
                             lambda x, v: np.array([x[0]]), 1, 0, 1)
    log = simulate_nonlinear(system, 60, 0.1, kernel_width=0.0, process_std=0.02, measurement_std=0.05,
                             initial_state=[3.5], seed=1)
    options = dict(process_covariance=np.array([[0.02**2 * 0.1]]), measurement_covariance=np.array([[0.05**2]]))
    found = search.search_start(system, 0.1, log.outputs, None, substeps=2, prior_mean=[3.0], prior_scale=1.0,
                                **options)
    assert found.modes[0].states[0, 0] == pytest.approx(3.5, abs=3 * 0.05)
