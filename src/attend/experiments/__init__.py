"""Reproduction experiments, one module per paper figure: thin clients of the library.

Every experiment module follows one contract:

- ``run(quick=True, progress=True, **options) -> ExperimentResult`` computes and returns; it
  draws nothing and writes no file. Everything a figure needs is kept in ``result.tables``
  (JSON-able values: numbers, strings, lists and dicts of them), so the JSON re-plots.
- ``plot(result, out_dir) -> list[str]`` draws the figures from the result alone (as rebuilt by
  ``ExperimentResult.from_json_dict``), writes PNG files into ``out_dir`` and returns their
  paths. Every axis is labelled, with units.
- ``CAPTIONS: dict[str, str]``: figure file name -> a caption a reader understands without the
  code (what is drawn, against what, and what to look for).
- ``claims(result) -> list[Claim]``: the paper's claims this experiment tests, with what attend
  measured, the published value where there is one, and the verdict.

``attend reproduce NAME`` calls ``run``, then ``plot``, then writes ``NAME.json``; ``attend
report DIR`` rebuilds the figures and ``DIR/index.html`` from the JSON files alone. Sweeps
(fig4, fig5) also take ``cluster="tcp://host:8786"`` to run on a Dask cluster (see
:mod:`attend.sweep`).
"""

from __future__ import annotations

import importlib
import importlib.util

#: experiment name -> (module, one-line description)
EXPERIMENTS: dict[str, tuple[str, str]] = {
    "fig2": ("attend.experiments.fig2", "state/input SSE vs embedding order p, DEM vs Kalman filter (paper Fig. 2)"),
    "quadrotor": ("attend.experiments.quadrotor", "real quadrotor flights in wind: roll-rate and motor-input estimation (Bos et al. 2022)"),
    "fig3": ("attend.experiments.fig3", "system identification of the mass-spring-damper with precision learning (paper Fig. 3)"),
    "fig4": ("attend.experiments.fig4", "parameter error vs prior parameter precision: exploration vs exploitation (paper Fig. 4)"),
    "fig5": ("attend.experiments.fig5", "over-exposed vs biased learner across sensor noise; noise-precision learning (paper Fig. 5)"),
    "ipp": ("attend.experiments.ipp", "UAV search and rescue: informative path planning with precision maps (paper Figs. 6-9)"),
    "rhythm-learning": ("attend.experiments.rhythm_learning", "rhythmic vs fixed prior precision in identification across sensor noise (paper §4.4)"),
    "rhythm-ipp": ("attend.experiments.rhythm_ipp", "when to replan in UAV search: precision-driven / rhythmic vs fixed flight budgets (paper §4.4, Fig. 10)"),
    "rhythm-tradeoff": ("attend.experiments.rhythm_tradeoff", "where rhythm helps: schedules tuned alike when switching costs (motion blur, planning latency, saccades)"),
    "vision": ("attend.experiments.vision", "active vision: saccades to the most informative location on a rhythm (paper Fig. 1)"),
    "search-scale": ("attend.experiments.search_scale", "UAV search at field scale: probability map, EFE planner vs the best lawnmower and a truth oracle, several UAVs"),
    "lorenz": ("attend.experiments.lorenz", "nonlinear DEM on the Lorenz attractor under coloured noise vs EKF/UKF and a particle smoother"),
    "attenuation": ("attend.control.attenuation", "sensory attenuation as attention: true and perceived force vs the attenuation of sensory precision (active inference control)"),
    "reaching": ("attend.control.reaching", "reaching with a two-joint arm: action fulfils the predicted movement to a cued target (active inference control, SPM's ADEM_reaching)"),
    "pendulum": ("attend.experiments.pendulum", "nonlinear DEM: pendulum state and unknown input through a (sin, cos) sensor vs augmented EKF/UKF"),
}


def available() -> dict[str, str]:
    """Experiments whose module is present in this installation: name -> description."""
    names = {}
    for name, (module, description) in EXPERIMENTS.items():
        if importlib.util.find_spec(module) is not None:
            names[name] = description
    return names


def load(name: str):
    """The module of experiment ``name``."""
    if name not in EXPERIMENTS:
        raise KeyError(name)
    return importlib.import_module(EXPERIMENTS[name][0])
