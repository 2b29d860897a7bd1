"""Tests of LearningSettings, the one settings value of identify and learn_batch: its checks name
the field, and explicit settings give bit for bit the results of the defaults they spell out."""

import warnings
from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.linear import simulate
from attend.models.parameters import parameter_vector
from attend.models.problems import mass_spring_damper
from attend.perception import learning as L
from attend.perception.learning import LearningSettings

DT = 0.1
FREE = np.array([False, False, True, True, False, True, False, False])

#: every field at the value identify used before it took settings (newton on; top order and input
#: order as "sample" mode and p give them)
IDENTIFY_DEFAULTS = dict(embedding_order=6, input_order=6, noise_prior_mean=(0.0, 0.0), noise_prior_precision=1.0,
                         max_iterations=50, tolerance=1e-3, integration_time=10.0, noise_integration_time=4.0,
                         noise_iterations=8, trim_edges=True, precision_convention="size", states="sample",
                         top_order="marginal", overrelax=True, newton=True, scaled=True)


def _logs(seeds=(0, 1), n=150):
    system = mass_spring_damper()
    u = np.exp(-0.25 * (np.arange(n) * DT - 6) ** 2)[:, None]
    logs = [simulate(system, u, DT, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=s)
            for s in seeds]
    return system, np.stack([g.outputs for g in logs]), np.stack([g.inputs for g in logs])


def _same(a, b):
    """Bit for bit: arrays equal (NaN where NaN), tuples and dicts element by element."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            _same(a[key], b[key])
    elif isinstance(a, (tuple, list)) and not hasattr(a, "_fields"):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif hasattr(a, "_fields"):
        for x, y in zip(a, b):
            _same(x, y)
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


# --- the checks --------------------------------------------------------------------------------

@pytest.mark.parametrize("field, value, match", [
    ("embedding_order", 0, "embedding_order: expected p >= 1"),
    ("embedding_order", 2.5, "embedding_order: expected an integer"),
    ("embedding_order", 30, "embedding_order: expected an integer in 0..24"),
    ("input_order", -1, "input_order: expected an integer"),
    ("noise_prior_mean", [0.0], "noise_prior_mean: expected a number or a pair"),
    ("noise_prior_mean", (0.0, np.nan), "noise_prior_mean: expected finite"),
    ("noise_prior_mean", "0", "noise_prior_mean: expected a number or a pair"),
    ("noise_prior_precision", 0.0, "noise_prior_precision: expected precisions > 0"),
    ("noise_prior_precision", (1.0, -1.0), "noise_prior_precision: expected precisions > 0"),
    ("noise_prior_precision", (1.0, 2.0, 3.0), "noise_prior_precision: expected a number or a pair"),
    ("max_iterations", 0, "max_iterations: expected an integer >= 1"),
    ("max_iterations", 10.0, "max_iterations: expected an integer >= 1"),
    ("tolerance", np.nan, "tolerance: expected a number"),
    ("tolerance", "1e-3", "tolerance: expected a number"),
    ("integration_time", 0.0, "integration_time: expected a finite number > 0"),
    ("integration_time", np.inf, "integration_time: expected a finite number > 0"),
    ("noise_integration_time", -4.0, "noise_integration_time: expected a finite number > 0"),
    ("noise_iterations", -1, "noise_iterations: expected an integer >= 0"),
    ("trim_edges", 1, "trim_edges: expected True or False"),
    ("precision_convention", "spm", "precision_convention: expected 'size' or 'max'"),
    ("states", "window", "states: expected 'sample' or 'path'"),
    ("top_order", "zero", "top_order: expected 'marginal' or 'truncate'"),
    ("overrelax", "yes", "overrelax: expected True or False"),
    ("newton", 0, "newton: expected True or False"),
    ("scaled", None, "scaled: expected True or False"),
])
def test_bad_settings_name_the_field(field, value, match):
    with pytest.raises(AttendInputError, match=match):
        LearningSettings(**{field: value})
    with pytest.raises(AttendInputError, match=match):  # a changed copy is checked again
        replace(LearningSettings(), **{field: value})


def test_settings_hold_plain_checked_values():
    settings = LearningSettings(embedding_order=np.int64(4), noise_prior_mean=np.array([1.0, 2.0]),
                                noise_prior_precision=np.exp(3), max_iterations=np.int32(7), tolerance=0,
                                trim_edges=np.bool_(False), newton=np.bool_(True))
    assert settings.embedding_order == 4 and type(settings.embedding_order) is int
    assert settings.noise_prior_mean == (1.0, 2.0)
    assert settings.noise_prior_precision == (float(np.exp(3)), float(np.exp(3)))
    assert type(settings.max_iterations) is int and type(settings.tolerance) is float
    assert settings.trim_edges is False and settings.newton is True
    assert settings == replace(settings) and hash(settings) == hash(replace(settings))
    with pytest.raises(FrozenInstanceError):
        settings.max_iterations = 3
    assert LearningSettings(noise_prior_precision=(2.0, np.inf)).noise_prior_precision == (2.0, np.inf)


def test_paper_learner_is_the_published_options_with_the_other_defaults():
    assert L.PAPER_LEARNER == LearningSettings(top_order="truncate", overrelax=False, newton=False, scaled=False)
    assert replace(L.PAPER_LEARNER, max_iterations=40).newton is False


def test_settings_of_another_type_are_rejected():
    _, Y, U = _logs()
    eta = parameter_vector(mass_spring_damper())[None].repeat(2, 0)
    with pytest.raises(AttendInputError, match="settings: expected a LearningSettings"):
        L.learn_batch(Y, U, DT, n_states=2, kernel_width=0.5, prior_mean=eta,
                      prior_precision=np.where(FREE, 1.0, L.KNOWN_PRIOR_PRECISION)[None], settings=dict(max_iterations=3))
    from attend.rhythm.learning import learn_scheduled

    with pytest.raises(AttendInputError, match="settings: expected a LearningSettings"):
        learn_scheduled(Y, U, DT, free_schedule=np.ones(3), free=FREE, prior_mean=eta, n_states=2, kernel_width=0.5,
                        settings=dict(embedding_order=4))


# --- explicit settings are the defaults, bit for bit (same process) -------------------------------

def test_identify_with_explicit_settings_is_its_default_bit_for_bit():
    system, Y, U = _logs(seeds=(0,))
    prior = parameter_vector(system) + 0.4 * FREE
    from attend.models.parameters import system_from_parameters

    start = system_from_parameters(prior, system)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", L.IdentifiabilityWarning)
        default = L.identify(start, Y[0], U[0], DT, kernel_width=0.5, free=FREE)
        explicit = L.identify(start, Y[0], U[0], DT, kernel_width=0.5, free=FREE,
                              settings=LearningSettings(**IDENTIFY_DEFAULTS))
        unset = L.identify(start, Y[0], U[0], DT, kernel_width=0.5, free=FREE, settings=LearningSettings())
    for result in (explicit, unset):
        for name in ("parameters", "parameter_precision", "log_precision", "log_precision_precision", "free_energy",
                     "parameter_history", "precision_history", "log_precision_history", "states"):
            _same(getattr(default, name), getattr(result, name))
        _same(default.settings, result.settings)
        assert (default.iterations, default.converged, default.message) == (result.iterations, result.converged,
                                                                              result.message)
    # the record holds the resolved settings: newton on, the sample mode's top order, d = p
    assert default.settings["newton"] is True and default.settings["top_order"] == "marginal"
    assert default.settings["input_order"] == 6 and default.settings["noise_prior_precision"] == [1.0, 1.0]


@pytest.mark.parametrize("states", ["sample", "path"])
def test_learn_batch_with_explicit_settings_is_its_default_bit_for_bit(states):
    system, Y, U = _logs()
    theta = parameter_vector(system)
    eta = np.stack([theta + 0.4 * FREE, theta - 0.3 * FREE])
    kw = dict(n_states=2, kernel_width=0.5, prior_mean=eta, prior_precision=np.where(FREE, 1.0, L.KNOWN_PRIOR_PRECISION)[None])
    default = L.learn_batch(Y, U, DT, settings=LearningSettings(max_iterations=10, states=states), **kw)
    spelled = dict(IDENTIFY_DEFAULTS, newton=False, max_iterations=10, states=states,
                   top_order="marginal" if states == "sample" else "truncate")
    explicit = L.learn_batch(Y, U, DT, settings=LearningSettings(**spelled), **kw)
    _same(default, explicit)
    if states == "sample":  # settings=None is LearningSettings()
        _same(L.learn_batch(Y, U, DT, **kw), L.learn_batch(Y, U, DT, settings=LearningSettings(), **kw))


def test_newton_none_is_each_functions_default():
    """newton=None means on in identify and off in learn_batch (the two functions' defaults before
    they took settings); an explicit value is kept by both; top_order and input_order resolve too."""
    from attend.perception.learning.settings import _resolved

    assert _resolved(None, newton=True).newton is True and _resolved(None, newton=False).newton is False
    assert _resolved(LearningSettings(newton=False), newton=True).newton is False
    assert _resolved(LearningSettings(newton=True), newton=False).newton is True
    path = _resolved(LearningSettings(states="path", embedding_order=3), newton=False)
    assert path.top_order == "truncate" and path.input_order == 3
    assert _resolved(LearningSettings(input_order=2, top_order="truncate"), newton=True).top_order == "truncate"
