"""Experiment "rhythm-ipp": when to stop flying and replan in UAV search (seed §4.4, Fig. 10).

The search-and-rescue mission of :mod:`attend.action` (40 x 40 map, 7 people, 150 s of flight,
``precision_gain`` planner with a 5-waypoint look-ahead) is flown under replan schedules
(:mod:`attend.rhythm.ipp_schedule`) at equal total flight time:

* fixed budgets: replan after every segment ("segment"), or after 10, 20, 40 s of flight on
  each plan ("fixed_10s", ...);
* "oscillator": replan at each trough of a precision oscillator (f = 0.05 Hz, one trough every
  20 s: the rhythm alone);
* "precision": keep flying while the rest of the plan offers at least the gain rate a fresh plan
  is expected to offer (the last plan's rate scaled by the uncertainty left), the oscillator's
  phase tilting the decision towards its troughs (kappa = 0.5);
* "precision_no_prior": the same rule without the oscillator (kappa = 0).

Per policy and trial: RSE, trace(P), people found vs flight time, number of replans, planner
wall time and the schedule's own decision time. Trial k uses seed k for the field, the
detector noise and the planner, the same for every policy (paired differences). Each trial x
policy is one task of :func:`attend.sweep.run_tasks` (here or on a Dask cluster).

Quick mode: 8 trials, per-cell (diagonal) map covariance, CMA-ES with 6 evaluations per replan
(one generation). Full mode: 25 trials, full covariance, 24 evaluations.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError
from attend.action.camera import Camera, Detector
from attend.action.field import make_field
from attend.action.flight import FlightModel
from attend.action.planners import PlanningSetup, make_planner
from attend.experiments._result import ExperimentResult
from attend.rhythm.ipp_schedule import make_schedule, run_scheduled_episode
from attend.sweep import run_tasks

SETTINGS = dict(
    budget_s=150.0,
    planner="precision_gain",
    lookahead_waypoints=5,
    policies=["segment", "fixed_10s", "fixed_20s", "fixed_40s", "oscillator", "precision", "precision_no_prior"],
    rhythmic_policy="precision",
    oscillator_frequency_hz=0.05,
    oscillator_phase_rad=0.0,
    prior_weight=0.5,
    tolerance=1.0,
    quick_trials=8,
    full_trials=25,
    quick_cma_evaluations=6,
    full_cma_evaluations=24,
    quick_diagonal=True,
    full_diagonal=False,
    first_seed=0,
)

#: policies that are fixed budgets (the rhythmic policy is compared with the best of them)
FIXED_PREFIXES = ("segment", "fixed_")


def trial(task: dict) -> dict:
    """One mission of one policy (a sweep task): ``task`` holds ``policy``, ``seed`` and the
    settings (budget_s, planner, lookahead_waypoints, cma_evaluations, diagonal, oscillator and
    rule parameters). Returns the curves and costs as plain arrays."""
    s = task["settings"]
    seed = int(task["seed"])
    field = make_field(seed)
    setup = PlanningSetup(field, Camera(), Detector(), FlightModel(), lookahead_waypoints=s["lookahead_waypoints"],
                          cma_evaluations=s["cma_evaluations"])
    planner = make_planner(s["planner"], setup, seed)
    schedule = make_schedule(task["policy"], s["oscillator_frequency_hz"], s["oscillator_phase_rad"],
                             s["prior_weight"], s["tolerance"])
    log = run_scheduled_episode(field, planner, schedule, s["budget_s"], seed, diagonal=s["diagonal"])
    return dict(
        policy=task["policy"], seed=seed, time_s=log.metric_times_s, rse=log.series("rse"), trace=log.series("trace"),
        people_found=log.series("people_found"), replan_times_s=np.array(log.replan_times_s),
        planner_times_s=np.array(log.planner_times_s), decision_times_s=np.array(log.decision_times_s),
        decisions=np.array(log.decisions, dtype=float).reshape(-1, 4),
    )


def _values_at(result: dict, key: str, times: np.ndarray) -> np.ndarray:
    index = np.searchsorted(result["time_s"], times, side="right") - 1
    return result[key][np.clip(index, 0, None)]


def _check(quick, trials, policies) -> tuple[int, list[str]]:
    if not isinstance(quick, (bool, np.bool_)):
        raise AttendInputError(f"quick: expected True or False, got {quick!r}")
    if trials is None:
        trials = SETTINGS["quick_trials"] if quick else SETTINGS["full_trials"]
    if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or trials < 1:
        raise AttendInputError(f"trials: expected an integer >= 1, got {trials!r}")
    policies = list(SETTINGS["policies"] if policies is None else policies)
    if not policies:
        raise AttendInputError("policies: expected at least one policy name")
    for name in policies:
        make_schedule(name)  # raises AttendInputError naming "policy"
    return int(trials), policies


def run(quick: bool = True, out_dir=None, progress: bool = True, cluster=None, trials: int | None = None,
        policies=None) -> ExperimentResult:
    """Fly every policy on the same seeded trials and compare them at equal flight time.

    quick: 8 trials, per-cell covariance, 6 CMA-ES evaluations per replan (< 90 s on 2 cores);
    otherwise 25 trials, full covariance, 24 evaluations. trials, policies: override the number
    of trials and the policy list (names as in SETTINGS["policies"]). cluster: a Dask scheduler
    address or client (see attend.sweep.run_tasks). Writes ``out_dir/rhythm-ipp.json`` and the
    figures when ``out_dir`` is given."""
    trials, policies = _check(quick, trials, policies)
    start = time.perf_counter()
    mode = "quick" if quick else "full"
    cfg = dict(SETTINGS, quick=bool(quick), trials=trials, policies=policies,
               cma_evaluations=SETTINGS[f"{mode}_cma_evaluations"], diagonal=SETTINGS[f"{mode}_diagonal"])
    seeds = list(range(cfg["first_seed"], cfg["first_seed"] + trials))
    tasks = [dict(policy=name, seed=seed, settings=cfg) for seed in seeds for name in policies]
    done = run_tasks(trial, tasks, cluster=cluster, progress=progress, desc="rhythm-ipp")
    runs = {name: [r for r in done if r["policy"] == name] for name in policies}

    result = ExperimentResult("rhythm-ipp", settings=cfg)
    grid_t = np.linspace(0.0, cfg["budget_s"], 151)
    summary = {}
    for name, rs in runs.items():
        summary[name] = dict(
            rse=np.array([r["rse"][-1] for r in rs]),
            trace=np.array([r["trace"][-1] for r in rs]),
            found=np.array([r["people_found"][-1] for r in rs]),
            rse_time_average=np.array([_values_at(r, "rse", grid_t).mean() for r in rs]),
            replans=np.array([len(r["replan_times_s"]) for r in rs], dtype=float),
            planner_s=np.array([r["planner_times_s"].sum() for r in rs]),
            decision_s=np.array([r["decision_times_s"].sum() for r in rs]),
        )
        summary[name]["compute_s"] = summary[name]["planner_s"] + summary[name]["decision_s"]
        v = summary[name]
        std = (lambda x: float(np.std(x, ddof=1)) if len(x) > 1 else 0.0)
        result.add(f"{name}_final_RSE_mean", v["rse"].mean(), "1")
        result.add(f"{name}_final_RSE_std", std(v["rse"]), "1")
        result.add(f"{name}_RSE_time_average_mean", v["rse_time_average"].mean(), "1")
        result.add(f"{name}_final_trace_mean", v["trace"].mean(), "1")
        result.add(f"{name}_people_found_mean", v["found"].mean(), "people")
        result.add(f"{name}_replans_mean", v["replans"].mean(), "plans")
        result.add(f"{name}_planner_time_mean", v["planner_s"].mean(), "s")
        result.add(f"{name}_decision_time_mean", v["decision_s"].mean(), "s")
        result.add(f"{name}_compute_time_mean", v["compute_s"].mean(), "s")
    fixed = [n for n in policies if n.startswith(FIXED_PREFIXES)]
    comparison = {}
    if fixed:
        best = min(fixed, key=lambda n: summary[n]["rse"].mean())
        result.notes.append(f"best fixed budget by mean final RSE: {best}")
        for name in policies:
            if name in fixed:
                continue
            diff = summary[name]["rse"] - summary[best]["rse"]
            sem = float(np.std(diff, ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else 0.0
            result.add(f"{name}_minus_best_fixed_final_RSE_mean", diff.mean(), "1")
            result.add(f"{name}_minus_best_fixed_final_RSE_sem", sem, "1")
            result.add(f"{name}_over_best_fixed_replans", summary[name]["replans"].mean() / summary[best]["replans"].mean(), "1")
            result.add(f"{name}_over_best_fixed_compute", summary[name]["compute_s"].mean() / summary[best]["compute_s"].mean(), "1")
            comparison[name] = dict(best_fixed=best, rse_difference=diff)
    result.add("wall_time", time.perf_counter() - start, "s")
    result.data = dict(runs=runs, summary=summary, comparison=comparison, grid_t=grid_t,
                       best_fixed=comparison and next(iter(comparison.values()))["best_fixed"])
    if out_dir is not None:
        result.figures.extend(str(p) for p in plot(result, out_dir))
        result.write(out_dir)
    return result


def plot(result: ExperimentResult, out_dir) -> list[Path]:
    """rhythm-ipp_curves.png (RSE, trace(P), people found vs flight time, mean per policy),
    rhythm-ipp_cost.png (replans and compute per policy) and rhythm-ipp_decisions.png (stay vs
    fresh gain rate of the first precision-driven mission, replans and oscillator troughs)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs, summary, grid_t = result.data["runs"], result.data["summary"], result.data["grid_t"]
    names = list(runs)
    fig = Figure(figsize=(15, 4.2), constrained_layout=True)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    for name in names:
        style = "-" if name.startswith(FIXED_PREFIXES) else "--"
        width = 2.2 if name == result.settings.get("rhythmic_policy") else 1.2
        for ax, key in zip(axes, ("rse", "trace", "people_found")):
            curves = np.array([_values_at(r, key, grid_t) for r in runs[name]])
            ax.plot(grid_t, curves.mean(axis=0), style, lw=width, label=name)
    for ax, label in zip(axes, ("RSE", "trace(P)", "people found")):
        ax.set_xlabel("flight time [s]")
        ax.set_title(f"{label} (mean of {len(runs[names[0]])} trials)")
    axes[0].legend(fontsize=8)
    curves_path = out / "rhythm-ipp_curves.png"
    fig.savefig(curves_path, dpi=110)

    fig = Figure(figsize=(15, 4.0), constrained_layout=True)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    x = np.arange(len(names))
    for ax, key, label in zip(axes, ("rse", "replans", "compute_s"),
                              ("final RSE", "replans per mission", "compute per mission [s] (planner + decisions)")):
        values = [summary[n][key] for n in names]
        ax.bar(x, [v.mean() for v in values], yerr=[v.std() for v in values], color="0.7")
        if key == "compute_s":
            ax.bar(x, [summary[n]["decision_s"].mean() for n in names], color="tab:red", label="decisions")
            ax.legend(fontsize=8)
        ax.set_xticks(x)
        ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
        ax.set_title(label)
    cost_path = out / "rhythm-ipp_cost.png"
    fig.savefig(cost_path, dpi=110)
    paths = [curves_path, cost_path]

    rhythmic = result.settings.get("rhythmic_policy")
    if rhythmic in runs and len(runs[rhythmic][0]["decisions"]):
        run0 = runs[rhythmic][0]
        d = run0["decisions"]
        fig = Figure(figsize=(9, 3.6), constrained_layout=True)
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        ax.plot(d[:, 0], d[:, 1], "o-", label="stay: rest of the plan")
        ax.plot(d[:, 0], d[:, 2], "s--", label="fresh plan (estimate)")
        for t in run0["replan_times_s"]:
            ax.axvline(t, color="k", lw=0.6, alpha=0.5)
        period = 1.0 / result.settings["oscillator_frequency_hz"]
        phase = result.settings["oscillator_phase_rad"]
        for t in np.arange(((-np.pi / 2 - phase) / (2 * np.pi)) % 1.0 * period, result.settings["budget_s"], period):
            ax.axvspan(t - 0.1 * period, t + 0.1 * period, color="tab:red", alpha=0.1)
        ax.set_xlabel("flight time [s] (black: replans; red: oscillator troughs)")
        ax.set_ylabel("expected trace(P) reduction per s")
        ax.set_title(f"{rhythmic}: decisions of trial seed {run0['seed']}")
        ax.legend(fontsize=8)
        decisions_path = out / "rhythm-ipp_decisions.png"
        fig.savefig(decisions_path, dpi=110)
        paths.append(decisions_path)
    return paths
