"""Every argument of every public function and class is documented in its docstring
(python-control's convention): the argument's name appears, as a word, in the docstring of the
function, or for a class in its class or ``__init__`` docstring; a public method's arguments in
the method's docstring. Private arguments (leading underscore), ``self`` and ``*args``/``**kwargs``
are exempt, as are the fields of NamedTuples (documented with the class).

Covered: every name attend re-exports, and the public modules of models, perception, action,
rhythm, io, the experiments with figures, the report and the CLI (MODULES). There are no exemptions.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest

MODULES = [
    "attend",
    "attend.perception",
    "attend.perception.learning",
    "attend.perception.learning.settings",
    "attend.perception.references",
    "attend.perception.dem",
    "attend.perception.spread_check",
    "attend.perception.dem_flow",
    "attend.perception.dem_online",
    "attend.perception.sample_window",
    "attend.perception.kalman",
    "attend.perception.input_width",
    "attend.perception.nonlinear",
    "attend.perception.nonlinear.learning",
    "attend.perception.nonlinear.path",
    "attend.perception.nonlinear.misfit",
    "attend.perception.nonlinear.path_learning",
    "attend.perception.nonlinear.jax_backend",
    "attend.perception.nonlinear.start",
    "attend.perception.nonlinear.start_search",
    "attend.perception.block_tridiagonal",
    "attend.perception.nonlinear._workspace",
    "attend.perception.nonlinear_smoothers",
    "attend.perception.nonlinear_smoothers.estimators",
    "attend.action",
    "attend.action.planners",
    "attend.action.episode",
    "attend.action.plots",
    "attend.rhythm",
    "attend.rhythm.oscillator",
    "attend.rhythm.schedule",
    "attend.rhythm.fixations",
    "attend.rhythm.learning",
    "attend.rhythm.replanning",
    "attend.rhythm.vision",
    "attend.report",
    "attend.plotting",
    "attend.cli",
    "attend.cli_identify",
    "attend.experiments.fig2",
    "attend.experiments.fig3",
    "attend.experiments.fig4",
    "attend.experiments.fig5",
    "attend.io",
    "attend.io.learned",
    "attend.io.bags",
    "attend.workflows",
    "attend.workflows.estimate",
    "attend.workflows.estimate_gaps",
    "attend.workflows.identify",
    "attend.workflows.identify_nonlinear",
    "attend.models.sample_times",
    "attend.models",
    "attend.models.linear",
    "attend.models.nonlinear",
    "attend.models.noise",
    "attend.models.noise_model",
    "attend.perception.estimate",
    "attend.models.generalized",
    "attend.models.parameters",
    "attend.models.problems",
    "attend.perception.interop",
    "attend.perception.file_estimators",
    "attend.action.belief",
    "attend.action.camera",
    "attend.action.field",
    "attend.action.flight",
    "attend.action.metrics",
    "attend.action.paper_search",
    "attend.action.mission.config",
    "attend.action.mission.ground",
    "attend.action.mission.mission",
    "attend.action.mission.flight_logs",
    "attend.action.mission.area_files",
    "attend.action.mission.plan_files",
    "attend.action.mission.simulate",
    "attend.action.mission.examples",
    "attend.action.mission.map_painter",
    "attend.action.mission.map_plot",
    "attend.action.mission.outputs",
    "attend.action.log_odds",
    "attend.control",
    "attend.control.attenuation",
    "attend.control.reaching",
    "attend.control.roll",
    "attend.control.arm",
    "attend.experiments.quadrotor",
    "attend.experiments.ipp",
    "attend.experiments.rhythm_ipp",
    "attend.experiments.rhythm_learning",
    "attend.experiments.rhythm_tradeoff",
    "attend.experiments.vision",
    "attend.experiments.lorenz",
    "attend.experiments.pendulum",
]

def public_names(module_name: str) -> list[str]:
    """``__all__``, else the public functions and classes defined in the module."""
    module = importlib.import_module(module_name)
    if hasattr(module, "__all__"):
        names = module.__all__
    else:
        names = [n for n, v in vars(module).items() if not n.startswith("_")
                 and (inspect.isfunction(v) or inspect.isclass(v)) and v.__module__ == module_name]
    return [n for n in names if inspect.isfunction(getattr(module, n)) or inspect.isclass(getattr(module, n))]


def _targets(obj):
    """(qualified name, signature, docstring) of the object and, for a class, its public methods."""
    if inspect.isfunction(obj):
        return [(obj.__qualname__, inspect.signature(obj), obj.__doc__ or "")]
    if issubclass(obj, tuple) and hasattr(obj, "_fields"):  # NamedTuple: fields documented with the class
        return []
    init_doc = vars(obj)["__init__"].__doc__ or "" if "__init__" in vars(obj) else ""
    try:
        targets = [(obj.__qualname__, inspect.signature(obj), (obj.__doc__ or "") + "\n" + init_doc)]
    except (TypeError, ValueError):
        targets = []
    for name, member in vars(obj).items():
        if not name.startswith("_") and inspect.isfunction(member):
            targets.append((f"{obj.__qualname__}.{name}", inspect.signature(member), member.__doc__ or ""))
    return targets


def undocumented(obj) -> list[str]:
    missing = []
    for qualname, signature, doc in _targets(obj):
        for parameter in signature.parameters.values():
            if parameter.name in ("self", "cls") or parameter.name.startswith("_") \
                    or parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
                continue
            if not re.search(rf"(?<![A-Za-z0-9_]){re.escape(parameter.name)}(?![A-Za-z0-9_])", doc):
                missing.append(f"{qualname}({parameter.name})")
    return missing


CASES = [pytest.param(module, name, id=f"{module}.{name}") for module in MODULES for name in public_names(module)]


@pytest.mark.parametrize("module, name", CASES)
def test_every_argument_is_documented(module, name):
    obj = getattr(importlib.import_module(module), name)
    assert not undocumented(obj), f"{module}.{name}: arguments missing from the docstring: {undocumented(obj)}"
