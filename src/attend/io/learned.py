"""The learned model files `attend identify` writes: the model file learned from, with the learned
values in [model] (so that `attend estimate` uses them) and the details in [learned]."""

from __future__ import annotations

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import numpy as np

from attend.io.model import ModelFile


def write_learned_model(path: str | Path, model: ModelFile, result) -> Path:
    """A model file with the learned A, B, C and noise precisions, their posterior precisions in
    [learned], ready for `attend estimate`. path: the TOML file to write (parent folders created);
    model: the model file learned from (its other sections are kept); result: the identification
    result of :func:`attend.workflows.identify_from_files`. Returns the path."""
    import tomli_w

    system = result.system()
    data = tomllib.loads(Path(model.path).read_text(encoding="utf-8-sig")) if model.path else {}
    data.setdefault("model", {})
    data["model"]["A"] = system.A.tolist()
    data["model"]["B"] = system.B.tolist()
    data["model"]["C"] = system.C.tolist()
    observer = data.setdefault("observer", {})
    observer["sensor_precision"] = float(result.sensor_precision)
    observer["process_precision"] = float(result.process_precision)
    learned = {
        "parameter_names": list(result.parameter_names),
        "parameters": [float(v) for v in result.parameters],
        "parameter_precision": [float(v) for v in np.diag(np.atleast_2d(result.parameter_precision))]
        if np.ndim(result.parameter_precision) == 2 else [float(v) for v in result.parameter_precision],
        "log_precision": [float(v) for v in result.log_precision],
        "free_energy": [float(v) for v in result.free_energy],
        "converged": bool(result.converged),
        "iterations": int(result.iterations),
        "message": str(result.message),
    }
    learned_section = {"learned": learned}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = "# Learned by `attend identify`: [model] holds the posterior means; [learned] the details.\n"
    data.pop("learned", None)
    body = tomli_w.dumps(data) + "\n# posterior parameter precisions (Pi_theta diagonal), noise log-precisions\n"
    body += "# [lambda_z, lambda_w], free energy per iteration\n" + tomli_w.dumps(learned_section)
    path.write_text(header + body)
    return path


def write_learned_nonlinear(path, model, names, result) -> Path:
    """A model file with the learned values in [model] parameters (used by `attend estimate`) and
    [learned] parameter_names, parameters, parameter_std, ... . path: the TOML to write; model:
    the model file learned from (its other sections kept); names, result: of :func:`attend.workflows.identify_nonlinear`."""
    import tomli_w

    data = tomllib.loads(Path(model.path).read_text(encoding="utf-8-sig"))
    parameters = data["model"].setdefault("parameters", {})
    parameters.update({name: float(value) for name, value in zip(names, result.parameters)})
    data.pop("learned", None)
    learned = {"learned": {
        "parameter_names": list(names), "parameters": [float(v) for v in result.parameters],
        "parameter_std": [float(v) for v in result.parameter_std], "converged": bool(result.converged),
        "iterations": int(result.iterations), "message": str(result.message)}}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = ("# Learned by `attend identify` (nonlinear: path mode, learn_path): [model] parameters holds the\n"
              "# learned values; [learned] their error bars (the estimator's spread, docs/nonlinear.md).\n")
    path.write_text(header + tomli_w.dumps(data) + "\n" + tomli_w.dumps(learned))
    return path
