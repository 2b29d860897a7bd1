"""The settings of the learner: one frozen value that :func:`identify` and :func:`learn_batch` take
as ``settings`` (the log, the model and the parameter prior stay their own arguments)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from numbers import Integral, Real

import numpy as np

from attend._validation import AttendInputError, order


@dataclass(frozen=True)
class LearningSettings:
    """How the D, E and M steps run: embedding, noise prior, stopping rule and numerical options.

    The symbols are those of :mod:`attend.perception.learning` (its docstring has the equations
    and the numbered options (1)-(4) named below). Every field is checked when the value is made;
    a bad value raises AttendInputError naming the field. ``dataclasses.replace(settings, ...)``
    gives a changed copy (checked again).

    embedding_order: p, the highest generalised order of the states (an integer in 1..24; the
        states, outputs and motion errors carry p + 1 orders). Default 6.
    input_order: d, the highest order of the embedded measured inputs (an integer in 0..24, or
        None for d = p, the default).
    noise_prior_mean: eta_lambda, the prior means of the noise log-precisions
        [lambda_z, lambda_w] (Pi_z = exp(lambda_z) I in 1/output unit^2, Pi_w = exp(lambda_w) I in
        s^2/state unit^2); one number for both or a pair; the learning starts there. Default (0, 0).
    noise_prior_precision: P_lambda, the prior precisions of [lambda_z, lambda_w] (> 0; one
        number for both or a pair; inf holds that log-precision fixed at its prior mean). Default
        (1, 1).
    max_iterations: the most D-E-M iterations (an integer >= 1). Default 50.
    tolerance: a run has converged when one whole iteration raises the free energy F by less than
        this [nats] (and its prior precision no longer changes); a negative value runs all
        ``max_iterations``. Default 1e-3.
    integration_time: L, the time over which the E-step integrates the gradient flow of F in theta
        (theta += (expm(L J) - I) inv(J) dF/dtheta with J = d2F/dtheta2; units of 1/J). Default 10.
    noise_integration_time: the same for the M-step's flow in lambda (units of 1/curvature of F in
        lambda). Default 4.
    noise_iterations: the most M-steps per iteration (an integer >= 0; each clipped to +-2 in
        lambda). Default 8.
    trim_edges: leave out of the sums the samples whose embedding window reaches past the log.
        Default True.
    precision_convention: how the temporal precision S is normalised, "size" (SPM: V inverted at
        the size used) or "max" (V inverted at max(p, d) + 1 orders; :func:`attend.block_precisions`).
        Default "size".
    states: the state model, "sample" (the paper's eq. 8: free generalised states at every sample)
        or "path" (one state trajectory, the data counted once; "Path mode" in the package
        docstring). Default "sample".
    top_order: the motion error's top order, "marginal" (x^(p+1) integrated out; F stays bounded in
        lambda_w on fast-sampled logs) or "truncate" (the paper's eq. 8, x^(p+1) = 0); None (the
        default) is "marginal" in sample mode and "truncate" in path mode.
    overrelax: option (3), extend each sweep's move in (theta, lambda) while F rises. Default True.
    newton: option (4), a Levenberg-Marquardt step on the collapsed free energy once sweeps creep;
        None (the default) means the default of the function that runs: on in :func:`identify`,
        off in :func:`learn_batch`.
    scaled: option (1), hold order k as (sqrt(2) s)^k d^k/dt^k (an exact reparameterisation that
        keeps S well conditioned). Default True.

    :data:`PAPER_LEARNER` is the learner as published (top_order "truncate", no over-relaxation,
    no Newton step, unscaled coordinates); the paper reproductions pass it.
    """

    embedding_order: int = 6
    input_order: int | None = None
    noise_prior_mean: tuple[float, float] = (0.0, 0.0)
    noise_prior_precision: tuple[float, float] = (1.0, 1.0)
    max_iterations: int = 50
    tolerance: float = 1e-3
    integration_time: float = 10.0
    noise_integration_time: float = 4.0
    noise_iterations: int = 8
    trim_edges: bool = True
    precision_convention: str = "size"
    states: str = "sample"
    top_order: str | None = None
    overrelax: bool = True
    newton: bool | None = None
    scaled: bool = True

    def __post_init__(self):
        p = order(self.embedding_order, "embedding_order")
        if p < 1:
            raise AttendInputError("embedding_order: expected p >= 1 for learning (with p = 0 the model has no "
                                   "derivative dx/dt to compare with A x + B u, so A and B cannot be learned)")
        checked = dict(
            embedding_order=p,
            input_order=None if self.input_order is None else order(self.input_order, "input_order"),
            noise_prior_mean=_pair(self.noise_prior_mean, "noise_prior_mean", positive=False),
            noise_prior_precision=_pair(self.noise_prior_precision, "noise_prior_precision", positive=True),
            max_iterations=_integer(self.max_iterations, "max_iterations", 1),
            tolerance=_real(self.tolerance, "tolerance"),
            integration_time=_positive(self.integration_time, "integration_time"),
            noise_integration_time=_positive(self.noise_integration_time, "noise_integration_time"),
            noise_iterations=_integer(self.noise_iterations, "noise_iterations", 0),
            trim_edges=_flag(self.trim_edges, "trim_edges"),
            precision_convention=_choice(self.precision_convention, "precision_convention", ("size", "max")),
            states=_choice(self.states, "states", ("sample", "path")),
            top_order=None if self.top_order is None else _choice(self.top_order, "top_order", ("marginal", "truncate")),
            overrelax=_flag(self.overrelax, "overrelax"),
            newton=None if self.newton is None else _flag(self.newton, "newton"),
            scaled=_flag(self.scaled, "scaled"),
        )
        for name, value in checked.items():  # the checked, plain-Python values (frozen: set once here)
            object.__setattr__(self, name, value)


def _pair(value, field: str, positive: bool) -> tuple[float, float]:
    """One number or a pair of numbers for [lambda_z, lambda_w], as a pair of floats."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    items = list(value) if isinstance(value, (list, tuple)) else [value, value]
    if len(items) != 2 or any(isinstance(v, (bool, np.bool_)) or not isinstance(v, Real) for v in items):
        raise AttendInputError(f"{field}: expected a number or a pair [lambda_z, lambda_w] of numbers, "
                               f"got {value!r}")
    pair = (float(items[0]), float(items[1]))
    if positive and any(np.isnan(v) or v <= 0 for v in pair):
        raise AttendInputError(f"{field}: expected precisions > 0 (inf holds lambda fixed), got {value!r}")
    if not positive and not all(np.isfinite(v) for v in pair):
        raise AttendInputError(f"{field}: expected finite log-precisions [lambda_z, lambda_w], got {value!r}")
    return pair


def _integer(value, field: str, minimum: int) -> int:
    """An integer >= minimum (True/False and 2.0 are errors)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Integral) or value < minimum:
        raise AttendInputError(f"{field}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _real(value, field: str) -> float:
    """A real number that is not NaN."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real) or np.isnan(value):
        raise AttendInputError(f"{field}: expected a number, got {value!r}")
    return float(value)


def _positive(value, field: str) -> float:
    """A finite number > 0."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real) or not 0 < value < np.inf:
        raise AttendInputError(f"{field}: expected a finite number > 0, got {value!r}")
    return float(value)


def _flag(value, field: str) -> bool:
    """True or False (not 0, 1 or text)."""
    if not isinstance(value, (bool, np.bool_)):
        raise AttendInputError(f"{field}: expected True or False, got {value!r}")
    return bool(value)


def _choice(value, field: str, options: tuple[str, ...]) -> str:
    """One of ``options``."""
    if not isinstance(value, str) or value not in options:
        raise AttendInputError(f"{field}: expected {' or '.join(repr(o) for o in options)}, got {value!r}")
    return value


#: The learner as published (eq. 8 with the top-order motion error truncated, plain D-E-M sweeps in
#: unscaled coordinates): what the paper reproductions (fig3, fig4, fig5, rhythm-learning) pass,
#: changed with ``dataclasses.replace(PAPER_LEARNER, max_iterations=..., ...)``
PAPER_LEARNER = LearningSettings(top_order="truncate", overrelax=False, newton=False, scaled=False)


def _resolved(settings: LearningSettings | None, *, newton: bool) -> LearningSettings:
    """``settings`` (default: LearningSettings()) with input_order, top_order and newton made
    explicit: d = p, the state model's top order, and ``newton`` where the settings say None."""
    if settings is None:
        settings = LearningSettings()
    elif not isinstance(settings, LearningSettings):
        raise AttendInputError(f"settings: expected a LearningSettings (attend.perception.learning), "
                               f"got {type(settings).__name__}")
    return replace(
        settings,
        input_order=settings.embedding_order if settings.input_order is None else settings.input_order,
        top_order=settings.top_order or ("marginal" if settings.states == "sample" else "truncate"),
        newton=newton if settings.newton is None else settings.newton,
    )
